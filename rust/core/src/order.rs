//! Keyphasor-referenced order processing: resampling at uniform rotor angles and the report's
//! time-domain run-out filter (subtract the synchronous revolution signature).
//!
//! The rotor angle is taken as linear in time between consecutive keyphasor pulses (times `kp`,
//! seconds, strictly increasing): angle = 2 pi (k + (t - kp[k]) / (kp[k+1] - kp[k])). Resampling
//! each revolution separately follows small speed drift, so a signature does not smear.

use crate::error::{expect_len, product, CoreError};
use crate::model::C64;

/// Keyphasor times must bound at least one revolution and increase strictly.
pub fn check_keyphasor(kp: &[f64]) -> Result<(), CoreError> {
    if kp.len() < 2 {
        return Err(CoreError::value("kp", "needs at least two keyphasor times (one whole revolution)"));
    }
    if kp.iter().any(|v| !v.is_finite()) || kp.windows(2).any(|w| !(w[1] > w[0])) {
        return Err(CoreError::value("kp", "(keyphasor times) must be finite and strictly increasing"));
    }
    Ok(())
}

fn check_sampling(fs: f64, t0: f64) -> Result<(), CoreError> {
    if !(fs > 0.0 && fs.is_finite()) {
        return Err(CoreError::value("fs", format!("(sample rate) must be positive and finite, got {fs}")));
    }
    if !t0.is_finite() {
        return Err(CoreError::value("t0", "(time of the first sample) must be finite"));
    }
    Ok(())
}

/// Weights of the 4-point Lagrange (cubic) stencil at samples -1, 0, 1, 2 for a fraction f in [0, 1).
#[inline(always)]
pub fn lagrange4(f: f64) -> [f64; 4] {
    [
        -f * (f - 1.0) * (f - 2.0) * (1.0 / 6.0),
        (f + 1.0) * (f - 1.0) * (f - 2.0) * 0.5,
        -(f + 1.0) * f * (f - 2.0) * 0.5,
        (f + 1.0) * f * (f - 1.0) * (1.0 / 6.0),
    ]
}

/// 4-point Lagrange (cubic) interpolation of uniformly sampled `x` at fractional index `u`.
#[inline(always)]
pub fn cubic_at(x: &[f64], u: f64) -> f64 {
    let n = x.len();
    if n == 0 {
        return f64::NAN;
    }
    let m = u.floor();
    let f = u - m;
    let m = m as isize;
    let at = |i: isize| -> f64 { x[i.clamp(0, n as isize - 1) as usize] };
    let w = lagrange4(f);
    // (saturating: a point far outside the samples puts m near the ends of isize)
    w[0] * at(m.saturating_sub(1)) + w[1] * at(m) + w[2] * at(m.saturating_add(1)) + w[3] * at(m.saturating_add(2))
}

/// Resample channels at P uniform angles per revolution for revolutions k0..k1 (between pulses
/// kp[k] and kp[k+1]). `x`: (C, N) row-major, sample i at time t0 + i / fs. `out`: (C, k1-k0, P).
#[allow(clippy::too_many_arguments)]
pub fn angle_resample(x: &[f64], nch: usize, fs: f64, t0: f64, kp: &[f64], k0: usize, k1: usize, p: usize, out: &mut [f64]) -> Result<(), CoreError> {
    if nch == 0 || x.len() % nch != 0 {
        return Err(CoreError::length("x", x.len(), format!("a multiple of the channel count {nch} (at least one channel)")));
    }
    let n = x.len() / nch;
    let channels: Vec<&[f64]> = (0..nch).map(|c| &x[c * n..(c + 1) * n]).collect();
    angle_resample_channels(&channels, fs, t0, kp, k0, k1, p, out)
}

