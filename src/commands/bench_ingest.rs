//! `chronomap bench ingest`: reading ROS 2 bags, against a bare read of the same file in the
//! same run — [`chronomap_bench::ingest`] measures, this picks the bags and prints.

use anyhow::Result;
use chronomap_bench::ingest::{IngestBench, IngestCase, default_cases};

use crate::bundled::GREG_TRAINING;
use crate::cli::BenchIngestArgs;
use crate::format::Table;
use crate::outln;
use crate::output::{print_bench, usage};

pub fn ingest(args: &BenchIngestArgs) -> Result<()> {
    if args.bag.len() != args.topic.len() {
        return Err(usage(format!(
            "--topic: {} bags but {} topics (give one --topic per --bag, in order)",
            args.bag.len(),
            args.topic.len()
        )));
    }
    let scratch = tempdir()?;
    let cases: Vec<IngestCase> = if args.bag.is_empty() {
        default_cases(&GREG_TRAINING.pairs()?, &scratch.0)?
    } else {
        args.bag
            .iter()
            .zip(&args.topic)
            .map(|(bag, topic)| IngestCase {
                bag: bag.clone(),
                topic: topic.clone(),
            })
            .collect()
    };
    let benches = chronomap_bench::ingest::run(&cases, args.repeats as usize)?;
    print_bench(args.json, &benches, print)
}

fn print(benches: &Vec<IngestBench>) -> Result<()> {
    for b in benches {
        outln!(
            "{} {} ({}): {} messages ({} on the topic), {:.2} MB, median of {}",
            b.bag,
            b.topic,
            b.type_name,
            b.messages,
            b.topic_messages,
            b.file_bytes as f64 / 1e6,
            b.repeats
        )?;
        let mut table = Table::new(["pass", "ms", "messages/s", "MB/s", "x bare read"]);
        for p in &b.passes {
            table.row([
                p.pass.to_string(),
                format!("{:.2}", p.seconds * 1e3),
                format!("{:.0}", p.messages_per_second),
                format!("{:.1}", p.megabytes_per_second),
                format!("{:.1}", p.ratio_to_bare_read),
            ]);
        }
        outln!("{}", table.render().trim_end())?;
    }
    Ok(())
}

/// A temporary folder, removed when dropped.
struct TempDir(std::path::PathBuf);

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn tempdir() -> Result<TempDir> {
    let dir = std::env::temp_dir().join(format!("chronomap-bench-ingest-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    Ok(TempDir(dir))
}
