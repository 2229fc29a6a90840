//! Standard errors of the identical-bearing estimate (Z1 = Z2 = Z) from its residuals, with the
//! structure of the equation errors.
//!
//! With identical bearings each row of Z (x: [Zxx, Zxy], y: [Zyx, Zyy]) is fitted to the
//! equations of both bearings of every run,
//!     [x_b  y_b]_r z = f_{b,r},   b = 1, 2,   r = 1..R,
//! stacked as X z = f (2R complex rows, 2 unknowns). Noise δq on the measured responses enters
//! both sides: the error of bearing b's equation is
//!     ε_b = (∂f_b/∂q) δq - z_x δx_b - z_y δy_b = B_b δq,
//! so with δq white and of one variance σ² per complex channel (the four alike), the two
//! equations of a run have the covariance σ² P, P = B Bᴴ (2 x 2, the same for every run at a
//! point), and the runs are independent. Least squares weighs both bearings' equations alike; its
//! error G⁻¹ Xᴴ ε (G = Xᴴ X) has the covariance
//!     V = σ² G⁻¹ S G⁻¹,   S = Σ_r X_rᴴ P X_r
//! (X_r: the run's two rows). The residual r = (I - H) ε, H = X G⁻¹ Xᴴ, has
//!     E|r|² = σ² tr M,   M = (I - H)(I_R ⊗ P),   tr M = R tr P - tr(G⁻¹ S),
//! which gives σ̂² = |r|² / tr M, and |r|² is close to a scaled χ² with
//!     ν = 2 (tr M)² / tr M²,   tr M² = R tr P² - 2 tr(G⁻¹ S₂) + tr((G⁻¹ S)²),   S₂ = Σ_r X_rᴴ P² X_r
//! real degrees of freedom (Satterthwaite; 2 per complex equation). For P = I (both equations
//! alike and independent) these are the plain s² = |r|² / (2R - 2) and 2 (2R - 2) dof of
//! [`identify_forces`](super::identify_forces), which treats the pooled equations so and, on the
//! NSF rig, gave standard errors 0.56-1.46 times the spread of the estimates (95 % intervals
//! covering 89-90 %).
//!
//! Responses measured at the probe planes take the noise as white at the probes: B is then B T,
//! with T the transform to the bearings ([`IdentProblem::planes`] when the problem holds the
//! responses at the probes, or `noise_planes` when they were moved to the bearings before). Noise
//! on the pedestal motion is not modelled.

use super::{force_point, load_q, motion_forces, sigma_at, Consts, IdentProblem, CHUNK};
use crate::error::{expect_len, product, CoreError};
use crate::model::C64;
use crate::par::Disjoint;

type M2 = [[C64; 2]; 2];

/// Outputs, all (batch, n, ...).
pub struct IdenticalStdOut<'a> {
    /// standard errors of K, (B, n, 8) as [`IdentOut`](super::IdentOut)'s (both bearings alike)
    pub k_std: &'a mut [f64],
    /// standard errors of C, (B, n, 8)
    pub c_std: &'a mut [f64],
    /// real degrees of freedom of the x row's and the y row's errors, (B, n, 2)
    pub dof: &'a mut [f64],
}

