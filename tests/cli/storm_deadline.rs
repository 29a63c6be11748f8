//! Storm cross-check of the deadline plans on the real Witham edges
//! (`chronomap_topo::deadline`): for every case of `topo_deadline`, the product with every
//! choice branching into one state per duration bucket
//! (`deadline::duration_branching_mdp`, written as DRN with integer rewards), and the Markov
//! chain of the expected-time plan alone. Storm's `Pmax=? [F{"time"}<=K "goal"]` (exact
//! arithmetic, `tests/oracle/storm_deadline.py`) must equal our backward induction to 1e-9 at
//! four bounds K each.
//!
//! Storm runs when `CHRONOMAP_STORM_PYTHON` names a Python interpreter that imports stormpy
//! (`.ci/run` sets it up). Without it the test checks that the files are written and says how
//! to enable the comparison, unless `CHRONOMAP_REQUIRE_STORM=1`, when it fails.

use std::ffi::OsString;

use chronomap_topo::deadline::duration_branching_mdp;

use crate::common::{oracle_python, run_oracle, scratch};
use crate::topo_deadline::{CASES, plan_case, witham_models};

/// Absolute tolerance of every comparison.
const TOLERANCE: f64 = 1e-9;

#[test]
fn witham_deadline_probabilities_equal_storms_reward_bounded_reachability() {
    let models = witham_models();
    let dir = scratch("storm_deadline");
    // (file, bound, our value)
    let mut expected: Vec<(String, usize, f64)> = Vec::new();
    let mut args: Vec<OsString> = Vec::new();
    for (i, case) in CASES.into_iter().enumerate() {
        // Twice the case's deadline D, compared at 0.9 D, D, 1.5 D and 2 D (buckets of 1 s).
        let (start, task, hour, deadline) = case;
        let planned = plan_case(&models, (start, task, hour, 2.0 * deadline));
        let mdp = planned.planned.product.mdp();
        assert_eq!(planned.plan.bucket_secs, 1.0);
        let d = deadline as usize;
        let bounds = [d * 9 / 10, d, d * 3 / 2, 2 * d];
        let policy = &planned.planned.solution.policy_choice;
        for (kind, solution, policy) in [
            ("deadline", &planned.solution, None),
            ("min_time", &planned.min_time, Some(&policy[..])),
        ] {
            let branching = duration_branching_mdp(mdp, &planned.laws, policy).unwrap();
            let name = format!("case{i}_{kind}.drn");
            let path = dir.join(&name);
            std::fs::write(&path, branching.to_drn(&[]).unwrap()).unwrap();
            let list: Vec<String> = bounds.iter().map(usize::to_string).collect();
            args.push(format!("{}:{}", path.display(), list.join(",")).into());
            for b in bounds {
                expected.push((name.clone(), b, solution.value(mdp.initial(), b)));
            }
        }
    }
    let enable = "set CHRONOMAP_STORM_PYTHON to a Python with stormpy 2.0 \
                  (python3 -m venv storm-venv && storm-venv/bin/pip install stormpy==2.0.0), \
                  see tests/oracle/README.md";
    let Some(python) = oracle_python("STORM", "storm_deadline", "Storm", enable) else {
        return;
    };
    let args: Vec<&std::ffi::OsStr> = args.iter().map(OsString::as_os_str).collect();
    let label = format!("storm_deadline.py on {} files", args.len());
    let storm = run_oracle(
        &python,
        "CHRONOMAP_STORM_PYTHON",
        "storm_deadline.py",
        &args,
        &label,
    );
    let mut worst: f64 = 0.0;
    for (name, bound, ours) in &expected {
        let theirs = storm[name]["bounds"][bound.to_string()]
            .as_f64()
            .unwrap_or_else(|| panic!("{name}: Storm gave no value for {bound}: {storm}"));
        println!(
            "{name} (states {}), K = {bound}: chronomap {ours:.12}, Storm {theirs:.12}",
            storm[name]["states"]
        );
        worst = worst.max((ours - theirs).abs());
        assert!(
            (ours - theirs).abs() <= TOLERANCE,
            "{name}, K = {bound}: chronomap {ours}, Storm {theirs}"
        );
    }
    println!("{} values: max |Δ| = {worst:.2e}", expected.len());
}
