//! Discrete AdaBoost (SAMME, two classes) with decision stumps: the loop classifier of
//! [Granström 2009] that [Stüde 2024] §3.2.1 trains with `T = 50` rounds.
//!
//! ```
//! use chronomap_lidar::adaboost::{AdaBoost, AdaBoostParams};
//!
//! // Two features; the class is "feature 1 above 0.5".
//! let x = [[0.3, 0.1], [0.9, 0.2], [0.1, 0.7], [0.5, 0.9], [0.2, 0.4], [0.8, 0.6]];
//! let y = [false, false, true, true, false, true];
//! let model = AdaBoost::fit(&x, &y, None, &AdaBoostParams::default())?;
//! // One stump separates them: feature 1 at the midpoint 0.5 of 0.4 and 0.6.
//! assert_eq!((model.stumps[0].feature, model.stumps[0].threshold), (Some(1), 0.5));
//! assert!(model.predict(&[0.0, 0.8])?);
//! assert!(model.probability(&[0.0, 0.8])? > 0.85); // 1/(1 + e^-2), the most a vote gives
//! # Ok::<(), chronomap_lidar::adaboost::AdaBoostError>(())
//! ```
//!
//! # Algorithm
//! AdaBoost [Freund & Schapire 1997] in the SAMME form of Zhu, Zou, Rosset & Hastie (2009),
//! which for two classes is discrete AdaBoost; written to follow scikit-learn 1.9's
//! `AdaBoostClassifier(estimator=DecisionTreeClassifier(max_depth=1))` step for step, so that
//! it can be checked against it (`crates/lidar/tests/it/sklearn_adaboost.rs`):
//! 1. Sample weights `w_i` (uniform `1/n` or given), normalised to sum 1.
//! 2. Each round `t`: weights below machine epsilon are raised to it (zero weights stay
//!    zero); the stump minimising the weighted Gini impurity is fitted; its weighted error is
//!    `ε_t = Σ w_i [h_t(x_i) ≠ y_i] / Σ w_i`. If `ε_t = 0` the stump is kept with weight 1
//!    and boosting stops; if `ε_t ≥ 1/2` it is dropped and boosting stops (an error in the
//!    first round). Otherwise its weight is `α_t = ln((1 − ε_t)/ε_t)`, the weights of the
//!    misclassified samples are multiplied by `e^{α_t}` (as `exp(ln w + α_t)`) and all are
//!    normalised.
//! 3. The decision function is `f(x) = 2 Σ_t α_t h_t(x) / Σ_t α_t` with `h_t ∈ {−1, +1}`
//!    (in `[−2, 2]`); the probability of a loop is `p = 1/(1 + e^{−f})` (scikit-learn's
//!    `predict_proba`, in `[0.119, 0.881]`); the class is `f > 0`.
//!
//! A stump splits on the feature and threshold whose two sides have the least weighted Gini
//! impurity (the largest `−W_l·G_l − W_r·G_r`, ties kept by the first feature and the
//! smallest threshold); thresholds lie midway between successive distinct values, values
//! closer than `1e-7` are not split apart, and each side predicts its weighted majority
//! (class 0 on a tie), all as scikit-learn's `BestSplitter`. scikit-learn visits the features
//! in a random order and reads `X` as `float32`, so it agrees exactly on data that
//! `float32` represents and where no two features tie.
//!
//! [Granström 2009]: K. Granström, J. Callmer, F. Ramos, J. Nieto, "Learning to detect loop
//! closure from range data", ICRA 2009.
//! [Stüde 2024]: M. Stüde, dissertation, Hannover 2024.

use serde::{Deserialize, Serialize};

/// The `kind` of AdaBoost model files (`chronomap_io::model_file`).
pub const MODEL_KIND: &str = "lidar-adaboost";
/// The most training samples [`AdaBoost::fit`] takes.
pub const MAX_SAMPLES: usize = 10_000_000;
/// The most features a sample may have.
pub const MAX_FEATURES: usize = 100_000;
/// The most boosting rounds.
pub const MAX_ROUNDS: usize = 100_000;
/// Values closer than this are not split apart (scikit-learn's `FEATURE_THRESHOLD`).
pub const FEATURE_THRESHOLD: f64 = 1e-7;

