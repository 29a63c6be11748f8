//! The map graph of [Stüde 2024] §3.3.1 and §3.3.3: metric maps linked at link points, the
//! relative poses of linked maps with their first-order covariance (eqs. (3.10)–(3.13)), the
//! composition along a path of maps found by Dijkstra's algorithm (eq. (3.14)), and the loop
//! search over link points and link-point candidates within the radius of eq. (3.8).
//!
//! The hybrid map `H = ⟨M₁:ₙ, L₁:ₘ, E₁:ₚ⟩`: maps `M`, link points `L` — each a pair of poses
//! `⟨⁽ʲ⁾m̄ᵢ, ⁽ᵏ⁾m̄ᵢ⟩` of the same place in two maps `j ≠ k` — and edges `E` joining every two
//! link points of the same map, weighted by their Euclidean distance in that map.
//!
//! ```
//! use chronomap_multimap::config::MapConfig;
//! use chronomap_multimap::graph::{MapGraph, PathWeight};
//! use chronomap_multimap::se2::{Pose2, UncertainPose};
//!
//! let mut g = MapGraph::new();
//! let m0 = g.add_map(MapConfig::ShortRange, None)?;
//! let m1 = g.add_map(MapConfig::LongRange, None)?;
//! // The door is at (4, 0) facing +x in map 0, and map 1 starts there (its origin).
//! let cov = [[0.04, 0.0, 0.0], [0.0, 0.04, 0.0], [0.0, 0.0, 0.01]];
//! let door_in_0 = UncertainPose::new(Pose2::new(4.0, 0.0, 0.0)?, cov)?;
//! g.add_link(m0, door_in_0, m1, UncertainPose::exact(Pose2::IDENTITY))?;
//! // The robot 3 m ahead in map 1 is 7 m ahead in map 0; the heading variance of the door
//! // pose moves it sideways by 3 m·σ_θ: var(y) = 0.04 + 3²·0.01.
//! let robot = UncertainPose::exact(Pose2::new(3.0, 0.0, 0.0)?);
//! let in_0 = g.pose_in(m0, m1, &robot, PathWeight::Hops)?;
//! assert!((in_0.mean.x - 7.0).abs() < 1e-12);
//! assert!((in_0.cov[1][1] - (0.04 + 9.0 * 0.01)).abs() < 1e-12);
//! # Ok::<(), chronomap_multimap::MultimapError>(())
//! ```
//!
//! [Stüde 2024]: M. Stüde, dissertation, Leibniz Universität Hannover, 2024.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use serde::{Deserialize, Serialize};

use crate::MultimapError;
use crate::config::MapConfig;
use crate::door::BoundingBox;
use crate::se2::{UncertainPose, validate_covariance};
use crate::search::{SearchParams, search_radius_for};

/// The most maps a graph holds.
pub const MAX_MAPS: usize = 100_000;
/// The most link points plus link-point candidates a graph holds.
pub const MAX_LINKS: usize = 100_000;
/// The most link points one map may have for the edges between them ([`MapGraph::link_edges`],
/// [`PathWeight::Distance`]): they are all pairs, so memory grows with the square (2,000 link
/// points: 4·10⁶ edges).
pub const MAX_LINKS_PER_MAP_FOR_EDGES: usize = 2_000;

/// One metric map `Mᵢ` (the map data itself lives with the SLAM method that made it).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MapNode {
    /// The SLAM configuration it was made with.
    pub config: MapConfig,
    /// The bounding box that chose the configuration, if known.
    pub bbox: Option<BoundingBox>,
}

/// A link point `Lᵢ`: the same place as a pose in each of two maps, with the uncertainty of
/// each (§3.3.1; `⁽ⁱ⁾mᵢ ~ N(⁽ⁱ⁾m̄ᵢ, ⁽ⁱ⁾Σᵢ)` of §3.3.3).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LinkPoint {
    /// The two maps, different.
    pub maps: [usize; 2],
    /// The link point's pose in `maps[0]` and in `maps[1]`.
    pub poses: [UncertainPose; 2],
}

/// A link-point candidate `LCᵢ`: a place in front of an open door, saved for later loop
/// closures (§3.3.3).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LinkCandidate {
    /// Its map.
    pub map: usize,
    /// Its pose in that map.
    pub pose: UncertainPose,
    /// The caller's key for the environment data saved with it (e.g. a scan index).
    pub tag: u64,
}

