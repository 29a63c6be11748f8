//! The per-cell descriptors of an office, drawn once from the seed.

use super::{CellClass, DAY_SECS, OfficeConfig, day_of};
use chronomap_core::rng::{Xoshiro256StarStar, derive_seed};

/// Purpose tags of the random streams (see [`derive_seed`]).
pub(crate) const TAG_LAYOUT: u64 = 1;
pub(crate) const TAG_PERIODIC: u64 = 2;
pub(crate) const TAG_NOISE: u64 = 3;

/// Share of periodic cells among dynamic cells.
const PERIODIC_SHARE: f64 = 0.25;
/// Share of persistent cells among dynamic cells (noise cells are the rest).
const PERSISTENT_SHARE: f64 = 0.09;
/// Share of static occupied cells among static cells.
const STATIC_OCCUPIED_SHARE: f64 = 0.10;
/// Cluster sizes (inclusive ranges of cells).
const PERIODIC_CLUSTER: (u64, u64) = (8, 32);
const PERSISTENT_CLUSTER: (u64, u64) = (4, 16);
const STATIC_OCCUPIED_RUN: (u64, u64) = (4, 64);
/// Largest shrink of a periodic cell's interval at each end, seconds.
const TRIM_MAX_SECS: f64 = 300.0;
/// Range of the noise rate `r` (bursts per hour at the profile's peak), log-uniform.
const NOISE_RATE_PER_HOUR: (f64, f64) = (0.05, 5.0);
/// Hours of the day during which persistent cells switch.
const PERSISTENT_HOURS: (f64, f64) = (8.0, 18.0);

/// The kinds of periodic objects (see the table in the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum PeriodicKind {
    Chair,
    Door,
    Table,
    Bin,
}

/// Parameter ranges of a kind of periodic object.
struct KindSpec {
    kind: PeriodicKind,
    /// Share of the periodic cells, in twentieths.
    weight: usize,
    weekdays_only: bool,
    inverted: bool,
    start_hours: (f64, f64),
    duration_hours: (f64, f64),
    jitter_minutes: (f64, f64),
    skip: (f64, f64),
}

/// Each kind satisfies `duration >= 2 × (jitter + trim) + 10 min` (so a day's interval is
/// never empty) and `start − jitter >= 0`, `end + jitter <= 24 h` (so it stays in its day).
const KINDS: [KindSpec; 4] = [
    KindSpec {
        kind: PeriodicKind::Chair,
        weight: 8,
        weekdays_only: true,
        inverted: false,
        start_hours: (7.5, 9.5),
        duration_hours: (6.0, 9.0),
        jitter_minutes: (15.0, 45.0),
        skip: (0.05, 0.15),
    },
    KindSpec {
        kind: PeriodicKind::Door,
        weight: 3,
        weekdays_only: true,
        inverted: true,
        start_hours: (7.0, 9.0),
        duration_hours: (8.0, 11.0),
        jitter_minutes: (15.0, 30.0),
        skip: (0.02, 0.08),
    },
    KindSpec {
        kind: PeriodicKind::Table,
        weight: 5,
        weekdays_only: true,
        inverted: false,
        start_hours: (11.5, 13.0),
        duration_hours: (1.0, 1.5),
        jitter_minutes: (10.0, 20.0),
        skip: (0.10, 0.30),
    },
    KindSpec {
        kind: PeriodicKind::Bin,
        weight: 4,
        weekdays_only: false,
        inverted: false,
        start_hours: (5.0, 19.0),
        duration_hours: (1.0, 4.0),
        jitter_minutes: (10.0, 20.0),
        skip: (0.05, 0.20),
    },
];

/// A daily process shared by a cluster of periodic cells.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct PeriodicProcess {
    pub kind: PeriodicKind,
    pub weekdays_only: bool,
    /// Occupied outside the interval instead of inside (a door closed out of hours).
    pub inverted: bool,
    /// Interval start and end, seconds after midnight, before jitter.
    pub start: f64,
    pub end: f64,
    /// Half-width of the uniform daily jitter of each end, seconds.
    pub jitter: f64,
    /// Probability that an active day's interval does not happen.
    pub skip: f64,
}

