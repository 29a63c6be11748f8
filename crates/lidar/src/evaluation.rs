//! Evaluation of loop detection on a keyframe sequence ([Stüde 2024] §3.2.1, "Loop
//! Classification" and its evaluation): labelled keyframe pairs, cross-validation whose folds
//! split the *keyframes* (no keyframe of a scored pair is seen in training), ROC / TPR at
//! FPR < 1 %, and the whole pipeline — search radius, classifier, verification — run along
//! the sequence. `examples/malaga_loops.rs` runs it on the Málaga log; `docs/lidar.md`
//! argues the choices.
//!
//! ```
//! use chronomap_lidar::evaluation::{LabelParams, label_pairs, sector_folds};
//!
//! // A square loop driven twice: keyframes every metre.
//! let lap: Vec<[f64; 2]> = (0..40).map(|k| {
//!     let (side, t) = (k / 10, (k % 10) as f64);
//!     [[t, 0.0], [10.0, t], [10.0 - t, 10.0], [0.0, 10.0 - t]][side]
//! }).collect();
//! let positions: Vec<[f64; 2]> = lap.iter().chain(&lap).copied().collect();
//! let pairs = label_pairs(&positions, &LabelParams::default())?;
//! // Every keyframe of lap 2 revisits its twin of lap 1 (0 m apart, 40 keyframes later),
//! // and neighbours within 3 m as well.
//! assert!(pairs.iter().any(|p| p.positive && (p.i, p.j) == (5, 45)));
//! // Folds are angular sectors around the centroid, opposite sectors together.
//! let folds = sector_folds(&positions, 2, 0.0)?;
//! assert_eq!(folds[5], folds[45]);
//! # Ok::<(), chronomap_lidar::evaluation::EvalError>(())
//! ```
//!
//! [Stüde 2024]: M. Stüde, dissertation, Hannover 2024.

use serde::{Deserialize, Serialize};

use crate::adaboost::{AdaBoost, AdaBoostError, AdaBoostParams, BoostedTrees};
use crate::search::{
    OdometryNoise, SearchError, SearchMode, SearchParams, propagate, search_mode, search_radius,
    verified, within_radius,
};
use crate::threshold::{MeanSd, RocPoint, ThresholdError, auc, rates_at, roc, threshold_for_fpr};

/// Why an evaluation cannot run. The message of the inner error is part of this one's, so it
/// is not also its [`source`](std::error::Error::source) (a chain printed in full would say it
/// twice: "covariance: not finite: covariance: not finite").
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EvalError {
    /// A position is not finite, or inputs differ in length.
    #[error("evaluation input: {0}")]
    Input(String),
    /// Training failed.
    #[error("training: {0}")]
    Train(AdaBoostError),
    /// A ROC curve failed.
    #[error("roc: {0}")]
    Roc(ThresholdError),
    /// A search quantity failed.
    #[error("search: {0}")]
    Search(SearchError),
}

impl From<AdaBoostError> for EvalError {
    fn from(e: AdaBoostError) -> Self {
        EvalError::Train(e)
    }
}

impl From<ThresholdError> for EvalError {
    fn from(e: ThresholdError) -> Self {
        EvalError::Roc(e)
    }
}

impl From<SearchError> for EvalError {
    fn from(e: SearchError) -> Self {
        EvalError::Search(e)
    }
}

/// How keyframe pairs are labelled.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LabelParams {
    /// Pairs closer than this (m) and more than `min_separation` keyframes apart are loops
    /// (3 m, [Stüde 2024] §3.2.1).
    pub near: f64,
    /// Pairs farther apart than this (m) are not loops (10 m); pairs between `near` and `far`,
    /// and close pairs of nearby keyframes, are ambiguous and left out.
    pub far: f64,
    /// Loops must be more than this many keyframes apart in the sequence (20).
    pub min_separation: usize,
}

impl Default for LabelParams {
    fn default() -> Self {
        LabelParams {
            near: 3.0,
            far: 10.0,
            min_separation: 20,
        }
    }
}

/// A labelled keyframe pair `i < j`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LabelledPair {
    /// The earlier keyframe.
    pub i: usize,
    /// The later keyframe.
    pub j: usize,
    /// A loop (true) or not.
    pub positive: bool,
    /// Their distance (m).
    pub distance: f64,
}

fn check_positions(positions: &[[f64; 2]]) -> Result<(), EvalError> {
    match positions
        .iter()
        .position(|p| !(p[0].is_finite() && p[1].is_finite()))
    {
        Some(k) => Err(EvalError::Input(format!("position {k} is not finite"))),
        None => Ok(()),
    }
}

/// The positive and negative pairs of keyframes at `positions` (see [`LabelParams`]).
///
/// # Errors
/// [`EvalError::Input`] for a non-finite position or `near > far`.
pub fn label_pairs(
    positions: &[[f64; 2]],
    params: &LabelParams,
) -> Result<Vec<LabelledPair>, EvalError> {
    check_positions(positions)?;
    if !(params.near >= 0.0 && params.near <= params.far && params.far.is_finite()) {
        return Err(EvalError::Input(
            "labels need 0 <= near <= far < inf".into(),
        ));
    }
    let mut out = Vec::new();
    for j in 0..positions.len() {
        for i in 0..j {
            let d = (positions[i][0] - positions[j][0]).hypot(positions[i][1] - positions[j][1]);
            if d < params.near && j - i > params.min_separation {
                out.push(LabelledPair {
                    i,
                    j,
                    positive: true,
                    distance: d,
                });
            } else if d > params.far {
                out.push(LabelledPair {
                    i,
                    j,
                    positive: false,
                    distance: d,
                });
            }
        }
    }
    Ok(out)
}

/// Folds of keyframes by place: `2·folds` equal angular sectors around the centroid of the
/// positions (starting at angle `rotation`), sector `s` in fold `s mod folds`, so that each
/// fold holds two opposite sectors. Both visits of a place fall into the same fold (their
/// loops can be scored), the two sectors of a fold are far apart (negatives), and the
/// training folds hold no keyframe of the place — nor its neighbours in the sequence, except
/// at sector borders.
///
/// # Errors
/// [`EvalError::Input`] for no fold, or a non-finite position or rotation.
pub fn sector_folds(
    positions: &[[f64; 2]],
    folds: usize,
    rotation: f64,
) -> Result<Vec<usize>, EvalError> {
    check_positions(positions)?;
    if folds == 0 || folds > 1000 || !rotation.is_finite() {
        return Err(EvalError::Input(
            "folds must be 1..=1000, rotation finite".into(),
        ));
    }
    let n = positions.len().max(1) as f64;
    let cx = positions.iter().map(|p| p[0]).sum::<f64>() / n;
    let cy = positions.iter().map(|p| p[1]).sum::<f64>() / n;
    let sectors = 2 * folds;
    let width = std::f64::consts::TAU / sectors as f64;
    Ok(positions
        .iter()
        .map(|p| {
            let a = ((p[1] - cy).atan2(p[0] - cx) - rotation).rem_euclid(std::f64::consts::TAU);
            ((a / width) as usize).min(sectors - 1) % folds
        })
        .collect())
}

