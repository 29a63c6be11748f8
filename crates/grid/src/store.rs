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
//! integers while every value fits, widened once, in place, to 128 bits for the whole grid when
//! one would not. A sum of `n` phasors of at most `2^50` units needs `51 + log2 n` bits, so 64
//! bits always suffice for about 8,000 frames; sampled every `Δt`, the prefix of a period `T`
//! stays below about `T / (π Δt)` phasors, but the sums of a cell with a rhythm at a period grow
//! with every frame, so long, dense series widen. All arithmetic is exact in either width, so
//! the width never changes a value.
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

/// Blocks of `stride` exact sums (`[re, im]` pairs): 64-bit integers while every value fits,
/// widened once, for the whole pool and in place, to 128 bits when one would not. Entries are
/// kept as 64-bit words: two an entry while narrow, four (low and high halves) once wide.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "StoredPool")]
pub(crate) struct Pool {
    stride: usize,
    /// Whether entries are 128-bit.
    wide: bool,
    /// `re, im` (narrow) or `re low, re high, im low, im high` (wide) of every entry (signed, so
    /// that small values of either sign take few bytes in a file).
    words: Vec<i64>,
}

/// A [`Pool`] as a grid file holds it.
#[derive(Deserialize)]
struct StoredPool {
    stride: usize,
    wide: bool,
    words: Vec<i64>,
}

impl TryFrom<StoredPool> for Pool {
    type Error = String;

    fn try_from(s: StoredPool) -> Result<Self, String> {
        let pool = Pool {
            stride: s.stride,
            wide: s.wide,
            words: s.words,
        };
        // The stride comes from the file: a product that overflows is no block size at all.
        let block = pool.stride.checked_mul(pool.words_per_entry()).unwrap_or(0);
        if block == 0 || !pool.words.len().is_multiple_of(block) {
            return Err(format!(
                "the pool's {} words are not blocks of {} entries",
                pool.words.len(),
                pool.stride
            ));
        }
        Ok(pool)
    }
}

/// The first entry of a block of a [`Pool`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct BlockAt(usize);

/// The value of low half `lo` and high half `hi`.
#[inline]
fn join(lo: i64, hi: i64) -> i128 {
    (i128::from(hi) << 64) | i128::from(lo as u64)
}

impl Pool {
    /// An empty pool of blocks of `stride` entries.
    pub(crate) fn new(stride: usize) -> Self {
        Pool {
            stride,
            wide: false,
            words: Vec::new(),
        }
    }

    fn words_per_entry(&self) -> usize {
        if self.wide { 4 } else { 2 }
    }

    /// Entries per block.
    pub(crate) fn stride(&self) -> usize {
        self.stride
    }

    /// Number of entries (`stride` a block).
    pub(crate) fn len(&self) -> usize {
        self.words.len() / self.words_per_entry()
    }

    /// Whether the sums are 128-bit.
    pub(crate) fn is_wide(&self) -> bool {
        self.wide
    }

    /// Heap bytes held.
    pub(crate) fn heap_bytes(&self) -> usize {
        self.words.capacity() * 8
    }

    /// Where the block at entry `at` is, to read its entries with [`Pool::entry`].
    #[inline]
    pub(crate) fn block(&self, at: usize) -> BlockAt {
        BlockAt(at)
    }

    /// Entry `j` of a block.
    #[inline]
    pub(crate) fn entry(&self, block: BlockAt, j: usize) -> [i128; 2] {
        self.get(block.0 + j)
    }

    /// Entry `i`.
    #[inline]
    pub(crate) fn get(&self, i: usize) -> [i128; 2] {
        if self.wide {
            let w = &self.words[4 * i..4 * i + 4];
            [join(w[0], w[1]), join(w[2], w[3])]
        } else {
            let w = &self.words[2 * i..2 * i + 2];
            [i128::from(w[0]), i128::from(w[1])]
        }
    }

    /// Makes every entry 128-bit, in place: the words double, moved from the back.
    pub(crate) fn widen(&mut self) {
        if self.wide {
            return;
        }
        let n = self.words.len() / 2;
        let room = self.words.capacity() / 2;
        self.words.reserve_exact(4 * room - self.words.len());
        self.words.resize(4 * n, 0);
        for i in (0..n).rev() {
            let (re, im) = (self.words[2 * i], self.words[2 * i + 1]);
            self.words[4 * i..4 * i + 4].copy_from_slice(&[re, re >> 63, im, im >> 63]);
        }
        self.wide = true;
    }

    /// Appends `n` zero entries (whole blocks), growing the capacity as [`reserve_within`]
    /// does (`min_step` and `limit` in entries).
    pub(crate) fn grow(&mut self, n: usize, min_step: usize, limit: usize) {
        let w = self.words_per_entry();
        reserve_within(
            &mut self.words,
            n * w,
            min_step * w,
            limit.saturating_mul(w),
        );
        self.words.resize(self.words.len() + n * w, 0);
    }

    /// Sets entries `at..at + n` to zero.
    pub(crate) fn zero(&mut self, at: usize, n: usize) {
        let w = self.words_per_entry();
        self.words[at * w..(at + n) * w].fill(0);
    }

