//! A deployable loop classifier: the descriptor, the pair features, the boosted model and the
//! threshold `p_min`, as one value that is trained, saved, checked on load and applied to
//! pairs of scans ([Stüde 2024] §3.2.1).
//!
//! Two configurations:
//! * [`ClassifierConfig::paper`] — the dissertation's: the 41 pair values of
//!   [`compare`], AdaBoost with decision stumps, trained on all
//!   loop pairs and as many random non-loops;
//! * [`ClassifierConfig::extended`] — ours (the default of `chronomap lidar`): the 41 values
//!   and the three heading-tolerant [profile](crate::profile) features, boosted depth-2
//!   trees, all pairs with class weights. On the Málaga keyframes it finds 3–5 times more loops
//!   at a false-positive rate below 1 % (`docs/lidar.md`).
//!
//! ```
//! use chronomap_lidar::Scan2d;
//! use chronomap_lidar::classifier::{ClassifierConfig, LoopClassifier};
//! use chronomap_lidar::evaluation::LabelledPair;
//!
//! // Corridors of different widths: a corridor and itself a little further on are a loop.
//! let corridor = |w: f64, shift: f64| {
//!     let ranges = (0..181).map(|k| {
//!         let a = -1.5 + k as f64 * 3.0 / 180.0;
//!         (w / a.sin().abs().max(1e-3)).min(30.0 + shift)
//!     });
//!     Scan2d::new(0.0, -1.5, 1.5, 80.0, ranges.collect())
//! };
//! let mut scans = Vec::new();
//! let mut pairs = Vec::new();
//! for k in 0..12 {
//!     let w = 1.0 + 0.4 * k as f64;
//!     scans.push(corridor(w, 0.0)?);
//!     scans.push(corridor(w, 1.0)?);
//!     pairs.push(LabelledPair { i: 2 * k, j: 2 * k + 1, positive: true, distance: 1.0 });
//!     if k > 0 {
//!         pairs.push(LabelledPair { i: 2 * k - 2, j: 2 * k + 1, positive: false, distance: 20.0 });
//!     }
//! }
//! let config = ClassifierConfig::extended();
//! let features = config.features(&scans)?;
//! let classifier = LoopClassifier::train(&config, &features, &pairs, 0.5, 0.01)?;
//! let p = classifier.probability(&features[0], &features[1])?;
//! assert!(p > 0.5, "{p}");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use serde::{Deserialize, Serialize};

use crate::Scan2d;
use crate::adaboost::AdaBoostParams;
use crate::descriptor::{Descriptor, DescriptorError, DescriptorParams, compare, describe_scan};
use crate::evaluation::{
    Balance, Candidate, CvParams, CvReport, EvalError, LabelParams, LabelledPair, LoopModel,
    NestedParams, PairModels, WeakLearner, cross_validate, nested_cross_validate,
};
use crate::profile::{ProfileParams, RangeProfile, compare_extended, range_profile};

/// The model-file kind of a saved [`LoopClassifier`].
pub const MODEL_KIND: &str = "lidar-loops";

/// How a classifier is built: features, weak learner, balancing, rounds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ClassifierConfig {
    /// The descriptor of each scan.
    pub descriptor: DescriptorParams,
    /// The profile features appended to the pair vector, if any (our extension).
    pub profile: Option<ProfileParams>,
    /// The weak learner.
    pub learner: WeakLearner,
    /// The balancing of the training pairs.
    pub balance: Balance,
    /// Boosting rounds `T` (50, [Stüde 2024] §3.2.1).
    pub rounds: usize,
    /// Seed of the balanced subsets.
    pub seed: u64,
}

impl ClassifierConfig {
    /// The dissertation's classifier: 41 pair values, stumps, subsampled non-loops, `T = 50`.
    pub fn paper() -> ClassifierConfig {
        ClassifierConfig {
            descriptor: DescriptorParams::default(),
            profile: None,
            learner: WeakLearner::Stump,
            balance: Balance::Subsample,
            rounds: 50,
            seed: 1,
        }
    }

