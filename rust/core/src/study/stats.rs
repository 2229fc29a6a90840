//! Streaming statistics of coefficient errors (docs/studies.md, "Statistics").
//!
//! Per point and coefficient: counts of finite and non-finite errors, the sum and sum of squares
//! of the finite ones, and a log-linear histogram of the error (as HDR histograms): with
//! x = |e| / E0 (E0 = 2⁻²⁰ ≈ 9.5e-7), x < 1 falls in 16 linear bins of width 1/16, and each
//! octave 2^E ≤ x < 2^(E+1) (E = 0..29) in 16 bins of width 2^E/16, read straight from the
//! exponent and the top four mantissa bits of x (no logarithm). Each sign has 496 bins; the
//! histogram has BINS = 1024 with the centre at 512 (e ≥ 0 above, e < 0 below) and the
//! end bins catching |e| ≥ 2³⁰ E0 ≈ 1024. A bin is at most 6.25 % of its value wide
//! (|e| ≥ E0), or E0/16 ≈ 6e-8 (|e| < E0). Counts are integers: merging the statistics of
//! different trials is exact and does not depend on the order.

use super::NCOEF;

/// Bins of each histogram.
pub const BINS: usize = 1024;
/// Scale of the histogram: errors below E0 are binned linearly, above by octaves.
pub const E0: f64 = 1.0 / 1_048_576.0;
/// Sub-bins per octave (and linear bins below E0).
pub const SUB: usize = 16;
/// Octaves above E0 before the end bins.
pub const OCTAVES: usize = 30;

/// Statistics of the points of one call, (points, 16[, BINS]) row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct StudyStats {
    pub points: usize,
    pub counts: Vec<u32>,
    pub finite: Vec<u32>,
    pub nonfinite: Vec<u32>,
    pub sum: Vec<f64>,
    pub sumsq: Vec<f64>,
}

impl StudyStats {
    pub fn new(points: usize) -> Self {
        let m = points * NCOEF;
        StudyStats { points, counts: vec![0; m * BINS], finite: vec![0; m], nonfinite: vec![0; m], sum: vec![0.0; m], sumsq: vec![0.0; m] }
    }
}

/// Magnitude index of x = |e| / E0 >= 0: floor(16 x) below 1, 16 + 16 E + t above (E the
/// octave, t the top four mantissa bits), clamped to the last bin of the side (BINS/2 - 1).
#[inline(always)]
fn magnitude_index(x: f64) -> u32 {
    let bits = x.to_bits();
    let expo = ((bits >> 52) & 0x7ff) as i64 - 1023; // floor(log2 x) for normal x >= 1
    let top = ((bits >> 48) & 0xf) as i64;
    let lin = (x * SUB as f64).min(SUB as f64) as i64; // used when x < 1
    let log = SUB as i64 + SUB as i64 * expo + top;
    let m = if x < 1.0 { lin } else { log };
    m.min((BINS / 2 - 1) as i64) as u32
}

/// Bin of the error `e` (any value; NaN lands in some bin and must not be counted).
#[inline(always)]
pub fn bin(e: f64) -> u32 {
    let m = magnitude_index(e.abs() * (1.0 / E0));
    let half = (BINS / 2) as u32;
    if e < 0.0 {
        half - 1 - m
    } else {
        half + m
    }
}

/// The value range [lo, hi) of bin `b` (the end bins reach to ±inf).
pub fn bin_edges(b: usize) -> (f64, f64) {
    let half = BINS / 2;
    let (m, neg) = if b >= half { (b - half, false) } else { (half - 1 - b, true) };
    let (lo, hi) = if m < SUB {
        (m as f64 / SUB as f64, (m + 1) as f64 / SUB as f64)
    } else {
        let (oct, t) = ((m - SUB) / SUB, (m - SUB) % SUB);
        let base = (2.0f64).powi(oct as i32);
        (base * (1.0 + t as f64 / SUB as f64), base * (1.0 + (t + 1) as f64 / SUB as f64))
    };
    let hi = if m == half - 1 { f64::INFINITY } else { hi * E0 };
    let lo = lo * E0;
    if neg {
        (-hi, -lo)
    } else {
        (lo, hi)
    }
}

