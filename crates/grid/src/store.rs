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
//! exact sum `Σ s` of fractional and sparse values for occupied accumulators). Each column (a
//! period, or the fractional sum) is held in 64-bit integers while all its values fit, and
//! widened once to 128 bits in every block when one would not (a sum of `n` phasors of at most
//! `2^50` units needs `51 + log2 n` bits: 64 bits always suffice for about 8,000 frames; the
//! prefix of a period `T` sampled every `Δt` stays below about `T / (π Δt)` phasors, so only
//! the longest periods of long, dense series widen). All arithmetic is exact in either width,
//! so the width never changes a value.
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

/// Blocks of `stride` exact sums (`[re, im]` pairs), one column per period and one for the
/// fractional values: each column is held in 64 bits while all its values fit, and widened once
/// to 128 bits (its high halves in a second array) when one would not. Only the columns of the
/// longest periods, whose prefix sums grow the most, ever need it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "StoredPool")]
pub(crate) struct Pool {
    stride: usize,
    /// The low 64 bits of every entry (all of a narrow column's value), `stride` a block.
    low: Vec<[i64; 2]>,
    /// The widened columns, in the order they widened.
    wide: Vec<u32>,
    /// The high 64 bits of the entries of widened columns, `wide.len()` a block.
    high: Vec<[i64; 2]>,
    /// Position of each column in `wide`, or `u32::MAX` (derived).
    #[serde(skip)]
    high_index: Vec<u32>,
}

/// A [`Pool`] as a grid file holds it.
#[derive(Deserialize)]
struct StoredPool {
    stride: usize,
    low: Vec<[i64; 2]>,
    wide: Vec<u32>,
    high: Vec<[i64; 2]>,
}

impl TryFrom<StoredPool> for Pool {
    type Error = String;

    fn try_from(s: StoredPool) -> Result<Self, String> {
        if s.stride == 0 || !s.low.len().is_multiple_of(s.stride) {
            return Err(format!(
                "the pool's {} entries are not blocks of {}",
                s.low.len(),
                s.stride
            ));
        }
        // The stride comes from the file: bounded by the entries read or by the columns named.
        if s.stride > s.low.len().max(s.wide.len()).max(1 << 17) {
            return Err(format!("a pool stride of {} columns", s.stride));
        }
        let mut high_index = vec![NARROW; s.stride];
        for (i, &column) in s.wide.iter().enumerate() {
            match high_index.get_mut(column as usize) {
                Some(entry) if *entry == NARROW => *entry = i as u32,
                _ => return Err(format!("wide column {column} is outside or repeated")),
            }
        }
        if s.high.len() != s.low.len() / s.stride * s.wide.len() {
            return Err("the high halves do not fit the wide columns".into());
        }
        Ok(Pool {
            stride: s.stride,
            low: s.low,
            wide: s.wide,
            high: s.high,
            high_index,
        })
    }
}

/// `high_index` of a narrow column.
const NARROW: u32 = u32::MAX;

/// The value of high half `hi` and low half `lo`.
#[inline]
fn join(hi: i64, lo: i64) -> i128 {
    (i128::from(hi) << 64) | i128::from(lo as u64)
}

impl Pool {
    /// An empty pool of blocks of `stride` entries.
    pub(crate) fn new(stride: usize) -> Self {
        Pool {
            stride,
            low: Vec::new(),
            wide: Vec::new(),
            high: Vec::new(),
            high_index: vec![NARROW; stride],
        }
    }

    /// Entries per block.
    pub(crate) fn stride(&self) -> usize {
        self.stride
    }

    /// Number of entries.
    pub(crate) fn len(&self) -> usize {
        self.low.len()
    }

    /// Number of columns held in 128 bits.
    pub(crate) fn wide_columns(&self) -> usize {
        self.wide.len()
    }

    /// Heap bytes held.
    pub(crate) fn heap_bytes(&self) -> usize {
        (self.low.capacity() + self.high.capacity()) * 16
            + (self.wide.capacity() + self.high_index.capacity()) * 4
    }

