//! Models of human activity as a rate function `λ(x, t)` (§5.4.1), and the piece-wise
//! homogeneous grid Poisson model of eq. 5.7.

use std::collections::{HashMap, HashSet};

use super::PsbtError;
use chronomap_activity::CopaMap;
use chronomap_activity::truth::TrackPoint;
use chronomap_core::num::{count_of, fmt_number};
use chronomap_core::par::Parallelism;

/// A spatio-temporal rate of people `λ(x, t)` (§5.4.1): any chronomap activity model can drive
/// the person search by implementing this.
pub trait RateField: Sync {
    /// `λ(x, t)`: people appearing per second per square metre at `x` (metres, map frame) at
    /// time `t` (seconds). Finite and `≥ 0`.
    fn density(&self, x: [f64; 2], t: f64) -> f64;

    /// `∫_D λ(x', t) dx'` over the disc `D` of `radius` around `centre` (eqs. 5.9 and 5.14):
    /// the rate of people (1/s) a robot at `centre` with a detection radius `radius` meets.
    /// The default integrates [`RateField::density`] by the midpoint rule on a square lattice
    /// of `radius/16` (about 800 evaluations; 1 % error for a flat field).
    fn disc_rate(&self, centre: [f64; 2], radius: f64, t: f64) -> f64 {
        let h = radius / 16.0;
        let mut total = 0.0;
        for i in -16..16 {
            for j in -16..16 {
                let dx = (f64::from(i) + 0.5) * h;
                let dy = (f64::from(j) + 0.5) * h;
                if dx * dx + dy * dy <= radius * radius {
                    total += self.density([centre[0] + dx, centre[1] + dy], t);
                }
            }
        }
        total * h * h
    }
}

/// The cells and time intervals of a [`GridPoisson`] model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridSpec {
    /// Lower-left corner of cell (0, 0), metres.
    pub origin: [f64; 2],
    /// Side of a cell in metres (1 m in §5.4.4).
    pub cell: f64,
    /// Cells along x.
    pub cols: usize,
    /// Cells along y.
    pub rows: usize,
    /// Start of interval 0 (seconds).
    pub t0: f64,
    /// Length of an interval `[t_τ, t_{τ+1})` in seconds.
    pub interval: f64,
    /// Number of intervals.
    pub intervals: usize,
}

/// The Gamma prior `Γ(α, β)` of a cell's rate (people per second): `α` pseudo-people seen in
/// `β` pseudo-seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GammaPrior {
    /// Shape `α > 0`.
    pub alpha: f64,
    /// Rate `β > 0` (seconds).
    pub beta: f64,
}

impl Default for GammaPrior {
    /// A weak prior: 0.01 people in 60 s (0.6 people per hour, worth a minute of data).
    fn default() -> Self {
        GammaPrior {
            alpha: 0.01,
            beta: 60.0,
        }
    }
}

/// The grid model of eq. 5.7: `λ(x, t) ≈ Σ_ij λ_ijτ 1_ijτ(x)`, a homogeneous Poisson process
/// per cell and time interval. `λ_ijτ` is the posterior mean `α/β` of a Gamma prior updated with
/// the people counted in the cell (`α += c`) and the seconds it was observed (`β += Δ`) in the
/// interval (\[LDA11\] in the dissertation). An interval in which a cell was never observed (e.g. an hour after the
/// training data) uses the cell's pooled posterior over all intervals; outside the grid the
/// rate is 0 (the grid covers the environment).
#[derive(Clone, Debug, PartialEq)]
pub struct GridPoisson {
    spec: GridSpec,
    prior: GammaPrior,
    /// People counted, per interval then cell.
    counts: Vec<f64>,
    /// Seconds observed, per interval then cell.
    seconds: Vec<f64>,
    /// Per cell, over all intervals: (people, seconds).
    pooled: Vec<(f64, f64)>,
}