/// Cross-validation settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CvParams {
    /// The classifier's parameters (`T = 50`).
    pub adaboost: AdaBoostParams,
    /// The false-positive bound for `p_min` (1 %).
    pub max_fpr: f64,
    /// Seed of the balanced training subsets.
    pub seed: u64,
}

impl Default for CvParams {
    fn default() -> Self {
        CvParams {
            adaboost: AdaBoostParams::default(),
            max_fpr: 0.01,
            seed: 1,
        }
    }
}

/// A scored test pair.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ScoredPair {
    /// The pair.
    pub pair: LabelledPair,
    /// Its fold.
    pub fold: usize,
    /// The loop probability of the model that did not see its keyframes.
    pub probability: f64,
}

/// One fold's result.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FoldResult {
    /// The fold.
    pub fold: usize,
    /// Training pairs (positives, negatives after balancing).
    pub trained_on: (usize, usize),
    /// Test pairs (positives, negatives).
    pub tested_on: (usize, usize),
    /// The fold's ROC curve.
    pub roc: Vec<RocPoint>,
    /// Its area.
    pub auc: f64,
    /// The point of its own ROC with the largest TPR at FPR below the bound (the threshold
    /// chosen on the fold's own scores, as the dissertation's cross-validation does).
    pub at_max_fpr: RocPoint,
    /// `p_min` chosen on the pooled scores of the *other* folds.
    pub heldout_threshold: f64,
    /// TPR and FPR of this fold at that `p_min` (a threshold it did not help choose).
    pub heldout_rates: (f64, f64),
}

/// The result of [`cross_validate`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CvReport {
    /// Per fold (folds without test positives or negatives are left out).
    pub folds: Vec<FoldResult>,
    /// Every scored test pair.
    pub scored: Vec<ScoredPair>,
    /// ROC of all scored pairs together.
    pub pooled_roc: Vec<RocPoint>,
    /// Its area.
    pub pooled_auc: f64,
    /// `p_min` on the pooled ROC.
    pub pooled_at_max_fpr: RocPoint,
}

impl CvReport {
    /// Mean ± sd over folds of the TPR at FPR below the bound (each fold's own threshold).
    pub fn tpr(&self) -> MeanSd {
        MeanSd::of(self.folds.iter().map(|f| f.at_max_fpr.tpr))
    }
    /// Mean ± sd over folds of the AUC.
    pub fn auc(&self) -> MeanSd {
        MeanSd::of(self.folds.iter().map(|f| f.auc))
    }
    /// Mean ± sd over folds of the TPR at the held-out threshold.
    pub fn heldout_tpr(&self) -> MeanSd {
        MeanSd::of(self.folds.iter().map(|f| f.heldout_rates.0))
    }
    /// Mean ± sd over folds of the FPR at the held-out threshold.
    pub fn heldout_fpr(&self) -> MeanSd {
        MeanSd::of(self.folds.iter().map(|f| f.heldout_rates.1))
    }
}

/// Training rows of the pairs that `keep` accepts: all positives and as many negatives,
/// drawn with `seed` ([Stüde 2024] §3.2.1 re-balances by random subsets).
fn balanced<'a, R: AsRef<[f64]>>(
    pairs: &[LabelledPair],
    x: &'a [R],
    keep: impl Fn(&LabelledPair) -> bool,
    seed: u64,
) -> (Vec<&'a [f64]>, Vec<bool>) {
    let (mut pos, mut neg): (Vec<usize>, Vec<usize>) = (Vec::new(), Vec::new());
    for (k, p) in pairs.iter().enumerate() {
        if keep(p) {
            if p.positive {
                pos.push(k);
            } else {
                neg.push(k);
            }
        }
    }
    let mut rng = chronomap_rng::Xoshiro256StarStar::seed_from_u64(seed);
    rng.shuffle(&mut neg);
    neg.truncate(pos.len());
    neg.sort_unstable();
    let rows = pos.iter().chain(&neg).map(|&k| x[k].as_ref()).collect();
    let labels = pos
        .iter()
        .map(|_| true)
        .chain(neg.iter().map(|_| false))
        .collect();
    (rows, labels)
}

fn check_rows<R: AsRef<[f64]>>(
    pairs: &[LabelledPair],
    x: &[R],
    fold_of: &[usize],
) -> Result<(), EvalError> {
    if x.len() != pairs.len() {
        return Err(EvalError::Input(format!(
            "{} feature rows for {} pairs",
            x.len(),
            pairs.len()
        )));
    }
    if let Some(p) = pairs.iter().find(|p| p.i.max(p.j) >= fold_of.len()) {
        return Err(EvalError::Input(format!(
            "pair ({}, {}) has a keyframe without a fold",
            p.i, p.j
        )));
    }
    Ok(())
}

/// Keyframe-disjoint cross-validation: for each fold `f`, train on the pairs of keyframes
/// outside `f` (balanced) and score the pairs of keyframes inside `f`. `x[k]` is the pair
/// feature vector of `pairs[k]`; `fold_of[i]` the fold of keyframe `i`.
///
/// # Errors
/// [`EvalError`] for inconsistent inputs, or if training or the pooled ROC fails (no
/// positives or negatives at all).
pub fn cross_validate<R: AsRef<[f64]>>(
    pairs: &[LabelledPair],
    x: &[R],
    fold_of: &[usize],
    params: &CvParams,
) -> Result<CvReport, EvalError> {
    check_rows(pairs, x, fold_of)?;
    let folds = fold_of.iter().max().map_or(0, |m| m + 1);
    let mut scored = Vec::new();
    let mut trained = Vec::new();
    for f in 0..folds {
        let outside = |p: &LabelledPair| fold_of[p.i] != f && fold_of[p.j] != f;
        let seed = chronomap_rng::derive_seed(params.seed, 0x11da_0001, f as u64, 0);
        let (rows, labels) = balanced(pairs, x, outside, seed);
        let test: Vec<usize> = (0..pairs.len())
            .filter(|&k| fold_of[pairs[k].i] == f && fold_of[pairs[k].j] == f)
            .collect();
        let has = |v: bool| test.iter().any(|&k| pairs[k].positive == v);
        if !has(true) || !has(false) || labels.is_empty() {
            continue;
        }
        let model = AdaBoost::fit(&rows, &labels, None, &params.adaboost)?;
        for &k in &test {
            scored.push(ScoredPair {
                pair: pairs[k],
                fold: f,
                probability: model.probability(x[k].as_ref())?,
            });
        }
        trained.push((f, labels.iter().filter(|&&l| l).count(), labels.len()));
    }
    report_from(scored, &trained, params.max_fpr)
}

