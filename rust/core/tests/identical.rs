//! Properties of the identical-bearing standard errors (identify::identical): exact invariances of
//! the formulas, and their refusals. The values themselves are checked against a dense NumPy
//! oracle and by Monte Carlo coverage in tests/test_identical_std.py.

mod common;

use common::*;
use proptest::prelude::*;
use rotorid_core::identify::identical::{identical_std, IdenticalStdOut};
use rotorid_core::identify::{identify_forces, IdentOut, IdentProblem};
use rotorid_core::{Rotor, C64};

fn cfg(cases: u32) -> ProptestConfig {
    ProptestConfig { cases, failure_persistence: None, ..ProptestConfig::default() }
}

/// Identical bearings' coefficients: bearing 1's copied to bearing 2.
fn identical(k: &[f64], cc: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let (mut k2, mut c2) = (k.to_vec(), cc.to_vec());
    k2.copy_within(0..4, 4);
    c2.copy_within(0..4, 4);
    (k2, c2)
}

/// Noisy responses of `runs` imbalance runs of an identical-bearing rotor at `w`.
fn noisy_runs(r: &Rotor, k: &[f64], cc: &[f64], w: &[f64], e: &[C64], noise: &[f64]) -> Vec<C64> {
    let mut q = imbalance_responses(r, k, cc, w, e);
    let scale = q.iter().map(|v| v.norm()).fold(0.0, f64::max);
    for (v, d) in q.iter_mut().zip(noise.chunks(2).cycle()) {
        *v += c(d[0], d[1]) * (0.02 * scale);
    }
    q
}

/// (k, c) of the identification, then (k_std, c_std, dof) of identical_std.
fn both(p: &IdentProblem) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let n = p.batch * p.w.len();
    let (mut k, mut cc, mut cond, mut resid, mut amp) = (vec![0.0; 8 * n], vec![0.0; 8 * n], vec![0.0; 2 * n], vec![0.0; n], vec![0.0; n]);
    identify_forces(p, IdentOut { k: &mut k, c: &mut cc, cond: &mut cond, resid: &mut resid, amp: &mut amp, k_std: None, c_std: None, rel_std: None }).unwrap();
    let (mut ks, mut cs, mut dof) = (vec![0.0; 8 * n], vec![0.0; 8 * n], vec![0.0; 2 * n]);
    identical_std(p, &k, &cc, None, IdenticalStdOut { k_std: &mut ks, c_std: &mut cs, dof: &mut dof }).unwrap();
    (ks, cs, dof)
}

fn close(a: &[f64], b: &[f64], rtol: f64) -> bool {
    a.iter().zip(b).all(|(x, y)| (x.is_nan() && y.is_nan()) || (x - y).abs() <= rtol * x.abs().max(y.abs()))
}

proptest! {
    #![proptest_config(cfg(24))]

    /// Responses and excitations scaled together leave the estimate, and so the standard errors
    /// and their dof, unchanged (the residual scales as the regressors); so does the order of
    /// the runs. The dof lie between 0 and the pooled count 2 (2R - 2).
    #[test]
    fn identical_std_is_invariant_under_scaling_and_run_order(r in rotors(), (k, cc) in bearings(), runs in 2usize..5,
                                                              e in proptest::collection::vec(-1.0f64..1.0, 32),
                                                              noise in proptest::collection::vec(-1.0f64..1.0, 64),
                                                              scale in 0.01f64..100.0) {
        let (k, cc) = identical(&k, &cc);
        let kmean = (k[0] + k[3]) / 2.0;
        let wn = (2.0 * kmean / r.m).sqrt();
        let w: Vec<f64> = (0..12).map(|i| wn * (0.3 + 0.25 * i as f64)).collect();
        let e: Vec<C64> = e[..8 * runs].chunks(2).map(|p| c(p[0], p[1])).collect();
        let q = noisy_runs(&r, &k, &cc, &w, &e, &noise);
        let gain: Vec<f64> = w.iter().map(|v| v * v).collect();
        let n = w.len();
        let qb: Vec<&[C64]> = q.chunks(4 * n).collect();
        let p = IdentProblem { rotor: r, w: &w, spin: &w, q: &qb, e: &e, gain: &gain, sigma: &[], q_ped: &[], planes: None, batch: 1, runs, identical: true };
        let (ks, cs, dof) = both(&p);
        for (i, d) in dof.iter().enumerate() {
            prop_assert!(d.is_nan() || (*d > 0.0 && *d <= 2.0 * (2.0 * runs as f64 - 2.0) + 1e-9), "dof {d} at {i}");
        }
        prop_assert!(ks.iter().filter(|v| v.is_finite()).count() > 0);
        // scaled together
        let qs: Vec<C64> = q.iter().map(|v| v * scale).collect();
        let es: Vec<C64> = e.iter().map(|v| v * scale).collect();
        let qsb: Vec<&[C64]> = qs.chunks(4 * n).collect();
        let ps = IdentProblem { q: &qsb, e: &es, ..p };
        let (ks2, cs2, dof2) = both(&ps);
        prop_assert!(close(&ks, &ks2, 1e-7) && close(&cs, &cs2, 1e-7) && close(&dof, &dof2, 1e-7));
        // runs reversed
        let qr: Vec<&[C64]> = qb.iter().rev().copied().collect();
        let er: Vec<C64> = e.chunks(4).rev().flatten().copied().collect();
        let pr = IdentProblem { q: &qr, e: &er, ..p };
        let (ks3, cs3, dof3) = both(&pr);
        prop_assert!(close(&ks, &ks3, 1e-7) && close(&cs, &cs3, 1e-7) && close(&dof, &dof3, 1e-7));
    }
}