/// Why a classifier cannot be trained, used or loaded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AdaBoostError {
    /// No samples, or more than [`MAX_SAMPLES`].
    #[error("training needs 1 to {MAX_SAMPLES} samples, got {0}")]
    SampleCount(usize),
    /// Samples of different lengths, or of no or more than [`MAX_FEATURES`] features.
    #[error("sample {index} has {found} features, expected {expected} (1 to {MAX_FEATURES})")]
    FeatureCount {
        /// The sample.
        index: usize,
        /// Its number of features.
        found: usize,
        /// The expected number.
        expected: usize,
    },
    /// A feature value is NaN or infinite.
    #[error("sample {index}, feature {feature}: {value} is not finite")]
    NonFinite {
        /// The sample.
        index: usize,
        /// The feature.
        feature: usize,
        /// The value.
        value: f64,
    },
    /// Labels and samples (or weights and samples) differ in number.
    #[error("{what}: {found} values for {samples} samples")]
    Length {
        /// `labels` or `weights`.
        what: &'static str,
        /// Their number.
        found: usize,
        /// The number of samples.
        samples: usize,
    },
    /// A weight is negative or not finite, or all are zero.
    #[error("weights: {0}")]
    Weights(&'static str),
    /// The training data (with positive weight) hold only one class.
    #[error("training needs both classes, the data hold only {0}")]
    OneClass(&'static str),
    /// The first stump is no better than chance.
    #[error("the first stump has weighted error {0} >= 0.5: nothing to boost")]
    WorseThanChance(f64),
    /// A parameter is out of range.
    #[error("rounds: {0} is not in 1..={MAX_ROUNDS}")]
    Rounds(usize),
    /// A loaded model breaks its invariants.
    #[error("invalid model: {0}")]
    Invalid(&'static str),
}

/// Training parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AdaBoostParams {
    /// Boosting rounds `T` (50, as Granström & Schön recommend; [Stüde 2024] §3.2.1).
    pub rounds: usize,
}

impl Default for AdaBoostParams {
    fn default() -> Self {
        AdaBoostParams { rounds: 50 }
    }
}

/// A decision stump: class `below` if `x[feature] <= threshold`, else `above`; a stump
/// without a feature (no split possible) predicts `below` everywhere.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Stump {
    /// The feature split on, if any.
    pub feature: Option<usize>,
    /// The threshold.
    pub threshold: f64,
    /// The class at or below the threshold.
    pub below: bool,
    /// The class above the threshold.
    pub above: bool,
}

impl Stump {
    /// The stump's class for `x`.
    pub fn predict(&self, x: &[f64]) -> bool {
        match self.feature {
            Some(f) if x[f] > self.threshold => self.above,
            _ => self.below,
        }
    }
}

/// A trained AdaBoost classifier.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AdaBoost {
    /// Number of features a sample has.
    pub n_features: usize,
    /// The weak classifiers, in training order.
    pub stumps: Vec<Stump>,
    /// Their weights `α_t`.
    pub alphas: Vec<f64>,
    /// The weighted training error `ε_t` of each round.
    pub errors: Vec<f64>,
}

impl AdaBoost {
    /// Trains on rows `x` with labels `y` (true: a loop) and optional sample weights.
    ///
    /// # Errors
    /// An [`AdaBoostError`] for empty or ragged data, non-finite values, bad weights, a single
    /// class, a first stump no better than chance or bad parameters.
    pub fn fit<R: AsRef<[f64]>>(
        x: &[R],
        y: &[bool],
        weights: Option<&[f64]>,
        params: &AdaBoostParams,
    ) -> Result<AdaBoost, AdaBoostError> {
        let (n_features, stumps, alphas, errors) =
            samme(x, y, weights, params, fit_stump, Stump::predict)?;
        Ok(AdaBoost {
            n_features,
            stumps,
            alphas,
            errors,
        })
    }

    /// The classifier of the first `rounds` rounds (all if there are fewer). Boosting round
    /// `t` does not depend on later rounds, so this is exactly the model that training with
    /// `T = rounds` gives — one fit at the largest `T` serves every smaller `T`.
    pub fn truncated(&self, rounds: usize) -> AdaBoost {
        let (stumps, alphas, errors) =
            first_rounds(&self.stumps, &self.alphas, &self.errors, rounds);
        AdaBoost {
            n_features: self.n_features,
            stumps,
            alphas,
            errors,
        }
    }

