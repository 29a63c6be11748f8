//! A static k-d tree (Bentley 1975; Friedman, Bentley & Finkel 1977) over `K`-dimensional
//! points: built once by median splits on the axis of widest spread, queried for the `k` nearest
//! neighbours within a radius. The registration uses it for point neighbourhoods (`K` = 2, 3)
//! and for nearest neighbours in feature space (`K` = 33); it is the workspace's one k-d tree.
//!
//! Why not a crate: kiddo 6.3 with default features off pulls 38 crates (a proc-macro stack,
//! `cc`, `generator`) and 67,000 lines, 24 s of CPU for a debug build on this workspace's 2-core
//! machines; these 150 lines do what the registration needs, with the same asymptotics.
//!
//! ```
//! use chronomap_geometry::kdtree::KdTree;
//!
//! let tree = KdTree::new(&[[0.0, 0.0], [3.0, 4.0], [1.0, 1.0]]);
//! // Nearest to (2, 2): (1, 1) at squared distance 2.
//! assert_eq!(tree.nearest(&[2.0, 2.0]), Some((2, 2.0)));
//! // The two nearest to the origin within distance 2 (squared 4): itself, then (1, 1).
//! let mut out = Vec::new();
//! tree.nearest_within(&[0.0, 0.0], 5, 4.0, &mut out);
//! assert_eq!(out, vec![(0, 0.0), (2, 2.0)]);
//! ```

/// Points per leaf.
const LEAF: usize = 12;

#[derive(Clone, Debug)]
enum Node {
    Leaf {
        start: u32,
        end: u32,
    },
    Split {
        axis: u32,
        value: f64,
        left: u32,
        right: u32,
    },
}

/// A k-d tree over `K`-dimensional points with finite coordinates.
#[derive(Clone, Debug)]
pub struct KdTree<const K: usize> {
    points: Vec<[f64; K]>,
    index: Vec<u32>,
    nodes: Vec<Node>,
}

impl<const K: usize> KdTree<K> {
    /// Builds the tree in O(n log n). Coordinates must be finite (the clouds of this crate are
    /// checked on construction); at most `u32::MAX` points.
    pub fn new(points: &[[f64; K]]) -> KdTree<K> {
        assert!(
            points.len() < u32::MAX as usize,
            "k-d tree: too many points"
        );
        let mut tree = KdTree {
            points: Vec::with_capacity(points.len()),
            index: (0..points.len() as u32).collect(),
            nodes: Vec::with_capacity(2 * points.len() / LEAF + 1),
        };
        if !points.is_empty() {
            tree.build(points, 0, points.len());
        }
        tree.points = tree.index.iter().map(|&i| points[i as usize]).collect();
        tree
    }

    fn build(&mut self, points: &[[f64; K]], start: usize, end: usize) -> u32 {
        let id = self.nodes.len() as u32;
        if end - start <= LEAF {
            self.nodes.push(Node::Leaf {
                start: start as u32,
                end: end as u32,
            });
            return id;
        }
        let mut lo = [f64::INFINITY; K];
        let mut hi = [f64::NEG_INFINITY; K];
        for &i in &self.index[start..end] {
            for a in 0..K {
                lo[a] = lo[a].min(points[i as usize][a]);
                hi[a] = hi[a].max(points[i as usize][a]);
            }
        }
        let axis = (0..K)
            .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
            .unwrap_or(0);
        let mid = (start + end) / 2;
        self.index[start..end].select_nth_unstable_by(mid - start, |&i, &j| {
            points[i as usize][axis].total_cmp(&points[j as usize][axis])
        });
        let value = points[self.index[mid] as usize][axis];
        self.nodes.push(Node::Leaf { start: 0, end: 0 });
        let left = self.build(points, start, mid);
        let right = self.build(points, mid, end);
        self.nodes[id as usize] = Node::Split {
            axis: axis as u32,
            value,
            left,
            right,
        };
        id
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether the tree is empty.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The nearest point: `(index, squared distance)`, `None` for an empty tree.
    pub fn nearest(&self, query: &[f64; K]) -> Option<(usize, f64)> {
        let mut out = Vec::with_capacity(1);
        self.nearest_within(query, 1, f64::INFINITY, &mut out);
        out.first().copied()
    }

    /// The `k` nearest points with squared distance at most `max_dist2`, nearest first, as
    /// `(index, squared distance)` into `out` (cleared first). Ties are broken by tree order.
    pub fn nearest_within(
        &self,
        query: &[f64; K],
        k: usize,
        max_dist2: f64,
        out: &mut Vec<(usize, f64)>,
    ) {
        out.clear();
        if k == 0 || self.nodes.is_empty() {
            return;
        }
        self.search(0, query, k, max_dist2, out);
    }

    fn search(&self, node: u32, q: &[f64; K], k: usize, bound: f64, out: &mut Vec<(usize, f64)>) {
        match self.nodes[node as usize] {
            Node::Leaf { start, end } => {
                for slot in start as usize..end as usize {
                    let p = &self.points[slot];
                    let d2: f64 = (0..K).map(|a| (p[a] - q[a]) * (p[a] - q[a])).sum();
                    let worst = if out.len() < k { bound } else { out[k - 1].1 };
                    if d2 <= worst && !(out.len() == k && d2 == worst) {
                        let at = out.partition_point(|&(_, e)| e <= d2);
                        if out.len() == k {
                            out.pop();
                        }
                        out.insert(at, (self.index[slot] as usize, d2));
                    }
                }
            }
            Node::Split {
                axis,
                value,
                left,
                right,
            } => {
                let diff = q[axis as usize] - value;
                let (near, far) = if diff < 0.0 {
                    (left, right)
                } else {
                    (right, left)
                };
                self.search(near, q, k, bound, out);
                let worst = if out.len() < k { bound } else { out[k - 1].1 };
                if diff * diff <= worst {
                    self.search(far, q, k, bound, out);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronomap_rng::Xoshiro256StarStar;

    #[test]
    fn agrees_with_brute_force() {
        let mut rng = Xoshiro256StarStar::seed_from_u64(7);
        // Integer grid coordinates make ties frequent.
        let points: Vec<[f64; 3]> = (0..2000)
            .map(|_| std::array::from_fn(|_| (rng.uniform(0.0, 10.0)).floor()))
            .collect();
        let tree = KdTree::new(&points);
        let mut out = Vec::new();
        for _ in 0..200 {
            let q: [f64; 3] = std::array::from_fn(|_| rng.uniform(-1.0, 11.0));
            let mut all: Vec<f64> = points
                .iter()
                .map(|p| (0..3).map(|a| (p[a] - q[a]).powi(2)).sum())
                .collect();
            all.sort_by(f64::total_cmp);
            tree.nearest_within(&q, 7, 4.0, &mut out);
            let expected: Vec<f64> = all.iter().copied().filter(|&d| d <= 4.0).take(7).collect();
            let got: Vec<f64> = out.iter().map(|&(_, d)| d).collect();
            assert_eq!(got, expected);
            for &(i, d) in &out {
                let e: f64 = (0..3).map(|a| (points[i][a] - q[a]).powi(2)).sum();
                assert_eq!(e, d);
            }
            assert_eq!(tree.nearest(&q).unwrap().1, all[0]);
        }
    }

    #[test]
    fn empty_and_tiny_trees() {
        let tree = KdTree::<2>::new(&[]);
        assert!(tree.is_empty() && tree.nearest(&[0.0, 0.0]).is_none());
        let tree = KdTree::new(&[[1.0, 1.0]]);
        assert_eq!(tree.nearest(&[0.0, 0.0]), Some((0, 2.0)));
    }
}
