//! The pedestal fit with measurement covariances (`pedestal_cov`: weighted steps and the sandwich)
//! against a dense reference written here: the force Jacobian by differences of the public bearing
//! forces, every point's residual covariance V = G Σ Gᵀ as a full (2R x 2R) nalgebra matrix, the
//! whitened design stored whole and solved by SVD, (X_wᵀ X_w)⁻¹ and the sandwich by explicit
//! inverses.

mod common;

use common::*;
use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use rotorid_core::identify::{bearing_forces, IdentProblem};
use rotorid_core::pedestal_cov::{cov_fit, sandwich, weighted_step, CovFitProblem, RunCov};
use rotorid_core::pedestal_fit::PedestalFitProblem;
use rotorid_core::C64;

/// Deterministic pseudo-random values in [-0.5, 0.5).
fn values(count: usize, seed: u64) -> Vec<f64> {
    let mut state = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    (0..count)
        .map(|_| {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        })
        .collect()
}

struct Case {
    w: Vec<f64>,
    sigma: Vec<f64>,
    q: Vec<Vec<C64>>,
    p: Vec<Vec<C64>>,
    e: Vec<C64>,
    /// per run (q, ped, cross) blocks (n, 8, 8)
    cov: Vec<[Vec<f64>; 3]>,
    shared: Vec<f64>,
    runs: usize,
}

impl Case {
    fn new(runs: usize, n: usize, sigma: f64, shared: bool, seed: u64) -> Case {
        let w: Vec<f64> = (0..n).map(|i| 60.0 + 900.0 * i as f64 / n as f64).collect();
        let cplx = |v: Vec<f64>, s: f64| v.chunks(2).map(|x| c(s * x[0], s * x[1])).collect::<Vec<_>>();
        let q: Vec<Vec<C64>> = (0..runs).map(|r| cplx(values(8 * n, seed + r as u64), 1e-5)).collect();
        let p: Vec<Vec<C64>> = (0..runs).map(|r| cplx(values(8 * n, seed + 50 + r as u64), 1e-6)).collect();
        let e = (0..4 * runs).map(|i| c(1e-4 * (1.0 + i as f64), -2e-5 * i as f64)).collect();
        // joint covariances B Bᵀ (16 x 16) per run and point, plus a shared part
        let joint = |seed: u64, s: f64| -> Vec<f64> {
            let b = values(n * 256, seed);
            let mut out = vec![0.0; n * 256];
            for k in 0..n {
                for u in 0..16 {
                    for v in 0..16 {
                        let sc = |i: usize| if i < 8 { 1e-8 } else { 1e-9 };
                        out[256 * k + 16 * u + v] = s * sc(u) * sc(v) * (0..16).map(|t| b[256 * k + 16 * u + t] * b[256 * k + 16 * v + t]).sum::<f64>();
                    }
                }
            }
            out
        };
        let sh = if shared { joint(seed + 900, 0.3) } else { Vec::new() };
        let cov = (0..runs)
            .map(|r| {
                let mut j = joint(seed + 100 + r as u64, 1.0);
                for (a, s) in j.iter_mut().zip(sh.iter()) {
                    *a += s;
                }
                let block = |r0: usize, c0: usize| -> Vec<f64> {
                    (0..n).flat_map(|k| (0..64).map(move |t| (k, t))).map(|(k, t)| j[256 * k + 16 * (r0 + t / 8) + c0 + t % 8]).collect()
                };
                [block(0, 0), block(8, 8), block(0, 8)]
            })
            .collect();
        Case { sigma: if sigma == 0.0 { Vec::new() } else { vec![sigma; n] }, w, q, p, e, cov, shared: sh, runs }
    }

    fn forces<'a>(&'a self, q: &'a [&'a [C64]], p: &'a [&'a [C64]]) -> IdentProblem<'a> {
        IdentProblem { rotor: nsf_rotor(), w: &self.w, spin: &self.w, q, e: &self.e, gain: &[], sigma: &self.sigma, q_ped: p, planes: None, batch: 1, runs: self.runs, identical: false }
    }

    /// joint covariance of run r at point k (16 x 16)
    fn joint(&self, r: usize, k: usize) -> DMatrix<f64> {
        let [cq, cp, cx] = &self.cov[r];
        DMatrix::from_fn(16, 16, |u, v| match (u < 8, v < 8) {
            (true, true) => cq[64 * k + 8 * u + v],
            (false, false) => cp[64 * k + 8 * (u - 8) + v - 8],
            (true, false) => cx[64 * k + 8 * u + v - 8],
            (false, true) => cx[64 * k + 8 * v + u - 8],
        })
    }
}

