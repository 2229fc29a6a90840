//! The pedestal fit (`pedestal_fit::fit`: streamed QR, HC3 from a second pass) against a dense
//! reference written here: the design matrix stored whole, solved through nalgebra's SVD, the HC3
//! covariance from the explicit (XᵀX)⁻¹ and hat-matrix diagonal.

mod common;

use common::*;
use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use rotorid_core::identify::{bearing_forces, IdentProblem};
use rotorid_core::lsq::{Solution, TallQr};
use rotorid_core::pedestal_fit::{fit, PedestalFitProblem};
use rotorid_core::{CoreError, C64};

/// Responses of `runs` runs at `n` points: smooth in the point index, distinct per run, with a
/// pseudo-random wobble so that the columns of the design are independent.
fn motions(runs: usize, n: usize, scale: f64, seed: u64) -> Vec<Vec<C64>> {
    let mut state = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    let mut next = move || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    };
    (0..runs)
        .map(|_| (0..4 * n).map(|_| c(scale * next(), scale * next())).collect())
        .collect()
}

struct Case {
    w: Vec<f64>,
    spin: Vec<f64>,
    sigma: Vec<f64>,
    q: Vec<Vec<C64>>,
    p: Vec<Vec<C64>>,
    e: Vec<C64>,
    runs: usize,
}

impl Case {
    fn new(runs: usize, n: usize, sigma: f64, seed: u64) -> Case {
        let w: Vec<f64> = (0..n).map(|i| 50.0 + 1500.0 * i as f64 / n as f64).collect();
        let sig = if sigma == 0.0 { Vec::new() } else { vec![sigma; n] };
        let e = (0..4 * runs).map(|i| c(1e-4 * (1.0 + i as f64), -2e-5 * i as f64)).collect();
        Case { spin: w.clone(), w, sigma: sig, q: motions(runs, n, 1e-5, seed), p: motions(runs, n, 1e-6, seed + 7), e, runs }
    }

    fn problem<'a>(&'a self, q: &'a [&'a [C64]], p: &'a [&'a [C64]]) -> IdentProblem<'a> {
        IdentProblem {
            rotor: nsf_rotor(),
            w: &self.w,
            spin: &self.spin,
            q,
            e: &self.e,
            gain: &[],
            sigma: &self.sigma,
            q_ped: p,
            planes: None,
            batch: 1,
            runs: self.runs,
            identical: false,
        }
    }
}

/// Dense reference of fit (b, i): (θ, HC3 covariance, rank, relative residual).
fn reference(case: &Case, select: &[bool], cross: bool, fi: usize) -> (Vec<f64>, DMatrix<f64>, usize, f64) {
    let q: Vec<&[C64]> = case.q.iter().map(|v| v.as_slice()).collect();
    let p: Vec<&[C64]> = case.p.iter().map(|v| v.as_slice()).collect();
    let prob = case.problem(&q, &p);
    let n = case.w.len();
    let mut forces = vec![c(0.0, 0.0); case.runs * n * 4];
    bearing_forces(&prob, &mut forces).unwrap();
    let (b, i) = (fi / 2, fi % 2);
    let (own, oth) = (2 * i + b, 2 * (1 - i) + b);
    let u = if cross { 5 } else { 3 };
    let mut rows: Vec<Vec<f64>> = Vec::new();
    let mut y: Vec<f64> = Vec::new();
    for r in 0..case.runs {
        for k in (0..n).filter(|&k| select.is_empty() || select[k]) {
            let s = c(if case.sigma.is_empty() { 0.0 } else { case.sigma[k] }, case.w[k]);
            let pk = &case.p[r][4 * k..4 * k + 4];
            let mut cols = vec![pk[own], s * s * pk[own], s * pk[own]];
            if cross {
                cols.extend([pk[oth], s * pk[oth]]);
            }
            let f = forces[(r * n + k) * 4 + own];
            rows.push(cols.iter().map(|z| z.re).collect());
            y.push(f.re);
            rows.push(cols.iter().map(|z| z.im).collect());
            y.push(f.im);
        }
    }
    let m = rows.len();
    let x = DMatrix::from_fn(m, u, |a, j| rows[a][j]);
    let scale: Vec<f64> = (0..u).map(|j| x.column(j).amax().max(1e-300)).collect();
    let xs = DMatrix::from_fn(m, u, |a, j| x[(a, j)] / scale[j]);
    let yv = DVector::from_vec(y.clone());
    let svd = xs.clone().svd(true, true);
    let smax = svd.singular_values.max();
    let rank = svd.singular_values.iter().filter(|&&s| s > f64::EPSILON * m.max(u) as f64 * smax).count();
    let ths = svd.solve(&yv, 0.0).unwrap();
    let xtxi = (xs.transpose() * &xs).try_inverse().unwrap();
    let r = &yv - &xs * &ths;
    let mut meat = DMatrix::zeros(u, u);
    for a in 0..m {
        let xa = xs.row(a).transpose();
        let h = (xa.transpose() * &xtxi * &xa)[(0, 0)];
        let wgt = (r[a] / (1.0 - h).max(1e-12)).powi(2);
        meat += &xa * xa.transpose() * wgt;
    }
    let cov_s = &xtxi * meat * &xtxi;
    let cov = DMatrix::from_fn(u, u, |a, j| cov_s[(a, j)] / (scale[a] * scale[j]));
    let theta = (0..u).map(|j| ths[j] / scale[j]).collect();
    (theta, cov, rank, r.norm() / yv.norm())
}

