//! The covariance checks against their definition by eigenvalues (nalgebra's symmetric
//! eigen-decomposition as the reference).

use nalgebra::DMatrix;
use proptest::prelude::*;
use rotorid_core::covariance::{check_covariances, move_covariances, CovFault, RunCov, COV_TOL};

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

/// M Σ Mᵀ in full (M = [[A, B], [0, I]], Σ the dense joint 16 x 16 matrix), the moved blocks'
/// reference: (cov', cross').
fn moved_reference(a: &[f64], b: Option<&[f64]>, c: &[f64], p: &[f64], x: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let m16 = DMatrix::from_fn(16, 16, |i, j| match (i < 8, j < 8) {
        (true, true) => a[8 * i + j],
        (true, false) => b.map_or(0.0, |b| b[8 * i + j - 8]),
        (false, true) => 0.0,
        (false, false) => f64::from(u8::from(i == j)),
    });
    let s = DMatrix::from_fn(16, 16, |i, j| match (i < 8, j < 8) {
        (true, true) => c[8 * i + j],
        (true, false) => x.get(8 * i + j - 8).copied().unwrap_or(0.0),
        (false, true) => x.get(8 * j + i - 8).copied().unwrap_or(0.0),
        (false, false) => p.get(8 * (i - 8) + j - 8).copied().unwrap_or(0.0),
    });
    let out = &m16 * s * m16.transpose();
    ((0..64).map(|t| out[(t / 8, t % 8)]).collect(), (0..64).map(|t| out[(t / 8, 8 + t % 8)]).collect())
}

proptest! {
    #![proptest_config(cfg(60))]

    /// The moved blocks are M Σ Mᵀ's, with and without pedestal motion and a cross block, over
    /// more points than a task holds; the moved covariance exactly symmetric; a NaN anywhere in
    /// a point's blocks makes that point (only) NaN.
    #[test]
    fn moved_covariances_are_the_joint_congruence(seed in proptest::collection::vec(-1.0f64..1.0, 23), ped in any::<bool>(),
                                                  with_cross in any::<bool>(), nan_at in 0usize..1500) {
        let n = 1500;
        let gen = |off: usize, len: usize| -> Vec<f64> { (0..len).map(|i| seed[(i * 7 + off) % seed.len()] + 0.3 * ((i + off) as f64).sin()).collect() };
        let a = gen(1, 64);
        let b = gen(2, 64);
        // covariances A Aᵀ-like (symmetric), a cross block of any sign
        let sym = |v: Vec<f64>| -> Vec<f64> { v.chunks(64).flat_map(|m| (0..64).map(move |t| m[8 * (t / 8) + t % 8] + m[8 * (t % 8) + t / 8])).collect() };
        let mut c = sym(gen(3, n * 64));
        let p = if ped { sym(gen(4, n * 64)) } else { Vec::new() };
        let x = if ped && with_cross { gen(5, n * 64) } else { Vec::new() };
        c[64 * nan_at + 9] = f64::NAN;
        let (mut cov, mut cross) = (vec![0.0; n * 64], vec![0.0; if ped { n * 64 } else { 0 }]);
        let (af, bf): ([f64; 64], [f64; 64]) = (a.clone().try_into().unwrap(), b.clone().try_into().unwrap());
        move_covariances(&af, if ped { Some(&bf) } else { None }, RunCov { q: &c, ped: &p, cross: &x },
                         &mut cov, if ped { Some(&mut cross) } else { None }).unwrap();
        for k in 0..n {
            let blk = |v: &[f64]| -> Vec<f64> { if v.is_empty() { Vec::new() } else { v[64 * k..64 * k + 64].to_vec() } };
            if k == nan_at {
                prop_assert!(cov[64 * k..64 * k + 64].iter().chain(cross.get(64 * k..64 * k + 64).into_iter().flatten()).all(|v| v.is_nan()));
                continue;
            }
            let (want_c, want_x) = moved_reference(&a, if ped { Some(&b) } else { None }, &blk(&c), &blk(&p), &blk(&x));
            let big = want_c.iter().chain(&want_x).fold(0.0f64, |m, v| m.max(v.abs()));
            for t in 0..64 {
                prop_assert!((cov[64 * k + t] - want_c[t]).abs() <= 1e-13 * big, "cov {k} {t}");
                prop_assert_eq!(cov[64 * k + t].to_bits(), cov[64 * k + 8 * (t % 8) + t / 8].to_bits());
                if ped {
                    prop_assert!((cross[64 * k + t] - want_x[t]).abs() <= 1e-13 * big, "cross {k} {t}");
                }
            }
        }
    }
}

#[test]
fn moved_covariances_refuse_bad_arguments_by_name() {
    let eye: [f64; 64] = std::array::from_fn(|t| f64::from(u8::from(t / 8 == t % 8)));
    let mut bad = eye;
    bad[3] = f64::INFINITY;
    let c = vec![0.0; 128];
    let (mut cov, mut cross) = (vec![0.0; 128], vec![0.0; 128]);
    let rc = RunCov { q: &c, ped: &c, cross: &[] };
    let err = |r: Result<(), rotorid_core::CoreError>| r.unwrap_err().name();
    assert_eq!(err(move_covariances(&eye, None, RunCov { q: &c[..100], ped: &[], cross: &[] }, &mut cov, None)), "cov");
    assert_eq!(err(move_covariances(&bad, None, RunCov { ped: &[], ..rc }, &mut cov, None)), "maps");
    assert_eq!(err(move_covariances(&eye, Some(&eye), RunCov { ped: &c[..64], ..rc }, &mut cov, Some(&mut cross))), "pedestal_cov");
    assert_eq!(err(move_covariances(&eye, Some(&eye), RunCov { cross: &c[..64], ..rc }, &mut cov, Some(&mut cross))), "cross");
    assert_eq!(err(move_covariances(&eye, Some(&eye), rc, &mut cov, None)), "cross (out)");
    assert_eq!(err(move_covariances(&eye, None, rc, &mut cov, None)), "pedestal_cov");
    assert_eq!(err(move_covariances(&eye, None, RunCov { ped: &[], ..rc }, &mut cov[..64], None)), "cov (out)");
    move_covariances(&eye, Some(&eye), rc, &mut cov, Some(&mut cross)).unwrap();
}
