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
//! Every perturbed copy of a point (2 m R for J, 2 m R + 1 for the bias) is one member of a batch
//! identified on the task's thread, a few points at a time, with the unperturbed runs read where
//! they are: nothing of size (copies x points) is ever formed.

use super::{identify_serial, IdentOut, IdentProblem, REPORT_TO_BIJ};
use crate::covariance::psd_cholesky;
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
    /// covariance of each run's x_r at each point, (runs, n, m, m) row-major; a point where any
    /// entry of a run is NaN has an unknown covariance (NaN outputs there)
    pub covs: &'a [f64],
    /// covariance common to every pair of runs, (n, m, m), or empty for independent runs
    /// (NaN entries count as zero)
    pub shared: &'a [f64],
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
    expect_len("covs", p.covs, product("covs", &[runs, n, m, m])?)?;
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
    let copies = 2 * m * runs * if out.bias.is_some() { 2 } else { 1 } + usize::from(out.bias.is_some());
    // a multiple of the identification's lanes (4), so that a lane group holds one copy's points
    let per_task = (TASK_LANES / copies / 4 * 4).max(4);
    let (cov, unknown) = (Disjoint::new(out.cov), Disjoint::new(out.unknown));
    let (k_std, c_std) = (Disjoint::new(out.k_std), Disjoint::new(out.c_std));
    let bias = out.bias.map(Disjoint::new);
    for_each_task(n.div_ceil(per_task), |j| {
        // SAFETY: for_each_task hands each task index j to one task
        let (cov, unknown) = unsafe { (cov.chunk(j, 256 * per_task), unknown.chunk(j, per_task)) };
        let std = unsafe { [k_std.chunk(j, 8 * per_task), c_std.chunk(j, 8 * per_task)] };
        let bias = bias.as_ref().map(|b| unsafe { b.chunk(j, 16 * per_task) });
        SCRATCH.with(|sc| task(p, m, j * per_task, cov, bias, unknown, std, &mut sc.borrow_mut()));
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

/// The points s.. of one task (as many as `unknown` holds).
#[allow(clippy::too_many_arguments)]
fn task(p: &CovProblem, m: usize, s: usize, cov: &mut [f64], mut bias: Option<&mut [f64]>, unknown: &mut [u8], std: [&mut [f64]; 2], scratch: &mut Scratch) {
    let ip = &p.ident;
    let (n, runs, tn) = (ip.points(), ip.runs, unknown.len());
    let e = s + tn;
    let ped = m == 16;
    let nd = 2 * m * runs; // copies for J
    let with_bias = bias.is_some();
    let nb = if with_bias { 2 * nd + 1 } else { nd }; // + sigma points and the unperturbed point
    let mr = m * runs;
    let covs_at = |r: usize, i: usize| &p.covs[((r * n) + s + i) * m * m..((r * n) + s + i + 1) * m * m];

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
        let known = (0..runs).all(|r| !covs_at(r, i).iter().any(|v| v.is_nan()));
        let unk = !(known && finite);
        unknown[i] = u8::from(unk);
        let ci = &mut cov[256 * i..256 * i + 256];
        if unk {
            ci.fill(f64::NAN);
            std[0][8 * i..8 * i + 8].fill(f64::NAN);
            std[1][8 * i..8 * i + 8].fill(f64::NAN);
        } else {
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
            // Cov = (J Σ) Jᵀ as rank-one updates over the mR columns; eq. 9 order from the upper
            // triangle (so exactly symmetric)
            cb.fill(0.0);
            for col in 0..mr {
                let jrow: &[f64; 16] = jt[16 * col..16 * col + 16].try_into().unwrap();
                let brow: &[f64; 16] = bt[16 * col..16 * col + 16].try_into().unwrap();
                for a in 0..16 {
                    let crow: &mut [f64; 16] = (&mut cb[16 * a..16 * a + 16]).try_into().unwrap();
                    for b in 0..16 {
                        crow[b] += brow[a] * jrow[b];
                    }
                }
            }
            for a in 0..16 {
                for b in 0..16 {
                    let (x, y) = (perm[a].min(perm[b]), perm[a].max(perm[b]));
                    ci[16 * a + b] = cb[16 * x + y];
                }
            }
            for u in 0..8 {
                std[0][8 * i + u] = cb[17 * u].max(0.0).sqrt();
                std[1][8 * i + u] = cb[17 * (8 + u)].max(0.0).sqrt();
            }
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