fn run_fit(case: &Case, select: &[bool], cross: bool) -> Result<Vec<rotorid_core::pedestal_fit::DirectionFit>, CoreError> {
    let q: Vec<&[C64]> = case.q.iter().map(|v| v.as_slice()).collect();
    let p: Vec<&[C64]> = case.p.iter().map(|v| v.as_slice()).collect();
    fit(&PedestalFitProblem { forces: case.problem(&q, &p), select, cross })
}

fn close(a: f64, b: f64, rtol: f64, atol: f64) -> bool {
    (a - b).abs() <= rtol * b.abs() + atol
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    #[test]
    fn fit_matches_the_dense_reference(runs in 1usize..4, n in 3usize..5000, cross in any::<bool>(),
                                       sigma in prop_oneof![Just(0.0), 1.0f64..30.0], seed in 0u64..1000,
                                       drop in 0usize..4) {
        let case = Case::new(runs, n, sigma, seed);
        // every `drop`-th point left out (none for 0)
        let select: Vec<bool> = if drop == 0 { Vec::new() } else { (0..n).map(|k| k % (drop + 1) != 0).collect() };
        let kept = if select.is_empty() { n } else { select.iter().filter(|&&v| v).count() };
        let u = if cross { 5 } else { 3 };
        prop_assume!(2 * runs * kept > u);
        let fits = run_fit(&case, &select, cross).unwrap();
        for (fi, got) in fits.iter().enumerate() {
            let (theta, cov, rank, resid) = reference(&case, &select, cross, fi);
            prop_assert_eq!(got.rank, rank);
            prop_assert_eq!(got.rows, 2 * runs * kept);
            if rank < u {
                prop_assert!(got.theta.iter().all(|v| v.is_nan()));
                continue;
            }
            for j in 0..u {
                let sd = cov[(j, j)].sqrt();
                // random data: θ is poorly determined, compare on its standard error's scale
                prop_assert!(close(got.theta[j], theta[j], 1e-9, 1e-9 * sd), "theta {}: {} vs {}", j, got.theta[j], theta[j]);
                for l in 0..u {
                    let bound = 1e-8 * (cov[(j, j)] * cov[(l, l)]).sqrt();
                    prop_assert!(close(got.cov[j * u + l], cov[(j, l)], 1e-8, bound), "cov {},{}: {} vs {}", j, l, got.cov[j * u + l], cov[(j, l)]);
                }
            }
            prop_assert!(close(got.resid, resid, 1e-10, 1e-14));
        }
    }
}

#[test]
fn results_repeat_bit_for_bit_on_one_or_two_threads() {
    let case = Case::new(3, 9000, 5.0, 3);
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap().install(|| run_fit(&case, &[], true).unwrap());
    let two = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap().install(|| run_fit(&case, &[], true).unwrap());
    for (a, b) in one.iter().zip(&two) {
        assert_eq!(a.theta, b.theta);
        assert_eq!(a.cov, b.cov);
        assert_eq!(a.resid, b.resid);
    }
}