/// The weight Dijkstra's algorithm minimises over a path of maps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum PathWeight {
    /// The number of link points passed.
    Hops,
    /// The Euclidean length of the walk from map origin to map origin through the link points
    /// (§3.3.1: edges between link points of one map weighted by their distance).
    Distance,
    /// The sum of the traces of the position blocks of the relative map poses' covariances
    /// (m²). An additive proxy: the covariance of a composition is not the sum of its parts
    /// (eq. (3.13) rotates and grows them), so this is not always the path of least final
    /// uncertainty.
    Uncertainty,
}

/// A path of maps from `maps[0]` to its last map, through `links[i]` from `maps[i]` to
/// `maps[i + 1]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MapPath {
    /// The map indices `v` of eq. (3.14), start and target included.
    pub maps: Vec<usize>,
    /// The link points passed.
    pub links: Vec<usize>,
    /// The weight of the path.
    pub cost: f64,
}

/// What a loop search found near the robot.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum LoopTarget {
    /// A link point.
    Link(usize),
    /// A link-point candidate.
    Candidate(usize),
}

/// One link point or candidate within the search radius.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LoopHit {
    /// Which.
    pub target: LoopTarget,
    /// Its position in the frame of the search's reference map (m).
    pub position: [f64; 2],
    /// Its distance from the robot's estimated position (m).
    pub distance: f64,
}

/// The result of [`MapGraph::loop_search`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LoopSearch {
    /// The robot's pose in the reference map with its propagated covariance (eq. (3.14)).
    pub pose: UncertainPose,
    /// The search radius of eq. (3.8) (m).
    pub radius: f64,
    /// The link points and candidates within it, nearest first.
    pub hits: Vec<LoopHit>,
}

/// Dijkstra's algorithm over a directed graph with non-negative weights: `adjacency[u]` lists
/// `(v, weight, tag)`. Returns the cost and the path as `(node, tag of the edge into it)`
/// after `source`, or `None` where `target` is unreachable. Ties are broken towards smaller
/// node indices. `O((V + E) log V)`.
pub fn dijkstra(
    adjacency: &[Vec<(usize, f64, usize)>],
    source: usize,
    target: usize,
) -> Option<(f64, Vec<(usize, usize)>)> {
    #[derive(PartialEq)]
    struct State(f64, usize);
    impl Eq for State {}
    impl Ord for State {
        fn cmp(&self, other: &Self) -> Ordering {
            other
                .0
                .total_cmp(&self.0)
                .then_with(|| other.1.cmp(&self.1))
        }
    }
    impl PartialOrd for State {
        fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
            Some(self.cmp(other))
        }
    }
    let n = adjacency.len();
    if source >= n || target >= n {
        return None;
    }
    let mut dist = vec![f64::INFINITY; n];
    let mut prev: Vec<Option<(usize, usize)>> = vec![None; n];
    let mut heap = BinaryHeap::new();
    dist[source] = 0.0;
    heap.push(State(0.0, source));
    while let Some(State(d, u)) = heap.pop() {
        if d > dist[u] {
            continue;
        }
        if u == target {
            break;
        }
        for &(v, w, tag) in &adjacency[u] {
            let nd = d + w;
            if nd < dist[v] {
                dist[v] = nd;
                prev[v] = Some((u, tag));
                heap.push(State(nd, v));
            }
        }
    }
    if !dist[target].is_finite() {
        return None;
    }
    let mut path = Vec::new();
    let mut v = target;
    while let Some((u, tag)) = prev[v] {
        path.push((v, tag));
        v = u;
    }
    path.reverse();
    Some((dist[target], path))
}

/// The hybrid map `H`: maps, link points and link-point candidates.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MapGraph {
    maps: Vec<MapNode>,
    links: Vec<LinkPoint>,
    candidates: Vec<LinkCandidate>,
}

impl MapGraph {
    /// An empty graph.
    pub fn new() -> MapGraph {
        MapGraph::default()
    }

    /// The maps.
    pub fn maps(&self) -> &[MapNode] {
        &self.maps
    }

    /// The link points.
    pub fn links(&self) -> &[LinkPoint] {
        &self.links
    }

    /// The link-point candidates.
    pub fn candidates(&self) -> &[LinkCandidate] {
        &self.candidates
    }

    /// Adds a map and returns its index.
    ///
    /// # Errors
    /// [`MultimapError::TooLarge`] if the graph already holds [`MAX_MAPS`] maps (the graph is
    /// left unchanged).
    pub fn add_map(
        &mut self,
        config: MapConfig,
        bbox: Option<BoundingBox>,
    ) -> Result<usize, MultimapError> {
        if self.maps.len() >= MAX_MAPS {
            return Err(MultimapError::TooLarge {
                what: "maps",
                n: self.maps.len() + 1,
                max: MAX_MAPS,
            });
        }
        self.maps.push(MapNode { config, bbox });
        Ok(self.maps.len() - 1)
    }

