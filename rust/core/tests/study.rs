//! Monte Carlo study kernel: exact data give rounding-level errors, the measured values satisfy
//! the equations of motion of the perturbed test, statistics merge exactly over trial ranges, and
//! every wrong argument is an `Err`.

mod common;

use common::{c, motion_residual, nsf_rotor};
use rotorid_core::study::{accumulate, realize, Excitation, ImpactErrors, Method, Study, SyncErrors, BINS, NCOEF};
use rotorid_core::C64;

const K: [f64; 8] = [3.0e6, 5.0e4, 3.0e4, 3.5e6, 3.0e6, 5.0e4, 3.0e4, 3.5e6];
const C: [f64; 8] = [2000.0, 250.0, 800.0, 2200.0, 2000.0, 250.0, 800.0, 2200.0];

fn runs() -> Vec<C64> {
    // m r e^{-j phi} per plane, four independent runs
    vec![c(3e-4, 0.0), c(3e-4, 0.0), c(0.0, -4e-4), c(5e-4, 0.0), c(3e-4, 0.0), c(0.0, -4e-4), c(0.0, 3e-4), c(4e-4, 0.0)]
}

fn sync_study<'a>(w: &'a [f64], u: &'a [C64], errors: SyncErrors, at_bearings: bool) -> Study<'a> {
    let r = nsf_rotor();
    let probes = if at_bearings { [-r.l1, r.l2, -r.l1, r.l2] } else { [-0.12, 0.15, -0.12, 0.15] };
    Study {
        rotor: r,
        w,
        kb: &K,
        cb: &C,
        probes_z: probes,
        excitation: Excitation::Imbalance { u, planes_z: [-0.07, 0.1], errors },
        method: Method::Forces,
        seed: 7,
    }
}

fn speeds() -> Vec<f64> {
    (0..24).map(|i| 300.0 + 30.0 * i as f64).collect()
}

#[test]
fn exact_data_identify_the_truth() {
    let (w, u) = (speeds(), runs());
    for method in [Method::Forces, Method::Report] {
        let mut s = sync_study(&w, &u, SyncErrors::default(), false);
        s.method = method;
        let st = accumulate(&s, 0, 5, 0, w.len()).unwrap();
        assert!(st.nonfinite.iter().all(|&v| v == 0));
        for (sum, n) in st.sum.iter().zip(&st.finite) {
            assert_eq!(*n, 5);
            assert!((sum / 5.0).abs() < 1e-7, "{method:?}: mean error {}", sum / 5.0);
        }
    }
}

#[test]
fn measured_vectors_are_the_perturbed_tests_responses() {
    // without errors, measured at the bearings, every run's vector of every trial satisfies the
    // equations of motion (checked term by term by the reference in tests/common) with the
    // generalized imbalance force of eq. 4
    let (w, u) = (speeds(), runs());
    let s = sync_study(&w, &u, SyncErrors::default(), true);
    let n = w.len();
    let mut q = vec![c(0.0, 0.0); 2 * 4 * n * 4];
    let mut wt = vec![0.0; 2 * n];
    realize(&s, 3, 5, &mut q, &mut wt).unwrap();
    for r in 0..4 {
        let (u1, u2) = (u[2 * r], u[2 * r + 1]);
        let (z1, z2) = (-0.07, 0.1);
        let sum = u1 + u2;
        let mom = u1 * z1 + u2 * z2;
        let e = [sum, c(0.0, -1.0) * sum, mom, c(0.0, 1.0) * mom];
        for i in 0..n {
            let qi = &q[(4 * n + r * n + i) * 4..(4 * n + r * n + i) * 4 + 4];
            let f: Vec<C64> = e.iter().map(|v| v * w[i] * w[i]).collect();
            let res = motion_residual(&s.rotor, &K, &C, w[i], w[i], qi, &f);
            let scale = f.iter().map(|v| v.norm()).fold(0.0, f64::max);
            assert!(res.iter().all(|v| v.norm() < 1e-9 * scale), "run {r} point {i}: {res:?}");
        }
    }
    assert_eq!(wt[n..], w[..]);
}

