//! Checks of measurement covariances: one m x m matrix per point, real, finite where known (a
//! matrix with a NaN is unknown), symmetric and positive semi-definite.
//!
//! Symmetric: |C_ij - C_ji| <= 1e-9 max|C| (the largest entry of every known matrix of the array).
//! Positive semi-definite within rounding: with S = (C + Cᵀ)/2 and τ = 1e-9 ‖S‖_F,
//!     λ_min(S) > -τ   <=>   S + τ I is positive definite   <=>   its Cholesky factor exists,
//! so an m x m Cholesky (m³/6 operations) decides what an eigen-decomposition would. ‖S‖_F lies
//! between λ_max and √m λ_max for such S, so τ is 1e-9 of the matrix's scale; the factorization's
//! own rounding (~m ε ‖S‖) is far below it.

use crate::error::{expect_len, CoreError};
use crate::par::{for_each_task, Disjoint};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Relative tolerance of both checks.
pub const COV_TOL: f64 = 1e-9;

/// A pivot of [`psd_cholesky`] at most this times its diagonal entry is a direction without
/// variance (a semi-definite covariance, e.g. from fewer blocks than it has entries): the rounding
/// of the subtraction leaves ~1e-16 of the diagonal there, a genuine pivot is far larger.
pub const PSD_PIVOT_TOL: f64 = 1e-12;

/// Matrices per task.
const CHUNK: usize = 512;

/// What is wrong with an array of covariances, at the first point (matrix index) it shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CovFault {
    /// an infinite entry (NaN marks an unknown covariance, inf is an error)
    Infinite(usize),
    /// a known matrix that is not symmetric (reported before any indefinite one)
    Asymmetric(usize),
    /// a known matrix with an eigenvalue below -τ
    Indefinite(usize),
}

/// Check the covariances `c` ((points, m, m) row-major) and copy them to `out`, every entry of an
/// unknown matrix (one with a NaN) NaN. Returns the first fault, if any (`out` is then partly
/// written).
pub fn check_covariances(c: &[f64], m: usize, out: &mut [f64]) -> Result<Option<CovFault>, CoreError> {
    if m == 0 {
        return Err(CoreError::value("m", "must be at least 1"));
    }
    if !c.len().is_multiple_of(m * m) {
        return Err(CoreError::length("c", c.len(), format!("a multiple of {}", m * m)));
    }
    expect_len("out", out, c.len())?;
    let mm = m * m;
    let points = c.len() / mm;
    let tasks = points.div_ceil(CHUNK);
    // pass 1: the first inf, and the largest entry of the known matrices
    let first_inf = AtomicUsize::new(usize::MAX);
    let big = std::sync::Mutex::new(0.0f64);
    for_each_task(tasks, |j| {
        let mut local = 0.0f64;
        for p in j * CHUNK..((j + 1) * CHUNK).min(points) {
            let a = &c[p * mm..(p + 1) * mm];
            if a.iter().any(|v| v.is_infinite()) {
                first_inf.fetch_min(p, Ordering::Relaxed);
            } else if !a.iter().any(|v| v.is_nan()) {
                local = a.iter().fold(local, |s, v| s.max(v.abs()));
            }
        }
        let mut g = big.lock().unwrap_or_else(|e| e.into_inner());
        *g = g.max(local);
    });
    let p = first_inf.into_inner();
    if p != usize::MAX {
        return Ok(Some(CovFault::Infinite(p)));
    }
    let sym_tol = COV_TOL * (big.into_inner().unwrap_or_else(|e| e.into_inner()) + 1e-300);
    // pass 2: symmetry and definiteness of each known matrix, copied as it goes
    let (first_asym, first_indef) = (AtomicUsize::new(usize::MAX), AtomicUsize::new(usize::MAX));
    let dst = Disjoint::new(out);
    for_each_task(tasks, |j| {
        // SAFETY: for_each_task hands each task index j to one task
        let o = unsafe { dst.chunk(j, CHUNK * mm) };
        let (mut s, mut l) = (vec![0.0; mm], vec![0.0; mm]);
        for (t, op) in o.chunks_exact_mut(mm).enumerate() {
            let p = j * CHUNK + t;
            let a = &c[p * mm..(p + 1) * mm];
            if a.iter().any(|v| v.is_nan()) {
                op.fill(f64::NAN);
                continue;
            }
            op.copy_from_slice(a);
            let mut fro = 0.0;
            let mut asym = false;
            for u in 0..m {
                for v in 0..m {
                    asym |= (a[u * m + v] - a[v * m + u]).abs() > sym_tol;
                    let x = 0.5 * (a[u * m + v] + a[v * m + u]);
                    s[u * m + v] = x;
                    fro += x * x;
                }
            }
            if asym {
                first_asym.fetch_min(p, Ordering::Relaxed);
                continue;
            }
            let tau = COV_TOL * fro.sqrt().max(1e-300);
            // S + τ I positive definite: every pivot positive
            if cholesky_lower(&s, m, tau, 0.0, &mut l) > 0 {
                first_indef.fetch_min(p, Ordering::Relaxed);
            }
        }
    });
    let (pa, pi) = (first_asym.into_inner(), first_indef.into_inner());
    Ok(if pa != usize::MAX {
        Some(CovFault::Asymmetric(pa))
    } else if pi != usize::MAX {
        Some(CovFault::Indefinite(pi))
    } else {
        None
    })
}