/// Dense reference of fit `fi` at θ: (weighted θ, (X_wᵀ X_w)⁻¹, χ², resid at the new θ, sandwich).
fn reference(case: &Case, fi: usize, cross: bool, theta: &[f64]) -> (Vec<f64>, DMatrix<f64>, f64, f64, DMatrix<f64>) {
    let n = case.w.len();
    let runs = case.runs;
    let qs: Vec<&[C64]> = case.q.iter().map(|v| v.as_slice()).collect();
    let ps: Vec<&[C64]> = case.p.iter().map(|v| v.as_slice()).collect();
    let mut f = vec![c(0.0, 0.0); runs * n * 4];
    bearing_forces(&case.forces(&qs, &ps), &mut f).unwrap();
    // the Jacobian of the forces: unit motion in coordinate d (all runs), less the forces at rest
    let zero = vec![c(0.0, 0.0); 4 * n];
    let zs: Vec<&[C64]> = (0..runs).map(|_| zero.as_slice()).collect();
    let mut f0 = vec![c(0.0, 0.0); runs * n * 4];
    bearing_forces(&case.forces(&zs, &zs), &mut f0).unwrap();
    let mut a = vec![[c(0.0, 0.0); 4]; n]; // a[k][d] = dF_own/dq_d
    let (b, i) = (fi / 2, fi % 2);
    let (own, oth) = (2 * i + b, 2 * (1 - i) + b);
    for d in 0..4 {
        let unit: Vec<C64> = (0..4 * n).map(|t| if t % 4 == d { c(1.0, 0.0) } else { c(0.0, 0.0) }).collect();
        let us: Vec<&[C64]> = (0..runs).map(|_| unit.as_slice()).collect();
        let mut fu = vec![c(0.0, 0.0); runs * n * 4];
        bearing_forces(&case.forces(&us, &zs), &mut fu).unwrap();
        for k in 0..n {
            a[k][d] = fu[k * 4 + own] - f0[k * 4 + own];
        }
    }
    let u = if cross { 5 } else { 3 };
    let nr = 2 * runs;
    let (mut xw, mut yw, mut x, mut y) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut meat = DMatrix::<f64>::zeros(u, u);
    for k in 0..n {
        let s = c(if case.sigma.is_empty() { 0.0 } else { case.sigma[k] }, case.w[k]);
        let d_own = theta[0] + s * s * theta[1] + s * theta[2];
        let d_oth = if cross { theta[3] + s * theta[4] } else { c(0.0, 0.0) };
        let mut g = DMatrix::<f64>::zeros(2, 16);
        for d in 0..4 {
            let mut gp = a[k][d];
            if d == own {
                gp -= d_own;
            }
            if cross && d == oth {
                gp -= d_oth;
            }
            let j = c(0.0, 1.0);
            for (col, v) in [(d, a[k][d]), (4 + d, j * a[k][d]), (8 + d, gp), (12 + d, j * gp)] {
                g[(0, col)] = v.re;
                g[(1, col)] = v.im;
            }
        }
        let mut v = DMatrix::<f64>::zeros(nr, nr);
        for r in 0..runs {
            for t in 0..runs {
                let sig = if r == t {
                    case.joint(r, k)
                } else if !case.shared.is_empty() {
                    DMatrix::from_row_slice(16, 16, &case.shared[256 * k..256 * (k + 1)])
                } else {
                    continue;
                };
                v.view_mut((2 * r, 2 * t), (2, 2)).copy_from(&(&g * sig * g.transpose()));
            }
        }
        let mut xk = DMatrix::<f64>::zeros(nr, u);
        let mut yk = DVector::<f64>::zeros(nr);
        for r in 0..runs {
            let pk = &case.p[r][4 * k..4 * k + 4];
            let mut cols = vec![pk[own], s * s * pk[own], s * pk[own]];
            if cross {
                cols.extend([pk[oth], s * pk[oth]]);
            }
            for (j, z) in cols.iter().enumerate() {
                xk[(2 * r, j)] = z.re;
                xk[(2 * r + 1, j)] = z.im;
            }
            yk[2 * r] = f[(r * n + k) * 4 + own].re;
            yk[2 * r + 1] = f[(r * n + k) * 4 + own].im;
        }
        meat += xk.transpose() * &v * &xk;
        let l = (v + DMatrix::identity(nr, nr) * 1e-300).cholesky().unwrap().l();
        let lx = l.solve_lower_triangular(&xk).unwrap();
        let ly = l.solve_lower_triangular(&yk).unwrap();
        for row in 0..nr {
            xw.push((0..u).map(|j| lx[(row, j)]).collect::<Vec<_>>());
            yw.push(ly[row]);
            x.push((0..u).map(|j| xk[(row, j)]).collect::<Vec<_>>());
            y.push(yk[row]);
        }
    }
    let m = xw.len();
    let xm = DMatrix::from_fn(m, u, |r, j| x[r][j]);
    let scale: Vec<f64> = (0..u).map(|j| xm.column(j).amax().max(1e-300)).collect();
    let xws = DMatrix::from_fn(m, u, |r, j| xw[r][j] / scale[j]);
    let ywv = DVector::from_vec(yw);
    let ths = xws.clone().svd(true, true).solve(&ywv, 0.0).unwrap();
    let theta_w: Vec<f64> = (0..u).map(|j| ths[j] / scale[j]).collect();
    let xtxi_w = (xws.transpose() * &xws).try_inverse().unwrap();
    let cov_w = DMatrix::from_fn(u, u, |a1, j| xtxi_w[(a1, j)] / (scale[a1] * scale[j]));
    let rw = &ywv - &xws * &ths;
    let chi2 = rw.norm_squared() / (m - u) as f64;
    let yv = DVector::from_vec(y);
    let r = &yv - &xm * DVector::from_vec(theta_w.clone());
    let xtxi = (xm.transpose() * &xm).try_inverse().unwrap();
    let sand = &xtxi * meat * &xtxi;
    (theta_w, cov_w, chi2, r.norm() / yv.norm(), sand)
}

