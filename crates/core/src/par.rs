//! Parallelism as a parameter, never a process-wide setting.

/// How much parallelism an algorithm may use.
///
/// Results never depend on this choice: algorithms that take it use exact accumulation
/// ([`crate::exact`]) so that sequential and parallel runs give identical bits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Parallelism {
    /// Run on the calling thread.
    #[default]
    Sequential,
    /// Split the work into this many tasks on the current rayon thread pool
    /// (0 = as many as the pool has threads).
    Rayon(usize),
}

impl Parallelism {
    /// Number of tasks to split work into.
    pub fn tasks(self) -> usize {
        match self {
            Parallelism::Sequential => 1,
            Parallelism::Rayon(0) => rayon::current_num_threads().max(1),
            Parallelism::Rayon(n) => n,
        }
    }
}
