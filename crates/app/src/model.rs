//! Saved temporal models as reports: a model fitted on a series and written to a model file
//! (`chronomap fit`, `chronomap ingest` of a state topic), what a model file holds (the spectrum
//! of FreMEn, [Krajník 2017] eqs. (3)-(10), the spectral set `P` of FFT FreMEn, §III-B, the
//! mixtures of PerGaM and Warped Hypertime, [Krajník 2019]), and the observations a model finds
//! anomalous.
//!
//! Each report serialises as the JSON the faces print (`json`) and renders itself as text
//! (`text`); the faces load the model, print and name their flags.

use std::path::Path;

use chronomap_core::anomaly::{Anomaly, detect_anomalies};
use chronomap_core::calendar::DaysOff;
use chronomap_core::fft::FftFremen;
use chronomap_core::{
    BuildError, ConfigError, FremenModel, FrequencyComponent, Ordered, TemporalModel, TimeSeries,
};
use chronomap_io::model_file::ModelFileError;
use chronomap_io::output::{OutputError, write_output};
use chronomap_models::AnyModel;
use chronomap_models::calendar::OnCalendar;
use chronomap_models::spec::{FitOptions, ModelSpec, Selection};
use serde_json::{Value, json};

use crate::report::{Table, duration, period, time};

/// A model-building error about the data of a named source, naming the offending
/// observation (its position among the data lines) when there is one:
/// `door.txt: observation 3: …`.
#[derive(Debug, thiserror::Error)]
#[error(
    "{source_name}: {}{error}",
    error.observation_index().map(|i| format!("observation {}: ", i + 1)).unwrap_or_default()
)]
pub struct DataIssue {
    /// The file (or bag and topic) the observations came from.
    pub source_name: String,
    /// Why they cannot be used.
    pub error: BuildError,
}