fn close(a: f64, b: f64, rtol: f64, atol: f64) -> bool {
    (a - b).abs() <= rtol * b.abs() + atol
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 16, failure_persistence: None, ..ProptestConfig::default() })]

    /// One weighted step and the sandwich of every fit equal the dense reference, for 1-3 runs,
    /// with and without a shared covariance, windowed or not, 3 or 5 unknowns, over more points than
    /// a task holds.
    #[test]
    fn steps_match_the_dense_reference(runs in 1usize..4, n in 3usize..1200, cross in any::<bool>(),
                                       shared in any::<bool>(), sigma in prop_oneof![Just(0.0), 1.0f64..30.0],
                                       seed in 0u64..1000) {
        let u = if cross { 5 } else { 3 };
        prop_assume!(2 * runs * n > u + 2);
        let case = Case::new(runs, n, sigma, shared, seed);
        let qs: Vec<&[C64]> = case.q.iter().map(|v| v.as_slice()).collect();
        let ps: Vec<&[C64]> = case.p.iter().map(|v| v.as_slice()).collect();
        let covs: Vec<RunCov> = case.cov.iter().map(|[a, b, x]| RunCov { q: a, ped: b, cross: x }).collect();
        let prob = CovFitProblem { fit: PedestalFitProblem { forces: case.forces(&qs, &ps), select: &[], cross }, covs: &covs, shared: &case.shared };
        let theta: Vec<f64> = [2e7, 20.0, 4e3, 1e6, 300.0][..u].to_vec();
        let thetas: Vec<Vec<f64>> = (0..4).map(|fi| theta.iter().map(|v| v * (1.0 + 0.1 * fi as f64)).collect()).collect();
        let steps = weighted_step(&prob, &thetas, true).unwrap();
        let sws = sandwich(&prob, &thetas).unwrap();
        for fi in 0..4 {
            let (th_ref, cov_ref, chi2_ref, resid_ref, sand_ref) = reference(&case, fi, cross, &thetas[fi]);
            let step = &steps[fi];
            prop_assert_eq!(step.rank, u);
            for j in 0..u {
                prop_assert!(close(step.theta[j], th_ref[j], 1e-7, 1e-9 * th_ref.iter().fold(0.0f64, |a, v| a.max(v.abs()))),
                             "fit {} theta[{}]: {} vs {}", fi, j, step.theta[j], th_ref[j]);
            }
            for a1 in 0..u {
                for j in 0..u {
                    let big = (cov_ref[(a1, a1)] * cov_ref[(j, j)]).sqrt();
                    prop_assert!(close(step.cov[a1 * u + j], cov_ref[(a1, j)], 1e-7, 1e-9 * big), "fit {} cov", fi);
                }
            }
            prop_assert!(close(step.chi2, chi2_ref, 1e-6, 1e-12), "chi2 {} vs {}", step.chi2, chi2_ref);
            prop_assert!(close(step.resid, resid_ref, 1e-6, 1e-14), "resid {} vs {}", step.resid, resid_ref);
            let sw = &sws[fi];
            for a1 in 0..u {
                for j in 0..u {
                    let big = (sand_ref[(a1, a1)] * sand_ref[(j, j)]).sqrt();
                    prop_assert!(close(sw[a1 * u + j], sand_ref[(a1, j)], 1e-7, 1e-9 * big), "fit {} sandwich", fi);
                }
            }
        }
    }
}

