//! `chronomap ingest`: ROS 2 bags in, the models, grids and files of the other commands out.
//! The bag is read by `chronomap-rosbag`; what it yields goes through the same code as the
//! text files of `fit` and `grid build`, so both give the same bits (`chronomap_app::ingest`
//! reads and writes, this prints).

use anyhow::Result;
use chronomap_app::ingest::{
    BagListing, IngestError, PeopleFiles, ingest_records, state_training, topic_kind,
};
use chronomap_rosbag::{Bag, RecordKind, TimeSource};

use super::grid;
use crate::cli::{GridBuildArgs, GridSource, IngestArgs, OrderArg, PeopleFormat, StoreArg};
use crate::output::{ProgressBar, print_json, usage};
use crate::{errln, outln};

pub fn run(args: &IngestArgs) -> Result<()> {
    let bag = Bag::open(&args.bag)?;
    let Some(topic) = &args.topic else {
        let listing = BagListing::of(&bag, &ProgressBar::new())?;
        for warning in &listing.summary.warnings {
            errln!("warning: {warning}");
        }
        if args.json {
            return print_json(&listing.json());
        }
        return Ok(outln!("{}", listing.text())?);
    };
    let (type_name, kind) = topic_kind(&bag, topic, &ProgressBar::new())?;
    let output = args.output.as_deref().ok_or_else(|| {
        usage(format!(
            "-o/--output: where to write what topic {topic} ({type_name}) becomes"
        ))
    })?;
    let time: TimeSource = args.time.into();
    if args.model.is_some() && kind != RecordKind::State {
        return Err(usage(format!(
            "--model: topic {topic} carries {type_name} ({}), not states",
            kind.name()
        )));
    }
    match kind {
        RecordKind::State => {
            // A state topic becomes a model file, fitted as `chronomap fit` fits a text file.
            let model = args.model.as_ref().ok_or_else(|| {
                usage(format!(
                    "--model: topic {topic} carries states; say which model to fit (e.g. fremen:2, fremen:auto, hist:24, auto)"
                ))
            })?;
            let (training, warning) = state_training(&bag, topic, time, &ProgressBar::new())?;
            if let Some(warning) = warning {
                errln!("warning: {warning}");
            }
            let report = chronomap_app::model::fit(
                &training,
                model,
                &args.fit.options(),
                &chronomap_core::calendar::DaysOff::default(),
                output,
            )?;
            if args.json {
                return print_json(&report.json());
            }
            Ok(outln!("{}", report.text())?)
        }
        RecordKind::Map => grid::build(&GridBuildArgs {
            source: GridSource {
                synthetic: false,
                frames: None,
                cell_series: Vec::new(),
                bag: Some(args.bag.clone()),
            },
            topic: Some(topic.clone()),
            time: args.time,
            cells: 0,
            days: 0,
            seed: 0,
            ros1: false,
            output: output.to_path_buf(),
            store: StoreArg::State,
            order: OrderArg::Fixed(2),
            periods: args.fit.periods.clone(),
            errors: false,
            holdout: args.fit.holdout,
            threads: None,
            json: args.json,
        }),
        _ => {
            let people = match args.people {
                PeopleFormat::Events => PeopleFiles::Events,
                PeopleFormat::Tracks => PeopleFiles::Tracks,
            };
            let bar = ProgressBar::new();
            let ingested = ingest_records(
                &bag, topic, &type_name, kind, time, people, output, &bar,
            )
            .map_err(|e| match e {
                IngestError::NoIdentity { .. } => usage(e.to_string()),
                e => e.into(),
            })?;
            drop(bar);
            if let Some(warning) = &ingested.warning {
                errln!("warning: {warning}");
            }
            if args.json {
                return print_json(&ingested.json());
            }
            Ok(outln!("{}", ingested.text())?)
        }
    }
}
