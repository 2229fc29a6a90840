//! Statistics of blocks of consecutive revolutions: what order tracking reports per steady-speed
//! segment or per coast-down block from the per-revolution order vectors
//! ([`crate::order::order_vectors`]).
//!
//! For a block of n revolutions r = s .. s + n with order vectors v_r (orders x channels, complex):
//!
//! * the mean vector  v̄ = (1/n) Σ_r v_r, and the block's mean speed and mid time;
//! * the scatter of the first order about its mean, per displacement channel c < 4:
//!   sqrt((1/n) Σ_r |v_r[0, c] - v̄[0, c]|²);
//! * the covariance of the mean of one order (the 1X) by batch means: the first
//!   n_b · ⌊n / n_b⌋ revolutions in n_b = min(n, max_batches) batches (16 by default,
//!   [`MAX_BATCHES`]) of ⌊n / n_b⌋, each batch's mean b_i
//!   written as real vector x_i of 2C values (groups of four channels, [Re, Im] each), and
//!   Cov(v̄) ≈ Σ_i (x_i - x̄)(x_i - x̄)ᵀ / ((n_b - 1) n_b) with n_b - 1 degrees of freedom
//!   (NaN with fewer than two batches). Batches of neighbouring revolutions absorb their
//!   correlation (a slow drift of the response is not white noise).

use crate::error::{expect_len, product, CoreError};
use crate::C64;

/// The most batches a block's covariance is estimated from, by default.
pub const MAX_BATCHES: usize = 16;

/// The per-revolution inputs: order vectors `per_rev` (revs, orders, channels), row-major, and
/// each revolution's speed (rpm) and mid time (s).
pub struct Revolutions<'a> {
    pub per_rev: &'a [C64],
    pub orders: usize,
    pub channels: usize,
    pub rpm: &'a [f64],
    pub t_mid: &'a [f64],
}

/// Outputs per block j (row-major): `mean` (blocks, orders, channels), `cov` (blocks, 2C, 2C),
/// `dof` (blocks), `rpm` and `t_mid` (blocks), `scatter` (blocks, 4).
pub struct BlockOutputs<'a> {
    pub mean: &'a mut [C64],
    pub cov: &'a mut [f64],
    pub dof: &'a mut [f64],
    pub rpm: &'a mut [f64],
    pub t_mid: &'a mut [f64],
    pub scatter: &'a mut [f64],
}

/// Row of channel `c`'s real part in the covariance's 2C-vector (groups of four channels, each
/// group's real parts then its imaginary parts); its imaginary part is `+ width` of its group.
fn re_row(c: usize, channels: usize) -> (usize, usize) {
    let g = c / 4 * 4;
    let width = (channels - g).min(4);
    (2 * g + (c - g), width)
}

