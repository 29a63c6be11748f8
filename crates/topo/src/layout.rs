//! Computed drawings of topological maps that carry no node positions (such as the Witham
//! Wharf map read from edge files): stress majorization ([Gansner 2004]: E. R. Gansner,
//! Y. Koren, S. North, "Graph drawing by stress majorization", Graph Drawing 2004, LNCS 3383).
//!
//! [`stress_layout`] places the nodes so that the straight-line distance between two nodes is
//! as close as possible to `edge_length` times the number of edges between them, and
//! [`stress`] scores any placement by the same measure. Positions are computed, not measured:
//! a viewer should say so.
//!
//! ```
//! use chronomap_topo::layout::{stress, stress_layout};
//! use chronomap_topo::TopoMap;
//!
//! // A path A — B — C (directions do not matter).
//! let mut map = TopoMap::new();
//! for name in ["A", "B", "C"] {
//!     map.add_node(name, None)?;
//! }
//! map.add_edge("A_B", "A", "B")?;
//! map.add_edge("C_B", "C", "B")?;
//! let xy = stress_layout(&map, 2.0);
//! let distance = |i: usize, j: usize| (xy[i][0] - xy[j][0]).hypot(xy[i][1] - xy[j][1]);
//! assert!((distance(0, 1) - 2.0).abs() < 1e-6 && (distance(0, 2) - 4.0).abs() < 1e-6);
//! assert!(xy[0][0] < 0.0 && xy[1][1].abs() < 1e-6); // horizontal, the first node on the left
//! assert!(stress(&map, &xy, 2.0) < 1e-9);
//! assert_eq!(stress_layout(&map, 2.0), xy); // deterministic, bit for bit
//! # Ok::<(), chronomap_topo::map::TopoError>(())
//! ```
//!
//! # Method
//! The map is taken as an undirected graph (an edge in either direction, or both, connects
//! two nodes; self-loops and repeated edges count once). For each connected component:
//!
//! 1. target distances `d_ij` = hop count (breadth-first search) × `edge_length`, weights
//!    `w_ij = d_ij^-2`; the stress is `Σ_{i<j} w_ij (‖x_i − x_j‖ − d_ij)²` ([Gansner 2004]
//!    eq. 1). With these weights the stress is scale-free, so the layout is computed for a
//!    unit edge length and scaled at the end.
//! 2. start: classical MDS — the two leading eigenvectors of the double-centred squared
//!    distance matrix `B = −½ J D⁽²⁾ J`, scaled by the square roots of their eigenvalues —
//!    found by subspace iteration on `B + sI` (`s` a Gershgorin bound, so that the leading
//!    eigenvalues are the largest, not the most negative; at most 100 iterations, a start
//!    need not be exact) from fixed pseudo-random vectors (SplitMix64 of the index: no seed,
//!    no state). A fixed pseudo-random offset of at most 10⁻⁷ edge lengths is added so that
//!    nodes that MDS puts on one spot (twins with the same neighbours) can separate, and a
//!    collinear start can leave its line.
//! 3. the SMACOF update of [Gansner 2004] §2: `L^w X(t+1) = L^{X(t)} X(t)`, with the weighted
//!    Laplacian `L^w` Cholesky-factored once (one node pinned, which removes the translation),
//!    repeated until the stress falls by less than a relative 10⁻⁶ in an iteration, or
//!    reaches 10⁻²⁴, or after 500 updates. Each update lowers the stress (majorization); a
//!    rounding-error increase ends the iteration with the better layout.
//! 4. normalisation: rotated about its centroid so that the principal axis of the positions is
//!    horizontal (a drawing wider than tall; no rotation when the spread is isotropic, as for
//!    a square), the centre of its bounding box moved to the origin, and turned by 180° if
//!    its first node (the lowest index) would be right of the centre.
//!
//! Components are then placed side by side, left to right, largest first (ties: the one with
//! the lowest node index first), vertically centred, with a gap of `2 × edge_length` between
//! bounding boxes; an isolated node is a component of one. Finally the bounding box of the
//! whole drawing is centred at the origin.
//!
//! # Cost
//! For `n` nodes and `m` edges: memory `O(n²)` (the distance matrix and the Cholesky factor,
//! about 64 MB at `n` = 2,000), time `O(n·(n + m))` for the distances, `O(n³)` once for the
//! factorisation and `O(n²)` per iteration (at most 500). The 18-node Witham map takes under
//! 2 ms (a test build; 0.3 ms in release). At 2,000 nodes, measured on one shared core (release build, December 2026):
//! about 3 s for a path or a 40 × 50 grid (the start is nearly right; the factorisation and
//! the start dominate), 16 s for a sparse random graph that no plane drawing fits, which runs
//! all 500 iterations. Maps with more than [`MAX_STRESS_NODES`] nodes get a cheap grid
//! instead (see [`stress_layout`]), so that a hostile map cannot make a service spend
//! minutes.
//!
//! # Why not a crate
//! None of the Rust crates looked at fits: `fdg-sim` is a force-directed simulation (not
//! stress) in `f32`, started from random positions drawn from `quad-rand`'s global generator
//! (so two calls differ), with `petgraph` and `glam` as dependencies; `forceatlas2` is AGPL-3.0 (this project is MIT OR Apache-2.0)
//! and random by default; `layout-rs` draws layered (Graphviz `dot`-style) diagrams. And no
//! linear-algebra crate is among this crate's dependencies: the two leading eigenvectors and
//! one Cholesky factorisation are a few lines here.