impl GridPoisson {
    /// A model that has seen nothing.
    ///
    /// # Errors
    /// [`PsbtError::Config`] for an empty grid, a cell or interval that is not a positive
    /// number, a non-finite origin or `t0`, or a prior with `α` or `β` not positive.
    pub fn new(spec: GridSpec, prior: GammaPrior) -> Result<Self, PsbtError> {
        let cells = spec.cols.checked_mul(spec.rows).unwrap_or(0);
        let total = cells.checked_mul(spec.intervals).unwrap_or(0);
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if total == 0 || total > 1 << 28 {
            return Err(PsbtError::Config(format!(
                "a grid of {} x {} cells and {} intervals",
                spec.cols, spec.rows, spec.intervals
            )));
        }
        if !(positive(spec.cell) && positive(spec.interval)) {
            return Err(PsbtError::Config(format!(
                "cell {} m and interval {} s must be positive numbers",
                spec.cell, spec.interval
            )));
        }
        if !(spec.origin.iter().all(|v| v.is_finite()) && spec.t0.is_finite()) {
            return Err(PsbtError::Config("the origin or t0 is not finite".into()));
        }
        if !(positive(prior.alpha) && positive(prior.beta)) {
            return Err(PsbtError::Config(format!(
                "the Gamma prior ({}, {}) needs positive parameters",
                prior.alpha, prior.beta
            )));
        }
        Ok(GridPoisson {
            spec,
            prior,
            counts: vec![0.0; total],
            seconds: vec![0.0; total],
            pooled: vec![(0.0, 0.0); cells],
        })
    }

    /// Learns from pedestrian tracks seen by sensors that cover the whole grid (as the ATC
    /// tracking system): in every interval, `c` is the number of distinct people detected in
    /// the cell (as [`chronomap_activity::truth`] counts them) and `Δ` the time from the first to
    /// the last detection of the interval (plus one second), the same for every cell.
    ///
    /// # Errors
    /// As [`GridPoisson::new`]; [`PsbtError::Config`] for a detection with a non-finite time or
    /// position.
    pub fn from_tracks(
        points: &[TrackPoint],
        spec: GridSpec,
        prior: GammaPrior,
    ) -> Result<Self, PsbtError> {
        let mut model = GridPoisson::new(spec, prior)?;
        let cells = spec.cols * spec.rows;
        let mut seen: HashSet<(usize, usize, u64)> = HashSet::new();
        let mut spans: HashMap<usize, (f64, f64)> = HashMap::new();
        for (i, p) in points.iter().enumerate() {
            if !(p.t.is_finite() && p.x.is_finite() && p.y.is_finite()) {
                return Err(PsbtError::Config(format!(
                    "detection {i} has a non-finite time or position"
                )));
            }
            let Some(interval) = model.interval_of(p.t) else {
                continue;
            };
            let span = spans.entry(interval).or_insert((p.t, p.t));
            span.0 = span.0.min(p.t);
            span.1 = span.1.max(p.t);
            if let Some(cell) = model.cell_of([p.x, p.y])
                && seen.insert((interval, cell, p.person))
            {
                model.counts[interval * cells + cell] += 1.0;
            }
        }
        for (interval, (first, last)) in spans {
            let observed = (last - first + 1.0).min(spec.interval);
            for cell in 0..cells {
                model.seconds[interval * cells + cell] = observed;
            }
        }
        model.pool();
        Ok(model)
    }

    /// Adds `people` counted in `seconds` of observation of the cell at `x` in the interval of
    /// `t` (eq. 5.7's Bayesian update). Ignored outside the grid.
    ///
    /// # Errors
    /// [`PsbtError::Config`] unless both are finite and `≥ 0`.
    pub fn observe(
        &mut self,
        x: [f64; 2],
        t: f64,
        people: f64,
        seconds: f64,
    ) -> Result<(), PsbtError> {
        if !(people.is_finite() && people >= 0.0 && seconds.is_finite() && seconds >= 0.0) {
            return Err(PsbtError::Config(format!(
                "{people} people in {seconds} s is not a count over a duration"
            )));
        }
        if let (Some(cell), Some(interval)) = (self.cell_of(x), self.interval_of(t)) {
            let i = interval * self.spec.cols * self.spec.rows + cell;
            self.counts[i] += people;
            self.seconds[i] += seconds;
            self.pooled[cell].0 += people;
            self.pooled[cell].1 += seconds;
        }
        Ok(())
    }

