//! `chronomap bt check`, `chronomap bt run` and `chronomap bt analyse`: BehaviorTree.CPP 4 XML
//! trees ([Stüde 2024] §5.2–5.3) checked and printed, ticked with leaves that follow a script of
//! outcomes (or stubs), or analysed as stochastic behavior trees (§5.2.2, eqs. 5.1–5.4). The
//! jobs and their reports are `chronomap_app_bt::bt`; this file translates flags, serves Groot2,
//! prints and writes.

use std::time::Duration;

use anyhow::{Context, Result, anyhow};
use chronomap_app_bt::bt::{self, BtJobError, Pacing, RunSetup};
use chronomap_bt::{BtDocument, Transition, Tree};
use chronomap_groot2::publisher::Publisher;
use chronomap_io::{write_bt_xml, write_btlog};
use chronomap_plot::render_panels_png;

use crate::cli::{BtAnalyseArgs, BtCheckArgs, BtRunArgs};
use crate::output::{print_json, usage};
use crate::{errln, out, outln};

/// An error of the application layer as the command reports it: a stub that does not fit the
/// document is a usage error (exit code 2), under the file's name where the job gives one.
fn job_error(e: BtJobError) -> anyhow::Error {
    match e {
        BtJobError::Usage(message) => usage(message),
        BtJobError::InFile { name, error } => job_error(*error).context(name),
        e => anyhow::Error::new(e),
    }
}

/// Prints a warning of a job on stderr.
fn warn(warning: String) {
    errln!("warning: {warning}");
}

pub fn check(args: &BtCheckArgs) -> Result<()> {
    let (xml, mut report) =
        bt::check(&args.file, &args.nodes, args.tree.as_deref(), &mut warn).map_err(job_error)?;
    if let Some(path) = &args.output {
        write_bt_xml(path, &xml.document)?;
        report.output = Some(path.display().to_string());
    }
    if args.json {
        return print_json(&serde_json::to_value(&report)?);
    }
    out!("{report}")?;
    Ok(())
}

pub fn run(args: &BtRunArgs) -> Result<()> {
    let mut prepared = bt::prepare_run(
        &RunSetup {
            file: &args.file,
            nodes: &args.nodes,
            script: args.script.as_deref(),
            ticks: args.ticks,
            stubs: &args.stubs,
            stub_all: args.stub_all,
            enums: &args.enums,
            tree: args.tree.as_deref(),
        },
        &mut warn,
    )
    .map_err(job_error)?;
    for note in &prepared.notes {
        errln!("note: {note}");
    }
    let period = Duration::from_millis(args.tick_ms);
    let live = start_live(args, &prepared)?;
    let mut update = |tree: &Tree, doc: &BtDocument, transitions: &[Transition]| {
        if let Some(publisher) = live.as_ref().and_then(|l| l.publisher.as_ref()) {
            publisher.update(tree, doc, transitions);
        }
    };
    let pacing = live.as_ref().map(|live| Pacing {
        pause: live.pause,
        monitor: live.publisher.as_ref().map(Publisher::tick_monitor),
        after_tick: &mut update,
    });
    let mut report = prepared.run(period, pacing).map_err(job_error)?;
    if let Some(path) = &args.btlog {
        write_btlog(path, &prepared.tree, Duration::ZERO, &report.recorded)?;
        report.btlog = Some(path.display().to_string());
    }
    if args.json {
        print_json(&serde_json::to_value(&report)?)?;
    } else {
        out!("{report}")?;
    }
    match report.failure() {
        Some(message) => Err(anyhow!(message.to_owned())),
        None => Ok(()),
    }
}

/// `--groot2`, `--tick-period`, `--linger`: the Groot2 server of a run and the wall-clock
/// pacing of its ticks. Dropped at the end of the run: it keeps answering for the linger
/// time first.
struct Live {
    publisher: Option<Publisher>,
    pause: Duration,
    linger: Duration,
}

impl Drop for Live {
    fn drop(&mut self) {
        if let Some(publisher) = &self.publisher
            && !self.linger.is_zero()
        {
            errln!(
                "note: groot2: answering on port {} for {} s more",
                publisher.port(),
                self.linger.as_secs()
            );
            std::thread::sleep(self.linger);
        }
    }
}

/// The Groot2 server (started now, before the first tick) and the pacing a run asks for, if
/// any.
fn start_live(args: &BtRunArgs, prepared: &bt::PreparedRun) -> Result<Option<Live>> {
    if args.groot2.is_none() && args.tick_period.is_none() {
        return Ok(None);
    }
    let publisher = match args.groot2 {
        Some(port) => {
            let publisher = Publisher::start(&prepared.tree, &prepared.xml.document, port)
                .with_context(|| format!("--groot2 {port}"))?;
            if let Some(ms) = args.groot2_heartbeat {
                publisher.set_max_heartbeat_delay(Duration::from_millis(ms));
            }
            errln!("note: groot2: serving on ports {port} and {}", port + 1);
            Some(publisher)
        }
        None => None,
    };
    let default_ms = if publisher.is_some() { 500 } else { 0 };
    Ok(Some(Live {
        publisher,
        pause: Duration::from_millis(args.tick_period.unwrap_or(default_ms)),
        linger: Duration::from_secs(args.linger.unwrap_or(0)),
    }))
}

/// `chronomap bt analyse`: the stochastic behavior tree of §5.2.2 ([`bt::analyse`]).
pub fn analyse(args: &BtAnalyseArgs) -> Result<()> {
    let analysis = bt::analyse(
        (&args.file, &args.nodes, &args.params),
        args.tree.as_deref(),
        (args.t_max, args.steps, args.plot.is_some()),
        &mut warn,
    )
    .map_err(job_error)?;
    if args.json {
        print_json(&analysis)?;
    } else {
        out!("{analysis}")?;
    }
    if let Some(path) = &args.plot {
        render_panels_png(&[analysis.panel()], path, 1000, 500)?;
        if !args.json {
            outln!("wrote {}", path.display())?;
        }
    }
    Ok(())
}