#[test]
fn bad_arguments_are_errors_not_panics() {
    let case = Case::new(2, 10, 0.0, 1);
    let q: Vec<&[C64]> = case.q.iter().map(|v| v.as_slice()).collect();
    let p: Vec<&[C64]> = case.p.iter().map(|v| v.as_slice()).collect();
    // no pedestal motion
    let err = fit(&PedestalFitProblem { forces: case.problem(&q, &[]), select: &[], cross: false }).unwrap_err();
    assert_eq!(err.name(), "q_ped");
    // a selection of the wrong length
    let sel = [true; 9];
    let err = fit(&PedestalFitProblem { forces: case.problem(&q, &p), select: &sel, cross: false }).unwrap_err();
    assert_eq!(err.name(), "select");
    // too few equations: one point of one run gives 2 equations for 3 unknowns
    let mut one = [false; 10];
    one[4] = true;
    let single = Case::new(1, 10, 0.0, 1);
    let q1: Vec<&[C64]> = single.q.iter().map(|v| v.as_slice()).collect();
    let p1: Vec<&[C64]> = single.p.iter().map(|v| v.as_slice()).collect();
    let err = fit(&PedestalFitProblem { forces: single.problem(&q1, &p1), select: &one, cross: false }).unwrap_err();
    assert!(err.to_string().contains("2 equations for 3 unknowns"), "{err}");
    // a NaN in the pedestal motion, and one in the response (through the forces)
    for which in 0..2 {
        let mut bad = Case::new(2, 10, 0.0, 1);
        if which == 0 { bad.p[1][13] = c(f64::NAN, 0.0) } else { bad.q[0][5] = c(0.0, f64::INFINITY) }
        let err = run_fit(&bad, &[], false).unwrap_err();
        assert_eq!(err.to_string(), "runs contain NaN or inf");
    }
    // a batch of two
    let mut prob = case.problem(&q, &p);
    prob.batch = 2;
    assert!(fit(&PedestalFitProblem { forces: prob, select: &[], cross: false }).is_err());
}

#[test]
fn no_motion_in_one_direction_is_rank_deficient_there_only() {
    let mut case = Case::new(2, 50, 0.0, 9);
    for r in 0..2 {
        for k in 0..50 {
            case.p[r][4 * k + 2] = c(0.0, 0.0); // y of pedestal 1
        }
    }
    let fits = run_fit(&case, &[], false).unwrap();
    assert_eq!(fits[1].rank, 0); // (1, y): every column zero
    assert!(fits[1].theta.iter().all(|v| v.is_nan()));
    assert_eq!(fits[0].rank, 3);
}

#[test]
fn tall_qr_rejects_blocks_that_do_not_fit() {
    let mut qr = TallQr::new(3).unwrap();
    let mut block = vec![0.0; 10];
    assert!(qr.fold_block(&mut block, 4, 5).is_err()); // more rows than the leading dimension
    assert!(qr.fold_block(&mut block, 4, 4).is_err()); // 3 columns of 4 need 12 values
    let mut ok = vec![1.0, 2.0, 3.0, 4.0, 0.5, 0.25, 1.0, 2.0, 3.0];
    qr.fold_block(&mut ok, 3, 3).unwrap();
    assert_eq!(qr.rows(), 3);
    let sol = Solution::from_factor(&qr.factor(), 3, 3).unwrap();
    assert_eq!(sol.rank, 2);
    // a block that ends right after its last column's rows (no room for a full last column)
    let mut a = TallQr::new(2).unwrap();
    let mut b = TallQr::new(2).unwrap();
    let full = [1.0, 2.0, 3.0, 0.0, 5.0, 7.0, 11.0, 0.0];
    let mut whole = full;
    a.fold_block(&mut whole, 4, 3).unwrap();
    let mut short = full[..7].to_vec();
    b.fold_block(&mut short, 4, 3).unwrap();
    assert_eq!(a.factor(), b.factor());
}
