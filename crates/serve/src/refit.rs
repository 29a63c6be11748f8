//! Refits of the models fitted on a whole series (`auto`, `fremen:auto`, `fft:L`, ...): on a
//! schedule and on request, on a thread of their own.
//!
//! Such a model keeps its observations ([`chronomap_models::learner`]) and predicts with its
//! last fit. After every commit group the writer asks [`Refits::schedule_due`] about the models
//! it changed; those the [`RefitPolicy`] finds due are queued (once each). A request
//! (`POST /v1/models/{id}/refit`) queues its model too, and waits for the outcome.
//!
//! One refit thread takes the queue in order: it takes the model's kept observations under
//! the registry's read lock (they are shared, not copied), fits them with the options of
//! `chronomap fit` (the defaults) on its own thread, and hands the fit to the writer as a
//! [`LogRecord::Refit`](crate::log::LogRecord::Refit). Neither the request handlers nor the
//! writer wait for a fit: writes go on meanwhile, and the fitted model learns what they added
//! when it is put in place. The fit is put in place, as every change, only once its log entry
//! is durable, and recovery installs the logged fit at the same place, so a restart (also
//! after SIGKILL) predicts exactly as before. Every refit and every failure is logged on
//! standard output (`refit: …`).

use std::collections::{HashMap, VecDeque};
use std::io::Write as _;
use std::sync::{Arc, Condvar, Mutex};
use std::time::Instant;

use chronomap_core::time::format_time;
use chronomap_core::{Parallelism, TemporalModel};
use chronomap_models::{FitOptions, RefitPolicy};
use tokio::sync::{mpsc, oneshot};

use crate::api::RefitResponse;
use crate::registry::{ApplyError, Registry, fit_info};
use crate::writer::{Shared, WriteCommand, WriteError, WriteOp};

/// Why a requested refit was not made.
#[derive(Clone, Debug)]
pub enum RefitFailure {
    /// No model with this id.
    NotFound(String),
    /// The model learns online (model id, spec).
    Online(String, String),
    /// The fit failed: too few observations, data the spec cannot fit (model id, why).
    Fit(String, String),
    /// The writer refused the fit.
    Write(WriteError),
    /// The service is stopping.
    Stopping,
}

impl std::fmt::Display for RefitFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RefitFailure::NotFound(id) => write!(f, "no model with id {id:?}"),
            RefitFailure::Online(id, spec) => write!(
                f,
                "model {id:?} (`{spec}`) learns online and is never refitted; models fitted \
                 on a whole series are: auto, fremen:auto, persistence:auto, pergam:auto, \
                 fft:L|auto, hyt-em, hyt-km"
            ),
            RefitFailure::Fit(id, reason) => write!(f, "model {id:?} cannot be refitted: {reason}"),
            RefitFailure::Write(WriteError::Apply(e)) => e.fmt(f),
            RefitFailure::Write(WriteError::Store(reason)) => f.write_str(reason),
            RefitFailure::Stopping => f.write_str("the service is shutting down"),
        }
    }
}

/// What a request waits for.
pub type Outcome = Result<RefitResponse, RefitFailure>;

/// A model queued for a refit, and who waits for it.
struct Queued {
    id: String,
    waiting: Vec<oneshot::Sender<Outcome>>,
}

#[derive(Default)]
struct Queue {
    queued: VecDeque<Queued>,
    /// Models whose last scheduled refit failed: their observation count and last time then.
    /// They are not scheduled again before the policy finds them due counted from there.
    failed: HashMap<String, (u64, f64)>,
    stop: bool,
}

/// The refit queue the writer, the request handlers and the refit thread share.
pub struct Refits {
    policy: RefitPolicy,
    queue: Mutex<Queue>,
    ready: Condvar,
}

impl Refits {
    /// An empty queue scheduling by `policy`.
    pub fn new(policy: RefitPolicy) -> Self {
        Refits {
            policy,
            queue: Mutex::new(Queue::default()),
            ready: Condvar::new(),
        }
    }