use std::collections::VecDeque;

use crate::map::TopoMap;

/// The most nodes [`stress_layout`] lays out by stress majorization; larger maps get a grid.
pub const MAX_STRESS_NODES: usize = 2000;

/// The most SMACOF updates per component.
const MAX_ITERATIONS: usize = 500;

/// Iteration stops when an update lowers the stress by less than this fraction.
const RELATIVE_TOLERANCE: f64 = 1e-6;

/// Iteration stops at this (scale-free) stress: every distance is exact to about 10⁻¹².
const STRESS_FLOOR: f64 = 1e-24;

/// The most subspace iterations of the MDS start.
const MDS_ITERATIONS: usize = 100;

/// The offset added to the MDS start, in edge lengths.
const START_OFFSET: f64 = 1e-7;

/// Positions `[x, y]` (metres) for every node of `map`, index-aligned with `map.nodes()`,
/// from stress majorization on hop distances × `edge_length` ([Gansner 2004]: the stress
/// function, eq. 1, with weights `d^-2`, and the SMACOF update; see the
/// [module docs](self#method)). E. R. Gansner, Y. Koren, S. North, "Graph drawing by stress
/// majorization", Graph Drawing 2004.
///
/// Pure and deterministic: the same map gives bit-identical positions. The graph is taken as
/// undirected; disconnected components are laid out separately and placed side by side,
/// largest first, `2 × edge_length` apart. The drawing's bounding box is centred at the
/// origin and each component's principal axis is horizontal. An empty map gives an empty
/// vector.
///
/// `edge_length` is the target distance between neighbours; a value that is not finite or
/// not positive is taken as 1.0 (no panic). Positions scale linearly with it (so a length
/// near `f64::MAX` overflows to infinities).
///
/// Maps with more than [`MAX_STRESS_NODES`] nodes are not laid out by stress: their nodes are
/// put on a square grid `edge_length` apart, row by row in index order (`⌈√n⌉` columns, so it
/// is at least as wide as tall), ignoring edges, so that the cost stays bounded.
pub fn stress_layout(map: &TopoMap, edge_length: f64) -> Vec<[f64; 2]> {
    let n = map.nodes().len();
    if n == 0 {
        return Vec::new();
    }
    let scale = clamped(edge_length);
    let unit = if n > MAX_STRESS_NODES {
        grid_layout(n)
    } else {
        unit_stress_layout(&adjacency(map))
    };
    unit.into_iter()
        .map(|[x, y]| [x * scale, y * scale])
        .collect()
}

/// The weighted stress of `positions` for `map` ([Gansner 2004] eq. 1):
/// `Σ_{i<j} w_ij (‖x_i − x_j‖ − d_ij)²` over the pairs of nodes connected by a path (the map
/// taken as undirected), with `d_ij` = hop count × `edge_length` and `w_ij = d_ij^-2`; 0 for a
/// perfect layout. With these weights the stress does not depend on the unit: positions
/// scaled by `k` with `edge_length` scaled by `k` score the same.
///
/// `edge_length` is clamped as by [`stress_layout`]. Returns NaN if `positions` does not have
/// one entry per node; non-finite positions give a non-finite stress.
///
/// Cost: time `O(n·(n + m))` (a breadth-first search from every node), memory `O(n + m)`.
pub fn stress(map: &TopoMap, positions: &[[f64; 2]], edge_length: f64) -> f64 {
    let n = map.nodes().len();
    if positions.len() != n {
        return f64::NAN;
    }
    let scale = clamped(edge_length);
    let adjacency = adjacency(map);
    let mut hops = vec![u32::MAX; n];
    let mut queue = VecDeque::new();
    let mut total = 0.0;
    for i in 0..n {
        bfs(&adjacency, i, &mut hops, &mut queue);
        for j in i + 1..n {
            if hops[j] == u32::MAX {
                continue;
            }
            let target = f64::from(hops[j]) * scale;
            let [dx, dy] = [
                positions[i][0] - positions[j][0],
                positions[i][1] - positions[j][1],
            ];
            let relative = ((dx * dx + dy * dy).sqrt() - target) / target;
            total += relative * relative;
        }
    }
    total
}

