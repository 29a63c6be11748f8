//! Storage of the run sums of changing cells (see the [crate docs](crate), "Memory").
//!
//! Every changing cell has two accumulators, the sums `S_k` of its occupied runs and those of
//! its unknown runs. Each is a signed sum of frame prefixes `±P_k(f)`, one term per *edge* (a
//! run beginning or ending at frame `f`), plus, for the occupied sums of fractional or sparse
//! observations, terms of their own. An accumulator is held
//!
//! * as nothing ([`Acc::Zero`]) before its first edge,
//! * as its edges alone ([`Acc::One`], [`Acc::Two`]: at most two, inline in the cell's slot),
//!   the prefixes `P(f)` of their frames being kept once for the whole grid as *snapshots*
//!   (shared by every cell with an edge at `f`; kept while referenced),
//! * as its own block of exact sums ([`Acc::Owned`]) from its third edge on, or from its first
//!   fractional or sparse observation.
//!
//! Blocks live in one [`Pool`] of `K + 1` entries per block (`K` candidate periods, plus the
//! exact sum `Σ s` of fractional and sparse values for occupied accumulators), as 64-bit
//! integers while every value fits, widened once to 128 bits for the whole grid when one would
//! not (a sum of `n` phasors of at most `2^50` units needs `51 + log2 n` bits: 64-bit storage
//! always suffices for about 8,000 frames, usually far longer). All arithmetic is exact in
//! either width, so the width never changes a value.
//!
//! The grid never holds more snapshots than accumulators held as edges (when it would, the
//! accumulators referencing a snapshot no other edge references take blocks of their own, which
//! costs nothing: the snapshot's block is freed): so the blocks in use never exceed two per
//! changing cell, the bound [`crate::MemoryEstimate`] relies on.

use serde::{Deserialize, Serialize};

/// Largest frame index an inline edge can name (frames from `2^31` on are added to owned
/// blocks directly).
pub(crate) const EDGE_FRAMES: u64 = 1 << 31;

/// One end of a run at a frame: `frame << 1 | close` (a run that ends adds `P(frame)`, one that
/// begins subtracts it).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub(crate) struct Edge(pub(crate) u32);

impl Edge {
    pub(crate) fn new(frame: u64, close: bool) -> Edge {
        debug_assert!(frame < EDGE_FRAMES);
        Edge(((frame as u32) << 1) | u32::from(close))
    }

    pub(crate) fn frame(self) -> u32 {
        self.0 >> 1
    }

    /// Whether the prefix is added (`true`) or subtracted.
    pub(crate) fn adds(self) -> bool {
        self.0 & 1 == 1
    }
}

/// How one accumulator of a cell is held.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub(crate) enum Acc {
    /// All sums zero.
    #[default]
    Zero,
    /// `±P(f)` of one edge.
    One(Edge),
    /// `±P(f₁) ± P(f₂)` of two edges, `f₁ < f₂`.
    Two(Edge, Edge),
    /// The sums in a block of the pool.
    Owned(u32),
}

impl Acc {
    /// The edges of an accumulator held as edges.
    pub(crate) fn edges(self) -> impl Iterator<Item = Edge> {
        let (a, b) = match self {
            Acc::One(a) => (Some(a), None),
            Acc::Two(a, b) => (Some(a), Some(b)),
            Acc::Zero | Acc::Owned(_) => (None, None),
        };
        a.into_iter().chain(b)
    }

    pub(crate) fn is_edges(self) -> bool {
        matches!(self, Acc::One(_) | Acc::Two(..))
    }
}

/// Which accumulator of a slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Which {
    Occupied = 0,
    Unknown = 1,
}

impl Which {
    /// The code of accumulator `self` of `slot` that snapshots fold into their XOR.
    pub(crate) fn code(self, slot: usize) -> u64 {
        ((slot as u64) << 1) | self as u64
    }

    pub(crate) fn of_code(code: u64) -> (usize, Which) {
        let which = if code & 1 == 0 {
            Which::Occupied
        } else {
            Which::Unknown
        };
        ((code >> 1) as usize, which)
    }
}