    /// Checks the invariants (for decoded models): at least one stump, as many weights,
    /// features in range, finite thresholds, positive finite weights, errors in `[0, 1/2)`.
    pub fn validate(&self) -> Result<(), AdaBoostError> {
        if self.n_features == 0 || self.n_features > MAX_FEATURES {
            return Err(AdaBoostError::Invalid("n_features out of range"));
        }
        if self.stumps.is_empty() || self.stumps.len() > MAX_ROUNDS {
            return Err(AdaBoostError::Invalid("no stump or too many"));
        }
        if self.alphas.len() != self.stumps.len() || self.errors.len() != self.stumps.len() {
            return Err(AdaBoostError::Invalid(
                "stumps, alphas and errors differ in number",
            ));
        }
        for s in &self.stumps {
            if s.feature.is_some_and(|f| f >= self.n_features) {
                return Err(AdaBoostError::Invalid("a stump's feature is out of range"));
            }
            if !s.threshold.is_finite() {
                return Err(AdaBoostError::Invalid("a stump's threshold is not finite"));
            }
        }
        if self.alphas.iter().any(|a| !(a.is_finite() && *a > 0.0)) {
            return Err(AdaBoostError::Invalid(
                "a weight is not positive and finite",
            ));
        }
        if self.errors.iter().any(|e| !(*e >= 0.0 && *e < 0.5)) {
            return Err(AdaBoostError::Invalid("an error is outside [0, 0.5)"));
        }
        Ok(())
    }

    fn check(&self, x: &[f64]) -> Result<(), AdaBoostError> {
        check_sample(self.n_features, x)
    }

    /// The decision function `f(x) = 2 Σ α_t h_t(x) / Σ α_t` in `[−2, 2]` (positive: a loop).
    ///
    /// # Errors
    /// [`AdaBoostError::FeatureCount`] for a sample of the wrong length,
    /// [`AdaBoostError::NonFinite`] for a NaN feature.
    pub fn decision(&self, x: &[f64]) -> Result<f64, AdaBoostError> {
        self.check(x)?;
        Ok(vote(&self.stumps, &self.alphas, x, Stump::predict))
    }

    /// The probability of a loop, `p_c = 1/(1 + e^{−f(x)})` (scikit-learn's `predict_proba`);
    /// [Stüde 2024] §3.2.1 thresholds it with `p_min`.
    ///
    /// # Errors
    /// As [`AdaBoost::decision`].
    pub fn probability(&self, x: &[f64]) -> Result<f64, AdaBoostError> {
        Ok(1.0 / (1.0 + (-self.decision(x)?).exp()))
    }

    /// The class, `f(x) > 0`.
    ///
    /// # Errors
    /// As [`AdaBoost::decision`].
    pub fn predict(&self, x: &[f64]) -> Result<bool, AdaBoostError> {
        Ok(self.decision(x)? > 0.0)
    }
}

/// The `kind` of depth-2 boosted-tree model files (`chronomap_io::model_file`).
pub const TREES_MODEL_KIND: &str = "lidar-adaboost-depth2";

/// A decision tree of depth 2 (scikit-learn's `DecisionTreeClassifier(max_depth=2)`): the
/// root split, then one stump on each side, fitted on that side's samples only. An extension
/// of the paper's weak learner (decision stumps, [Stüde 2024] §3.2.1), measured in
/// `docs/lidar.md`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Tree2 {
    /// The root split (without a feature: the tree is a single leaf, `root.below`).
    pub root: Stump,
    /// The stump for samples at or below the root's threshold.
    pub below: Stump,
    /// The stump for samples above it.
    pub above: Stump,
}

impl Tree2 {
    /// The tree's class for `x`.
    pub fn predict(&self, x: &[f64]) -> bool {
        match self.root.feature {
            Some(f) if x[f] > self.root.threshold => self.above.predict(x),
            Some(_) => self.below.predict(x),
            None => self.root.below,
        }
    }

    fn stumps(&self) -> [&Stump; 3] {
        [&self.root, &self.below, &self.above]
    }
}

/// SAMME AdaBoost with depth-2 trees ([`Tree2`]) instead of stumps: the same rounds, weights,
/// decision function and probability as [`AdaBoost`] (see the [module docs](self)).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BoostedTrees {
    /// Number of features a sample has.
    pub n_features: usize,
    /// The weak classifiers, in training order.
    pub trees: Vec<Tree2>,
    /// Their weights `α_t`.
    pub alphas: Vec<f64>,
    /// The weighted training error `ε_t` of each round.
    pub errors: Vec<f64>,
}

impl BoostedTrees {
    /// Trains on rows `x` with labels `y` and optional sample weights, as [`AdaBoost::fit`].
    ///
    /// # Errors
    /// As [`AdaBoost::fit`].
    pub fn fit<R: AsRef<[f64]>>(
        x: &[R],
        y: &[bool],
        weights: Option<&[f64]>,
        params: &AdaBoostParams,
    ) -> Result<BoostedTrees, AdaBoostError> {
        let (n_features, trees, alphas, errors) =
            samme(x, y, weights, params, fit_tree2, Tree2::predict)?;
        Ok(BoostedTrees {
            n_features,
            trees,
            alphas,
            errors,
        })
    }

