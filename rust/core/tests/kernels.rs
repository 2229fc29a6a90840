//! Property tests of the core kernels against the reference implementations in `common`.

mod common;

use common::*;
use proptest::prelude::*;
use rotorid_core::identify::{identify_forces, identify_report, relative_std, IdentOut, IdentProblem};
use rotorid_core::{forced, modal, order, timesim, CoreError, Rotor, C64};

fn cfg(cases: u32) -> ProptestConfig {
    ProptestConfig { cases, failure_persistence: None, ..ProptestConfig::default() }
}

/// Speeds spread over the rotor's natural frequencies: 0.2 to 3 times the bounce frequency.
fn speeds_for(r: &Rotor, k: &[f64], n: usize) -> Vec<f64> {
    let kmean = (k[0] + k[3] + k[4] + k[7]) / 4.0;
    let wn = (2.0 * kmean / r.m).sqrt();
    (0..n).map(|i| wn * 0.2 * 15f64.powf(i as f64 / (n - 1) as f64)).collect()
}

/// Split (blocks, n, 4) responses into the per-run blocks the identification takes.
fn blocks(q: &[C64], n: usize) -> Vec<&[C64]> {
    q.chunks(4 * n).collect()
}

fn cplx_vec(v: &[f64]) -> Vec<C64> {
    v.chunks(2).map(|p| c(p[0], p[1])).collect()
}

struct Identified {
    k: Vec<f64>,
    c: Vec<f64>,
    cond: Vec<f64>,
    resid: Vec<f64>,
    k_std: Vec<f64>,
    nbad: usize,
}

fn run_identify(p: &IdentProblem, report: bool) -> Result<Identified, CoreError> {
    let npts = p.batch * p.w.len();
    let (mut k, mut cc, mut cond) = (vec![0.0; npts * 8], vec![0.0; npts * 8], vec![0.0; npts * 2]);
    let (mut resid, mut amp) = (vec![0.0; npts], vec![0.0; npts]);
    let (mut ks, mut cs) = (vec![0.0; npts * 8], vec![0.0; npts * 8]);
    let mut rel = vec![-1.0; npts];
    let out = IdentOut {
        k: &mut k,
        c: &mut cc,
        cond: &mut cond,
        resid: &mut resid,
        amp: &mut amp,
        k_std: Some(&mut ks),
        c_std: Some(&mut cs),
        rel_std: if report { None } else { Some(&mut rel) },
    };
    let nbad = if report { identify_report(p, out)? } else { identify_forces(p, out)? };
    if !report {
        // the relative standard error filled inside the kernel is the separate pass's, bit for bit
        let mut sep = vec![0.0; npts];
        relative_std(&k, &cc, &ks, &cs, &mut sep)?;
        for (i, (a, b)) in rel.iter().zip(&sep).enumerate() {
            assert!(a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()), "point {i}: fused {a} vs separate {b}");
        }
    }
    Ok(Identified { k, c: cc, cond, resid, k_std: ks, nbad })
}