/// Why a model cannot be fitted and written.
#[derive(Debug, thiserror::Error)]
pub enum ModelJobError {
    /// The spec cannot be fitted to the observations.
    #[error("cannot fit {spec}")]
    Fit {
        /// The model asked for.
        spec: String,
        /// Why.
        #[source]
        source: DataIssue,
    },
    /// The model cannot be encoded.
    #[error(transparent)]
    File(#[from] ModelFileError),
    /// The model file cannot be written.
    #[error(transparent)]
    Output(#[from] OutputError),
}

/// Observations to fit a model on, and how to name them.
#[derive(Clone, Debug)]
pub struct Training {
    /// The file (or bag and topic) they came from, for messages.
    pub name: String,
    /// What the JSON report says about them (`"train"`).
    pub json: Value,
    /// The observations.
    pub series: TimeSeries,
}

/// What [`fit`] did: the model fitted, how it was chosen, the file written.
#[derive(Clone, Debug)]
pub struct FitReport {
    /// The training data as the JSON report names them.
    pub train: Value,
    /// Their name in text.
    pub train_name: String,
    /// Observations fitted on (those of working days, with a calendar).
    pub observations: usize,
    /// Days off of the model's calendar (0: none).
    pub days_off: usize,
    /// The model asked for (`fremen:auto`).
    pub model: String,
    /// The model fitted (`fremen:4`).
    pub fitted: String,
    /// The model fitted, in words (`fremen:auto -> fremen:4`).
    pub fitted_as: String,
    /// Its kind (`fremen`).
    pub kind: &'static str,
    /// Its order, if it has one.
    pub order: Option<usize>,
    /// How it was chosen ([`describe_selection`]).
    pub selection: Option<String>,
    /// The file written.
    pub output: String,
    /// Bytes written.
    pub bytes: usize,
}

impl FitReport {
    /// The report as `chronomap fit --json` prints it.
    pub fn json(&self) -> Value {
        json!({
            "train": self.train,
            "model": self.model,
            "fitted": self.fitted,
            "kind": self.kind,
            "order": self.order,
            "selection": self.selection,
            "observations": self.observations,
            "days_off": self.days_off,
            "output": self.output,
            "bytes": self.bytes,
        })
    }

    /// The report as `chronomap fit` prints it.
    pub fn text(&self) -> String {
        let mut lines = vec![format!(
            "fitted {} as {} on {} observations of {}",
            self.model, self.fitted_as, self.observations, self.train_name
        )];
        lines.extend(self.selection.clone());
        lines.push(format!("wrote {} ({} bytes)", self.output, self.bytes));
        lines.join("\n")
    }
}

/// Fits `spec` on `training` with `options` and writes the model file to `output` (a pipe or
/// a device is written through). With `days_off`, the model is fitted on the working days and
/// saved with its calendar ([`OnCalendar`]): whoever opens the file predicts a day off by its
/// stand-in.
///
/// # Errors
/// [`ModelJobError::Fit`] naming the observation that cannot be used, or the file's error.
pub fn fit(
    training: &Training,
    spec: &ModelSpec,
    options: &FitOptions,
    days_off: &DaysOff,
    output: &Path,
) -> Result<FitReport, ModelJobError> {
    let train = &training.series;
    let (times, values) = days_off.working_days(&train.times, &train.values);
    let mut fitted = spec
        .fit(&times, &values, options)
        .map_err(|error| ModelJobError::Fit {
            spec: spec.to_string(),
            source: DataIssue {
                source_name: training.name.clone(),
                error,
            },
        })?;
    if !days_off.is_empty() {
        fitted.model =
            AnyModel::Calendar(Box::new(OnCalendar::new(fitted.model, days_off.clone())));
    }
    // The size is what was written, not the output's size afterwards (0 for `-o /dev/null`
    // or a pipe, which the one output writer writes through).
    let encoded = chronomap_io::encode_model(fitted.model.kind(), &fitted.model)?;
    write_output(output, &encoded)?;
    Ok(FitReport {
        train: training.json.clone(),
        train_name: training.name.clone(),
        observations: times.len(),
        days_off: days_off.len(),
        model: spec.to_string(),
        fitted: fitted.model.spec().to_string(),
        fitted_as: fitted.model.fitted_as(),
        kind: fitted.model.kind(),
        order: fitted.model.order(),
        selection: fitted.selection.as_ref().map(describe_selection),
        output: output.display().to_string(),
        bytes: encoded.len(),
    })
}

/// The held-out error of each candidate order, `ORDER:ERROR` from order 0 up, space-separated
/// (eq. (15) of [Krajník 2017] per order).
pub fn errors_by_order(errors: &[f64]) -> String {
    errors
        .iter()
        .enumerate()
        .map(|(k, e)| format!("{k}:{e:.4}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// One line saying how a model's order or family was chosen: the order on held-back
/// observations, the weights of `auto`'s stack, or the periodicities of Warped Hypertime
/// ([Krajník 2019] §III-B).
pub fn describe_selection(selection: &Selection) -> String {
    match selection {
        Selection::Order(s) => format!(
            "order {} chosen on {} held-back observations (error by order {})",
            s.order,
            s.held_back,
            errors_by_order(&s.errors)
        ),
        Selection::Stack(stack) => {
            let weights: Vec<String> = stack
                .weights
                .iter()
                .map(|(m, w)| format!("{m} {w:.3}"))
                .collect();
            let best = stack
                .errors
                .iter()
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .map_or(String::new(), |(m, e)| format!(", best single {m} {e:.4}"));
            format!(
                "weights {} fitted on {} out-of-sample predictions from {} rolling origins \
                 (Brier {:.4}{best})",
                weights.join(", "),
                stack.held_back,
                stack.origins,
                stack.combined_error
            )
        }
        Selection::Hypertime {
            periods,
            components,
        } => {
            let periods: Vec<String> = periods.iter().map(|&p| period(p)).collect();
            format!(
                "{components} mixture components, periodicities {} (chosen on the most recent 25 % of the training data)",
                if periods.is_empty() {
                    "none".to_string()
                } else {
                    periods.join(", ")
                }
            )
        }
    }
}

/// The spectral set `P` of an FFT FreMEn model ([Krajník 2017] §III-B) as a table.
pub fn fft_components_table(m: &FftFremen) -> Table {
    let mut table = Table::new(["bin", "period", "amplitude |X|/N", "phase (rad)"]);
    for c in m.components() {
        table.row([
            c.bin.to_string(),
            period(m.period_of_bin(c.bin)),
            format!("{:.5}", c.amplitude),
            format!("{:+.3}", c.phase),
        ]);
    }
    table
}

/// The spectral set `P` of an FFT FreMEn model as JSON (the rows of [`fft_components_table`]).
pub fn fft_components_json(m: &FftFremen) -> Vec<Value> {
    m.components()
        .iter()
        .map(|c| {
            json!({
                "bin": c.bin,
                "period_secs": m.period_of_bin(c.bin),
                "amplitude": c.amplitude,
                "phase": c.phase,
            })
        })
        .collect()
}

/// What a model file holds, as `chronomap inspect` shows it.
#[derive(Clone, Debug)]
pub struct Inspection {
    /// The file, as named.
    pub file: String,
    /// The model it holds.
    pub model: AnyModel,
    /// Whether FreMEn models show their whole spectrum, not only the components in use.
    pub spectrum: bool,
}

impl Inspection {
    /// The report as `chronomap inspect` prints it.
    pub fn text(&self) -> String {
        let model = &self.model;
        let span = model.span();
        let mut lines = vec![
            format!("file:   {}", self.file),
            format!("model:  {} ({})", model.spec(), model.kind()),
        ];
        lines.push(if span.count > 0 {
            format!(
                "data:   {} observations, {} .. {} ({})",
                span.count,
                time(span.first),
                time(span.last),
                duration(span.duration())
            )
        } else {
            "data:   none (predicts 0.5)".to_string()
        });
        lines.extend(self.detail_lines(model));
        lines.join("\n")
    }

    /// What `model` holds, line by line (a calendar first, then its model of working days).
    fn detail_lines(&self, model: &AnyModel) -> Vec<String> {
        let mut out = Vec::new();
        match model {
            AnyModel::Mean(m) => out.push(format!("mean:   {:.6}", m.mean().unwrap_or(0.5))),
            AnyModel::Histogram(h) => {
                out.push(format!(
                    "bins:   {} over {}",
                    h.bins(),
                    period(h.period_secs())
                ));
                out.push(bin_table(h.period_secs(), &h.bin_means()));
            }
            AnyModel::Recent(h) => {
                out.push(format!(
                    "bins:   {} over {}, of the last {} periods ({} observations)",
                    h.bins(),
                    period(h.period_secs()),
                    h.cycles(),
                    h.window_count()
                ));
                out.push(bin_table(h.period_secs(), &h.bin_means()));
            }
            AnyModel::Fremen(m) => out.push(fremen_text(m, self.spectrum)),
            AnyModel::Persistence(m) => {
                out.push(match m.persistence_secs() {
                    Some(tau) => format!("persistence tau: {} (eq. 12)", duration(tau)),
                    None => "persistence tau: infinite (no change observed)".to_string(),
                });
                out.push(fremen_text(m.fremen(), self.spectrum));
            }
            AnyModel::Markov(m) => {
                out.push(format!(
                    "rates:  0->1 {:.3e}/s, 1->0 {:.3e}/s",
                    m.rate_up_per_sec(),
                    m.rate_down_per_sec()
                ));
                if let Some(pi) = m.stationary() {
                    out.push(format!("stationary p: {pi:.4}"));
                }
                if let Some((t, s)) = m.last_observation() {
                    out.push(format!("last observation: {s} at {}", time(t)));
                }
            }
            AnyModel::Pergam(m) => {
                let fit = m.fit();
                out.push(format!(
                    "period: {}, scale A = {:.4}, {} EM iterations",
                    period(m.config().period_secs),
                    fit.scale,
                    fit.iterations
                ));
                let mut table = Table::new(["weight", "mean (into period)", "sigma"]);
                for c in &fit.components {
                    table.row([
                        format!("{:.3}", c.weight),
                        duration(c.mean_secs),
                        duration(c.sigma_secs),
                    ]);
                }
                out.push(table.render());
            }
            AnyModel::Hypertime(m) => {
                let periods: Vec<String> = m.periods().iter().map(|&p| period(p)).collect();
                out.push(format!(
                    "{} mixture components over {} periodicities: {}",
                    m.components(),
                    m.periods().len(),
                    if periods.is_empty() {
                        "none (the mean)".to_string()
                    } else {
                        periods.join(", ")
                    }
                ));
            }
            AnyModel::Fft(m) => {
                let (start, step) = m.sampling();
                out.push(format!(
                    "series: {} samples every {step} s from {} (spectrum over the first {})",
                    m.len(),
                    time(start),
                    m.model_len()
                ));
                out.push(format!(
                    "gain:   {:.6}; outlier set: {} toggles; estimation error {:.4}",
                    m.gain(),
                    m.outlier_toggles().len(),
                    m.estimation_error()
                ));
                out.push(fft_components_table(m).render());
            }
            AnyModel::Calendar(m) => {
                out.push(calendar_line(m.days_off()));
                out.extend(self.detail_lines(m.model()));
            }
            AnyModel::Stack(m) => {
                out.push(
                    "a weighted average of these models (weights fitted by rolling-origin cross-validation):"
                        .to_string(),
                );
                let mut table = Table::new(["weight", "model"]);
                for (member, weight) in m.members() {
                    table.row([format!("{weight:.4}"), member.spec().to_string()]);
                }
                out.push(table.render());
            }
        }
        out
    }

    /// The report as `chronomap inspect --json` prints it.
    pub fn json(&self) -> Value {
        let model = &self.model;
        let span = model.span();
        let data = (span.count > 0).then(|| {
            json!({
                "observations": span.count,
                "first": span.first,
                "last": span.last,
                "duration_secs": span.duration(),
            })
        });
        let details = self.detail_json(model);
        json!({
            "file": self.file,
            "model": model.spec().to_string(),
            "kind": model.kind(),
            "data": data,
            "details": details,
        })
    }

    /// What `model` holds, as JSON (a calendar: its days off and its model's details).
    fn detail_json(&self, model: &AnyModel) -> Value {
        match model {
            AnyModel::Mean(m) => json!({"mean": m.mean().unwrap_or(0.5)}),
            AnyModel::Histogram(h) => json!({
                "bins": h.bins(),
                "period_secs": h.period_secs(),
                "bin_means": h.bin_means(),
                "bin_starts_secs": bin_starts(h.period_secs(), h.bins()),
            }),
            AnyModel::Recent(h) => json!({
                "bins": h.bins(),
                "period_secs": h.period_secs(),
                "cycles": h.cycles(),
                "window_observations": h.window_count(),
                "bin_means": h.bin_means(),
                "bin_starts_secs": bin_starts(h.period_secs(), h.bins()),
            }),
            AnyModel::Fremen(m) => json!({"fremen": fremen_json(m, self.spectrum)}),
            AnyModel::Persistence(m) => json!({
                "persistence_secs": m.persistence_secs(),
                "fremen": fremen_json(m.fremen(), self.spectrum),
            }),
            AnyModel::Markov(m) => json!({
                "rate_up_per_sec": m.rate_up_per_sec(),
                "rate_down_per_sec": m.rate_down_per_sec(),
                "stationary": m.stationary(),
                "last_observation": m.last_observation().map(|(t, s)| json!({"time": t, "state": s})),
            }),
            AnyModel::Pergam(m) => {
                let fit = m.fit();
                json!({
                    "period_secs": m.config().period_secs,
                    "scale": fit.scale,
                    "iterations": fit.iterations,
                    "components": fit.components.iter().map(|c| json!({
                        "weight": c.weight,
                        "mean_secs": c.mean_secs,
                        "sigma_secs": c.sigma_secs,
                    })).collect::<Vec<_>>(),
                })
            }
            AnyModel::Hypertime(m) => json!({
                "components": m.components(),
                "periods_secs": m.periods(),
            }),
            AnyModel::Fft(m) => {
                let (start, step) = m.sampling();
                json!({
                    "samples": m.len(),
                    "start": start,
                    "step_secs": step,
                    "model_len": m.model_len(),
                    "gain": m.gain(),
                    "outlier_toggles": m.outlier_toggles().len(),
                    "estimation_error": m.estimation_error(),
                    "components": fft_components_json(m),
                })
            }
            AnyModel::Calendar(m) => json!({
                "days_off": m.days_off().days().map(chronomap_core::time::format_date).collect::<Vec<_>>(),
                "model": m.model().spec().to_string(),
                "details": self.detail_json(m.model()),
            }),
            AnyModel::Stack(m) => json!({
                "members": m.members().map(|(member, weight)| json!({
                    "weight": weight,
                    "model": member.spec().to_string(),
                })).collect::<Vec<_>>(),
            }),
        }
    }
}

/// `days off: 8 (2016-01-01 .. 2016-12-27)`.
fn calendar_line(days_off: &DaysOff) -> String {
    let mut days = days_off.days();
    match (days.next(), days.last()) {
        (Some(first), last) => format!(
            "days off: {} ({} .. {}), predicted as the Sunday before",
            days_off.len(),
            chronomap_core::time::format_date(first),
            chronomap_core::time::format_date(last.unwrap_or(first))
        ),
        (None, _) => "days off: none".to_string(),
    }
}

/// Start of histogram bin `i` of `bins` over `period` seconds.
fn bin_start(period: f64, bins: usize, i: usize) -> f64 {
    period * i as f64 / bins as f64
}

/// Where each of `bins` bins of a period starts, in seconds.
fn bin_starts(period: f64, bins: usize) -> Vec<f64> {
    (0..bins).map(|i| bin_start(period, bins, i)).collect()
}

/// A histogram's bins: their number, start and mean (`-` for bins never seen).
fn bin_table(period: f64, means: &[Option<f64>]) -> String {
    let mut table = Table::new(["bin", "from", "mean"]);
    for (i, mean) in means.iter().enumerate() {
        table.row([
            i.to_string(),
            duration(bin_start(period, means.len(), i)),
            mean.map_or("-".into(), |m| format!("{m:.4}")),
        ]);
    }
    table.render()
}

/// The rows of a FreMEn table: the components in use, or the whole spectrum; and the periods
/// in use.
fn fremen_rows(m: &FremenModel, full: bool) -> (Vec<FrequencyComponent>, Vec<f64>) {
    let used: Vec<f64> = m.components().iter().map(|c| c.period_secs).collect();
    let rows = if full {
        m.spectrum()
    } else {
        m.components().to_vec()
    };
    (rows, used)
}

/// A FreMEn model's order and its components `|γ|`, `2|γ|` and phase ([Krajník 2017] eq. (10)).
fn fremen_text(m: &FremenModel, full: bool) -> String {
    let fit = m.fit();
    let mut table = Table::new(["period", "|gamma|", "cos amplitude", "phase (rad)", "used"]);
    let (rows, used) = fremen_rows(m, full);
    for c in rows {
        table.row([
            period(c.period_secs),
            format!("{:.5}", c.amplitude),
            format!("{:.5}", 2.0 * c.amplitude),
            format!("{:+.3}", c.phase),
            if used.contains(&c.period_secs) {
                "yes"
            } else {
                ""
            }
            .to_string(),
        ]);
    }
    format!(
        "FreMEn: order {} of {} candidate periods ({}), mean {:.6}\n{}",
        m.order(),
        m.max_order(),
        m.config().periods,
        fit.mean,
        table.render()
    )
}

fn fremen_json(m: &FremenModel, full: bool) -> Value {
    let (rows, used) = fremen_rows(m, full);
    json!({
        "order": m.order(),
        "max_order": m.max_order(),
        "periods": m.config().periods.to_string(),
        "mean": m.fit().mean,
        "components": rows.iter().map(|c| json!({
            "period_secs": c.period_secs,
            "amplitude": c.amplitude,
            "cos_amplitude": 2.0 * c.amplitude,
            "phase": c.phase,
            "used": used.contains(&c.period_secs),
        })).collect::<Vec<_>>(),
    })
}

/// The observations of a series that a model finds anomalous at a confidence level
/// ([`detect_anomalies`]).
#[derive(Clone, Debug)]
pub struct AnomalyReport {
    /// The model file, as named.
    pub model: String,
    /// Observations checked.
    pub observations: usize,
    /// The confidence level `c`.
    pub confidence: f64,
    /// The anomalies, in time order.
    pub anomalies: Vec<Anomaly>,
}

/// The observations of `series` that `model` (the file `name`) finds anomalous: observed 0
/// while `p ≥ confidence`, or 1 while `p < 1 − confidence`.
///
/// # Errors
/// A confidence level outside [0.5, 1].
pub fn anomalies(
    name: &str,
    model: &AnyModel,
    series: &TimeSeries,
    confidence: f64,
) -> Result<AnomalyReport, ConfigError> {
    Ok(AnomalyReport {
        model: name.to_string(),
        observations: series.len(),
        confidence,
        anomalies: detect_anomalies(model, &series.times, &series.values, confidence)?,
    })
}

impl AnomalyReport {
    /// The report as `chronomap anomalies --json` prints it.
    pub fn json(&self) -> Value {
        json!({
            "model": self.model,
            "observations": self.observations,
            "confidence": self.confidence,
            "anomalies": self.anomalies.iter().map(|a| json!({
                "time": a.time,
                "observed": a.observed,
                "p": a.predicted,
            })).collect::<Vec<_>>(),
        })
    }

    /// The report as `chronomap anomalies` prints it.
    pub fn text(&self) -> String {
        let c = self.confidence;
        let mut text = format!(
            "{} of {} observations are anomalous at confidence {c} (observed 0 while p >= {c}, or 1 while p < {:.3})",
            self.anomalies.len(),
            self.observations,
            1.0 - c
        );
        if !self.anomalies.is_empty() {
            let mut table = Table::new(["time", "observed", "p(t)"]);
            for a in &self.anomalies {
                table.row([
                    time(a.time),
                    a.observed.to_string(),
                    format!("{:.4}", a.predicted),
                ]);
            }
            text.push('\n');
            text.push_str(&table.render());
        }
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series(times: &[f64], values: &[f64]) -> TimeSeries {
        TimeSeries {
            times: times.to_vec(),
            values: values.to_vec(),
        }
    }

    #[test]
    fn the_mean_is_fitted_written_and_reported() {
        let dir = chronomap_testutil::fresh_dir(
            std::env::temp_dir().join(format!("chronomap-app-model-{}", std::process::id())),
        );
        // Three of four observations are 1: the mean model predicts 0.75.
        let training = Training {
            name: "door.txt".into(),
            json: json!({"file": "door.txt", "observations": 4}),
            series: series(&[0.0, 60.0, 120.0, 180.0], &[1.0, 1.0, 0.0, 1.0]),
        };
        let spec: ModelSpec = "mean".parse().unwrap();
        let output = dir.join("door.cmm");
        let report = fit(
            &training,
            &spec,
            &FitOptions::default(),
            &DaysOff::default(),
            &output,
        )
        .unwrap();
        assert_eq!(
            report.bytes as u64,
            std::fs::metadata(&output).unwrap().len()
        );
        assert_eq!(report.kind, "mean");
        assert_eq!(report.selection, None);
        assert_eq!(
            report.text(),
            format!(
                "fitted mean as mean on 4 observations of door.txt\nwrote {} ({} bytes)",
                output.display(),
                report.bytes
            )
        );
        assert_eq!(report.json()["train"]["observations"], 4);

        let model = chronomap_io::read_any_model(&output).unwrap();
        let inspection = Inspection {
            file: "door.cmm".into(),
            model: model.clone(),
            spectrum: false,
        };
        let text = inspection.text();
        assert!(text.ends_with("\nmean:   0.750000"), "{text}");
        assert_eq!(inspection.json()["details"]["mean"], 0.75);
        assert_eq!(inspection.json()["data"]["duration_secs"], 180.0);

        // At confidence 0.7 a 0 is anomalous (p = 0.75 ≥ 0.7), a 1 is not (p ≥ 0.3).
        let test = series(&[240.0, 300.0], &[0.0, 1.0]);
        let found = anomalies("door.cmm", &model, &test, 0.7).unwrap();
        assert_eq!(found.anomalies.len(), 1);
        assert_eq!(found.anomalies[0].time, 240.0);
        assert_eq!(
            found.text().lines().next().unwrap(),
            "1 of 2 observations are anomalous at confidence 0.7 (observed 0 while p >= 0.7, or 1 while p < 0.300)"
        );
        assert!(anomalies("door.cmm", &model, &test, 0.4).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_bad_observation_is_named_under_the_model() {
        let training = Training {
            name: "door.txt".into(),
            json: Value::Null,
            series: series(&[10.0, 5.0], &[1.0, 0.0]),
        };
        let spec: ModelSpec = "fremen:2".parse().unwrap();
        let error = fit(
            &training,
            &spec,
            &FitOptions::default(),
            &DaysOff::default(),
            Path::new("/nonexistent/never.cmm"),
        )
        .unwrap_err();
        assert_eq!(error.to_string(), "cannot fit fremen:2");
        let cause = std::error::Error::source(&error).unwrap().to_string();
        assert!(cause.starts_with("door.txt: observation 2: "), "{cause}");
    }

    #[test]
    fn orders_and_selections_read_as_one_line() {
        assert_eq!(errors_by_order(&[0.25, 0.125]), "0:0.2500 1:0.1250");
        let hypertime = Selection::Hypertime {
            periods: vec![86_400.0, 604_800.0],
            components: 3,
        };
        assert_eq!(
            describe_selection(&hypertime),
            "3 mixture components, periodicities 24 h, 1 week (chosen on the most recent 25 % of the training data)"
        );
    }
}