    /// The classifier of the first `rounds` rounds, as [`AdaBoost::truncated`].
    pub fn truncated(&self, rounds: usize) -> BoostedTrees {
        let (trees, alphas, errors) = first_rounds(&self.trees, &self.alphas, &self.errors, rounds);
        BoostedTrees {
            n_features: self.n_features,
            trees,
            alphas,
            errors,
        }
    }

    /// Checks the invariants (for decoded models), as [`AdaBoost::validate`].
    pub fn validate(&self) -> Result<(), AdaBoostError> {
        let as_stumps = AdaBoost {
            n_features: self.n_features,
            stumps: self.trees.iter().map(|t| t.root.clone()).collect(),
            alphas: self.alphas.clone(),
            errors: self.errors.clone(),
        };
        as_stumps.validate()?;
        for s in self.trees.iter().flat_map(|t| t.stumps()) {
            if s.feature.is_some_and(|f| f >= self.n_features) || !s.threshold.is_finite() {
                return Err(AdaBoostError::Invalid(
                    "a tree's feature is out of range or its threshold not finite",
                ));
            }
        }
        Ok(())
    }

    /// The decision function `f(x) = 2 Σ α_t h_t(x) / Σ α_t` in `[−2, 2]`.
    ///
    /// # Errors
    /// As [`AdaBoost::decision`].
    pub fn decision(&self, x: &[f64]) -> Result<f64, AdaBoostError> {
        check_sample(self.n_features, x)?;
        Ok(vote(&self.trees, &self.alphas, x, Tree2::predict))
    }

    /// The probability of a loop, `1/(1 + e^{−f(x)})`.
    ///
    /// # Errors
    /// As [`AdaBoost::decision`].
    pub fn probability(&self, x: &[f64]) -> Result<f64, AdaBoostError> {
        Ok(1.0 / (1.0 + (-self.decision(x)?).exp()))
    }
}

fn check_sample(n_features: usize, x: &[f64]) -> Result<(), AdaBoostError> {
    if x.len() != n_features {
        return Err(AdaBoostError::FeatureCount {
            index: 0,
            found: x.len(),
            expected: n_features,
        });
    }
    if let Some((feature, &value)) = x.iter().enumerate().find(|(_, v)| v.is_nan()) {
        return Err(AdaBoostError::NonFinite {
            index: 0,
            feature,
            value,
        });
    }
    Ok(())
}

/// The best depth-2 tree for weights `w`: the Gini-best root split, then the Gini-best split
/// of each side on that side's samples (a pure or single-sample side is a leaf).
fn fit_tree2<R: AsRef<[f64]>>(x: &[R], y: &[bool], w: &[f64], order: &[Vec<u32>]) -> Tree2 {
    let root = fit_stump(x, y, w, order);
    let Some(f) = root.feature else {
        return Tree2 {
            below: root.clone(),
            above: root.clone(),
            root,
        };
    };
    let side = |above: bool| {
        let inside = |i: usize| (x[i].as_ref()[f] > root.threshold) == above;
        let wn: Vec<f64> = (0..w.len())
            .map(|i| if inside(i) { w[i] } else { 0.0 })
            .collect();
        let sub: Vec<Vec<u32>> = order
            .iter()
            .map(|o| o.iter().copied().filter(|&i| inside(i as usize)).collect())
            .collect();
        if sub[0].len() < 2 {
            let class = if above { root.above } else { root.below };
            return Stump {
                feature: None,
                threshold: 0.0,
                below: class,
                above: class,
            };
        }
        fit_stump(x, y, &wn, &sub)
    };
    Tree2 {
        below: side(false),
        above: side(true),
        root,
    }
}