/// The step shared by a cluster of persistent cells.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Step {
    /// Unix time of the change.
    pub time: f64,
    /// State before the change.
    pub initially_occupied: bool,
}

/// Descriptor of one cell (12 bytes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Cell {
    Free,
    Occupied,
    Periodic {
        process: u32,
        /// Shrink of the interval at its start and end, seconds.
        trim_start: u16,
        trim_end: u16,
    },
    Noise {
        /// Bursts per hour at the profile's peak.
        rate: f32,
    },
    Persistent {
        step: u32,
    },
}

impl Cell {
    pub fn class(self) -> CellClass {
        match self {
            Cell::Free => CellClass::StaticFree,
            Cell::Occupied => CellClass::StaticOccupied,
            Cell::Periodic { .. } => CellClass::Periodic,
            Cell::Noise { .. } => CellClass::Noise,
            Cell::Persistent { .. } => CellClass::Persistent,
        }
    }
}

/// All descriptors of an office.
#[derive(Clone, Debug)]
pub(crate) struct Layout {
    pub cells: Vec<Cell>,
    pub periodic: Vec<PeriodicProcess>,
    pub steps: Vec<Step>,
    /// Cells per class, indexed by `CellClass as usize`.
    pub counts: [usize; 5],
}

/// A run of consecutive cells laid out together.
#[derive(Clone, Copy)]
enum Segment {
    Free,
    Noise,
    Occupied(u32),
    Periodic { process: u32, len: u32 },
    Persistent { step: u32, len: u32 },
}

/// Sizes of clusters of `lo..=hi` cells adding up to `total`: a remainder smaller than `lo`
/// joins the last cluster (which then has up to `hi + lo − 1` cells); only a `total` below
/// `lo` gives a smaller cluster.
fn cluster_sizes(rng: &mut Xoshiro256StarStar, total: usize, (lo, hi): (u64, u64)) -> Vec<u32> {
    let mut sizes = Vec::new();
    let mut left = total as u64;
    while left > 0 {
        let mut size = rng.int_in(lo, hi).min(left);
        if left - size < lo {
            size = left;
        }
        sizes.push(size as u32);
        left -= size;
    }
    sizes
}

/// Splits `total` in proportion to `weights` (largest remainders), summing exactly to it.
fn apportion(total: usize, weights: &[usize]) -> Vec<usize> {
    let sum: usize = weights.iter().sum();
    let mut shares: Vec<usize> = weights.iter().map(|&w| total * w / sum).collect();
    let mut order: Vec<usize> = (0..weights.len()).collect();
    order.sort_by_key(|&i| std::cmp::Reverse(total * weights[i] % sum));
    let missing = total - shares.iter().sum::<usize>();
    for &i in order.iter().take(missing) {
        shares[i] += 1;
    }
    shares
}

