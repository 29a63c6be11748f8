//! Seeded pseudo-random numbers: SplitMix64 (seeding and hashing) and xoshiro256\*\*
//! (the generator every random draw of chronomap uses: exploration strategies, synthetic
//! workloads).
//!
//! Both are the reference algorithms of Steele, Lea & Flood (SplitMix64) and Blackman &
//! Vigna (xoshiro256\*\*), checked against their published outputs by known-answer tests, so
//! a workload generated from a seed is the same on every platform and every version of the
//! toolchain. Neither is cryptographic.
//!
//! Independent streams (one per grid cell and day, say) come from [`derive_seed`]: a seed,
//! a tag naming the purpose, and two integers are hashed into the seed of a fresh
//! [`Xoshiro256StarStar`], so that a cell's draws on a day depend on nothing else.
#![deny(missing_docs)]

/// The SplitMix64 increment `⌊2^64 / φ⌋`.
const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;

/// The SplitMix64 output function: a bijective 64-bit mixer with good avalanche.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Hashes a seed, a purpose tag and two integers into the seed of an independent stream.
///
/// Every argument changes the result; swapping `a` and `b` changes it too.
#[inline]
pub fn derive_seed(seed: u64, tag: u64, a: u64, b: u64) -> u64 {
    let mut h = mix64(seed.wrapping_add(GOLDEN));
    h = mix64(h ^ mix64(tag.wrapping_add(2u64.wrapping_mul(GOLDEN))));
    h = mix64(h ^ mix64(a.wrapping_add(3u64.wrapping_mul(GOLDEN))));
    mix64(h ^ mix64(b.wrapping_add(4u64.wrapping_mul(GOLDEN))))
}

/// SplitMix64: a 64-bit state advanced by a constant and mixed; used to expand one `u64`
/// seed into the 256-bit state of [`Xoshiro256StarStar`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    /// A generator started from `seed`.
    pub fn new(seed: u64) -> Self {
        SplitMix64 { state: seed }
    }

    /// The next output.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(GOLDEN);
        mix64(self.state)
    }
}

/// xoshiro256\*\*: fast, 256 bits of state, period `2^256 − 1`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Xoshiro256StarStar {
    s: [u64; 4],
}

impl Xoshiro256StarStar {
    /// A generator with the given raw state. The all-zero state (the one fixed point of the
    /// recurrence) is replaced by the state [`seed_from_u64(0)`](Self::seed_from_u64) gives.
    pub fn from_state(s: [u64; 4]) -> Self {
        if s == [0; 4] {
            return Xoshiro256StarStar::seed_from_u64(0);
        }
        Xoshiro256StarStar { s }
    }

    /// A generator whose state is four consecutive outputs of [`SplitMix64::new(seed)`](SplitMix64::new)
    /// (the seeding the algorithm's authors recommend).
    pub fn seed_from_u64(seed: u64) -> Self {
        let mut sm = SplitMix64::new(seed);
        let s = [sm.next_u64(), sm.next_u64(), sm.next_u64(), sm.next_u64()];
        // Four consecutive SplitMix64 outputs are never all zero (mix64 is a bijection of
        // distinct inputs), so `from_state`'s fallback is not needed here.
        Xoshiro256StarStar { s }
    }

