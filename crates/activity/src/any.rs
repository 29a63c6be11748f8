//! Any activity model a model file holds, behind one interface: CoPA-Map ([Stüde 2024] §4.2,
//! [`CopaMap`]) or Log-AM ([`LogAdditive`]).
//!
//! The command line asks the same questions of either (its training square, the rate and its
//! uncertainty at points of space × time); [`AnyActivityModel`] answers them once, as
//! `chronomap_grid::AnyGrid` does for grids, so no face matches on what was stored.
//!
//! ```
//! use chronomap_activity::{AnyActivityModel, LogAdditive, LogAdditiveConfig, RateSamples};
//! use chronomap_core::Parallelism;
//!
//! // Two cells over four days of 12 hour bins: the first busy, the second quiet.
//! let mut samples = RateSamples::default();
//! for t in 0..48 {
//!     samples.push([0.25, 0.25], f64::from(t), 10.0)?;
//!     samples.push([0.75, 0.25], f64::from(t), 1.0)?;
//! }
//! let config = LogAdditiveConfig { period: 12.0, ..LogAdditiveConfig::default() };
//! let model = AnyActivityModel::LogAdditive(LogAdditive::fit(&samples, &config)?);
//! assert_eq!(model.domain(), [0.25, 0.25, 0.75, 0.25]);
//! let (mean, std) = model.predict(&[([0.25, 0.25], 48.0), ([0.75, 0.25], 48.0)], Parallelism::Sequential)?;
//! assert!((mean[0] - 10.0).abs() < 1e-6 && (mean[1] - 1.0).abs() < 1e-6);
//! assert_eq!(std.len(), 2);
//! # Ok::<(), chronomap_activity::ActivityError>(())
//! ```

use chronomap_core::Parallelism;

use crate::{ActivityError, CopaMap, LogAdditive};

/// What an activity-model file holds: CoPA-Map or Log-AM.
#[derive(Clone, Debug)]
pub enum AnyActivityModel {
    /// CoPA-Map ([Stüde 2024] §4.2): heteroscedastic sparse GPs over space × time.
    Copa(Box<CopaMap>),
    /// Log-AM: ln(1 + rate) as a level per cell, a profile of the day and their interaction.
    LogAdditive(LogAdditive),
}

impl AnyActivityModel {
    /// The training square `[x1_min, x2_min, x1_max, x2_max]` of the cell centres.
    pub fn domain(&self) -> [f64; 4] {
        match self {
            AnyActivityModel::Copa(m) => m.domain(),
            AnyActivityModel::LogAdditive(m) => m.domain(),
        }
    }

    /// The predicted rate (people per hour) and its standard deviation at every `(x, t)` of
    /// `points`; CoPA-Map computes on the threads `parallelism` allows (the results do not
    /// depend on it), Log-AM on the calling thread.
    ///
    /// # Errors
    /// [`ActivityError::Gp`] for CoPA-Map's non-finite inputs.
    pub fn predict(
        &self,
        points: &[([f64; 2], f64)],
        parallelism: Parallelism,
    ) -> Result<(Vec<f64>, Vec<f64>), ActivityError> {
        match self {
            AnyActivityModel::Copa(m) => Ok(m.predict_with_std(points, parallelism)?),
            AnyActivityModel::LogAdditive(m) => Ok(points
                .iter()
                .map(|&(x, t)| m.predict_with_std(x, t))
                .unzip()),
        }
    }
}