#[test]
fn trial_ranges_merge_exactly_and_repeat() {
    let (w, u) = (speeds(), runs());
    let e = SyncErrors { amplitude_rel: 0.01, phase_rad: 0.01, noise_m: 1e-8, keyphasor_rad: 0.002, delay_s: 1e-6, probe_position_m: 1e-4, mass_rel: 0.01, angle_rad: 0.01, speed_rel: 0.001 };
    let s = sync_study(&w, &u, e, false);
    let all = accumulate(&s, 0, 40, 0, w.len()).unwrap();
    let a = accumulate(&s, 0, 17, 0, w.len()).unwrap();
    let b = accumulate(&s, 17, 40, 0, w.len()).unwrap();
    let merged: Vec<u32> = a.counts.iter().zip(&b.counts).map(|(x, y)| x + y).collect();
    assert_eq!(merged, all.counts);
    assert_eq!(all.counts.len(), w.len() * NCOEF * BINS);
    for j in 0..all.sum.len() {
        assert!((a.sum[j] + b.sum[j] - all.sum[j]).abs() <= 1e-12 * all.sumsq[j].sqrt().max(1e-300) * 40.0);
    }
    // a sub-range of points gives the same statistics for those points
    let part = accumulate(&s, 0, 40, 5, 9).unwrap();
    assert_eq!(part.counts[..], all.counts[5 * NCOEF * BINS..9 * NCOEF * BINS]);
    assert_eq!(accumulate(&s, 0, 40, 0, w.len()).unwrap(), all);
    // a different seed gives different numbers
    let mut s2 = s;
    s2.seed = 8;
    assert_ne!(accumulate(&s2, 0, 40, 0, w.len()).unwrap().counts, all.counts);
}

#[test]
fn impact_study_exact_and_noisy() {
    let w: Vec<f64> = (1..20).map(|i| 2.0 * std::f64::consts::PI * 10.0 * i as f64).collect();
    let planes = [0.0, 0.0];
    let dirs = [0u8, 1u8];
    let r = nsf_rotor();
    let mut s = Study {
        rotor: r,
        w: &w,
        kb: &K,
        cb: &C,
        probes_z: [-r.l1, r.l2, -r.l1, r.l2],
        excitation: Excitation::Impact { planes_z: &planes, dirs: &dirs, spin: 100.0, errors: ImpactErrors::default() },
        method: Method::Forces,
        seed: 1,
    };
    let st = accumulate(&s, 0, 3, 0, w.len()).unwrap();
    assert!(st.sum.iter().all(|v| v.abs() < 3.0 * 1e-7));
    s.excitation = Excitation::Impact { planes_z: &planes, dirs: &dirs, spin: 100.0, errors: ImpactErrors { frf_rel: 0.05, ..Default::default() } };
    let st = accumulate(&s, 0, 50, 0, w.len()).unwrap();
    let rms: f64 = (st.sumsq.iter().sum::<f64>() / st.finite.iter().map(|&v| v as f64).sum::<f64>()).sqrt();
    assert!(rms > 1e-3, "noisy FRFs must give visible errors, rms {rms}");
}

#[test]
fn wrong_arguments_are_errors() {
    let (w, u) = (speeds(), runs());
    let good = sync_study(&w, &u, SyncErrors::default(), false);
    assert!(accumulate(&good, 5, 2, 0, w.len()).is_err());
    assert!(accumulate(&good, 0, 2, 3, 3).is_err());
    assert!(accumulate(&good, 0, 2, 0, w.len() + 1).is_err());
    let bad_w = [300.0, -1.0];
    assert!(accumulate(&sync_study(&bad_w, &u, SyncErrors::default(), false), 0, 1, 0, 2).is_err());
    let nan_w = [300.0, f64::NAN];
    assert!(accumulate(&sync_study(&nan_w, &u, SyncErrors::default(), false), 0, 1, 0, 2).is_err());
    let neg = SyncErrors { phase_rad: -0.1, ..Default::default() };
    assert!(accumulate(&sync_study(&w, &u, neg, false), 0, 1, 0, w.len()).is_err());
    let one_run = &u[..2];
    assert!(accumulate(&sync_study(&w, one_run, SyncErrors::default(), false), 0, 1, 0, w.len()).is_err());
    let odd = &u[..3];
    assert!(accumulate(&sync_study(&w, odd, SyncErrors::default(), false), 0, 1, 0, w.len()).is_err());
    let mut same_probes = good;
    same_probes.probes_z = [0.1, 0.1, -0.1, 0.2];
    assert!(accumulate(&same_probes, 0, 1, 0, w.len()).is_err());
    let short_k = [1.0; 7];
    let mut sk = good;
    sk.kb = &short_k;
    assert!(accumulate(&sk, 0, 1, 0, w.len()).is_err());
    let mut q = vec![c(0.0, 0.0); 3];
    let mut wt = vec![0.0; w.len()];
    assert!(realize(&good, 0, 1, &mut q, &mut wt).is_err());
}