    /// Ours: 44 pair values (the profile features added), depth-2 trees, class weights,
    /// `T = 50`.
    pub fn extended() -> ClassifierConfig {
        ClassifierConfig {
            profile: Some(ProfileParams::default()),
            learner: WeakLearner::Depth2,
            balance: Balance::Weighted,
            ..ClassifierConfig::paper()
        }
    }

    /// Checks the parameters.
    ///
    /// # Errors
    /// [`DescriptorError::Param`] for bad descriptor or profile parameters or no rounds.
    pub fn validate(&self) -> Result<(), DescriptorError> {
        self.descriptor.validate()?;
        if let Some(p) = &self.profile {
            p.validate()?;
        }
        if self.rounds == 0 {
            return Err(DescriptorError::Param {
                field: "rounds",
                value: 0.0,
            });
        }
        Ok(())
    }

    /// What the classifier needs of each scan.
    ///
    /// # Errors
    /// As [`describe_scan`] and [`range_profile`]; the error does not say which scan (the
    /// caller knows).
    pub fn scan_features(&self, scan: &Scan2d) -> Result<ScanFeatures, DescriptorError> {
        Ok(ScanFeatures {
            descriptor: describe_scan(scan, &self.descriptor)?,
            profile: match &self.profile {
                Some(p) => Some(range_profile(scan, p)?),
                None => None,
            },
        })
    }

    /// [`ClassifierConfig::scan_features`] of every scan.
    ///
    /// # Errors
    /// [`EvalError::Input`] naming the first scan that fails.
    pub fn features(&self, scans: &[Scan2d]) -> Result<Vec<ScanFeatures>, EvalError> {
        scans
            .iter()
            .enumerate()
            .map(|(k, s)| {
                self.scan_features(s)
                    .map_err(|e| EvalError::Input(format!("scan {}: {e}", k + 1)))
            })
            .collect()
    }

    /// The pair vector of two scans' features (41 or 44 values).
    ///
    /// # Errors
    /// As [`compare`] and [`compare_extended`]; [`DescriptorError::Mismatch`] if a profile
    /// is missing.
    pub fn pair(&self, a: &ScanFeatures, b: &ScanFeatures) -> Result<Vec<f64>, DescriptorError> {
        match (&self.profile, &a.profile, &b.profile) {
            (None, _, _) => Ok(compare(&a.descriptor, &b.descriptor)?.to_vec()),
            (Some(p), Some(pa), Some(pb)) => {
                Ok(compare_extended((&a.descriptor, pa), (&b.descriptor, pb), p)?.to_vec())
            }
            _ => Err(DescriptorError::Mismatch(
                "the classifier needs range profiles of both scans",
            )),
        }
    }

    /// The pair vectors of `pairs`.
    ///
    /// # Errors
    /// [`EvalError::Input`] naming the first pair that fails or indexes no scan.
    pub fn pair_rows(
        &self,
        features: &[ScanFeatures],
        pairs: &[LabelledPair],
    ) -> Result<Vec<Vec<f64>>, EvalError> {
        pairs
            .iter()
            .map(|p| match (features.get(p.i), features.get(p.j)) {
                (Some(a), Some(b)) => self
                    .pair(a, b)
                    .map_err(|e| EvalError::Input(format!("pair ({}, {}): {e}", p.i, p.j))),
                _ => Err(EvalError::Input(format!(
                    "pair ({}, {}) names a scan beyond the {}",
                    p.i,
                    p.j,
                    features.len()
                ))),
            })
            .collect()
    }
}

impl ClassifierConfig {
    /// Whether this is the dissertation's procedure (41 values, stumps, subsampled
    /// non-loops), whatever its rounds and seed.
    pub fn is_paper(&self) -> bool {
        self.profile.is_none()
            && self.learner == WeakLearner::Stump
            && self.balance == Balance::Subsample
    }