    fn pool(&mut self) {
        let cells = self.pooled.len();
        for (cell, pooled) in self.pooled.iter_mut().enumerate() {
            *pooled = (0..self.spec.intervals).fold((0.0, 0.0), |(c, s), k| {
                (
                    c + self.counts[k * cells + cell],
                    s + self.seconds[k * cells + cell],
                )
            });
        }
    }

    /// The grid.
    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    /// The cell containing `x`.
    pub fn cell_of(&self, x: [f64; 2]) -> Option<usize> {
        let c = ((x[0] - self.spec.origin[0]) / self.spec.cell).floor();
        let r = ((x[1] - self.spec.origin[1]) / self.spec.cell).floor();
        (c >= 0.0 && r >= 0.0 && c < self.spec.cols as f64 && r < self.spec.rows as f64)
            .then(|| r as usize * self.spec.cols + c as usize)
    }

    /// The interval containing `t`.
    pub fn interval_of(&self, t: f64) -> Option<usize> {
        let k = ((t - self.spec.t0) / self.spec.interval).floor();
        (k >= 0.0 && k < self.spec.intervals as f64).then_some(k as usize)
    }

    /// `λ_ijτ` of the cell at `x` at time `t` in people per second ([`GridPoisson`] says which
    /// posterior applies).
    pub fn cell_rate(&self, x: [f64; 2], t: f64) -> f64 {
        let GammaPrior { alpha, beta } = self.prior;
        let Some(cell) = self.cell_of(x) else {
            return 0.0;
        };
        let cells = self.pooled.len();
        match self.interval_of(t) {
            Some(k) if self.seconds[k * cells + cell] > 0.0 => {
                (alpha + self.counts[k * cells + cell]) / (beta + self.seconds[k * cells + cell])
            }
            _ => {
                let (c, s) = self.pooled[cell];
                (alpha + c) / (beta + s)
            }
        }
    }

    /// Whether anybody was ever counted in the cell at `x`.
    pub fn has_detections(&self, x: [f64; 2]) -> bool {
        self.cell_of(x).is_some_and(|c| self.pooled[c].0 > 0.0)
    }
}

impl RateField for GridPoisson {
    fn density(&self, x: [f64; 2], t: f64) -> f64 {
        self.cell_rate(x, t) / (self.spec.cell * self.spec.cell)
    }

    /// Exact for the piece-wise constant density up to the area of each cell inside the disc,
    /// which is measured on 6 × 6 points per cell.
    fn disc_rate(&self, centre: [f64; 2], radius: f64, t: f64) -> f64 {
        let s = self.spec.cell;
        let (ox, oy) = (self.spec.origin[0], self.spec.origin[1]);
        // Only the grid's cells have a rate (0 outside), so the disc's cell range is clamped
        // to the grid: a huge radius cannot make a huge loop, and a saturated (or NaN → 0)
        // index is clamped like any other.
        let clamp = |v: f64, n: usize| (v.floor() as i64).clamp(0, n as i64 - 1);
        let (cols, rows) = (self.spec.cols, self.spec.rows);
        let c0 = clamp((centre[0] - radius - ox) / s, cols);
        let c1 = clamp((centre[0] + radius - ox) / s, cols);
        let r0 = clamp((centre[1] - radius - oy) / s, rows);
        let r1 = clamp((centre[1] + radius - oy) / s, rows);
        const N: usize = 6;
        let mut total = 0.0;
        for r in r0..=r1 {
            for c in c0..=c1 {
                let (x0, y0) = (ox + c as f64 * s, oy + r as f64 * s);
                let mut inside = 0usize;
                for i in 0..N {
                    let dx = x0 + (i as f64 + 0.5) * s / N as f64 - centre[0];
                    for j in 0..N {
                        let dy = y0 + (j as f64 + 0.5) * s / N as f64 - centre[1];
                        inside += usize::from(dx * dx + dy * dy <= radius * radius);
                    }
                }
                if inside > 0 {
                    let rate = self.cell_rate([x0 + s / 2.0, y0 + s / 2.0], t);
                    total += rate * inside as f64 / (N * N) as f64;
                }
            }
        }
        total
    }
}

