//! The atomic actions of §5.4.2 as SBT actions: *Wait at place x_i* (eqs. 5.9–5.12), *Search
//! from x_i to x_j* (eqs. 5.13–5.19) and *Move to x_0* (a search that can only fail by
//! navigation).

use super::PsbtConfig;
use chronomap_bt_stochastic::{Action, SbtError};

/// Smallest rate of people used (1/s): below it a wait would never end in any horizon that
/// matters, and eq. 5.11 would divide by zero.
pub const MIN_RATE: f64 = 1e-12;

/// `T' = −ln(1 − p'_s) / μ_w` (eq. 5.11): how long a wait lasts before it fails, chosen so that
/// a person appears within it with the confidence `p'_s`.
pub fn wait_timeout(mu_w: f64, confidence: f64) -> f64 {
    -(1.0 - confidence).ln() / mu_w.max(MIN_RATE)
}

/// The wait action `W_{A,i}` at a place where people appear with rate `μ_w` (eq. 5.9,
/// `μ_w = ∫_{D_i} λ(x, t₀) dx`) and whose timeout is `T'` (eq. 5.11).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WaitAction {
    /// `μ_w` (1/s).
    pub mu_w: f64,
    /// `T'` (s).
    pub timeout: f64,
}

impl WaitAction {
    /// A wait planned with confidence `p'_s`: `T'` from eq. 5.11.
    pub fn planned(mu_w: f64, confidence: f64) -> Self {
        let mu_w = mu_w.max(MIN_RATE);
        WaitAction {
            mu_w,
            timeout: wait_timeout(mu_w, confidence),
        }
    }

    /// Eq. 5.10: `p_{s,w}(t) = 1 − e^{−μ_w t}` for `t ≥ 0` (`t` from the start of the wait),
    /// while the robot waits (`t ≤ T'`); after `T'` it stays at its value at `T'`.
    pub fn p_success_at(&self, t: f64) -> f64 {
        if t < 0.0 {
            return 0.0;
        }
        -(-self.mu_w * t.min(self.timeout)).exp_m1()
    }

    /// Eq. 5.12: the wait fails only when `T'` has passed: `p_{f,w}(t) = 1 − p_{s,w}(T')` for
    /// `t ≥ T'`, else 0. (With `T'` from eq. 5.11 that is `1 − p'_s`.)
    pub fn p_failure_at(&self, t: f64) -> f64 {
        if t >= self.timeout {
            (-self.mu_w * self.timeout).exp()
        } else {
            0.0
        }
    }

    /// The SBT tuple `⟨p_s, μ, ν⟩`: success with `p_s = 1 − e^{−μ_w T'}` (= `p'_s` when `T'`
    /// comes from eq. 5.11 with the same `μ_w`), success rate `μ_w`, failure rate `1/T'`.
    ///
    /// # Errors
    /// [`SbtError`] if the rates are not finite.
    pub fn sbt(&self) -> Result<Action, SbtError> {
        Action::new(
            -(-self.mu_w * self.timeout).exp_m1(),
            self.mu_w,
            1.0 / self.timeout,
        )
    }
}

/// The search action `S_{A,i→j}` along a path of length `l_sp` driven at `v̄_sp` (eq. 5.13),
/// with the rates `μ_{sp,k}` of the people the robot meets at `t_k = kΔt` (eq. 5.14).
#[derive(Clone, Debug, PartialEq)]
pub struct SearchAction {
    /// `l_sp` in metres.
    pub length: f64,
    /// `μ_{sp,k}`, one per `t_k = kΔt`, `k = 0..=⌊l_sp/(v̄Δt)⌋`.
    pub rates: Vec<f64>,
    /// `Δt` in seconds.
    pub time_step: f64,
    /// `v̄_sp` in m/s.
    pub speed: f64,
    /// `l_fail` in metres.
    pub fail_distance: f64,
    /// `p'_s`.
    pub confidence: f64,
}

impl SearchAction {
    /// A search along a path of `length` metres with the rates `rates` at its time steps,
    /// parameters from `config`.
    pub fn new(length: f64, rates: Vec<f64>, config: &PsbtConfig) -> Self {
        SearchAction {
            length,
            rates,
            time_step: config.time_step_s,
            speed: config.speed_mps,
            fail_distance: config.fail_distance_m,
            confidence: config.confidence,
        }
    }