/// Residual-based standard errors of an identical-bearing identification (see the module's
/// documentation) at the estimate `k`, `c` ((B, n, 8), as
/// [`identify_forces`](super::identify_forces) returns them with `p.identical`; bearing 1's half
/// of each point is read). `noise_planes`: the transform [T11, T12, T21, T22] from the planes
/// where the noise is white to the bearings, for responses moved there before (None: white where
/// `p` holds them, at its `planes` or at the bearings). Points whose estimate is not finite, or
/// whose residual has no degree of freedom, get NaN.
pub fn identical_std(p: &IdentProblem, k: &[f64], c: &[f64], noise_planes: Option<[f64; 4]>, out: IdenticalStdOut) -> Result<(), CoreError> {
    p.check()?;
    if !p.identical {
        return Err(CoreError::value("identical", "identical_std is for an identical-bearing problem"));
    }
    let n = p.points();
    let points = product("points", &[p.batch, n])?;
    expect_len("k", k, product("k", &[points, 8])?)?;
    expect_len("c", c, points * 8)?;
    expect_len("k_std", out.k_std, points * 8)?;
    expect_len("c_std", out.c_std, points * 8)?;
    expect_len("dof", out.dof, points * 2)?;
    if noise_planes.is_some_and(|t| t.iter().any(|v| !v.is_finite())) {
        return Err(CoreError::value("noise_planes", "must be finite"));
    }
    let noise_t = noise_planes.or(p.planes);
    let kc = Consts::new(&p.rotor);
    let (ks, cs, dof) = (Disjoint::new(out.k_std), Disjoint::new(out.c_std), Disjoint::new(out.dof));
    crate::par::for_each_task(points.div_ceil(CHUNK), |j| {
        // SAFETY: for_each_task hands each chunk index j to one task
        let (ks, cs, dof) = unsafe { (ks.chunk(j, 8 * CHUNK), cs.chunk(j, 8 * CHUNK), dof.chunk(j, 2 * CHUNK)) };
        for (t, ((kso, cso), dofo)) in ks.chunks_exact_mut(8).zip(cs.chunks_exact_mut(8)).zip(dof.chunks_exact_mut(2)).enumerate() {
            let idx = j * CHUNK + t;
            let (b, i) = (idx / n, idx % n);
            let (sv, nu) = point(p, &kc, noise_t.as_ref(), b, i, &k[8 * idx..8 * idx + 8], &c[8 * idx..8 * idx + 8]);
            let w = p.w[i];
            let sg = sigma_at(p, i);
            // Z = K + s C = (K + sigma C) + j w C, its error circular: var K = var Re Z (1 + (sigma/w)^2)
            let kfac = (1.0 + (sg / w) * (sg / w)).sqrt();
            // [bearing][row][col], both bearings alike
            for (o, s) in sv.iter().flatten().chain(sv.iter().flatten()).enumerate() {
                kso[o] = s * kfac;
                cso[o] = s / w.abs();
            }
            dofo.copy_from_slice(&nu);
        }
    });
    Ok(())
}

