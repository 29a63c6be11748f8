//! Requests that compute run here, never on the async threads that answer every other
//! request, on one of two pools of the same kind ([`Class`]):
//!
//! * **heavy** ([`Class::Heavy`]): a grid's predicted map, a CoPA-Map's prediction over many
//!   cells, a now-or-later plan, and model requests with a large body or much work (more than
//!   [`LIGHT_MAX_PREDICTIONS`] predictions or [`LIGHT_MAX_BODY_BYTES`] of JSON);
//! * **light** ([`Class::Light`]): the other model requests (`predict`, `entropy`,
//!   `forecast`, `evaluate`, `detect` of a few thousand predictions), a grid cell's times and
//!   a topological map's edges at a time: at most milliseconds each, so that they never wait
//!   behind a map that computes for seconds.
//!
//! Each pool runs [`HeavyLimits::workers`] threads, each request on one thread
//! ([`Parallelism::Sequential`]), at most `workers + queue` admitted at once (one more is
//! answered `503` with `Retry-After`), and each request is stopped soon after its client goes
//! away (the handler's future is dropped, which sets the job's [`Cancel`] flag; the work checks
//! it between chunks).

use std::panic::AssertUnwindSafe;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use axum::http::StatusCode;
use chronomap_core::Parallelism;
use tokio::sync::{Semaphore, oneshot};

use crate::server::ApiError;

/// Requests admitted beyond those running, by default (`--heavy-queue`).
pub const DEFAULT_HEAVY_QUEUE: usize = 32;

/// Light requests admitted beyond those running, by default (`--light-queue`): each computes
/// for milliseconds at most, so many may wait.
pub const DEFAULT_LIGHT_QUEUE: usize = 256;

/// Most predictions (times × orders, or ids) of a model request computed on the light pool;
/// more go to the heavy pool. At most tens of milliseconds on one thread with the costliest
/// model (FreMEn of order 84, about 1.6 µs a prediction).
pub const LIGHT_MAX_PREDICTIONS: u64 = 16_384;

/// Most predictions of a model request computed where its body was parsed, on the async
/// thread, instead of on the light pool: at most about 50 µs with the costliest model (FreMEn
/// of order 84, about 1.6 µs a prediction) — less than parsing a body of
/// [`LIGHT_MAX_BODY_BYTES`] there — while the hop to a pool thread and back costs two thread
/// wake-ups, which on a busy machine wait for a core (a door prediction's p99 went from
/// 0.3 ms to over 1 ms with the hop on 2 cores).
pub const INLINE_MAX_PREDICTIONS: u64 = 32;

/// Largest body of a model request parsed on the async threads (well under a millisecond of
/// JSON); a larger one is parsed, checked and computed on the heavy pool.
pub const LIGHT_MAX_BODY_BYTES: usize = 256 << 10;

/// Seconds a client refused with `503` is asked to wait (`Retry-After`).
pub const RETRY_AFTER_SECS: u32 = 1;

/// How each heavy request computes: on its worker thread alone, so that `workers` bounds the
/// threads all heavy requests together keep busy.
pub const PARALLELISM: Parallelism = Parallelism::Sequential;

/// Which of the two pools a request runs on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Class {
    /// Maps, plans and large model requests (`--heavy-workers`, `--heavy-queue`).
    Heavy,
    /// Small model requests (`--light-workers`, `--light-queue`).
    Light,
}

impl Class {
    fn name(self) -> &'static str {
        match self {
            Class::Heavy => "heavy",
            Class::Light => "light",
        }
    }
}

/// How much work one pool takes on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HeavyLimits {
    /// Threads computing heavy requests, each running one request at a time
    /// (`--heavy-workers`; default half the hardware threads, at least 1, so that the async
    /// threads, the writer and the refits keep a core).
    pub workers: usize,
    /// Heavy requests admitted to wait for a worker (`--heavy-queue`); one more while `workers
    /// + queue` are admitted is answered `503` with `Retry-After`.
    pub queue: usize,
}

