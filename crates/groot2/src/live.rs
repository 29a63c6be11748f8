//! A scripted run ticked in real time: the loop of [`chronomap_bt::script::run_script`] with
//! a call after every tick (to update a [`crate::publisher::Publisher`]) and a wall-clock
//! pause before every tick, so that a client can watch the tree change.

use std::collections::BTreeMap;
use std::time::Duration;

use chronomap_bt::script::{
    Script, ScriptRun, ScriptTick, ScriptedOutcomes, TickFailure, TickRecord,
};
use chronomap_bt::{Status, Transition, Tree};

/// Runs `tree` through `script` as `run_script` does — tick *k* at the script's time (given,
/// or the previous tick's plus `period`; tick 1 at 0), the outcomes of line *k* set before it,
/// the run ended when the root stops running or a tick fails — and, for every tick, first
/// calls `pause` (a wall-clock wait), then ticks, then calls `after_tick` with the tree and the
/// tick's status changes. The script is expected to have been checked (`run_script` on the
/// same tree type refuses bad scripts before anything runs).
pub fn run_script_paced(
    tree: &mut Tree,
    outcomes: &ScriptedOutcomes,
    script: &Script,
    period: Duration,
    pause: &mut dyn FnMut(),
    after_tick: &mut dyn FnMut(&Tree, &[Transition]),
) -> ScriptRun {
    let last = script.ticks.last().map_or(0, |t| t.tick);
    let by_tick: BTreeMap<u64, &ScriptTick> = script.ticks.iter().map(|t| (t.tick, t)).collect();
    tree.set_recording(true);
    tree.take_transitions();
    let mut ticks = Vec::new();
    let mut time = Duration::ZERO;
    let mut finished = false;
    let mut failure = None;
    for k in 1..=last {
        let line = by_tick.get(&k);
        time = match line.and_then(|l| l.at_ms) {
            Some(ms) => Duration::from_millis(ms),
            None if k == 1 => Duration::ZERO,
            None => time.saturating_add(period),
        };
        for (name, status) in line.map(|l| l.outcomes.as_slice()).unwrap_or_default() {
            outcomes.set(name, *status);
        }
        pause();
        let result = tree.tick_exactly_once(time);
        let transitions = tree.take_transitions();
        after_tick(tree, &transitions);
        match result {
            Ok(status) => {
                ticks.push(TickRecord {
                    tick: k,
                    time,
                    status,
                    transitions,
                });
                if status != Status::Running {
                    finished = true;
                    break;
                }
            }
            Err(error) => {
                failure = Some(TickFailure {
                    tick: k,
                    time,
                    error,
                    transitions,
                });
                break;
            }
        }
    }
    let done = failure.as_ref().map_or_else(
        || ticks.last().map_or(0, |t| t.tick),
        |f: &TickFailure| f.tick,
    );
    let unused = script
        .ticks
        .iter()
        .map(|t| t.tick)
        .filter(|&t| t > done)
        .collect();
    ScriptRun {
        ticks,
        finished,
        unused,
        failure,
    }
}
