//! Writes navigation MDP cases for the Storm cross-check of `chronomap_topo::mdp`: per case
//! the product (`NAME.drn`), the restricted product (`NAME.restricted.drn`), the Navigation
//! MDP in PRISM (`NAME.nm`) with its co-safe LTL property (`NAME.props`), and the values
//! chronomap computes (`expected.json`, the shape `tests/oracle/storm_check.py` reads).
//!
//! ```text
//! cargo run --example mdp_storm_cases -- /tmp/mdp-cases
//! python3 tests/oracle/storm_check.py --expect /tmp/mdp-cases/expected.json \
//!     /tmp/mdp-cases/*.drn /tmp/mdp-cases/*.nm
//! ```

use std::collections::BTreeMap;
use std::path::PathBuf;

use chronomap_core::rng::Xoshiro256StarStar;
use chronomap_topo::map::TopoMap;
use chronomap_topo::mdp::{NavigationMdp, SolverOptions, prism_property};
use chronomap_topo::plan::Task;
use serde_json::Value;

#[path = "../tests/cli/storm_case.rs"]
mod storm_case;
use storm_case::write_case;

struct Case {
    name: &'static str,
    map: TopoMap,
    success: Vec<f64>,
    duration: Vec<f64>,
    start: &'static str,
    /// The task in co-safe LTL over node names: its automaton for the product, and the
    /// property for PRISM.
    ltl: &'static str,
}

/// A map of `nodes` and `(id, from, to, success probability, duration)` edges, with the
/// probabilities and durations of its edges.
fn nav_map(
    nodes: &[&str],
    edges: &[(&str, &str, &str, f64, f64)],
) -> (TopoMap, Vec<f64>, Vec<f64>) {
    let mut map = TopoMap::new();
    for n in nodes {
        map.add_node(n, None).unwrap();
    }
    for (id, from, to, _, _) in edges {
        map.add_edge(id, from, to).unwrap();
    }
    let success = edges.iter().map(|e| e.3).collect();
    let duration = edges.iter().map(|e| e.4).collect();
    (map, success, duration)
}

/// A 5-node office: a door Office→Lab open 20 % of the time, a longer safe corridor route,
/// and a certain back-and-forth Office↔Hall (an end component).
fn office() -> (TopoMap, Vec<f64>, Vec<f64>) {
    nav_map(
        &["Office", "Hall", "Lab", "C1", "C2"],
        &[
            ("Office_Lab", "Office", "Lab", 0.2, 10.0),
            ("Lab_Office", "Lab", "Office", 0.2, 10.0),
            ("Office_C1", "Office", "C1", 0.98, 20.0),
            ("C1_Office", "C1", "Office", 0.98, 20.0),
            ("C1_C2", "C1", "C2", 0.97, 25.0),
            ("C2_C1", "C2", "C1", 0.97, 25.0),
            ("C2_Lab", "C2", "Lab", 0.99, 20.0),
            ("Lab_C2", "Lab", "C2", 0.99, 20.0),
            ("Office_Hall", "Office", "Hall", 1.0, 5.0),
            ("Hall_Office", "Hall", "Office", 1.0, 5.0),
            ("Hall_C2", "Hall", "C2", 0.5, 40.0),
        ],
    )
}

/// Two routes of equal probability 0.81: direct (100 s, first in edge order) and via M.
fn tie() -> (TopoMap, Vec<f64>, Vec<f64>) {
    nav_map(
        &["S", "M", "G"],
        &[
            ("S_G", "S", "G", 0.81, 100.0),
            ("S_M", "S", "M", 0.9, 30.0),
            ("M_G", "M", "G", 0.9, 30.0),
        ],
    )
}