    /// Entry `i`.
    #[inline]
    pub(crate) fn get(&self, i: usize) -> [i128; 2] {
        let lo = self.low[i];
        if !self.wide.is_empty() {
            let h = self.high_index[i % self.stride];
            if h != NARROW {
                let hi = self.high[i / self.stride * self.wide.len() + h as usize];
                return [join(hi[0], lo[0]), join(hi[1], lo[1])];
            }
        }
        [i128::from(lo[0]), i128::from(lo[1])]
    }

    /// Sets entry `i` (its column must be wide enough).
    fn set(&mut self, i: usize, value: [i128; 2]) {
        self.low[i] = [value[0] as i64, value[1] as i64];
        let h = self.high_index[i % self.stride];
        if h != NARROW {
            let at = i / self.stride * self.wide.len() + h as usize;
            self.high[at] = [(value[0] >> 64) as i64, (value[1] >> 64) as i64];
        }
    }

    /// Holds column `column` in 128 bits from now on.
    pub(crate) fn widen(&mut self, column: usize) {
        if self.high_index[column] != NARROW {
            return;
        }
        let (w, blocks) = (self.wide.len(), self.low.len() / self.stride);
        let mut high = Vec::with_capacity(self.low.capacity() / self.stride * (w + 1));
        for b in 0..blocks {
            high.extend_from_slice(&self.high[b * w..(b + 1) * w]);
            let lo = self.low[b * self.stride + column];
            high.push([lo[0] >> 63, lo[1] >> 63]);
        }
        self.high = high;
        self.high_index[column] = w as u32;
        self.wide.reserve_exact(1);
        self.wide.push(column as u32);
    }

    /// Appends `n` zero entries (whole blocks), growing the capacity as [`reserve_within`]
    /// does.
    pub(crate) fn grow(&mut self, n: usize, min_step: usize, limit: usize) {
        let w = self.wide.len();
        reserve_within(&mut self.low, n, min_step, limit);
        let blocks = self.low.capacity() / self.stride;
        if blocks * w > self.high.capacity() {
            self.high.reserve_exact(blocks * w - self.high.len());
        }
        self.low.resize(self.low.len() + n, [0; 2]);
        self.high.resize(self.low.len() / self.stride * w, [0; 2]);
    }

    /// Sets entries `at..at + n` (whole blocks) to zero.
    pub(crate) fn zero(&mut self, at: usize, n: usize) {
        self.low[at..at + n].fill([0; 2]);
        let w = self.wide.len();
        let (b0, b1) = (at / self.stride, (at + n) / self.stride);
        self.high[b0 * w..b1 * w].fill([0; 2]);
    }

    /// Appends the blocks of `other` (a pool of the same stride).
    pub(crate) fn append(&mut self, other: Pool) {
        let stride = self.stride;
        let mut values = Vec::with_capacity(stride);
        for block in 0..other.len() / stride {
            values.clear();
            values.extend((0..stride).map(|j| other.get(block * stride + j)));
            let at = self.len();
            self.grow(stride, stride, usize::MAX);
            self.add_rows(at, &values, false);
        }
    }

    /// `pool[at + j] += values[j]` (or `-=` if `negate`) for the entries of one block from its
    /// start `at`, widening a column whose sum leaves 64 bits.
    pub(crate) fn add_rows(&mut self, at: usize, values: &[[i128; 2]], negate: bool) {
        debug_assert!(at.is_multiple_of(self.stride) && values.len() <= self.stride);
        let block = at / self.stride;
        for (j, value) in values.iter().enumerate() {
            let value = if negate {
                [-value[0], -value[1]]
            } else {
                *value
            };
            let h = self.high_index[j];
            if h == NARROW {
                let lo = &mut self.low[at + j];
                let sum = [i128::from(lo[0]) + value[0], i128::from(lo[1]) + value[1]];
                if let (Ok(re), Ok(im)) = (i64::try_from(sum[0]), i64::try_from(sum[1])) {
                    *lo = [re, im];
                    continue;
                }
                self.widen(j);
                self.set(at + j, sum);
            } else {
                let hi = self.high[block * self.wide.len() + h as usize];
                let lo = self.low[at + j];
                self.set(
                    at + j,
                    [join(hi[0], lo[0]) + value[0], join(hi[1], lo[1]) + value[1]],
                );
            }
        }
    }
}