/// Checks the training data and returns the number of features and the normalised weights.
fn prepare<R: AsRef<[f64]>>(
    x: &[R],
    y: &[bool],
    weights: Option<&[f64]>,
    rounds: usize,
) -> Result<(usize, Vec<f64>), AdaBoostError> {
    let n = x.len();
    if n == 0 || n > MAX_SAMPLES {
        return Err(AdaBoostError::SampleCount(n));
    }
    if !(1..=MAX_ROUNDS).contains(&rounds) {
        return Err(AdaBoostError::Rounds(rounds));
    }
    let d = x[0].as_ref().len();
    for (index, row) in x.iter().enumerate() {
        let row = row.as_ref();
        if row.len() != d || d == 0 || d > MAX_FEATURES {
            return Err(AdaBoostError::FeatureCount {
                index,
                found: row.len(),
                expected: d,
            });
        }
        if let Some((feature, &value)) = row.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(AdaBoostError::NonFinite {
                index,
                feature,
                value,
            });
        }
    }
    if y.len() != n {
        return Err(AdaBoostError::Length {
            what: "labels",
            found: y.len(),
            samples: n,
        });
    }
    let mut w: Vec<f64> = match weights {
        None => vec![1.0; n],
        Some(w) if w.len() != n => {
            return Err(AdaBoostError::Length {
                what: "weights",
                found: w.len(),
                samples: n,
            });
        }
        Some(w) => {
            if w.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(AdaBoostError::Weights("negative or not finite"));
            }
            w.to_vec()
        }
    };
    let total: f64 = w.iter().sum();
    if !(total > 0.0 && total.is_finite()) {
        return Err(AdaBoostError::Weights("they sum to zero or overflow"));
    }
    w.iter_mut().for_each(|v| *v /= total);
    if !y.iter().zip(&w).any(|(&c, &v)| c && v > 0.0) {
        return Err(AdaBoostError::OneClass("positives"));
    }
    if !y.iter().zip(&w).any(|(&c, &v)| !c && v > 0.0) {
        return Err(AdaBoostError::OneClass("positives"));
    }
    Ok((d, w))
}

/// Sample order of each feature by value (ties by index).
fn feature_order<R: AsRef<[f64]>>(x: &[R], d: usize) -> Vec<Vec<u32>> {
    (0..d)
        .map(|f| {
            let mut idx: Vec<u32> = (0..x.len() as u32).collect();
            idx.sort_by(|&a, &b| x[a as usize].as_ref()[f].total_cmp(&x[b as usize].as_ref()[f]));
            idx
        })
        .collect()
}

/// Training of either ensemble: the inputs checked ([`prepare`]), the sample order of each
/// feature by value (ties by index) computed once, then the SAMME rounds ([`boost`]) with
/// the weak learner `fit` (applied by `predict`). Returns the number of features, the learners, `α_t` and `ε_t`.
#[allow(clippy::type_complexity)]
fn samme<R: AsRef<[f64]>, L>(
    x: &[R],
    y: &[bool],
    weights: Option<&[f64]>,
    params: &AdaBoostParams,
    fit: fn(&[R], &[bool], &[f64], &[Vec<u32>]) -> L,
    predict: fn(&L, &[f64]) -> bool,
) -> Result<(usize, Vec<L>, Vec<f64>, Vec<f64>), AdaBoostError> {
    let (d, w) = prepare(x, y, weights, params.rounds)?;
    let order = feature_order(x, d);
    let rounds = boost(x, y, w, params.rounds, |w| fit(x, y, w, &order), predict)?;
    let alphas = rounds.iter().map(|r| r.1).collect();
    let errors = rounds.iter().map(|r| r.2).collect();
    Ok((d, rounds.into_iter().map(|r| r.0).collect(), alphas, errors))
}

/// The decision function `f(x) = 2 Σ α_t h_t(x) / Σ α_t` of either ensemble.
fn vote<L>(learners: &[L], alphas: &[f64], x: &[f64], predict: fn(&L, &[f64]) -> bool) -> f64 {
    let (mut vote, mut total) = (0.0, 0.0);
    for (l, &a) in learners.iter().zip(alphas) {
        vote += if predict(l, x) { 2.0 * a } else { -2.0 * a };
        total += a;
    }
    vote / total
}

/// The first `rounds` rounds (at least one, at most all) of either ensemble.
fn first_rounds<L: Clone>(
    learners: &[L],
    alphas: &[f64],
    errors: &[f64],
    rounds: usize,
) -> (Vec<L>, Vec<f64>, Vec<f64>) {
    let t = rounds.clamp(1, learners.len().max(1));
    (
        learners.iter().take(t).cloned().collect(),
        alphas.iter().take(t).copied().collect(),
        errors.iter().take(t).copied().collect(),
    )
}

