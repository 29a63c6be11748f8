//! Graph algorithms on sparse MDPs: backward reachability, `Prob1E`, strongly connected
//! components and maximal end components (Baier & Katoen, *Principles of Model Checking*,
//! §10.6: Alg. 45-47).

use super::SparseMdp;

/// Reverse adjacency: the choices with an outcome into each state, and each choice's state.
pub(crate) struct Predecessors {
    start: Vec<usize>,
    choices: Vec<usize>,
    /// The state of every choice.
    pub(crate) owner: Vec<usize>,
}

impl Predecessors {
    pub(crate) fn new(mdp: &SparseMdp) -> Self {
        let n = mdp.state_count();
        let mut owner = vec![0; mdp.choice_count()];
        let mut start = vec![0usize; n + 1];
        for s in 0..n {
            for c in mdp.choices(s) {
                owner[c] = s;
                for &t in mdp.targets(c) {
                    start[t + 1] += 1;
                }
            }
        }
        for t in 0..n {
            start[t + 1] += start[t];
        }
        let mut next = start.clone();
        let mut choices = vec![0; start[n]];
        for c in 0..mdp.choice_count() {
            for &t in mdp.targets(c) {
                choices[next[t]] = c;
                next[t] += 1;
            }
        }
        Predecessors {
            start,
            choices,
            owner,
        }
    }

    /// The choices with an outcome into `state` (a choice appears once per such outcome).
    pub(crate) fn of(&self, state: usize) -> &[usize] {
        &self.choices[self.start[state]..self.start[state + 1]]
    }

    /// The states that can reach a `target` state through choices with `ok(c)`; choices of
    /// target states are not followed (targets are absorbing). Targets are included.
    pub(crate) fn backward(&self, target: &[bool], ok: impl Fn(usize) -> bool) -> Vec<bool> {
        let mut reach = target.to_vec();
        let mut stack: Vec<usize> = (0..target.len()).filter(|&s| target[s]).collect();
        while let Some(t) = stack.pop() {
            for &c in self.of(t) {
                let s = self.owner[c];
                if !reach[s] && ok(c) {
                    reach[s] = true;
                    stack.push(s);
                }
            }
        }
        reach
    }

    /// `Prob1E`: the states from which some policy using choices with `ok(c)` reaches a
    /// `target` state with probability one (targets included).
    pub(crate) fn prob1e(
        &self,
        mdp: &SparseMdp,
        target: &[bool],
        ok: impl Fn(usize) -> bool,
    ) -> Vec<bool> {
        let n = mdp.state_count();
        let mut u = vec![true; n];
        loop {
            // Choices that stay inside U.
            let stays: Vec<bool> = (0..mdp.choice_count())
                .map(|c| ok(c) && mdp.targets(c).iter().all(|&t| u[t]))
                .collect();
            let r = self.backward(target, |c| u[self.owner[c]] && stays[c]);
            if r == u {
                return u;
            }
            u = r;
        }
    }
}

/// Strongly connected components of the graph with the `active` states and, for each active
/// state, an edge to every outcome of its choices with `edge_ok(c)` (outcomes must be active).
/// Returns a component id per state (`usize::MAX` for inactive states). Iterative Tarjan.
pub(crate) fn sccs(mdp: &SparseMdp, active: &[bool], edge_ok: &[bool]) -> Vec<usize> {
    const NONE: usize = usize::MAX;
    let n = mdp.state_count();
    let mut index = vec![NONE; n];
    let mut low = vec![0usize; n];
    let mut on_stack = vec![false; n];
    let mut component = vec![NONE; n];
    let mut stack = Vec::new();
    let mut next_index = 0;
    let mut components = 0;
    // Successor lists, flattened per state.
    let successors = |s: usize| {
        mdp.choices(s)
            .filter(|&c| edge_ok[c])
            .flat_map(|c| mdp.targets(c).iter().copied())
    };
    // Call stack: (state, its successors collected, position in them).
    let mut calls: Vec<(usize, Vec<usize>, usize)> = Vec::new();
    for root in 0..n {
        if !active[root] || index[root] != NONE {
            continue;
        }
        // A state reached for the first time: numbered and pushed at the top of the loop.
        let mut discovered = Some(root);
        loop {
            if let Some(v) = discovered.take() {
                index[v] = next_index;
                low[v] = next_index;
                next_index += 1;
                stack.push(v);
                on_stack[v] = true;
                calls.push((v, successors(v).collect(), 0));
            }
            let Some(frame) = calls.last_mut() else {
                break;
            };
            let v = frame.0;
            if frame.2 < frame.1.len() {
                let w = frame.1[frame.2];
                frame.2 += 1;
                if !active[w] {
                    continue;
                }
                if index[w] == NONE {
                    discovered = Some(w);
                } else if on_stack[w] {
                    low[v] = low[v].min(index[w]);
                }
            } else {
                calls.pop();
                if let Some(parent) = calls.last() {
                    let p = parent.0;
                    low[p] = low[p].min(low[v]);
                }
                if low[v] == index[v] {
                    while let Some(w) = stack.pop() {
                        on_stack[w] = false;
                        component[w] = components;
                        if w == v {
                            break;
                        }
                    }
                    components += 1;
                }
            }
        }
    }
    component
}

