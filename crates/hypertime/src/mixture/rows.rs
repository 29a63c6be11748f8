//! Validated weighted rows, their weighted moments, and fixed-size chunking (results never
//! depend on the number of threads: chunks are fixed, partial sums reduced in chunk order).

use chronomap_core::Parallelism;
use rayon::prelude::*;

use super::MixtureError;

/// Rows per chunk of the per-row loops. Fixed, so that sums are the same on any thread pool.
pub(super) const CHUNK: usize = 2048;

/// `n × dim` row-major data with optional non-negative weights, checked.
#[derive(Clone, Copy, Debug)]
pub(super) struct Rows<'a> {
    pub x: &'a [f64],
    pub dim: usize,
    pub n: usize,
    pub w: Option<&'a [f64]>,
    /// Sum of the weights (`n` without weights).
    pub total: f64,
    /// Threads the per-chunk loops may use ([`Parallelism::Sequential`] unless
    /// [`Rows::with_parallelism`] says otherwise).
    pub parallelism: Parallelism,
}

impl<'a> Rows<'a> {
    /// Checks shapes, finiteness and weights.
    pub fn new(x: &'a [f64], dim: usize, w: Option<&'a [f64]>) -> Result<Self, MixtureError> {
        if dim == 0 {
            return Err(MixtureError::DimensionMismatch(
                "dim must be at least 1".into(),
            ));
        }
        if !x.len().is_multiple_of(dim) {
            return Err(MixtureError::DimensionMismatch(format!(
                "{} values are not a multiple of dim {dim}",
                x.len()
            )));
        }
        let n = x.len() / dim;
        if let Some(w) = w
            && w.len() != n
        {
            return Err(MixtureError::DimensionMismatch(format!(
                "{} weights for {n} rows",
                w.len()
            )));
        }
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Err(MixtureError::NonFinite {
                row: i / dim,
                coordinate: i % dim,
                value: x[i],
            });
        }
        let total = match w {
            Some(w) => {
                if let Some(i) = w.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
                    return Err(MixtureError::InvalidWeight {
                        row: i,
                        weight: w[i],
                    });
                }
                w.iter().sum()
            }
            None => n as f64,
        };
        if n == 0 || total.is_nan() || total <= 0.0 {
            return Err(MixtureError::EmptyData);
        }
        if !total.is_finite() {
            return Err(MixtureError::InvalidWeight {
                row: 0,
                weight: total,
            });
        }
        Ok(Rows {
            x,
            dim,
            n,
            w,
            total,
            parallelism: Parallelism::Sequential,
        })
    }

    /// The same rows, their chunks run on the threads `parallelism` allows.
    pub fn with_parallelism(self, parallelism: Parallelism) -> Self {
        Rows {
            parallelism,
            ..self
        }
    }

    /// Fewest chunks a rayon task takes, so that the chunks split into at most
    /// `parallelism.tasks()` tasks (1 for `Rayon(0)`: as the pool likes).
    fn min_chunks(&self) -> usize {
        match self.parallelism {
            Parallelism::Rayon(0) | Parallelism::Sequential => 1,
            par => self.chunks().div_ceil(par.tasks()).max(1),
        }
    }

    /// Row `i`.
    #[inline]
    pub fn row(&self, i: usize) -> &'a [f64] {
        &self.x[i * self.dim..(i + 1) * self.dim]
    }

    /// Weight of row `i`.
    #[inline]
    pub fn weight(&self, i: usize) -> f64 {
        self.w.map_or(1.0, |w| w[i])
    }

    /// `min(k, number of distinct rows of positive weight)` (`-0.0 == 0.0`).
    pub fn distinct_up_to(&self, k: usize) -> usize {
        let mut found: Vec<usize> = Vec::with_capacity(k.min(self.n));
        for i in 0..self.n {
            if found.len() >= k {
                break;
            }
            if self.weight(i) > 0.0 && found.iter().all(|&j| self.row(j) != self.row(i)) {
                found.push(i);
            }
        }
        found.len()
    }

    /// Weighted mean and weighted (population) covariance, `dim × dim` row-major (two
    /// passes, centred).
    pub fn mean_covariance(&self) -> (Vec<f64>, Vec<f64>) {
        let d = self.dim;
        let mut mean = vec![0.0; d];
        for i in 0..self.n {
            let w = self.weight(i);
            if w == 0.0 {
                continue;
            }
            for (m, x) in mean.iter_mut().zip(self.row(i)) {
                *m += w * x;
            }
        }
        mean.iter_mut().for_each(|m| *m /= self.total);
        let mut cov = vec![0.0; d * d];
        let mut diff = vec![0.0; d];
        for i in 0..self.n {
            let w = self.weight(i);
            if w == 0.0 {
                continue;
            }
            for ((e, x), m) in diff.iter_mut().zip(self.row(i)).zip(&mean) {
                *e = x - m;
            }
            for a in 0..d {
                let wa = w * diff[a];
                for b in 0..=a {
                    cov[a * d + b] += wa * diff[b];
                }
            }
        }
        for a in 0..d {
            for b in 0..=a {
                let v = cov[a * d + b] / self.total;
                cov[a * d + b] = v;
                cov[b * d + a] = v;
            }
        }
        (mean, cov)
    }

    /// Number of chunks of [`CHUNK`] rows.
    pub fn chunks(&self) -> usize {
        self.n.div_ceil(CHUNK)
    }

    /// `f(first_row, rows)` for every chunk of [`CHUNK`] rows; the partial results in chunk
    /// order. Runs as rayon tasks when there is more than one chunk and
    /// [`Rows::parallelism`] allows; the results are the same either way.
    pub fn map_chunks<P, F>(&self, f: F) -> Vec<P>
    where
        P: Send,
        F: Fn(usize, usize) -> P + Sync + Send,
    {
        let n = self.n;
        let run = |c: usize| {
            let start = c * CHUNK;
            f(start, CHUNK.min(n - start))
        };
        match self.parallelism {
            _ if self.chunks() <= 1 => vec![run(0)],
            Parallelism::Sequential => (0..self.chunks()).map(run).collect(),
            Parallelism::Rayon(_) => (0..self.chunks())
                .into_par_iter()
                .with_min_len(self.min_chunks())
                .map(run)
                .collect(),
        }
    }

    /// As [`Rows::map_chunks`], with per-row outputs: `a` holds `stride_a >= 1` values per
    /// row and `b` `stride_b >= 1`; `f(first_row, rows, a_chunk, b_chunk)`.
    pub fn map_chunks_mut<A, B, P, F>(
        &self,
        a: &mut [A],
        stride_a: usize,
        b: &mut [B],
        stride_b: usize,
        f: F,
    ) -> Vec<P>
    where
        A: Send,
        B: Send,
        P: Send,
        F: Fn(usize, usize, &mut [A], &mut [B]) -> P + Sync + Send,
    {
        assert!(stride_a > 0 && stride_b > 0);
        assert!(a.len() == self.n * stride_a && b.len() == self.n * stride_b);
        let n = self.n;
        let run = |(c, (a, b)): (usize, (&mut [A], &mut [B]))| {
            let start = c * CHUNK;
            f(start, CHUNK.min(n - start), a, b)
        };
        match self.parallelism {
            _ if self.chunks() <= 1 => vec![run((0, (a, b)))],
            Parallelism::Sequential => a
                .chunks_mut(CHUNK * stride_a)
                .zip(b.chunks_mut(CHUNK * stride_b))
                .enumerate()
                .map(run)
                .collect(),
            Parallelism::Rayon(_) => a
                .par_chunks_mut(CHUNK * stride_a)
                .zip(b.par_chunks_mut(CHUNK * stride_b))
                .enumerate()
                .with_min_len(self.min_chunks())
                .map(run)
                .collect(),
        }
    }
}