/// The activity of a fitted CoPA-Map ([Stüde 2024] §4.2) as a [`RateField`] for the person search
/// (§5.4.1): the grid model of eq. 5.7 whose cells are those the model was trained on, each
/// with the model's predicted rate at its centre at the model time `model_t`.
///
/// Units: CoPA-Map predicts people per hour of observation in a cell of side `cell` metres
/// (the ATC grid: 0.5 m), so a cell's rate is `y / 3600` people per second and the density
/// `y / (3600 · cell²)` people per second and square metre, which is what
/// [`RateField::density`] returns. Time: the field is the model at `model_t` (in the model's
/// own `t` units, hour bins for the ATC grid) at every query time — the person search
/// evaluates its rates at the request time only (eqs. 5.9 and 5.14), and the caller maps that
/// time onto the model's axis. Space: the cells tile the model's training square
/// ([`CopaMap::domain`], widened by half a cell to the cell edges); outside it the rate is 0,
/// as for [`GridPoisson`].
///
/// # Errors
/// [`PsbtError::Config`] for a cell that is not a positive number, a non-finite `model_t`, a
/// training square of more than 2²⁸ cells, or a prediction that fails or is not finite.
pub fn copa_field(
    model: &CopaMap,
    cell: f64,
    model_t: f64,
    parallelism: Parallelism,
) -> Result<GridPoisson, PsbtError> {
    if !(cell.is_finite() && cell > 0.0 && model_t.is_finite()) {
        return Err(PsbtError::Config(format!(
            "CoPA-Map cell {cell} m at t = {model_t}: need a positive cell and a finite time"
        )));
    }
    let [x0, y0, x1, y1] = model.domain();
    let origin = [x0 - cell / 2.0, y0 - cell / 2.0];
    let count = |span: f64| {
        count_of((span / cell).round() + 1.0, crate::world::MAX_COUNT).ok_or_else(|| {
            PsbtError::Config(format!(
                "CoPA-Map cell {} m over a training square {} m wide gives more than {} cells \
                 across",
                fmt_number(cell),
                fmt_number(span),
                crate::world::MAX_COUNT
            ))
        })
    };
    let cols = count(x1 - x0)?;
    let rows = count(y1 - y0)?;
    // One interval of an hour: a cell "observed for 3600 s with y people" has rate y/3600 per
    // second. The prior is negligible (1e-300 people in 1e-300 s).
    let spec = GridSpec {
        origin,
        cell,
        cols,
        rows,
        t0: 0.0,
        interval: 3600.0,
        intervals: 1,
    };
    let prior = GammaPrior {
        alpha: 1e-300,
        beta: 1e-300,
    };
    let mut field = GridPoisson::new(spec, prior)?;
    let centres: Vec<([f64; 2], f64)> = (0..rows)
        .flat_map(|r| {
            (0..cols).map(move |c| {
                (
                    [
                        origin[0] + (c as f64 + 0.5) * cell,
                        origin[1] + (r as f64 + 0.5) * cell,
                    ],
                    model_t,
                )
            })
        })
        .collect();
    let (mean, _) = model
        .predict_with_std(&centres, parallelism)
        .map_err(|e| PsbtError::Config(format!("CoPA-Map prediction: {e}")))?;
    for (&(x, _), &per_hour) in centres.iter().zip(&mean) {
        if !(per_hour.is_finite() && per_hour >= 0.0) {
            return Err(PsbtError::Config(format!(
                "CoPA-Map predicts {per_hour} people per hour at ({}, {})",
                x[0], x[1]
            )));
        }
        field.observe(x, 0.0, per_hour, 3600.0)?;
    }
    Ok(field)
}
