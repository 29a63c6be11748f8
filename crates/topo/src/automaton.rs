//! Deterministic finite automata over node labels: the bridge between co-safe LTL tasks
//! ([`crate::ltl`]) and navigation MDPs ([`crate::mdp`]).

use serde::{Deserialize, Serialize};

/// A deterministic finite automaton reading, at every step, which node the robot is at.
///
/// The alphabet is exclusive: at each step exactly one of the atoms (node names the task
/// mentions) holds, or none of them (the robot is at another node, or in the failure sink).
/// Letter `i < atoms.len()` means "atom `i` holds"; letter `atoms.len()` means "no atom holds".
///
/// Product semantics: the automaton reads the label of every state the system is in, starting
/// with the initial one, so a product starts in `(s₀, next(initial, letter(s₀)))`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Dfa {
    /// The atoms, in letter order.
    pub atoms: Vec<String>,
    /// Initial state.
    pub initial: usize,
    /// `accepting[q]`: whether reaching `q` satisfies the task (accepting states are absorbing
    /// for co-safe tasks).
    pub accepting: Vec<bool>,
    /// `delta[q * letters + letter]`: the successor of `q` on `letter`.
    pub delta: Vec<usize>,
}

impl Dfa {
    /// Number of letters: `atoms.len() + 1`.
    pub fn letters(&self) -> usize {
        self.atoms.len() + 1
    }

    /// Number of states.
    pub fn states(&self) -> usize {
        self.accepting.len()
    }

    /// The successor of `state` on `letter`.
    ///
    /// # Panics
    /// If `state` or `letter` is out of range.
    pub fn next(&self, state: usize, letter: usize) -> usize {
        assert!(letter < self.letters(), "letter {letter} out of range");
        self.delta[state * self.letters() + letter]
    }

    /// The letter of a node name: its atom index, or "no atom" if the task does not mention it.
    pub fn letter_of(&self, node: Option<&str>) -> usize {
        node.and_then(|n| self.atoms.iter().position(|a| a == n))
            .unwrap_or(self.atoms.len())
    }

    /// Whether the automaton accepts a finite word (a sequence of letters read from `initial`).
    pub fn accepts(&self, word: &[usize]) -> bool {
        let mut q = self.initial;
        for &letter in word {
            q = self.next(q, letter);
        }
        self.accepting[q]
    }

    /// Checks the shape of the automaton.
    pub fn is_consistent(&self) -> bool {
        let n = self.states();
        n > 0
            && self.initial < n
            && self.delta.len() == n * self.letters()
            && self.delta.iter().all(|&q| q < n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_hand_made_automaton_for_eventually_kitchen() {
        // F Kitchen: state 0 waits, state 1 accepts.
        let dfa = Dfa {
            atoms: vec!["Kitchen".into()],
            initial: 0,
            accepting: vec![false, true],
            delta: vec![1, 0, 1, 1],
        };
        assert!(dfa.is_consistent());
        let kitchen = dfa.letter_of(Some("Kitchen"));
        let other = dfa.letter_of(Some("Sofas"));
        assert_eq!((kitchen, other), (0, 1));
        assert!(dfa.accepts(&[other, kitchen, other]));
        assert!(!dfa.accepts(&[other, other]));
        assert!(!dfa.accepts(&[]));
    }
}
