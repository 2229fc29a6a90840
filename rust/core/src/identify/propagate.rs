//! Measurement covariance propagated through the identification, and the estimator's bias.
//!
//! At each point the identification maps the measured responses of the R runs,
//!     x = [x_1, ..., x_R],   x_r = [Re q_r, Im q_r]  (m = 8 real values per run), or with
//!     pedestal motion x_r = [Re q_r, Im q_r, Re q_ped,r, Im q_ped,r]  (m = 16),
//! to the report vector p (16 values in eq. 9 order: Kxx1, Kxx2, Kxy1, ..., Cyy2). Both sides of
//! the equations hold measured responses (errors in variables), and to first order
//!     Cov(p) = J Σ Jᵀ,   J = ∂p/∂x  (16 x mR),
//! with Σ block diagonal (Σ_r: run r's m x m covariance) or, with a covariance S common to every
//! pair of runs (all runs less one baseline run), S in every off-diagonal block. The columns of J
//! are central differences of the estimator itself,
//!     J e_j = (p(x + h e_j) - p(x - h e_j)) / 2h,   h = 1e-6 rms(q) at the point,
//! so J is that of whichever solver gave p ("forces" or "report", two runs or many).
//!
//! The noise also moves a nonlinear estimator's mean away from the truth (least squares with
//! noisy regressors shrinks toward zero). To second order the bias is ½ tr(H Σ), H the Hessian of
//! p; it is taken from sigma points, run by run:
//!     b = ½ Σ_r Σ_k [p(x + l_rk) + p(x - l_rk) - 2 p(x)],
//! with l_rk the columns of L_r, L_r L_rᵀ = Σ_r (a Cholesky factor that allows a positive
//! semi-definite Σ_r, [`crate::covariance::psd_cholesky`]): by Taylor, p(x + l) + p(x - l) - 2 p(x) = lᵀ H l + O(|l|⁴),
//! and Σ_k l_kᵀ H l_k = tr(H L Lᵀ) = tr(H Σ_r) for any such L.
//!
//! The accelerometers' calibration (with pedestal motion) is an error common to all runs: channel
//! j (xp1, xp2, yp1, yp2) of every run's pedestal motion reads (1 + g_j) e^{i φ_j} times the truth,
//! g_j and φ_j independent with standard deviations σ_g, σ_φ. To first order the inputs move
//! along d_gj = ∂x/∂g_j: run r's pedestal component j by its motion p_rj, and, for a run measured
//! at the probes (relative motion at the bearings q = A q_probes + B p, the probes riding on the
//! pedestals), its q by B[:, j] p_rj; d_φj is the same with i p_rj. Then
//!     Cov_cal(p) = Σ_j σ_g² (J d_gj)(J d_gj)ᵀ + σ_φ² (J d_φj)(J d_φj)ᵀ
//! is added to J Σ Jᵀ, with the same J (a systematic error of the same estimator).
//!
//! Every perturbed copy of a point (2 m R for J, 2 m R + 1 for the bias) is one member of a batch
//! identified on the task's thread, a few points at a time, with the unperturbed runs read where
//! they are: nothing of size (copies x points) is ever formed.

use super::{identify_serial, IdentOut, IdentProblem, REPORT_TO_BIJ};
use crate::covariance::{psd_cholesky, RunCov};
use crate::error::{expect_len, product, CoreError};
use crate::model::C64;
use crate::par::{for_each_task, Disjoint};

/// Relative step of the central differences: h = H_REL rms(q) at each point (H_REL where q = 0).
pub const H_REL: f64 = 1e-6;

/// Perturbed copies per point and task: a task takes `TASK_LANES / copies` points (at least 4), so
/// its buffers (~70 bytes of inputs and outputs per copy and point) stay in the core's L2 cache.
const TASK_LANES: usize = 2048;