/// `edge_length`, or 1.0 where it is not finite and positive.
fn clamped(edge_length: f64) -> f64 {
    if edge_length.is_finite() && edge_length > 0.0 {
        edge_length
    } else {
        1.0
    }
}

/// Sorted, deduplicated neighbours of every node, edges taken both ways, self-loops dropped.
fn adjacency(map: &TopoMap) -> Vec<Vec<usize>> {
    let mut neighbours = vec![Vec::new(); map.nodes().len()];
    for edge in map.edges() {
        if edge.from != edge.to {
            neighbours[edge.from].push(edge.to);
            neighbours[edge.to].push(edge.from);
        }
    }
    for list in &mut neighbours {
        list.sort_unstable();
        list.dedup();
    }
    neighbours
}

/// Hop counts from `source` into `hops` (`u32::MAX`: unreachable).
fn bfs(adjacency: &[Vec<usize>], source: usize, hops: &mut [u32], queue: &mut VecDeque<usize>) {
    hops.fill(u32::MAX);
    hops[source] = 0;
    queue.clear();
    queue.push_back(source);
    while let Some(node) = queue.pop_front() {
        for &next in &adjacency[node] {
            if hops[next] == u32::MAX {
                hops[next] = hops[node] + 1;
                queue.push_back(next);
            }
        }
    }
}

/// `n` nodes on a grid of `⌈√n⌉` columns, unit spacing, row by row, bounding box centred.
fn grid_layout(n: usize) -> Vec<[f64; 2]> {
    let mut columns = n.isqrt();
    if columns * columns < n {
        columns += 1;
    }
    let rows = n.div_ceil(columns);
    let (cx, cy) = ((columns - 1) as f64 / 2.0, (rows - 1) as f64 / 2.0);
    (0..n)
        .map(|i| [(i % columns) as f64 - cx, cy - (i / columns) as f64])
        .collect()
}

/// The layout for a unit edge length: components laid out, placed side by side, centred.
fn unit_stress_layout(adjacency: &[Vec<usize>]) -> Vec<[f64; 2]> {
    let n = adjacency.len();
    // Components in the order of their lowest node, each sorted by node index.
    let mut component_of = vec![usize::MAX; n];
    let mut components: Vec<Vec<usize>> = Vec::new();
    let mut queue = VecDeque::new();
    for start in 0..n {
        if component_of[start] != usize::MAX {
            continue;
        }
        let id = components.len();
        let mut members = vec![start];
        component_of[start] = id;
        queue.push_back(start);
        while let Some(node) = queue.pop_front() {
            for &next in &adjacency[node] {
                if component_of[next] == usize::MAX {
                    component_of[next] = id;
                    members.push(next);
                    queue.push_back(next);
                }
            }
        }
        members.sort_unstable();
        components.push(members);
    }
    // Largest first; the stable sort keeps ties in the order of their lowest node.
    components.sort_by_key(|members| std::cmp::Reverse(members.len()));

    let mut positions = vec![[0.0, 0.0]; n];
    let mut left = 0.0;
    for members in &components {
        let local = component_layout(adjacency, members);
        let (min_x, max_x, min_y, max_y) = bounding_box(&local);
        let (dx, dy) = (left - min_x, -(min_y + max_y) / 2.0);
        for (&node, &[x, y]) in members.iter().zip(&local) {
            positions[node] = [x + dx, y + dy];
        }
        left = max_x + dx + 2.0;
    }
    let (min_x, max_x, min_y, max_y) = bounding_box(&positions);
    let (cx, cy) = ((min_x + max_x) / 2.0, (min_y + max_y) / 2.0);
    for p in &mut positions {
        *p = [p[0] - cx, p[1] - cy];
    }
    positions
}

/// `(min x, max x, min y, max y)` of non-empty `points`.
fn bounding_box(points: &[[f64; 2]]) -> (f64, f64, f64, f64) {
    points.iter().fold(
        (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ),
        |(a, b, c, d), &[x, y]| (a.min(x), b.max(x), c.min(y), d.max(y)),
    )
}

/// The normalised unit-length layout of one connected component (`members`, sorted).
fn component_layout(adjacency: &[Vec<usize>], members: &[usize]) -> Vec<[f64; 2]> {
    let k = members.len();
    if k == 1 {
        return vec![[0.0, 0.0]];
    }
    // Hop distances between members (row-major k × k); all finite in a component.
    let mut distances = vec![0.0; k * k];
    let mut hops = vec![u32::MAX; adjacency.len()];
    let mut queue = VecDeque::new();
    for (i, &node) in members.iter().enumerate() {
        bfs(adjacency, node, &mut hops, &mut queue);
        for (j, &other) in members.iter().enumerate() {
            distances[i * k + j] = f64::from(hops[other]);
        }
    }
    let start = classical_mds(&distances, k);
    // From here on, 1 / d_ij (0 on the diagonal): a multiplication instead of a division.
    for d in &mut distances {
        if *d > 0.0 {
            *d = 1.0 / *d;
        }
    }
    let layout = smacof(&distances, k, start);
    normalised(layout)
}

