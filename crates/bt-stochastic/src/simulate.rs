//! Monte-Carlo execution of a stochastic behavior tree: ticks the tree as Algorithms 5.1 and
//! 5.2 do, drawing each leaf's outcome and duration. Independent of the Markov chain, so the
//! tests can check the chain against it.

use super::Node;
use chronomap_rng::Xoshiro256StarStar;

/// How a run of a tree ended and how long it took (seconds).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Run {
    /// Whether the tree returned success.
    pub success: bool,
    /// Time from the first tick to the outcome.
    pub duration: f64,
}

/// Runs `tree` once: an action succeeds with probability `p_s` after `Exp(μ)` seconds, else
/// fails after `Exp(ν)`; a condition holds with probability `p_s` and takes no time.
pub fn run(tree: &Node, rng: &mut Xoshiro256StarStar) -> Run {
    match tree {
        Node::Action(a) => {
            if rng.bernoulli(a.p_success()) {
                Run {
                    success: true,
                    duration: rng.exp1() / a.mu(),
                }
            } else {
                Run {
                    success: false,
                    duration: rng.exp1() / a.nu(),
                }
            }
        }
        Node::Condition(c) => Run {
            success: rng.bernoulli(c.p_success()),
            duration: 0.0,
        },
        Node::Sequence(children) => {
            let mut duration = 0.0;
            for child in children {
                let r = run(child, rng);
                duration += r.duration;
                if !r.success {
                    return Run {
                        success: false,
                        duration,
                    };
                }
            }
            Run {
                success: true,
                duration,
            }
        }
        Node::Fallback(children) => {
            let mut duration = 0.0;
            for child in children {
                let r = run(child, rng);
                duration += r.duration;
                if r.success {
                    return Run {
                        success: true,
                        duration,
                    };
                }
            }
            Run {
                success: false,
                duration,
            }
        }
    }
}
