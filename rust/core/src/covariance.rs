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
        let mut s = vec![0.0; mm];
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
            if !positive_definite_shifted(&mut s, m, tau) {
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

/// Whether S + τ I (symmetric, m x m, overwritten by its Cholesky factor) is positive definite:
/// every pivot d_j = S_jj + τ - Σ_{k<j} L_jk² positive.
fn positive_definite_shifted(s: &mut [f64], m: usize, tau: f64) -> bool {
    for j in 0..m {
        let mut d = s[j * m + j] + tau;
        for k in 0..j {
            d -= s[j * m + k] * s[j * m + k];
        }
        if !(d > 0.0) {
            return false;
        }
        let ljj = d.sqrt();
        s[j * m + j] = ljj;
        for i in j + 1..m {
            let mut v = s[i * m + j];
            for k in 0..j {
                v -= s[i * m + k] * s[j * m + k];
            }
            s[i * m + j] = v / ljj;
        }
    }
    true
}