/// A fixed pseudo-random number in `[−½, ½)` for index `i` of sequence `stream`: SplitMix64
/// of the pair (no state, no seed; the same every run). Not an arithmetic sequence modulo 1,
/// whose regular differences can miss a whole eigenvector of a symmetric graph (a cycle).
fn irregular(i: usize, stream: u64) -> f64 {
    let mut z = (i as u64)
        .wrapping_mul(2)
        .wrapping_add(stream)
        .wrapping_add(1)
        .wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64 - 0.5
}

/// Classical MDS coordinates of a `k × k` distance matrix (see the module docs), plus the
/// small deterministic offset.
fn classical_mds(distances: &[f64], k: usize) -> Vec<[f64; 2]> {
    let kf = k as f64;
    // B_ij = −½ (d²_ij − r_i − r_j + g), with row means r and grand mean g of d².
    let row_means: Vec<f64> = distances
        .chunks_exact(k)
        .map(|row| row.iter().map(|d| d * d).sum::<f64>() / kf)
        .collect();
    let grand = row_means.iter().sum::<f64>() / kf;
    let b = |i: usize, j: usize| {
        let d = distances[i * k + j];
        -0.5 * (d * d - row_means[i] - row_means[j] + grand)
    };
    let shift = (0..k)
        .map(|i| (0..k).map(|j| b(i, j).abs()).sum::<f64>())
        .fold(0.0, f64::max);
    // y = (B + sI) q for two vectors at once.
    let multiply = |q: &[[f64; 2]]| -> Vec<[f64; 2]> {
        (0..k)
            .map(|i| {
                let mut sum = [shift * q[i][0], shift * q[i][1]];
                for (j, qj) in q.iter().enumerate() {
                    let bij = b(i, j);
                    sum[0] += bij * qj[0];
                    sum[1] += bij * qj[1];
                }
                sum
            })
            .collect()
    };
    // Start vectors: pseudo-random, centred (B·1 = 0, so iterates stay centred).
    let mut q: Vec<[f64; 2]> = (0..k).map(|i| [irregular(i, 0), irregular(i, 1)]).collect();
    for c in 0..2 {
        let mean = q.iter().map(|v| v[c]).sum::<f64>() / kf;
        for v in &mut q {
            v[c] -= mean;
        }
    }
    orthonormalise(&mut q);
    let mut previous = f64::NEG_INFINITY;
    for _ in 0..MDS_ITERATIONS {
        let y = multiply(&q);
        let rayleigh: f64 = q
            .iter()
            .zip(&y)
            .map(|(a, b)| a[0] * b[0] + a[1] * b[1])
            .sum();
        q = y;
        if !orthonormalise(&mut q) {
            break;
        }
        if (rayleigh - previous).abs() <= 1e-12 * rayleigh.abs() {
            break;
        }
        previous = rayleigh;
    }
    // Rayleigh–Ritz: diagonalise the 2 × 2 projection H = Qᵀ (B + sI) Q.
    let y = multiply(&q);
    let dot = |a: usize, c: usize| q.iter().zip(&y).map(|(u, v)| u[a] * v[c]).sum::<f64>();
    let (h11, h12, h22) = (dot(0, 0), (dot(0, 1) + dot(1, 0)) / 2.0, dot(1, 1));
    let angle = 0.5 * (2.0 * h12).atan2(h11 - h22);
    let (s, c) = angle.sin_cos();
    let mean = (h11 + h22) / 2.0;
    let radius = ((h11 - h22) / 2.0).hypot(h12);
    let scales = [
        (mean + radius - shift).max(0.0).sqrt(),
        (mean - radius - shift).max(0.0).sqrt(),
    ];
    q.iter()
        .enumerate()
        .map(|(i, &[u, v])| {
            [
                (c * u + s * v) * scales[0] + START_OFFSET * irregular(i, 2),
                (c * v - s * u) * scales[1] + START_OFFSET * irregular(i, 3),
            ]
        })
        .collect()
}