/// Reserves room for `n` more elements of `v`: by an eighth of its length (at least
/// `min_step`) if it is full, so that little of a large array is unused, but no further than
/// `limit` elements when `limit` leaves room for the `n`. (Large arrays are moved by remapping
/// their pages, not by copying them.)
pub(crate) fn reserve_within<T>(v: &mut Vec<T>, n: usize, min_step: usize, limit: usize) {
    let needed = v.len() + n;
    if needed <= v.capacity() {
        return;
    }
    let wanted = needed.max(v.len() + (v.len() / 8).max(min_step));
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
    fn columns_widen_exactly_when_a_sum_leaves_64_bits() {
        let big = i128::from(i64::MAX);
        let mut pool = Pool::new(3);
        pool.grow(6, 3, 6);
        pool.add_rows(0, &[[5, -7], [big, 1], [1, 1]], false);
        pool.add_rows(3, &[[9, 9], [-3, 4]], false);
        assert_eq!(pool.wide_columns(), 0);
        // Column 1 of the first block overflows: only that column widens, in every block.
        pool.add_rows(0, &[[1, 1], [1, 0], [2, 2]], false);
        assert_eq!((pool.wide_columns(), pool.high.len()), (1, 2));
        let all = |pool: &Pool| (0..6).map(|i| pool.get(i)).collect::<Vec<_>>();
        assert_eq!(
            all(&pool),
            [[6, -6], [big + 1, 1], [3, 3], [9, 9], [-3, 4], [0, 0]]
        );
        // Far beyond 64 bits, and back.
        pool.add_rows(3, &[[0, 0], [-(big << 20), big << 20]], false);
        assert_eq!(pool.get(4), [-3 - (big << 20), 4 + (big << 20)]);
        pool.add_rows(3, &[[0, 0], [-(big << 20), big << 20]], true);
        pool.add_rows(0, &[[0, 0], [big + 1, 1]], true);
        assert_eq!(
            all(&pool),
            [[6, -6], [0, 0], [3, 3], [9, 9], [-3, 4], [0, 0]]
        );
        // Subtraction below i64::MIN widens another column; zeroing clears both halves.
        pool.add_rows(0, &[[0, 0], [0, 0], [i128::from(i64::MIN), 0]], false);
        assert_eq!(pool.wide_columns(), 1);
        pool.add_rows(0, &[[0, 0], [0, 0], [10, 0]], true);
        assert_eq!(pool.get(2), [i128::from(i64::MIN) - 7, 3]);
        assert_eq!(pool.wide_columns(), 2);
        pool.zero(0, 3);
        assert_eq!(all(&pool)[..3], [[0, 0]; 3]);
        // Appending converts to this pool's columns.
        let mut other = Pool::new(3);
        other.grow(3, 3, 3);
        other.add_rows(0, &[[1, 2], [3, 4], [5, 6]], false);
        pool.append(other.clone());
        assert_eq!(pool.get(7), [3, 4]);
        // ... and values that fit stay narrow in a narrow pool.
        other.append(pool.clone());
        assert_eq!((other.wide_columns(), other.get(3 + 4)), (0, [-3, 4]));
    }

    #[test]
    fn capacity_grows_by_an_eighth_within_the_limit() {
        let mut v: Vec<u8> = Vec::new();
        reserve_within(&mut v, 1, 4, 10);
        assert_eq!(v.capacity(), 4);
        v.resize(4, 0);
        reserve_within(&mut v, 1, 4, 10);
        assert_eq!(v.capacity(), 8);
        v.resize(8, 0);
        reserve_within(&mut v, 1, 4, 10);
        assert_eq!(v.capacity(), 10);
        let mut v: Vec<u8> = vec![0; 800];
        reserve_within(&mut v, 1, 4, 10_000);
        assert_eq!(v.capacity(), 900);
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
