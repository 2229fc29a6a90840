//! Batched forced response: H(Omega, omega) q = F with H = -w^2 M + j w Omega G + j w C + K
//! (report eq. 13-14 for imbalance, eq. 27-28 for impacts).

use crate::error::{expect_len, expect_len_or_broadcast, product, CoreError};
use crate::model::{assemble, Rotor, C64};
use rayon::prelude::*;

/// Solve a 4x4 complex system in place by LU with partial pivoting, for `nrhs` right-hand sides
/// stored consecutively in `rhs` (each of length 4). Returns false if the matrix is singular
/// (a zero pivot, or for a forced response a pivot spread beyond 1e10); the right-hand sides are
/// then set to NaN.
#[inline(always)]
pub fn solve4(h: &mut [[C64; 4]; 4], rhs: &mut [C64]) -> bool {
    solve4_impl(h, rhs, 1e-10)
}

/// As [`solve4`] but accepting nearly singular matrices (inverse iteration solves with a shifted
/// matrix that is singular to rounding on purpose); only an exactly zero pivot fails.
#[inline(always)]
pub fn solve4_near_singular(h: &mut [[C64; 4]; 4], rhs: &mut [C64]) -> bool {
    solve4_impl(h, rhs, 0.0)
}

/// |re| + |im|: within a factor sqrt(2) of the modulus, enough to choose pivots and measure their
/// spread, and without the `hypot` call that took 42 % of a forced response.
#[inline(always)]
fn mag(z: C64) -> f64 {
    z.re.abs() + z.im.abs()
}

#[inline(always)]
fn solve4_impl(h: &mut [[C64; 4]; 4], rhs: &mut [C64], max_spread: f64) -> bool {
    let nrhs = rhs.len() / 4;
    let mut scale = 0.0f64;
    for row in h.iter() {
        for v in row.iter() {
            scale = scale.max(mag(*v));
        }
    }
    let tiny = scale * 1e-15;
    // the pivots' spread bounds the condition number from below: at an undamped resonance the last
    // pivot is rounding noise (1e-16 of the others), which must not pass as a huge response; a spread
    // beyond 1e10 (a damping ratio below ~1e-10) is treated as singular
    let (mut pmin, mut pmax) = (f64::INFINITY, 0.0f64);
    for k in 0..4 {
        // pivot
        let mut p = k;
        let mut best = mag(h[k][k]);
        for i in (k + 1)..4 {
            let v = mag(h[i][k]);
            if v > best {
                best = v;
                p = i;
            }
        }
        pmin = pmin.min(best);
        pmax = pmax.max(best);
        if !(best > tiny) || pmin < max_spread * pmax {
            for v in rhs.iter_mut() {
                *v = C64::new(f64::NAN, f64::NAN);
            }
            return false;
        }
        if p != k {
            h.swap(p, k);
            for r in 0..nrhs {
                rhs.swap(4 * r + p, 4 * r + k);
            }
        }
        let inv = 1.0 / h[k][k];
        for i in (k + 1)..4 {
            let f = h[i][k] * inv;
            if f == C64::new(0.0, 0.0) {
                continue;
            }
            for j in (k + 1)..4 {
                let t = h[k][j];
                h[i][j] -= f * t;
            }
            for r in 0..nrhs {
                let t = rhs[4 * r + k];
                rhs[4 * r + i] -= f * t;
            }
        }
    }
    for r in 0..nrhs {
        let b = &mut rhs[4 * r..4 * r + 4];
        for k in (0..4).rev() {
            let mut s = b[k];
            for j in (k + 1)..4 {
                s -= h[k][j] * b[j];
            }
            b[k] = s / h[k][k];
        }
    }
    true
}

/// Dynamic stiffness H at one point (M and G precomputed by the caller).
#[inline(always)]
pub fn dynamic_stiffness(rotor: &Rotor, m: &[[f64; 4]; 4], g: &[[f64; 4]; 4], kb: &[f64], cb: &[f64], spin: f64, w: f64) -> [[C64; 4]; 4] {
    let k = assemble(kb, rotor.l1, rotor.l2);
    let c = assemble(cb, rotor.l1, rotor.l2);
    let mut h = [[C64::new(0.0, 0.0); 4]; 4];
    for i in 0..4 {
        for j in 0..4 {
            h[i][j] = C64::new(k[i][j] - w * w * m[i][j], w * spin * g[i][j] + w * c[i][j]);
        }
    }
    h
}

/// For every point i: solve H_i q = F_i for `nrhs` force vectors, with
/// H_i = K_i - w_i^2 M + j w_i (C_i + Omega_i G).
///
/// `kb`, `cb`: (n, 8) or (1, 8) broadcast, order [bearing][i][j]; `spin` (Omega), `w`: (n,),
/// rad/s; `force`: (n, nrhs, 4) or (1, nrhs, 4) broadcast; `out`: (n, nrhs, 4). Returns the
/// number of singular points (their output is NaN).
#[allow(clippy::too_many_arguments)]
pub fn forced_response(
    rotor: &Rotor,
    kb: &[f64],
    cb: &[f64],
    spin: &[f64],
    w: &[f64],
    force: &[C64],
    nrhs: usize,
    out: &mut [C64],
) -> Result<usize, CoreError> {
    let n = w.len();
    if nrhs == 0 {
        return Err(CoreError::value("nrhs", "must be at least 1 (one force vector per point)"));
    }
    expect_len("spin", spin, n)?;
    expect_len_or_broadcast("k", kb, 8, product("k", &[n, 8])?)?;
    expect_len_or_broadcast("c", cb, 8, product("c", &[n, 8])?)?;
    expect_len_or_broadcast("force", force, 4 * nrhs, product("force", &[n, nrhs, 4])?)?;
    expect_len("out", out, product("out", &[n, nrhs, 4])?)?;
    Ok(forced_kernel(rotor, kb, cb, spin, w, force, nrhs, out))
}

#[allow(clippy::too_many_arguments)]
fn forced_kernel(rotor: &Rotor, kb: &[f64], cb: &[f64], spin: &[f64], w: &[f64], force: &[C64], nrhs: usize, out: &mut [C64]) -> usize {
    let n = w.len();
    let broadcast = force.len() == nrhs * 4 && n != 1;
    let kbc = kb.len() == 8;
    let cbc = cb.len() == 8;
    let m = rotor.mass_matrix();
    let g = rotor.gyro_matrix();
    out.par_chunks_mut(nrhs * 4)
        .with_min_len(256)
        .enumerate()
        .map(|(i, o)| {
            let f = if broadcast { &force[..] } else { &force[i * nrhs * 4..(i + 1) * nrhs * 4] };
            o.copy_from_slice(f);
            let ki = if kbc { 0 } else { 8 * i };
            let ci = if cbc { 0 } else { 8 * i };
            let mut h = dynamic_stiffness(rotor, &m, &g, &kb[ki..ki + 8], &cb[ci..ci + 8], spin[i], w[i]);
            if solve4(&mut h, o) { 0usize } else { 1usize }
        })
        .sum()
}
