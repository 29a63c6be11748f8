//! Text exports: the PRISM language (STRANDS `mdp_plan_exec` layout) and Storm's explicit DRN
//! format. Pure string builders; writing files is the caller's business.

use std::fmt::Write;

use super::{MdpError, NavigationMdp, Solution, SparseMdp};
// PRISM's identifiers are LTL's atoms: `[A-Za-z_][A-Za-z0-9_]*`.
use crate::ltl::is_identifier;

/// A number as the shortest decimal that reads back to the same `f64` (no exponent, always
/// with a decimal point, as PRISM and Storm both parse it).
fn number(x: f64) -> String {
    let s = format!("{x}");
    if s.contains('.') || !x.is_finite() {
        s
    } else {
        s + ".0"
    }
}

/// PRISM's keywords (language and property operators).
const PRISM_KEYWORDS: &[&str] = &[
    "A",
    "bool",
    "clock",
    "const",
    "ctmc",
    "C",
    "double",
    "dtmc",
    "E",
    "endinit",
    "endinvariant",
    "endmodule",
    "endobservables",
    "endrewards",
    "endsystem",
    "false",
    "formula",
    "filter",
    "func",
    "F",
    "global",
    "G",
    "init",
    "invariant",
    "I",
    "int",
    "label",
    "max",
    "mdp",
    "min",
    "module",
    "nondeterministic",
    "observable",
    "observables",
    "of",
    "Pmax",
    "Pmin",
    "P",
    "pomdp",
    "popomdp",
    "probabilistic",
    "prob",
    "pta",
    "rate",
    "rewards",
    "Rmax",
    "Rmin",
    "R",
    "S",
    "stochastic",
    "system",
    "true",
    "U",
    "W",
    "X",
];

fn check_name(name: &str, role: &'static str, keywords: &[&str]) -> Result<(), MdpError> {
    let reason = if !is_identifier(name) {
        "not an identifier ([A-Za-z_][A-Za-z0-9_]*)"
    } else if keywords.contains(&name) {
        "a reserved word"
    } else {
        return Ok(());
    };
    Err(MdpError::InvalidName {
        name: name.to_string(),
        role,
        reason,
    })
}

impl NavigationMdp {
    /// The Navigation MDP in the PRISM language, in the layout of STRANDS `mdp_plan_exec`:
    /// one variable `waypoint:[-1..N-1] init initial;` (`-1` is the failure sink `s_f`), one
    /// command per edge named by its id,
    /// `[e] (waypoint=i) -> p:(waypoint'=j) + 1-p:(waypoint'=-1);` (outcomes of probability
    /// zero left out, probabilities as shortest round-trip decimals), one label per node,
    /// `label "Name" = (waypoint=i);`, and the reward structure `"time"` with the durations.
    /// PRISM and Storm give the sink (and nodes without edges) a self-loop, as
    /// [`NavigationMdp::product`] assumes.
    ///
    /// # Errors
    /// [`MdpError::NodeOutOfRange`] if `initial` is not a node; [`MdpError::InvalidName`] if
    /// an edge id is not a PRISM identifier or is a keyword, or a node name is not an
    /// identifier or is `init` or `deadlock` (PRISM's built-in labels).
    pub fn to_prism(&self, initial: usize) -> Result<String, MdpError> {
        let n = self.node_count();
        if initial >= n {
            return Err(MdpError::NodeOutOfRange {
                node: initial,
                nodes: n,
            });
        }
        for edge in self.edges() {
            check_name(&edge.id, "a PRISM action", PRISM_KEYWORDS)?;
        }
        for name in self.node_names() {
            check_name(name, "a PRISM label", &["init", "deadlock"])?;
        }
        let sink_value = |s: usize| if s == self.sink() { -1 } else { s as i64 };
        let mut out = String::new();
        let _ = writeln!(
            out,
            "// Navigation MDP at time t ([Fentanes 2015] sec. V), STRANDS mdp_plan_exec layout: \
             waypoint = node index, -1 = failure sink"
        );
        let _ = writeln!(out, "mdp\n\nmodule M");
        let _ = writeln!(out, "  waypoint:[-1..{}] init {initial};", n - 1);
        for (e, edge) in self.edges().iter().enumerate() {
            let outcomes: Vec<String> = self
                .outcomes(e)
                .map(|(t, p)| format!("{}:(waypoint'={})", number(p), sink_value(t)))
                .collect();
            let _ = writeln!(
                out,
                "  [{}] (waypoint={}) -> {};",
                edge.id,
                edge.from,
                outcomes.join(" + ")
            );
        }
        let _ = writeln!(out, "endmodule\n");
        for (i, name) in self.node_names().iter().enumerate() {
            let _ = writeln!(out, "label \"{name}\" = (waypoint={i});");
        }
        let _ = writeln!(out, "\nrewards \"time\"");
        for (e, edge) in self.edges().iter().enumerate() {
            let _ = writeln!(
                out,
                "  [{}] (waypoint={}):{};",
                edge.id,
                edge.from,
                number(self.duration()[e])
            );
        }
        let _ = writeln!(out, "endrewards");
        Ok(out)
    }
}