/// The statistics of the blocks `starts[j] .. starts[j] + lengths[j]` of `rev` into `out`;
/// `cov_order`: the order index whose mean's covariance is estimated (None: cov and dof NaN), from
/// at most `max_batches` batches ([`MAX_BATCHES`] unless a caller has reason to differ).
/// Errors: lengths that do not fit, fewer than four channels (the scatter's displacement
/// channels), an empty block or one past the last revolution, `cov_order` not an order index,
/// `max_batches` below 2.
pub fn block_statistics(rev: &Revolutions, starts: &[usize], lengths: &[usize], cov_order: Option<usize>, max_batches: usize, out: &mut BlockOutputs) -> Result<(), CoreError> {
    let (no, nc) = (rev.orders, rev.channels);
    if no == 0 {
        return Err(CoreError::value("orders", "must be at least 1"));
    }
    if nc < 4 {
        return Err(CoreError::value("channels", format!("must be at least 4 (the displacement probes), got {nc}")));
    }
    let per = no * nc;
    let revs = rev.rpm.len();
    expect_len("per_rev", rev.per_rev, product("per_rev", &[revs, no, nc])?)?;
    expect_len("t_mid", rev.t_mid, revs)?;
    let nb = starts.len();
    expect_len("lengths", lengths, nb)?;
    if let Some(j) = (0..nb).find(|&j| lengths[j] == 0 || starts[j].checked_add(lengths[j]).is_none_or(|e| e > revs)) {
        return Err(CoreError::value("starts", format!("block {j} ({} revolutions from {}) is empty or ends past the {revs} revolutions", lengths[j], starts[j])));
    }
    if let Some(o) = cov_order.filter(|&o| o >= no) {
        return Err(CoreError::value("cov_order", format!("must be an order index below {no}, got {o}")));
    }
    if max_batches < 2 {
        return Err(CoreError::value("max_batches", format!("must be at least 2 (a covariance needs two batches), got {max_batches}")));
    }
    let m = 2 * nc;
    expect_len("mean", out.mean, product("mean", &[nb, per])?)?;
    expect_len("cov", out.cov, product("cov", &[nb, m, m])?)?;
    expect_len("dof", out.dof, nb)?;
    expect_len("rpm", out.rpm, nb)?;
    expect_len("t_mid", out.t_mid, nb)?;
    expect_len("scatter", out.scatter, product("scatter", &[nb, 4])?)?;
    let mut scratch = vec![0.0; (max_batches.min(revs) + 1) * m];
    for j in 0..nb {
        let (s, n) = (starts[j], lengths[j]);
        let block = &rev.per_rev[s * per..(s + n) * per];
        let mean = &mut out.mean[j * per..(j + 1) * per];
        mean_of_rows(block, per, mean);
        out.rpm[j] = rev.rpm[s..s + n].iter().sum::<f64>() / n as f64;
        out.t_mid[j] = rev.t_mid[s..s + n].iter().sum::<f64>() / n as f64;
        for c in 0..4 {
            let ss: f64 = block.chunks_exact(per).map(|v| (v[c] - mean[c]).norm_sqr()).sum();
            out.scatter[j * 4 + c] = (ss / n as f64).sqrt();
        }
        let cov = &mut out.cov[j * m * m..(j + 1) * m * m];
        out.dof[j] = match cov_order {
            Some(o) if n >= 2 => batch_mean_covariance(block, per, o * nc, nc, max_batches, &mut scratch, cov),
            _ => {
                cov.fill(f64::NAN);
                f64::NAN
            }
        };
    }
    Ok(())
}

/// The mean of the rows (of `width` values) of `rows` into `mean`.
fn mean_of_rows(rows: &[C64], width: usize, mean: &mut [C64]) {
    mean.fill(C64::new(0.0, 0.0));
    for row in rows.chunks_exact(width) {
        for (a, &v) in mean.iter_mut().zip(row) {
            *a += v;
        }
    }
    let inv = 1.0 / (rows.len() / width) as f64;
    for a in mean.iter_mut() {
        *a *= inv;
    }
}