/// Maximal end components of the sub-MDP of the `active` states and the choices with
/// `ok(c)`: a component id per state, `usize::MAX` for states in no end component (Baier &
/// Katoen Alg. 47). A choice belongs to the end component of its state iff all its outcomes
/// do.
pub(crate) fn mecs(mdp: &SparseMdp, active: &[bool], ok: impl Fn(usize) -> bool) -> Vec<usize> {
    const NONE: usize = usize::MAX;
    let n = mdp.state_count();
    let mut state_in = active.to_vec();
    let mut owner = vec![0; mdp.choice_count()];
    for s in 0..n {
        for c in mdp.choices(s) {
            owner[c] = s;
        }
    }
    let mut choice_in: Vec<bool> = (0..mdp.choice_count())
        .map(|c| state_in[owner[c]] && ok(c) && mdp.targets(c).iter().all(|&t| state_in[t]))
        .collect();
    loop {
        let component = sccs(mdp, &state_in, &choice_in);
        let mut changed = false;
        for c in 0..mdp.choice_count() {
            if choice_in[c]
                && mdp
                    .targets(c)
                    .iter()
                    .any(|&t| component[t] != component[owner[c]])
            {
                choice_in[c] = false;
                changed = true;
            }
        }
        for (s, inside) in state_in.iter_mut().enumerate() {
            if *inside && !mdp.choices(s).any(|c| choice_in[c]) {
                *inside = false;
                changed = true;
            }
        }
        if !changed {
            // Renumber the components of the remaining states densely.
            let mut id = vec![NONE; n];
            let mut renumber = std::collections::HashMap::new();
            for s in 0..n {
                if state_in[s] {
                    let next = renumber.len();
                    id[s] = *renumber.entry(component[s]).or_insert(next);
                }
            }
            return id;
        }
        for (c, inside) in choice_in.iter_mut().enumerate() {
            if *inside && !mdp.targets(c).iter().all(|&t| state_in[t]) {
                *inside = false;
            }
        }
    }
}

/// Equivalence classes for a quotient: every end component is one class, every other state of
/// interest its own class. `members` lists the states of each class (CSR).
pub(crate) struct Classes {
    start: Vec<usize>,
    members: Vec<usize>,
}

impl Classes {
    /// Classes of the `active` states given their end component ids (`usize::MAX` = none).
    pub(crate) fn new(active: &[bool], mec: &[usize]) -> Self {
        const NONE: usize = usize::MAX;
        let n = active.len();
        let mut of = vec![NONE; n];
        let mut next = 0;
        let mut mec_class = std::collections::HashMap::new();
        // States in reverse order: iterations visit classes in this order, which propagates
        // values from deep (late-discovered) states toward the initial one.
        for s in (0..n).rev() {
            if !active[s] {
                continue;
            }
            of[s] = if mec[s] == NONE {
                next += 1;
                next - 1
            } else {
                *mec_class.entry(mec[s]).or_insert_with(|| {
                    next += 1;
                    next - 1
                })
            };
        }
        let mut start = vec![0usize; next + 1];
        for s in 0..n {
            if of[s] != NONE {
                start[of[s] + 1] += 1;
            }
        }
        for k in 0..next {
            start[k + 1] += start[k];
        }
        let mut fill = start.clone();
        let mut members = vec![0; start[next]];
        for s in 0..n {
            if of[s] != NONE {
                members[fill[of[s]]] = s;
                fill[of[s]] += 1;
            }
        }
        Classes { start, members }
    }

    /// Number of classes.
    pub(crate) fn len(&self) -> usize {
        self.start.len() - 1
    }

    /// The states of class `k`.
    pub(crate) fn members(&self, k: usize) -> &[usize] {
        &self.members[self.start[k]..self.start[k + 1]]
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Choice, SparseMdp};
    use super::*;

    fn choice(outcomes: &[(usize, f64)]) -> Choice {
        Choice {
            action: 0,
            cost: 1.0,
            outcomes: outcomes.to_vec(),
        }
    }

    #[test]
    fn end_components_of_a_small_mdp() {
        // 0 <-> 1 (a cycle, an end component), 1 -> 2 w.p. 1/2 else 0, 2 self-loop (an end
        // component of its own), 3 -> 0 or 2 (in none: it cannot return to itself).
        let mdp = SparseMdp::new(
            0,
            vec![false; 4],
            vec!["a".into()],
            vec![
                vec![choice(&[(1, 1.0)])],
                vec![choice(&[(0, 1.0)]), choice(&[(2, 0.5), (0, 0.5)])],
                vec![choice(&[(2, 1.0)])],
                vec![choice(&[(0, 0.5), (2, 0.5)])],
            ],
        )
        .unwrap();
        let id = mecs(&mdp, &[true; 4], |_| true);
        assert_eq!(id[0], id[1]);
        assert_ne!(id[0], usize::MAX);
        assert_ne!(id[2], usize::MAX);
        assert_ne!(id[2], id[0]);
        assert_eq!(id[3], usize::MAX);
        // Without the choice 1 -> 0 there is no cycle between 0 and 1 any more.
        let id = mecs(&mdp, &[true; 4], |c| c != 1);
        assert_eq!((id[0], id[1]), (usize::MAX, usize::MAX));
        // Prob1E of {2}: every state can reach it almost surely (0 -> 1, then 1 -> 2 | 0).
        let pred = Predecessors::new(&mdp);
        let target = [false, false, true, false];
        assert_eq!(pred.prob1e(&mdp, &target, |_| true), vec![true; 4]);
        // Forbidding 1's risky choice leaves only the 0 <-> 1 loop: 0 and 1 fail, and so
        // does 3, which enters the loop with probability 1/2.
        assert_eq!(
            pred.prob1e(&mdp, &target, |c| c != 2),
            vec![false, false, true, false]
        );
    }
}
