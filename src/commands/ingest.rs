//! `chronomap ingest`: ROS 2 bags in, the models, grids and files of the other commands out.
//! The bag is read by `chronomap-rosbag`; what it yields goes through the same code as the
//! text files of `fit` and `grid build`, so both give the same bits.

use std::path::Path;

use anyhow::{Result, anyhow};
use chronomap_app::ingest::{People, events_of, read_people, track_rows};
use chronomap_core::TimeSeries;
use chronomap_io::tracks::write_tracks;
use chronomap_io::{write_data_file, write_events};
use chronomap_rosbag::records::{encode_poses, encode_scans};
use chronomap_rosbag::{Bag, BagSummary, DefinitionSource, RecordKind, TimeSource};
use serde_json::{Value, json};

use super::grid;
use super::model::{Training, fit_and_save};
use crate::cli::{
    GridBuildArgs, GridSource, IngestArgs, OrderArg, PeopleFormat, StoreArg, TimeArg,
};
use crate::format::{Table, time};
use crate::outln;
use crate::output::{ProgressBar, print_json, usage};

pub fn run(args: &IngestArgs) -> Result<()> {
    let bag = Bag::open(&args.bag)?;
    let Some(topic) = &args.topic else {
        return list(&bag, args.json);
    };
    let type_name = bag.topic_type(topic, &ProgressBar::new())?.ok_or_else(|| {
        anyhow!(
            "{}: there is no topic {topic} (list the topics: chronomap ingest {})",
            bag.name(),
            bag.name()
        )
    })?;
    let Some(kind) = RecordKind::of(&type_name) else {
        return Err(anyhow!(
            "{}: topic {topic} is {type_name}, which chronomap does not learn from (it reads {})",
            bag.name(),
            known_kinds()
        ));
    };
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
        RecordKind::State => ingest_states(&bag, topic, args, output),
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
        RecordKind::People => {
            let People {
                messages,
                detections,
            } = read_people(&bag, topic, time, &ProgressBar::new())?;
            let written = match args.people {
                PeopleFormat::Events => {
                    write_events(output, &events_of(&detections))?;
                    "events"
                }
                PeopleFormat::Tracks => {
                    let rows = track_rows(&detections).map_err(|_| {
                        usage(format!(
                            "--people tracks: {} {topic} has poses without identities \
                             (geometry_msgs/msg/PoseArray); write events instead",
                            bag.name()
                        ))
                    })?;
                    write_tracks(output, &rows)?;
                    "tracks"
                }
            };
            let first_frame = detections.first().map(|d| d.frame_id.clone());
            report(
                args,
                &bag,
                topic,
                &type_name,
                messages,
                &format!(
                    "{} detections in {messages} messages as {written}",
                    detections.len()
                ),
                output,
                json!({ "detections": detections.len(), "format": written, "frame_id": first_frame }),
            )
        }
        RecordKind::Scan => {
            let scans = bag.read_scans(topic, time, &ProgressBar::new())?;
            write_data_file(output, encode_scans(&scans).as_bytes())?;
            let beams = scans.first().map_or(0, |s| s.ranges.len());
            report(
                args,
                &bag,
                topic,
                &type_name,
                scans.len(),
                &format!("{} scans of {beams} beams", scans.len()),
                output,
                json!({ "scans": scans.len(), "beams": beams }),
            )
        }
        RecordKind::Odometry => {
            let poses = bag.read_odometry(topic, time, &ProgressBar::new())?;
            write_data_file(output, encode_poses(&poses).as_bytes())?;
            report(
                args,
                &bag,
                topic,
                &type_name,
                poses.len(),
                &format!("{} poses", poses.len()),
                output,
                json!({ "poses": poses.len() }),
            )
        }
    }
}

/// A state topic becomes a model file, fitted as `chronomap fit` fits a text file.
fn ingest_states(bag: &Bag, topic: &str, args: &IngestArgs, output: &Path) -> Result<()> {
    let model = args.model.as_ref().ok_or_else(|| {
        usage(format!(
            "--model: topic {topic} carries states; say which model to fit (e.g. fremen:2, fremen:auto, hist:24, auto)"
        ))
    })?;
    let states = bag.read_states(topic, args.time.into(), &ProgressBar::new())?;
    warn_count(bag, topic, states.times.len());
    let name = format!("{} {topic}", bag.name());
    let training = Training {
        json: json!({
            "bag": bag.name(),
            "topic": topic,
            "time": time_name(args.time),
            "observations": states.times.len(),
        }),
        name,
        series: TimeSeries {
            times: states.times,
            values: states.values,
        },
    };
    fit_and_save(&training, model, &args.fit, output, args.json)
}