    /// The next output.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        let s = &mut self.s;
        let result = s[1].wrapping_mul(5).rotate_left(7).wrapping_mul(9);
        let t = s[1] << 17;
        s[2] ^= s[0];
        s[3] ^= s[1];
        s[1] ^= s[2];
        s[0] ^= s[3];
        s[2] ^= t;
        s[3] = s[3].rotate_left(45);
        result
    }

    /// A uniform number in `[0, 1)` with 53 random bits.
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// A uniform number in `[lo, hi)` (`lo` when `hi <= lo`).
    #[inline]
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        if hi <= lo {
            return lo;
        }
        lo + (hi - lo) * self.next_f64()
    }

    /// A uniform integer in `lo..=hi` (`lo` when `hi <= lo`), by Lemire's widening
    /// multiplication; the bias, at most `(hi − lo + 1) / 2^64`, is negligible here.
    #[inline]
    pub fn int_in(&mut self, lo: u64, hi: u64) -> u64 {
        if hi <= lo {
            return lo;
        }
        let n = (hi - lo).wrapping_add(1);
        if n == 0 {
            return self.next_u64();
        }
        lo + ((u128::from(self.next_u64()) * u128::from(n)) >> 64) as u64
    }

    /// `true` with probability `p` (never for `p <= 0`, always for `p >= 1`).
    #[inline]
    pub fn bernoulli(&mut self, p: f64) -> bool {
        self.next_f64() < p
    }

    /// An exponentially distributed number with mean 1.
    #[inline]
    pub fn exp1(&mut self) -> f64 {
        // 1 − u lies in (0, 1], so the logarithm is finite.
        -(1.0 - self.next_f64()).ln()
    }

    /// A standard normal number (Box–Muller: `sqrt(−2 ln(1 − u)) · cos(2π v)` of two uniform
    /// numbers `u` then `v`).
    #[inline]
    pub fn standard_normal(&mut self) -> f64 {
        // 1 − u lies in (0, 1], so the logarithm is finite.
        let u = 1.0 - self.next_f64();
        let v = self.next_f64();
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }

    /// Shuffles `items` uniformly (Fisher–Yates).
    pub fn shuffle<T>(&mut self, items: &mut [T]) {
        for i in (1..items.len()).rev() {
            let j = self.int_in(0, i as u64) as usize;
            items.swap(i, j);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Published SplitMix64 outputs for seed 1234567.
    #[test]
    fn splitmix64_known_answers() {
        let mut sm = SplitMix64::new(1_234_567);
        let got: Vec<u64> = (0..5).map(|_| sm.next_u64()).collect();
        assert_eq!(
            got,
            [
                6_457_827_717_110_365_317,
                3_203_168_211_198_807_973,
                9_817_491_932_198_370_423,
                4_593_380_528_125_082_431,
                16_408_922_859_458_223_821,
            ]
        );
    }

    /// Outputs of the reference `xoshiro256starstar.c` from the state `[1, 2, 3, 4]`.
    #[test]
    fn xoshiro256starstar_known_answers() {
        let mut rng = Xoshiro256StarStar::from_state([1, 2, 3, 4]);
        let got: Vec<u64> = (0..10).map(|_| rng.next_u64()).collect();
        assert_eq!(
            got,
            [
                11_520,
                0,
                1_509_978_240,
                1_215_971_899_390_074_240,
                1_216_172_134_540_287_360,
                607_988_272_756_665_600,
                16_172_922_978_634_559_625,
                8_476_171_486_693_032_832,
                10_595_114_339_597_558_777,
                2_904_607_092_377_533_576,
            ]
        );
    }

    #[test]
    fn derived_seeds_depend_on_every_argument() {
        let base = derive_seed(1, 2, 3, 4);
        assert_ne!(base, derive_seed(0, 2, 3, 4));
        assert_ne!(base, derive_seed(1, 0, 3, 4));
        assert_ne!(base, derive_seed(1, 2, 0, 4));
        assert_ne!(base, derive_seed(1, 2, 3, 0));
        assert_ne!(base, derive_seed(1, 2, 4, 3));
        assert_eq!(base, derive_seed(1, 2, 3, 4));
    }

    #[test]
    fn draws_stay_in_their_ranges_and_look_uniform() {
        let mut rng = Xoshiro256StarStar::seed_from_u64(7);
        let n = 100_000;
        let mut sum = 0.0;
        let mut exp_sum = 0.0;
        let mut counts = [0u32; 6];
        for _ in 0..n {
            let u = rng.next_f64();
            assert!((0.0..1.0).contains(&u));
            sum += u;
            exp_sum += rng.exp1();
            let k = rng.int_in(1, 6);
            assert!((1..=6).contains(&k));
            counts[(k - 1) as usize] += 1;
        }
        assert!((sum / n as f64 - 0.5).abs() < 0.01);
        assert!((exp_sum / n as f64 - 1.0).abs() < 0.02);
        for c in counts {
            assert!((f64::from(c) / n as f64 - 1.0 / 6.0).abs() < 0.01);
        }
        assert_eq!(rng.uniform(3.0, 3.0), 3.0);
        assert_eq!(rng.int_in(5, 5), 5);
        let mut v: Vec<u32> = (0..50).collect();
        rng.shuffle(&mut v);
        let mut sorted = v.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..50).collect::<Vec<_>>());
        assert_ne!(v, sorted);
    }
}
