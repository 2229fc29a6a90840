//! Batched eigen-analysis of the rotor-bearing system (state-space form of eq. 1 without forcing).

use crate::error::{expect_len, product, CoreError};
use crate::forced::solve4_near_singular;
use crate::model::{assemble, Rotor, C64};
use faer::Mat;
use rayon::prelude::*;

/// Invert a real 4x4 matrix (Gauss-Jordan with partial pivoting).
fn inv4(a: &[[f64; 4]; 4]) -> Option<[[f64; 4]; 4]> {
    let mut m = *a;
    let mut inv = [[0.0; 4]; 4];
    for i in 0..4 {
        inv[i][i] = 1.0;
    }
    for k in 0..4 {
        let mut p = k;
        for i in (k + 1)..4 {
            if m[i][k].abs() > m[p][k].abs() {
                p = i;
            }
        }
        if m[p][k] == 0.0 {
            return None;
        }
        m.swap(p, k);
        inv.swap(p, k);
        let d = 1.0 / m[k][k];
        for j in 0..4 {
            m[k][j] *= d;
            inv[k][j] *= d;
        }
        for i in 0..4 {
            if i != k {
                let f = m[i][k];
                for j in 0..4 {
                    m[i][j] -= f * m[k][j];
                    inv[i][j] -= f * inv[k][j];
                }
            }
        }
    }
    Some(inv)
}

/// Balance a square matrix in place by a diagonal similarity D^-1 A D with powers of two (the
/// scaling loop of LAPACK's dgebal, without permutations). Returns D.
fn balance(a: &mut Mat<f64>) -> Vec<f64> {
    let n = a.nrows();
    let mut d = vec![1.0; n];
    let radix = 2.0f64;
    for _ in 0..100 {
        let mut done = true;
        for i in 0..n {
            let (mut c, mut r) = (0.0, 0.0);
            for j in 0..n {
                if j != i {
                    c += a[(j, i)].abs();
                    r += a[(i, j)].abs();
                }
            }
            if c == 0.0 || r == 0.0 {
                continue;
            }
            let s = c + r;
            let mut f = 1.0;
            let (mut cc, mut rr) = (c, r);
            while cc < rr / radix {
                cc *= radix;
                rr /= radix;
                f *= radix;
            }
            while cc >= rr * radix {
                cc /= radix;
                rr *= radix;
                f /= radix;
            }
            if (cc + rr) < 0.95 * s {
                done = false;
                d[i] *= f;
                for j in 0..n {
                    a[(i, j)] /= f;
                    a[(j, i)] *= f;
                }
            }
        }
        if done {
            break;
        }
    }
    d
}

/// For each point: eigenvalues with positive imaginary part (up to 4, sorted by damped natural
/// frequency, NaN-padded when a mode is overdamped) and the displacement part of their
/// eigenvectors (order [x1, x2, y1, y2], normalized to unit largest component, real at that
/// component). `lam`: (n, 4); `shapes`: (n, 4 modes, 4 dofs). Returns the number of points where
/// the eigen-solver failed (NaN output).
pub fn modal(rotor: &Rotor, kb: &[f64], cb: &[f64], spin: &[f64], lam: &mut [C64], shapes: &mut [C64]) -> Result<usize, CoreError> {
    let n = spin.len();
    expect_len("k", kb, product("k", &[n, 8])?)?;
    expect_len("c", cb, n * 8)?;
    expect_len("lam", lam, product("lam", &[n, 4])?)?;
    expect_len("shapes", shapes, product("shapes", &[n, 16])?)?;
    Ok(modal_kernel(rotor, kb, cb, spin, lam, shapes))
}

fn modal_kernel(rotor: &Rotor, kb: &[f64], cb: &[f64], spin: &[f64], lam: &mut [C64], shapes: &mut [C64]) -> usize {
    let m = rotor.mass_matrix();
    let g = rotor.gyro_matrix();
    let minv = match inv4(&m) {
        Some(v) => v,
        None => {
            for v in lam.iter_mut().chain(shapes.iter_mut()) {
                *v = C64::new(f64::NAN, f64::NAN);
            }
            return spin.len();
        }
    };
    lam.par_chunks_mut(4)
        .zip(shapes.par_chunks_mut(16))
        .enumerate()
        .map(|(i, (lo, so))| {
            let k = assemble(&kb[8 * i..8 * i + 8], rotor.l1, rotor.l2);
            let c = assemble(&cb[8 * i..8 * i + 8], rotor.l1, rotor.l2);
            let mut a = Mat::<f64>::zeros(8, 8);
            for r in 0..4 {
                a[(r, 4 + r)] = 1.0;
                for col in 0..4 {
                    let mut sk = 0.0;
                    let mut sc = 0.0;
                    for t in 0..4 {
                        sk += minv[r][t] * k[t][col];
                        sc += minv[r][t] * (c[t][col] + spin[i] * g[t][col]);
                    }
                    a[(4 + r, col)] = -sk;
                    a[(4 + r, 4 + col)] = -sc;
                }
            }
            for v in lo.iter_mut().chain(so.iter_mut()) {
                *v = C64::new(f64::NAN, f64::NAN);
            }
            // balance (LAPACK-style diagonal similarity with powers of 2): the state matrix of a
            // stiff, heavily damped rotor spans many decades, and unbalanced eigenvalues came
            // out ~3e-7 relative off (checked against 40-digit mpmath)
            let dscale = balance(&mut a);
            let evd = match a.eigen() {
                Ok(e) => e,
                Err(_) => return 1usize,
            };
            let s = evd.S().column_vector();
            let u = evd.U();
            let mut idx: Vec<usize> = (0..8).filter(|&t| s[t].im > 1e-9 * s[t].norm().max(1e-300)).collect();
            idx.sort_by(|&x, &y| s[x].im.partial_cmp(&s[y].im).unwrap_or(std::cmp::Ordering::Equal));
            for (mi, &t) in idx.iter().take(4).enumerate() {
                lo[mi] = C64::new(s[t].re, s[t].im);
                let mut v = [C64::new(0.0, 0.0); 4];
                for d in 0..4 {
                    v[d] = C64::new(u[(d, t)].re, u[(d, t)].im) * dscale[d];
                }
                // Two steps of inverse iteration on D(lam) = lam^2 M + lam (C + Omega G) + K with a
                // relative shift of 1e-12: the Schur-based eigenvectors of (nearly) repeated
                // eigenvalues can be poor (residual 1e-5 relative seen); this restores them.
                let lam_s = lo[mi] * (1.0 + 1e-12);
                for _ in 0..2 {
                    let mut dm = [[C64::new(0.0, 0.0); 4]; 4];
                    for r in 0..4 {
                        for col in 0..4 {
                            dm[r][col] = lam_s * lam_s * m[r][col] + lam_s * (c[r][col] + spin[i] * g[r][col]) + k[r][col];
                        }
                    }
                    let mut y = v;
                    if !solve4_near_singular(&mut dm, &mut y) {
                        break;
                    }
                    let nrm = y.iter().map(|z| z.norm_sqr()).sum::<f64>().sqrt();
                    if !(nrm > 0.0 && nrm.is_finite()) {
                        break;
                    }
                    for d in 0..4 {
                        v[d] = y[d] / nrm;
                    }
                }
                let best = (0..4).fold(0, |b, d| if v[d].norm() > v[b].norm() { d } else { b });
                let piv = v[best];
                let scale = if piv.norm() > 0.0 { 1.0 / piv } else { C64::new(1.0, 0.0) };
                for d in 0..4 {
                    so[4 * mi + d] = v[d] * scale;
                }
            }
            0usize
        })
        .sum()
}