impl HeavyLimits {
    /// Half the hardware threads, at least 1.
    pub fn default_workers() -> usize {
        std::thread::available_parallelism().map_or(1, |n| n.get().div_ceil(2))
    }

    /// The light pool's defaults: [`HeavyLimits::default_workers`] threads,
    /// [`DEFAULT_LIGHT_QUEUE`] waiting.
    pub fn light() -> Self {
        HeavyLimits {
            workers: HeavyLimits::default_workers(),
            queue: DEFAULT_LIGHT_QUEUE,
        }
    }
}

impl Default for HeavyLimits {
    fn default() -> Self {
        HeavyLimits {
            workers: HeavyLimits::default_workers(),
            queue: DEFAULT_HEAVY_QUEUE,
        }
    }
}

/// Set when the request a job computes for is gone; the job checks it between chunks of work.
#[derive(Clone, Debug, Default)]
pub struct Cancel(Arc<AtomicBool>);

impl Cancel {
    /// Whether the client went away.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Acquire)
    }

    fn set(&self) {
        self.0.store(true, Ordering::Release);
    }
}

/// Cancels a job when the handler's future holding it is dropped (the client disconnected)
/// or finishes.
struct CancelOnDrop(Cancel);

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        self.0.set();
    }
}

/// Heavy requests now: admitted and waiting for a worker, and computing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HeavyLoad {
    /// Admitted, waiting for a worker.
    pub waiting: u64,
    /// Computing.
    pub running: u64,
    /// Given up since the start because their client went away (before or while computing).
    pub cancelled: u64,
}

/// A pool requests that compute run on (heavy or light, [`Class`]).
pub struct Heavy {
    class: Class,
    pool: rayon::ThreadPool,
    admitted: Arc<Semaphore>,
    waiting: AtomicU64,
    running: AtomicU64,
    cancelled: AtomicU64,
    limits: HeavyLimits,
}

impl std::fmt::Debug for Heavy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Heavy")
            .field("class", &self.class)
            .field("limits", &self.limits)
            .field("load", &self.load())
            .finish()
    }
}

impl Heavy {
    /// Starts the worker threads of the heavy pool.
    ///
    /// # Errors
    /// No worker (`workers == 0`), or the threads cannot be started.
    pub fn new(limits: HeavyLimits) -> Result<Self, String> {
        Heavy::of_class(Class::Heavy, limits)
    }