/// A random `n`-node map: a ring both ways plus random chords; some edges take no time.
fn random_map(seed: u64, n: u64, chords: usize) -> (TopoMap, Vec<f64>, Vec<f64>) {
    let mut rng = Xoshiro256StarStar::seed_from_u64(seed);
    let mut map = TopoMap::new();
    for i in 0..n {
        map.add_node(&format!("W{i}"), None).unwrap();
    }
    let mut pairs = Vec::new();
    for i in 0..n {
        pairs.push((i, (i + 1) % n));
        pairs.push(((i + 1) % n, i));
    }
    for _ in 0..chords {
        let (a, b) = (rng.int_in(0, n - 1), rng.int_in(0, n - 1));
        if a != b && !pairs.contains(&(a, b)) {
            pairs.push((a, b));
        }
    }
    let (mut success, mut duration) = (Vec::new(), Vec::new());
    for (a, b) in pairs {
        map.add_edge(&format!("W{a}_W{b}"), &format!("W{a}"), &format!("W{b}"))
            .unwrap();
        let p = [1.0, 0.99, 0.9, 0.75, 0.5, 0.2][rng.int_in(0, 5) as usize];
        success.push(p);
        duration.push(if rng.bernoulli(0.15) {
            0.0
        } else {
            (rng.uniform(5.0, 60.0) * 10.0).round() / 10.0
        });
    }
    (map, success, duration)
}

fn cases() -> Vec<Case> {
    let case = |name, (map, success, duration), start, ltl| Case {
        name,
        map,
        success,
        duration,
        start,
        ltl,
    };
    let dead_end = nav_map(
        &["Lab", "D", "E"],
        &[
            ("Lab_D", "Lab", "D", 0.6, 3.0),
            ("Lab_E", "Lab", "E", 0.5, 4.0),
            ("E_Lab", "E", "Lab", 1.0, 0.0),
        ],
    );
    vec![
        case("office_reach", office(), "Office", "F Lab"),
        case("office_ordered", office(), "Lab", "F (Hall & F Lab)"),
        case("office_avoid", office(), "Office", "!C1 U Lab"),
        // A node named like an operator is quoted in the formula.
        case("tie", tie(), "S", "F \"G\""),
        case(
            "random_ordered",
            random_map(7, 12, 10),
            "W0",
            "F (W5 & F W9)",
        ),
        case("random_avoid", random_map(11, 12, 10), "W0", "!W3 U W7"),
        case(
            "random40_ordered3",
            random_map(5, 40, 60),
            "W0",
            "F (W5 & F (W20 & F W33))",
        ),
        // [Fentanes 2015] Table III: `F v1 ∨ F v14`.
        case(
            "random40_either",
            random_map(9, 40, 60),
            "W0",
            "F W1 | F W14",
        ),
        case(
            "dead_end",
            dead_end,
            "Lab",
            // Two consecutive letters other than Lab (a dead end reads its letter forever).
            "F (!Lab & X !Lab)",
        ),
    ]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = PathBuf::from(
        std::env::args()
            .nth(1)
            .ok_or("usage: mdp_storm_cases OUTPUT_DIR")?,
    );
    std::fs::create_dir_all(&dir)?;
    let mut expected = BTreeMap::new();
    for case in cases() {
        let nav = NavigationMdp::new(&case.map, &case.success, &case.duration)?;
        let start = case.map.node(case.start)?;
        let task = Task::parse(case.ltl, &case.map)?;
        let product = nav.product(start, task.dfa())?;
        let sol = product.solve(&SolverOptions::default())?;
        let mdp = product.mdp();
        let property = prism_property(case.ltl)?;
        let name = case.name;
        write_case(
            &dir,
            name,
            (&nav, start),
            mdp,
            &sol,
            &property,
            &mut expected,
        )?;
        let policy: Vec<&str> = sol
            .policy
            .iter()
            .flatten()
            .map(|&e| nav.edges()[e].id.as_str())
            .take(6)
            .collect();
        println!(
            "{name:16} {:>4} states {:>4} choices  Pmax {:.12}  cost {:>10.6} s  gap {:.1e}  \
             sweeps {}/{}/{}  policy {policy:?}…",
            sol.state_count,
            sol.choice_count,
            sol.pmax_initial,
            sol.cost_initial,
            sol.gap,
            sol.iterations.pmax,
            sol.iterations.pmax_upper,
            sol.iterations.cost,
        );
    }
    std::fs::write(
        dir.join("expected.json"),
        serde_json::to_string_pretty(&Value::from(serde_json::Map::from_iter(expected)))?,
    )?;
    Ok(())
}