/// The checks shared by the per-revolution functions: keyphasor times, sampling, at least one
/// channel and all of one length, revolutions k0..k1 inside the pulses, at least 4 points per
/// revolution.
fn check_revolutions(x: &[&[f64]], fs: f64, t0: f64, kp: &[f64], k0: usize, k1: usize, p: usize) -> Result<(), CoreError> {
    check_keyphasor(kp)?;
    check_sampling(fs, t0)?;
    let nch = x.len();
    if nch == 0 {
        return Err(CoreError::value("x", "needs at least one channel"));
    }
    if let Some(c) = x.iter().position(|ch| ch.len() != x[0].len()) {
        return Err(CoreError::length("x", x[c].len(), format!("{} samples in every channel (channel {c} differs)", x[0].len())));
    }
    if !(k0 < k1 && k1 < kp.len()) {
        return Err(CoreError::value("k0, k1", format!("need k0 < k1 < len(kp) = {}, got k0 = {k0}, k1 = {k1}", kp.len())));
    }
    if p < 4 {
        return Err(CoreError::value("p", format!("(points per revolution) must be at least 4, got {p}")));
    }
    Ok(())
}

/// [`angle_resample`] of channels stored apart (as a recording's loaders give them: no (C, N)
/// array is built to resample them), each of the same length.
#[allow(clippy::too_many_arguments)]
pub fn angle_resample_channels(x: &[&[f64]], fs: f64, t0: f64, kp: &[f64], k0: usize, k1: usize, p: usize, out: &mut [f64]) -> Result<(), CoreError> {
    check_revolutions(x, fs, t0, kp, k0, k1, p)?;
    expect_len("out", out, product("out", &[x.len(), k1 - k0, p])?)?;
    resample_kernel(x, fs, t0, kp, k0, k1, p, out);
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn resample_kernel(x: &[&[f64]], fs: f64, t0: f64, kp: &[f64], k0: usize, k1: usize, p: usize, out: &mut [f64]) {
    let revs = k1 - k0;
    let out = crate::par::Disjoint::new(out);
    // one task per channel, shared with the calling thread (crate::par)
    crate::par::for_each_task(x.len(), |c| {
        // SAFETY: for_each_task hands each channel c to one task
        let o = unsafe { out.chunk(c, revs * p) };
        let xc = x[c];
        for r in 0..revs {
            let (ta, tb) = (kp[k0 + r], kp[k0 + r + 1]);
            for j in 0..p {
                let t = ta + (tb - ta) * (j as f64) / (p as f64);
                o[r * p + j] = cubic_at(xc, (t - t0) * fs);
            }
        }
    });
}

/// Per-revolution order vectors of channels resampled at `p` uniform angles per revolution
/// (revolutions k0..k1 between pulses `kp[k]`, `kp[k+1]`; each channel of the same length, sample
/// i at t0 + i / fs), each revolution's drift ramp removed. `out`: complex (k1 - k0, n_orders, C),
/// 0-pk amplitudes.
///
/// For revolution r with resampled values x_j (j = 0..p, angle 2 pi j / p from the pulse) and
/// mean m_r, order n's vector is
///
/// ```text
/// X_r(n) = (2 / p) [ sum_j (x_j - m_r) e^{-2 pi i n j / p} - s_r sum_j (j / p - 1/2) e^{-2 pi i n j / p} ]
/// ```
///
/// (the bin n of `rfft(x - s_r ramp) * 2 / p`), where s_r, the change of the revolution means per
/// revolution (central differences, one-sided at the first and last revolution, 0 for a single
/// revolution), is the slope of a slow drift that does not close on itself over a revolution
/// and would otherwise leak into every order. Only the requested orders are summed, against a
/// table of cosines and sines whose angles are reduced exactly (n j mod p). Each revolution is
/// summed about its mean, so an offset that dwarfs the vibration (a probe's gap voltage) does not
/// enter the bins' rounding (the cosines and sines sum to zero over a revolution; their rounded
/// values do not, and a direct sum would carry offset x p^1.5 eps); the means themselves carry
/// the offset's rounding, ~1e-16 of it, as the FFT's do. Resampling and sums are fused: a
/// revolution's stencil weights are computed once for every channel and the resampled values
/// never leave the cache. NaN or inf samples give NaN for the revolutions they touch (and,
/// through s_r, their neighbours).
#[allow(clippy::too_many_arguments)]
pub fn order_vectors(x: &[&[f64]], fs: f64, t0: f64, kp: &[f64], k0: usize, k1: usize, p: usize, orders: &[usize], out: &mut [C64]) -> Result<(), CoreError> {
    check_revolutions(x, fs, t0, kp, k0, k1, p)?;
    let nch = x.len();
    if x[0].is_empty() {
        return Err(CoreError::value("x", "has no samples"));
    }
    if orders.is_empty() {
        return Err(CoreError::value("orders", "needs at least one order"));
    }
    if let Some(&n) = orders.iter().find(|&&n| n == 0 || n.saturating_mul(2) >= p) {
        return Err(CoreError::value("orders", format!("must be from 1 to below p/2 = {} (p = {p} points per revolution), got {n}", p as f64 / 2.0)));
    }
    let revs = k1 - k0;
    let nord = orders.len();
    expect_len("out", out, product("out", &[revs, nord, nch])?)?;
    let table = OrderTable::new(p, orders);
    // the order sums go to `out` as they are taken (revolution, order, channel); the revolution
    // means (revolution, channel) are all the memory the drift slopes need besides
    let mut means = vec![0.0; revs * nch];
    let nblocks = revs.div_ceil(REV_BLOCK);
    {
        let ctx = OrderCtx { x, fs, t0, kp, k0, table: &table };
        let (mb, ob) = (crate::par::Disjoint::new(&mut means), crate::par::Disjoint::new(out));
        crate::par::for_each_task(nblocks, |b| {
            // SAFETY: for_each_task hands each block b to one task
            let (m, o) = unsafe { (mb.chunk(b, REV_BLOCK * nch), ob.chunk(b, REV_BLOCK * nord * nch)) };
            order_block_dispatch(&ctx, b * REV_BLOCK, m, o);
        });
    }
    let scale = 2.0 / p as f64;
    for r in 0..revs {
        for c in 0..nch {
            let m = |r: usize| means[r * nch + c];
            let slope = if revs == 1 {
                0.0
            } else if r == 0 {
                m(1) - m(0)
            } else if r == revs - 1 {
                m(r) - m(r - 1)
            } else {
                (m(r + 1) - m(r - 1)) * 0.5
            };
            for i in 0..nord {
                let o = &mut out[(r * nord + i) * nch + c];
                let re = o.re - slope * table.ramp[i];
                let im = o.im - slope * table.ramp[nord + i];
                *o = C64::new(re * scale, im * scale);
            }
        }
    }
    Ok(())
}

/// Revolutions per task of [`order_vectors`].
const REV_BLOCK: usize = 32;

/// The rows the order sums are taken against: for each order n its cosines cos(2 pi n j / p),
/// then for each order its sines -sin(2 pi n j / p) (the sign of a forward DFT), each row padded
/// with zeros to a multiple of 8 points; and each row's sum against the ramp j / p - 1/2.
struct OrderTable {
    p: usize,
    /// row length: p rounded up to a multiple of 8
    row: usize,
    rows: Vec<f64>,
    ramp: Vec<f64>,
}

impl OrderTable {
    fn new(p: usize, orders: &[usize]) -> Self {
        let row = p.div_ceil(8) * 8;
        let nord = orders.len();
        let mut rows = vec![0.0; 2 * nord * row];
        let w = 2.0 * std::f64::consts::PI / p as f64;
        for (i, &n) in orders.iter().enumerate() {
            for j in 0..p {
                // n j mod p without overflow (n < p / 2, j < p)
                let ph = w * ((n as u128 * j as u128) % p as u128) as f64;
                rows[i * row + j] = ph.cos();
                rows[(nord + i) * row + j] = -ph.sin();
            }
        }
        let ramp = (0..2 * nord)
            .map(|k| (0..p).map(|j| (j as f64 / p as f64 - 0.5) * rows[k * row + j]).sum())
            .collect();
        OrderTable { p, row, rows, ramp }
    }
}

/// What every block of revolutions of [`order_vectors`] reads.
struct OrderCtx<'a> {
    x: &'a [&'a [f64]],
    fs: f64,
    t0: f64,
    kp: &'a [f64],
    k0: usize,
    table: &'a OrderTable,
}

