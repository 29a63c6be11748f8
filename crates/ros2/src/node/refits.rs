//! Refits of the states whose models are fitted on a whole series (`auto`, `fremen:auto`, ...;
//! [`chronomap_models::learner`]): one background thread fits, one at a time, so that a fit
//! of seconds never holds up the node's round; the node installs each fit when it is done
//! ([`World::install_refit`], journaled with the fitted model, so that a restart installs it at
//! the same place without fitting again).
//!
//! A refit is started when a state's refit policy (`refit_observations`, `refit_period`)
//! says so, or for every such state on request (`~/refit`). A fit that fails (too few
//! observations for `auto`, ...) is logged and not tried again before new observations arrive.
//!
//! A state with a prediction interval (`auto` of a continuous state) has its squared values
//! fitted in the same job, right after its values ([`World::spread_refit_job`]); both fits are
//! installed and journaled together. Should only the squares' fit fail, the model is installed
//! and the second moment keeps its last fit (logged).

use std::sync::mpsc::{self, Receiver, Sender};
use std::time::Instant;

use chronomap_core::error::BuildError;
use chronomap_core::{Parallelism, TemporalModel};
use chronomap_models::learner::{Refit, RefitJob};
use chronomap_models::spec::{FitOptions, Selection};

use crate::world::World;

/// A fit to make: the state and its kept observations.
struct Job {
    index: usize,
    job: RefitJob,
    /// The squared values, for a state with an interval.
    spread: Option<RefitJob>,
    requested: bool,
}

/// A fit made.
struct Done {
    index: usize,
    requested: bool,
    result: Result<Refit, BuildError>,
    /// The fit of the squared values (`None`: no such job, or the values' fit failed).
    spread: Option<Result<Refit, BuildError>>,
    secs: f64,
}

/// The refits of a configured node (see the [module docs](self)).
pub(super) struct Refits {
    jobs: Option<Sender<Job>>,
    done: Receiver<Done>,
    worker: Option<std::thread::JoinHandle<()>>,
    /// Per state: a fit is running.
    running: Vec<bool>,
    /// Per state: the observation count when its last fit failed.
    failed_at: Vec<Option<u64>>,
    /// A refit of every refitted state was asked for (`~/refit`).
    requested: bool,
}

/// The options of every refit: those of `chronomap fit`, on one thread (the result does not
/// depend on it; the node's round keeps the other cores).
fn fit_options() -> FitOptions {
    FitOptions {
        parallelism: Parallelism::Sequential,
        ..FitOptions::default()
    }
}

impl Refits {
    /// No refit running, for `states` states; the worker thread starts with the first job.
    pub(super) fn new(states: usize) -> Refits {
        let (jobs, inbox) = mpsc::channel::<Job>();
        let (outbox, done) = mpsc::channel();
        let worker = std::thread::Builder::new()
            .name("chronomap-refit".into())
            .spawn(move || {
                for Job {
                    index,
                    job,
                    spread,
                    requested,
                } in inbox
                {
                    let started = Instant::now();
                    let result = job.run(&fit_options());
                    let spread = match (&result, spread) {
                        (Ok(_), Some(spread)) => Some(spread.run(&fit_options())),
                        _ => None,
                    };
                    let secs = started.elapsed().as_secs_f64();
                    let sent = outbox.send(Done {
                        index,
                        requested,
                        result,
                        spread,
                        secs,
                    });
                    if sent.is_err() {
                        break;
                    }
                }
            })
            .ok();
        if worker.is_none() {
            log::error!(
                "cannot start the refit thread: models fitted on a whole series are not refitted"
            );
        }
        Refits {
            jobs: worker.as_ref().map(|_| jobs),
            done,
            worker,
            running: vec![false; states],
            failed_at: vec![None; states],
            requested: false,
        }
    }

    /// Asks for a refit of every refitted state at the next round; returns their names.
    pub(super) fn request(&mut self, world: &World) -> Vec<String> {
        self.requested = true;
        world
            .config()
            .states
            .iter()
            .filter(|s| !s.learns_online())
            .map(|s| s.name.clone())
            .collect()
    }

    /// Installs the fits that are done and starts those that are due.
    pub(super) fn step(&mut self, world: &mut World) {
        while let Ok(done) = self.done.try_recv() {
            self.running[done.index] = false;
            self.finish(world, done);
        }
        let requested = std::mem::take(&mut self.requested);
        for index in 0..self.running.len() {
            if self.running[index] {
                continue;
            }
            let count = world.state_model(index).span().count;
            let due = requested || (world.refit_due(index) && self.failed_at[index] != Some(count));
            if !due {
                continue;
            }
            let (Some(job), Some(jobs)) = (world.refit_job(index), &self.jobs) else {
                continue;
            };
            if jobs
                .send(Job {
                    index,
                    job,
                    spread: world.spread_refit_job(index),
                    requested,
                })
                .is_ok()
            {
                self.running[index] = true;
            }
        }
    }

    /// Installs a fit, or logs why not.
    fn finish(&mut self, world: &mut World, done: Done) {
        let state = &world.config().states[done.index];
        let (name, spec) = (state.name.clone(), state.model.to_string());
        let how = if done.requested {
            "requested"
        } else {
            "scheduled"
        };
        let refit = match done.result {
            Ok(refit) => refit,
            Err(e) => {
                self.failed_at[done.index] = Some(world.state_model(done.index).span().count);
                log::warn!(
                    "refit of states.{name} ({spec}, {how}) failed after {:.2} s: {e}; tried \
                     again once new observations arrive",
                    done.secs
                );
                return;
            }
        };
        let spread = match done.spread {
            None => None,
            Some(Ok(fit)) => Some(fit),
            Some(Err(e)) => {
                log::warn!(
                    "refit of the squared values of states.{name} ({spec}, {how}) failed: {e}; \
                     its interval keeps the last fit of the second moment"
                );
                None
            }
        };
        let summary = describe(&refit);
        let (observations, first, last) = (
            refit.record.observations,
            refit.record.first_time,
            refit.record.last_time,
        );
        match world.install_refit(done.index, refit, spread) {
            Ok(()) => {
                self.failed_at[done.index] = None;
                log::info!(
                    "refit of states.{name} ({spec}, {how}): {summary} on {observations} \
                     observations from {first} to {last} in {:.2} s",
                    done.secs
                );
            }
            Err(e) => log::warn!("refit of states.{name} ({spec}, {how}) not put in place: {e}"),
        }
    }
}

impl Drop for Refits {
    /// Ends the worker after the fit it is making (a fit not installed is made again after
    /// a restart, when it is due).
    fn drop(&mut self) {
        self.jobs = None;
        if let Some(worker) = self.worker.take()
            && worker.is_finished()
        {
            let _ = worker.join();
        }
    }
}

/// What a fit chose, in a few words: the members and weights of `auto`, the order of
/// `fremen:auto`.
fn describe(refit: &Refit) -> String {
    match &refit.record.selection {
        Some(Selection::Stack(stack)) => {
            let weights: Vec<String> = stack
                .weights
                .iter()
                .map(|(spec, w)| format!("{spec} {w:.3}"))
                .collect();
            format!("weights {}", weights.join(", "))
        }
        Some(Selection::Order(order)) => format!("order {}", order.order),
        _ => format!("`{}`", refit.model.spec()),
    }
}