/// The PRISM property `Pmax=? [ φ ]` of a co-safe LTL formula over node names: names become
/// quoted labels (`F Kitchen` → `Pmax=? [ F "Kitchen" ]`), `->`/`<->`/`&&`/`||` become
/// PRISM's `=>`/`<=>`/`&`/`|`; the temporal operators `F G X U R W`, `true`, `false`,
/// parentheses, `!`, `&`, `|` and already quoted labels are kept.
///
/// # Errors
/// [`MdpError::InvalidFormula`] for a character PRISM would not read (a name that is not an
/// identifier, an unterminated quote).
pub fn prism_property(formula: &str) -> Result<String, MdpError> {
    const OPERATORS: &[&str] = &["F", "G", "X", "U", "R", "W", "true", "false"];
    let mut out = String::new();
    let chars: Vec<char> = formula.chars().collect();
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let rest: String = chars[i..chars.len().min(i + 3)].iter().collect();
        if c.is_whitespace() || matches!(c, '(' | ')' | '!') {
            out.push(c);
            i += 1;
        } else if rest.starts_with("<->") {
            out.push_str("<=>");
            i += 3;
        } else if rest.starts_with("->") || rest.starts_with("=>") {
            out.push_str("=>");
            i += 2;
        } else if rest.starts_with("<=>") {
            out.push_str("<=>");
            i += 3;
        } else if rest.starts_with("&&") || rest.starts_with("||") {
            out.push(c);
            i += 2;
        } else if matches!(c, '&' | '|') {
            out.push(c);
            i += 1;
        } else if c == '"' {
            let end = chars[i + 1..]
                .iter()
                .position(|&d| d == '"')
                .ok_or_else(|| MdpError::InvalidFormula("unterminated quote".into()))?;
            out.extend(&chars[i..=i + 1 + end]);
            i += end + 2;
        } else if c.is_ascii_alphanumeric() || c == '_' {
            let len = chars[i..]
                .iter()
                .take_while(|d| d.is_ascii_alphanumeric() || **d == '_')
                .count();
            let word: String = chars[i..i + len].iter().collect();
            if OPERATORS.contains(&word.as_str()) {
                out.push_str(&word);
            } else if is_identifier(&word) {
                let _ = write!(out, "\"{word}\"");
            } else {
                return Err(MdpError::InvalidFormula(format!(
                    "{word:?} is not a PRISM identifier"
                )));
            }
            i += len;
        } else {
            return Err(MdpError::InvalidFormula(format!(
                "unexpected character {c:?}"
            )));
        }
    }
    Ok(format!("Pmax=? [ {} ]", out.trim()))
}