/// The propagation's inputs.
pub struct CovProblem<'a> {
    /// The identification: one batch member (`batch` = 1), responses at the bearings (`planes`
    /// None), pedestal motion or not.
    pub ident: IdentProblem<'a>,
    /// the report's 16-unknown formulation (`identify_report`) rather than the bearing-force solver
    pub report: bool,
    /// covariance of each run's x_r at each point; a point where any entry of a run is NaN has an
    /// unknown covariance (NaN outputs there)
    pub covs: RunCovs<'a>,
    /// covariance common to every pair of runs, (n, m, m), or empty for independent runs
    /// (NaN entries count as zero)
    pub shared: &'a [f64],
    /// the accelerometers' calibration uncertainty (pedestal motion only), or None. With it,
    /// `covs` may be [`RunCovs::Absent`] (no measurement covariance: Cov(p) is the calibration's
    /// alone; no bias, no shared covariance then).
    pub calibration: Option<Calibration<'a>>,
}

/// The runs' measurement covariances.
#[derive(Clone, Copy)]
pub enum RunCovs<'a> {
    /// (runs, n, m, m) row-major
    Dense(&'a [f64]),
    /// with pedestal motion, each run's three (n, 8, 8) blocks (no (n, 16, 16) array)
    Blocks(&'a [RunCov<'a>]),
    /// none: only with a calibration (Cov(p) is the calibration's alone)
    Absent,
}

/// The accelerometers' calibration uncertainty, common to all runs (see the module's documentation).
#[derive(Clone, Copy)]
pub struct Calibration<'a> {
    /// σ_g, relative (0.02 = 2 %)
    pub gain_std: f64,
    /// σ_φ, radians
    pub phase_std: f64,
    /// per run, B (4 x 4, row-major over [x1, x2, y1, y2]): the relative motion at the bearings
    /// moved by a unit of measured pedestal motion; zeros for a run measured at the bearings
    pub probe_maps: &'a [[f64; 16]],
}

/// The propagation's outputs.
pub struct CovOut<'a> {
    /// Cov(p), (n, 16, 16), eq. 9 order; all NaN where `unknown`
    pub cov: &'a mut [f64],
    /// b, (n, 16), or None; NaN where `unknown`
    pub bias: Option<&'a mut [f64]>,
    /// (n,) 1 where a run's covariance is unknown or the estimator is singular (J not finite)
    pub unknown: &'a mut [u8],
    /// standard errors of K and C, sqrt of Cov(p)'s diagonal (negative rounding as 0), (n, 8) each
    /// in [bearing][i][j] order as the identification's k and c; NaN where `unknown`
    pub k_std: &'a mut [f64],
    pub c_std: &'a mut [f64],
    /// with a calibration: the standard errors of the measurement covariance alone (J Σ Jᵀ), as
    /// `k_std` and `c_std`, or None
    pub meas_std: Option<[&'a mut [f64]; 2]>,
}

