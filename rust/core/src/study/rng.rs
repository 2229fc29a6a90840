//! Counter-based random numbers for Monte Carlo studies (docs/studies.md, "Random numbers").
//!
//! Every number is a pure function of (seed, trial, stream, index), so a trial draws the same
//! numbers on any thread, in any chunk, on any machine of a cluster:
//!
//! - `mix` is the SplitMix64 finalizer (a bijection of u64 with full avalanche);
//! - a stream's key is `mix(mix(mix(seed ^ S) ^ (trial·G + 1)) ^ (stream·H + 1))`;
//! - uniform i of a stream is `((mix(key + (i + 1)·G) >> 11) + 0.5) · 2⁻⁵³ ∈ (0, 1)`;
//! - normals 2j and 2j + 1 are Box-Muller of uniforms 2j and 2j + 1:
//!   `r = sqrt(−2 ln u₂ⱼ)`, `(r cos 2πu₂ⱼ₊₁, r sin 2πu₂ⱼ₊₁)`.
//!
//! `ln` and `sincos_turns` are branch-free polynomial versions (relative error ~1e-16) written so
//! that loops over many values compile to SIMD instructions.

const SEED_SALT: u64 = 0x5EED_5EED_5EED_5EED;
const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;
const STREAM_MUL: u64 = 0xD1B5_4A32_D192_ED03;

/// SplitMix64 finalizer.
#[inline(always)]
pub fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Key of stream `stream` (0: per-trial draws, 1 + p: draws of point p) of trial `trial`.
#[inline(always)]
pub fn stream_key(seed: u64, trial: u64, stream: u64) -> u64 {
    let k = mix(mix(seed ^ SEED_SALT) ^ trial.wrapping_mul(GOLDEN).wrapping_add(1));
    mix(k ^ stream.wrapping_mul(STREAM_MUL).wrapping_add(1))
}

/// Uniform number `i` of the stream with key `key`, strictly inside (0, 1): the top 52 bits m of
/// the mixed counter give (m + ½)·2⁻⁵², built from the bits of 1 + m·2⁻⁵² (no integer-to-float
/// conversion, which AVX2 lacks for 64-bit integers; every step is exact).
#[inline(always)]
pub fn uniform(key: u64, i: u64) -> f64 {
    let m = mix(key.wrapping_add(i.wrapping_add(1).wrapping_mul(GOLDEN))) >> 12;
    (f64::from_bits(0x3FF0_0000_0000_0000 | m) - 1.0) + 1.0 / 9_007_199_254_740_992.0
}

/// Natural logarithm of a positive normal number: x = 2^e · m with m in [√½, √2), then
/// ln m = 2 atanh(s), s = (m − 1)/(m + 1), |s| ≤ 0.1716, by its odd series to s²¹.
#[inline(always)]
pub fn ln(x: f64) -> f64 {
    let bits = x.to_bits();
    // the biased exponent as a float through the bits of 2^52 + e (exact, no int conversion)
    let eb = f64::from_bits(0x4330_0000_0000_0000 | ((bits >> 52) & 0x7ff)) - 4_503_599_627_370_496.0;
    let mut m = f64::from_bits((bits & 0x000F_FFFF_FFFF_FFFF) | 0x3FF0_0000_0000_0000);
    let big = m > std::f64::consts::SQRT_2;
    m = if big { m * 0.5 } else { m };
    let e = eb - 1023.0 + if big { 1.0 } else { 0.0 };
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    // 2 (s + s^3/3 + ... + s^21/21)
    let mut p = 1.0 / 21.0;
    p = p * s2 + 1.0 / 19.0;
    p = p * s2 + 1.0 / 17.0;
    p = p * s2 + 1.0 / 15.0;
    p = p * s2 + 1.0 / 13.0;
    p = p * s2 + 1.0 / 11.0;
    p = p * s2 + 1.0 / 9.0;
    p = p * s2 + 1.0 / 7.0;
    p = p * s2 + 1.0 / 5.0;
    p = p * s2 + 1.0 / 3.0;
    p = p * s2 + 1.0;
    e * std::f64::consts::LN_2 + 2.0 * s * p
}