/// ROC, AUC and thresholds per fold and pooled, from the scored pairs of the folds in
/// `trained` (`(fold, training positives, training rows)`).
fn report_from(
    scored: Vec<ScoredPair>,
    trained: &[(usize, usize, usize)],
    max_fpr: f64,
) -> Result<CvReport, EvalError> {
    let split = |keep: &dyn Fn(&ScoredPair) -> bool| -> (Vec<f64>, Vec<bool>) {
        scored
            .iter()
            .filter(|s| keep(s))
            .map(|s| (s.probability, s.pair.positive))
            .unzip()
    };
    let mut results = Vec::new();
    for &(f, tp, tn) in trained {
        let (scores, labels) = split(&|s| s.fold == f);
        let curve = roc(&scores, &labels)?;
        let (other_scores, other_labels) = split(&|s| s.fold != f);
        let heldout_threshold = roc(&other_scores, &other_labels)
            .map(|c| threshold_for_fpr(&c, max_fpr).threshold)
            .unwrap_or(f64::INFINITY);
        results.push(FoldResult {
            fold: f,
            trained_on: (tp, tn - tp),
            tested_on: (
                labels.iter().filter(|&&l| l).count(),
                labels.iter().filter(|&&l| !l).count(),
            ),
            auc: auc(&curve),
            at_max_fpr: threshold_for_fpr(&curve, max_fpr),
            heldout_threshold,
            heldout_rates: rates_at(&scores, &labels, heldout_threshold),
            roc: curve,
        });
    }
    let (scores, labels) = split(&|_| true);
    let pooled_roc = roc(&scores, &labels)?;
    Ok(CvReport {
        folds: results,
        scored,
        pooled_auc: auc(&pooled_roc),
        pooled_at_max_fpr: threshold_for_fpr(&pooled_roc, max_fpr),
        pooled_roc,
    })
}

/// How a training set is balanced.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Balance {
    /// All positives and as many random negatives ([Stüde 2024] §3.2.1; what
    /// [`cross_validate`] does).
    Subsample,
    /// All pairs, weighted so that positives and negatives weigh the same in total (our
    /// extension: no negative is thrown away).
    Weighted,
}

/// The weak learner of the boosted classifier.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum WeakLearner {
    /// Decision stumps ([Stüde 2024] §3.2.1, [`AdaBoost`]).
    Stump,
    /// Depth-2 trees (our extension, [`BoostedTrees`]).
    Depth2,
}

/// A trained loop classifier of either kind.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum LoopModel {
    /// Boosted stumps (the paper's).
    Stumps(AdaBoost),
    /// Boosted depth-2 trees.
    Depth2(BoostedTrees),
}

impl LoopModel {
    /// Trains a model of kind `learner` with `rounds` rounds on the pairs `keep` accepts,
    /// balanced as `balance` says (the subsample drawn with `seed`).
    ///
    /// # Errors
    /// [`EvalError::Input`] if `x` and `pairs` differ in length; [`EvalError::Train`] if training
    /// fails (e.g. one class only).
    pub fn train<R: AsRef<[f64]>>(
        pairs: &[LabelledPair],
        x: &[R],
        keep: impl Fn(&LabelledPair) -> bool,
        learner: WeakLearner,
        balance: Balance,
        rounds: usize,
        seed: u64,
    ) -> Result<LoopModel, EvalError> {
        if x.len() != pairs.len() {
            return Err(EvalError::Input(format!(
                "{} feature rows for {} pairs",
                x.len(),
                pairs.len()
            )));
        }
        let (rows, labels, weights) = match balance {
            Balance::Subsample => {
                let (rows, labels) = balanced(pairs, x, keep, seed);
                (rows, labels, None)
            }
            Balance::Weighted => {
                let kept: Vec<usize> = (0..pairs.len()).filter(|&k| keep(&pairs[k])).collect();
                let labels: Vec<bool> = kept.iter().map(|&k| pairs[k].positive).collect();
                let pos = labels.iter().filter(|&&l| l).count().max(1) as f64;
                let neg = labels.iter().filter(|&&l| !l).count().max(1) as f64;
                let weights = labels
                    .iter()
                    .map(|&l| if l { 0.5 / pos } else { 0.5 / neg })
                    .collect::<Vec<f64>>();
                let rows = kept.iter().map(|&k| x[k].as_ref()).collect();
                (rows, labels, Some(weights))
            }
        };
        if rows.is_empty() {
            return Err(EvalError::Train(AdaBoostError::SampleCount(0)));
        }
        let params = AdaBoostParams { rounds };
        Ok(match learner {
            WeakLearner::Stump => {
                LoopModel::Stumps(AdaBoost::fit(&rows, &labels, weights.as_deref(), &params)?)
            }
            WeakLearner::Depth2 => LoopModel::Depth2(BoostedTrees::fit(
                &rows,
                &labels,
                weights.as_deref(),
                &params,
            )?),
        })
    }

    /// The probability of a loop.
    ///
    /// # Errors
    /// As [`AdaBoost::probability`].
    pub fn probability(&self, x: &[f64]) -> Result<f64, EvalError> {
        Ok(match self {
            LoopModel::Stumps(m) => m.probability(x)?,
            LoopModel::Depth2(m) => m.probability(x)?,
        })
    }

    /// The model of the first `rounds` rounds ([`AdaBoost::truncated`]).
    pub fn truncated(&self, rounds: usize) -> LoopModel {
        match self {
            LoopModel::Stumps(m) => LoopModel::Stumps(m.truncated(rounds)),
            LoopModel::Depth2(m) => LoopModel::Depth2(m.truncated(rounds)),
        }
    }

    /// Rounds trained.
    pub fn rounds(&self) -> usize {
        match self {
            LoopModel::Stumps(m) => m.stumps.len(),
            LoopModel::Depth2(m) => m.trees.len(),
        }
    }
}

/// One classifier configuration for [`nested_cross_validate`]: its training pairs and features,
/// the features of the scored pairs, the weak learner and the balancing.
#[derive(Clone, Debug)]
pub struct Candidate<'a, R: AsRef<[f64]>> {
    /// A name for reports.
    pub name: String,
    /// Training pairs (e.g. [`label_pairs`] with a tighter `near` and `min_separation = 0`:
    /// neighbouring keyframes of one place are "same place" too).
    pub train_pairs: &'a [LabelledPair],
    /// Their feature rows.
    pub train_x: &'a [R],
    /// Feature rows of the scored pairs (same features as `train_x`).
    pub score_x: &'a [R],
    /// The weak learner.
    pub learner: WeakLearner,
    /// The balancing.
    pub balance: Balance,
}

/// Settings of [`nested_cross_validate`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NestedParams {
    /// The rounds `T` to choose from (each candidate is trained once at the largest and
    /// truncated: [`AdaBoost::truncated`]).
    pub rounds: Vec<usize>,
    /// The false-positive bound (1 %).
    pub max_fpr: f64,
    /// Seed of the balanced subsets.
    pub seed: u64,
}