/// Percentiles of histograms: `counts` holds `rows` histograms of [`BINS`] bins one after the
/// other, `out` receives (percentiles.len(), rows) row-major. For percentile q of a histogram with
/// total count N and cumulative counts C_b, the value lies in the first bin b with C_b >=
/// max(q N / 100, 1e-9), at the fraction f = clamp((q N / 100 - C_(b-1)) / max(n_b, 1), 0, 1)
/// of the bin: lo_b + f (hi_b - lo_b), with lo_b, hi_b the bin's edges (the two end bins, open
/// on one side, both edges at their finite one). NaN for an empty histogram. One pass over the
/// counts per histogram, a binary search per percentile.
pub fn percentiles_of_counts<T: Copy + Into<u64>>(counts: &[T], percentiles: &[f64], out: &mut [f64]) -> Result<(), crate::error::CoreError> {
    use crate::error::{expect_len, CoreError};
    if !counts.len().is_multiple_of(BINS) {
        return Err(CoreError::length("counts", counts.len(), format!("a multiple of {BINS} (histograms of {BINS} bins)")));
    }
    let rows = counts.len() / BINS;
    expect_len("out", out, rows * percentiles.len())?;
    if let Some(q) = percentiles.iter().find(|q| !(0.0..=100.0).contains(*q)) {
        return Err(CoreError::value("percentiles", format!("must be between 0 and 100, got {q}")));
    }
    // lower edge of every bin; the upper edge is the next bin's lower edge (+inf for the last)
    let mut lo: [f64; BINS] = std::array::from_fn(|b| bin_edges(b).0);
    let mut hi = [0.0f64; BINS];
    hi[..BINS - 1].copy_from_slice(&lo[1..]);
    lo[0] = hi[0];
    hi[BINS - 1] = lo[BINS - 1];
    let mut cum = vec![0u64; BINS];
    for (r, h) in counts.chunks_exact(BINS).enumerate() {
        let mut c = 0u64;
        for (dst, &v) in cum.iter_mut().zip(h) {
            c += v.into();
            *dst = c;
        }
        let total = c as f64;
        for (i, &q) in percentiles.iter().enumerate() {
            let target = q / 100.0 * total;
            let thr = target.max(1e-9);
            let b = cum.partition_point(|&c| (c as f64) < thr);
            let b = if b == BINS { 0 } else { b };
            let before = if b > 0 { cum[b - 1] as f64 } else { 0.0 };
            let inbin = h[b].into().max(1) as f64;
            let frac = ((target - before) / inbin).clamp(0.0, 1.0);
            out[i * rows + r] = if c > 0 { lo[b] + frac * (hi[b] - lo[b]) } else { f64::NAN };
        }
    }
    Ok(())
}

/// Add the errors of one trial at a block of points: `errs` and their `bins` (points * 16),
/// counts (points * 16 histograms, `stride` apart) and the per-coefficient sums.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn add_block(errs: &[f64], bins: &[u32], counts: &mut [u32], stride: usize, finite: &mut [u32], nonfinite: &mut [u32], sum: &mut [f64], sumsq: &mut [f64]) {
    for (j, (&e, &b)) in errs.iter().zip(bins).enumerate() {
        if e.is_finite() {
            counts[j * stride + b as usize] += 1;
            finite[j] += 1;
            sum[j] += e;
            sumsq[j] += e * e;
        } else {
            nonfinite[j] += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_interpolate_inside_the_bin_of_the_rank() {
        // 10 counts in bin 600 and 30 in bin 700: the median (target 20) is a third into bin 700,
        // percentile 0 the start of bin 600's values, 100 the end of bin 700
        let mut h = vec![0u32; 2 * BINS];
        h[600] = 10;
        h[700] = 30;
        let mut out = vec![0.0; 6];
        percentiles_of_counts(&h, &[0.0, 50.0, 100.0], &mut out).unwrap();
        let (lo7, hi7) = (bin_edges(700).0, bin_edges(701).0);
        assert_eq!(out[0], bin_edges(600).0);
        assert_eq!(out[2], lo7 + (10.0 / 30.0) * (hi7 - lo7));
        assert_eq!(out[4], hi7);
        // the second histogram is empty
        assert!(out[1].is_nan() && out[3].is_nan() && out[5].is_nan());
        assert!(percentiles_of_counts(&h[..BINS - 1], &[50.0], &mut out[..0]).is_err());
        assert!(percentiles_of_counts(&h, &[50.0], &mut out[..1]).is_err());
        assert!(percentiles_of_counts(&h, &[f64::NAN], &mut out[..2]).is_err());
        assert!(percentiles_of_counts(&h, &[100.5], &mut out[..2]).is_err());
    }

    #[test]
    fn every_error_falls_in_the_bin_whose_edges_enclose_it() {
        let mut last = 0;
        for i in -4000..=4000 {
            let e = (i as f64 / 100.0).sinh() * E0;
            let b = bin(e) as usize;
            assert!(b >= last && b < BINS);
            last = b;
            let (lo, hi) = bin_edges(b);
            assert!(lo <= e && e < hi || (e < 0.0 && lo < e && e <= hi), "{e} not in bin {b} = [{lo}, {hi})");
        }
        assert_eq!(bin(0.0) as usize, BINS / 2);
        assert_eq!(bin(1e300) as usize, BINS - 1);
        assert_eq!(bin(-1e300), 0);
        assert_eq!(bin(1e-3) + bin(-1e-3), BINS as u32 - 1);
        // widths: 6.25 % of the value at most above E0
        for b in BINS / 2 + SUB..BINS - 1 {
            let (lo, hi) = bin_edges(b);
            assert!((hi - lo) / lo <= 1.0 / SUB as f64 + 1e-12);
        }
        // the bins tile the line without gaps
        for b in 0..BINS - 1 {
            assert_eq!(bin_edges(b).1, bin_edges(b + 1).0, "gap after bin {b}");
        }
    }
}