/// (sin 2πt, cos 2πt) for any finite t (in turns): t is reduced to the nearest quarter turn k/4,
/// the remainder r = 2π(t − k/4) ∈ [−π/4, π/4] goes through Taylor series to r¹⁷ / r¹⁸, and the
/// quadrant k mod 4 rotates the pair. Exact reduction: t − round(4t)/4 has no rounding error.
#[inline(always)]
pub fn sincos_turns(t: f64) -> (f64, f64) {
    let q = (4.0 * t).round();
    let r = (t - 0.25 * q) * std::f64::consts::TAU;
    let r2 = r * r;
    // sin r = r (1 - r²/3! + r⁴/5! - ... + r¹⁶/17!), Horner from the top
    let mut s = 1.0 / 355_687_428_096_000.0; // 1/17!
    s = s * r2 - 1.0 / 1_307_674_368_000.0; // 1/15!
    s = s * r2 + 1.0 / 6_227_020_800.0; // 1/13!
    s = s * r2 - 1.0 / 39_916_800.0; // 1/11!
    s = s * r2 + 1.0 / 362_880.0; // 1/9!
    s = s * r2 - 1.0 / 5_040.0; // 1/7!
    s = s * r2 + 1.0 / 120.0; // 1/5!
    s = s * r2 - 1.0 / 6.0; // 1/3!
    s = s * r2 + 1.0;
    let sin_r = r * s;
    let mut c = 1.0 / 6_402_373_705_728_000.0; // 1/18!
    c = c * r2 - 1.0 / 20_922_789_888_000.0; // 1/16!
    c = c * r2 + 1.0 / 87_178_291_200.0; // 1/14!
    c = c * r2 - 1.0 / 479_001_600.0; // 1/12!
    c = c * r2 + 1.0 / 3_628_800.0; // 1/10!
    c = c * r2 - 1.0 / 40_320.0; // 1/8!
    c = c * r2 + 1.0 / 720.0; // 1/6!
    c = c * r2 - 1.0 / 24.0; // 1/4!
    c = c * r2 + 0.5; // 1/2!
    let cos_r = 1.0 - r2 * c;
    // quadrant k = q mod 4 (q may be negative): rotate (sin, cos) by k quarter turns
    let k = q - 4.0 * (0.25 * q).floor(); // q mod 4 in {0, 1, 2, 3}, in floats (exact)
    let swap = k == 1.0 || k == 3.0;
    let (s0, c0) = if swap { (cos_r, -sin_r) } else { (sin_r, cos_r) };
    let neg = k >= 2.0;
    if neg {
        (-s0, -c0)
    } else {
        (s0, c0)
    }
}

/// Standard normals `2j` and `2j + 1` of the stream `key` (Box-Muller).
#[inline(always)]
pub fn normal_pair(key: u64, j: u64) -> (f64, f64) {
    let u1 = uniform(key, 2 * j);
    let u2 = uniform(key, 2 * j + 1);
    let r = (-2.0 * ln(u1)).sqrt();
    let (s, c) = sincos_turns(u2);
    (r * c, r * s)
}

/// Normal `i` of the stream `key`.
#[inline(always)]
pub fn normal(key: u64, i: u64) -> f64 {
    let (a, b) = normal_pair(key, i / 2);
    if i % 2 == 0 {
        a
    } else {
        b
    }
}

/// Fill `out` with the normal pairs `pairs[k]` of the stream `key`: out[2k], out[2k+1] =
/// normals 2·pairs[k] and 2·pairs[k] + 1. A loop the compiler vectorizes.
#[inline(always)]
pub fn normal_pairs(key: u64, pairs: &[u64], out: &mut [f64]) {
    for (k, &j) in pairs.iter().enumerate() {
        let (a, b) = normal_pair(key, j);
        out[2 * k] = a;
        out[2 * k + 1] = b;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ln_matches_libm() {
        let mut worst = 0.0f64;
        for i in 1..200_000u64 {
            let x = uniform(7, i);
            for y in [x, x * 1e-300, x * 1e300, 1.0 + x * 1e-9] {
                let rel = ((ln(y) - y.ln()) / y.ln().abs().max(1e-300)).abs();
                worst = worst.max(rel);
            }
        }
        assert!(worst < 1e-15, "ln: worst relative error {worst:e}"); // ~2 ulp
        assert_eq!(ln(1.0), 0.0);
    }

    #[test]
    fn sincos_matches_libm() {
        let mut worst = 0.0f64;
        for i in 0..200_000u64 {
            let t = (uniform(11, i) - 0.5) * 20.0;
            let (s, c) = sincos_turns(t);
            let a = t * std::f64::consts::TAU;
            worst = worst.max((s - a.sin()).abs()).max((c - a.cos()).abs());
        }
        // absolute error: the argument 2πt itself carries ~|a|·1e-16
        assert!(worst < 1e-14, "sincos: worst absolute error {worst:e}");
        let (s, c) = sincos_turns(0.25);
        assert_eq!((s, c), (1.0, 0.0));
    }

    #[test]
    fn normals_have_unit_variance_and_no_thread_dependence() {
        let key = stream_key(42, 3, 1);
        let n = 400_000u64;
        let (mut m1, mut m2, mut m4) = (0.0, 0.0, 0.0);
        for i in 0..n {
            let x = normal(key, i);
            m1 += x;
            m2 += x * x;
            m4 += x * x * x * x;
        }
        let (m1, m2, m4) = (m1 / n as f64, m2 / n as f64, m4 / n as f64);
        assert!(m1.abs() < 5.0 / (n as f64).sqrt(), "mean {m1}");
        assert!((m2 - 1.0).abs() < 5.0 * (2.0 / n as f64).sqrt(), "variance {m2}");
        assert!((m4 - 3.0).abs() < 0.05, "fourth moment {m4}");
        // the same draw whatever else was drawn before
        assert_eq!(normal(key, 12345), normal_pair(key, 6172).1);
        assert_ne!(stream_key(42, 3, 1), stream_key(42, 4, 1));
        assert_ne!(stream_key(42, 3, 1), stream_key(43, 3, 1));
    }
}