/// The points whose covariance is unknown: `out[k]` set where any of the arrays `blocks` (each
/// `out.len()` points of equal size, e.g. the (n, 8, 8) blocks of several runs) has a NaN at point
/// k (left as it is elsewhere, so calls accumulate).
pub fn unknown_points(blocks: &[&[f64]], out: &mut [bool]) -> Result<(), CoreError> {
    let n = out.len();
    for b in blocks {
        if n == 0 || b.len() % n != 0 {
            if n == 0 && b.is_empty() {
                continue;
            }
            return Err(CoreError::length("blocks", b.len(), format!("a multiple of {n} (the points)")));
        }
    }
    let dst = Disjoint::new(out);
    for_each_task(n.div_ceil(CHUNK), |j| {
        // SAFETY: for_each_task hands each task index j to one task
        let o = unsafe { dst.chunk(j, CHUNK) };
        for b in blocks {
            let per = b.len() / n;
            for (t, u) in o.iter_mut().enumerate() {
                let k = j * CHUNK + t;
                *u |= b[k * per..(k + 1) * per].iter().any(|v| v.is_nan());
            }
        }
    });
    Ok(())
}

/// A lower-triangular L (m x m, row-major) with L Lᵀ = A for a symmetric positive semi-definite A,
/// of which only the lower triangle is read (Cholesky, column by column):
///     d_j = A_jj - Σ_{k<j} L_jk²,   L_jj = √d_j,   L_ij = (A_ij - Σ_{k<j} L_ik L_jk) / L_jj  (i > j).
/// A pivot d_j <= [`PSD_PIVOT_TOL`] A_jj (a direction without variance, up to rounding; negative
/// only for an indefinite A) leaves column j zero, so a semi-definite A has a factor too.
pub fn psd_cholesky(a: &[f64], m: usize, l: &mut [f64]) {
    cholesky_lower(a, m, 0.0, PSD_PIVOT_TOL, l);
}

/// The Cholesky factor of A + shift I into `l`, from A's lower triangle:
///     d_j = A_jj + shift - Σ_{k<j} L_jk²,   L_jj = √d_j,   L_ij = (A_ij - Σ_{k<j} L_ik L_jk) / L_jj.
/// A pivot d_j <= floor A_jj (or NaN) leaves column j zero. Returns the number of such pivots
/// (0: A + shift I is positive definite).
pub(crate) fn cholesky_lower(a: &[f64], m: usize, shift: f64, floor: f64, l: &mut [f64]) -> usize {
    l.fill(0.0);
    let mut dropped = 0;
    for j in 0..m {
        let mut d = a[j * m + j] + shift;
        for k in 0..j {
            d -= l[j * m + k] * l[j * m + k];
        }
        if !(d > floor * a[j * m + j]) {
            dropped += 1;
            continue;
        }
        let ljj = d.sqrt();
        l[j * m + j] = ljj;
        for i in j + 1..m {
            let mut v = a[i * m + j];
            for k in 0..j {
                v -= l[i * m + k] * l[j * m + k];
            }
            l[i * m + j] = v / ljj;
        }
    }
    dropped
}

/// One run's measurement covariance in its three blocks, (n, 8, 8) each: the joint covariance of
/// z = [Re q, Im q, Re q_ped, Im q_ped] is [[q, cross], [crossᵀ, ped]] (never formed as an
/// (n, 16, 16) array).
#[derive(Clone, Copy)]
pub struct RunCov<'a> {
    /// of [Re q, Im q] (the probes, moved to the bearings)
    pub q: &'a [f64],
    /// of [Re q_ped, Im q_ped] (the accelerometers)
    pub ped: &'a [f64],
    /// between the two (rows q, columns q_ped), or empty: uncorrelated
    pub cross: &'a [f64],
}

impl RunCov<'_> {
    /// One block per run, each of n points (`cross` empty or of n points too).
    pub fn check_all(covs: &[RunCov], runs: usize, n: usize) -> Result<(), CoreError> {
        expect_len("covs (runs)", covs, runs)?;
        for c in covs {
            expect_len("covs (q)", c.q, n * 64)?;
            expect_len("covs (pedestal)", c.ped, n * 64)?;
            if !c.cross.is_empty() {
                expect_len("covs (cross)", c.cross, n * 64)?;
            }
        }
        Ok(())
    }

    /// The joint 16 x 16 matrix of point k, row-major.
    pub fn joint(&self, k: usize, out: &mut [f64; 256]) {
        for u in 0..8 {
            for v in 0..8 {
                out[16 * u + v] = self.q[64 * k + 8 * u + v];
                out[16 * (8 + u) + 8 + v] = self.ped[64 * k + 8 * u + v];
                let c = if self.cross.is_empty() { 0.0 } else { self.cross[64 * k + 8 * u + v] };
                out[16 * u + 8 + v] = c;
                out[16 * (8 + v) + u] = c;
            }
        }
    }
}

