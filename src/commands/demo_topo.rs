//! The topological part of `chronomap demo` ([Fentanes 2015]): edge models of the Witham Wharf
//! deployment, their score on the later weeks, and a now-or-later table through the lab door.

use std::path::Path;
use std::time::Instant;

use anyhow::{Result, anyhow};
use chronomap_topo::edges::{EdgeModelConfig, EdgeModels};

use super::demo::indent;
use super::topo::{DayTable, score_table};
use crate::bundled;
use crate::format::time;
use crate::outln;
use crate::output::ProgressBar;

/// 2014-08-20 00:00 UTC: the chronological split (train before, test from).
const SPLIT: f64 = 1_408_492_800.0;

/// Prints section 5 of the demo; writes the heat map into `out` if given. Returns the files
/// written.
pub fn run(out: Option<&Path>) -> Result<Vec<String>> {
    outln!(
        "\n5. Now or later? Navigation on a topological map whose edges know time ([Fentanes 2015]).\n"
    )?;
    // Success: FreMEn of order 1 with persistence (the daily rhythm of the doors plus the
    // memory of the last attempts); durations: FreMEn with automatic order.
    let config = EdgeModelConfig {
        success_order: Some(1),
        ..EdgeModelConfig::default()
    };
    let fit = |map, attempts: &[_]| {
        EdgeModels::fit(map, attempts, config.clone())
            .map_err(|(edge, e)| anyhow!("Witham edge {edge}: {e}"))
    };

    let bar = ProgressBar::stage("Witham edges", 0);
    let stats = bundled::witham_edges()?;
    let (first, last) = stats
        .time_span()
        .ok_or_else(|| anyhow!("the Witham data have no attempt"))?;
    let (train, test) = stats.split_at(SPLIT);
    let train_attempts = train.total_attempts();
    let models = fit(train.map, &train.attempts)?;
    let online = models.evaluate_online(&test.attempts)?;
    let frozen = models.evaluate(&test.attempts)?;
    drop(bar);
    outln!(
        "   Witham Wharf, {} nodes, {} edges, {} traversal attempts, {} .. {}.",
        stats.map.nodes().len(),
        stats.map.edges().len(),
        stats.total_attempts(),
        time(first),
        time(last)
    )?;
    outln!(
        "   Trained on the {} attempts before {}, scored on the {} after (the robot's later weeks):\n",
        train_attempts,
        time(SPLIT),
        test.total_attempts()
    )?;
    let table = score_table(
        "static (s²)",
        [
            (
                "online: models learn each attempt after predicting it".to_string(),
                &online,
            ),
            ("frozen: models as trained".to_string(), &frozen),
        ],
    );
    outln!("{}", indent(&table.render()))?;
    outln!(
        "\n   Online, the per-edge models beat the static per-edge rates by far: persistence (\
         [Krajník 2017] eq. 12-13)\n   carries the robot's retry bursts. Frozen for weeks, the daily rhythm \
         alone does not transfer."
    )?;

    let bar = ProgressBar::stage("Witham plans", 0);
    let started = Instant::now();
    let models = fit(stats.map, &stats.attempts)?;
    let fit_seconds = started.elapsed().as_secs_f64();
    let table = DayTable::compute(&models, "Station", "F Kitchen", last + 86_400.0, 7, 120)?;
    drop(bar);
    outln!(
        "\n   Fitted on all attempts in {fit_seconds:.2} s. Task \"F Kitchen\" from Station: the lab's \
         only way out\n   is the door LabDoor1 -> LabDoor2. Maximum probability of success and first \
         action in the week\n   after the data ({} plans in {:.1} ms):\n",
        7 * 12,
        1e3 * table.seconds
    )?;
    outln!("{}", indent(&table.render()))?;
    outln!(
        "\n   The door's daily rhythm: hopeless at night, best in the afternoon; the first night \
         still\n   remembers the successes just before the data end (persistence)."
    )?;
    let mut written = Vec::new();
    if let Some(dir) = out {
        let path = dir.join("witham_now_or_later.png");
        table.plot(&path)?;
        written.push(path.display().to_string());
    }
    Ok(written)
}