/// (standard error of Re z per row and column, dof per row) of point i of batch member b, the
/// noise white where `noise_t` moves it from (None: at the bearings).
// (2 x 2 and 4 x 4 blocks indexed as in the formulas)
#[allow(clippy::too_many_arguments, clippy::needless_range_loop)]
fn point(p: &IdentProblem, kc: &Consts, noise_t: Option<&[f64; 4]>, b: usize, i: usize, k: &[f64], c: &[f64]) -> ([[f64; 2]; 2], [f64; 2]) {
    const NAN2: ([[f64; 2]; 2], [f64; 2]) = ([[f64::NAN; 2]; 2], [f64::NAN; 2]);
    let (w, sg) = (p.w[i], sigma_at(p, i));
    let spin = p.spin[if p.spin.len() == 1 { 0 } else { i }];
    // z[row][col] = (K + sigma C) + j w C of bearing 1 (= bearing 2)
    let zc = |o: usize| C64::new(k[o] + sg * c[o], w * c[o]);
    let z = [[zc(0), zc(1)], [zc(2), zc(3)]];
    if !z.iter().flatten().all(|v| v.re.is_finite() && v.im.is_finite()) {
        return NAN2;
    }
    // J[f][j] = d f / d q_j (forces [f1x, f2x, f1y, f2y], q [x1, x2, y1, y2] at the bearings),
    // times the probe planes' transform when q is measured there
    let mut jac = [[C64::new(0.0, 0.0); 4]; 4];
    for jq in 0..4 {
        let mut unit = [C64::new(0.0, 0.0); 4];
        unit[jq] = C64::new(1.0, 0.0);
        let f = motion_forces(kc, w, sg, spin, &unit);
        for fi in 0..4 {
            jac[fi][jq] = f[fi];
        }
    }
    // the runs' moments Q = sum_r conj(v_r) v_r^T of v_r = [x1, y1, x2, y2] (bearing-major, as
    // X_r's rows): G = sum_a Q[a][a] and S = sum_{a,b} P_ab Q[a][b] by 2 x 2 blocks, for both rows
    // without another pass over the runs
    let runs = p.runs;
    let mut mom = [[C64::new(0.0, 0.0); 4]; 4];
    let mut rss = [0.0f64; 2];
    for r in 0..runs {
        let q = load_q(p, b, r, i);
        let f = force_point(p, kc, b, r, i);
        let v = [q[0], q[2], q[1], q[3]];
        for m in 0..4 {
            let vm = v[m].conj();
            for n in m..4 {
                mom[m][n] += vm * v[n];
            }
        }
        for (bb, xrow) in v.chunks_exact(2).enumerate() {
            for row in 0..2 {
                // f index of (row, bearing): f1x, f2x, f1y, f2y
                let e = f[2 * row + bb] - z[row][0] * xrow[0] - z[row][1] * xrow[1];
                rss[row] += e.norm_sqr();
            }
        }
    }
    for m in 0..4 {
        for n in 0..m {
            mom[m][n] = mom[n][m].conj();
        }
    }
    // block (a, b) of the moments: [i][j] = Q[2a + i][2b + j]
    let block = |a: usize, bb: usize| -> M2 { [[mom[2 * a][2 * bb], mom[2 * a][2 * bb + 1]], [mom[2 * a + 1][2 * bb], mom[2 * a + 1][2 * bb + 1]]] };
    let mut g = block(0, 0);
    add(&mut g, &block(1, 1));
    // S = sum_{a,b} P_ab Q_ab for a 2 x 2 P
    let weighted = |pm: &M2| -> M2 {
        let mut o = [[C64::new(0.0, 0.0); 2]; 2];
        for a in 0..2 {
            for bb in 0..2 {
                let q = block(a, bb);
                for x in 0..2 {
                    for y in 0..2 {
                        o[x][y] += pm[a][bb] * q[x][y];
                    }
                }
            }
        }
        o
    };
    let det = (g[0][0] * g[1][1] - g[0][1] * g[1][0]).re;
    // a singular Gram matrix (or NaN): no standard error
    if det.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return NAN2;
    }
    let gi: M2 = [[g[1][1] / det, -g[0][1] / det], [-g[1][0] / det, g[0][0] / det]];
    let mut sv = [[f64::NAN; 2]; 2];
    let mut nu = [f64::NAN; 2];
    for row in 0..2 {
        // B[bearing][q]: d(equation error)/dq
        let mut bm = [[C64::new(0.0, 0.0); 4]; 2];
        for bb in 0..2 {
            bm[bb] = jac[2 * row + bb];
            bm[bb][bb] -= z[row][0];
            bm[bb][2 + bb] -= z[row][1];
            if let Some(t) = noise_t {
                // q_bearings = T q_probes per direction: the row vector times T, i.e. T's transpose
                // applied as planes_point applies T
                bm[bb] = crate::model::planes_point(&[t[0], t[2], t[1], t[3]], bm[bb]);
            }
        }
        let mut pm: M2 = [[C64::new(0.0, 0.0); 2]; 2];
        for a in 0..2 {
            for bb in 0..2 {
                pm[a][bb] = (0..4).map(|j| bm[a][j] * bm[bb][j].conj()).sum();
            }
        }
        let p2 = mul(&pm, &pm);
        let (s, s2) = (weighted(&pm), weighted(&p2));
        let a = mul(&gi, &s);
        let rf = runs as f64;
        let tr_p = pm[0][0].re + pm[1][1].re;
        let tr_m = rf * tr_p - (a[0][0].re + a[1][1].re);
        // tr P² = sum |P_ab|² (P Hermitian)
        let tr_p2 = pm.iter().flatten().map(|v| v.norm_sqr()).sum::<f64>();
        let gis2 = mul(&gi, &s2);
        let aa = mul(&a, &a);
        let tr_m2 = rf * tr_p2 - 2.0 * (gis2[0][0].re + gis2[1][1].re) + (aa[0][0].re + aa[1][1].re);
        // no residual degree of freedom (one run: tr M is rounding)
        if runs < 2 || !(tr_m > 1e-9 * rf * tr_p && tr_m2 > 0.0) {
            continue;
        }
        let v = mul(&a, &gi);
        let s2hat = rss[row] / tr_m;
        for col in 0..2 {
            // a circular complex error: half the variance in the real part
            sv[row][col] = (0.5 * s2hat * v[col][col].re).sqrt();
        }
        nu[row] = 2.0 * tr_m * tr_m / tr_m2;
    }
    (sv, nu)
}

#[inline(always)]
fn mul(a: &M2, b: &M2) -> M2 {
    let mut o = [[C64::new(0.0, 0.0); 2]; 2];
    for r in 0..2 {
        for c in 0..2 {
            o[r][c] = a[r][0] * b[0][c] + a[r][1] * b[1][c];
        }
    }
    o
}

#[inline(always)]
fn add(acc: &mut M2, a: &M2) {
    for r in 0..2 {
        for c in 0..2 {
            acc[r][c] += a[r][c];
        }
    }
}