/// The batch-means covariance (module doc) of the values at `offset .. offset + nc` of each row
/// of `block` (n >= 2 rows of `width`) into `cov` (2nc x 2nc); returns its dof n_b - 1.
/// `scratch`: at least (min(n, max_batches) + 1) * 2nc values.
fn batch_mean_covariance(block: &[C64], width: usize, offset: usize, nc: usize, max_batches: usize, scratch: &mut [f64], cov: &mut [f64]) -> f64 {
    let n = block.len() / width;
    let nb = n.min(max_batches);
    let size = n / nb;
    let m = 2 * nc;
    let (xbar, x) = scratch.split_at_mut(m);
    let x = &mut x[..nb * m];
    for (i, xi) in x.chunks_exact_mut(m).enumerate() {
        let rows = &block[i * size * width..(i + 1) * size * width];
        for c in 0..nc {
            let sum: C64 = rows.chunks_exact(width).map(|v| v[offset + c]).sum();
            let b = sum / size as f64;
            let (re, w) = re_row(c, nc);
            xi[re] = b.re;
            xi[re + w] = b.im;
        }
    }
    // two passes: the deviations from the batches' mean, then their products
    xbar.fill(0.0);
    for xi in x.chunks_exact(m) {
        for (a, &v) in xbar.iter_mut().zip(xi) {
            *a += v;
        }
    }
    for a in xbar.iter_mut() {
        *a /= nb as f64;
    }
    for xi in x.chunks_exact_mut(m) {
        for (v, &b) in xi.iter_mut().zip(xbar.iter()) {
            *v -= b;
        }
    }
    let scale = 1.0 / ((nb - 1) * nb) as f64;
    for a in 0..m {
        for b in a..m {
            let s: f64 = x.chunks_exact(m).map(|d| d[a] * d[b]).sum();
            cov[a * m + b] = s * scale;
            cov[b * m + a] = s * scale;
        }
    }
    (nb - 1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pseudo-random values in [-1, 1) (a fixed LCG: the tests need no crate).
    fn noise(seed: u64, n: usize) -> Vec<f64> {
        let mut s = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (0..n)
            .map(|_| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 52) as f64 - 1.0
            })
            .collect()
    }

    struct Case {
        per_rev: Vec<C64>,
        rpm: Vec<f64>,
        t_mid: Vec<f64>,
        orders: usize,
        channels: usize,
    }

    fn case(revs: usize, orders: usize, channels: usize, seed: u64) -> Case {
        let v = noise(seed, 2 * revs * orders * channels);
        let per_rev = v.chunks_exact(2).map(|p| C64::new(p[0], p[1])).collect();
        let rpm = noise(seed + 1, revs).iter().map(|x| 3000.0 + 100.0 * x).collect();
        let t_mid = (0..revs).map(|r| 0.02 * r as f64 + 0.01).collect();
        Case { per_rev, rpm, t_mid, orders, channels }
    }

    #[derive(Debug)]
    struct Out {
        mean: Vec<C64>,
        cov: Vec<f64>,
        dof: Vec<f64>,
        rpm: Vec<f64>,
        t_mid: Vec<f64>,
        scatter: Vec<f64>,
    }

    fn run(c: &Case, starts: &[usize], lengths: &[usize], cov_order: Option<usize>) -> Result<Out, CoreError> {
        run_with(c, starts, lengths, cov_order, MAX_BATCHES)
    }

    fn run_with(c: &Case, starts: &[usize], lengths: &[usize], cov_order: Option<usize>, max_batches: usize) -> Result<Out, CoreError> {
        let nb = starts.len();
        let m = 2 * c.channels;
        let mut o = Out {
            mean: vec![C64::new(0.0, 0.0); nb * c.orders * c.channels],
            cov: vec![0.0; nb * m * m],
            dof: vec![0.0; nb],
            rpm: vec![0.0; nb],
            t_mid: vec![0.0; nb],
            scatter: vec![0.0; nb * 4],
        };
        let rev = Revolutions { per_rev: &c.per_rev, orders: c.orders, channels: c.channels, rpm: &c.rpm, t_mid: &c.t_mid };
        let mut out = BlockOutputs { mean: &mut o.mean, cov: &mut o.cov, dof: &mut o.dof, rpm: &mut o.rpm, t_mid: &mut o.t_mid, scatter: &mut o.scatter };
        block_statistics(&rev, starts, lengths, cov_order, max_batches, &mut out).map(|_| o)
    }

    /// The reference: each statistic from its definition, one value at a time, the covariance's
    /// real vector laid out by an explicit table ([Re 0-3, Im 0-3, Re 4-7, Im 4-7] for 8 channels).
    fn reference(c: &Case, s: usize, n: usize, cov_order: usize, max_batches: usize) -> (Vec<C64>, Vec<f64>, f64, f64, [f64; 4]) {
        let (no, nc) = (c.orders, c.channels);
        let at = |r: usize, o: usize, ch: usize| c.per_rev[(r * no + o) * nc + ch];
        let mut mean = vec![C64::new(0.0, 0.0); no * nc];
        for o in 0..no {
            for ch in 0..nc {
                mean[o * nc + ch] = (s..s + n).map(|r| at(r, o, ch)).sum::<C64>() / n as f64;
            }
        }
        let rpm = (s..s + n).map(|r| c.rpm[r]).sum::<f64>() / n as f64;
        let mut scatter = [0.0; 4];
        for (ch, sc) in scatter.iter_mut().enumerate() {
            *sc = ((s..s + n).map(|r| (at(r, 0, ch) - mean[ch]).norm_sqr()).sum::<f64>() / n as f64).sqrt();
        }
        let layout: Vec<(usize, bool)> = match nc {
            4 => (0..4).map(|ch| (ch, false)).chain((0..4).map(|ch| (ch, true))).collect(),
            8 => [(0..4, false), (0..4, true), (4..8, false), (4..8, true)]
                .into_iter()
                .flat_map(|(r, im)| r.map(move |ch| (ch, im)))
                .collect(),
            _ => unreachable!(),
        };
        let nb = n.min(max_batches);
        let size = n / nb;
        let x: Vec<Vec<f64>> = (0..nb)
            .map(|i| {
                layout
                    .iter()
                    .map(|&(ch, im)| {
                        let b = (0..size).map(|k| at(s + i * size + k, cov_order, ch)).sum::<C64>() / size as f64;
                        if im { b.im } else { b.re }
                    })
                    .collect()
            })
            .collect();
        let m = 2 * nc;
        let xbar: Vec<f64> = (0..m).map(|a| x.iter().map(|xi| xi[a]).sum::<f64>() / nb as f64).collect();
        let mut cov = vec![0.0; m * m];
        for a in 0..m {
            for b in 0..m {
                cov[a * m + b] = x.iter().map(|xi| (xi[a] - xbar[a]) * (xi[b] - xbar[b])).sum::<f64>() / ((nb - 1) * nb) as f64;
            }
        }
        (mean, cov, (nb - 1) as f64, rpm, scatter)
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-13 * (1.0 + b.abs())
    }

    #[test]
    fn blocks_match_the_definitions() {
        // block lengths below, at and above 16 (one batch per revolution, then batches of
        // several, with revolutions left over), and overlapping, out-of-order blocks
        // (and fewer batches than the default)
        for &(nc, no, mb) in &[(4usize, 1usize, MAX_BATCHES), (4, 3, MAX_BATCHES), (8, 2, MAX_BATCHES), (8, 2, 5)] {
            let c = case(200, no, nc, 7 + nc as u64);
            let starts = [0, 3, 40, 100, 17, 150];
            let lengths = [2, 16, 37, 64, 1, 50];
            for cov_order in [0, no - 1] {
                let o = run_with(&c, &starts, &lengths, Some(cov_order), mb).unwrap();
                let m = 2 * nc;
                for j in 0..starts.len() {
                    let (mean, cov, dof, rpm, scatter) = reference(&c, starts[j], lengths[j], cov_order, mb);
                    let per = no * nc;
                    for (a, b) in o.mean[j * per..(j + 1) * per].iter().zip(&mean) {
                        assert!(close(a.re, b.re) && close(a.im, b.im), "mean of block {j}");
                    }
                    assert!(close(o.rpm[j], rpm));
                    assert!(close(o.t_mid[j], 0.02 * (starts[j] as f64 + (lengths[j] - 1) as f64 / 2.0) + 0.01));
                    for ch in 0..4 {
                        assert!(close(o.scatter[j * 4 + ch], scatter[ch]), "scatter of block {j}, channel {ch}");
                    }
                    if lengths[j] == 1 {
                        assert!(o.dof[j].is_nan() && o.cov[j * m * m..(j + 1) * m * m].iter().all(|v| v.is_nan()));
                        continue;
                    }
                    assert_eq!(o.dof[j], dof);
                    for (i, (a, b)) in o.cov[j * m * m..(j + 1) * m * m].iter().zip(&cov).enumerate() {
                        assert!((a - b).abs() <= 1e-13 * cov[0].abs().max(1e-300), "cov[{i}] of block {j}: {a} vs {b}");
                    }
                }
            }
        }
    }

    #[test]
    fn no_covariance_order_gives_nan() {
        let c = case(20, 2, 4, 3);
        let o = run(&c, &[0, 10], &[10, 10], None).unwrap();
        assert!(o.cov.iter().all(|v| v.is_nan()) && o.dof.iter().all(|v| v.is_nan()));
        assert!(o.mean.iter().all(|v| v.re.is_finite()));
    }

    #[test]
    fn alternating_batches_give_the_known_covariance() {
        // 48 revolutions in 16 batches of 3; batch i has channel 6's imaginary part at +-d about
        // a constant, so the batch-mean covariance is d^2 / 15 at that channel's row alone (row
        // 14 of the 16 of 8 channels: the second group's real parts are rows 8-11, its imaginary
        // parts rows 12-15), with 15 dof
        let d = 0.25;
        let mut c = case(48, 2, 8, 5);
        let first: Vec<C64> = c.per_rev[..16].to_vec();
        for (r, v) in c.per_rev.chunks_exact_mut(16).enumerate() {
            v.copy_from_slice(&first);
            v[8 + 6].im += if (r / 3) % 2 == 0 { d } else { -d };
        }
        let o = run(&c, &[0], &[48], Some(1)).unwrap();
        assert_eq!(o.dof[0], 15.0);
        for a in 0..16 {
            for b in 0..16 {
                let want = if a == 14 && b == 14 { d * d / 15.0 } else { 0.0 };
                assert!((o.cov[a * 16 + b] - want).abs() < 1e-15, "cov[{a}, {b}] = {}", o.cov[a * 16 + b]);
            }
        }
        // order 0 does not vary: no scatter
        assert!(o.scatter.iter().all(|&v| v < 1e-15));
    }

    #[test]
    fn bad_arguments_are_errors() {
        let c = case(10, 2, 4, 1);
        let err = |starts: &[usize], lengths: &[usize], o: Option<usize>| run(&c, starts, lengths, o).unwrap_err().name();
        assert_eq!(err(&[8], &[3], Some(0)), "starts"); // past the end
        assert_eq!(err(&[0], &[0], Some(0)), "starts"); // empty
        assert_eq!(err(&[usize::MAX], &[2], Some(0)), "starts"); // overflow
        assert_eq!(err(&[0, 1], &[2], Some(0)), "lengths");
        assert_eq!(err(&[0], &[2], Some(2)), "cov_order");
        assert_eq!(run_with(&c, &[0], &[2], Some(0), 1).unwrap_err().name(), "max_batches");
        let short = Case { per_rev: c.per_rev[..40].to_vec(), rpm: c.rpm[..5].to_vec(), t_mid: c.t_mid[..5].to_vec(), orders: 2, channels: 4 };
        assert_eq!(run(&short, &[0], &[2], None).map(|_| ()), Ok(()));
        let bad = Case { per_rev: c.per_rev[..39].to_vec(), ..short };
        assert_eq!(run(&bad, &[0], &[2], None).unwrap_err().name(), "per_rev");
        let three = Case { per_rev: vec![C64::new(0.0, 0.0); 30], rpm: vec![1.0; 10], t_mid: vec![0.0; 10], orders: 1, channels: 3 };
        assert_eq!(run(&three, &[0], &[2], None).unwrap_err().name(), "channels");
    }
}