/// The SAMME rounds of the [module docs](self) with any weak learner: `fit` trains one on
/// the current weights, `predict` applies it. Returns `(learner, α_t, ε_t)` per round.
fn boost<R: AsRef<[f64]>, L>(
    x: &[R],
    y: &[bool],
    mut w: Vec<f64>,
    rounds: usize,
    mut fit: impl FnMut(&[f64]) -> L,
    predict: impl Fn(&L, &[f64]) -> bool,
) -> Result<Vec<(L, f64, f64)>, AdaBoostError> {
    let n = x.len();
    let zero: Vec<bool> = w.iter().map(|&v| v == 0.0).collect();
    let mut out = Vec::new();
    let mut incorrect = vec![false; n];
    for round in 0..rounds {
        for (v, &z) in w.iter_mut().zip(&zero) {
            *v = if z { 0.0 } else { v.max(f64::EPSILON) };
        }
        let learner = fit(&w);
        let (mut wrong, mut sum) = (0.0, 0.0);
        for i in 0..n {
            incorrect[i] = predict(&learner, x[i].as_ref()) != y[i];
            sum += w[i];
            if incorrect[i] {
                wrong += w[i];
            }
        }
        let error = wrong / sum;
        if error <= 0.0 {
            out.push((learner, 1.0, 0.0));
            break;
        }
        if error >= 0.5 {
            if round == 0 {
                return Err(AdaBoostError::WorseThanChance(error));
            }
            break;
        }
        let alpha = ((1.0 - error) / error).ln();
        out.push((learner, alpha, error));
        if round + 1 == rounds {
            break;
        }
        for i in 0..n {
            if w[i] > 0.0 {
                w[i] = (w[i].ln() + if incorrect[i] { alpha } else { 0.0 }).exp();
            }
        }
        let total: f64 = w.iter().sum();
        if !total.is_finite() || total <= 0.0 {
            break;
        }
        w.iter_mut().for_each(|v| *v /= total);
    }
    Ok(out)
}

/// Weighted class totals `[negative, positive]`.
fn gini(counts: [f64; 2], total: f64) -> f64 {
    1.0 - (counts[0] * counts[0] + counts[1] * counts[1]) / (total * total)
}

/// The class of the weighted majority (negative on a tie).
fn majority(counts: [f64; 2]) -> bool {
    counts[1] > counts[0]
}