impl SparseMdp {
    /// The MDP in Storm's explicit DRN format (checked with Storm 2.0 through stormpy):
    ///
    /// ```text
    /// @type: MDP
    /// @parameters
    ///
    /// @reward_models
    /// time
    /// @nr_states
    /// 3
    /// @nr_choices
    /// 4
    /// @model
    /// state 0 init
    /// \taction Door [10.0]
    /// \t\t1 : 0.2
    /// \t\t2 : 0.8
    /// …
    /// ```
    ///
    /// Costs are action rewards of the reward model `time`. States are labelled `init`,
    /// `goal` and with every extra label `(name, flags)` whose flag is set. A state without
    /// choices gets a self-loop `absorb` with reward 0 (Storm would add it anyway), so that
    /// `@nr_choices` counts it.
    ///
    /// # Errors
    /// [`MdpError::LengthMismatch`] if a label's flags are not one per state;
    /// [`MdpError::InvalidName`] for a label name that is not an identifier or repeats
    /// `init`/`goal`, or an action name containing whitespace.
    pub fn to_drn(&self, labels: &[(&str, &[bool])]) -> Result<String, MdpError> {
        let n = self.state_count();
        for &(name, flags) in labels {
            check_name(name, "a DRN label", &["init", "goal"])?;
            if flags.len() != n {
                return Err(MdpError::LengthMismatch {
                    what: "label flags",
                    expected: n,
                    found: flags.len(),
                });
            }
        }
        for name in &self.action_names {
            if name.is_empty() || name.chars().any(char::is_whitespace) {
                return Err(MdpError::InvalidName {
                    name: name.clone(),
                    role: "a DRN action",
                    reason: "empty or contains whitespace",
                });
            }
        }
        let absorbing = (0..n).filter(|&s| self.choices(s).is_empty()).count();
        let mut out = String::new();
        let _ = writeln!(out, "// written by chronomap-core (mdp::SparseMdp::to_drn)");
        let _ = writeln!(out, "@type: MDP\n@parameters\n\n@reward_models\ntime");
        let _ = writeln!(out, "@nr_states\n{n}");
        let _ = writeln!(out, "@nr_choices\n{}", self.choice_count() + absorbing);
        let _ = writeln!(out, "@model");
        for s in 0..n {
            let _ = write!(out, "state {s}");
            if s == self.initial {
                out.push_str(" init");
            }
            if self.goal[s] {
                out.push_str(" goal");
            }
            for &(name, flags) in labels {
                if flags[s] {
                    let _ = write!(out, " {name}");
                }
            }
            out.push('\n');
            if self.choices(s).is_empty() {
                let _ = writeln!(out, "\taction absorb [0.0]\n\t\t{s} : 1.0");
            }
            for c in self.choices(s) {
                let _ = writeln!(
                    out,
                    "\taction {} [{}]",
                    self.action_name(c),
                    number(self.cost(c))
                );
                for (t, p) in self.outcomes(c) {
                    let _ = writeln!(out, "\t\t{t} : {}", number(p));
                }
            }
        }
        Ok(out)
    }
}

/// The DRN of a solved MDP (a product, typically): labels `init`, `goal` and `decided`
/// ([`Solution::decided`]). Storm's `Pmax=? [F "goal"]` on it is [`Solution::pmax`].
///
/// # Errors
/// [`MdpError::SolutionMismatch`] if the solution is of another MDP; see
/// [`SparseMdp::to_drn`].
pub fn product_drn(mdp: &SparseMdp, solution: &Solution) -> Result<String, MdpError> {
    check_solution(mdp, solution)?;
    mdp.to_drn(&[("decided", &solution.decided)])
}

/// The DRN of the restricted MDP: only the `Pmax`-optimal choices of the states that are not
/// decided ([`Solution::optimal`]); decided states become absorbing. Storm's
/// `Rmin=? [F "decided"]` on it is [`Solution::cost`].
///
/// # Errors
/// As [`product_drn`].
pub fn restricted_drn(mdp: &SparseMdp, solution: &Solution) -> Result<String, MdpError> {
    check_solution(mdp, solution)?;
    // Decided states keep no choice: they are the targets.
    let mut keep = vec![false; mdp.choice_count()];
    for s in (0..mdp.state_count()).filter(|&s| !solution.decided[s]) {
        for c in mdp.choices(s) {
            keep[c] = solution.optimal[c];
        }
    }
    mdp.restrict(&keep)?
        .to_drn(&[("decided", &solution.decided)])
}

fn check_solution(mdp: &SparseMdp, solution: &Solution) -> Result<(), MdpError> {
    if solution.state_count != mdp.state_count() || solution.decided.len() != mdp.state_count() {
        return Err(MdpError::SolutionMismatch {
            expected: mdp.state_count(),
            found: solution.decided.len(),
        });
    }
    if solution.optimal.len() != mdp.choice_count() {
        return Err(MdpError::LengthMismatch {
            what: "optimal choices",
            expected: mdp.choice_count(),
            found: solution.optimal.len(),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_round_trip_without_exponents() {
        for x in [
            0.1 + 0.2,
            1e-300,
            0.06999999999999995,
            123456.789,
            1.0,
            0.0,
            2e20,
        ] {
            let s = number(x);
            assert!(!s.contains('e') && s.contains('.'), "{s}");
            assert_eq!(s.parse::<f64>().unwrap(), x);
        }
        assert_eq!(number(1.0), "1.0");
        assert_eq!(number(0.93), "0.93");
    }
}