    fn check_map(&self, map: usize) -> Result<(), MultimapError> {
        if map < self.maps.len() {
            Ok(())
        } else {
            Err(MultimapError::UnknownMap(map))
        }
    }

    fn check_room(&self) -> Result<(), MultimapError> {
        let n = self.links.len() + self.candidates.len();
        if n >= MAX_LINKS {
            return Err(MultimapError::TooLarge {
                what: "link points and candidates",
                n: n + 1,
                max: MAX_LINKS,
            });
        }
        Ok(())
    }

    /// Adds a link point between `map_a` and `map_b` at `pose_a` in `map_a` and `pose_b` in
    /// `map_b` (a door passage, or a loop closure found by registration) and returns its
    /// index.
    pub fn add_link(
        &mut self,
        map_a: usize,
        pose_a: UncertainPose,
        map_b: usize,
        pose_b: UncertainPose,
    ) -> Result<usize, MultimapError> {
        self.check_map(map_a)?;
        self.check_map(map_b)?;
        if map_a == map_b {
            return Err(MultimapError::SameMap(map_a));
        }
        for p in [&pose_a, &pose_b] {
            p.mean.validate("link pose")?;
            validate_covariance("link pose covariance", &p.cov)?;
        }
        self.check_room()?;
        self.links.push(LinkPoint {
            maps: [map_a, map_b],
            poses: [pose_a, pose_b],
        });
        Ok(self.links.len() - 1)
    }

    /// Adds a link-point candidate in `map` at `pose`, with the caller's `tag` for its data.
    pub fn add_candidate(
        &mut self,
        map: usize,
        pose: UncertainPose,
        tag: u64,
    ) -> Result<usize, MultimapError> {
        self.check_map(map)?;
        pose.mean.validate("candidate pose")?;
        validate_covariance("candidate pose covariance", &pose.cov)?;
        self.check_room()?;
        self.candidates.push(LinkCandidate { map, pose, tag });
        Ok(self.candidates.len() - 1)
    }

    /// The pose `⁽ᶠ⁾pₒ` of the other map's origin in the frame of `from`, through link point
    /// `link`, with its first-order covariance: eq. (3.10),
    /// `π(ᶠT_L (ᵒT_L)⁻¹) = ᶠm ⊕ ⊖ᵒm`, propagated by the Jacobians of `⊕` and `⊖`
    /// (eqs. (3.12)–(3.13)), both link poses independent.
    pub fn relative_pose(&self, link: usize, from: usize) -> Result<UncertainPose, MultimapError> {
        let l = self
            .links
            .get(link)
            .ok_or(MultimapError::UnknownLink(link))?;
        let (a, b) = if l.maps[0] == from {
            (l.poses[0], l.poses[1])
        } else if l.maps[1] == from {
            (l.poses[1], l.poses[0])
        } else {
            return Err(MultimapError::UnknownMap(from));
        };
        Ok(a.compose(&b.inverse()))
    }

    /// The edges `E` within `map` (§3.3.1): every two of its link points, with the Euclidean
    /// distance of their positions in `map`'s frame, as `(link, link, distance)`.
    ///
    /// # Errors
    /// [`MultimapError::UnknownMap`]; [`MultimapError::TooLarge`] if the map has more than
    /// [`MAX_LINKS_PER_MAP_FOR_EDGES`] link points.
    pub fn link_edges(&self, map: usize) -> Result<Vec<(usize, usize, f64)>, MultimapError> {
        self.check_map(map)?;
        let members: Vec<(usize, [f64; 2])> = self.members_for_edges(map)?;
        let mut edges = Vec::new();
        for (i, &(a, pa)) in members.iter().enumerate() {
            for &(b, pb) in &members[i + 1..] {
                edges.push((a, b, (pa[0] - pb[0]).hypot(pa[1] - pb[1])));
            }
        }
        Ok(edges)
    }

    /// [`MapGraph::members`], refused beyond [`MAX_LINKS_PER_MAP_FOR_EDGES`] (their edges are
    /// all pairs).
    fn members_for_edges(&self, map: usize) -> Result<Vec<(usize, [f64; 2])>, MultimapError> {
        let members = self.members(map);
        if members.len() > MAX_LINKS_PER_MAP_FOR_EDGES {
            return Err(MultimapError::TooLarge {
                what: "link points of one map (their edges are all pairs)",
                n: members.len(),
                max: MAX_LINKS_PER_MAP_FOR_EDGES,
            });
        }
        Ok(members)
    }

