//! The covariance checks against their definition by eigenvalues (nalgebra's symmetric
//! eigen-decomposition as the reference).

use nalgebra::DMatrix;
use proptest::prelude::*;
use rotorid_core::covariance::{check_covariances, CovFault, COV_TOL};

fn cfg(cases: u32) -> ProptestConfig {
    ProptestConfig { cases, failure_persistence: None, ..ProptestConfig::default() }
}

/// Q diag(λ) Qᵀ with Q orthogonal (from the QR of a seeded matrix), row-major.
fn with_eigenvalues(lambda: &[f64], seed: &[f64]) -> Vec<f64> {
    let m = lambda.len();
    let a = DMatrix::from_fn(m, m, |i, j| seed[(i * m + j) % seed.len()] + 0.1 * ((i * 7 + j * 3) as f64).sin());
    let q = a.qr().q();
    let s = &q * DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(lambda)) * q.transpose();
    let mut out = vec![0.0; m * m];
    for i in 0..m {
        for j in 0..m {
            // exactly symmetric, as a covariance estimate is
            out[i * m + j] = 0.5 * (s[(i, j)] + s[(j, i)]);
        }
    }
    out
}

proptest! {
    #![proptest_config(cfg(200))]

    /// The verdict is the eigenvalue criterion λ_min(S) > -1e-9 ‖S‖_F, outside a thin band
    /// around the threshold where rounding decides.
    #[test]
    fn definiteness_is_the_eigenvalue_criterion(m in 1usize..17, seed in proptest::collection::vec(-1.0f64..1.0, 17),
                                                lam in proptest::collection::vec(0.0f64..1.0, 16),
                                                neg in -14.0f64..-3.0, scale in -30.0f64..10.0) {
        let mut lambda: Vec<f64> = lam[..m].iter().map(|v| v * 10f64.powf(scale)).collect();
        let top = lambda.iter().cloned().fold(0.0, f64::max);
        lambda[0] = -(10f64.powf(neg)) * top.max(1e-300);
        let a = with_eigenvalues(&lambda, &seed);
        let ev = DMatrix::from_row_slice(m, m, &a).symmetric_eigenvalues();
        let fro = a.iter().map(|v| v * v).sum::<f64>().sqrt();
        let tau = COV_TOL * fro.max(1e-300);
        let lmin = ev.iter().cloned().fold(f64::INFINITY, f64::min);
        let mut out = vec![0.0; m * m];
        let fault = check_covariances(&a, m, &mut out).unwrap();
        if lmin > -tau * (1.0 - 1e-4) {
            prop_assert_eq!(fault, None, "λ_min {:e}, τ {:e}", lmin, tau);
            prop_assert_eq!(&out, &a);
        } else if lmin < -tau * (1.0 + 1e-4) {
            prop_assert_eq!(fault, Some(CovFault::Indefinite(0)), "λ_min {:e}, τ {:e}", lmin, tau);
        }
    }
}

/// Faults come at the first point that shows them: inf anywhere before anything else, then an
/// asymmetric matrix before any indefinite one; unknown matrices (a NaN) are all NaN in the copy.
#[test]
fn faults_and_unknown_points() {
    let m = 8;
    let good = with_eigenvalues(&[1.0, 2.0, 0.5, 0.0, 3.0, 1e-3, 0.2, 0.0], &[0.3, -0.2, 0.9]);
    let indefinite = with_eigenvalues(&[1.0, 2.0, -1e-6, 0.0, 3.0, 1e-3, 0.2, 0.0], &[0.3, -0.2, 0.9]);
    let mut asym = good.clone();
    asym[3] += 1e-7;
    let mut nan = good.clone();
    nan[9] = f64::NAN;
    let mut inf = good.clone();
    inf[63] = f64::INFINITY;
    let stack = |ms: &[&Vec<f64>]| ms.iter().flat_map(|v| v.iter().cloned()).collect::<Vec<f64>>();
    let check = |c: Vec<f64>| {
        let mut out = vec![0.0; c.len()];
        let f = check_covariances(&c, m, &mut out).unwrap();
        (f, out)
    };
    let (f, out) = check(stack(&[&good, &nan, &good]));
    assert_eq!(f, None);
    assert!(out[64..128].iter().all(|v| v.is_nan()));
    assert_eq!(&out[..64], &good[..]);
    assert_eq!(check(stack(&[&good, &indefinite, &asym, &inf])).0, Some(CovFault::Infinite(3)));
    assert_eq!(check(stack(&[&good, &indefinite, &asym])).0, Some(CovFault::Asymmetric(2)));
    assert_eq!(check(stack(&[&good, &nan, &indefinite])).0, Some(CovFault::Indefinite(2)));
    // over many tasks: the first of several faults
    let mut many = Vec::new();
    for p in 0..3000 {
        many.extend_from_slice(if p == 2100 || p == 2900 || p == 700 + 2000 { &indefinite } else { &good });
    }
    assert_eq!(check(many).0, Some(CovFault::Indefinite(2100)));
    // a zero matrix is a covariance (known exactly)
    assert_eq!(check(vec![0.0; 64]).0, None);
    let mut out = vec![0.0; 64];
    assert_eq!(check_covariances(&good[..60], m, &mut out[..60]).unwrap_err().name(), "c");
    assert_eq!(check_covariances(&good, m, &mut out[..8]).unwrap_err().name(), "out");
    assert_eq!(check_covariances(&good, 0, &mut out).unwrap_err().name(), "m");
}

/// Unknown points: a NaN anywhere in a point's entries of any block, over more points than a
/// task holds; calls accumulate; a block whose size is not a multiple of the points is refused.
#[test]
fn unknown_points_are_found_in_every_block() {
    use rotorid_core::covariance::unknown_points;
    let n = 1500;
    let mut a = vec![1.0; n * 64];
    let mut b = vec![2.0; n * 64];
    a[64 * 7 + 63] = f64::NAN;
    b[64 * 1200] = f64::NAN;
    b[64 * 1499 + 5] = f64::NAN;
    let mut out = vec![false; n];
    unknown_points(&[&a, &b], &mut out).unwrap();
    let want: Vec<usize> = out.iter().enumerate().filter(|(_, &u)| u).map(|(k, _)| k).collect();
    assert_eq!(want, vec![7, 1200, 1499]);
    let mut c = vec![0.0; n * 3];
    c[3 * 10 + 2] = f64::NAN;
    unknown_points(&[&c], &mut out).unwrap();
    assert!(out[10] && out[7] && out.iter().filter(|&&u| u).count() == 4);
    assert_eq!(unknown_points(&[&c[..10]], &mut out).unwrap_err().name(), "blocks");
    let mut none: Vec<bool> = Vec::new();
    assert!(unknown_points(&[], &mut none).is_ok());
}