/// Gram–Schmidt on the two columns of `q`; false if they are (numerically) dependent.
fn orthonormalise(q: &mut [[f64; 2]]) -> bool {
    let norm0 = q.iter().map(|v| v[0] * v[0]).sum::<f64>().sqrt();
    if !(norm0 > 0.0 && norm0.is_finite()) {
        return false;
    }
    for v in q.iter_mut() {
        v[0] /= norm0;
    }
    let projection: f64 = q.iter().map(|v| v[0] * v[1]).sum();
    for v in q.iter_mut() {
        v[1] -= projection * v[0];
    }
    let norm1 = q.iter().map(|v| v[1] * v[1]).sum::<f64>().sqrt();
    if !(norm1 > 1e-12 && norm1.is_finite()) {
        return false;
    }
    for v in q.iter_mut() {
        v[1] /= norm1;
    }
    true
}

/// Stress majorization from `start` ([Gansner 2004] §2); `inverse` holds `1 / d_ij`
/// (row-major `k × k`, hop units).
fn smacof(inverse: &[f64], k: usize, start: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    let Some(factor) = laplacian_cholesky(inverse, k) else {
        return start;
    };
    let mut current = start;
    let mut previous: Option<(f64, Vec<[f64; 2]>)> = None;
    for iteration in 0..=MAX_ITERATIONS {
        // The stress of `current` and the right-hand side L^Z Z, in one pass over the pairs:
        // (L^Z Z)_i = Σ_j w_ij d_ij (z_i − z_j) / ‖z_i − z_j‖, with w_ij d_ij = 1 / d_ij.
        let mut sigma = 0.0;
        let mut rhs = vec![[0.0, 0.0]; k];
        for i in 0..k {
            let [xi, yi] = current[i];
            let (mut bx, mut by) = (0.0, 0.0);
            let row = &inverse[i * k + i + 1..(i + 1) * k];
            for ((&inv, zj), bj) in row.iter().zip(&current[i + 1..]).zip(&mut rhs[i + 1..]) {
                let (dx, dy) = (xi - zj[0], yi - zj[1]);
                let dist = (dx * dx + dy * dy).sqrt();
                let relative = dist * inv - 1.0;
                sigma += relative * relative;
                let f = if dist > 0.0 { inv / dist } else { 0.0 };
                bx += f * dx;
                by += f * dy;
                bj[0] -= f * dx;
                bj[1] -= f * dy;
            }
            rhs[i][0] += bx;
            rhs[i][1] += by;
        }
        if let Some((previous_sigma, previous_layout)) = previous {
            if sigma > previous_sigma {
                return previous_layout;
            }
            if previous_sigma - sigma <= RELATIVE_TOLERANCE * previous_sigma {
                return current;
            }
        }
        if !sigma.is_finite() || sigma <= STRESS_FLOOR || iteration == MAX_ITERATIONS {
            return current;
        }
        let next = factor.solve(&rhs);
        previous = Some((sigma, std::mem::replace(&mut current, next)));
    }
    current
}

/// The Cholesky factor of the weighted Laplacian `L^w` without the row and column of node 0.
struct Cholesky {
    /// Size (`k − 1`).
    size: usize,
    /// Lower triangle, row-major `size × size` (the upper part unused).
    lower: Vec<f64>,
}