    /// Starts the worker threads of a pool of `class`.
    ///
    /// # Errors
    /// No worker (`workers == 0`), or the threads cannot be started.
    pub fn of_class(class: Class, limits: HeavyLimits) -> Result<Self, String> {
        let name = class.name();
        if limits.workers == 0 {
            return Err(format!("{name} workers: at least 1"));
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(limits.workers)
            .thread_name(move |i| format!("chronomap-{name}-{i}"))
            .build()
            .map_err(|e| format!("cannot start the {name}-request threads: {e}"))?;
        Ok(Heavy {
            class,
            pool,
            admitted: Arc::new(Semaphore::new(
                limits
                    .workers
                    .saturating_add(limits.queue)
                    .min(Semaphore::MAX_PERMITS),
            )),
            waiting: AtomicU64::new(0),
            running: AtomicU64::new(0),
            cancelled: AtomicU64::new(0),
            limits,
        })
    }

    /// Which pool it is.
    pub fn class(&self) -> Class {
        self.class
    }

    /// The limits it runs under.
    pub fn limits(&self) -> HeavyLimits {
        self.limits
    }

    /// Heavy requests waiting and computing now.
    pub fn load(&self) -> HeavyLoad {
        HeavyLoad {
            waiting: self.waiting.load(Ordering::Acquire),
            running: self.running.load(Ordering::Acquire),
            cancelled: self.cancelled.load(Ordering::Acquire),
        }
    }

    /// Runs `work` on a worker for the service itself (a grid's fit that later requests
    /// share): neither admitted nor cancelled, counted as running while it runs.
    pub(crate) fn prepare(self: &Arc<Self>, work: impl FnOnce() + Send + 'static) {
        let heavy = Arc::clone(self);
        self.pool.spawn(move || {
            heavy.running.fetch_add(1, Ordering::AcqRel);
            // `work` catches its own panics: it must report to its waiters.
            let _ = std::panic::catch_unwind(AssertUnwindSafe(work));
            heavy.running.fetch_sub(1, Ordering::AcqRel);
        });
    }

    /// Runs `job` on a worker and answers what it returns; `503` with `Retry-After` at once if
    /// `workers + queue` requests are admitted already. Dropping the returned future (the
    /// client went away) cancels the job: it does not start if it still waits, and a running
    /// job sees [`Cancel::is_cancelled`]. A job that panics answers `500`.
    ///
    /// # Errors
    /// `503` when full, `500` when the job panicked, else the job's own error.
    pub async fn run<T, F>(self: &Arc<Self>, job: F) -> Result<T, ApiError>
    where
        T: Send + 'static,
        F: FnOnce(&Cancel) -> Result<T, ApiError> + Send + 'static,
    {
        self.admit()?.run(job).await
    }

    /// Admits a request, or answers `503` with `Retry-After` if `workers + queue` are admitted
    /// already: a request that must wait for something else first (a grid's fit) is refused
    /// before it waits.
    ///
    /// # Errors
    /// `503` when full.
    pub fn admit(self: &Arc<Self>) -> Result<Admitted, ApiError> {
        let permit = Arc::clone(&self.admitted)
            .try_acquire_owned()
            .map_err(|_| {
                let name = self.class.name();
                ApiError::busy(format!(
                    "the service is computing {} {name} requests and {} more are waiting \
                     (--{name}-workers, --{name}-queue); retry in {RETRY_AFTER_SECS} s",
                    self.limits.workers, self.limits.queue
                ))
            })?;
        Ok(Admitted {
            heavy: Arc::clone(self),
            permit,
        })
    }
}

/// A heavy request admitted to the pool ([`Heavy::admit`]); dropping it leaves its place.
#[derive(Debug)]
pub struct Admitted {
    heavy: Arc<Heavy>,
    permit: tokio::sync::OwnedSemaphorePermit,
}

impl Admitted {
    /// [`Heavy::run`] of an admitted request.
    ///
    /// # Errors
    /// As [`Heavy::run`], except `503`.
    pub async fn run<T, F>(self, job: F) -> Result<T, ApiError>
    where
        T: Send + 'static,
        F: FnOnce(&Cancel) -> Result<T, ApiError> + Send + 'static,
    {
        let Admitted { heavy, permit } = self;
        let cancel = Cancel::default();
        let guard = CancelOnDrop(cancel.clone());
        let (reply, answer) = oneshot::channel();
        heavy.waiting.fetch_add(1, Ordering::AcqRel);
        let pool = Arc::clone(&heavy);
        pool.pool.spawn(move || {
            heavy.waiting.fetch_sub(1, Ordering::AcqRel);
            if cancel.is_cancelled() {
                heavy.cancelled.fetch_add(1, Ordering::AcqRel);
                drop(permit);
                return;
            }
            heavy.running.fetch_add(1, Ordering::AcqRel);
            let outcome = std::panic::catch_unwind(AssertUnwindSafe(|| job(&cancel)));
            // The flag is set only once the handler is gone or has its answer, which it gets
            // below: set here, the client went away.
            if cancel.is_cancelled() {
                heavy.cancelled.fetch_add(1, Ordering::AcqRel);
            }
            heavy.running.fetch_sub(1, Ordering::AcqRel);
            drop(permit);
            let _ = reply.send(outcome);
        });
        let outcome = answer.await;
        drop(guard);
        match outcome {
            Ok(Ok(answer)) => answer,
            Ok(Err(_)) => Err(ApiError::internal(
                "the computation failed unexpectedly (a bug; the service goes on)".into(),
            )),
            Err(_) => Err(ApiError::internal("the computation was dropped".into())),
        }
    }
}

/// The answer of a job that saw its client go away (nobody reads it).
pub(crate) fn cancelled() -> ApiError {
    ApiError::new(
        StatusCode::SERVICE_UNAVAILABLE,
        "cancelled",
        "the client went away".into(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::{Duration, Instant};

    fn runtime() -> tokio::runtime::Runtime {
        tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap()
    }

    #[test]
    fn one_more_than_workers_plus_queue_is_refused_with_503_and_retry_after() {
        let heavy = Arc::new(
            Heavy::new(HeavyLimits {
                workers: 1,
                queue: 1,
            })
            .unwrap(),
        );
        let rt = runtime();
        let (release, released) = std::sync::mpsc::channel::<()>();
        let released = Arc::new(std::sync::Mutex::new(released));
        rt.block_on(async {
            let gate = Arc::clone(&released);
            let first = tokio::spawn({
                let heavy = Arc::clone(&heavy);
                async move {
                    heavy
                        .run(move |_| {
                            gate.lock().unwrap().recv().unwrap();
                            Ok(1)
                        })
                        .await
                }
            });
            let second = tokio::spawn({
                let heavy = Arc::clone(&heavy);
                async move { heavy.run(|_| Ok(2)).await }
            });
            // Both admitted: one computing, one waiting.
            let start = Instant::now();
            while heavy.load()
                != (HeavyLoad {
                    waiting: 1,
                    running: 1,
                    cancelled: 0,
                })
            {
                assert!(start.elapsed() < Duration::from_secs(10), "{heavy:?}");
                tokio::time::sleep(Duration::from_millis(5)).await;
            }
            let refused = heavy.run(|_| Ok(3)).await.unwrap_err();
            let response = axum::response::IntoResponse::into_response(refused);
            assert_eq!(response.status(), StatusCode::SERVICE_UNAVAILABLE);
            assert_eq!(response.headers()["retry-after"], "1");
            release.send(()).unwrap();
            assert_eq!(first.await.unwrap().unwrap(), 1);
            assert_eq!(second.await.unwrap().unwrap(), 2);
            assert_eq!(heavy.load(), HeavyLoad::default());
            // Admitted again once they are done.
            assert_eq!(heavy.run(|_| Ok(4)).await.unwrap(), 4);
        });
    }

    #[test]
    fn a_dropped_request_cancels_its_job_and_a_panic_is_a_500() {
        let heavy = Arc::new(
            Heavy::new(HeavyLimits {
                workers: 1,
                queue: 4,
            })
            .unwrap(),
        );
        let rt = runtime();
        let seen = Arc::new(AtomicBool::new(false));
        rt.block_on(async {
            let flag = Arc::clone(&seen);
            let job = heavy.run(move |cancel| {
                let start = Instant::now();
                while !cancel.is_cancelled() {
                    assert!(start.elapsed() < Duration::from_secs(10));
                    std::thread::sleep(Duration::from_millis(1));
                }
                flag.store(true, Ordering::Release);
                Err::<(), _>(cancelled())
            });
            // The client goes away after 50 ms.
            assert!(
                tokio::time::timeout(Duration::from_millis(50), job)
                    .await
                    .is_err()
            );
            let start = Instant::now();
            while heavy.load().running != 0 {
                assert!(start.elapsed() < Duration::from_secs(10));
                tokio::time::sleep(Duration::from_millis(5)).await;
            }
            assert!(seen.load(Ordering::Acquire));
            assert_eq!(
                heavy.load(),
                HeavyLoad {
                    waiting: 0,
                    running: 0,
                    cancelled: 1
                }
            );
            let panicked = heavy
                .run(|_| -> Result<(), ApiError> { panic!("a bug") })
                .await
                .unwrap_err();
            let response = axum::response::IntoResponse::into_response(panicked);
            assert_eq!(response.status(), StatusCode::INTERNAL_SERVER_ERROR);
            assert_eq!(heavy.run(|_| Ok(5)).await.unwrap(), 5);
        });
    }
}