/// Sum of `a` in 8 lanes combined pairwise (the same order at every SIMD level).
#[inline(always)]
fn lane_sum(a: &[f64]) -> f64 {
    let mut acc = [0.0f64; 8];
    for ch in a.chunks_exact(8) {
        for l in 0..8 {
            acc[l] += ch[l];
        }
    }
    ((acc[0] + acc[4]) + (acc[2] + acc[6])) + ((acc[1] + acc[5]) + (acc[3] + acc[7]))
}

/// Dot product of `a` and `b` (lengths multiples of 8) in 8 lanes, as [`lane_sum`].
#[inline(always)]
fn lane_dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0f64; 8];
    for (ca, cb) in a.chunks_exact(8).zip(b.chunks_exact(8)) {
        for l in 0..8 {
            acc[l] += ca[l] * cb[l];
        }
    }
    ((acc[0] + acc[4]) + (acc[2] + acc[6])) + ((acc[1] + acc[5]) + (acc[3] + acc[7]))
}

/// Revolutions first..first + REV_BLOCK (fewer at the end) of [`order_vectors`]: `means` gets
/// each revolution's mean per channel (revolution, channel), `sums` the order sums of the values
/// about it as complex numbers [sum x cos, sum x (-sin)] (revolution, order, channel).
#[inline(always)]
fn order_block(ctx: &OrderCtx, first: usize, means: &mut [f64], sums: &mut [C64]) {
    let tab = ctx.table;
    let (p, row) = (tab.p, tab.row);
    let nk = tab.rows.len() / row;
    let nch = ctx.x.len();
    let n = ctx.x[0].len();
    let nord = nk / 2;
    let nrev = means.len() / nch;
    let pf = p as f64;
    let mut w = vec![[0.0f64; 4]; p];
    let mut mi = vec![0isize; p];
    let mut buf = vec![0.0f64; row];
    for r in 0..nrev {
        let k = ctx.k0 + first + r;
        let (ta, tb) = (ctx.kp[k], ctx.kp[k + 1]);
        // the stencil of each angle (as cubic_at computes it), shared by every channel
        for j in 0..p {
            let t = ta + (tb - ta) * (j as f64) / pf;
            let u = (t - ctx.t0) * ctx.fs;
            let m = u.floor();
            w[j] = lagrange4(u - m);
            mi[j] = m as isize;
        }
        // u increases with j: the whole revolution needs no clamping when its ends need none
        let inside = mi[0] >= 1 && mi[p - 1] <= n as isize - 3;
        for c in 0..nch {
            let xc = ctx.x[c];
            if inside {
                for j in 0..p {
                    let b = (mi[j] - 1) as usize;
                    let s = &xc[b..b + 4];
                    let wj = &w[j];
                    buf[j] = wj[0] * s[0] + wj[1] * s[1] + wj[2] * s[2] + wj[3] * s[3];
                }
            } else {
                // (saturating: pulses far from the record put m near the ends of isize)
                let at = |i: isize| -> f64 { xc[i.clamp(0, n as isize - 1) as usize] };
                for j in 0..p {
                    let (m, wj) = (mi[j], &w[j]);
                    buf[j] = wj[0] * at(m.saturating_sub(1)) + wj[1] * at(m) + wj[2] * at(m.saturating_add(1))
                        + wj[3] * at(m.saturating_add(2));
                }
            }
            let m0 = lane_sum(&buf) / pf;
            for v in &mut buf[..p] {
                *v -= m0;
            }
            means[r * nch + c] = m0;
            for i in 0..nord {
                let re = lane_dot(&buf, &tab.rows[i * row..(i + 1) * row]);
                let im = lane_dot(&buf, &tab.rows[(nord + i) * row..(nord + i + 1) * row]);
                sums[(r * nord + i) * nch + c] = C64::new(re, im);
            }
        }
    }
}