/// Cov(p) and, if asked for, the bias b at every point (see the module's documentation).
pub fn propagate(p: &CovProblem, out: CovOut) -> Result<(), CoreError> {
    let ip = &p.ident;
    ip.check()?;
    if ip.batch != 1 {
        return Err(CoreError::value("batch", "the propagation takes one problem (batch = 1)"));
    }
    if ip.planes.is_some() {
        return Err(CoreError::value("planes", "the propagation takes responses at the bearings (planes = None)"));
    }
    if p.report && !ip.identical && ip.runs < 2 {
        return Err(CoreError::value("runs", "the report formulation needs at least two runs (one with identical bearings)"));
    }
    let (n, runs) = (ip.points(), ip.runs);
    let m = if ip.q_ped.is_empty() { 8 } else { 16 };
    if let Some(cal) = &p.calibration {
        if m != 16 {
            return Err(CoreError::value("calibration", "the accelerometers' calibration needs pedestal motion (q_ped)"));
        }
        if !(cal.gain_std.is_finite() && cal.gain_std >= 0.0 && cal.phase_std.is_finite() && cal.phase_std >= 0.0) {
            return Err(CoreError::value("calibration", format!("gain_std and phase_std must be finite and >= 0, got {} and {}", cal.gain_std, cal.phase_std)));
        }
        expect_len("probe_maps", cal.probe_maps, runs)?;
        if cal.probe_maps.iter().flatten().any(|v| !v.is_finite()) {
            return Err(CoreError::value("probe_maps", "must be finite"));
        }
    }
    match p.covs {
        RunCovs::Dense(c) => expect_len("covs", c, product("covs", &[runs, n, m, m])?)?,
        RunCovs::Blocks(_) if m != 16 => return Err(CoreError::value("covs", "blocks are for runs with pedestal motion (q_ped)")),
        RunCovs::Blocks(b) => RunCov::check_all(b, runs, n)?,
        RunCovs::Absent if p.calibration.is_none() => return Err(CoreError::value("covs", "are needed (absent only with a calibration)")),
        RunCovs::Absent if out.bias.is_some() || !p.shared.is_empty() => {
            return Err(CoreError::value("covs", "the bias and a shared covariance need the runs' measurement covariances"))
        }
        RunCovs::Absent => {}
    }
    if !p.shared.is_empty() {
        expect_len("shared", p.shared, n * m * m)?;
    }
    expect_len("cov", out.cov, n * 256)?;
    if let Some(b) = &out.bias {
        expect_len("bias", b, n * 16)?;
    }
    expect_len("unknown", out.unknown, n)?;
    expect_len("k_std", out.k_std, n * 8)?;
    expect_len("c_std", out.c_std, n * 8)?;
    if let Some([mk, mc]) = &out.meas_std {
        expect_len("meas_std", mk, n * 8)?;
        expect_len("meas_std", mc, n * 8)?;
    }
    let copies = 2 * m * runs * if out.bias.is_some() { 2 } else { 1 } + usize::from(out.bias.is_some());
    // a multiple of the identification's lanes (4), so that a lane group holds one copy's points
    let per_task = (TASK_LANES / copies / 4 * 4).max(4);
    let (cov, unknown) = (Disjoint::new(out.cov), Disjoint::new(out.unknown));
    let (k_std, c_std) = (Disjoint::new(out.k_std), Disjoint::new(out.c_std));
    let bias = out.bias.map(Disjoint::new);
    let meas_std = out.meas_std.map(|[a, b]| [Disjoint::new(a), Disjoint::new(b)]);
    for_each_task(n.div_ceil(per_task), |j| {
        // SAFETY: for_each_task hands each task index j to one task
        let (cov, unknown) = unsafe { (cov.chunk(j, 256 * per_task), unknown.chunk(j, per_task)) };
        let std = unsafe { [k_std.chunk(j, 8 * per_task), c_std.chunk(j, 8 * per_task)] };
        let bias = bias.as_ref().map(|b| unsafe { b.chunk(j, 16 * per_task) });
        let meas_std = meas_std.as_ref().map(|[a, b]| unsafe { [a.chunk(j, 8 * per_task), b.chunk(j, 8 * per_task)] });
        let outs = TaskOut { cov, bias, unknown, std, meas_std };
        SCRATCH.with(|sc| task(p, m, j * per_task, outs, &mut sc.borrow_mut()));
    });
    Ok(())
}

/// Which run and which real input a perturbed copy moves: copies come in pairs (+, -) per column
/// `col` = r m + comp of J (or of the runs' L).
#[inline(always)]
fn column(copy: usize, m: usize) -> (usize, usize) {
    let col = copy / 2;
    (col / m, col % m)
}