impl Layout {
    pub fn generate(config: &OfficeConfig) -> Layout {
        let mut rng = Xoshiro256StarStar::seed_from_u64(derive_seed(config.seed, TAG_LAYOUT, 0, 0));
        let n = config.cells;
        let n_dynamic = ((config.dynamic_fraction * n as f64).round() as usize).min(n);
        let n_periodic = (PERIODIC_SHARE * n_dynamic as f64).round() as usize;
        let n_persistent =
            ((PERSISTENT_SHARE * n_dynamic as f64).round() as usize).min(n_dynamic - n_periodic);
        let n_noise = n_dynamic - n_periodic - n_persistent;
        let n_static = n - n_dynamic;
        let n_occupied = (STATIC_OCCUPIED_SHARE * n_static as f64).round() as usize;
        let n_free = n_static - n_occupied;

        let mut segments = Vec::with_capacity(n_free + n_noise + n_occupied / 4 + 64);

        // Periodic clusters: each kind gets its exact share of the periodic cells.
        let weights: Vec<usize> = KINDS.iter().map(|k| k.weight).collect();
        let mut periodic = Vec::new();
        for (spec, quota) in KINDS.iter().zip(apportion(n_periodic, &weights)) {
            for len in cluster_sizes(&mut rng, quota, PERIODIC_CLUSTER) {
                let start = rng.uniform(spec.start_hours.0, spec.start_hours.1) * 3600.0;
                let duration = rng.uniform(spec.duration_hours.0, spec.duration_hours.1) * 3600.0;
                let jitter = rng.uniform(spec.jitter_minutes.0, spec.jitter_minutes.1) * 60.0;
                let skip = rng.uniform(spec.skip.0, spec.skip.1);
                segments.push(Segment::Periodic {
                    process: periodic.len() as u32,
                    len,
                });
                periodic.push(PeriodicProcess {
                    kind: spec.kind,
                    weekdays_only: spec.weekdays_only,
                    inverted: spec.inverted,
                    start,
                    end: start + duration,
                    jitter,
                    skip,
                });
            }
        }

        // Persistent clusters, switch days spread evenly over the workload (systematic
        // sampling: one random offset for all).
        let sizes = cluster_sizes(&mut rng, n_persistent, PERSISTENT_CLUSTER);
        let first_day = day_of(config.start_time);
        let offset = rng.next_f64();
        let mut steps = Vec::with_capacity(sizes.len());
        for (k, &len) in sizes.iter().enumerate() {
            let x = (k as f64 + offset) / sizes.len() as f64;
            let day = ((x * f64::from(config.days)).floor() as i64).min(i64::from(config.days) - 1);
            let hour = rng.uniform(PERSISTENT_HOURS.0, PERSISTENT_HOURS.1);
            segments.push(Segment::Persistent {
                step: steps.len() as u32,
                len,
            });
            steps.push(Step {
                time: (first_day + day) as f64 * DAY_SECS + hour * 3600.0,
                initially_occupied: rng.bernoulli(0.5),
            });
        }

        for len in cluster_sizes(&mut rng, n_occupied, STATIC_OCCUPIED_RUN) {
            segments.push(Segment::Occupied(len));
        }
        segments.extend(std::iter::repeat_n(Segment::Noise, n_noise));
        segments.extend(std::iter::repeat_n(Segment::Free, n_free));
        rng.shuffle(&mut segments);

        let (rate_lo, rate_hi) = (NOISE_RATE_PER_HOUR.0.ln(), NOISE_RATE_PER_HOUR.1.ln());
        let mut cells = Vec::with_capacity(n);
        for segment in segments {
            match segment {
                Segment::Free => cells.push(Cell::Free),
                Segment::Noise => cells.push(Cell::Noise {
                    rate: rng.uniform(rate_lo, rate_hi).exp() as f32,
                }),
                Segment::Occupied(len) => {
                    cells.extend(std::iter::repeat_n(Cell::Occupied, len as usize));
                }
                Segment::Periodic { process, len } => {
                    for _ in 0..len {
                        cells.push(Cell::Periodic {
                            process,
                            trim_start: rng.uniform(0.0, TRIM_MAX_SECS) as u16,
                            trim_end: rng.uniform(0.0, TRIM_MAX_SECS) as u16,
                        });
                    }
                }
                Segment::Persistent { step, len } => {
                    cells.extend(std::iter::repeat_n(Cell::Persistent { step }, len as usize));
                }
            }
        }
        debug_assert_eq!(cells.len(), n);

        let mut counts = [0; 5];
        counts[CellClass::StaticFree as usize] = n_free;
        counts[CellClass::StaticOccupied as usize] = n_occupied;
        counts[CellClass::Periodic as usize] = n_periodic;
        counts[CellClass::Noise as usize] = n_noise;
        counts[CellClass::Persistent as usize] = n_persistent;
        Layout {
            cells,
            periodic,
            steps,
            counts,
        }
    }
}
