//! The straightforward reference of eqs. 5.1–5.2: the dense generator `Q` of a [`Chain`]
//! (transient states, then `S`, then `F`) and its transient solution by dense uniformisation
//! (`π_{k+1} = π_k P`, `P = I + Q/Λ`, one full matrix–vector product per jump). Slow and
//! simple on purpose: it is the oracle of the sparse [`Chain::transient`] and of the person
//! search's fast synthesis (`chronomap-psbt`).

use super::{Chain, Outcome, SbtError, Target, check_query, poisson_truncation, poisson_weights};

/// A dense generator: `n × n` row-major rates (`q[i·n + j]`, `i ≠ j`: rate from `i` to `j`;
/// the diagonal makes each row sum to 0) and the initial distribution, with the transient
/// states first, then `S` (index `n − 2`) and `F` (index `n − 1`).
#[derive(Clone, Debug, PartialEq)]
pub struct DenseGenerator {
    /// Number of states, absorbing ones included.
    pub n: usize,
    /// Row-major generator.
    pub q: Vec<f64>,
    /// Initial distribution `π₀`.
    pub initial: Vec<f64>,
}

impl DenseGenerator {
    /// The generator of `chain`.
    pub fn of(chain: &Chain) -> Self {
        let states = chain.states();
        let n = states + 2;
        let index = |t: Target| match t {
            Target::State(j) => j,
            Target::Success => n - 2,
            Target::Failure => n - 1,
        };
        let mut q = vec![0.0; n * n];
        for (i, out) in chain.exits().iter().enumerate() {
            for &(target, rate) in out {
                q[i * n + index(target)] += rate;
                q[i * n + i] -= rate;
            }
        }
        let mut initial = vec![0.0; n];
        for &(target, p) in chain.initial() {
            initial[index(target)] += p;
        }
        DenseGenerator { n, q, initial }
    }

    /// `p_{s,T}(t)`, `p_{f,T}(t)` at each time by dense uniformisation, truncated where the
    /// Poisson tail is below `tolerance`.
    ///
    /// # Errors
    /// [`SbtError::Query`] for a negative or non-finite time or a tolerance outside `(0, 1)`.
    pub fn transient(&self, times: &[f64], tolerance: f64) -> Result<Vec<Outcome>, SbtError> {
        check_query(times, tolerance)?;
        let n = self.n;
        let lambda = (0..n)
            .map(|i| -self.q[i * n + i])
            .fold(0.0, f64::max)
            .max(f64::MIN_POSITIVE);
        let t_max = times.iter().copied().fold(0.0, f64::max);
        let steps = poisson_truncation(lambda * t_max, tolerance);
        let mut p = self.q.iter().map(|&x| x / lambda).collect::<Vec<f64>>();
        for i in 0..n {
            p[i * n + i] += 1.0;
        }
        let mut pi = self.initial.clone();
        let mut history = vec![(pi[n - 2], pi[n - 1])];
        for _ in 0..steps {
            let mut next = vec![0.0; n];
            for i in 0..n {
                for j in 0..n {
                    next[j] += pi[i] * p[i * n + j];
                }
            }
            pi = next;
            history.push((pi[n - 2], pi[n - 1]));
        }
        Ok(times
            .iter()
            .map(|&t| {
                let (w, tail) = poisson_weights(lambda * t, steps);
                Outcome {
                    p_success: w.iter().zip(&history).map(|(w, h)| w * h.0).sum(),
                    p_failure: w.iter().zip(&history).map(|(w, h)| w * h.1).sum(),
                    error_bound: tail,
                }
            })
            .collect())
    }
}