/// The prefix `P(f)` of a frame that edges reference: its block, how many edges reference it
/// and the XOR of their accumulator codes ([`Which::code`]), which names the one accumulator
/// referencing it when only one does.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub(crate) struct Snapshot {
    pub(crate) block: u32,
    pub(crate) refs: u32,
    pub(crate) codes: u64,
}

/// Blocks of exact sums, 64-bit while every value fits, else 128-bit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) enum Pool {
    /// Every value fits in an `i64`.
    Narrow(Vec<[i64; 2]>),
    /// Widened once a value did not.
    Wide(Vec<[i128; 2]>),
}

impl Default for Pool {
    fn default() -> Self {
        Pool::Narrow(Vec::new())
    }
}

impl Pool {
    pub(crate) fn len(&self) -> usize {
        match self {
            Pool::Narrow(v) => v.len(),
            Pool::Wide(v) => v.len(),
        }
    }

    pub(crate) fn is_wide(&self) -> bool {
        matches!(self, Pool::Wide(_))
    }

    /// Heap bytes held.
    pub(crate) fn heap_bytes(&self) -> usize {
        match self {
            Pool::Narrow(v) => v.capacity() * std::mem::size_of::<[i64; 2]>(),
            Pool::Wide(v) => v.capacity() * std::mem::size_of::<[i128; 2]>(),
        }
    }

    #[inline]
    pub(crate) fn get(&self, i: usize) -> [i128; 2] {
        match self {
            Pool::Narrow(v) => [i128::from(v[i][0]), i128::from(v[i][1])],
            Pool::Wide(v) => v[i],
        }
    }

    /// Converts every entry to 128 bits.
    pub(crate) fn widen(&mut self) {
        if let Pool::Narrow(v) = self {
            let mut wide = Vec::with_capacity(v.capacity());
            wide.extend(v.iter().map(|e| [i128::from(e[0]), i128::from(e[1])]));
            *self = Pool::Wide(wide);
        }
    }

    /// Appends `n` zero entries, growing the capacity by half (at least `min_step` entries) but
    /// never past `limit` entries if that is enough.
    pub(crate) fn grow(&mut self, n: usize, min_step: usize, limit: usize) {
        match self {
            Pool::Narrow(v) => {
                reserve_within(v, n, min_step, limit);
                v.resize(v.len() + n, [0; 2]);
            }
            Pool::Wide(v) => {
                reserve_within(v, n, min_step, limit);
                v.resize(v.len() + n, [0; 2]);
            }
        }
    }

    /// Appends the entries of `other` (widening them if this pool is wide; `other` must not
    /// be wide unless this one is).
    pub(crate) fn append(&mut self, other: Pool) {
        match (self, other) {
            (Pool::Narrow(v), Pool::Narrow(w)) => v.extend(w),
            (Pool::Wide(v), Pool::Wide(w)) => v.extend(w),
            (Pool::Wide(v), Pool::Narrow(w)) => {
                v.extend(w.iter().map(|e| [i128::from(e[0]), i128::from(e[1])]));
            }
            (this @ Pool::Narrow(_), other @ Pool::Wide(_)) => {
                this.widen();
                this.append(other);
            }
        }
    }

    /// Sets entries `at..at + n` to zero.
    pub(crate) fn zero(&mut self, at: usize, n: usize) {
        match self {
            Pool::Narrow(v) => v[at..at + n].fill([0; 2]),
            Pool::Wide(v) => v[at..at + n].fill([0; 2]),
        }
    }