    /// Keyframe-disjoint cross-validation of this configuration over the folds `fold_of`
    /// (`rows[k]` the pair vector of `pairs[k]`): the paper's procedure as [`cross_validate`]
    /// runs it, any other configuration as [`nested_cross_validate`] with it as the only
    /// candidate (nothing to choose).
    ///
    /// # Errors
    /// As those two.
    pub fn cross_validate<R: AsRef<[f64]>>(
        &self,
        pairs: &[LabelledPair],
        rows: &[R],
        fold_of: &[usize],
        max_fpr: f64,
        seed: u64,
    ) -> Result<CvReport, EvalError> {
        if self.is_paper() {
            let params = CvParams {
                seed,
                max_fpr,
                adaboost: AdaBoostParams {
                    rounds: self.rounds,
                },
            };
            return cross_validate(pairs, rows, fold_of, &params);
        }
        let candidate = Candidate {
            name: "configured".into(),
            train_pairs: pairs,
            train_x: rows,
            score_x: rows,
            learner: self.learner,
            balance: self.balance,
        };
        let params = NestedParams {
            rounds: vec![self.rounds],
            max_fpr,
            seed,
        };
        Ok(nested_cross_validate(pairs, &[candidate], fold_of, &params)?.report)
    }

    /// The models that score any pair without having seen its keyframes
    /// ([`PairModels::train_with`] with this configuration; `done` after each fold pair).
    ///
    /// # Errors
    /// As [`PairModels::train_with`].
    pub fn pair_models<R: AsRef<[f64]>>(
        &self,
        pairs: &[LabelledPair],
        rows: &[R],
        fold_of: &[usize],
        done: &mut dyn FnMut(),
    ) -> Result<PairModels, EvalError> {
        PairModels::train_with(
            pairs,
            rows,
            fold_of,
            self.learner,
            self.balance,
            self.rounds,
            self.seed,
            done,
        )
    }
}

/// The descriptor of one scan and, for the extended classifier, its range profile.
#[derive(Clone, Debug, PartialEq)]
pub struct ScanFeatures {
    /// `χ`.
    pub descriptor: Descriptor,
    /// The profile (extended classifier only).
    pub profile: Option<RangeProfile>,
}

/// A trained loop classifier with its threshold.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LoopClassifier {
    /// How it was built.
    pub config: ClassifierConfig,
    /// The boosted model.
    pub model: LoopModel,
    /// Pairs whose loop probability exceeds this are loops.
    pub p_min: f64,
    /// The false-positive bound `p_min` was chosen for.
    pub max_fpr: f64,
    /// How its training pairs were labelled, if known.
    pub labels: Option<LabelParams>,
    /// Its training pairs: loops, non-loops.
    pub trained_on: (usize, usize),
}

impl LoopClassifier {
    /// Trains the model of `config` on every pair of `pairs` (features of the scans in
    /// `features`), with the threshold `p_min` chosen elsewhere (by cross-validation).
    ///
    /// # Errors
    /// [`EvalError::Input`] for bad parameters, a threshold or bound outside `[0, 1]`, or a
    /// pair without scans; [`EvalError::Train`] if training fails (one class only).
    pub fn train(
        config: &ClassifierConfig,
        features: &[ScanFeatures],
        pairs: &[LabelledPair],
        p_min: f64,
        max_fpr: f64,
    ) -> Result<LoopClassifier, EvalError> {
        config
            .validate()
            .map_err(|e| EvalError::Input(e.to_string()))?;
        let rows = config.pair_rows(features, pairs)?;
        let model = LoopModel::train(
            pairs,
            &rows,
            |_| true,
            config.learner,
            config.balance,
            config.rounds,
            config.seed,
        )?;
        let positives = pairs.iter().filter(|p| p.positive).count();
        let classifier = LoopClassifier {
            config: config.clone(),
            model,
            p_min,
            max_fpr,
            labels: None,
            trained_on: (positives, pairs.len() - positives),
        };
        classifier.validate()?;
        Ok(classifier)
    }

