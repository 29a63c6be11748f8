//! `chronomap monitor sim`: the fault-injection simulation of the system monitoring of [Stüde 2024]
//! §5.3 (`chronomap_bt_monitor::sim`), printed as the intervention table and the metrics of
//! Tables 5.2 and 5.3.

use std::time::Duration;

use anyhow::{Context, Result, bail};
use chronomap_bt::{BtDocument, Registry};
use chronomap_bt_monitor::sim::{SimConfig, SimReport, arbiter_document, random_faults, simulate};
use chronomap_core::num::fmt_number;
use chronomap_io::{BtXml, read_bt_xml};

use crate::cli::MonitorSimArgs;
use crate::format::Table;
use crate::outln;
use crate::output::print_json;

fn clock(seconds: f64) -> String {
    let s = seconds.round() as u64;
    format!("{}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60)
}

fn arbiter(args: &MonitorSimArgs) -> Result<BtDocument> {
    let Some(file) = &args.arbiter else {
        return Ok(arbiter_document());
    };
    let BtXml {
        document, warnings, ..
    } = read_bt_xml(file, &Registry::new())?;
    for warning in warnings {
        crate::errln!("warning: {warning}");
    }
    Ok(document)
}

pub fn sim(args: &MonitorSimArgs) -> Result<()> {
    if !(args.hours.is_finite() && args.hours > 0.0 && args.hours <= 10_000.0) {
        bail!(
            "--hours {}: expected more than 0 and at most 10000",
            fmt_number(args.hours)
        );
    }
    // Checked above: at most 10000 h, so the cast cannot saturate.
    let duration = Duration::from_secs((args.hours * 3600.0).round() as u64);
    let faults = match &args.faults {
        Some(file) => chronomap_io::read_fault_file(file)?,
        None => random_faults(args.seed, duration),
    };
    let doc = arbiter(args)?;
    let mut config = SimConfig::new(duration, args.seed, faults);
    if args.certain {
        config.p_fix = Some(1.0);
    }
    let name = args
        .arbiter
        .as_ref()
        .map_or_else(|| "arbiter".to_owned(), |f| f.display().to_string());
    let report = simulate(&config, &doc).with_context(|| name)?;
    if args.json {
        print_json(&report)
    } else {
        print_report(&report)
    }
}

fn print_report(r: &SimReport) -> Result<()> {
    outln!(
        "{} faults injected over {:.1} h; {} recoveries, {} messages, {} unrequested supervisor interventions",
        r.faults.len(),
        r.operating_h,
        r.interventions.len(),
        r.messages.len(),
        r.unrequested.len()
    )?;
    if !r.interventions.is_empty() {
        let mut table = Table::new([
            "start", "end", "monitor", "category", "step", "reaction", "outcome", "success",
        ]);
        for i in &r.interventions {
            table.row([
                clock(i.start.as_secs_f64()),
                clock(i.end.as_secs_f64()),
                i.monitor.clone(),
                i.category.as_str().to_owned(),
                i.step.to_string(),
                i.reaction.clone(),
                format!("{:?}", i.outcome)
                    .to_lowercase()
                    .replace("notfixed", "not fixed"),
                if i.success { "yes" } else { "no" }.to_owned(),
            ]);
        }
        outln!("\nInterventions (success: no recovery of the same category within 60 s, §5.3.2)")?;
        outln!("{}", table.render())?;
        let mut table = Table::new(["type", "reaction", "#", "success"]);
        for x in &r.reactions {
            table.row([
                x.category.as_str().to_owned(),
                x.reaction.clone(),
                x.count.to_string(),
                format!("{:.1} %", 100.0 * x.successes as f64 / x.count as f64),
            ]);
        }
        outln!("\nRecoveries by category (Table 5.3)")?;
        outln!("{}", table.render())?;
    }
    if !(r.messages.is_empty() && r.unrequested.is_empty()) {
        outln!()?;
    }
    for (t, text) in &r.messages {
        outln!("message at {}: {text}", clock(*t))?;
    }
    for t in &r.unrequested {
        outln!("unrequested supervisor intervention at {}", clock(*t))?;
    }
    outln!("\nMetrics (Table 5.2)")?;
    let mut table = Table::new(["metric", "value"]);
    table.row([
        "time operating t_o".to_owned(),
        format!("{:.2} h", r.operating_h),
    ]);
    table.row(["time moving t_m".to_owned(), format!("{:.2} h", r.moving_h)]);
    table.row([
        "A%(t_o) = t_m/t_o".to_owned(),
        format!("{:.1} %", 100.0 * r.autonomy),
    ]);
    table.row(["mean TSL".to_owned(), format!("{:.2} h", r.tsl_mean_h)]);
    table.row(["max TSL".to_owned(), format!("{:.2} h", r.tsl_max_h)]);
    outln!("{}", table.render())?;
    Ok(())
}