    /// The length used in rates: at least one time step of driving, so that a search to a
    /// place next door does not have an infinite rate.
    fn effective_length(&self) -> f64 {
        self.length.max(self.speed * self.time_step)
    }

    /// Eq. 5.15: `μ_{sp,tot}⁻¹ = min_k (t_k − ln(1 − p'_s)/μ_{sp,k})`, the earliest time at
    /// which a person is expected with confidence `p'_s` if the robot stopped at `x(t_k)`.
    /// Infinite if no rate is positive.
    pub fn time_to_success(&self) -> f64 {
        let c = -(1.0 - self.confidence).ln();
        self.rates
            .iter()
            .enumerate()
            .filter(|(_, mu)| **mu > 0.0)
            .map(|(k, mu)| k as f64 * self.time_step + c / mu)
            .fold(f64::INFINITY, f64::min)
    }

    /// Eq. 5.16: `p_{s,sp}(t) = 1 − exp(−∫_0^t μ_sp(t̃) dt̃)` with `μ_sp` constant on
    /// `[t_k, t_k + Δt)` and zero after the last step (`t` from the start of the search).
    pub fn p_success_at(&self, t: f64) -> f64 {
        let mut integral = 0.0;
        for (k, mu) in self.rates.iter().enumerate() {
            let start = k as f64 * self.time_step;
            if t <= start {
                break;
            }
            integral += mu * (t - start).min(self.time_step);
        }
        -(-integral).exp_m1()
    }

    /// Eq. 5.17: `ν_sp = v̄/l_sp + v̄/l_fail`.
    pub fn failure_rate(&self) -> f64 {
        self.speed / self.effective_length() + self.speed / self.fail_distance
    }

    /// Eq. 5.18: before `ν_sp⁻¹` the search fails only by navigation,
    /// `1 − e^{−v̄ t / l_fail}`; afterwards with `1 − p_{s,sp}(ν_sp⁻¹)`.
    pub fn p_failure_at(&self, t: f64) -> f64 {
        let end = 1.0 / self.failure_rate();
        if t >= end {
            1.0 - self.p_success_at(end)
        } else {
            -(-self.speed * t / self.fail_distance).exp_m1()
        }
    }

    /// Eq. 5.19: `p_{s,sp}(ν_sp⁻¹) ≤ exp(−l_sp/(l_fail + l_sp))`, which eq. 5.18 needs.
    pub fn satisfies_eq_5_19(&self) -> bool {
        let l = self.effective_length();
        self.p_success_at(1.0 / self.failure_rate()) <= (-l / (self.fail_distance + l)).exp()
    }

    /// The SBT tuple: `p_s = p_{s,sp}(ν_sp⁻¹)` (the success probability eq. 5.18 leaves),
    /// `μ = μ_{sp,tot}` (eq. 5.15), `ν = ν_sp` (eq. 5.17).
    ///
    /// # Errors
    /// [`SbtError`] if a rate is not finite.
    pub fn sbt(&self) -> Result<Action, SbtError> {
        let nu = self.failure_rate();
        let time = self.time_to_success();
        if !time.is_finite() {
            return Action::new(0.0, 0.0, nu);
        }
        Action::new(self.p_success_at(1.0 / nu), 1.0 / time, nu)
    }
}

/// *Move to x_0* after a person was found, `length` metres away: a search action that can
/// only fail by navigation (§5.4.3): it arrives with probability `e^{−l/l_fail}` (failures are
/// exponential in distance with mean `l_fail`), after `Exp(v̄/l)`; a failure comes with the rate
/// of eq. 5.17. `None` when the robot is already there.
///
/// # Errors
/// [`SbtError`] if a rate is not finite.
pub fn move_to(length: f64, config: &PsbtConfig) -> Result<Option<Action>, SbtError> {
    if length <= 0.0 {
        return Ok(None);
    }
    let l = length.max(config.speed_mps * config.time_step_s);
    let v = config.speed_mps;
    Action::new(
        (-length / config.fail_distance_m).exp(),
        v / l,
        v / l + v / config.fail_distance_m,
    )
    .map(Some)
}