crate::lanes::simd_dispatch! {
    /// [`order_block`] at the widest SIMD level of this CPU.
    fn order_block_dispatch(ctx: &OrderCtx, first: usize, means: &mut [f64], sums: &mut [C64]) -> () => order_block
}

/// Subtract a revolution signature from samples i0..i1 of every channel.
/// `template`: (C, P), the signature of each channel over one revolution starting at the pulse.
/// Samples outside [kp[0], kp[last]) cannot be placed in a revolution and are set to NaN.
/// `out`: (C, i1 - i0). One pass over the samples: the rotor angle and the interpolation weights
/// of a sample are computed once and applied to every channel. Returns the number of input
/// samples in i0..i1 that are NaN or inf (counted on the way, their outputs are NaN).
#[allow(clippy::too_many_arguments)]
pub fn runout_subtract(
    x: &[f64],
    nch: usize,
    fs: f64,
    t0: f64,
    kp: &[f64],
    template: &[f64],
    p: usize,
    i0: usize,
    i1: usize,
    out: &mut [f64],
) -> Result<usize, CoreError> {
    check_keyphasor(kp)?;
    check_sampling(fs, t0)?;
    if nch == 0 || x.len() % nch != 0 {
        return Err(CoreError::length("x", x.len(), format!("a multiple of the channel count {nch} (at least one channel)")));
    }
    let n = x.len() / nch;
    if p < 4 {
        return Err(CoreError::value("template", format!("needs at least 4 points per revolution, got {p}")));
    }
    expect_len("template", template, product("template", &[nch, p])?)?;
    if !(i0 <= i1 && i1 <= n) {
        return Err(CoreError::value("i0, i1", format!("need 0 <= i0 <= i1 <= {n}, got i0 = {i0}, i1 = {i1}")));
    }
    expect_len("out", out, nch * (i1 - i0))?;
    Ok(runout_kernel(x, nch, fs, t0, kp, template, p, i0, i1, out))
}