    /// The link points of `map` with their positions in its frame.
    fn members(&self, map: usize) -> Vec<(usize, [f64; 2])> {
        self.links
            .iter()
            .enumerate()
            .flat_map(|(i, l)| {
                (0..2)
                    .filter(move |&s| l.maps[s] == map)
                    .map(move |s| (i, [l.poses[s].mean.x, l.poses[s].mean.y]))
            })
            .collect()
    }

    /// The path of maps from `from` to `to` minimising `weight`, by Dijkstra's algorithm
    /// ([Stüde 2024] §3.3.3, eq. (3.14)).
    pub fn map_path(
        &self,
        from: usize,
        to: usize,
        weight: PathWeight,
    ) -> Result<MapPath, MultimapError> {
        self.check_map(from)?;
        self.check_map(to)?;
        if from == to {
            return Ok(MapPath {
                maps: vec![from],
                links: Vec::new(),
                cost: 0.0,
            });
        }
        let no_path = MultimapError::NoPath { from, to };
        match weight {
            PathWeight::Hops | PathWeight::Uncertainty => {
                let mut adj = vec![Vec::new(); self.maps.len()];
                for (i, l) in self.links.iter().enumerate() {
                    for (a, b) in [(l.maps[0], l.maps[1]), (l.maps[1], l.maps[0])] {
                        let w = match weight {
                            PathWeight::Hops => 1.0,
                            _ => {
                                let c = self.relative_pose(i, a)?.cov;
                                c[0][0] + c[1][1]
                            }
                        };
                        adj[a].push((b, w, i));
                    }
                }
                let (cost, path) = dijkstra(&adj, from, to).ok_or(no_path)?;
                let mut maps = vec![from];
                maps.extend(path.iter().map(|&(m, _)| m));
                Ok(MapPath {
                    maps,
                    links: path.iter().map(|&(_, l)| l).collect(),
                    cost,
                })
            }
            PathWeight::Distance => {
                // Nodes: link points 0..L, then map origins L..L+M; edges within each map.
                let nl = self.links.len();
                let mut adj = vec![Vec::new(); nl + self.maps.len()];
                for map in 0..self.maps.len() {
                    let mut members: Vec<(usize, [f64; 2])> = self.members_for_edges(map)?;
                    members.push((nl + map, [0.0, 0.0]));
                    for &(a, pa) in &members {
                        for &(b, pb) in &members {
                            if a != b {
                                adj[a].push((b, (pa[0] - pb[0]).hypot(pa[1] - pb[1]), map));
                            }
                        }
                    }
                }
                let (cost, path) = dijkstra(&adj, nl + from, nl + to).ok_or(no_path)?;
                // Transitions: a link point between edges in different maps.
                let mut maps = vec![from];
                let mut links = Vec::new();
                for w in path.windows(2) {
                    let ((node, map_in), (_, map_out)) = (w[0], w[1]);
                    if map_in != map_out {
                        links.push(node);
                        maps.push(map_out);
                    }
                }
                Ok(MapPath { maps, links, cost })
            }
        }
    }

    /// The pose of the last map's origin in the first map's frame along `path`, with its
    /// covariance: the chain `⁽ᵛ¹⁾p_v₂ ⊕ ⁽ᵛ²⁾p_v₃ ⊕ …` of eq. (3.14), evaluated from left to
    /// right with eq. (3.13) at each step.
    pub fn compose_path(&self, path: &MapPath) -> Result<UncertainPose, MultimapError> {
        let mut acc = UncertainPose::exact(crate::se2::Pose2::IDENTITY);
        for (k, &link) in path.links.iter().enumerate() {
            let from = *path.maps.get(k).ok_or(MultimapError::UnknownLink(link))?;
            acc = acc.compose(&self.relative_pose(link, from)?);
        }
        Ok(acc)
    }

    /// `pose` (given in map `source`) in the frame of map `target`, along the path chosen by
    /// `weight`: eq. (3.14), `⁽⁰⁾p_r = ⁽⁰⁾p_k ⊕ ⁽ᵏ⁾p_r`.
    pub fn pose_in(
        &self,
        target: usize,
        source: usize,
        pose: &UncertainPose,
        weight: PathWeight,
    ) -> Result<UncertainPose, MultimapError> {
        pose.mean.validate("pose")?;
        validate_covariance("pose covariance", &pose.cov)?;
        let path = self.map_path(target, source, weight)?;
        Ok(self.compose_path(&path)?.compose(pose))
    }