/// `L^w` with `w_ij = d_ij⁻²` (`inverse` holds `1 / d_ij`), node 0 removed, factored; `None`
/// if it is not positive definite (it always is for a connected component, barring rounding).
fn laplacian_cholesky(inverse: &[f64], k: usize) -> Option<Cholesky> {
    let size = k - 1;
    let mut a = vec![0.0; size * size];
    for i in 1..k {
        let mut diagonal = 0.0;
        for j in 0..k {
            if j != i {
                let w = inverse[i * k + j] * inverse[i * k + j];
                diagonal += w;
                if j > 0 && j < i {
                    a[(i - 1) * size + (j - 1)] = -w;
                }
            }
        }
        a[(i - 1) * size + (i - 1)] = diagonal;
    }
    // Cholesky–Banachiewicz, row by row, in place.
    for i in 0..size {
        let (above, below) = a.split_at_mut(i * size);
        let row_i = &mut below[..size];
        for j in 0..i {
            let row_j = &above[j * size..j * size + j + 1];
            let value = (row_i[j] - dot(&row_i[..j], &row_j[..j])) / row_j[j];
            row_i[j] = value;
        }
        let pivot = row_i[i] - dot(&row_i[..i], &row_i[..i]);
        if !(pivot > 0.0 && pivot.is_finite()) {
            return None;
        }
        row_i[i] = pivot.sqrt();
    }
    Some(Cholesky { size, lower: a })
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

impl Cholesky {
    /// The positions solving `L^w X = rhs` with node 0 at the origin.
    fn solve(&self, rhs: &[[f64; 2]]) -> Vec<[f64; 2]> {
        let size = self.size;
        let row = |i: usize| &self.lower[i * size..i * size + i + 1];
        // Forward: L y = b (b without node 0).
        let mut y: Vec<[f64; 2]> = rhs[1..].to_vec();
        for i in 0..size {
            let l = row(i);
            let mut sum = y[i];
            for (p, &lip) in l[..i].iter().enumerate() {
                sum[0] -= lip * y[p][0];
                sum[1] -= lip * y[p][1];
            }
            y[i] = [sum[0] / l[i], sum[1] / l[i]];
        }
        // Backward: Lᵀ x = y, column by column so that L is read by rows.
        for i in (0..size).rev() {
            let l = row(i);
            let x = [y[i][0] / l[i], y[i][1] / l[i]];
            y[i] = x;
            for (p, &lip) in l[..i].iter().enumerate() {
                y[p][0] -= lip * x[0];
                y[p][1] -= lip * x[1];
            }
        }
        let mut positions = Vec::with_capacity(size + 1);
        positions.push([0.0, 0.0]);
        positions.extend(y);
        positions
    }
}

/// Rotated about the centroid so that the principal axis is horizontal, the bounding box
/// centred at the origin, turned by 180° if the first point is right of the centre.
fn normalised(mut points: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    let n = points.len() as f64;
    let mx = points.iter().map(|p| p[0]).sum::<f64>() / n;
    let my = points.iter().map(|p| p[1]).sum::<f64>() / n;
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for p in &points {
        let (dx, dy) = (p[0] - mx, p[1] - my);
        sxx += dx * dx;
        syy += dy * dy;
        sxy += dx * dy;
    }
    // The major axis is at angle θ = ½ atan2(2 sxy, sxx − syy); rotate by −θ unless the
    // spread is isotropic (a square, a regular polygon), where any angle is a principal one.
    let anisotropy = (2.0 * sxy).hypot(sxx - syy);
    if anisotropy > 1e-9 * (sxx + syy) {
        let (s, c) = (0.5 * (2.0 * sxy).atan2(sxx - syy)).sin_cos();
        for p in &mut points {
            let (dx, dy) = (p[0] - mx, p[1] - my);
            *p = [c * dx + s * dy, c * dy - s * dx];
        }
    }
    let (min_x, max_x, min_y, max_y) = bounding_box(&points);
    let (cx, cy) = ((min_x + max_x) / 2.0, (min_y + max_y) / 2.0);
    let turn = points[0][0] - cx > 0.0;
    for p in &mut points {
        *p = if turn {
            [cx - p[0], cy - p[1]]
        } else {
            [p[0] - cx, p[1] - cy]
        };
    }
    points
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map_of(nodes: usize, edges: &[(usize, usize)]) -> TopoMap {
        let mut map = TopoMap::new();
        for i in 0..nodes {
            map.add_node(&format!("N{i}"), None).unwrap();
        }
        for &(a, b) in edges {
            map.add_edge(&format!("N{a}_N{b}"), &format!("N{a}"), &format!("N{b}"))
                .unwrap();
        }
        map
    }

    fn distance(p: &[[f64; 2]], i: usize, j: usize) -> f64 {
        (p[i][0] - p[j][0]).hypot(p[i][1] - p[j][1])
    }

    fn min_pairwise(p: &[[f64; 2]]) -> f64 {
        let mut min = f64::INFINITY;
        for i in 0..p.len() {
            for j in i + 1..p.len() {
                min = min.min(distance(p, i, j));
            }
        }
        min
    }

    /// The Witham Wharf map as `chronomap_io::topo_files::read_edge_directory` builds it:
    /// an edge per `<From>_<To>.data.xz` file in stem order, nodes in byte order of names.
    fn witham() -> TopoMap {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../data/witham_topological_nav/edges");
        let mut stems: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .filter_map(|entry| {
                let name = entry.unwrap().file_name().into_string().unwrap();
                name.strip_suffix(".data.xz").map(str::to_owned)
            })
            .collect();
        stems.sort();
        let mut names: Vec<&str> = stems
            .iter()
            .flat_map(|stem| {
                let (from, to) = stem.split_once('_').unwrap();
                [from, to]
            })
            .collect();
        names.sort_unstable();
        names.dedup();
        let mut map = TopoMap::new();
        for name in names {
            map.add_node(name, None).unwrap();
        }
        for stem in &stems {
            let (from, to) = stem.split_once('_').unwrap();
            map.add_edge(stem, from, to).unwrap();
        }
        map
    }

    #[test]
    fn a_path_is_a_straight_line_of_edge_lengths() {
        let map = map_of(5, &[(0, 1), (2, 1), (2, 3), (3, 4)]);
        let p = stress_layout(&map, 1.5);
        assert_eq!(p.len(), 5);
        for i in 0..4 {
            assert!((distance(&p, i, i + 1) - 1.5).abs() < 1e-6, "{p:?}");
        }
        assert!(p.iter().all(|q| q[1].abs() < 1e-6), "not horizontal: {p:?}");
        assert!((distance(&p, 0, 4) - 6.0).abs() < 1e-6);
        assert!(p[0][0] <= 0.0 && (p[0][0] + 3.0).abs() < 1e-6 && (p[4][0] - 3.0).abs() < 1e-6);
        assert!(stress(&map, &p, 1.5) < 1e-9);
    }

    #[test]
    fn a_four_cycle_is_the_least_stress_square() {
        // Targets: sides L (4 pairs), diagonals 2L (2 pairs). A square of side tL has stress
        // 4(t − 1)² + 2(√2 t − 2)²/4 = 5t² − (8 + 2√2)t + 6, least at t = 0.8 + 0.2√2
        // (≈ 1.0828), where it is 2.4 − 1.6√2 (≈ 0.137258; a random search over all
        // placements of 4 points finds nothing lower). Not side L: the diagonal pulls.
        let length = 2.0;
        let map = map_of(4, &[(0, 1), (1, 2), (2, 3), (3, 0), (0, 3)]);
        let p = stress_layout(&map, length);
        let side = (0.8 + 0.2 * std::f64::consts::SQRT_2) * length;
        for (i, j) in [(0, 1), (1, 2), (2, 3), (3, 0)] {
            assert!((distance(&p, i, j) - side).abs() < 1e-5, "{p:?}");
        }
        for (i, j) in [(0, 2), (1, 3)] {
            assert!((distance(&p, i, j) - std::f64::consts::SQRT_2 * side).abs() < 1e-5);
        }
        let least = 2.4 - 1.6 * std::f64::consts::SQRT_2;
        let s = stress(&map, &p, length);
        assert!(s >= least - 1e-12 && s - least < 1e-9, "{s} vs {least}");
        // The stress of the square of side L (what a drawing by edge lengths alone gives).
        let unit: Vec<[f64; 2]> = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
            .iter()
            .map(|&[x, y]| [x * length, y * length])
            .collect();
        let expected = 2.0 * (std::f64::consts::SQRT_2 / 2.0 - 1.0).powi(2);
        assert!((stress(&map, &unit, length) - expected).abs() < 1e-12);
        assert!(expected > least);
    }

    #[test]
    fn components_are_side_by_side_largest_first() {
        // N0 alone, N1 — N2, N3 — N4, N5 — N6 — N7.
        let map = map_of(8, &[(1, 2), (4, 3), (5, 6), (7, 6)]);
        let length = 3.0;
        let p = stress_layout(&map, length);
        for (i, j) in [(1, 2), (3, 4), (5, 6), (6, 7)] {
            assert!((distance(&p, i, j) - length).abs() < 1e-6, "{p:?}");
        }
        assert!(p.iter().all(|q| q[1].abs() < 1e-6), "{p:?}");
        // Left to right: the path of 3, the edge 1–2, the edge 3–4, the single node; each
        // component's first node on its left.
        let order = [[5, 6, 7], [1, 1, 2], [3, 3, 4], [0, 0, 0]];
        for pair in order.windows(2) {
            let right_end = p[pair[0][2]][0];
            let next_start = p[pair[1][0]][0];
            assert!(
                (next_start - right_end - 2.0 * length).abs() < 1e-6,
                "{p:?}"
            );
        }
        // The bounding box is centred: from −(2 + 1 + 1 + 3·2)·L/2 to +.
        let half = (2.0 + 1.0 + 1.0 + 6.0) * length / 2.0;
        assert!((p[5][0] + half).abs() < 1e-6 && (p[0][0] - half).abs() < 1e-6);
        // Two disconnected edges: no overlap.
        let two = stress_layout(&map_of(4, &[(0, 1), (2, 3)]), 1.0);
        assert!(two[1][0] + 2.0 - two[2][0] < 1e-9 && min_pairwise(&two) >= 1.0 - 1e-9);
        assert!((two[0][0] + 2.0).abs() < 1e-9 && (two[3][0] - 2.0).abs() < 1e-9);
    }

    #[test]
    fn small_and_odd_inputs() {
        assert!(stress_layout(&TopoMap::new(), 1.0).is_empty());
        assert_eq!(stress_layout(&map_of(1, &[]), 1.0), vec![[0.0, 0.0]]);
        let two = map_of(2, &[(0, 1), (1, 0), (0, 0)]);
        let p = stress_layout(&two, 1.0);
        assert!(
            (p[0][0] + 0.5).abs() < 1e-9 && (p[1][0] - 0.5).abs() < 1e-9,
            "{p:?}"
        );
        assert!(p[0][1].abs() < 1e-9 && p[1][1].abs() < 1e-9, "{p:?}");
        for bad in [f64::NAN, f64::INFINITY, 0.0, -2.0] {
            assert_eq!(stress_layout(&two, bad), stress_layout(&two, 1.0));
            assert_eq!(stress(&two, &[[0.0, 0.0], [2.0, 0.0]], bad), 1.0);
        }
        assert!(stress(&two, &[[0.0, 0.0]], 1.0).is_nan());
        // Scale-free: positions and lengths scaled together score the same.
        let map = map_of(3, &[(0, 1), (1, 2)]);
        let p = [[0.0, 0.0], [1.0, 0.2], [1.5, 1.0]];
        let q = p.map(|[x, y]| [4.0 * x, 4.0 * y]);
        assert!((stress(&map, &p, 1.0) - stress(&map, &q, 4.0)).abs() < 1e-12);
    }

    #[test]
    fn twins_are_pulled_apart() {
        // A long path with two leaves (same neighbours) at one end, and a star.
        let fork = map_of(7, &[(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (4, 6)]);
        let p = stress_layout(&fork, 1.0);
        assert!(distance(&p, 5, 6) > 1.0, "{p:?}");
        let star = map_of(6, &[(0, 1), (0, 2), (0, 3), (0, 4), (0, 5)]);
        let p = stress_layout(&star, 1.0);
        assert!(min_pairwise(&p) > 0.5, "{p:?}");
    }

    #[test]
    fn large_maps_get_a_grid() {
        let n = MAX_STRESS_NODES + 1;
        let map = map_of(n, &[(0, 1)]);
        let p = stress_layout(&map, 2.0);
        // 45 columns, 45 rows (the last with 21 nodes), 2 m apart, centred.
        assert_eq!(p.len(), n);
        assert_eq!(
            (p[0], p[44], p[45]),
            ([-44.0, 44.0], [44.0, 44.0], [-44.0, 42.0])
        );
        assert_eq!(p[n - 1], [-44.0 + 2.0 * 20.0, -44.0]);
        assert!((min_pairwise(&p[..100]) - 2.0).abs() < 1e-12);
    }

    #[test]
    fn the_witham_map_is_drawn_readably_and_deterministically() {
        let map = witham();
        assert_eq!((map.nodes().len(), map.edges().len()), (18, 61));
        let length = 2.0;
        let p = stress_layout(&map, length);
        let again = stress_layout(&map, length);
        let bits = |p: &[[f64; 2]]| -> Vec<[u64; 2]> {
            p.iter().map(|q| [q[0].to_bits(), q[1].to_bits()]).collect()
        };
        assert_eq!(bits(&p), bits(&again));
        let min = min_pairwise(&p);
        assert!(min >= 0.3 * length, "{min}");
        // The synthetic circle of `chronomap_io::topo_files::node_poses` (radius 18/π m,
        // counter-clockwise in index order): about 2 m between neighbours on the circle.
        let n = map.nodes().len();
        let radius = (n as f64 / std::f64::consts::PI).max(1.0);
        let circle: Vec<[f64; 2]> = (0..n)
            .map(|k| {
                let angle = 2.0 * std::f64::consts::PI * k as f64 / n as f64;
                [radius * angle.cos(), radius * angle.sin()]
            })
            .collect();
        let (ours, theirs) = (stress(&map, &p, length), stress(&map, &circle, length));
        assert!(ours < theirs, "{ours} vs {theirs}");
        // The circle at its best radius (stress is quadratic in a scale factor a:
        // least at a = Σ w r d / Σ w r², with r the circle's distances).
        let (mut wrd, mut wrr) = (0.0, 0.0);
        let hops = |i: usize, j: usize| -> Option<f64> {
            let mut h = vec![u32::MAX; n];
            bfs(&adjacency(&map), i, &mut h, &mut VecDeque::new());
            (h[j] != u32::MAX).then(|| f64::from(h[j]) * length)
        };
        for i in 0..n {
            for j in i + 1..n {
                let (r, d) = (distance(&circle, i, j), hops(i, j).unwrap());
                wrd += r / d;
                wrr += r * r / (d * d);
            }
        }
        let best: Vec<[f64; 2]> = circle
            .iter()
            .map(|&[x, y]| [x * wrd / wrr, y * wrd / wrr])
            .collect();
        let best_circle = stress(&map, &best, length);
        assert!(
            ours < best_circle && best_circle <= theirs,
            "{ours} vs {best_circle}"
        );
        // Wider than tall, centred.
        let (min_x, max_x, min_y, max_y) = bounding_box(&p);
        assert!(max_x - min_x >= max_y - min_y);
        assert!((min_x + max_x).abs() < 1e-9 && (min_y + max_y).abs() < 1e-9);
        println!(
            "witham: stress {ours:.6} (circle {theirs:.6}, at its best radius \
             {best_circle:.6}), min pairwise distance {min:.4} m \
             for edge length {length} m, width {:.3} m, height {:.3} m",
            max_x - min_x,
            max_y - min_y
        );
    }
}