    /// Appends the entries of `other`, widening this pool if `other` is wide.
    pub(crate) fn append(&mut self, other: Pool) {
        if other.wide {
            self.widen();
        }
        if self.wide && !other.wide {
            let mut other = other;
            other.widen();
            self.words.extend_from_slice(&other.words);
        } else {
            self.words.extend_from_slice(&other.words);
        }
    }

    /// `pool[at + j] += values[j]` (or `-=` if `negate`), widening the pool if a sum leaves 64
    /// bits.
    pub(crate) fn add_rows(&mut self, at: usize, values: &[[i128; 2]], negate: bool) {
        if negate {
            self.add_signed::<true>(at, values);
        } else {
            self.add_signed::<false>(at, values);
        }
    }

    /// [`Pool::add_rows`] with the sign known when compiled (no multiplication in the loop).
    fn add_signed<const NEGATE: bool>(&mut self, at: usize, values: &[[i128; 2]]) {
        let term = |v: i128| if NEGATE { -v } else { v };
        if self.wide {
            for (w, value) in self.words[4 * at..4 * (at + values.len())]
                .chunks_exact_mut(4)
                .zip(values)
            {
                let re = join(w[0], w[1]) + term(value[0]);
                let im = join(w[2], w[3]) + term(value[1]);
                w.copy_from_slice(&[re as i64, (re >> 64) as i64, im as i64, (im >> 64) as i64]);
            }
            return;
        }
        for (j, value) in values.iter().enumerate() {
            let w = &mut self.words[2 * (at + j)..2 * (at + j) + 2];
            let re = i128::from(w[0]) + term(value[0]);
            let im = i128::from(w[1]) + term(value[1]);
            match (i64::try_from(re), i64::try_from(im)) {
                (Ok(re), Ok(im)) => {
                    w[0] = re;
                    w[1] = im;
                }
                _ => {
                    // Entries before `j` are added; widen and add the rest in 128 bits.
                    self.widen();
                    self.add_signed::<NEGATE>(at + j, &values[j..]);
                    return;
                }
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
    fn pools_widen_in_place_exactly_when_a_sum_leaves_64_bits() {
        let big = i128::from(i64::MAX);
        let mut pool = Pool::new(3);
        pool.grow(6, 3, 6);
        pool.add_rows(0, &[[5, -7], [big, 1], [-1, 1]], false);
        pool.add_rows(3, &[[9, 9], [-3, 4]], false);
        assert!(!pool.is_wide());
        // The second entry overflows: the first was added in 64 bits, the rest in 128.
        pool.add_rows(0, &[[1, 1], [1, 0], [2, 2]], false);
        assert!(pool.is_wide());
        assert_eq!(pool.heap_bytes(), 6 * 4 * 8);
        let all = |pool: &Pool| (0..6).map(|i| pool.get(i)).collect::<Vec<_>>();
        assert_eq!(
            all(&pool),
            [[6, -6], [big + 1, 1], [1, 3], [9, 9], [-3, 4], [0, 0]]
        );
        // Far beyond 64 bits, below, and back.
        pool.add_rows(3, &[[0, 0], [-(big << 20), big << 20]], false);
        assert_eq!(pool.get(4), [-3 - (big << 20), 4 + (big << 20)]);
        pool.add_rows(3, &[[0, 0], [-(big << 20), big << 20]], true);
        pool.add_rows(0, &[[0, 0], [big + 1, 1]], true);
        assert_eq!(
            all(&pool),
            [[6, -6], [0, 0], [1, 3], [9, 9], [-3, 4], [0, 0]]
        );
        pool.zero(0, 3);
        assert_eq!(all(&pool)[..3], [[0, 0]; 3]);
        // Subtraction below i64::MIN widens too.
        let mut narrow = Pool::new(1);
        narrow.grow(2, 1, 2);
        narrow.add_rows(1, &[[i128::from(i64::MIN), -1]], false);
        narrow.add_rows(1, &[[1, 0]], true);
        assert_eq!(
            (narrow.get(0), narrow.get(1)),
            ([0, 0], [i128::from(i64::MIN) - 1, -1])
        );
        // Appending converts to the wider of the two.
        let mut other = Pool::new(3);
        other.grow(3, 3, 3);
        other.add_rows(0, &[[1, 2], [3, 4], [5, 6]], false);
        pool.append(other.clone());
        assert_eq!(pool.get(7), [3, 4]);
        other.append(pool.clone());
        assert!(other.is_wide());
        assert_eq!((other.get(0), other.get(3 + 4)), ([1, 2], [-3, 4]));
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
    fn a_stored_pool_whose_stride_overflows_is_refused() {
        let stored = |stride| StoredPool {
            stride,
            wide: true,
            words: vec![0; 8],
        };
        // 2^62 entries of 4 words: the block size overflows (a panic in a checked build).
        let err = Pool::try_from(stored(1 << 62)).unwrap_err();
        assert_eq!(
            err,
            "the pool's 8 words are not blocks of 4611686018427387904 entries"
        );
        assert_eq!(Pool::try_from(stored(2)).unwrap().len(), 2);
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
