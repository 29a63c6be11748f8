//! Where to search (§5.4.3): places sampled with probability proportional to the rate of their
//! cell, thinned to one per detection radius; the order to visit them as an open travelling
//! salesman problem, solved by a small seeded genetic algorithm (and by brute force in tests).

use chronomap_core::rng::Xoshiro256StarStar;

/// Samples up to `count` of the `candidates` (each with its cell rate and position) with
/// probability `∝` rate (§5.4.3), after the `fixed` ones (indices kept first, as they are). A
/// draw closer than `radius` to a kept place replaces it only if its rate is larger (then every
/// kept place within `radius` goes) and none of them is fixed; otherwise it is dropped. Stops
/// after `count` places or `50·count` draws. Returns indices into `candidates`, the fixed first.
pub fn sample_places(
    candidates: &[([f64; 2], f64)],
    fixed: &[usize],
    count: usize,
    radius: f64,
    rng: &mut Xoshiro256StarStar,
) -> Vec<usize> {
    let mut cumulative = Vec::with_capacity(candidates.len());
    let mut total = 0.0;
    for &(_, rate) in candidates {
        total += rate.max(0.0);
        cumulative.push(total);
    }
    let mut kept: Vec<usize> = Vec::new();
    for &f in fixed {
        if kept.len() < count && f < candidates.len() && !kept.contains(&f) {
            kept.push(f);
        }
    }
    let is_fixed = |k: usize| fixed.contains(&k);
    if total <= 0.0 || kept.len() == count {
        return kept;
    }
    let near = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]) < radius;
    for _ in 0..50 * count {
        if kept.len() == count {
            break;
        }
        let u = rng.next_f64() * total;
        let drawn = cumulative
            .partition_point(|&c| c <= u)
            .min(candidates.len() - 1);
        if kept.contains(&drawn) {
            continue;
        }
        let (at, rate) = candidates[drawn];
        let conflicts: Vec<usize> = kept
            .iter()
            .copied()
            .filter(|&k| near(candidates[k].0, at))
            .collect();
        if conflicts
            .iter()
            .all(|&k| !is_fixed(k) && rate > candidates[k].1)
        {
            kept.retain(|k| !conflicts.contains(k));
            kept.push(drawn);
        }
    }
    kept
}

/// Samples up to `count` candidates uniformly (the RND baseline), dropping draws within
/// `radius` of a kept one. Returns indices.
pub fn sample_uniform(
    candidates: &[[f64; 2]],
    count: usize,
    radius: f64,
    rng: &mut Xoshiro256StarStar,
) -> Vec<usize> {
    let mut kept: Vec<usize> = Vec::new();
    if candidates.is_empty() {
        return kept;
    }
    for _ in 0..50 * count {
        if kept.len() == count {
            break;
        }
        let drawn = rng.int_in(0, candidates.len() as u64 - 1) as usize;
        let at = candidates[drawn];
        if kept
            .iter()
            .all(|&k| (candidates[k][0] - at[0]).hypot(candidates[k][1] - at[1]) >= radius)
        {
            kept.push(drawn);
        }
    }
    kept
}

/// Settings of the open TSP: exact for few places, else the genetic algorithm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TspConfig {
    /// Up to this many places every tour is tried ([`open_tsp_brute_force`]; 7 by default:
    /// `7! = 5040` tours, fewer than the `population × generations` the genetic algorithm
    /// evaluates); more are ordered by [`open_tsp_genetic`].
    pub exact_up_to: usize,
    /// Tours per generation.
    pub population: usize,
    /// Generations.
    pub generations: usize,
    /// Probability that a child is mutated (a reversed segment).
    pub mutation: f64,
}

impl Default for TspConfig {
    fn default() -> Self {
        TspConfig {
            exact_up_to: 7,
            population: 100,
            generations: 300,
            mutation: 0.3,
        }
    }
}

/// Cost of the open tour `0 → order[0] → order[1] → …` (node 0 is the fixed start).
/// `cost[i][j]` is the cost from node `i` to node `j` (`0..=n`).
pub fn tour_cost(cost: &[Vec<f64>], order: &[usize]) -> f64 {
    let mut total = 0.0;
    let mut at = 0;
    for &next in order {
        total += cost[at][next];
        at = next;
    }
    total
}

/// The cheapest open tour from node 0 through nodes `1..=n` by brute force (`n!` tours; the
/// test oracle). Ties keep the lexicographically first order.
pub fn open_tsp_brute_force(cost: &[Vec<f64>]) -> Vec<usize> {
    let n = cost.len().saturating_sub(1);
    let mut order: Vec<usize> = (1..=n).collect();
    let mut best = order.clone();
    let mut best_cost = tour_cost(cost, &order);
    // Heap's algorithm would visit every permutation too; lexicographic order keeps ties stable.
    while next_permutation(&mut order) {
        let c = tour_cost(cost, &order);
        if c < best_cost {
            best_cost = c;
            best = order.clone();
        }
    }
    best
}

fn next_permutation(v: &mut [usize]) -> bool {
    if v.len() < 2 {
        return false;
    }
    let mut i = v.len() - 1;
    while i > 0 && v[i - 1] >= v[i] {
        i -= 1;
    }
    if i == 0 {
        return false;
    }
    let mut j = v.len() - 1;
    while v[j] <= v[i - 1] {
        j -= 1;
    }
    v.swap(i - 1, j);
    v[i..].reverse();
    true
}