impl Default for NestedParams {
    fn default() -> Self {
        NestedParams {
            rounds: vec![25, 50, 100, 200],
            max_fpr: 0.01,
            seed: 1,
        }
    }
}

/// What the inner cross-validation chose for an outer fold.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Choice {
    /// The outer fold.
    pub fold: usize,
    /// Index of the chosen candidate.
    pub candidate: usize,
    /// The chosen `T`.
    pub rounds: usize,
    /// Its inner score: pooled TPR at FPR below the bound, then AUC (tie-break).
    pub inner: (f64, f64),
}

/// The result of [`nested_cross_validate`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NestedReport {
    /// The outer folds' results, as [`cross_validate`] reports them.
    pub report: CvReport,
    /// The configuration each outer fold used.
    pub chosen: Vec<Choice>,
}

/// Nested keyframe-disjoint cross-validation. For each outer fold `f` (keyframes with
/// `fold_of == f`): if there is more than one (candidate, `T`) to choose from, an inner
/// cross-validation over the *other* folds picks one — for each inner fold `g ≠ f`, train on
/// pairs with no keyframe in `f` or `g`, score the `score_pairs` inside `g`, pool, and take the
/// highest TPR at FPR below the bound (ties: the higher AUC, then the earlier candidate and
/// smaller `T`). The choice is then trained on all pairs with no keyframe in `f` and scores
/// the `score_pairs` inside `f`. The test fold is never seen by the choice.
///
/// # Errors
/// [`EvalError::Input`] for no candidate or `T`, rows that do not match their pairs, or a
/// keyframe without a fold; [`EvalError::Train`] / [`EvalError::Roc`] as [`cross_validate`].
pub fn nested_cross_validate<R: AsRef<[f64]>>(
    score_pairs: &[LabelledPair],
    candidates: &[Candidate<'_, R>],
    fold_of: &[usize],
    params: &NestedParams,
) -> Result<NestedReport, EvalError> {
    check_candidates(score_pairs, candidates, fold_of, params)?;
    let folds = fold_of.iter().max().map_or(0, |m| m + 1);
    let in_fold = |p: &LabelledPair, f: usize| fold_of[p.i] == f && fold_of[p.j] == f;
    let has_both = |f: usize| {
        let mut pos_neg = (false, false);
        for p in score_pairs.iter().filter(|p| in_fold(p, f)) {
            if p.positive {
                pos_neg.0 = true;
            } else {
                pos_neg.1 = true;
            }
        }
        pos_neg.0 && pos_neg.1
    };
    let mut scored = Vec::new();
    let mut trained = Vec::new();
    let mut chosen = Vec::new();
    for f in 0..folds {
        if !has_both(f) {
            continue;
        }
        let (ci, t, inner) = if candidates.len() * params.rounds.len() > 1 {
            choose(score_pairs, candidates, fold_of, Some(f), params)?
        } else {
            (0, params.rounds[0], (f64::NAN, f64::NAN))
        };
        let c = &candidates[ci];
        let tag = ((f * folds + f) * candidates.len() + ci) as u64;
        let model = train_outside(c, fold_of, &[f], t, params.seed, tag)?;
        let (mut positives, mut negatives) = (0, 0);
        for k in (0..score_pairs.len()).filter(|&k| in_fold(&score_pairs[k], f)) {
            scored.push(ScoredPair {
                pair: score_pairs[k],
                fold: f,
                probability: model.probability(c.score_x[k].as_ref())?,
            });
        }
        for p in c.train_pairs {
            if fold_of[p.i] != f && fold_of[p.j] != f {
                if p.positive {
                    positives += 1;
                } else {
                    negatives += 1;
                }
            }
        }
        if c.balance == Balance::Subsample {
            negatives = negatives.min(positives);
        }
        trained.push((f, positives, positives + negatives));
        chosen.push(Choice {
            fold: f,
            candidate: ci,
            rounds: t,
            inner,
        });
    }
    Ok(NestedReport {
        report: report_from(scored, &trained, params.max_fpr)?,
        chosen,
    })
}

/// The inner cross-validation of [`nested_cross_validate`], also usable on its own to choose
/// the configuration of a deployed classifier: leaving out fold `exclude` (if any), for each
/// other fold `g` train every candidate at the largest `T` on pairs with no keyframe in
/// `exclude` or `g`, score the `score_pairs` inside `g`, pool over `g`, and return the
/// (candidate, `T`) with the highest TPR at FPR below the bound (ties: higher AUC, then the
/// earlier candidate and smaller `T`) with its (TPR, AUC).
///
/// # Errors
/// As [`nested_cross_validate`]; [`EvalError::Input`] if no candidate could be scored.
pub fn select_candidate<R: AsRef<[f64]>>(
    score_pairs: &[LabelledPair],
    candidates: &[Candidate<'_, R>],
    fold_of: &[usize],
    exclude: Option<usize>,
    params: &NestedParams,
) -> Result<Choice, EvalError> {
    check_candidates(score_pairs, candidates, fold_of, params)?;
    let (candidate, rounds, inner) = choose(score_pairs, candidates, fold_of, exclude, params)?;
    if !inner.0.is_finite() {
        return Err(EvalError::Input("no candidate could be scored".into()));
    }
    Ok(Choice {
        fold: exclude.unwrap_or(usize::MAX),
        candidate,
        rounds,
        inner,
    })
}

fn check_candidates<R: AsRef<[f64]>>(
    score_pairs: &[LabelledPair],
    candidates: &[Candidate<'_, R>],
    fold_of: &[usize],
    params: &NestedParams,
) -> Result<(), EvalError> {
    if candidates.is_empty() || params.rounds.is_empty() || params.rounds.contains(&0) {
        return Err(EvalError::Input(
            "nested cross-validation needs candidates and positive rounds".into(),
        ));
    }
    for c in candidates {
        check_rows(score_pairs, c.score_x, fold_of)?;
        check_rows(c.train_pairs, c.train_x, fold_of)?;
    }
    Ok(())
}

/// Trains candidate `c` on its pairs with no keyframe in the folds `out`.
fn train_outside<R: AsRef<[f64]>>(
    c: &Candidate<'_, R>,
    fold_of: &[usize],
    out: &[usize],
    rounds: usize,
    seed: u64,
    tag: u64,
) -> Result<LoopModel, EvalError> {
    let keep = |p: &LabelledPair| !out.contains(&fold_of[p.i]) && !out.contains(&fold_of[p.j]);
    let seed = chronomap_rng::derive_seed(seed, 0x11da_0003, tag, 0);
    LoopModel::train(
        c.train_pairs,
        c.train_x,
        keep,
        c.learner,
        c.balance,
        rounds,
        seed,
    )
}

fn choose<R: AsRef<[f64]>>(
    score_pairs: &[LabelledPair],
    candidates: &[Candidate<'_, R>],
    fold_of: &[usize],
    exclude: Option<usize>,
    params: &NestedParams,
) -> Result<(usize, usize, (f64, f64)), EvalError> {
    let folds = fold_of.iter().max().map_or(0, |m| m + 1);
    let t_max = *params.rounds.iter().max().unwrap_or(&1);
    let in_fold = |p: &LabelledPair, f: usize| fold_of[p.i] == f && fold_of[p.j] == f;
    let mut best = (0, params.rounds[0], (f64::NEG_INFINITY, f64::NEG_INFINITY));
    for (ci, c) in candidates.iter().enumerate() {
        // scores[t][..]: pooled inner scores at each T.
        let mut scores: Vec<Vec<f64>> = vec![Vec::new(); params.rounds.len()];
        let mut labels = Vec::new();
        for g in (0..folds).filter(|&g| Some(g) != exclude) {
            let test: Vec<usize> = (0..score_pairs.len())
                .filter(|&k| in_fold(&score_pairs[k], g))
                .collect();
            if test.is_empty() {
                continue;
            }
            let tag = ((exclude.unwrap_or(folds) * folds + g) * candidates.len() + ci) as u64;
            let out: Vec<usize> = exclude.into_iter().chain([g]).collect();
            let model = match train_outside(c, fold_of, &out, t_max, params.seed, tag) {
                Ok(m) => m,
                Err(EvalError::Train(_)) => continue,
                Err(e) => return Err(e),
            };
            for (ti, &t) in params.rounds.iter().enumerate() {
                let m = model.truncated(t);
                for &k in &test {
                    scores[ti].push(m.probability(c.score_x[k].as_ref())?);
                }
            }
            labels.extend(test.iter().map(|&k| score_pairs[k].positive));
        }
        if !(labels.contains(&true) && labels.contains(&false)) {
            continue;
        }
        for (ti, &t) in params.rounds.iter().enumerate() {
            let curve = roc(&scores[ti], &labels)?;
            let value = (threshold_for_fpr(&curve, params.max_fpr).tpr, auc(&curve));
            if value.0 > best.2.0 || (value.0 == best.2.0 && value.1 > best.2.1) {
                best = (ci, t, value);
            }
        }
    }
    Ok(best)
}

/// The most classifier trainings one cross-validated run may ask for ([`cv_trainings`]):
/// 1,000. The work grows with `layouts × folds` and, for the out-of-fold models of
/// [`PairModels`], with `folds²`: 100 folds and 10 layouts are 6,050 trainings, the command
/// line's default 5 folds and 10 layouts 65.
pub const MAX_TRAININGS: usize = 1_000;

/// Classifier trainings of `layouts` cross-validations over `folds` folds (one per fold) and,
/// with `pair_models`, of the `folds·(folds+1)/2` [`PairModels`] (saturating).
pub fn cv_trainings(folds: usize, layouts: usize, pair_models: bool) -> usize {
    let models = if pair_models {
        folds.saturating_mul(folds.saturating_add(1)) / 2
    } else {
        0
    };
    layouts.saturating_mul(folds).saturating_add(models)
}

/// The most AdaBoost rounds one cross-validated run may ask for ([`cv_rounds`]): 100,000.
/// [`MAX_TRAININGS`] counts trainings, but each runs `rounds` boosting rounds (up to
/// [`crate::adaboost::MAX_ROUNDS`]), and a round is a pass over every labelled pair (about
/// 1 ms for the 3,000 pairs of the Málaga keyframes): this bounds their product. The command
/// line's defaults (50 rounds, 5 folds, 10 layouts) take 3,250, the most trainings at 50
/// rounds 50,000.
pub const MAX_BOOSTING_ROUNDS: usize = 100_000;

/// AdaBoost rounds of a run of [`cv_trainings`] trainings of `rounds` rounds each (saturating).
pub fn cv_rounds(folds: usize, layouts: usize, pair_models: bool, rounds: usize) -> usize {
    cv_trainings(folds, layouts, pair_models).saturating_mul(rounds)
}

/// Classifiers for scoring *any* keyframe pair without having seen its keyframes: the model
/// for folds `a ≤ b` is trained on the pairs of keyframes outside both.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PairModels {
    /// The fold of each keyframe.
    pub fold_of: Vec<usize>,
    /// Number of folds.
    pub folds: usize,
    /// Model of folds `(a, b)`, `a ≤ b`, at `a·folds + b` (none without training data).
    pub models: Vec<Option<LoopModel>>,
}

impl PairModels {
    /// Trains the `folds·(folds+1)/2` models.
    ///
    /// # Errors
    /// As [`cross_validate`].
    pub fn train<R: AsRef<[f64]>>(
        pairs: &[LabelledPair],
        x: &[R],
        fold_of: &[usize],
        params: &CvParams,
    ) -> Result<PairModels, EvalError> {
        check_rows(pairs, x, fold_of)?;
        let folds = fold_of.iter().max().map_or(0, |m| m + 1);
        let mut models = vec![None; folds * folds];
        for a in 0..folds {
            for b in a..folds {
                let outside = |p: &LabelledPair| {
                    ![a, b].contains(&fold_of[p.i]) && ![a, b].contains(&fold_of[p.j])
                };
                let seed = chronomap_rng::derive_seed(params.seed, 0x11da_0002, a as u64, b as u64);
                let (rows, labels) = balanced(pairs, x, outside, seed);
                if labels.contains(&true) && labels.contains(&false) {
                    models[a * folds + b] = Some(LoopModel::Stumps(AdaBoost::fit(
                        &rows,
                        &labels,
                        None,
                        &params.adaboost,
                    )?));
                }
            }
        }
        Ok(PairModels {
            fold_of: fold_of.to_vec(),
            folds,
            models,
        })
    }

    /// Trains the `folds·(folds+1)/2` models of any configuration ([`LoopModel::train`] with
    /// `learner`, `balance` and `rounds`); a fold pair whose outside holds only one class gets
    /// no model. `done` is called after each fold pair (for a progress report).
    ///
    /// # Errors
    /// [`EvalError::Input`] for rows that do not match their pairs or a keyframe without a fold;
    /// [`EvalError::Train`] as [`LoopModel::train`].
    #[allow(clippy::too_many_arguments)] // the configuration's parts, then the progress report
    pub fn train_with<R: AsRef<[f64]>>(
        pairs: &[LabelledPair],
        x: &[R],
        fold_of: &[usize],
        learner: WeakLearner,
        balance: Balance,
        rounds: usize,
        seed: u64,
        done: &mut dyn FnMut(),
    ) -> Result<PairModels, EvalError> {
        check_rows(pairs, x, fold_of)?;
        let folds = fold_of.iter().max().map_or(0, |m| m + 1);
        let mut models = vec![None; folds * folds];
        for a in 0..folds {
            for b in a..folds {
                let outside = |p: &LabelledPair| {
                    ![a, b].contains(&fold_of[p.i]) && ![a, b].contains(&fold_of[p.j])
                };
                let (mut pos, mut neg) = (false, false);
                for p in pairs.iter().filter(|p| outside(p)) {
                    pos |= p.positive;
                    neg |= !p.positive;
                }
                if pos && neg {
                    let seed = chronomap_rng::derive_seed(seed, 0x11da_0004, a as u64, b as u64);
                    models[a * folds + b] = Some(LoopModel::train(
                        pairs, x, outside, learner, balance, rounds, seed,
                    )?);
                }
                done();
            }
        }
        Ok(PairModels {
            fold_of: fold_of.to_vec(),
            folds,
            models,
        })
    }

    /// The loop probability of keyframes `i` and `j` with pair features `x`, by the model that
    /// saw neither; `None` if there is none.
    ///
    /// # Errors
    /// As [`LoopModel::probability`].
    pub fn probability(&self, i: usize, j: usize, x: &[f64]) -> Result<Option<f64>, EvalError> {
        let (Some(&a), Some(&b)) = (self.fold_of.get(i), self.fold_of.get(j)) else {
            return Ok(None);
        };
        let (a, b) = (a.min(b), a.max(b));
        match &self.models[a * self.folds + b] {
            Some(m) => Ok(Some(m.probability(x)?)),
            None => Ok(None),
        }
    }
}

/// The folds of layout `layout` of `layouts`: [`sector_folds`] with the sectors rotated by
/// `layout/layouts` of a sector's width, so that the layouts together cover every rotation
/// once.
///
/// # Errors
/// As [`sector_folds`]; [`EvalError::Input`] for no layouts or `layout ≥ layouts`.
pub fn layout_folds(
    positions: &[[f64; 2]],
    folds: usize,
    layout: usize,
    layouts: usize,
) -> Result<Vec<usize>, EvalError> {
    if layout >= layouts || folds == 0 {
        return Err(EvalError::Input(format!(
            "fold layout {layout} of {layouts} with {folds} folds"
        )));
    }
    let width = std::f64::consts::TAU / (2 * folds) as f64;
    sector_folds(positions, folds, width * layout as f64 / layouts as f64)
}

/// Odometry increments `(dx, dy, dθ)`: `a ⊕ b` and `b` in the frame of `a`
/// ([`chronomap_geometry::se2`]).
pub use chronomap_geometry::se2::{between, compose};

/// The odometry increment from keyframe to keyframe: `odometry` holds `(time, [dx, dy, dθ])`
/// in time order, each the motion up to its time; the increment of keyframe `k` composes those
/// after keyframe `k − 1`'s time up to its own (keyframe 0 gets the identity).
pub fn keyframe_increments(odometry: &[(f64, [f64; 3])], keyframe_times: &[f64]) -> Vec<[f64; 3]> {
    let mut out = Vec::with_capacity(keyframe_times.len());
    let mut next = 0;
    for (k, &t) in keyframe_times.iter().enumerate() {
        let mut inc = [0.0; 3];
        while next < odometry.len() && odometry[next].0 <= t {
            if k > 0 {
                inc = compose(inc, odometry[next].1);
            }
            next += 1;
        }
        out.push(inc);
    }
    out
}

/// Settings of [`run_pipeline`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PipelineParams {
    /// The search (appendix A defaults, `p_min` to be set from cross-validation).
    pub search: SearchParams,
    /// Odometry noise of the dead-reckoning covariance.
    pub noise: OdometryNoise,
    /// Nodes this close in the sequence are not loop candidates (20).
    pub min_separation: usize,
    /// Keyframes before this index are an earlier session whose relation to the current one
    /// is unknown until the first loop links them (0: one session).
    pub session_start: usize,
    /// A detection is correct if the true positions are closer than this (3 m).
    pub near: f64,
}

impl Default for PipelineParams {
    fn default() -> Self {
        PipelineParams {
            search: SearchParams::default(),
            noise: OdometryNoise::default(),
            min_separation: 20,
            session_start: 0,
            near: 3.0,
        }
    }
}

/// An accepted loop.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    /// The new keyframe.
    pub query: usize,
    /// The node it closes the loop with.
    pub target: usize,
    /// The loop probability.
    pub probability: f64,
    /// Where the search looked.
    pub mode: SearchMode,
    /// The search radius (m; infinite for a global search).
    pub radius: f64,
    /// Candidates scored.
    pub candidates: usize,
    /// The true distance of the pair (m).
    pub true_distance: f64,
    /// Whether it is a true loop.
    pub correct: bool,
}

/// The result of [`run_pipeline`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PipelineReport {
    /// Accepted loops in sequence order.
    pub detections: Vec<Detection>,
    /// Keyframes that have a true loop partner among the eligible nodes.
    pub queries_with_loop: usize,
    /// Of those, keyframes whose search space held a true partner.
    pub queries_with_loop_in_space: usize,
    /// Of those, keyframes with a correct accepted loop.
    pub queries_closed: usize,
    /// True loop pairs (eligible node, query) in all.
    pub true_pairs: usize,
    /// Of those, pairs that were in the search space when the query came.
    pub true_pairs_in_space: usize,
    /// Pairs scored in all.
    pub scored_pairs: usize,
    /// Detections rejected by verification.
    pub rejected_by_verification: usize,
    /// The search radius at each keyframe (m; infinite for global searches).
    pub radii: Vec<f64>,
}