    /// Queues the models among `ids` that the policy finds due (called with the registry
    /// after a commit group, and at start with every id).
    pub fn schedule_due<'a>(&self, registry: &Registry, ids: impl IntoIterator<Item = &'a str>) {
        let mut queue = self.queue.lock().expect("refit queue lock");
        for id in ids {
            let Some(entry) = registry.get(id) else {
                continue;
            };
            if !entry.model.is_due(&self.policy) {
                continue;
            }
            if let Some(&(count, time)) = queue.failed.get(id) {
                let span = entry.model.span();
                if !self
                    .policy
                    .is_due(span.count.saturating_sub(count), span.last - time)
                {
                    continue;
                }
            }
            if queue.queued.iter().all(|q| q.id != id) {
                queue.queued.push_back(Queued {
                    id: id.to_owned(),
                    waiting: Vec::new(),
                });
                self.ready.notify_one();
            }
        }
    }

    /// Queues a refit of `id` on request; the receiver gets its outcome. A model already queued
    /// (and not started) is refitted once for both.
    pub fn request(&self, id: &str) -> oneshot::Receiver<Outcome> {
        let (reply, outcome) = oneshot::channel();
        let mut queue = self.queue.lock().expect("refit queue lock");
        if queue.stop {
            let _ = reply.send(Err(RefitFailure::Stopping));
            return outcome;
        }
        match queue.queued.iter_mut().find(|q| q.id == id) {
            Some(queued) => queued.waiting.push(reply),
            None => {
                queue.queued.push_back(Queued {
                    id: id.to_owned(),
                    waiting: vec![reply],
                });
                self.ready.notify_one();
            }
        }
        outcome
    }

    /// Stops the refit thread after the refit in progress (queued requests get
    /// [`RefitFailure::Stopping`]).
    pub fn stop(&self) {
        let mut queue = self.queue.lock().expect("refit queue lock");
        queue.stop = true;
        for queued in queue.queued.drain(..) {
            for reply in queued.waiting {
                let _ = reply.send(Err(RefitFailure::Stopping));
            }
        }
        self.ready.notify_all();
    }

    /// The next model to refit, or `None` once stopped.
    fn next(&self) -> Option<Queued> {
        let mut queue = self.queue.lock().expect("refit queue lock");
        loop {
            if queue.stop {
                return None;
            }
            if let Some(next) = queue.queued.pop_front() {
                return Some(next);
            }
            queue = self.ready.wait(queue).expect("refit queue lock");
        }
    }

    fn failed(&self, id: &str, at: Option<(u64, f64)>) {
        let mut queue = self.queue.lock().expect("refit queue lock");
        match at {
            Some(at) => queue.failed.insert(id.to_owned(), at),
            None => queue.failed.remove(id),
        };
    }
}

/// The options of every refit: those of `chronomap fit` by default, on one thread (the result
/// does not depend on it; the other cores stay with the requests).
pub fn fit_options() -> FitOptions {
    FitOptions {
        parallelism: Parallelism::Sequential,
        ..FitOptions::default()
    }
}

/// Runs the refit thread until [`Refits::stop`]: fits, hands each fit to the writer over
/// `writes`, answers requests and logs.
pub fn run(refits: Arc<Refits>, shared: Arc<Shared>, writes: mpsc::Sender<WriteCommand>) {
    while let Some(Queued { id, waiting }) = refits.next() {
        let requested = !waiting.is_empty();
        let outcome = refit_one(&refits, &shared, &writes, &id, requested);
        for reply in waiting {
            let _ = reply.send(outcome.clone());
        }
    }
}