/// The open tour from node 0 through nodes `1..=n` (§5.4.3): the cheapest by brute force for
/// `n ≤` [`TspConfig::exact_up_to`], else by [`open_tsp_genetic`].
pub fn open_tsp(cost: &[Vec<f64>], config: &TspConfig, rng: &mut Xoshiro256StarStar) -> Vec<usize> {
    if cost.len().saturating_sub(1) <= config.exact_up_to.min(10) {
        open_tsp_brute_force(cost)
    } else {
        open_tsp_genetic(cost, config, rng)
    }
}

/// The open tour from node 0 through nodes `1..=n` by a genetic algorithm (\[Dav10\] in the dissertation): order
/// crossover of two tournament-selected parents, segment-reversal mutation, the best tour kept
/// (elitism); the initial population holds the nearest-neighbour tour and random ones. The
/// best tour is then improved by 2-opt and or-opt moves until none helps. Deterministic for a
/// given `rng`.
pub fn open_tsp_genetic(
    cost: &[Vec<f64>],
    config: &TspConfig,
    rng: &mut Xoshiro256StarStar,
) -> Vec<usize> {
    let n = cost.len().saturating_sub(1);
    if n <= 1 {
        return (1..=n).collect();
    }
    let size = config.population.max(4);
    let mut population: Vec<(f64, Vec<usize>)> = Vec::with_capacity(size);
    let greedy = nearest_neighbour(cost);
    population.push((tour_cost(cost, &greedy), greedy));
    while population.len() < size {
        let mut order: Vec<usize> = (1..=n).collect();
        rng.shuffle(&mut order);
        population.push((tour_cost(cost, &order), order));
    }
    let by_cost = |a: &(f64, Vec<usize>), b: &(f64, Vec<usize>)| {
        a.0.total_cmp(&b.0).then_with(|| a.1.cmp(&b.1))
    };
    population.sort_by(by_cost);
    for _ in 0..config.generations {
        let mut next = vec![population[0].clone()];
        while next.len() < size {
            let a = tournament(&population, rng);
            let b = tournament(&population, rng);
            let mut child = order_crossover(&population[a].1, &population[b].1, rng);
            if rng.bernoulli(config.mutation) {
                let i = rng.int_in(0, n as u64 - 1) as usize;
                let j = rng.int_in(0, n as u64 - 1) as usize;
                child[i.min(j)..=i.max(j)].reverse();
            }
            next.push((tour_cost(cost, &child), child));
        }
        next.sort_by(by_cost);
        population = next;
    }
    let mut best = population.swap_remove(0).1;
    local_search(cost, &mut best);
    best
}

fn nearest_neighbour(cost: &[Vec<f64>]) -> Vec<usize> {
    let n = cost.len() - 1;
    let mut left: Vec<usize> = (1..=n).collect();
    let mut order = Vec::with_capacity(n);
    let mut at = 0;
    while !left.is_empty() {
        let (i, _) = left
            .iter()
            .enumerate()
            .min_by(|a, b| cost[at][*a.1].total_cmp(&cost[at][*b.1]))
            .expect("not empty");
        at = left.remove(i);
        order.push(at);
    }
    order
}

fn tournament(population: &[(f64, Vec<usize>)], rng: &mut Xoshiro256StarStar) -> usize {
    let last = population.len() as u64 - 1;
    let a = rng.int_in(0, last) as usize;
    let b = rng.int_in(0, last) as usize;
    a.min(b) // the population is sorted by cost
}

/// Order crossover (OX1): a segment of `a`, the rest in the order of `b`.
fn order_crossover(a: &[usize], b: &[usize], rng: &mut Xoshiro256StarStar) -> Vec<usize> {
    let n = a.len();
    let i = rng.int_in(0, n as u64 - 1) as usize;
    let j = rng.int_in(0, n as u64 - 1) as usize;
    let (lo, hi) = (i.min(j), i.max(j));
    let segment = &a[lo..=hi];
    let mut rest = b.iter().copied().filter(|x| !segment.contains(x));
    let mut child = Vec::with_capacity(n);
    for (k, &from_a) in a.iter().enumerate() {
        if (lo..=hi).contains(&k) {
            child.push(from_a);
        } else {
            child.push(rest.next().expect("a permutation"));
        }
    }
    child
}

/// Improves the open tour by 2-opt (reverse a segment) and or-opt (move one node elsewhere)
/// moves until none helps (costs may be asymmetric, so each move is priced in full).
fn local_search(cost: &[Vec<f64>], order: &mut Vec<usize>) {
    let n = order.len();
    let mut current = tour_cost(cost, order);
    loop {
        let mut improved = false;
        for i in 0..n {
            for j in i + 1..n {
                order[i..=j].reverse();
                let c = tour_cost(cost, order);
                if c + 1e-12 < current {
                    current = c;
                    improved = true;
                } else {
                    order[i..=j].reverse();
                }
            }
        }
        for i in 0..n {
            for j in 0..n {
                if i == j {
                    continue;
                }
                let node = order.remove(i);
                order.insert(j, node);
                let c = tour_cost(cost, order);
                if c + 1e-12 < current {
                    current = c;
                    improved = true;
                } else {
                    let node = order.remove(j);
                    order.insert(i, node);
                }
            }
        }
        if !improved {
            break;
        }
    }
}