#[allow(clippy::too_many_arguments)]
fn runout_kernel(x: &[f64], nch: usize, fs: f64, t0: f64, kp: &[f64], template: &[f64], p: usize, i0: usize, i1: usize, out: &mut [f64]) -> usize {
    let n = x.len() / nch;
    let m = i1 - i0;
    // templates padded periodically (one point before, two after) so stencils need no modulo
    let mut ext = vec![0.0; nch * (p + 3)];
    for c in 0..nch {
        for j in 0..p + 3 {
            ext[c * (p + 3) + j] = template[c * p + (j + p - 1) % p];
        }
    }
    let inv_period: Vec<f64> = kp.windows(2).map(|w| 1.0 / (w[1] - w[0])).collect();
    const BLOCK: usize = 1 << 14;
    let nblocks = m.div_ceil(BLOCK);
    // output rows are per channel; hand each block its disjoint sub-slices of every row
    let mut rows: Vec<&mut [f64]> = out.chunks_mut(m.max(1)).collect();
    let mut per_block: Vec<Vec<&mut [f64]>> = (0..nblocks).map(|_| Vec::with_capacity(nch)).collect();
    for row in rows.iter_mut() {
        let mut rest: &mut [f64] = std::mem::take(row);
        for pb in per_block.iter_mut() {
            let take = BLOCK.min(rest.len());
            let (head, tail) = rest.split_at_mut(take);
            pb.push(head);
            rest = tail;
        }
    }
    let ctx = Runout { x, n, nch, fs, t0, kp, inv_period: &inv_period, ext: &ext, p };
    let blocks = crate::par::Disjoint::new(&mut per_block);
    // SAFETY: sum_tasks hands each block b to one task
    crate::par::sum_tasks(nblocks, |b| runout_block_dispatch(&ctx, i0 + b * BLOCK, &mut unsafe { blocks.chunk(b, 1) }[0]))
}

