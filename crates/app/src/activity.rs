//! Maps of human activity ([Stüde 2024] chapter 4) as the faces use them: a model file opened
//! by its content ([`open_activity_model`]: CoPA-Map or Log-AM, by the kind its header names)
//! and the baselines' settings from the few numbers the command line takes
//! ([`baseline_config`]).

use std::path::Path;

use chronomap_activity::{
    AnyActivityModel, BaselineConfig, FrAamConfig, GpHomConfig, LogAdditive, LogAdditiveConfig,
    WhyteConfig,
};
use chronomap_core::Parallelism;
use chronomap_io::model_file::ModelFileError;
use chronomap_io::{LOG_ADDITIVE_KIND, read_copa_map, read_model_file};
use thiserror::Error;

use crate::open::FileKind;

/// Why an activity model file cannot be opened.
#[derive(Debug, Error)]
pub enum OpenActivityError {
    /// The container or its payload is wrong (as [`chronomap_io::read_model_file`] and
    /// [`chronomap_io::read_copa_map`] say).
    #[error(transparent)]
    ModelFile(#[from] ModelFileError),
    /// A Log-AM whose invariants do not hold.
    #[error("{path}: an inconsistent Log-AM: {reason}")]
    InconsistentLogAdditive {
        /// The file.
        path: String,
        /// The broken invariant.
        reason: String,
    },
}

/// The activity model in `path`: Log-AM if the header names [`LOG_ADDITIVE_KIND`], else
/// CoPA-Map (whose reader names what is wrong with anything else), each checked.
///
/// # Errors
/// [`OpenActivityError`].
pub fn open_activity_model(path: &Path) -> Result<AnyActivityModel, OpenActivityError> {
    let log_additive =
        FileKind::of(path).is_ok_and(|kind| kind.model_kind() == Some(LOG_ADDITIVE_KIND));
    if !log_additive {
        return Ok(AnyActivityModel::Copa(Box::new(read_copa_map(path)?)));
    }
    let (_, model): (String, LogAdditive) = read_model_file(path)?;
    model
        .check()
        .map_err(|e| OpenActivityError::InconsistentLogAdditive {
            path: path.display().to_string(),
            reason: e.to_string(),
        })?;
    Ok(AnyActivityModel::LogAdditive(model))
}

/// The baselines' settings ([Stüde 2024] §4.3.2) from the command line's numbers: Fr-AAM's
/// base period, GP-Hom trained like CoPA-Map (day period, inducing points, iterations) and
/// WHyTe on the threads `parallelism` allows, Log-AM with the day `period`.
pub fn baseline_config(
    period: f64,
    inducing: usize,
    iterations: usize,
    parallelism: Parallelism,
) -> BaselineConfig {
    BaselineConfig {
        fr_aam: FrAamConfig {
            period,
            ..FrAamConfig::default()
        },
        gp_hom: GpHomConfig {
            inducing,
            iterations,
            day_period: period,
            parallelism,
            ..GpHomConfig::default()
        },
        whyte: WhyteConfig {
            day_period: period,
            parallelism,
            ..WhyteConfig::default()
        },
        log_additive: LogAdditiveConfig {
            period,
            ..LogAdditiveConfig::default()
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronomap_activity::RateSamples;

    fn log_additive() -> LogAdditive {
        let mut samples = RateSamples::default();
        for t in 0..48 {
            samples.push([0.25, 0.25], f64::from(t), 10.0).unwrap();
            samples.push([0.75, 0.25], f64::from(t), 1.0).unwrap();
        }
        let config = LogAdditiveConfig {
            period: 12.0,
            ..LogAdditiveConfig::default()
        };
        LogAdditive::fit(&samples, &config).unwrap()
    }

    #[test]
    fn opens_log_am_by_its_header_and_refuses_other_kinds_as_copa_maps() {
        let dir = chronomap_testutil::fresh_dir(
            std::env::temp_dir().join(format!("chronomap-app-activity-{}", std::process::id())),
        );
        let model = log_additive();
        // The name says nothing: the header does.
        let path = dir.join("model.bin");
        chronomap_io::write_model_file(&path, LOG_ADDITIVE_KIND, &model).unwrap();
        let opened = open_activity_model(&path).unwrap();
        assert!(matches!(&opened, AnyActivityModel::LogAdditive(m) if *m == model));
        assert_eq!(opened.domain(), [0.25, 0.25, 0.75, 0.25]);

        let other = dir.join("other.cmm");
        chronomap_io::write_model_file(&other, "fremen", &1u8).unwrap();
        let error = open_activity_model(&other).unwrap_err().to_string();
        assert_eq!(
            error,
            format!(
                "{}: the payload of kind \"fremen\" does not decode as the requested model \
                 type: Hit the end of buffer, expected more data",
                other.display()
            )
        );
        let missing = dir.join("missing");
        let error = open_activity_model(&missing).unwrap_err();
        assert!(matches!(error, OpenActivityError::ModelFile(_)), "{error}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
