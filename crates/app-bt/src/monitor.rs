//! The system monitoring of [Stüde 2024] §5.3 as a job: a fault-injection simulation of a
//! behavior-tree arbiter (the built-in one or a BehaviorTree.CPP 4 file) with random or given
//! faults ([`chronomap_bt_monitor::sim`]), reported as the intervention table and the metrics
//! of Tables 5.2 and 5.3.
//!
//! ```
//! use chronomap_app_bt::monitor::{SimSetup, simulate};
//!
//! // One simulated hour of random faults, every recovery certain.
//! let report = simulate(&SimSetup { hours: 1.0, seed: 1, faults: None, certain: true, arbiter: None }, &mut |_| {}).unwrap();
//! assert!((report.0.operating_h - 1.0).abs() < 1e-9);
//! assert!(report.text().contains("Metrics (Table 5.2)"));
//! ```

use std::fmt;
use std::path::Path;
use std::time::Duration;

use chronomap_bt::Registry;
use chronomap_bt_monitor::sim::{
    SimConfig, SimError, SimReport, arbiter_document, random_faults, simulate as run,
};
use chronomap_core::num::fmt_number;
use chronomap_io::{BtXml, BtXmlError, FaultFileError, read_bt_xml, read_fault_file};
use serde::Serialize;

use chronomap_app::report::Table;