/// One task's share of [`CovOut`].
struct TaskOut<'a> {
    cov: &'a mut [f64],
    bias: Option<&'a mut [f64]>,
    unknown: &'a mut [u8],
    std: [&'a mut [f64]; 2],
    meas_std: Option<[&'a mut [f64]; 2]>,
}

/// The points s.. of one task (as many as `unknown` holds).
fn task(p: &CovProblem, m: usize, s: usize, out: TaskOut, scratch: &mut Scratch) {
    let TaskOut { cov, mut bias, unknown, mut std, mut meas_std } = out;
    let ip = &p.ident;
    let (n, runs, tn) = (ip.points(), ip.runs, unknown.len());
    let e = s + tn;
    let ped = m == 16;
    let nd = 2 * m * runs; // copies for J
    let with_bias = bias.is_some();
    let meas = !matches!(p.covs, RunCovs::Absent); // else the calibration's covariance alone
    let nb = if with_bias { 2 * nd + 1 } else { nd }; // + sigma points and the unperturbed point
    let mr = m * runs;
    // each run's m x m covariance at point i of the task: the dense array's, or the blocks'
    // joint matrices formed once for the task
    let mut joints = Vec::new();
    if let RunCovs::Blocks(b) = p.covs {
        joints = vec![0.0; tn * runs * 256];
        for i in 0..tn {
            for (r, rc) in b.iter().enumerate() {
                rc.joint(s + i, (&mut joints[(i * runs + r) * 256..(i * runs + r + 1) * 256]).try_into().unwrap());
            }
        }
    }
    let covs_at = |r: usize, i: usize| -> &[f64] {
        match p.covs {
            RunCovs::Dense(c) => &c[((r * n) + s + i) * m * m..((r * n) + s + i + 1) * m * m],
            RunCovs::Blocks(_) => &joints[(i * runs + r) * 256..(i * runs + r + 1) * 256],
            RunCovs::Absent => &[],
        }
    };

    // the step h of each point, and each run's L where the bias is asked for
    let mut h = vec![0.0; tn];
    for (i, hi) in h.iter_mut().enumerate() {
        let mut sum = 0.0;
        for blk in ip.q.iter() {
            for v in &blk[4 * (s + i)..4 * (s + i) + 4] {
                let a = v.norm();
                sum += a * a;
            }
        }
        let scale = (sum / (4 * runs) as f64).sqrt();
        *hi = H_REL * if scale > 0.0 { scale } else { 1.0 };
    }
    let mut ls = Vec::new();
    if with_bias {
        ls = vec![0.0; tn * runs * m * m];
        let mut known = vec![0.0; m * m];
        for i in 0..tn {
            for r in 0..runs {
                for (k, &v) in known.iter_mut().zip(covs_at(r, i)) {
                    *k = if v.is_nan() { 0.0 } else { v };
                }
                psd_cholesky(&known, m, &mut ls[(i * runs + r) * m * m..(i * runs + r + 1) * m * m]);
            }
        }
    }

    // the moved run of every copy (and its pedestal motion), as blocks of (tn, 4)
    let moved = if with_bias { 2 * nd } else { nd };
    let mut qbuf = vec![C64::new(0.0, 0.0); moved * tn * 4];
    let mut pbuf = if ped { vec![C64::new(0.0, 0.0); moved * tn * 4] } else { Vec::new() };
    for copy in 0..moved {
        let sigma_point = copy >= nd;
        let (r, comp) = column(copy - if sigma_point { nd } else { 0 }, m);
        let sign = if copy % 2 == 0 { 1.0 } else { -1.0 };
        let qb = &mut qbuf[copy * tn * 4..(copy + 1) * tn * 4];
        qb.copy_from_slice(&ip.q[r][4 * s..4 * e]);
        if ped {
            pbuf[copy * tn * 4..(copy + 1) * tn * 4].copy_from_slice(&ip.q_ped[r][4 * s..4 * e]);
        }
        for i in 0..tn {
            if !sigma_point {
                // one real input moved by +-h
                let d = sign * h[i];
                let v = if comp < 8 { &mut qbuf[(copy * tn + i) * 4 + comp % 4] } else { &mut pbuf[(copy * tn + i) * 4 + comp % 4] };
                if comp % 8 < 4 {
                    v.re += d;
                } else {
                    v.im += d;
                }
            } else {
                // x_r moved by +-l_k, column comp of run r's L
                let l = &ls[(i * runs + r) * m * m..(i * runs + r + 1) * m * m];
                for d in 0..4 {
                    let (re, im) = (l[d * m + comp], l[(4 + d) * m + comp]);
                    let v = &mut qbuf[(copy * tn + i) * 4 + d];
                    if sign > 0.0 {
                        *v += C64::new(re, im);
                    } else {
                        *v -= C64::new(re, im);
                    }
                    if ped {
                        let (re, im) = (l[(8 + d) * m + comp], l[(12 + d) * m + comp]);
                        let v = &mut pbuf[(copy * tn + i) * 4 + d];
                        if sign > 0.0 {
                            *v += C64::new(re, im);
                        } else {
                            *v -= C64::new(re, im);
                        }
                    }
                }
            }
        }
    }
    let orig_q: Vec<&[C64]> = ip.q.iter().map(|b| &b[4 * s..4 * e]).collect();
    let orig_p: Vec<&[C64]> = ip.q_ped.iter().map(|b| &b[4 * s..4 * e]).collect();
    let mut qblocks: Vec<&[C64]> = Vec::with_capacity(nb * runs);
    let mut pblocks: Vec<&[C64]> = Vec::with_capacity(if ped { nb * runs } else { 0 });
    for copy in 0..nb {
        let r_moved = if copy < moved { column(copy % nd, m).0 } else { usize::MAX };
        for r in 0..runs {
            if r == r_moved {
                qblocks.push(&qbuf[copy * tn * 4..(copy + 1) * tn * 4]);
                if ped {
                    pblocks.push(&pbuf[copy * tn * 4..(copy + 1) * tn * 4]);
                }
            } else {
                qblocks.push(orig_q[r]);
                if ped {
                    pblocks.push(orig_p[r]);
                }
            }
        }
    }
    // per-point arguments for the task's points; (1,) and empty ones as they are
    let pick = |a: &[f64]| -> (usize, usize) { if a.len() == n && n > 1 { (s, e) } else { (0, a.len()) } };
    let (g0, g1) = pick(ip.gain);
    let (sp0, sp1) = pick(ip.spin);
    let local = IdentProblem {
        rotor: ip.rotor,
        w: &ip.w[s..e],
        spin: &ip.spin[sp0..sp1],
        q: &qblocks,
        e: ip.e,
        gain: &ip.gain[g0..g1],
        sigma: if ip.sigma.is_empty() { ip.sigma } else { &ip.sigma[s..e] },
        q_ped: &pblocks,
        planes: None,
        batch: nb,
        runs,
        identical: ip.identical,
    };
    let pts = nb * tn;
    let Scratch { k, c, cond, resid, amp } = scratch;
    for (v, len) in [(&mut *k, pts * 8), (&mut *c, pts * 8), (&mut *cond, pts * 2), (&mut *resid, pts), (&mut *amp, pts)] {
        v.resize(len, 0.0);
    }
    identify_serial(
        &local,
        p.report,
        IdentOut { k: &mut k[..pts * 8], c: &mut c[..pts * 8], cond: &mut cond[..pts * 2], resid: &mut resid[..pts], amp: &mut amp[..pts], k_std: None, c_std: None, rel_std: None },
    );
    // copy `copy` at point i: its k and c, 8 each in [bearing][i][j] order. The work below keeps
    // that order ("bij": u < 8 K, u >= 8 C) and writes eq. 9 order at the end through `perm`.
    let kc_of = |copy: usize, i: usize| -> (&[f64], &[f64]) {
        let o = (copy * tn + i) * 8;
        (&k[o..o + 8], &c[o..o + 8])
    };
    let mut perm = [0usize; 16];
    for t in 0..8 {
        perm[t] = REPORT_TO_BIJ[t];
        perm[8 + t] = 8 + REPORT_TO_BIJ[t];
    }

    // Jᵀ and (J Σ)ᵀ, (mR, 16) row-major: the loops below run over the 16 outputs, contiguous
    let mut jt = vec![0.0; mr * 16];
    let mut bt = vec![0.0; mr * 16];
    let mut common = vec![0.0; m * m];
    let mut cb = [0.0; 256]; // Cov(p) in bij order
    for i in 0..tn {
        let two_h = 2.0 * h[i];
        let mut finite = true;
        for col in 0..mr {
            let ((kp, cp), (km, cm)) = (kc_of(2 * col, i), kc_of(2 * col + 1, i));
            let row = &mut jt[16 * col..16 * col + 16];
            for o in 0..8 {
                let (dk, dc) = ((kp[o] - km[o]) / two_h, (cp[o] - cm[o]) / two_h);
                finite &= dk.is_finite() && dc.is_finite();
                row[o] = dk;
                row[8 + o] = dc;
            }
        }
        let known = !meas || (0..runs).all(|r| !covs_at(r, i).iter().any(|v| v.is_nan()));
        let unk = !(known && finite);
        unknown[i] = u8::from(unk);
        let ci = &mut cov[256 * i..256 * i + 256];
        if unk {
            ci.fill(f64::NAN);
            for sd in std.iter_mut().chain(meas_std.iter_mut().flatten()) {
                sd[8 * i..8 * i + 8].fill(f64::NAN);
            }
        } else {
            cb.fill(0.0);
            if meas {
                // (J Σ)ᵀ = Σ Jᵀ (Σ symmetric) block by block: Σ's block (r, t) is run r's own
                // covariance (t = r) or the shared one, whose NaN entries count as zero
                let with_shared = !p.shared.is_empty();
                if with_shared {
                    for (c, &v) in common.iter_mut().zip(&p.shared[(s + i) * m * m..(s + i + 1) * m * m]) {
                        *c = if v.is_nan() { 0.0 } else { v };
                    }
                }
                bt.fill(0.0);
                for r in 0..runs {
                    for t in 0..runs {
                        let blk = if t == r {
                            covs_at(r, i)
                        } else if with_shared {
                            &common[..]
                        } else {
                            continue;
                        };
                        for u in 0..m {
                            let jrow: &[f64; 16] = jt[16 * (r * m + u)..16 * (r * m + u) + 16].try_into().unwrap();
                            for v in 0..m {
                                let suv = blk[u * m + v];
                                let brow: &mut [f64; 16] = (&mut bt[16 * (t * m + v)..16 * (t * m + v) + 16]).try_into().unwrap();
                                for o in 0..16 {
                                    brow[o] += suv * jrow[o];
                                }
                            }
                        }
                    }
                }
                // Cov = (J Σ) Jᵀ as rank-one updates over the mR columns
                for col in 0..mr {
                    let jrow: &[f64; 16] = jt[16 * col..16 * col + 16].try_into().unwrap();
                    let brow: &[f64; 16] = bt[16 * col..16 * col + 16].try_into().unwrap();
                    rank_one(&mut cb, 1.0, brow, jrow);
                }
                if let Some([mk, mc]) = meas_std.as_mut() {
                    diagonal_std(&cb, &mut mk[8 * i..8 * i + 8], &mut mc[8 * i..8 * i + 8]);
                }
            }
            if let Some(cal) = &p.calibration {
                let pts: Vec<&[C64]> = ip.q_ped.iter().map(|b| &b[4 * (s + i)..4 * (s + i) + 4]).collect();
                add_calibration(cal, &jt, &pts, &mut cb);
            }
            // eq. 9 order from the upper triangle (so exactly symmetric)
            for a in 0..16 {
                for b in 0..16 {
                    let (x, y) = (perm[a].min(perm[b]), perm[a].max(perm[b]));
                    ci[16 * a + b] = cb[16 * x + y];
                }
            }
            let [sk, sc] = &mut std;
            diagonal_std(&cb, &mut sk[8 * i..8 * i + 8], &mut sc[8 * i..8 * i + 8]);
        }
        if let Some(b) = bias.as_deref_mut() {
            let bi = &mut b[16 * i..16 * i + 16];
            if unk {
                bi.fill(f64::NAN);
                continue;
            }
            let (k0, c0) = kc_of(2 * nd, i);
            let mut acc = [0.0; 16];
            for col in 0..mr {
                let ((kp, cp), (km, cm)) = (kc_of(nd + 2 * col, i), kc_of(nd + 2 * col + 1, i));
                for o in 0..8 {
                    acc[o] += (kp[o] + km[o]) - 2.0 * k0[o];
                    acc[8 + o] += (cp[o] + cm[o]) - 2.0 * c0[o];
                }
            }
            for (o, &u) in perm.iter().enumerate() {
                bi[o] = 0.5 * acc[u];
            }
        }
    }
}

/// cb += f a bᵀ (16 x 16, row-major).
#[inline(always)]
fn rank_one(cb: &mut [f64; 256], f: f64, a: &[f64; 16], b: &[f64; 16]) {
    for u in 0..16 {
        let crow: &mut [f64; 16] = (&mut cb[16 * u..16 * u + 16]).try_into().unwrap();
        let fa = f * a[u];
        for v in 0..16 {
            crow[v] += fa * b[v];
        }
    }
}

/// The standard errors of K and C (8 each, bij order) from the diagonal of a bij-order
/// covariance (negative rounding as 0).
fn diagonal_std(cb: &[f64; 256], k: &mut [f64], c: &mut [f64]) {
    for u in 0..8 {
        k[u] = cb[17 * u].max(0.0).sqrt();
        c[u] = cb[17 * (8 + u)].max(0.0).sqrt();
    }
}

/// cb += Cov_cal at one point: Σ_j σ_g² g_j g_jᵀ + σ_φ² f_j f_jᵀ with g_j = J d_gj and f_j = J d_φj
/// (module documentation). `jt`: Jᵀ (16 R rows of 16, run r's rows r 16.. in the order
/// [Re q, Im q, Re p, Im p]); `ped`: each run's pedestal motion at the point (4 values).
/// With u_r = J's Re-direction for channel j (B[:, j] on Re q, 1 on Re p_j) and v_r its Im
/// direction, a change δ p_rj moves p by u_r Re δ + v_r Im δ; δ = p_rj for the gain, i p_rj for
/// the phase.
fn add_calibration(cal: &Calibration, jt: &[f64], ped: &[&[C64]], cb: &mut [f64; 256]) {
    for j in 0..4 {
        let (mut g, mut f) = ([0.0; 16], [0.0; 16]);
        for (r, (b, p)) in cal.probe_maps.iter().zip(ped).enumerate() {
            let rows = &jt[256 * r..256 * (r + 1)];
            let row = |c: usize| -> &[f64] { &rows[16 * c..16 * c + 16] };
            let (mut u, mut v) = ([0.0; 16], [0.0; 16]);
            for o in 0..16 {
                u[o] = row(8 + j)[o];
                v[o] = row(12 + j)[o];
            }
            for d in 0..4 {
                let bdj = b[4 * d + j];
                if bdj != 0.0 {
                    for o in 0..16 {
                        u[o] += bdj * row(d)[o];
                        v[o] += bdj * row(4 + d)[o];
                    }
                }
            }
            let dp = p[j];
            for o in 0..16 {
                g[o] += u[o] * dp.re + v[o] * dp.im;
                f[o] += v[o] * dp.re - u[o] * dp.im;
            }
        }
        rank_one(cb, cal.gain_std * cal.gain_std, &g, &g);
        rank_one(cb, cal.phase_std * cal.phase_std, &f, &f);
    }
}

/// A task's buffers for the identification of its copies, kept by each thread from call to call
/// (fresh ones per task: 7 % of the samples in memset and page faults).
#[derive(Default)]
struct Scratch {
    k: Vec<f64>,
    c: Vec<f64>,
    cond: Vec<f64>,
    resid: Vec<f64>,
    amp: Vec<f64>,
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}