/// The weighted fit's θ does not depend on the covariances' overall size; its covariance scales
/// with it (until χ² < 1 stops the widening); and argument errors name the argument.
#[test]
fn scaling_the_covariances_and_argument_errors() {
    let case = Case::new(2, 40, 0.0, false, 3);
    let qs: Vec<&[C64]> = case.q.iter().map(|v| v.as_slice()).collect();
    let ps: Vec<&[C64]> = case.p.iter().map(|v| v.as_slice()).collect();
    let scaled: Vec<[Vec<f64>; 3]> = case.cov.iter().map(|blocks| blocks.clone().map(|b| b.iter().map(|v| v * 4.0).collect())).collect();
    let run = |cov: &[[Vec<f64>; 3]]| {
        let covs: Vec<RunCov> = cov.iter().map(|[a, b, x]| RunCov { q: a, ped: b, cross: x }).collect();
        let prob = CovFitProblem { fit: PedestalFitProblem { forces: case.forces(&qs, &ps), select: &[], cross: false }, covs: &covs, shared: &[] };
        weighted_step(&prob, &vec![vec![2e7, 20.0, 4e3]; 4], false).unwrap().remove(1)
    };
    let (a, b) = (run(&case.cov), run(&scaled));
    assert!(a.resid.is_nan());
    for j in 0..3 {
        assert!(close(a.theta[j], b.theta[j], 1e-9, 0.0));
        assert!(close(b.cov[4 * j], 4.0 * a.cov[4 * j], 1e-9, 0.0));
    }
    assert!(close(b.chi2, a.chi2 / 4.0, 1e-9, 0.0));

    let covs: Vec<RunCov> = case.cov.iter().map(|[a, b, x]| RunCov { q: a, ped: b, cross: x }).collect();
    let fit = PedestalFitProblem { forces: case.forces(&qs, &ps), select: &[], cross: false };
    let prob = CovFitProblem { fit, covs: &covs, shared: &[] };
    let ones = vec![vec![1.0; 3]; 4];
    assert_eq!(weighted_step(&prob, &ones[..3], false).unwrap_err().name(), "thetas");
    assert_eq!(weighted_step(&prob, &vec![vec![1.0; 2]; 4], false).unwrap_err().name(), "theta");
    assert_eq!(sandwich(&prob, &vec![vec![1.0, f64::NAN, 1.0]; 4]).unwrap_err().name(), "theta");
    let prob = CovFitProblem { covs: &covs[..1], ..prob };
    assert_eq!(weighted_step(&prob, &ones, false).unwrap_err().name(), "covs (runs)");
    let short = [RunCov { q: &covs[0].q[..64], ..covs[0] }, covs[1]];
    let prob = CovFitProblem { covs: &short, ..prob };
    assert_eq!(weighted_step(&prob, &ones, false).unwrap_err().name(), "covs (q)");
    let prob = CovFitProblem { covs: &covs, shared: &[0.0; 10], ..prob };
    assert_eq!(cov_fit(&prob, &vec![vec![1.0; 3]; 4], true).unwrap_err().name(), "shared");
    let prob = CovFitProblem { shared: &[], ..prob };
    assert_eq!(cov_fit(&prob, &vec![vec![1.0; 3]; 3], true).unwrap_err().name(), "thetas");
    assert_eq!(cov_fit(&prob, &vec![vec![1.0; 3]; 3], false).unwrap_err().name(), "thetas");
}