/// The fused relative standard error on the parallel path (more points than the serial limit),
/// with NaN points among them, and refused without the standard errors it is made of.
#[test]
fn fused_relative_std_matches_the_separate_pass_on_the_parallel_path() {
    let r = Rotor { m: 10.0, it: 0.1, ip: 0.02, l1: 0.1, l2: 0.12 };
    let n = 9000;
    let w: Vec<f64> = (0..n).map(|i| 20.0 + i as f64 * 0.1).collect();
    let mut q: Vec<C64> = (0..3 * n * 4).map(|i| c(1e-6 * (1.0 + (i % 7) as f64), 1e-6 * ((i % 5) as f64 - 2.0))).collect();
    q[4 * 17 + 2] = c(f64::NAN, 0.0);
    let e: Vec<C64> = (0..12).map(|i| c(1e-4 * (i % 3) as f64, 1e-5 * (i % 4) as f64)).collect();
    let gain: Vec<f64> = w.iter().map(|v| v * v).collect();
    let bl = blocks(&q, n);
    let p = IdentProblem { rotor: r, w: &w, spin: &w, q: &bl, e: &e, gain: &gain, sigma: &[], q_ped: &[], planes: None, batch: 1, runs: 3, identical: false };
    let id = run_identify(&p, false).unwrap();
    assert_eq!(id.nbad, 1);
    let (mut k, mut cc, mut cond, mut resid, mut amp, mut rel) = (vec![0.0; 8 * n], vec![0.0; 8 * n], vec![0.0; 2 * n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let out = IdentOut { k: &mut k, c: &mut cc, cond: &mut cond, resid: &mut resid, amp: &mut amp, k_std: None, c_std: None, rel_std: Some(&mut rel) };
    let err = identify_forces(&p, out).unwrap_err();
    assert_eq!(err.name(), "rel_std");
}

/// Largest error of the identified impedances K + j w C per bearing, relative to the largest
/// true impedance of that bearing, over the points whose condition number is below `max_cond`.
fn impedance_error(id: &Identified, k: &[f64], cc: &[f64], w: &[f64], max_cond: f64) -> (f64, usize) {
    let mut worst = 0.0f64;
    let mut used = 0;
    for (i, &wi) in w.iter().enumerate() {
        for b in 0..2 {
            if !(id.cond[2 * i + b] < max_cond) {
                continue;
            }
            used += 1;
            let scale = (0..4).map(|t| c(k[4 * b + t], wi * cc[4 * b + t]).norm()).fold(0.0, f64::max);
            for t in 0..4 {
                let j = 8 * i + 4 * b + t;
                let err = c(id.k[j] - k[4 * b + t], wi * (id.c[j] - cc[4 * b + t])).norm();
                worst = worst.max(err / scale);
            }
        }
    }
    (worst, used)
}

proptest! {
    #![proptest_config(cfg(200))]

    /// solve4 through the forced response: the equations of motion hold, and the answer equals
    /// a full-pivoting elimination of the same system.
    #[test]
    fn forced_response_satisfies_the_equations_of_motion(r in rotors(), (k, cc) in bearings(),
                                                        wr in 0.05f64..5.0, spin_r in -2.0f64..2.0,
                                                        f in proptest::collection::vec(-1.0f64..1.0, 8)) {
        let w = wr * (k[0] / r.m).sqrt();
        let spin = spin_r * w;
        let force = cplx_vec(&f);
        let mut q = [c(0.0, 0.0); 4];
        let bad = forced::forced_response(&r, &k, &cc, &[spin], &[w], &force, 1, &mut q).unwrap();
        prop_assert_eq!(bad, 0);
        let res = motion_residual(&r, &k, &cc, spin, w, &q, &force);
        let scale = motion_scale(&r, &k, &cc, spin, w, &q);
        for v in res {
            prop_assert!(v.norm() <= 1e-12 * scale, "residual {} of scale {}", v.norm(), scale);
        }
        // the same system through the reference solver (H from unit forces, column by column)
        let mut h = [[c(0.0, 0.0); 4]; 4];
        for j in 0..4 {
            let mut e = [c(0.0, 0.0); 4];
            e[j] = c(1.0, 0.0);
            let hj = motion_residual(&r, &k, &cc, spin, w, &e, &[c(0.0, 0.0); 4]);
            for i in 0..4 {
                h[i][j] = hj[i];
            }
        }
        let qref = solve_full_pivot(&h, &[force[0], force[1], force[2], force[3]]).unwrap();
        let qn = qref.iter().fold(0.0f64, |a, z| a.max(z.norm()));
        for i in 0..4 {
            prop_assert!((q[i] - qref[i]).norm() <= 1e-9 * qn);
        }
    }

    /// Broadcast bearings and forces give the same answer as one row per point.
    #[test]
    fn forced_response_broadcast_equals_per_point(r in rotors(), (k, cc) in bearings(), n in 1usize..40) {
        let w = speeds_for(&r, &k, n.max(2));
        let n = w.len();
        let force = [c(1.0, 0.5), c(-0.2, 0.1), c(0.3, 0.0), c(0.0, -1.0)];
        let mut a = vec![c(0.0, 0.0); 4 * n];
        forced::forced_response(&r, &k, &cc, &w, &w, &force, 1, &mut a).unwrap();
        let kk: Vec<f64> = (0..n).flat_map(|_| k).collect();
        let cr: Vec<f64> = (0..n).flat_map(|_| cc).collect();
        let ff: Vec<C64> = (0..n).flat_map(|_| force).collect();
        let mut b = vec![c(0.0, 0.0); 4 * n];
        forced::forced_response(&r, &kk, &cr, &w, &w, &ff, 1, &mut b).unwrap();
        prop_assert_eq!(a, b);
    }

    /// A gain per point equals the force scaled point by point (imbalance: F = e Omega^2).
    #[test]
    fn scaled_forced_response_equals_scaled_force(r in rotors(), (k, cc) in bearings(), n in 1usize..3000) {
        let w = speeds_for(&r, &k, n.max(2));
        let n = w.len();
        let e = [c(0.3, -0.1), c(0.2, 0.4), c(-0.01, 0.0), c(0.02, 0.05)];
        let gain: Vec<f64> = w.iter().map(|v| v * v).collect();
        let mut a = vec![c(0.0, 0.0); 4 * n];
        forced::forced_response_scaled(&r, &k, &cc, &w, &w, &e, 1, &gain, &mut a).unwrap();
        let f: Vec<C64> = gain.iter().flat_map(|&g| e.iter().map(move |&v| v * g)).collect();
        let mut b = vec![c(0.0, 0.0); 4 * n];
        forced::forced_response(&r, &k, &cc, &w, &w, &f, 1, &mut b).unwrap();
        for i in 0..n {
            let scale = (0..4).map(|d| b[4 * i + d].norm()).fold(0.0, f64::max);
            for d in 0..4 {
                prop_assert!((a[4 * i + d] - b[4 * i + d]).norm() <= 1e-13 * scale);
            }
        }
        prop_assert!(forced::forced_response_scaled(&r, &k, &cc, &w, &w, &e, 1, &gain[1..], &mut a).is_err());
        // the imbalance entry (w = spin, gain = spin^2 formed in the kernel) is the same, bit for bit
        forced::forced_response_scaled(&r, &k, &cc, &w, &w, &e, 1, &gain, &mut a).unwrap();
        let mut d = vec![c(0.0, 0.0); 4 * n];
        forced::forced_response_imbalance(&r, &k, &cc, &w, &e, 1, &mut d).unwrap();
        let bits = |v: &[C64]| v.iter().map(|z| (z.re.to_bits(), z.im.to_bits())).collect::<Vec<_>>();
        prop_assert_eq!(bits(&a), bits(&d));
        prop_assert!(forced::forced_response_imbalance(&r, &k, &cc, &w, &e, 1, &mut d[4..]).is_err());
    }

    /// `forced_response_with`: the gains, then the plane transform, applied in the kernel's pass
    /// give the bits of the separate steps (`forced_response_imbalance`, then `apply_planes`),
    /// with 1-3 right-hand sides, for tails of a group and parallel chunks; a gain of the wrong
    /// length is an error.
    #[test]
    fn forced_response_with_planes_equals_the_separate_move(r in rotors(), (k, cc) in bearings(), n in 1usize..5000,
                                                            nrhs in 1usize..4, t in proptest::collection::vec(-2.0f64..2.0, 4)) {
        let w = speeds_for(&r, &k, n.max(2));
        let n = w.len();
        let t: [f64; 4] = t.try_into().unwrap();
        let e: Vec<C64> = (0..4 * nrhs).map(|i| c(0.1 * i as f64 - 0.3, 0.05 * (i % 3) as f64)).collect();
        let mut at_b = vec![c(0.0, 0.0); 4 * nrhs * n];
        forced::forced_response_imbalance(&r, &k, &cc, &w, &e, nrhs, &mut at_b).unwrap();
        let mut want = vec![c(0.0, 0.0); at_b.len()];
        rotorid_core::model::apply_planes(&t, &at_b, &mut want).unwrap();
        let mut got = vec![c(0.0, 0.0); at_b.len()];
        forced::forced_response_with(&r, &k, &cc, &w, &w, &e, nrhs, forced::Gain::SpinSquared, Some(&t), &mut got).unwrap();
        let bits = |v: &[C64]| v.iter().map(|z| (z.re.to_bits(), z.im.to_bits())).collect::<Vec<_>>();
        prop_assert_eq!(bits(&got), bits(&want));
        // without a transform it is the response at the bearings itself
        forced::forced_response_with(&r, &k, &cc, &w, &w, &e, nrhs, forced::Gain::SpinSquared, None, &mut got).unwrap();
        prop_assert_eq!(bits(&got), bits(&at_b));
        let short = vec![1.0; n - 1];
        prop_assert!(forced::forced_response_with(&r, &k, &cc, &w, &w, &e, nrhs, forced::Gain::PerPoint(&short), Some(&t), &mut got).is_err());
    }

    /// The gains and the plane transform, applied to the kernel's lanes before they are stored,
    /// give the bits of the unit-gain response scaled point by point (`v *= g`) and then moved by
    /// `apply_planes`: per-point gains and Omega^2, 1-3 right-hand sides, tails of a group,
    /// parallel chunks, and a point with a non-finite coefficient (its group takes the per-point
    /// path, which must scale and move the same way; that point itself is NaN).
    #[test]
    fn gains_and_planes_in_the_lanes_equal_scaling_and_moving_afterwards(
        r in rotors(), (k, cc) in bearings(), n in 1usize..3000, nrhs in 1usize..4,
        t in proptest::collection::vec(-2.0f64..2.0, 4), g in proptest::collection::vec(-3.0f64..3.0, 1..40),
        nan_at in proptest::option::of(0usize..3000), square in any::<bool>(), move_planes in any::<bool>())
    {
        let w = speeds_for(&r, &k, n.max(2));
        let n = w.len();
        let t: [f64; 4] = t.try_into().unwrap();
        let gain: Vec<f64> = (0..n).map(|i| g[i % g.len()] * (1.0 + i as f64)).collect();
        let mut kp: Vec<f64> = (0..n).flat_map(|_| k.iter().copied()).collect();
        if let Some(i) = nan_at {
            kp[8 * (i % n) + 3] = f64::NAN;
        }
        let e: Vec<C64> = (0..4 * nrhs).map(|i| c(0.1 * i as f64 - 0.3, 0.05 * (i % 3) as f64)).collect();
        let mut unit = vec![c(0.0, 0.0); 4 * nrhs * n];
        forced::forced_response(&r, &kp, &cc, &w, &w, &e, nrhs, &mut unit).unwrap();
        let mut want = unit.clone();
        for (i, p) in want.chunks_mut(4 * nrhs).enumerate() {
            let gi = if square { w[i] * w[i] } else { gain[i] };
            p.iter_mut().for_each(|v| *v *= gi);
        }
        if move_planes {
            let scaled = want.clone();
            rotorid_core::model::apply_planes(&t, &scaled, &mut want).unwrap();
        }
        let mut got = vec![c(0.0, 0.0); want.len()];
        let gk = if square { forced::Gain::SpinSquared } else { forced::Gain::PerPoint(&gain) };
        let nsing = forced::forced_response_with(&r, &kp, &cc, &w, &w, &e, nrhs, gk, move_planes.then_some(&t), &mut got).unwrap();
        let bits = |v: &[C64]| v.iter().map(|z| (z.re.to_bits(), z.im.to_bits())).collect::<Vec<_>>();
        prop_assert_eq!(bits(&got), bits(&want));
        if let Some(i) = nan_at {
            prop_assert!(got[4 * nrhs * (i % n)].re.is_nan());
            prop_assert!(nsing >= 1);
        }
    }

    /// Exact responses of 2-4 runs identify the bearings they came from (both solvers), and the
    /// two solvers agree.
    #[test]
    fn identification_recovers_the_bearings(r in rotors(), (k, cc) in bearings(), runs in 2usize..5,
                                            e in proptest::collection::vec(-1.0f64..1.0, 32)) {
        let w = speeds_for(&r, &k, 24);
        let e = cplx_vec(&e[..8 * runs]);
        let q = imbalance_responses(&r, &k, &cc, &w, &e);
        let gain: Vec<f64> = w.iter().map(|v| v * v).collect();
        let qb = blocks(&q, w.len());
        let p = IdentProblem { rotor: r, w: &w, spin: &w, q: &qb, e: &e, gain: &gain, sigma: &[], q_ped: &[], planes: None, batch: 1, runs, identical: false };
        let fast = run_identify(&p, false).unwrap();
        let (err, used) = impedance_error(&fast, &k, &cc, &w, 1e5);
        prop_assert!(used > 0);
        prop_assert!(err < 1e-7, "forces solver: relative impedance error {err:e}");
        prop_assert_eq!(fast.nbad, 0);
        for (i, rs) in fast.resid.iter().enumerate() {
            prop_assert!(fast.cond[2 * i].is_nan() || !(fast.cond[2 * i] < 1e5) || *rs < 1e-8, "residual {rs}");
        }
        let rep = run_identify(&p, true).unwrap();
        let (err_r, _) = impedance_error(&rep, &k, &cc, &w, 1e5);
        prop_assert!(err_r < 1e-6, "report solver: relative impedance error {err_r:e}");
        if runs > 2 {
            // exact data: standard errors are at rounding level relative to the coefficients
            for (i, s) in fast.k_std.iter().enumerate() {
                prop_assert!(!(*s < 0.0), "negative standard error at {i}");
            }
        }
    }

    /// An empty gain is Omega^2 from `spin`, bit for bit, with both solvers (the public API's
    /// imbalance identifications pass no gain array).
    #[test]
    fn empty_gain_is_spin_squared(r in rotors(), (k, cc) in bearings(), runs in 2usize..5,
                                  e in proptest::collection::vec(-1.0f64..1.0, 32)) {
        let w = speeds_for(&r, &k, 11);
        let e = cplx_vec(&e[..8 * runs]);
        let q = imbalance_responses(&r, &k, &cc, &w, &e);
        let gain: Vec<f64> = w.iter().map(|v| v * v).collect();
        let qb = blocks(&q, w.len());
        let given = IdentProblem { rotor: r, w: &w, spin: &w, q: &qb, e: &e, gain: &gain, sigma: &[], q_ped: &[], planes: None, batch: 1, runs, identical: false };
        let implied = IdentProblem { gain: &[], ..given };
        for report in [false, true] {
            let (a, b) = (run_identify(&given, report).unwrap(), run_identify(&implied, report).unwrap());
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            prop_assert_eq!(bits(&a.k), bits(&b.k));
            prop_assert_eq!(bits(&a.c), bits(&b.c));
            prop_assert_eq!(bits(&a.cond), bits(&b.cond));
        }
    }

    /// Responses at the probe planes with the eq. 19 transform given (`planes`) identify exactly as
    /// the same responses moved to the bearings first by `model::apply_planes`, bit for bit, with
    /// both solvers; `planes` with pedestal motion, or not finite, is refused.
    #[test]
    fn planes_in_the_kernel_equal_moved_responses(r in rotors(), (k, cc) in bearings(), runs in 2usize..5,
                                                  e in proptest::collection::vec(-1.0f64..1.0, 32),
                                                  t in proptest::collection::vec(-2.0f64..2.0, 4)) {
        use rotorid_core::model::apply_planes;
        let w = speeds_for(&r, &k, 13);
        let e = cplx_vec(&e[..8 * runs]);
        let q = imbalance_responses(&r, &k, &cc, &w, &e);
        let t: [f64; 4] = [t[0] + 3.0, t[1], t[2], t[3] + 3.0]; // invertible enough
        let mut moved = vec![c(0.0, 0.0); q.len()];
        apply_planes(&t, &q, &mut moved).unwrap();
        let gain: Vec<f64> = w.iter().map(|v| v * v).collect();
        let (qb, mb) = (blocks(&q, w.len()), blocks(&moved, w.len()));
        let at_bearings = IdentProblem { rotor: r, w: &w, spin: &w, q: &mb, e: &e, gain: &gain, sigma: &[], q_ped: &[], planes: None, batch: 1, runs, identical: false };
        let at_probes = IdentProblem { q: &qb, planes: Some(t), ..at_bearings };
        for report in [false, true] {
            let (a, b) = (run_identify(&at_bearings, report).unwrap(), run_identify(&at_probes, report).unwrap());
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            prop_assert_eq!(bits(&a.k), bits(&b.k));
            prop_assert_eq!(bits(&a.c), bits(&b.c));
            prop_assert_eq!(bits(&a.resid), bits(&b.resid));
        }
        let ped = vec![c(0.0, 0.0); q.len()];
        let pb = blocks(&ped, w.len());
        prop_assert_eq!(at_probes.check().map_err(|e| e.name()), Ok(()));
        prop_assert_eq!(IdentProblem { q_ped: &pb, ..at_probes }.check().unwrap_err().name(), "planes");
        prop_assert_eq!(IdentProblem { planes: Some([f64::NAN, 0.0, 0.0, 1.0]), ..at_probes }.check().unwrap_err().name(), "planes");
    }

    /// A batch of problems equals the problems solved one at a time.
    #[test]
    fn batch_equals_single_problems(r in rotors(), (k, cc) in bearings(), (k2, c2) in bearings(),
                                    e in proptest::collection::vec(-1.0f64..1.0, 24)) {
        let w = speeds_for(&r, &k, 9);
        let runs = 3;
        let e = cplx_vec(&e);
        let qa = imbalance_responses(&r, &k, &cc, &w, &e);
        let qb = imbalance_responses(&r, &k2, &c2, &w, &e);
        let gain: Vec<f64> = w.iter().map(|v| v * v).collect();
        let qab: Vec<C64> = qa.iter().chain(qb.iter()).cloned().collect();
        let qabb = blocks(&qab, w.len());
        let pab = IdentProblem { rotor: r, w: &w, spin: &w, q: &qabb, e: &e, gain: &gain, sigma: &[], q_ped: &[], planes: None, batch: 2, runs, identical: false };
        let both = run_identify(&pab, false).unwrap();
        for (bi, qq) in [&qa, &qb].into_iter().enumerate() {
            let qqb = blocks(qq, w.len());
            let p1 = IdentProblem { rotor: r, w: &w, spin: &w, q: &qqb, e: &e, gain: &gain, sigma: &[], q_ped: &[], planes: None, batch: 1, runs, identical: false };
            let one = run_identify(&p1, false).unwrap();
            let o = bi * w.len() * 8;
            for t in 0..w.len() * 8 {
                let (x, y) = (one.k[t], both.k[o + t]);
                prop_assert!(x == y || (x.is_nan() && y.is_nan()));
            }
        }
    }

    /// One running speed and one gain for every frequency (impacts): broadcast equals repeated.
    #[test]
    fn broadcast_spin_and_gain_equal_repeated_values(r in rotors(), (k, cc) in bearings(), sr in 0.0f64..2.0,
                                                     e in proptest::collection::vec(-1.0f64..1.0, 16)) {
        let w = speeds_for(&r, &k, 37);
        let spin = sr * w[10];
        let e = cplx_vec(&e);
        let mut q = Vec::new();
        for run in 0..2 {
            let mut out = vec![c(0.0, 0.0); w.len() * 4];
            forced::forced_response(&r, &k, &cc, &vec![spin; w.len()], &w, &e[4 * run..4 * run + 4], 1, &mut out).unwrap();
            q.extend(out);
        }
        let qb = blocks(&q, w.len());
        let (full_spin, ones) = (vec![spin; w.len()], vec![1.0; w.len()]);
        let a = IdentProblem { rotor: r, w: &w, spin: &full_spin, q: &qb, e: &e, gain: &ones, sigma: &[], q_ped: &[], planes: None, batch: 1, runs: 2, identical: false };
        let b = IdentProblem { spin: &[spin], gain: &[1.0], ..a };
        for report in [false, true] {
            let (ia, ib) = (run_identify(&a, report).unwrap(), run_identify(&b, report).unwrap());
            prop_assert!(ia.k.iter().zip(&ib.k).all(|(x, y)| x == y || (x.is_nan() && y.is_nan())));
            prop_assert!(ia.c.iter().zip(&ib.c).all(|(x, y)| x == y || (x.is_nan() && y.is_nan())));
        }
    }

    /// Identical bearings identified under `identical = true` (8 unknowns) are recovered too.
    #[test]
    fn identical_bearings(r in rotors(), (k, cc) in bearings(), e in proptest::collection::vec(-1.0f64..1.0, 16)) {
        let mut k = k;
        let mut cc = cc;
        for t in 0..4 {
            k[4 + t] = k[t];
            cc[4 + t] = cc[t];
        }
        let w = speeds_for(&r, &k, 12);
        let e = cplx_vec(&e);
        let q = imbalance_responses(&r, &k, &cc, &w, &e);
        let gain: Vec<f64> = w.iter().map(|v| v * v).collect();
        let qb = blocks(&q, w.len());
        let p = IdentProblem { rotor: r, w: &w, spin: &w, q: &qb, e: &e, gain: &gain, sigma: &[], q_ped: &[], planes: None, batch: 1, runs: 2, identical: true };
        let id = run_identify(&p, false).unwrap();
        let (err, used) = impedance_error(&id, &k, &cc, &w, 1e5);
        prop_assert!(used > 0);
        prop_assert!(err < 1e-7, "{err:e}");
    }

    /// Modal analysis: every eigenpair satisfies (lam^2 M + lam (C + Omega G) + K) v = 0, checked
    /// through the equations of motion with s = lam.
    #[test]
    fn modal_eigenpairs_satisfy_the_equations(r in rotors(), (k, cc) in bearings(), spin_r in 0.0f64..2.0) {
        let spin = spin_r * (k[0] / r.m).sqrt();
        let (mut lam, mut sh) = ([c(0.0, 0.0); 4], [c(0.0, 0.0); 16]);
        let failed = modal::modal(&r, &k, &cc, &[spin], &mut lam, &mut sh).unwrap();
        prop_assert_eq!(failed, 0);
        for m in 0..4 {
            let l = lam[m];
            if l.re.is_nan() {
                continue; // overdamped pair
            }
            let v = &sh[4 * m..4 * m + 4];
            let res = pencil_residual(&r, &k, &cc, spin, l, v);
            let vn = v.iter().fold(0.0f64, |a, z| a.max(z.norm()));
            let scale = (l.norm_sqr() * (r.m + r.it) + l.norm() * (cc.iter().fold(0.0f64, |a, b| a.max(b.abs())) + spin * r.ip)
                + k.iter().fold(0.0f64, |a, b| a.max(b.abs()))) * vn;
            prop_assert!(res <= 1e-8 * scale, "mode {m}: residual {res:e} of {scale:e}");
        }
    }
}

/// |D(lam) v| with D(s) = s^2 M + s (C + Omega G) + K, from the equations of motion: at s the
/// bearing impedance is K + s C, i.e. K + j w C with j w = s.
fn pencil_residual(r: &Rotor, k: &[f64], cc: &[f64], spin: f64, s: C64, v: &[C64]) -> f64 {
    // evaluate term by term with complex s (motion_residual is written for s = j w)
    let span = r.l1 + r.l2;
    let (x1, x2, y1, y2) = (v[0], v[1], v[2], v[3]);
    let z = |b: usize, i: usize, j: usize| c(k[4 * b + 2 * i + j], 0.0) + s * cc[4 * b + 2 * i + j];
    let f1 = [z(0, 0, 0) * x1 + z(0, 0, 1) * y1, z(0, 1, 0) * x1 + z(0, 1, 1) * y1];
    let f2 = [z(1, 0, 0) * x2 + z(1, 0, 1) * y2, z(1, 1, 0) * x2 + z(1, 1, 1) * y2];
    let s2 = s * s;
    let xg = (x1 * r.l2 + x2 * r.l1) / span;
    let yg = (y1 * r.l2 + y2 * r.l1) / span;
    let (tx, ty) = ((x2 - x1) / span, (y2 - y1) / span);
    let res = [
        s2 * r.m * xg + f1[0] + f2[0],
        s2 * r.m * yg + f1[1] + f2[1],
        s2 * r.it * tx + s * spin * r.ip * ty - r.l1 * f1[0] + r.l2 * f2[0],
        -(s2 * r.it * ty) + s * spin * r.ip * tx + r.l1 * f1[1] - r.l2 * f2[1],
    ];
    res.iter().fold(0.0f64, |a, z| a.max(z.norm()))
}

#[test]
fn undamped_symmetric_rotor_has_the_textbook_frequencies() {
    // l1 = l2 = a, equal isotropic springs k, no damping, no spin: bounce sqrt(2k/m) and rocking
    // sqrt(2 k a^2 / I_T), each twice (x and y)
    let (m, it, a, kk) = (20.0, 0.5, 0.2, 1e6);
    let r = Rotor::from_slice(&[m, it, 0.1, a, a]).unwrap();
    let k = [kk, 0.0, 0.0, kk, kk, 0.0, 0.0, kk];
    let (mut lam, mut sh) = ([c(0.0, 0.0); 4], [c(0.0, 0.0); 16]);
    modal::modal(&r, &k, &[0.0; 8], &[0.0], &mut lam, &mut sh).unwrap();
    let mut want = [(2.0 * kk / m).sqrt(), (2.0 * kk / m).sqrt(), (2.0 * kk * a * a / it).sqrt(), (2.0 * kk * a * a / it).sqrt()];
    want.sort_by(|x, y| x.partial_cmp(y).unwrap());
    for i in 0..4 {
        assert!((lam[i].im - want[i]).abs() < 1e-9 * want[i], "{:?} vs {:?}", lam, want);
        assert!(lam[i].re.abs() < 1e-9 * want[i]);
    }
}

#[test]
fn heavily_damped_mode_gets_its_shape() {
    // a mode at -2385 + 127j 1/s: the pencil shifted by 1e-12 is singular to working precision
    // (mass and stiffness terms cancel), the shift must grow for the inverse iteration
    let r = Rotor::from_slice(&[229.0, 0.5905303955078125, 0.5905303955078125, 0.375, 0.578125]).unwrap();
    let k = [4e6, 1e6, -1e6, 8e6, 3e6, -7.5e5, -7.5e5, 6e6];
    let cc = [7071.067811865475, 0.0, 0.0, 4419.417382415922, 4975.5260400283305, 310.97037750177066, -1243.8815100070826, 6063.922361284528];
    let (mut lam, mut sh) = ([c(0.0, 0.0); 4], [c(0.0, 0.0); 16]);
    assert_eq!(modal::modal(&r, &k, &cc, &[0.0], &mut lam, &mut sh).unwrap(), 0);
    for m in 0..3 {
        let v = &sh[4 * m..4 * m + 4];
        let res = pencil_residual(&r, &k, &cc, 0.0, lam[m], v);
        let scale = lam[m].norm_sqr() * (r.m + r.it) + lam[m].norm() * 8e3 + 8e6;
        assert!(res < 1e-8 * scale, "mode {m} ({}): residual {res:e} of {scale:e}", lam[m]);
    }
}

#[test]
fn undamped_resonance_hit_exactly_is_singular() {
    let (m, it, a, kk) = (20.0, 0.5, 0.2, 1e6);
    let r = Rotor::from_slice(&[m, it, 0.0, a, a]).unwrap();
    let k = [kk, 0.0, 0.0, kk, kk, 0.0, 0.0, kk];
    let w = (2.0 * kk / m).sqrt();
    let mut q = [c(0.0, 0.0); 4];
    let force = [c(1.0, 0.0), c(0.0, 0.0), c(0.0, 0.0), c(0.0, 0.0)];
    let bad = forced::forced_response(&r, &k, &[0.0; 8], &[w], &[w], &force, 1, &mut q).unwrap();
    assert_eq!(bad, 1);
    assert!(q.iter().all(|z| z.re.is_nan()));
}

/// Reference run-out subtraction, one sample at a time: find the revolution by linear search,
/// the angle fraction, and interpolate the periodic template with a 4-point Lagrange stencil.
fn runout_reference(x: &[f64], fs: f64, t0: f64, kp: &[f64], tpl: &[f64], i: usize) -> f64 {
    let t = t0 + i as f64 / fs;
    if t < kp[0] || t >= kp[kp.len() - 1] {
        return f64::NAN;
    }
    let k = (0..kp.len() - 1).find(|&k| kp[k] <= t && t < kp[k + 1]).unwrap();
    let p = tpl.len();
    let u = (t - kp[k]) / (kp[k + 1] - kp[k]) * p as f64;
    let m = u.floor();
    let f = u - m;
    let at = |j: isize| tpl[(j.rem_euclid(p as isize)) as usize];
    let m = m as isize;
    let w = [
        -f * (f - 1.0) * (f - 2.0) / 6.0,
        (f + 1.0) * (f - 1.0) * (f - 2.0) / 2.0,
        -(f + 1.0) * f * (f - 2.0) / 2.0,
        (f + 1.0) * f * (f - 1.0) / 6.0,
    ];
    x[i] - (w[0] * at(m - 1) + w[1] * at(m) + w[2] * at(m + 1) + w[3] * at(m + 2))
}

proptest! {
    #![proptest_config(cfg(48))]

    /// The run-out filter equals the sample-by-sample reference, on drifting speeds and any
    /// sample window, and removes a periodic signature down to the interpolation error.
    #[test]
    fn runout_filter_matches_reference(rev_samples in 20.0f64..200.0, drift in -0.2f64..0.2, p in 16usize..300,
                                        phase in 0.0f64..6.28, start in 0.0f64..1.0, nch in 1usize..4) {
        let fs = 1000.0;
        let nrev = 12;
        // keyphasor with a speed ramp
        let mut kp = vec![start / fs * rev_samples];
        for r in 0..nrev {
            let period = rev_samples / fs * (1.0 + drift * r as f64 / nrev as f64);
            kp.push(kp[r] + period);
        }
        let n = (kp[nrev] * fs) as usize + 10;
        let t0 = 0.0;
        // signal: signature s(theta) = cos(theta + phase) + 0.3 cos(2 theta), per channel scaled
        let theta = |t: f64| -> f64 {
            if t < kp[0] || t >= kp[nrev] { return f64::NAN; }
            let k = (0..nrev).find(|&k| kp[k] <= t && t < kp[k + 1]).unwrap();
            2.0 * std::f64::consts::PI * (k as f64 + (t - kp[k]) / (kp[k + 1] - kp[k]))
        };
        let mut x = vec![0.0; nch * n];
        let mut tpl = vec![0.0; nch * p];
        for ch in 0..nch {
            let g = 1.0 + ch as f64;
            for i in 0..n {
                let th = theta(t0 + i as f64 / fs);
                x[ch * n + i] = if th.is_nan() { 0.5 } else { g * ((th + phase).cos() + 0.3 * (2.0 * th).cos()) };
            }
            for j in 0..p {
                let th = 2.0 * std::f64::consts::PI * j as f64 / p as f64;
                tpl[ch * p + j] = g * ((th + phase).cos() + 0.3 * (2.0 * th).cos());
            }
        }
        let (i0, i1) = (3usize, n - 2);
        let mut out = vec![0.0; nch * (i1 - i0)];
        let nonfinite = order::runout_subtract(&x, nch, fs, t0, &kp, &tpl, p, i0, i1, &mut out).unwrap();
        prop_assert_eq!(nonfinite, 0);
        for ch in 0..nch {
            for i in i0..i1 {
                let want = runout_reference(&x[ch * n..(ch + 1) * n], fs, t0, &kp, &tpl[ch * p..(ch + 1) * p], i);
                let got = out[ch * (i1 - i0) + i - i0];
                prop_assert!((want.is_nan() && got.is_nan()) || (want - got).abs() < 1e-12, "ch {ch} sample {i}: {got} vs {want}");
                if !got.is_nan() {
                    // cubic interpolation of a 2-harmonic signature at p >= 16 points per revolution
                    let h = 2.0 * std::f64::consts::PI * 2.0 / p as f64;
                    prop_assert!(got.abs() < 0.2 * (1.0 + ch as f64) * h.powi(4) + 1e-12);
                }
            }
        }
    }

    /// Resampling at uniform angles reproduces a signal defined by its angle, to the cubic
    /// interpolation error.
    #[test]
    fn angle_resample_follows_the_angle(rev_samples in 30.0f64..300.0, drift in -0.2f64..0.2, p in 4usize..64) {
        let fs = 5000.0;
        let nrev = 6;
        let mut kp = vec![0.0123];
        for r in 0..nrev {
            kp.push(kp[r] + rev_samples / fs * (1.0 + drift * r as f64 / nrev as f64));
        }
        let n = (kp[nrev] * fs) as usize + 4;
        let x: Vec<f64> = (0..n).map(|i| {
            let t = i as f64 / fs;
            let k = (0..nrev).find(|&k| kp[k] <= t && t < kp[k + 1]);
            match k {
                Some(k) => (2.0 * std::f64::consts::PI * (t - kp[k]) / (kp[k + 1] - kp[k])).sin(),
                None => 0.0,
            }
        }).collect();
        let (k0, k1) = (1, nrev - 1);
        let mut out = vec![0.0; (k1 - k0) * p];
        order::angle_resample(&x, 1, fs, 0.0, &kp, k0, k1, p, &mut out).unwrap();
        let h = 2.0 * std::f64::consts::PI / (rev_samples * 0.8);
        // the angle is linear within a revolution, so the signal's slope jumps at a pulse when the
        // period changes; a stencil across a pulse sees that kink (error ~ slope jump x spacing)
        let kink = 2.0 * std::f64::consts::PI * drift.abs() / nrev as f64 / (0.8 * rev_samples);
        for r in 0..k1 - k0 {
            for j in 0..p {
                let want = (2.0 * std::f64::consts::PI * j as f64 / p as f64).sin();
                prop_assert!((out[r * p + j] - want).abs() < 0.05 * h.powi(4) + kink + 1e-12, "rev {r} point {j}");
            }
        }
    }

    /// The fused order vectors equal the plain computation: angle_resample of every revolution,
    /// revolution means, their central differences (one-sided at the ends), the drift ramp
    /// removed, a DFT bin by its definition, 2 / p. With offsets up to 1e4 times the vibration,
    /// revolutions at both record ends (clamped stencils) and more revolutions than a task holds.
    #[test]
    fn order_vectors_match_resampling_and_a_plain_dft(p in 8usize..80, nch in 1usize..4, nrev in 1usize..70,
                                                      offset in prop_oneof![Just(0.0), -1e-2f64..1e-2],
                                                      drift in -0.2f64..0.2, seed in 0u64..1000,
                                                      at_ends in any::<bool>()) {
        let fs = 4000.0;
        let rev_samples = 37.3;
        let t_start = if at_ends { 0.0 } else { 0.01 };
        let mut kp = vec![t_start];
        for r in 0..nrev {
            kp.push(kp[r] + rev_samples / fs * (1.0 + drift * r as f64 / nrev as f64));
        }
        let n = ((kp[nrev] * fs) as usize + if at_ends { 1 } else { 8 }).max(1);
        let mut state = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
        let mut rnd = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let chans: Vec<Vec<f64>> = (0..nch).map(|c| {
            let (a1, a2, ph) = (1e-6 * rnd(), 1e-6 * rnd(), 6.0 * rnd());
            (0..n).map(|i| {
                let th = 2.0 * std::f64::consts::PI * i as f64 / rev_samples;
                offset * (c + 1) as f64 + a1 * (th + ph).cos() + a2 * (2.0 * th).sin() + 1e-8 * rnd() + 1e-7 * i as f64 / n as f64
            }).collect()
        }).collect();
        let x: Vec<&[f64]> = chans.iter().map(|v| v.as_slice()).collect();
        let orders = [1usize, 2, (p - 1) / 2];
        let (k0, k1) = (0, nrev);
        let mut out = vec![C64::new(0.0, 0.0); nrev * orders.len() * nch];
        order::order_vectors(&x, fs, 0.0, &kp, k0, k1, p, &orders, &mut out).unwrap();
        let mut res = vec![0.0; nch * nrev * p];
        order::angle_resample_channels(&x, fs, 0.0, &kp, k0, k1, p, &mut res).unwrap();
        for c in 0..nch {
            let row = |r: usize| &res[(c * nrev + r) * p..(c * nrev + r + 1) * p];
            let mean: Vec<f64> = (0..nrev).map(|r| row(r).iter().sum::<f64>() / p as f64).collect();
            // 1e-10 of the vibration (~1e-6) and 1e-14 of the offset (the means' rounding)
            let tol = 1e-16 + 1e-14 * offset.abs() * (c + 1) as f64;
            for r in 0..nrev {
                let slope = if nrev == 1 { 0.0 } else if r == 0 { mean[1] - mean[0] } else if r == nrev - 1 {
                    mean[r] - mean[r - 1] } else { 0.5 * (mean[r + 1] - mean[r - 1]) };
                for (i, &ord) in orders.iter().enumerate() {
                    let (mut re, mut im) = (0.0, 0.0);
                    for (j, &v) in row(r).iter().enumerate() {
                        let th = 2.0 * std::f64::consts::PI * ((ord * j) % p) as f64 / p as f64;
                        let d = v - mean[r] - slope * (j as f64 / p as f64 - 0.5);
                        re += d * th.cos();
                        im -= d * th.sin();
                    }
                    let got = out[(r * orders.len() + i) * nch + c];
                    let want = C64::new(re * 2.0 / p as f64, im * 2.0 / p as f64);
                    prop_assert!((got - want).norm() <= tol, "channel {c} rev {r} order {ord}: {got} vs {want}");
                }
            }
        }
    }

    /// Time stepping equals the recursion written out in full.
    #[test]
    fn lti_run_matches_the_recursion(n in 1usize..6, m in 1usize..3, steps in 1usize..30,
                                     vals in proptest::collection::vec(-1.0f64..1.0, 200)) {
        let mut it = vals.iter().cycle().cloned();
        let phi: Vec<f64> = (0..n * n).map(|_| 0.5 * it.next().unwrap()).collect();
        let g0: Vec<f64> = (0..n * m).map(|_| it.next().unwrap()).collect();
        let g1: Vec<f64> = (0..n * m).map(|_| it.next().unwrap()).collect();
        let u: Vec<f64> = (0..steps * m).map(|_| it.next().unwrap()).collect();
        let x0: Vec<f64> = (0..n).map(|_| it.next().unwrap()).collect();
        let mut out = vec![0.0; steps * n];
        timesim::lti_run(n, m, &phi, &g0, &g1, &u, &x0, &mut out).unwrap();
        let mut x = x0.clone();
        for s in 0..steps {
            for i in 0..n {
                prop_assert!((out[s * n + i] - x[i]).abs() < 1e-12 * (1.0 + x[i].abs()));
            }
            if s + 1 < steps {
                let mut nx = vec![0.0; n];
                for i in 0..n {
                    nx[i] = (0..n).map(|j| phi[i * n + j] * x[j]).sum::<f64>()
                        + (0..m).map(|j| g0[i * m + j] * u[s * m + j] + g1[i * m + j] * (u[(s + 1) * m + j] - u[s * m + j])).sum::<f64>();
                }
                x = nx;
            }
        }
    }

    /// The output equations y_i = C_i x + D_i u written at every step are those of the states
    /// lti_run returns (same recursion, same bits for the states themselves with C = I, D = 0),
    /// and both report the first step whose state is not finite.
    #[test]
    fn lti_outputs_match_the_states(n in 1usize..6, m in 1usize..3, steps in 1usize..30, p in 1usize..4,
                                    blow_up in proptest::option::of(0usize..30),
                                    vals in proptest::collection::vec(-1.0f64..1.0, 200)) {
        let mut it = vals.iter().cycle().cloned();
        let phi: Vec<f64> = (0..n * n).map(|_| 0.5 * it.next().unwrap()).collect();
        let g0: Vec<f64> = (0..n * m).map(|_| it.next().unwrap()).collect();
        let g1: Vec<f64> = (0..n * m).map(|_| it.next().unwrap()).collect();
        let mut u: Vec<f64> = (0..steps * m).map(|_| it.next().unwrap()).collect();
        if let Some(b) = blow_up.filter(|&b| b < steps) {
            u[b * m] = f64::INFINITY; // reaches the state one step later (through G0, G1)
        }
        let x0: Vec<f64> = (0..n).map(|_| it.next().unwrap()).collect();
        let c: Vec<f64> = (0..p * n).map(|_| it.next().unwrap()).collect();
        let d: Vec<f64> = (0..p * m).map(|_| it.next().unwrap()).collect();
        let mut states = vec![0.0; steps * n];
        let bad_states = timesim::lti_run(n, m, &phi, &g0, &g1, &u, &x0, &mut states).unwrap();
        let eye: Vec<f64> = (0..n * n).map(|k| if k / n == k % n { 1.0 } else { 0.0 }).collect();
        let (mut y, mut xs) = (vec![0.0; steps * p], vec![0.0; steps * n]);
        let bad = {
            let mut outs = [timesim::Output { p, c: &c, d: &d, out: &mut y }, timesim::Output { p: n, c: &eye, d: &vec![0.0; n * m], out: &mut xs }];
            timesim::lti_outputs(n, m, &phi, &g0, &g1, &u, &x0, &mut outs).unwrap()
        };
        prop_assert_eq!(bad, bad_states);
        let want_bad = states.chunks(n).position(|x| !x.iter().all(|v| v.is_finite()));
        prop_assert_eq!(bad, want_bad);
        // from the step the input is infinite on, D u holds 0 * inf (NaN) and the states are not
        // finite from the next step on: compare the steps before
        let cut = blow_up.unwrap_or(steps).min(want_bad.unwrap_or(steps));
        for k in 0..cut {
            for i in 0..n {
                prop_assert!(xs[k * n + i] == states[k * n + i], "state {} {}", k, i); // (-0 is +0 after + 0 x)
            }
            for i in 0..p {
                let want: f64 = (0..n).map(|j| c[i * n + j] * states[k * n + j]).sum::<f64>()
                    + (0..m).map(|j| d[i * m + j] * u[k * m + j]).sum::<f64>();
                prop_assert!((y[k * p + i] - want).abs() <= 1e-12 * (1.0 + want.abs()), "output {} {}", k, i);
            }
        }
    }

    /// The fixed-size path (8 or 16 states, one input: the rotor alone or on pedestals, SIMD over
    /// rows) gives the bits of the recursion summed row by row in the order of the generic loop,
    /// for the states and for stacked outputs.
    #[test]
    fn lti_fixed_sizes_give_the_bits_of_the_row_sums(big in proptest::bool::ANY, steps in 1usize..40, p1 in 1usize..9,
                                                    vals in proptest::collection::vec(-1.0f64..1.0, 300)) {
        let n = if big { 16 } else { 8 };
        let mut it = vals.iter().cycle().cloned();
        let phi: Vec<f64> = (0..n * n).map(|_| 0.25 * it.next().unwrap()).collect();
        let g0: Vec<f64> = (0..n).map(|_| it.next().unwrap()).collect();
        let g1: Vec<f64> = (0..n).map(|_| it.next().unwrap()).collect();
        let u: Vec<f64> = (0..steps).map(|_| it.next().unwrap()).collect();
        let x0: Vec<f64> = (0..n).map(|_| it.next().unwrap()).collect();
        let p2 = n - p1; // all n rows of the fixed path, in two outputs
        let c1: Vec<f64> = (0..p1 * n).map(|_| it.next().unwrap()).collect();
        let c2: Vec<f64> = (0..p2 * n).map(|_| it.next().unwrap()).collect();
        let (d1, d2): (Vec<f64>, Vec<f64>) = ((0..p1).map(|_| it.next().unwrap()).collect(), (0..p2).map(|_| it.next().unwrap()).collect());
        let mut states = vec![0.0; steps * n];
        timesim::lti_run(n, 1, &phi, &g0, &g1, &u, &x0, &mut states).unwrap();
        let (mut y1, mut y2) = (vec![0.0; steps * p1], vec![0.0; steps * p2]);
        {
            let mut outs = [timesim::Output { p: p1, c: &c1, d: &d1, out: &mut y1 }, timesim::Output { p: p2, c: &c2, d: &d2, out: &mut y2 }];
            timesim::lti_outputs(n, 1, &phi, &g0, &g1, &u, &x0, &mut outs).unwrap();
        }
        let row_sum = |row: &[f64], x: &[f64], tail: f64| -> f64 {
            let mut s = 0.0;
            for j in 0..x.len() {
                s += row[j] * x[j];
            }
            s + tail
        };
        let mut x = x0.clone();
        for k in 0..steps {
            for i in 0..n {
                prop_assert_eq!(states[k * n + i].to_bits(), x[i].to_bits(), "state {} {}", k, i);
            }
            for (c, d, y, p) in [(&c1, &d1, &y1, p1), (&c2, &d2, &y2, p2)] {
                for i in 0..p {
                    let want = row_sum(&c[i * n..(i + 1) * n], &x, d[i] * u[k]);
                    prop_assert_eq!(y[k * p + i].to_bits(), want.to_bits(), "output {} {}", k, i);
                }
            }
            if k + 1 < steps {
                let nx: Vec<f64> = (0..n).map(|i| row_sum(&phi[i * n..(i + 1) * n], &x, g0[i] * u[k] + g1[i] * (u[k + 1] - u[k]))).collect();
                x = nx;
            }
        }
    }

    /// Any lengths: an entry point answers Ok or a CoreError naming an argument, never panics.
    #[test]
    fn wrong_lengths_are_errors_not_panics(nk in 0usize..20, nc in 0usize..20, ns in 0usize..4, nw in 0usize..4,
                                           nf in 0usize..20, nrhs in 0usize..3, no in 0usize..20) {
        let r = nsf_rotor();
        let (k, cc) = (vec![1e6; nk], vec![1e3; nc]);
        let (spin, w) = (vec![100.0; ns], vec![100.0; nw]);
        let f = vec![c(1.0, 0.0); nf];
        let mut out = vec![c(0.0, 0.0); no];
        match forced::forced_response(&r, &k, &cc, &spin, &w, &f, nrhs, &mut out) {
            Ok(_) => prop_assert_eq!(no, nw * nrhs * 4),
            Err(e) => prop_assert!(["nrhs", "spin", "k", "c", "force", "out"].contains(&e.name())),
        }
        let (mut lam, mut sh) = (vec![c(0.0, 0.0); no], vec![c(0.0, 0.0); nf]);
        if let Err(e) = modal::modal(&r, &k, &cc, &spin, &mut lam, &mut sh) {
            prop_assert!(["k", "c", "lam", "shapes"].contains(&e.name()));
        }
    }
}

#[test]
fn identification_argument_errors_name_the_argument() {
    let r = nsf_rotor();
    let w = [100.0, 200.0];
    let q = vec![c(1e-6, 0.0); 2 * 2 * 4];
    let qb = blocks(&q, 2);
    let uneven: [&[C64]; 2] = [&q[..8], &q[..7]];
    let e = vec![c(1e-4, 0.0); 2 * 4];
    let gain = [1e4, 4e4];
    let base = IdentProblem { rotor: r, w: &w, spin: &w, q: &qb, e: &e, gain: &gain, sigma: &[], q_ped: &[], planes: None, batch: 1, runs: 2, identical: false };
    assert!(run_identify(&base, false).is_ok());
    let cases: Vec<(IdentProblem, &str)> = vec![
        (IdentProblem { runs: 0, ..base }, "runs"),
        (IdentProblem { q: &qb[..1], ..base }, "q (blocks)"),
        (IdentProblem { q: &uneven, ..base }, "q"),
        (IdentProblem { e: &e[..5], ..base }, "e"),
        (IdentProblem { gain: &[1.0, 2.0, 3.0], ..base }, "gain"),
        (IdentProblem { spin: &[100.0, 200.0, 300.0], ..base }, "spin"),
        (IdentProblem { sigma: &[0.0], ..base }, "sigma"),
        (IdentProblem { sigma: &[0.0, f64::NAN], ..base }, "sigma"),
        (IdentProblem { w: &[100.0, 0.0], ..base }, "w"),
        (IdentProblem { batch: 3, ..base }, "q (blocks)"),
    ];
    for (p, name) in cases {
        for report in [false, true] {
            match run_identify(&p, report) {
                Err(err) => assert_eq!(err.name(), name, "{err}"),
                Ok(_) => panic!("expected an error about {name}"),
            }
        }
    }
    // the refinement threshold
    let (mut k, mut cc, mut cond, mut resid, mut amp) = (vec![0.0; 16], vec![0.0; 16], vec![0.0; 4], vec![0.0; 2], vec![0.0; 2]);
    let out = IdentOut { k: &mut k, c: &mut cc, cond: &mut cond, resid: &mut resid, amp: &mut amp, k_std: None, c_std: None, rel_std: None };
    match rotorid_core::identify::identify_forces_refined(&base, out, f64::NAN) {
        Err(err) => assert_eq!(err.name(), "refine_cond", "{err}"),
        Ok(_) => panic!("expected an error about refine_cond"),
    }
}

proptest! {
    #![proptest_config(cfg(200))]
    /// The vectorized check of the vibration frequencies refuses a zero, an inf or a NaN wherever
    /// it is (in a block of eight or in the remainder) and takes negative frequencies and the
    /// extremes of the finite non-zero values.
    #[test]
    fn a_bad_frequency_anywhere_is_refused(n in 1usize..40, at in 0usize..40, bad in prop_oneof![
            Just(0.0), Just(-0.0), Just(f64::NAN), Just(f64::INFINITY), Just(f64::NEG_INFINITY)], negative in proptest::bool::ANY) {
        let r = nsf_rotor();
        let mut w: Vec<f64> = (0..n).map(|i| (if negative { -1.0 } else { 1.0 }) * (50.0 + 10.0 * i as f64)).collect();
        let q = vec![c(1e-6, 2e-7); 2 * n * 4];
        let qb = blocks(&q, n);
        let e: Vec<C64> = (0..8).map(|i| c(1e-4 * (1.0 + i as f64), 0.0)).collect();
        let p = |w: &[f64]| run_identify(&IdentProblem { rotor: r, w, spin: &[100.0], q: &qb, e: &e, gain: &[1.0], sigma: &[], q_ped: &[], planes: None, batch: 1, runs: 2, identical: false }, false).map(|_| ());
        prop_assert!(p(&w).is_ok());
        // the extremes of the finite non-zero values are taken
        for good in [5e-324, -f64::MIN_POSITIVE, f64::MAX, -f64::MAX] {
            let mut edge = w.clone();
            edge[at % n] = good;
            prop_assert!(p(&edge).is_ok(), "w = {} refused", good);
        }
        w[at % n] = bad;
        match p(&w) {
            Err(err) => prop_assert_eq!(err.name(), "w"),
            Ok(_) => prop_assert!(false, "a bad w at {} of {} was taken", at % n, n),
        }
    }
}

proptest! {
    /// The one-pass bounds check finds the first value a plain scan finds.
    #[test]
    fn first_outside_is_the_first_value_a_scan_finds(vals in proptest::collection::vec(
            prop_oneof![8 => 1e-3f64..1e6, 1 => Just(0.0), 1 => Just(-1.0), 1 => Just(f64::NAN),
                        1 => Just(f64::INFINITY), 1 => Just(1e6)], 0..100), prefix in 0usize..400) {
        // a run of inside values, then a mix: the first outside value falls in any block, or none
        let a: Vec<f64> = std::iter::repeat(1.0).take(prefix).chain(vals.iter().copied()).collect();
        let want = a.iter().position(|&v| !(v > 0.0 && v < 1e6));
        prop_assert_eq!(rotorid_core::bounds::first_outside(&a, 0.0, 1e6), want);
    }
}

#[test]
fn order_argument_errors_name_the_argument() {
    let x = vec![0.0; 100];
    let kp = [0.01, 0.02, 0.03];
    let mut out = vec![0.0; 2 * 8];
    assert!(order::angle_resample(&x, 1, 1000.0, 0.0, &kp, 0, 2, 8, &mut out).is_ok());
    let err = |r: Result<(), CoreError>| r.unwrap_err().name();
    assert_eq!(err(order::angle_resample(&x, 1, 1000.0, 0.0, &[0.02, 0.01], 0, 1, 8, &mut out)), "kp");
    assert_eq!(err(order::angle_resample(&x, 1, 0.0, 0.0, &kp, 0, 2, 8, &mut out)), "fs");
    assert_eq!(err(order::angle_resample(&x, 1, 1000.0, f64::NAN, &kp, 0, 2, 8, &mut out)), "t0");
    assert_eq!(err(order::angle_resample(&x, 1, 1000.0, 0.0, &kp, 2, 2, 8, &mut out)), "k0, k1");
    assert_eq!(err(order::angle_resample(&x, 1, 1000.0, 0.0, &kp, 0, 2, 3, &mut out)), "p");
    assert_eq!(err(order::angle_resample(&x, 3, 1000.0, 0.0, &kp, 0, 2, 8, &mut out)), "x");
    assert_eq!(err(order::angle_resample(&x, 1, 1000.0, 0.0, &kp, 0, 2, 8, &mut out[..3])), "out");
    let chans: [&[f64]; 1] = [&x];
    let mut ov = vec![C64::new(0.0, 0.0); 2 * 2];
    let ok = |r: Result<(), CoreError>| r.is_ok();
    assert!(ok(order::order_vectors(&chans, 1000.0, 0.0, &kp, 0, 2, 8, &[1, 3], &mut ov)));
    let err = |r: Result<(), CoreError>| r.unwrap_err().name();
    assert_eq!(err(order::order_vectors(&chans, 1000.0, 0.0, &[0.02, 0.01], 0, 1, 8, &[1, 3], &mut ov)), "kp");
    assert_eq!(err(order::order_vectors(&chans, -1.0, 0.0, &kp, 0, 2, 8, &[1, 3], &mut ov)), "fs");
    assert_eq!(err(order::order_vectors(&chans, 1000.0, f64::INFINITY, &kp, 0, 2, 8, &[1, 3], &mut ov)), "t0");
    assert_eq!(err(order::order_vectors(&[], 1000.0, 0.0, &kp, 0, 2, 8, &[1, 3], &mut ov)), "x");
    assert_eq!(err(order::order_vectors(&[&x[..], &x[1..]], 1000.0, 0.0, &kp, 0, 2, 8, &[1, 3], &mut ov)), "x");
    assert_eq!(err(order::order_vectors(&[&x[..0]], 1000.0, 0.0, &kp, 0, 2, 8, &[1, 3], &mut ov)), "x");
    assert_eq!(err(order::order_vectors(&chans, 1000.0, 0.0, &kp, 1, 1, 8, &[1, 3], &mut ov)), "k0, k1");
    assert_eq!(err(order::order_vectors(&chans, 1000.0, 0.0, &kp, 0, 3, 8, &[1, 3], &mut ov)), "k0, k1");
    assert_eq!(err(order::order_vectors(&chans, 1000.0, 0.0, &kp, 0, 2, 3, &[1], &mut ov[..2])), "p");
    assert_eq!(err(order::order_vectors(&chans, 1000.0, 0.0, &kp, 0, 2, 8, &[], &mut ov[..0])), "orders");
    assert_eq!(err(order::order_vectors(&chans, 1000.0, 0.0, &kp, 0, 2, 8, &[0, 1], &mut ov)), "orders");
    assert_eq!(err(order::order_vectors(&chans, 1000.0, 0.0, &kp, 0, 2, 8, &[1, 4], &mut ov)), "orders");
    assert_eq!(err(order::order_vectors(&chans, 1000.0, 0.0, &kp, 0, 2, 8, &[1, 3], &mut ov[..3])), "out");
    // pulses far outside the record: the stencils clamp to its ends, nothing overflows
    for far in [[-1e300, -0.9e300, -0.8e300], [1e300, 1.1e300, 1.2e300], [-1e300, 0.5, 1e300]] {
        assert!(order::order_vectors(&chans, 1000.0, 0.0, &far, 0, 2, 8, &[1, 3], &mut ov).is_ok());
        let mut res = vec![0.0; 2 * 8];
        assert!(order::angle_resample(&x, 1, 1000.0, 0.0, &far, 0, 2, 8, &mut res).is_ok());
    }
    let tpl = vec![0.0; 8];
    let mut o2 = vec![0.0; 50];
    assert!(order::runout_subtract(&x, 1, 1000.0, 0.0, &kp, &tpl, 8, 10, 60, &mut o2).is_ok());
    let mut xn = x.clone();
    xn[20] = f64::NAN;
    xn[70] = f64::INFINITY;
    xn[5] = f64::NAN; // outside i0..i1: not counted
    assert_eq!(order::runout_subtract(&xn, 1, 1000.0, 0.0, &kp, &tpl, 8, 10, 60, &mut o2), Ok(1));
    assert!(o2[10].is_nan());
    let err = |r: Result<usize, CoreError>| r.unwrap_err().name();
    assert_eq!(err(order::runout_subtract(&x, 1, 1000.0, 0.0, &kp, &tpl, 8, 60, 10, &mut o2)), "i0, i1");
    assert_eq!(err(order::runout_subtract(&x, 1, 1000.0, 0.0, &kp, &tpl[..5], 8, 10, 60, &mut o2)), "template");
    assert_eq!(err(order::runout_subtract(&x, 0, 1000.0, 0.0, &kp, &tpl, 8, 10, 60, &mut o2)), "x");
    let err = |r: Result<Option<usize>, CoreError>| r.unwrap_err().name();
    assert_eq!(err(timesim::lti_run(2, 0, &[0.0; 4], &[], &[], &[], &[0.0; 2], &mut [])), "m");
    assert_eq!(err(timesim::lti_run(2, 1, &[0.0; 3], &[0.0; 2], &[0.0; 2], &[0.0; 2], &[0.0; 2], &mut [0.0; 4])), "phi");
}

#[test]
fn flag_codes_match_their_definition() {
    use rotorid_core::identify::{flag_codes, FLAG_ILL_CONDITIONED, FLAG_LOW_AMPLITUDE, FLAG_SINGULAR, FLAG_UNCERTAIN};
    let _ = FLAG_UNCERTAIN;
    let cond = [1.0, 2.0, f64::INFINITY, 1.0, 5e4, 1.0, 1.0, f64::NAN, 10.0, 10.0];
    let amp = [1.0, 2.0, 4.0, 0.1, 3.0];
    // point 1 is uncertain too, but a singular point carries that reason alone; a NaN relative
    // standard error (unknown) flags nothing
    let rel_std = [0.01, 0.5, 0.01, 0.01, f64::NAN];
    let (mut rel, mut code, mut ok) = ([0.0; 5], [0u8; 5], [false; 5]);
    flag_codes(&cond, &amp, &rel_std, &[], &[], &[], 1e4, 0.08, 0.1, &mut rel, &mut code, &mut ok).unwrap();
    assert_eq!(rel, [0.25, 0.5, 1.0, 0.025, 0.75]);
    assert_eq!(code, [0, FLAG_SINGULAR, FLAG_ILL_CONDITIONED, FLAG_SINGULAR | FLAG_LOW_AMPLITUDE, 0]);
    assert_eq!(ok, [true, false, false, false, true]);
    let (mut rel0, mut code0, mut ok0) = ([9.0; 2], [9u8; 2], [true; 2]);
    flag_codes(&[1.0; 4], &[0.0, 0.0], &[0.0; 2], &[], &[], &[], 1e4, 0.08, 0.1, &mut rel0, &mut code0, &mut ok0).unwrap();
    assert_eq!((rel0, code0, ok0), ([0.0; 2], [FLAG_LOW_AMPLITUDE; 2], [false; 2]));
    assert!(flag_codes(&cond[..9], &amp, &rel_std, &[], &[], &[], 1e4, 0.08, 0.1, &mut rel, &mut code, &mut ok).is_err());
    assert!(flag_codes(&cond, &amp, &rel_std, &[0.0; 39], &[], &[], 1e4, 0.08, 0.1, &mut rel, &mut code, &mut ok).is_err());
    assert_eq!(
        flag_codes(&cond, &amp, &rel_std, &[], &[], &[], 1e4, 0.08, 0.1, &mut rel, &mut code, &mut [false; 4]).unwrap_err().to_string(),
        "ok has 4 elements, expected 5"
    );
    assert_eq!(
        flag_codes(&cond, &amp, &rel_std, &[], &[], &[1.0; 3], 1e4, 0.08, 0.1, &mut rel, &mut code, &mut ok).unwrap_err().to_string(),
        "dof has 3 elements, expected 40"
    );
}

#[test]
fn flag_codes_peak_propagates_nan_like_numpy() {
    use rotorid_core::identify::flag_codes;
    for n in [1usize, 7, 8, 9, 23, 64] {
        for nan_at in [None, Some(0), Some(n - 1), Some(n / 2)] {
            let mut amp: Vec<f64> = (0..n).map(|i| 1.0 + (i * 37 % 11) as f64).collect();
            if let Some(j) = nan_at {
                amp[j] = f64::NAN;
            }
            let top = amp.iter().cloned().fold(0.0f64, f64::max);
            let (mut rel, mut code, mut ok) = (vec![0.0; n], vec![0u8; n], vec![false; n]);
            flag_codes(&vec![1.0; 2 * n], &amp, &[], &[], &[], &[], 1e4, 0.0, 0.1, &mut rel, &mut code, &mut ok).unwrap();
            for i in 0..n {
                let want = if nan_at.is_some() { 0.0 } else { amp[i] / top };
                assert_eq!(rel[i], want, "n {n}, NaN at {nan_at:?}, point {i}");
            }
        }
    }
}

/// The parallel pass (from 32,768 points, in chunks of 8,192) gives what the definition gives
/// point by point: the peak is reduced over chunks (a NaN in the last chunk reaches the first),
/// with and without standard errors, at sizes around the chunk boundaries, with no degrees of
/// freedom (+inf), one for every point and one per point (1, 2 or +inf: Student's t of 1 and 2
/// degrees of freedom has closed forms, F(x; 1) = 1/2 + atan(x)/pi, F(x; 2) = 1/2 + x/(2 sqrt(2 + x^2))).
#[test]
fn flag_codes_in_parallel_match_the_definition_point_by_point() {
    use rotorid_core::identify::{flag_codes, FLAG_ILL_CONDITIONED, FLAG_LOW_AMPLITUDE, FLAG_NEGATIVE_DAMPING, FLAG_SINGULAR, FLAG_UNCERTAIN};
    for n in [32_767usize, 32_768, 40_961, 100_000] {
        for nan_last in [false, true] {
            let amp: Vec<f64> = (0..n).map(|i| if nan_last && i == n - 1 { f64::NAN } else { ((i * 7919) % 1000) as f64 }).collect();
            let cond: Vec<f64> = (0..2 * n).map(|j| match j % 13 { 0 => f64::INFINITY, 5 => 2e4, 9 => f64::NAN, _ => 3.0 }).collect();
            let rel_std: Vec<f64> = (0..n).map(|i| ((i % 17) as f64) / 50.0).collect();
            // damping: every 29th value negative, every 31st standard error unknown, NaN among them
            // (-3, -6 and -50 standard errors: flagged at +inf; at 2 dof from -4.5; at 1 dof from -14)
            let c: Vec<f64> = (0..8 * n).map(|j| match j % 29 { 0 => -3.0, 7 => -0.5, 11 => f64::NAN, 13 => -6.0, 17 => -50.0, _ => 100.0 }).collect();
            let c_std: Vec<f64> = (0..8 * n).map(|j| if j % 31 == 0 { f64::NAN } else { 1.0 }).collect();
            let peak = if nan_last { f64::NAN } else { 999.0 };
            let per_point: Vec<f64> = (0..n).map(|i| [f64::INFINITY, 1.0, 2.0][i % 3]).collect();
            for (with_std, dof) in [(false, &[][..]), (true, &[][..]), (true, &[2.0][..]), (true, &per_point[..])] {
                // ok starts as the opposite of what it must become: every value is written
                let (mut rel, mut code) = (vec![0.0; n], vec![0u8; n]);
                let mut ok: Vec<bool> = (0..n).map(|i| i % 2 == 0).collect();
                let (cs, ss) = if with_std { (&c[..], &c_std[..]) } else { (&c[..], &[][..]) };
                flag_codes(&cond, &amp, if with_std { &rel_std } else { &[] }, cs, ss, dof, 1e4, 0.05, 0.2, &mut rel, &mut code, &mut ok).unwrap();
                for i in 0..n {
                    let (c0, c1) = (cond[2 * i], cond[2 * i + 1]);
                    let finite = c0.is_finite() && c1.is_finite();
                    let ra = if peak > 0.0 { amp[i] / peak } else { 0.0 };
                    let mut want = 0;
                    if !finite {
                        want |= FLAG_SINGULAR;
                    }
                    if finite && c0.max(c1) > 1e4 {
                        want |= FLAG_ILL_CONDITIONED;
                    }
                    if finite && with_std && rel_std[i] > 0.2 {
                        want |= FLAG_UNCERTAIN;
                    }
                    if ra < 0.05 {
                        want |= FLAG_LOW_AMPLITUDE;
                    }
                    // the direct terms (Cxx, Cyy of both bearings) with F_t(d / s; dof) below
                    // Phi(-2) = 0.02275 (d < -2 s at +inf dof), or below 0 where the error is unknown
                    let v = match dof.len() {
                        0 => f64::INFINITY,
                        1 => dof[0],
                        _ => dof[i],
                    };
                    if [0, 3, 4, 7].iter().any(|&t| {
                        let (d, s) = (c[8 * i + t], if with_std { c_std[8 * i + t] } else { f64::NAN });
                        let x = d / s;
                        if s.is_nan() {
                            d < 0.0
                        } else if v == 1.0 {
                            0.5 + x.atan() / std::f64::consts::PI < 0.022_750_131_948_179_2
                        } else if v == 2.0 {
                            0.5 + x / (2.0 * (2.0 + x * x).sqrt()) < 0.022_750_131_948_179_2
                        } else {
                            d + 2.0 * s < 0.0
                        }
                    }) {
                        want |= FLAG_NEGATIVE_DAMPING;
                    }
                    assert_eq!(code[i], want, "n {n}, NaN last {nan_last}, std {with_std}, point {i}");
                    assert_eq!(ok[i], want == 0, "ok: n {n}, NaN last {nan_last}, std {with_std}, point {i}");
                    assert_eq!(rel[i].to_bits(), ra.to_bits(), "n {n}, point {i}");
                }
            }
        }
    }
}

/// apply_planes reports the first non-finite value of q (NaN or inf, in the real or the
/// imaginary part; in the serial and the parallel pass) and None when all are finite.
#[test]
fn apply_planes_finds_the_first_non_finite_value() {
    use rotorid_core::model::apply_planes;
    let t = [0.7, 0.3, -0.2, 1.1];
    for n in [3usize, 5000, 70_000] {
        let q: Vec<C64> = (0..4 * n).map(|i| c(i as f64 * 1e-3, -(i as f64) * 2e-3)).collect();
        let mut out = vec![c(0.0, 0.0); q.len()];
        assert_eq!(apply_planes(&t, &q, &mut out).unwrap(), None);
        for (at, bad) in [(4 * n - 1, c(f64::NAN, 0.0)), (2 * n + 1, c(0.0, f64::INFINITY)), (0, c(f64::NEG_INFINITY, 1.0))] {
            let mut qb = q.clone();
            qb[at] = bad;
            if at > 0 {
                qb[4 * n - 1] = c(f64::NAN, f64::NAN); // a later one does not hide the first
            }
            assert_eq!(apply_planes(&t, &qb, &mut out).unwrap(), Some(at), "n {n}, at {at}");
        }
    }
}