fn refit_one(
    refits: &Refits,
    shared: &Shared,
    writes: &mpsc::Sender<WriteCommand>,
    id: &str,
    requested: bool,
) -> Outcome {
    let how = if requested { "requested" } else { "scheduled" };
    let (job, spread_job, spec, current, last) = {
        let registry = shared.registry.read().expect("registry lock");
        let entry = registry
            .get(id)
            .ok_or_else(|| RefitFailure::NotFound(id.to_owned()))?;
        let spec = entry.config.spec.to_string();
        let job = entry
            .model
            .refit_job()
            .ok_or_else(|| RefitFailure::Online(id.to_owned(), spec.clone()))?;
        // A model of continuous values fitted on a whole series with a second moment
        // (`auto`): its squares are fitted with it, on the same observations.
        let spread_job = entry.spread.as_ref().and_then(|s| s.refit_job());
        // Fitted on every observation already, and so is the second moment (one restored from
        // a log written before `auto` had one is fitted now): nothing to do.
        let current = (entry.model.since_fit().0 == 0
            && entry.spread.as_ref().is_none_or(|s| s.since_fit().0 == 0))
        .then(|| entry.fit_info())
        .flatten();
        (job, spread_job, spec, current, entry.model.span().last)
    };
    if let Some(fit) = current {
        return Ok(RefitResponse {
            seq: shared.seq.load(std::sync::atomic::Ordering::Acquire),
            refitted: false,
            fit,
            secs: 0.0,
        });
    }
    let started = Instant::now();
    let fitted = job.run(&fit_options());
    let secs = started.elapsed().as_secs_f64();
    let refit = match fitted {
        Ok(refit) => refit,
        Err(e) => {
            refits.failed(id, Some((job.through(), last)));
            log(format_args!(
                "refit of model {id:?} ({spec}, {how}) failed after {secs:.2} s on {} \
                 observations: {e}",
                job.observations()
            ));
            return Err(RefitFailure::Fit(id.to_owned(), e.to_string()));
        }
    };
    // Without a fit of the second moment the model keeps predicting its intervals from the
    // last one (it goes on learning the squares online meanwhile).
    let spread = spread_job.and_then(|job| match job.run(&fit_options()) {
        Ok(fit) => Some(fit),
        Err(e) => {
            log(format_args!(
                "refit of the second moment of model {id:?} ({spec}, {how}) failed on {} \
                 observations: {e}",
                job.observations()
            ));
            None
        }
    });
    let secs = started.elapsed().as_secs_f64();
    refits.failed(id, None);
    let fit = fit_info(&refit.record, &refit.model);
    let (reply, written) = oneshot::channel();
    let command = WriteCommand {
        ops: vec![WriteOp::refit(id.to_owned(), refit, spread)],
        reply,
    };
    if writes.blocking_send(command).is_err() {
        return Err(RefitFailure::Stopping);
    }
    match written.blocking_recv() {
        Ok(Ok(written)) => {
            let weights: Vec<String> = fit
                .weights
                .iter()
                .map(|w| format!("{} {:.3}", w.model, w.weight))
                .collect();
            log(format_args!(
                "refit of model {id:?} ({spec}, {how}): {} on {} observations {} .. {} in \
                 {secs:.2} s{}; log position {}",
                fit.fitted,
                fit.observations,
                format_time(fit.first_time),
                format_time(fit.last_time),
                if weights.is_empty() {
                    String::new()
                } else {
                    format!(" (weights {})", weights.join(", "))
                },
                written.seq
            ));
            Ok(RefitResponse {
                seq: written.seq,
                refitted: true,
                fit,
                secs,
            })
        }
        Ok(Err(e)) => {
            // Removed meanwhile, or overtaken by more observations than it keeps.
            log(format_args!(
                "refit of model {id:?} ({spec}, {how}) was not put in place: {}",
                match &e {
                    WriteError::Apply(e) => e.to_string(),
                    WriteError::Store(reason) => reason.clone(),
                }
            ));
            Err(match e {
                WriteError::Apply(ApplyError::NotFound(_)) => RefitFailure::NotFound(id.to_owned()),
                other => RefitFailure::Write(other),
            })
        }
        Err(_) => Err(RefitFailure::Stopping),
    }
}

/// One line of the service's log (standard output; a closed stdout is ignored).
fn log(line: std::fmt::Arguments<'_>) {
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "refit: {line}");
    let _ = out.flush();
}