    /// The loop search of §3.3.3: the robot at `pose` in map `map` is expressed in the frame
    /// of map `reference` (eq. (3.14)); every link point not touching `map` and every
    /// candidate of another map whose position in that frame lies within the radius
    /// `r(λ_max)` of eq. (3.8) — `λ_max` of the propagated position covariance `⁽⁰⁾Σ` — is
    /// returned, nearest first. Maps not connected to `reference` are skipped.
    pub fn loop_search(
        &self,
        reference: usize,
        map: usize,
        pose: &UncertainPose,
        params: &SearchParams,
        weight: PathWeight,
    ) -> Result<LoopSearch, MultimapError> {
        let robot = self.pose_in(reference, map, pose, weight)?;
        let radius = search_radius_for(&robot.cov, params)?;
        let mut frames: Vec<Option<Option<crate::se2::Pose2>>> = vec![None; self.maps.len()];
        let mut frame = |m: usize| -> Result<Option<crate::se2::Pose2>, MultimapError> {
            if let Some(f) = frames[m] {
                return Ok(f);
            }
            let f = match self.map_path(reference, m, weight) {
                Ok(path) => Some(self.compose_path(&path)?.mean),
                Err(MultimapError::NoPath { .. }) => None,
                Err(e) => return Err(e),
            };
            frames[m] = Some(f);
            Ok(f)
        };
        let mut hits = Vec::new();
        let mut consider =
            |target, m: usize, local: &crate::se2::Pose2| -> Result<(), MultimapError> {
                if let Some(f) = frame(m)? {
                    let q = f.compose(local);
                    let distance = q.distance(&robot.mean);
                    if distance <= radius {
                        hits.push(LoopHit {
                            target,
                            position: [q.x, q.y],
                            distance,
                        });
                    }
                }
                Ok(())
            };
        for (i, l) in self.links.iter().enumerate() {
            if l.maps.contains(&map) {
                continue;
            }
            consider(LoopTarget::Link(i), l.maps[0], &l.poses[0].mean)?;
        }
        for (i, c) in self.candidates.iter().enumerate() {
            if c.map != map {
                consider(LoopTarget::Candidate(i), c.map, &c.pose.mean)?;
            }
        }
        hits.sort_by(|a, b| a.distance.total_cmp(&b.distance));
        Ok(LoopSearch {
            pose: robot,
            radius,
            hits,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronomap_rng::Xoshiro256StarStar;

    /// All simple paths from `s` to `t` by depth-first search: the oracle for Dijkstra.
    fn brute_force(adj: &[Vec<(usize, f64, usize)>], s: usize, t: usize) -> Option<f64> {
        fn go(
            adj: &[Vec<(usize, f64, usize)>],
            u: usize,
            t: usize,
            seen: &mut Vec<bool>,
            d: f64,
            best: &mut f64,
        ) {
            if u == t {
                *best = best.min(d);
                return;
            }
            for &(v, w, _) in &adj[u] {
                if !seen[v] {
                    seen[v] = true;
                    go(adj, v, t, seen, d + w, best);
                    seen[v] = false;
                }
            }
        }
        let mut seen = vec![false; adj.len()];
        seen[s] = true;
        let mut best = f64::INFINITY;
        go(adj, s, t, &mut seen, 0.0, &mut best);
        best.is_finite().then_some(best)
    }

    #[test]
    fn dijkstra_matches_brute_force_on_random_small_graphs() {
        let mut rng = Xoshiro256StarStar::seed_from_u64(7);
        let mut compared = 0;
        for _ in 0..300 {
            let n = rng.int_in(2, 8) as usize;
            let mut adj = vec![Vec::new(); n];
            for (u, row) in adj.iter_mut().enumerate() {
                for v in 0..n {
                    if u != v && rng.bernoulli(0.35) {
                        row.push((v, rng.uniform(0.0, 10.0).floor(), u * n + v));
                    }
                }
            }
            let (s, t) = (
                rng.int_in(0, n as u64 - 1) as usize,
                rng.int_in(0, n as u64 - 1) as usize,
            );
            let oracle = brute_force(&adj, s, t);
            let got = dijkstra(&adj, s, t);
            assert_eq!(oracle.is_some(), got.is_some());
            if let (Some(o), Some((d, path))) = (oracle, got) {
                assert_eq!(o, d);
                // The path is a walk along existing edges whose weights sum to the cost.
                let mut u = s;
                let mut sum = 0.0;
                for &(v, tag) in &path {
                    let e = adj[u].iter().find(|e| e.0 == v && e.2 == tag).unwrap();
                    sum += e.1;
                    u = v;
                }
                assert_eq!(u, t);
                assert_eq!(sum, d);
                compared += 1;
            }
        }
        assert!(compared > 100, "{compared}");
    }
}