#[test]
fn identical_std_refuses_what_it_cannot_compute() {
    let r = nsf_rotor();
    let w = [300.0, 400.0, 500.0];
    let e = [c(1e-4, 0.0), c(0.0, -1e-4), c(0.0, 0.0), c(0.0, 0.0), c(0.0, 0.0), c(0.0, 0.0), c(1e-5, 0.0), c(0.0, 1e-5)];
    // two runs' responses, far from collinear
    let q: Vec<C64> = (0..24).map(|j| c(1e-5 * (1.0 + 0.7 * j as f64).sin(), 1e-5 * (0.3 + 1.3 * j as f64).cos())).collect();
    let qb: Vec<&[C64]> = q.chunks(12).collect();
    let p = IdentProblem { rotor: r, w: &w, spin: &w, q: &qb, e: &e, gain: &[], sigma: &[], q_ped: &[], planes: None, batch: 1, runs: 2, identical: false };
    let (k, cc) = (vec![1e6; 24], vec![1e3; 24]);
    let (mut ks, mut cs, mut dof) = (vec![0.0; 24], vec![0.0; 24], vec![0.0; 6]);
    let err = identical_std(&p, &k, &cc, None, IdenticalStdOut { k_std: &mut ks, c_std: &mut cs, dof: &mut dof }).unwrap_err();
    assert_eq!(err.name(), "identical");
    let p = IdentProblem { identical: true, ..p };
    let err = identical_std(&p, &k[..16], &cc, None, IdenticalStdOut { k_std: &mut ks, c_std: &mut cs, dof: &mut dof }).unwrap_err();
    assert_eq!(err.name(), "k");
    let err = identical_std(&p, &k, &cc, None, IdenticalStdOut { k_std: &mut ks, c_std: &mut cs, dof: &mut dof[..4] }).unwrap_err();
    assert_eq!(err.name(), "dof");
    // a NaN estimate gives NaN, the other points numbers
    let mut kn = k.clone();
    kn[8] = f64::NAN;
    identical_std(&p, &kn, &cc, None, IdenticalStdOut { k_std: &mut ks, c_std: &mut cs, dof: &mut dof }).unwrap();
    assert!(ks[8..16].iter().all(|v| v.is_nan()) && dof[2..4].iter().all(|v| v.is_nan()));
    assert!(ks[..8].iter().all(|v| v.is_finite()) && dof[..2].iter().all(|v| v.is_finite()));
    // one run: no residual degree of freedom
    let p1 = IdentProblem { q: &qb[..1], e: &e[..4], runs: 1, ..p };
    identical_std(&p1, &k, &cc, None, IdenticalStdOut { k_std: &mut ks, c_std: &mut cs, dof: &mut dof }).unwrap();
    assert!(ks.iter().chain(&dof).all(|v| v.is_nan()));
}