    /// `pool[at + j] += values[j]` (or `-=` if `negate`), widening if a sum leaves 64 bits.
    pub(crate) fn add_rows(&mut self, at: usize, values: &[[i128; 2]], negate: bool) {
        let done = match self {
            Pool::Narrow(v) => {
                let rows = &mut v[at..at + values.len()];
                let mut done = values.len();
                for (j, (row, value)) in rows.iter_mut().zip(values).enumerate() {
                    let (re, im) = if negate {
                        (i128::from(row[0]) - value[0], i128::from(row[1]) - value[1])
                    } else {
                        (i128::from(row[0]) + value[0], i128::from(row[1]) + value[1])
                    };
                    match (i64::try_from(re), i64::try_from(im)) {
                        (Ok(re), Ok(im)) => *row = [re, im],
                        _ => {
                            done = j;
                            break;
                        }
                    }
                }
                done
            }
            Pool::Wide(v) => {
                for (row, value) in v[at..at + values.len()].iter_mut().zip(values) {
                    if negate {
                        row[0] -= value[0];
                        row[1] -= value[1];
                    } else {
                        row[0] += value[0];
                        row[1] += value[1];
                    }
                }
                values.len()
            }
        };
        if done < values.len() {
            self.widen();
            self.add_rows(at + done, &values[done..], negate);
        }
    }
}

/// Reserves room for `n` more elements of `v`: by half its length (at least `min_step`) if it
/// is full, but no further than `limit` elements when `limit` leaves room for the `n`.
pub(crate) fn reserve_within<T>(v: &mut Vec<T>, n: usize, min_step: usize, limit: usize) {
    let needed = v.len() + n;
    if needed <= v.capacity() {
        return;
    }
    let wanted = needed.max(v.len() + (v.len() / 2).max(min_step));
    let target = if needed <= limit {
        wanted.min(limit)
    } else {
        wanted
    };
    v.reserve_exact(target - v.len());
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn narrow_pools_widen_exactly_when_a_sum_leaves_64_bits() {
        let mut pool = Pool::default();
        pool.grow(3, 1, 3);
        pool.add_rows(0, &[[5, -7], [i128::from(i64::MAX), 1], [1, 1]], false);
        assert!(!pool.is_wide());
        // The second row overflows: rows before it were added in 64 bits, the rest in 128.
        pool.add_rows(0, &[[1, 1], [1, 0], [2, 2]], false);
        assert!(pool.is_wide());
        assert_eq!(
            (0..3).map(|i| pool.get(i)).collect::<Vec<_>>(),
            [[6, -6], [i128::from(i64::MAX) + 1, 1], [3, 3]]
        );
        pool.add_rows(1, &[[i128::from(i64::MAX) + 1, 1]], true);
        assert_eq!(pool.get(1), [0, 0]);
        // Subtraction below i64::MIN widens too.
        let mut pool = Pool::default();
        pool.grow(1, 1, 1);
        pool.add_rows(0, &[[i128::from(i64::MIN), 0]], false);
        pool.add_rows(0, &[[1, 0]], true);
        assert_eq!(pool.get(0), [i128::from(i64::MIN) - 1, 0]);
    }

    #[test]
    fn capacity_grows_by_half_within_the_limit() {
        let mut v: Vec<u8> = Vec::new();
        reserve_within(&mut v, 1, 4, 10);
        assert_eq!(v.capacity(), 4);
        v.resize(4, 0);
        reserve_within(&mut v, 1, 4, 10);
        assert_eq!(v.capacity(), 8);
        v.resize(8, 0);
        reserve_within(&mut v, 1, 4, 10);
        assert_eq!(v.capacity(), 10);
        v.resize(10, 0);
        // Past the limit (which the grid's bounds never allow) it still grows.
        reserve_within(&mut v, 1, 4, 10);
        assert!(v.capacity() >= 11);
    }

    #[test]
    fn edges_and_codes_round_trip() {
        let e = Edge::new(12_345, true);
        assert_eq!((e.frame(), e.adds()), (12_345, true));
        let e = Edge::new(EDGE_FRAMES - 1, false);
        assert_eq!((u64::from(e.frame()), e.adds()), (EDGE_FRAMES - 1, false));
        assert_eq!(
            Which::of_code(Which::Unknown.code(77)),
            (77, Which::Unknown)
        );
        assert_eq!(
            Which::of_code(Which::Occupied.code(0)),
            (0, Which::Occupied)
        );
        assert_eq!(std::mem::size_of::<Acc>(), 12);
    }
}