/// The best stump for weights `w` (scikit-learn's `BestSplitter` with the Gini criterion at
/// depth 1; see the module docs).
fn fit_stump<R: AsRef<[f64]>>(x: &[R], y: &[bool], w: &[f64], order: &[Vec<u32>]) -> Stump {
    let mut total = [0.0; 2];
    for (&c, &v) in y.iter().zip(w) {
        total[usize::from(c)] += v;
    }
    let weight = total[0] + total[1];
    let leaf = Stump {
        feature: None,
        threshold: 0.0,
        below: majority(total),
        above: majority(total),
    };
    if gini(total, weight) <= f64::EPSILON || x.len() < 2 {
        return leaf;
    }
    let mut best: Option<(f64, usize, usize)> = None; // (proxy, feature, position)
    for (f, idx) in order.iter().enumerate() {
        let value = |p: usize| x[idx[p] as usize].as_ref()[f];
        let n = idx.len();
        if value(n - 1) <= value(0) + FEATURE_THRESHOLD {
            continue;
        }
        let mut left = [0.0; 2];
        let mut left_weight = 0.0;
        for p in 1..n {
            let i = idx[p - 1] as usize;
            left[usize::from(y[i])] += w[i];
            left_weight += w[i];
            if value(p) <= value(p - 1) + FEATURE_THRESHOLD {
                continue;
            }
            let right = [total[0] - left[0], total[1] - left[1]];
            let right_weight = weight - left_weight;
            let proxy =
                -right_weight * gini(right, right_weight) - left_weight * gini(left, left_weight);
            if best.is_none_or(|(b, _, _)| proxy > b) {
                best = Some((proxy, f, p));
            }
        }
    }
    let Some((_, f, p)) = best else {
        return leaf;
    };
    let idx = &order[f];
    let (lo, hi) = (
        x[idx[p - 1] as usize].as_ref()[f],
        x[idx[p] as usize].as_ref()[f],
    );
    let mut threshold = lo / 2.0 + hi / 2.0;
    if threshold == hi || !threshold.is_finite() {
        threshold = lo;
    }
    let mut left = [0.0; 2];
    for &i in &idx[..p] {
        left[usize::from(y[i as usize])] += w[i as usize];
    }
    let right = [total[0] - left[0], total[1] - left[1]];
    Stump {
        feature: Some(f),
        threshold,
        below: majority(left),
        above: majority(right),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Hand-computed two rounds on four points of one feature.
    #[test]
    fn two_rounds_by_hand() {
        // x: 1 2 3 4, y: 0 1 0 1. Best Gini split: x <= 1.5 (left {0}, right {1,0,1})
        // or x <= 3.5 ({0,1,0} | {1}); both have proxy −(3·(1 − 5/9))/4·… equal: the first
        // (smallest threshold) wins. Error 1/4, α = ln 3.
        let x = [[1.0], [2.0], [3.0], [4.0]];
        let y = [false, true, false, true];
        let m = AdaBoost::fit(&x, &y, None, &AdaBoostParams { rounds: 2 }).unwrap();
        assert_eq!(m.stumps[0].threshold, 1.5);
        assert_eq!((m.stumps[0].below, m.stumps[0].above), (false, true));
        assert!((m.alphas[0] - 3f64.ln()).abs() < 1e-15);
        assert_eq!(m.errors[0], 0.25);
        // Round 2: sample 3 (x = 3) weighs 3/6 = 1/2, the others 1/6 each.
        // Split x <= 3.5: left {0: 1/6, 1: 1/6, 0: 1/2} → class 0; right {1: 1/6} → 1; error 1/6.
        assert_eq!(m.stumps[1].threshold, 3.5);
        assert!((m.errors[1] - 1.0 / 6.0).abs() < 1e-15);
        assert!((m.alphas[1] - 5f64.ln()).abs() < 1e-14);
        // x = 2: stump 1 says 1, stump 2 says 0 → f = 2(ln3 − ln5)/(ln3 + ln5).
        let f = m.decision(&[2.0]).unwrap();
        let expected = 2.0 * (3f64.ln() - 5f64.ln()) / (3f64.ln() + 5f64.ln());
        assert!((f - expected).abs() < 1e-15);
        assert!((m.probability(&[2.0]).unwrap() - 1.0 / (1.0 + (-expected).exp())).abs() < 1e-15);
    }

    #[test]
    fn a_perfect_first_stump_stops_with_weight_one() {
        let x = [[0.0, 5.0], [1.0, 5.0], [2.0, 5.0]];
        let m = AdaBoost::fit(&x, &[false, false, true], None, &AdaBoostParams::default()).unwrap();
        assert_eq!(m.stumps.len(), 1);
        assert_eq!((m.stumps[0].feature, m.stumps[0].threshold), (Some(0), 1.5));
        assert_eq!(m.alphas, vec![1.0]);
        assert_eq!(m.decision(&[3.0, 0.0]).unwrap(), 2.0);
    }

    #[test]
    fn weights_move_the_split() {
        // x 1..4, y 0 1 0 1: unweighted, x <= 1.5 and x <= 3.5 tie and the first wins; a
        // sample at x = 3 ten times as heavy makes {x <= 3.5} (Gini proxy −1.83) beat
        // {x <= 1.5} (−3.33) and {x <= 2.5} (−2.82).
        let x = [[1.0], [2.0], [3.0], [4.0]];
        let y = [false, true, false, true];
        let p = AdaBoostParams { rounds: 1 };
        let plain = AdaBoost::fit(&x, &y, None, &p).unwrap();
        assert_eq!(plain.stumps[0].threshold, 1.5);
        let heavy = AdaBoost::fit(&x, &y, Some(&[1.0, 1.0, 10.0, 1.0]), &p).unwrap();
        assert_eq!(heavy.stumps[0].threshold, 3.5);
        assert!((heavy.errors[0] - 1.0 / 13.0).abs() < 1e-15);
        // A zero weight takes a sample out of training.
        let zero = AdaBoost::fit(&x, &y, Some(&[1.0, 0.0, 1.0, 1.0]), &p).unwrap();
        assert_eq!(zero.stumps[0].threshold, 3.5);
        assert_eq!(zero.errors[0], 0.0);
    }

    #[test]
    fn bad_input_is_refused() {
        let p = AdaBoostParams::default();
        let empty: [[f64; 1]; 0] = [];
        assert_eq!(
            AdaBoost::fit(&empty, &[], None, &p),
            Err(AdaBoostError::SampleCount(0))
        );
        let x = [vec![1.0], vec![2.0, 3.0]];
        assert!(matches!(
            AdaBoost::fit(&x, &[true, false], None, &p),
            Err(AdaBoostError::FeatureCount { index: 1, .. })
        ));
        let x = [[1.0], [f64::NAN]];
        assert!(matches!(
            AdaBoost::fit(&x, &[true, false], None, &p),
            Err(AdaBoostError::NonFinite {
                index: 1,
                feature: 0,
                ..
            })
        ));
        let x = [[1.0], [2.0]];
        assert_eq!(
            AdaBoost::fit(&x, &[true, true], None, &p),
            Err(AdaBoostError::OneClass("positives"))
        );
        assert!(matches!(
            AdaBoost::fit(&x, &[true, false], Some(&[1.0, -1.0]), &p),
            Err(AdaBoostError::Weights(_))
        ));
        assert!(matches!(
            AdaBoost::fit(&x, &[true], None, &p),
            Err(AdaBoostError::Length { .. })
        ));
        assert_eq!(
            AdaBoost::fit(&x, &[true, false], None, &AdaBoostParams { rounds: 0 }),
            Err(AdaBoostError::Rounds(0))
        );
        // Identical samples of both classes: no split, the leaf errs half the time.
        let x = [[1.0], [1.0]];
        assert!(matches!(
            AdaBoost::fit(&x, &[true, false], None, &p),
            Err(AdaBoostError::WorseThanChance(_))
        ));
        let m = AdaBoost::fit(&[[1.0], [2.0]], &[true, false], None, &p).unwrap();
        assert!(m.decision(&[1.0, 2.0]).is_err());
        assert!(m.decision(&[f64::NAN]).is_err());
    }

    #[test]
    fn truncation_equals_training_fewer_rounds() {
        // Noisy one-feature data: many rounds before the error stops falling.
        let x: Vec<[f64; 2]> = (0..40)
            .map(|k| [(k * 7 % 40) as f64, (k * 13 % 17) as f64])
            .collect();
        let y: Vec<bool> = (0..40)
            .map(|k| ((k * 7 % 40) > 18) ^ (k % 5 == 0))
            .collect();
        let long = AdaBoost::fit(&x, &y, None, &AdaBoostParams { rounds: 12 }).unwrap();
        let short = AdaBoost::fit(&x, &y, None, &AdaBoostParams { rounds: 4 }).unwrap();
        assert!(long.stumps.len() > 4);
        assert_eq!(long.truncated(4), short);
        let trees = BoostedTrees::fit(&x, &y, None, &AdaBoostParams { rounds: 12 }).unwrap();
        let few = BoostedTrees::fit(&x, &y, None, &AdaBoostParams { rounds: 3 }).unwrap();
        assert_eq!(trees.truncated(3), few);
        trees.validate().unwrap();
    }

    #[test]
    fn a_depth2_tree_learns_xor_that_stumps_cannot() {
        let x = [[0.0, 0.0], [0.0, 1.0], [1.0, 0.0], [1.0, 1.0]];
        let y = [false, true, true, false];
        let p = AdaBoostParams::default();
        // Every stump errs on half the weight.
        assert!(matches!(
            AdaBoost::fit(&x, &y, None, &p),
            Err(AdaBoostError::WorseThanChance(_))
        ));
        // Root x0 <= 0.5 (all splits tie, the first wins), then x1 <= 0.5 on each side.
        let m = BoostedTrees::fit(&x, &y, None, &p).unwrap();
        assert_eq!(m.trees.len(), 1);
        let t = &m.trees[0];
        assert_eq!((t.root.feature, t.root.threshold), (Some(0), 0.5));
        assert_eq!((t.below.feature, t.below.threshold), (Some(1), 0.5));
        assert_eq!((t.below.below, t.below.above), (false, true));
        assert_eq!((t.above.below, t.above.above), (true, false));
        assert_eq!(m.alphas, vec![1.0]);
        for (xi, &yi) in x.iter().zip(&y) {
            assert_eq!(m.decision(xi).unwrap(), if yi { 2.0 } else { -2.0 });
        }
        let mut bad = m.clone();
        bad.trees[0].above.feature = Some(2);
        assert!(bad.validate().is_err());
        assert!(m.probability(&[0.0]).is_err());
    }

    #[test]
    fn validate_catches_damaged_models() {
        let m = AdaBoost::fit(
            &[[1.0], [2.0], [3.0]],
            &[true, false, true],
            None,
            &AdaBoostParams::default(),
        )
        .unwrap();
        assert_eq!(m.validate(), Ok(()));
        let mut bad = m.clone();
        bad.stumps[0].feature = Some(3);
        assert!(bad.validate().is_err());
        let mut bad = m.clone();
        bad.alphas.pop();
        assert!(bad.validate().is_err());
        let mut bad = m;
        bad.alphas[0] = f64::NAN;
        assert!(bad.validate().is_err());
    }
}