impl PipelineReport {
    /// Accepted loops that are true.
    pub fn correct(&self) -> usize {
        self.detections.iter().filter(|d| d.correct).count()
    }
    /// Accepted loops that are false.
    pub fn wrong(&self) -> usize {
        self.detections.len() - self.correct()
    }
}

/// Runs loop detection along a keyframe sequence ([Stüde 2024] §3.2.1): dead reckoning from
/// `increments` (robot frame, [`keyframe_increments`]) with the covariance of
/// [`propagate`]; at each keyframe `j` the nodes within the radius of eq. (3.8) around the
/// estimated sensor position (`sensor`: the laser's offset in the robot frame) — or all nodes
/// while `α < α_min` — that are more than `min_separation` keyframes back are scored with
/// `score(i, j)`; the most probable pair above `p_min` is a loop, verified by `n_ver` further
/// detections within `r_ver` while fewer than `n_start` loops were accepted. An accepted loop
/// resets the covariance and shifts the current pose estimate so that its scan's place is the
/// target node's (translation only; a stand-in for registration and graph optimisation, which
/// this crate does not do); the first link of a second session shifts that session's nodes
/// along. Detections are
/// judged by `truth` (true positions, e.g. SLAM poses).
///
/// # Errors
/// [`EvalError`] for inconsistent inputs, bad parameters, or a failing `score`.
pub fn run_pipeline(
    increments: &[[f64; 3]],
    sensor: [f64; 2],
    truth: &[[f64; 2]],
    params: &PipelineParams,
    mut score: impl FnMut(usize, usize) -> Result<Option<f64>, EvalError>,
) -> Result<PipelineReport, EvalError> {
    let n = increments.len();
    if truth.len() != n {
        return Err(EvalError::Input(format!(
            "{} true positions for {n} keyframes",
            truth.len()
        )));
    }
    check_positions(truth)?;
    if increments.iter().flatten().any(|v| !v.is_finite()) || !sensor.iter().all(|v| v.is_finite())
    {
        return Err(EvalError::Input(
            "an increment or the sensor offset is not finite".into(),
        ));
    }
    params.search.validate()?;
    let s = &params.search;
    let place = |pose: [f64; 3]| {
        let p = compose(pose, [sensor[0], sensor[1], 0.0]);
        [p[0], p[1]]
    };
    let dist = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
    let mut poses: Vec<[f64; 3]> = Vec::with_capacity(n);
    let mut pose = [0.0; 3];
    let mut cov = [[0.0; 3]; 3];
    let mut linked = params.session_start == 0;
    let mut report = PipelineReport {
        detections: Vec::new(),
        queries_with_loop: 0,
        queries_with_loop_in_space: 0,
        queries_closed: 0,
        true_pairs: 0,
        true_pairs_in_space: 0,
        scored_pairs: 0,
        rejected_by_verification: 0,
        radii: Vec::with_capacity(n),
    };
    for j in 0..n {
        if j == params.session_start && j > 0 {
            // A new session: its own frame, no knowledge of the old one.
            pose = [0.0; 3];
            cov = [[0.0; 3]; 3];
        } else if j > 0 {
            (pose, cov) = propagate(pose, cov, increments[j], &params.noise);
        }
        poses.push(pose);
        let places: Vec<[f64; 2]> = poses.iter().map(|&p| place(p)).collect();
        let here = places[j];
        // Before the second session starts, every node is local (no global search).
        let (n_local, n_wm) = if linked || j < params.session_start {
            (j + 1, j + 1)
        } else {
            (j + 1 - params.session_start, j + 1)
        };
        let mode = search_mode(n_local, n_wm, s.alpha_min);
        let old_session =
            |i: usize| !linked && i < params.session_start && j >= params.session_start;
        let eligible = |i: usize| i < j && (j - i > params.min_separation || old_session(i));
        let (candidates, radius) = match mode {
            SearchMode::Local => {
                let r = search_radius([[cov[0][0], cov[0][1]], [cov[1][0], cov[1][1]]], s)?;
                (within_radius(here, r, &places, eligible), r)
            }
            SearchMode::Global => ((0..j).filter(|&i| eligible(i)).collect(), f64::INFINITY),
        };
        report.radii.push(radius);
        let true_partners: Vec<usize> = (0..j)
            .filter(|&i| eligible(i) && dist(truth[i], truth[j]) < params.near)
            .collect();
        report.true_pairs += true_partners.len();
        let in_space = true_partners
            .iter()
            .filter(|i| candidates.contains(i))
            .count();
        report.true_pairs_in_space += in_space;
        if !true_partners.is_empty() {
            report.queries_with_loop += 1;
            if in_space > 0 {
                report.queries_with_loop_in_space += 1;
            }
        }
        let mut positives = Vec::new();
        for &i in &candidates {
            if let Some(p) = score(i, j)? {
                report.scored_pairs += 1;
                if p > s.p_min {
                    positives.push((i, p));
                }
            }
        }
        let Some(&(target, probability)) = positives.iter().max_by(|a, b| a.1.total_cmp(&b.1))
        else {
            continue;
        };
        if report.detections.len() < s.n_start {
            let detected: Vec<usize> = positives.iter().map(|p| p.0).collect();
            if !verified(target, &detected, &places, s) {
                report.rejected_by_verification += 1;
                continue;
            }
        }
        let d = dist(truth[target], truth[j]);
        let correct = d < params.near;
        report.detections.push(Detection {
            query: j,
            target,
            probability,
            mode,
            radius,
            candidates: candidates.len(),
            true_distance: d,
            correct,
        });
        if correct {
            report.queries_closed += 1;
        }
        // Shift the current pose (and an unlinked session) so that its scan's place is the
        // target's (translation only: the relative heading would come from registration).
        let first = if linked { j } else { params.session_start };
        let (dx, dy) = (places[target][0] - here[0], places[target][1] - here[1]);
        for p in &mut poses[first..=j] {
            p[0] += dx;
            p[1] += dy;
        }
        pose = poses[j];
        cov = [[0.0; 3]; 3];
        linked = true;
    }
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wrapped_error_says_its_cause_once() {
        // `lidar detect` printed "search: covariance: not finite: covariance: not finite": the
        // inner error was both in the message and returned as its source.
        let errors = [
            EvalError::from(
                search_radius([[f64::NAN, 0.0], [0.0, 1.0]], &SearchParams::default()).unwrap_err(),
            ),
            EvalError::from(roc(&[0.5], &[true]).unwrap_err()),
        ];
        assert_eq!(errors[0].to_string(), "search: covariance: not finite");
        assert_eq!(
            errors[1].to_string(),
            "roc: a ROC curve needs positives and negatives"
        );
        for e in &errors {
            assert!(std::error::Error::source(e).is_none(), "{e}");
        }
        let scan = crate::Scan2d::new(0.0, 0.0, 1.0, f64::NAN, vec![1.0, 2.0]).unwrap_err();
        let d = crate::descriptor::DescriptorError::from(scan);
        assert!(std::error::Error::source(&d).is_none(), "{d}");
    }

    #[test]
    fn labels_leave_out_the_ambiguous_band() {
        let positions = [[0.0, 0.0], [5.0, 0.0], [20.0, 0.0], [1.0, 0.0]];
        let p = LabelParams {
            min_separation: 2,
            ..LabelParams::default()
        };
        let pairs = label_pairs(&positions, &p).unwrap();
        // (0,3): 1 m, 3 apart → loop; (1,3): 4 m → ambiguous; (0,1): 5 m → ambiguous;
        // pairs with keyframe 2 (> 10 m) → negatives.
        let got: Vec<(usize, usize, bool)> = pairs.iter().map(|p| (p.i, p.j, p.positive)).collect();
        assert_eq!(
            got,
            vec![(0, 2, false), (1, 2, false), (0, 3, true), (2, 3, false)]
        );
    }

    #[test]
    fn nested_cv_chooses_the_informative_candidate_on_training_folds() {
        // 40 keyframes in 4 folds; every pair labelled; one feature set carries the label,
        // the other is noise.
        let fold_of: Vec<usize> = (0..40).map(|k| k % 4).collect();
        let mut pairs = Vec::new();
        for j in 0..40 {
            for i in 0..j {
                pairs.push(LabelledPair {
                    i,
                    j,
                    positive: (i + j) % 3 == 0,
                    distance: 0.0,
                });
            }
        }
        let noise = |k: usize| ((k * 2_654_435_761) % 1000) as f64 / 1000.0;
        let useless: Vec<Vec<f64>> = (0..pairs.len()).map(|k| vec![noise(k)]).collect();
        let useful: Vec<Vec<f64>> = pairs
            .iter()
            .enumerate()
            .map(|(k, p)| vec![f64::from(u8::from(p.positive)) + 0.1 * noise(k)])
            .collect();
        let candidate = |name: &str, x: &'static [Vec<f64>]| Candidate {
            name: name.into(),
            train_pairs: Box::leak(pairs.clone().into_boxed_slice()),
            train_x: x,
            score_x: x,
            learner: WeakLearner::Stump,
            balance: Balance::Weighted,
        };
        let useless: &'static [Vec<f64>] = Box::leak(useless.into_boxed_slice());
        let useful: &'static [Vec<f64>] = Box::leak(useful.into_boxed_slice());
        let cs = [candidate("noise", useless), candidate("label", useful)];
        let params = NestedParams {
            rounds: vec![1, 5],
            ..NestedParams::default()
        };
        let r = nested_cross_validate(&pairs, &cs, &fold_of, &params).unwrap();
        assert_eq!(r.chosen.len(), 4);
        for c in &r.chosen {
            assert_eq!(c.candidate, 1, "{c:?}");
            // Both T separate perfectly: the tie goes to the smaller T.
            assert_eq!((c.rounds, c.inner), (1, (1.0, 1.0)));
        }
        assert_eq!(r.report.pooled_auc, 1.0);
        // Each outer fold scored only its own pairs.
        assert!(r.report.scored.iter().all(|s| fold_of[s.pair.i] == s.fold));
        let all = select_candidate(&pairs, &cs, &fold_of, None, &params).unwrap();
        assert_eq!((all.candidate, all.rounds), (1, 1));
        assert!(nested_cross_validate(&pairs, &cs[..0], &fold_of, &params).is_err());
    }

    #[test]
    fn the_trainings_of_a_run_are_counted_before_it() {
        // Per layout one model per fold; eval's out-of-fold models one per fold pair a ≤ b.
        assert_eq!(cv_trainings(5, 10, true), 10 * 5 + 15);
        assert_eq!(cv_trainings(100, 10, true), 1000 + 5050);
        assert_eq!(cv_trainings(30, 10, false), 300);
        assert_eq!(cv_trainings(usize::MAX, 2, true), usize::MAX);
        // Each training boosts `rounds` times: the defaults 65 × 50, the most trainings at
        // the default rounds 1,000 × 50, both within the bound; 65 × 2,000 is not.
        assert_eq!(cv_rounds(5, 10, true, 50), 3_250);
        assert_eq!(cv_rounds(5, 10, false, 50), 2_500);
        assert_eq!(cv_rounds(30, 10, true, 50), 38_250);
        assert_eq!(cv_rounds(2, 500, false, 50), MAX_TRAININGS * 50);
        assert!(cv_rounds(2, 500, false, 50) <= MAX_BOOSTING_ROUNDS);
        assert_eq!(cv_rounds(5, 10, true, 2_000), 130_000);
        assert!(cv_rounds(5, 10, true, 2_000) > MAX_BOOSTING_ROUNDS);
        assert_eq!(cv_rounds(2, 1, false, usize::MAX), usize::MAX);
        // The pair models report each fold pair: 4 folds, 10 pairs (a ≤ b).
        let fold_of: Vec<usize> = (0..12).map(|k| k % 4).collect();
        let mut pairs = Vec::new();
        for j in 0..12 {
            for i in 0..j {
                pairs.push(LabelledPair {
                    i,
                    j,
                    positive: (i + j) % 3 == 0,
                    distance: 0.0,
                });
            }
        }
        let x: Vec<Vec<f64>> = pairs
            .iter()
            .map(|p| vec![f64::from(u8::from(p.positive))])
            .collect();
        let mut done = 0;
        let models = PairModels::train_with(
            &pairs,
            &x,
            &fold_of,
            WeakLearner::Stump,
            Balance::Weighted,
            3,
            1,
            &mut || done += 1,
        )
        .unwrap();
        assert_eq!(done, cv_trainings(4, 0, true));
        assert_eq!(done, 10);
        assert_eq!(models.models.iter().filter(|m| m.is_some()).count(), 10);
    }

    #[test]
    fn increments_compose_between_keyframe_times() {
        let q = std::f64::consts::FRAC_PI_2;
        let odo = [
            (1.0, [1.0, 0.0, q]),
            (2.0, [1.0, 0.0, 0.0]),
            (3.0, [1.0, 0.0, 0.0]),
        ];
        let inc = keyframe_increments(&odo, &[1.0, 3.0]);
        assert_eq!(inc[0], [0.0; 3]);
        // Forward 1 then forward 1 again (no turn in between): 2 m ahead.
        assert!((inc[1][0] - 2.0).abs() < 1e-12 && inc[1][1].abs() < 1e-12);
        let c = compose([0.0, 0.0, q], [1.0, 0.0, 0.0]);
        assert!(c[0].abs() < 1e-12 && (c[1] - 1.0).abs() < 1e-12);
    }

    /// A straight corridor driven out and back: keyframes every metre; the way back revisits
    /// the way out. With a perfect scorer, loops are found once the return passes the start
    /// of the corridor.
    #[test]
    fn pipeline_with_a_perfect_scorer_closes_true_loops_only() {
        let mut truth = Vec::new();
        let mut inc = Vec::new();
        for k in 0..30 {
            truth.push([k as f64, 0.0]);
            inc.push(if k == 0 { [0.0; 3] } else { [1.0, 0.0, 0.0] });
        }
        for k in 0..30 {
            truth.push([29.0 - k as f64, 0.0]);
            inc.push(if k == 0 {
                [0.0, 0.0, std::f64::consts::PI]
            } else {
                [1.0, 0.0, 0.0]
            });
        }
        let truth_c = truth.clone();
        let score = |i: usize, j: usize| -> Result<Option<f64>, EvalError> {
            let d = (truth_c[i][0] - truth_c[j][0]).hypot(truth_c[i][1] - truth_c[j][1]);
            Ok(Some(if d < 1.5 { 0.8 } else { 0.2 }))
        };
        let params = PipelineParams::default();
        let report = run_pipeline(&inc, [0.0, 0.0], &truth, &params, score).unwrap();
        assert_eq!(report.wrong(), 0);
        assert!(report.correct() > 10, "{report:?}");
        // The first detections needed two further detections within 5 m of the target.
        let first = report.detections[0];
        assert!(first.query > 40 && first.correct);
        // The radius grows between loops and falls back to r_min after one.
        assert!(report.radii[first.query] > 3.0);
        let expected = 3.0 + 0.5 * (5.991f64 * 0.0025).sqrt();
        assert!((report.radii[first.query + 1] - expected).abs() < 1e-12);
    }
}