    /// Checks the invariants (for classifiers read from files): valid parameters and model,
    /// a model of the configuration's learner, `p_min` and `max_fpr` in `[0, 1]`.
    ///
    /// # Errors
    /// [`EvalError::Input`] saying what is wrong.
    pub fn validate(&self) -> Result<(), EvalError> {
        let bad = |why: String| Err(EvalError::Input(why));
        if let Err(e) = self.config.validate() {
            return bad(e.to_string());
        }
        let width = crate::descriptor::PAIR_FEATURES
            + self
                .config
                .profile
                .as_ref()
                .map_or(0, |_| crate::profile::PROFILE_FEATURES);
        let (ok_kind, n_features) = match &self.model {
            LoopModel::Stumps(m) => {
                m.validate()?;
                (self.config.learner == WeakLearner::Stump, m.n_features)
            }
            LoopModel::Depth2(m) => {
                m.validate()?;
                (self.config.learner == WeakLearner::Depth2, m.n_features)
            }
        };
        if !ok_kind {
            return bad("the model is not of the configured weak learner".into());
        }
        if n_features != width {
            return bad(format!(
                "the model takes {n_features} pair values, the configuration makes {width}"
            ));
        }
        if !(0.0..=1.0).contains(&self.p_min) || !(0.0..=1.0).contains(&self.max_fpr) {
            return bad(format!(
                "p_min {} and max_fpr {} must lie in [0, 1]",
                self.p_min, self.max_fpr
            ));
        }
        Ok(())
    }

    /// The loop probability of two scans.
    ///
    /// # Errors
    /// As [`ClassifierConfig::pair`] and the model's probability.
    pub fn probability(&self, a: &ScanFeatures, b: &ScanFeatures) -> Result<f64, EvalError> {
        let x = self
            .config
            .pair(a, b)
            .map_err(|e| EvalError::Input(e.to_string()))?;
        self.model.probability(&x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn corridor(w: f64) -> Scan2d {
        let ranges = (0..181)
            .map(|k| {
                let a = -1.5 + k as f64 * 3.0 / 180.0;
                (w / a.sin().abs().max(1e-3)).min(30.0)
            })
            .collect();
        Scan2d::new(0.0, -1.5, 1.5, 80.0, ranges).unwrap()
    }

    fn trained(config: &ClassifierConfig) -> (LoopClassifier, Vec<ScanFeatures>) {
        let scans: Vec<Scan2d> = (0..16)
            .flat_map(|k| {
                [
                    corridor(1.0 + 0.3 * k as f64),
                    corridor(1.02 + 0.3 * k as f64),
                ]
            })
            .collect();
        let features = config.features(&scans).unwrap();
        let mut pairs = Vec::new();
        for k in 0..16 {
            pairs.push(LabelledPair {
                i: 2 * k,
                j: 2 * k + 1,
                positive: true,
                distance: 0.5,
            });
            for m in (0..16usize).filter(|&m| m.abs_diff(k) > 3) {
                pairs.push(LabelledPair {
                    i: 2 * k,
                    j: 2 * m + 1,
                    positive: false,
                    distance: 20.0,
                });
            }
        }
        let c = LoopClassifier::train(config, &features, &pairs, 0.6, 0.01).unwrap();
        (c, features)
    }

    #[test]
    fn both_configurations_tell_a_place_from_another() {
        for config in [ClassifierConfig::paper(), ClassifierConfig::extended()] {
            let (c, f) = trained(&config);
            assert_eq!(c.trained_on.0, 16);
            assert!(c.probability(&f[4], &f[5]).unwrap() > 0.5);
            assert!(c.probability(&f[4], &f[25]).unwrap() < 0.5);
            c.validate().unwrap();
        }
    }

    #[test]
    fn inconsistent_classifiers_are_refused() {
        let (mut c, f) = trained(&ClassifierConfig::extended());
        c.p_min = 1.5;
        assert!(c.validate().unwrap_err().to_string().contains("p_min 1.5"));
        c.p_min = 0.6;
        // A model of 44 values with the paper's 41-value configuration.
        c.config.profile = None;
        c.config.learner = WeakLearner::Depth2;
        let e = c.validate().unwrap_err().to_string();
        assert!(
            e.contains("takes 44 pair values") && e.contains("makes 41"),
            "{e}"
        );
        // Features without a profile cannot be scored by the extended classifier.
        let (c, _) = trained(&ClassifierConfig::extended());
        let bare = ScanFeatures {
            descriptor: f[0].descriptor.clone(),
            profile: None,
        };
        assert!(c.probability(&bare, &bare).is_err());
    }
}