/// Why a simulation cannot run.
#[derive(Debug, thiserror::Error)]
pub enum MonitorJobError {
    /// The simulated time is not in (0, 10000] hours.
    #[error("--hours {}: expected more than 0 and at most 10000", fmt_number(*.0))]
    Hours(f64),
    /// The fault file cannot be read.
    #[error(transparent)]
    Faults(#[from] FaultFileError),
    /// The arbiter file cannot be read.
    #[error(transparent)]
    Arbiter(#[from] BtXmlError),
    /// The simulation failed (`name`: the arbiter's file, or "arbiter").
    #[error("{name}")]
    Simulation {
        /// The arbiter's file, or "arbiter".
        name: String,
        /// Why.
        #[source]
        error: SimError,
    },
}

/// What a simulation is given (`chronomap monitor sim`'s flags).
#[derive(Clone, Copy, Debug)]
pub struct SimSetup<'a> {
    /// Simulated hours, more than 0 and at most 10,000.
    pub hours: f64,
    /// Seed of the random faults and recovery outcomes.
    pub seed: u64,
    /// A fault file to inject instead of random faults.
    pub faults: Option<&'a Path>,
    /// Every recovery fixes its fault (unless the fault says otherwise) instead of Table 5.3's
    /// success rates.
    pub certain: bool,
    /// The arbiter tree's file (default: the built-in one).
    pub arbiter: Option<&'a Path>,
}

/// The result of a simulation ([`SimReport`]), serialised as it.
#[derive(Clone, Debug, Serialize)]
#[serde(transparent)]
pub struct Simulation(pub SimReport);

/// Runs the simulation `setup` describes; warnings of reading the arbiter go to `warn`.
///
/// # Errors
/// [`MonitorJobError`]: hours out of range, a fault or arbiter file that cannot be read, an
/// arbiter that does not fit the simulation.
pub fn simulate(
    setup: &SimSetup<'_>,
    warn: &mut dyn FnMut(String),
) -> Result<Simulation, MonitorJobError> {
    let hours = setup.hours;
    if !(hours.is_finite() && hours > 0.0 && hours <= 10_000.0) {
        return Err(MonitorJobError::Hours(hours));
    }
    // Checked above: at most 10000 h, so the cast cannot saturate.
    let duration = Duration::from_secs((hours * 3600.0).round() as u64);
    let faults = match setup.faults {
        Some(file) => read_fault_file(file)?,
        None => random_faults(setup.seed, duration),
    };
    let doc = match setup.arbiter {
        None => arbiter_document(),
        Some(file) => {
            let BtXml {
                document, warnings, ..
            } = read_bt_xml(file, &Registry::new())?;
            for warning in warnings {
                warn(warning.to_string());
            }
            document
        }
    };
    let mut config = SimConfig::new(duration, setup.seed, faults);
    if setup.certain {
        config.p_fix = Some(1.0);
    }
    let report = run(&config, &doc).map_err(|error| MonitorJobError::Simulation {
        name: setup
            .arbiter
            .map_or_else(|| "arbiter".to_owned(), |f| f.display().to_string()),
        error,
    })?;
    Ok(Simulation(report))
}

/// `H:MM:SS` of `seconds`.
fn clock(seconds: f64) -> String {
    let s = seconds.round() as u64;
    format!("{}:{:02}:{:02}", s / 3600, s / 60 % 60, s % 60)
}

impl Simulation {
    /// The report as `chronomap monitor sim` prints it.
    pub fn text(&self) -> String {
        self.to_string()
    }
}

impl fmt::Display for Simulation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = &self.0;
        writeln!(
            f,
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
            writeln!(
                f,
                "\nInterventions (success: no recovery of the same category within 60 s, §5.3.2)"
            )?;
            writeln!(f, "{}", table.render())?;
            let mut table = Table::new(["type", "reaction", "#", "success"]);
            for x in &r.reactions {
                table.row([
                    x.category.as_str().to_owned(),
                    x.reaction.clone(),
                    x.count.to_string(),
                    format!("{:.1} %", 100.0 * x.successes as f64 / x.count as f64),
                ]);
            }
            writeln!(f, "\nRecoveries by category (Table 5.3)")?;
            writeln!(f, "{}", table.render())?;
        }
        if !(r.messages.is_empty() && r.unrequested.is_empty()) {
            writeln!(f)?;
        }
        for (t, text) in &r.messages {
            writeln!(f, "message at {}: {text}", clock(*t))?;
        }
        for t in &r.unrequested {
            writeln!(f, "unrequested supervisor intervention at {}", clock(*t))?;
        }
        writeln!(f, "\nMetrics (Table 5.2)")?;
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
        writeln!(f, "{}", table.render())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setup(hours: f64) -> SimSetup<'static> {
        SimSetup {
            hours,
            seed: 1,
            faults: None,
            certain: false,
            arbiter: None,
        }
    }

    #[test]
    fn hours_out_of_range_are_refused_by_name() {
        for hours in [0.0, -1.0, 10_000.5, f64::NAN] {
            let e = simulate(&setup(hours), &mut |_| {}).unwrap_err();
            assert!(matches!(e, MonitorJobError::Hours(_)), "{hours}");
        }
        assert_eq!(
            simulate(&setup(0.0), &mut |_| {}).unwrap_err().to_string(),
            "--hours 0: expected more than 0 and at most 10000"
        );
    }

    #[test]
    fn clock_shows_hours_minutes_seconds() {
        assert_eq!(clock(0.0), "0:00:00");
        assert_eq!(clock(3_725.4), "1:02:05");
        assert_eq!(clock(36_000.0), "10:00:00");
    }

    #[test]
    fn the_hand_written_scenario_recovers_in_the_known_order() {
        let faults = chronomap_testutil::repo_path("tests/data/monitor/faults.txt");
        let setup = SimSetup {
            hours: 0.5,
            faults: Some(&faults),
            certain: true,
            ..setup(0.5)
        };
        let report = simulate(&setup, &mut |_| {}).unwrap();
        let rows: Vec<(f64, f64, &str, bool)> = report
            .0
            .interventions
            .iter()
            .map(|i| {
                (
                    i.start.as_secs_f64(),
                    i.end.as_secs_f64(),
                    i.leaf.as_str(),
                    i.success,
                )
            })
            .collect();
        assert_eq!(
            rows[..3],
            [
                (100.0, 120.0, "SlowRotate", false),
                (120.0, 150.0, "RestartLocalization", true),
                (300.0, 310.0, "WaitAndRetry", false),
            ]
        );
        // Stuck from 1200 s, last motion at 1199 s: the supervisor comes at 1799 s; moving
        // 1086 s of the 1800 (tests/cli/monitor.rs counts them).
        assert_eq!(report.0.unrequested, [1799.0]);
        assert!((report.0.autonomy - 1086.0 / 1800.0).abs() < 1e-9);
        let text = report.text();
        assert!(
            text.contains("\nunrequested supervisor intervention at 0:29:59\n"),
            "{text}"
        );
        assert!(text.contains("\nA%(t_o) = t_m/t_o   60.3 %\n"), "{text}");
        assert!(text.contains("\n0:01:40  0:02:00  "), "{text}");
    }
}
