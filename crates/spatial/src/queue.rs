//! The entry of the least-cost-first queue of the grid searches ([`crate::search`]: Dijkstra in
//! `chronomap-activity`'s service disturbance, A* in `chronomap-psbt`).

use std::cmp::Ordering;

/// A [`std::collections::BinaryHeap`] entry that pops the least cost first (ordered by
/// `total_cmp`), ties broken by the least cell index, so that a search is deterministic.
#[derive(Debug, PartialEq)]
pub struct MinCost(
    /// The cost so far.
    pub f64,
    /// The cell index.
    pub usize,
);

impl Eq for MinCost {}

impl Ord for MinCost {
    fn cmp(&self, other: &Self) -> Ordering {
        other
            .0
            .total_cmp(&self.0)
            .then_with(|| other.1.cmp(&self.1))
    }
}

impl PartialOrd for MinCost {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

#[cfg(test)]
mod tests {
    use super::MinCost;
    use std::collections::BinaryHeap;

    #[test]
    fn pops_least_cost_then_least_cell() {
        let mut heap: BinaryHeap<MinCost> = [
            MinCost(2.0, 1),
            MinCost(1.0, 7),
            MinCost(1.0, 3),
            MinCost(0.5, 9),
        ]
        .into_iter()
        .collect();
        let order: Vec<(f64, usize)> =
            std::iter::from_fn(|| heap.pop().map(|e| (e.0, e.1))).collect();
        assert_eq!(order, [(0.5, 9), (1.0, 3), (1.0, 7), (2.0, 1)]);
    }
}