fn time_name(time: TimeArg) -> &'static str {
    match time {
        TimeArg::Auto => "auto",
        TimeArg::Header => "header",
        TimeArg::Log => "log",
        TimeArg::Publish => "publish",
    }
}

/// Says so when `metadata.yaml` counts another number of messages on `topic` than were read.
fn warn_count(bag: &Bag, topic: &str, messages: usize) {
    if let Some(warning) = bag.count_warning(topic, messages as u64) {
        crate::errln!("warning: {warning}");
    }
}

/// Prints what was read and written.
#[allow(clippy::too_many_arguments)]
fn report(
    args: &IngestArgs,
    bag: &Bag,
    topic: &str,
    type_name: &str,
    messages: usize,
    what: &str,
    output: &Path,
    details: Value,
) -> Result<()> {
    warn_count(bag, topic, messages);
    if args.json {
        return print_json(&json!({
            "bag": bag.name(),
            "topic": topic,
            "type": type_name,
            "time": time_name(args.time),
            "messages": messages,
            "read": details,
            "output": output.display().to_string(),
        }));
    }
    outln!("{}: {topic} ({type_name}): {what}", bag.name())?;
    outln!("wrote {}", output.display())?;
    Ok(())
}

fn known_kinds() -> String {
    [
        RecordKind::State,
        RecordKind::Map,
        RecordKind::People,
        RecordKind::Scan,
        RecordKind::Odometry,
    ]
    .iter()
    .map(|k| k.types())
    .collect::<Vec<_>>()
    .join("; ")
}

/// What `ingest --topic` makes of a topic of `kind`.
fn makes(kind: Option<RecordKind>) -> &'static str {
    match kind {
        Some(RecordKind::State) => "a model (--model SPEC)",
        Some(RecordKind::Map) => "a grid",
        Some(RecordKind::People) => "events or tracks",
        Some(RecordKind::Scan) => "scans",
        Some(RecordKind::Odometry) => "poses",
        None => "nothing (not a type chronomap learns from)",
    }
}

/// Lists every topic: unknown ones too, with the reason they are not used.
fn list(bag: &Bag, json_out: bool) -> Result<()> {
    let summary: BagSummary = bag.summary(&ProgressBar::new())?;
    for warning in &summary.warnings {
        crate::errln!("warning: {warning}");
    }
    if json_out {
        let topics: Vec<Value> = summary
            .topics
            .iter()
            .map(|t| {
                let kind = RecordKind::of(&t.type_name);
                json!({
                    "topic": t.name,
                    "type": t.type_name,
                    "encoding": t.encoding,
                    "messages": t.count,
                    "first": t.first,
                    "last": t.last,
                    "kind": kind.map(RecordKind::name),
                    "definition": match &t.definition {
                        DefinitionSource::Bag => "bag".to_string(),
                        DefinitionSource::BuiltIn => "built-in".to_string(),
                        DefinitionSource::Missing(why) => format!("missing: {why}"),
                    },
                })
            })
            .collect();
        return print_json(&json!({
            "bag": bag.name(),
            "messages": summary.messages,
            "bytes": summary.bytes,
            "topics": topics,
            "warnings": summary.warnings,
        }));
    }
    let topics = summary.topics.len();
    outln!(
        "{}: {} messages on {topics} topic{}",
        bag.name(),
        summary.messages,
        if topics == 1 { "" } else { "s" }
    )?;
    let mut table =
        Table::new(["topic", "type", "messages", "from", "to", "ingest makes"]).left(&[1, 5]);
    for t in &summary.topics {
        let kind = RecordKind::of(&t.type_name);
        let makes = match &t.definition {
            DefinitionSource::Missing(why) => format!("nothing: {why}"),
            _ => makes(kind).to_string(),
        };
        table.row([
            t.name.clone(),
            t.type_name.clone(),
            t.count.to_string(),
            time(t.first),
            time(t.last),
            makes,
        ]);
    }
    outln!("{}", table.render().trim_end())?;
    Ok(())
}
