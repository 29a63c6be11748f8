//! One least-cost search for every grid and graph of chronomap: Dijkstra's algorithm
//! (Dijkstra 1959, "A note on two problems in connexion with graphs"), which becomes A* (Hart,
//! Nilsson & Raphael 1968, "A formal basis for the heuristic determination of minimum cost
//! paths") with an admissible heuristic `h(n)`: nodes leave the queue in the order of
//! `g(n) + h(n)`, the cost so far plus the estimate of the rest, and with `h ≡ 0` that is
//! Dijkstra's order.
//!
//! The graph is anything that lists the edges of a node ([`Graph`]): the
//! [`PlanningGrid`](crate::PlanningGrid)'s Moore neighbourhood, or the same grid with a weight per
//! cell ([`Weighted`]). The queue is [`MinCost`]: equal priorities pop the least node index first,
//! so every search is deterministic.
//!
//! ```
//! use chronomap_spatial::search::{Graph, least_cost};
//!
//! // A path 0 – 1 – 2 of edges 1.0 and 2.5, and a shortcut 0 – 2 of 4.0.
//! struct Line;
//! impl Graph for Line {
//!     fn node_count(&self) -> usize {
//!         3
//!     }
//!     fn edges(&self, node: usize) -> impl Iterator<Item = (usize, f64)> {
//!         let edges: &[(usize, f64)] = match node {
//!             0 => &[(1, 1.0), (2, 4.0)],
//!             1 => &[(0, 1.0), (2, 2.5)],
//!             _ => &[(1, 2.5), (0, 4.0)],
//!         };
//!         edges.iter().copied()
//!     }
//! }
//! let paths = least_cost(&Line, 0, Some(2), |_| 0.0, f64::INFINITY).unwrap();
//! assert_eq!(paths.path_to(2), Some(vec![0, 1, 2]));
//! assert_eq!(paths.cost(2), 3.5);
//! ```

use std::collections::BinaryHeap;

use crate::queue::MinCost;

/// A directed graph of the nodes `0..node_count()` with non-negative edge costs.
pub trait Graph {
    /// The number of nodes.
    fn node_count(&self) -> usize;

    /// The edges leaving `node`: `(to, cost)`, in a fixed order (the order decides between
    /// equally cheap paths).
    fn edges(&self, node: usize) -> impl Iterator<Item = (usize, f64)>;
}

/// A graph whose edge `u → v` costs the edge of the inner graph times the weight of the node
/// it enters, `c(u, v) · w(v)`: a cost map over the cells of a grid.
#[derive(Clone, Copy, Debug)]
pub struct Weighted<'a, G: ?Sized> {
    graph: &'a G,
    weights: &'a [f64],
}

impl<'a, G: Graph + ?Sized> Weighted<'a, G> {
    /// `graph` with one weight per node, or `None` if `weights` has another length. Weights
    /// of nodes a search may enter must be finite and `> 0`.
    pub fn new(graph: &'a G, weights: &'a [f64]) -> Option<Self> {
        (weights.len() == graph.node_count()).then_some(Weighted { graph, weights })
    }
}

impl<G: Graph + ?Sized> Graph for Weighted<'_, G> {
    fn node_count(&self) -> usize {
        self.graph.node_count()
    }

    fn edges(&self, node: usize) -> impl Iterator<Item = (usize, f64)> {
        self.graph
            .edges(node)
            .map(|(to, cost)| (to, cost * self.weights[to]))
    }
}

/// The result of [`least_cost`]: the cost of every node reached from the source and the tree
/// of least-cost paths back to it.
#[derive(Clone, Debug)]
pub struct ShortestPaths {
    source: usize,
    cost: Vec<f64>,
    previous: Vec<usize>,
    settled: Vec<bool>,
}

impl ShortestPaths {
    /// The source node.
    pub fn source(&self) -> usize {
        self.source
    }

    /// The least cost found from the source to `node`: final for a [settled](Self::settled)
    /// node, infinite for a node never reached (or beyond the graph).
    pub fn cost(&self, node: usize) -> f64 {
        self.cost.get(node).copied().unwrap_or(f64::INFINITY)
    }

    /// The nodes reached (a finite cost), the source included, in index order.
    pub fn reached(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.cost.len()).filter(|&i| self.cost[i].is_finite())
    }

    /// Whether the search took `node` off its queue, so that [`ShortestPaths::cost`] is the
    /// least cost to it.
    pub fn settled(&self, node: usize) -> bool {
        self.settled.get(node).copied().unwrap_or(false)
    }

    /// The least-cost path from the source to a settled `node`, both included.
    pub fn path_to(&self, node: usize) -> Option<Vec<usize>> {
        if !self.settled(node) {
            return None;
        }
        let mut nodes = vec![node];
        while let Some(&last) = nodes.last()
            && last != self.source
        {
            nodes.push(self.previous[last]);
        }
        nodes.reverse();
        Some(nodes)
    }
}

/// Least-cost paths from `source` (module docs): nodes are settled in the order of
/// `g + heuristic(node)` until `goal` is settled (or, without a goal, until the queue is
/// empty); a node is only reached on paths costing at most `bound`. With `heuristic ≡ 0`
/// this is Dijkstra's algorithm, with an admissible and consistent heuristic it is A*; either
/// way the cost of a settled node is its least cost. Among equally cheap paths the first one
/// found wins (edges are visited in [`Graph::edges`] order, equal priorities pop the least
/// node first). `None` if `source` is not a node of the graph.
///
/// # Complexity
/// `O(E log E)` for the `E` edges of the nodes settled.
pub fn least_cost<G: Graph + ?Sized>(
    graph: &G,
    source: usize,
    goal: Option<usize>,
    heuristic: impl Fn(usize) -> f64,
    bound: f64,
) -> Option<ShortestPaths> {
    let n = graph.node_count();
    if source >= n {
        return None;
    }
    let mut cost = vec![f64::INFINITY; n];
    let mut previous = vec![usize::MAX; n];
    let mut settled = vec![false; n];
    let mut queue = BinaryHeap::new();
    cost[source] = 0.0;
    queue.push(MinCost(heuristic(source), source));
    while let Some(MinCost(_, node)) = queue.pop() {
        if settled[node] {
            continue;
        }
        settled[node] = true;
        if goal == Some(node) {
            break;
        }
        for (next, step) in graph.edges(node) {
            let candidate = cost[node] + step;
            if candidate <= bound && !settled[next] && candidate < cost[next] {
                cost[next] = candidate;
                previous[next] = node;
                queue.push(MinCost(candidate + heuristic(next), next));
            }
        }
    }
    Some(ShortestPaths {
        source,
        cost,
        previous,
        settled,
    })
}
