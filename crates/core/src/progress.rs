//! How far a long computation has come, reported to whoever called it.
//!
//! Like [`Parallelism`](crate::Parallelism), progress is a parameter, never a global: an
//! algorithm that can run for more than a few seconds takes a `&dyn Progress` and calls
//! [`Progress::stage`] and [`Progress::advance`]; the command line draws a bar from it, a
//! service or a notebook may log it, and [`NoProgress`] ignores it. Reporting never changes a
//! result, and an implementation must be cheap: it may be called from several threads at once,
//! once per frame, iteration or item.
//!
//! ```
//! use std::sync::atomic::{AtomicU64, Ordering};
//! use chronomap_core::progress::{NoProgress, Progress};
//!
//! fn sum_of_squares(n: u64, progress: &dyn Progress) -> u64 {
//!     progress.stage("squares", n);
//!     (0..n).map(|i| { progress.advance(1); i * i }).sum()
//! }
//!
//! struct Count(AtomicU64);
//! impl Progress for Count {
//!     fn advance(&self, steps: u64) {
//!         self.0.fetch_add(steps, Ordering::Relaxed);
//!     }
//! }
//! let count = Count(AtomicU64::new(0));
//! assert_eq!(sum_of_squares(4, &count), 14);
//! assert_eq!(count.0.load(Ordering::Relaxed), 4);
//! assert_eq!(sum_of_squares(4, &NoProgress), 14);
//! ```

/// Receives the progress of a long computation. Every method has an empty default.
pub trait Progress: Sync {
    /// A new stage of the computation begins, with `total` steps (0 when unknown).
    fn stage(&self, name: &str, total: u64) {
        let _ = (name, total);
    }

    /// `steps` more steps of the current stage are done.
    fn advance(&self, steps: u64) {
        let _ = steps;
    }
}

/// Progress that nobody watches.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NoProgress;

impl Progress for NoProgress {}