/// What every block of the run-out filter reads.
struct Runout<'a> {
    x: &'a [f64],
    n: usize,
    nch: usize,
    fs: f64,
    t0: f64,
    kp: &'a [f64],
    inv_period: &'a [f64],
    /// templates padded periodically, (C, P + 3)
    ext: &'a [f64],
    p: usize,
}

/// Samples per stencil table: the weights and template offsets of this many samples are computed
/// once (vectorized, one revolution segment at a time) and applied to every channel.
const SUB: usize = 512;

/// One block of output samples starting at `first` (one slice per channel).
///
/// The rotor angle of sample i, t_i = t0 + i / fs, in revolution k (kp[k] <= t_i < kp[k+1]) is
/// u_i = (t_i - kp[k]) P / (kp[k+1] - kp[k]) template points; the signature there is the 4-point
/// Lagrange stencil sum_m w_m(frac u_i) T[floor u_i - 1 + m]. Within a revolution segment every
/// step is branch-free, so the weight loop vectorizes; samples outside the pulses get weight NaN
/// (output NaN).
#[inline(always)]
fn runout_block(ctx: &Runout, first: usize, outs: &mut [&mut [f64]]) -> usize {
    let mut nonfinite = 0usize;
    let len = outs.first().map(|o| o.len()).unwrap_or(0);
    let (kp, p) = (ctx.kp, ctx.p);
    let pf = p as f64;
    let last = kp[kp.len() - 1];
    let mut w = [[0.0f64; SUB]; 4];
    let mut mi = [0usize; SUB];
    let mut t = [0.0f64; SUB];
    for s0 in (0..len).step_by(SUB) {
        let m = SUB.min(len - s0);
        for j in 0..m {
            t[j] = ctx.t0 + (first + s0 + j) as f64 / ctx.fs;
        }
        // revolution segments of this stencil table (t is increasing)
        let mut j = 0;
        while j < m {
            let tj = t[j];
            if tj < kp[0] || tj >= last {
                // outside the pulses: until the first pulse, or to the end
                let end = if tj < kp[0] { j + t[j..m].partition_point(|&v| v < kp[0]) } else { m };
                for q in j..end {
                    w[0][q] = f64::NAN;
                    w[1][q] = 0.0;
                    w[2][q] = 0.0;
                    w[3][q] = 0.0;
                    mi[q] = 0;
                }
                j = end;
                continue;
            }
            let k = kp.partition_point(|&v| v <= tj) - 1;
            let end = j + t[j..m].partition_point(|&v| v < kp[k + 1]);
            let (tk, sc) = (kp[k], ctx.inv_period[k] * pf);
            for q in j..end {
                let u = (t[q] - tk) * sc;
                let mf = u.floor();
                let f = u - mf;
                let lw = lagrange4(f);
                w[0][q] = lw[0];
                w[1][q] = lw[1];
                w[2][q] = lw[2];
                w[3][q] = lw[3];
                mi[q] = (mf as usize).min(p - 1);
            }
            j = end;
        }
        for (c, o) in outs.iter_mut().enumerate().take(ctx.nch) {
            let e = &ctx.ext[c * (p + 3)..(c + 1) * (p + 3)];
            let xr = &ctx.x[c * ctx.n + first + s0..c * ctx.n + first + s0 + m];
            let o = &mut o[s0..s0 + m];
            for q in 0..m {
                let b = mi[q];
                let sig = w[0][q] * e[b] + w[1][q] * e[b + 1] + w[2][q] * e[b + 2] + w[3][q] * e[b + 3];
                o[q] = xr[q] - sig;
                nonfinite += (!xr[q].is_finite()) as usize;
            }
        }
    }
    nonfinite
}

crate::lanes::simd_dispatch! {
    /// [`runout_block`] at the widest SIMD level of this CPU (inline `floor`, vector weights).
    fn runout_block_dispatch(ctx: &Runout, first: usize, outs: &mut [&mut [f64]]) -> usize => runout_block
}