/// Points per task of [`move_covariances`].
const MOVE_TASK: usize = 1024;

/// A run's covariance moved between planes with its responses: q' = A q (+ B p with pedestal
/// motion, the probes riding on the pedestals), p' = p, with A and B the 8 x 8 real maps of
/// [Re q, Im q] (row-major). The joint covariance of [q', p'] is M Σ Mᵀ, M = [[A, B], [0, I]]:
///     cov'   = A C Aᵀ + (A X Bᵀ) + (A X Bᵀ)ᵀ + B P Bᵀ,
///     cross' = A X + B P,
/// C, P, X the blocks of `rc` (P and X absent without `b`; X empty counts as zero). `cov'` is
/// exactly symmetric (its upper triangle mirrored); a point where any block holds a NaN is all
/// NaN in both outputs (an unknown covariance). `cross` (n, 8, 8) is written with `b` only.
pub fn move_covariances(a: &[f64; 64], b: Option<&[f64; 64]>, rc: RunCov, cov: &mut [f64], cross: Option<&mut [f64]>) -> Result<(), CoreError> {
    use nalgebra::SMatrix;
    type M8 = SMatrix<f64, 8, 8>;

    if rc.q.len() % 64 != 0 {
        return Err(CoreError::length("cov", rc.q.len(), "a multiple of 64 (n, 8, 8)".to_string()));
    }
    let n = rc.q.len() / 64;
    if a.iter().chain(b.into_iter().flatten()).any(|v| !v.is_finite()) {
        return Err(CoreError::value("maps", "must be finite"));
    }
    match b {
        Some(_) => {
            expect_len("pedestal_cov", rc.ped, n * 64)?;
            if !rc.cross.is_empty() {
                expect_len("cross", rc.cross, n * 64)?;
            }
            match &cross {
                Some(x) => expect_len("cross (out)", x, n * 64)?,
                None => return Err(CoreError::value("cross (out)", "is needed with pedestal motion (b)")),
            }
        }
        None if !rc.ped.is_empty() || !rc.cross.is_empty() => {
            return Err(CoreError::value("pedestal_cov", "moves with the pedestal map b only"));
        }
        None => {}
    }
    expect_len("cov (out)", cov, n * 64)?;
    let am = M8::from_row_slice(a);
    let bm = b.map(|b| M8::from_row_slice(b));
    let (out_cov, out_cross) = (Disjoint::new(cov), cross.map(Disjoint::new));
    for_each_task(n.div_ceil(MOVE_TASK), |t| {
        // SAFETY: for_each_task hands each task index t to one task
        let oc = unsafe { out_cov.chunk(t, 64 * MOVE_TASK) };
        let mut ox = out_cross.as_ref().map(|x| unsafe { x.chunk(t, 64 * MOVE_TASK) });
        for j in 0..oc.len() / 64 {
            let k = t * MOVE_TASK + j;
            let blk = |s: &[f64]| -> Option<M8> { if s.is_empty() { None } else { Some(M8::from_row_slice(&s[64 * k..64 * k + 64])) } };
            let (c, p, x) = (blk(rc.q).unwrap(), blk(rc.ped), blk(rc.cross));
            let oc = &mut oc[64 * j..64 * j + 64];
            let nan = c.iter().chain(p.iter().flatten()).chain(x.iter().flatten()).any(|v| v.is_nan());
            if nan {
                oc.fill(f64::NAN);
                if let Some(ox) = ox.as_deref_mut() {
                    ox[64 * j..64 * j + 64].fill(f64::NAN);
                }
                continue;
            }
            let mut moved = am * c * am.transpose();
            if let (Some(bm), Some(ox)) = (&bm, ox.as_deref_mut()) {
                let p = p.unwrap();
                let bp = bm * p;
                moved += bp * bm.transpose();
                let mut xc = bp;
                if let Some(x) = x {
                    let ax = am * x;
                    let axb = ax * bm.transpose();
                    moved += axb + axb.transpose();
                    xc += ax;
                }
                for u in 0..8 {
                    for v in 0..8 {
                        ox[64 * j + 8 * u + v] = xc[(u, v)];
                    }
                }
            }
            for u in 0..8 {
                for v in 0..8 {
                    oc[8 * u + v] = moved[(u.min(v), u.max(v))];
                }
            }
        }
    });
    Ok(())
}
