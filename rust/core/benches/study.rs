//! Where a Monte Carlo study's time goes, one thread: the whole trial (`study::accumulate`) per
//! trial-point, and its parts alone at the same SIMD level (AVX2 + FMA when the CPU has it):
//! normal pairs (Box-Muller on the counter-based stream), phase rotations (sin/cos), the
//! identification of one point from 4 runs, and the histogram bin of an error.
//!
//!     cargo bench -p rotorid-core --bench study
//!
//! The sum of the parts (16 pairs + 16 rotations + 1 identification + 16 bins per trial-point, the
//! synchronous study with amplitude and phase errors) is what the one-pass kernel cannot go below
//! without faster parts; the README compares it with the NumPy baseline's time per trial-point.

use rotorid_core::identify::{identify_forces, IdentOut, IdentProblem};
use rotorid_core::study::{accumulate, rng, stats, Excitation, Method, Study, SyncErrors};
use rotorid_core::{Rotor, C64};
use std::hint::black_box;
use std::time::Instant;

fn best_s<F: FnMut()>(mut f: F) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..7 {
        let t0 = Instant::now();
        f();
        best = best.min(t0.elapsed().as_secs_f64());
    }
    best
}

// the parts as the kernel uses them: independent values written to arrays (no reduction, which
// would serialize the loop)
#[inline(always)]
fn pairs(key: u64, a: &mut [f64], b: &mut [f64]) {
    for j in 0..a.len() {
        let (x, y) = rng::normal_pair(key, j as u64);
        a[j] = x;
        b[j] = y;
    }
}

#[inline(always)]
fn rotations(t: &[f64], s: &mut [f64], c: &mut [f64]) {
    for i in 0..t.len() {
        let (x, y) = rng::sincos_turns(t[i]);
        s[i] = x;
        c[i] = y;
    }
}

#[inline(always)]
fn bins(e: &[f64], out: &mut [u32]) {
    for i in 0..e.len() {
        out[i] = stats::bin(e[i]);
    }
}

macro_rules! at_simd {
    ($name:ident, $body:ident($($a:ident: $t:ty),*)) => {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2,fma")]
        unsafe fn $name($($a: $t),*) {
            $body($($a),*)
        }
    };
}
at_simd!(pairs_avx2, pairs(key: u64, a: &mut [f64], b: &mut [f64]));
at_simd!(rotations_avx2, rotations(t: &[f64], s: &mut [f64], c: &mut [f64]));
at_simd!(bins_avx2, bins(e: &[f64], out: &mut [u32]));

fn main() {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    #[cfg(target_arch = "x86_64")]
    let avx2 = std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma");
    #[cfg(not(target_arch = "x86_64"))]
    let avx2 = false;
    pool.install(|| {
        let rotor = Rotor::from_slice(&[45.3, 0.704, 0.299, 0.189, 0.217]).unwrap();
        let kb = [3.0e6, 5.0e4, 3.0e4, 3.5e6, 3.0e6, 5.0e4, 3.0e4, 3.5e6];
        let cb = [2000.0, 250.0, 800.0, 2200.0, 2000.0, 250.0, 800.0, 2200.0];
        let n = 1000;
        let w: Vec<f64> = (0..n).map(|i| (1000.0 + 6000.0 * i as f64 / n as f64) * std::f64::consts::PI / 30.0).collect();
        let c = |re: f64, im: f64| C64::new(re, im);
        let u = [c(3.8e-4, 0.0), c(3.1e-4, 0.0), c(0.0, -4.7e-4), c(4.8e-4, 0.0), c(0.0, 3.8e-4), c(0.0, 4.1e-4), c(4.7e-4, 0.0), c(0.0, -4.8e-4)];
        let trials = 200u64;
        let mut study = Study {
            rotor,
            w: &w,
            kb: &kb,
            cb: &cb,
            probes_z: [-0.119, 0.146, -0.119, 0.146],
            excitation: Excitation::Imbalance { u: &u, planes_z: [-0.067, 0.102], errors: SyncErrors::default() },
            method: Method::Forces,
            seed: 1,
        };
        let per = (trials as usize * n) as f64;
        let t_zero = best_s(|| {
            black_box(accumulate(&study, 0, trials, 0, n).unwrap());
        }) / per;
        study.excitation = Excitation::Imbalance {
            u: &u,
            planes_z: [-0.067, 0.102],
            errors: SyncErrors { amplitude_rel: 0.01, phase_rad: 0.5f64.to_radians(), ..Default::default() },
        };
        let t_ap = best_s(|| {
            black_box(accumulate(&study, 0, trials, 0, n).unwrap());
        }) / per;

        // the identification alone: 4 runs at n points, 50 batches
        let q: Vec<C64> = (0..4 * n * 4).map(|i| c(1e-6 * (1.0 + (i % 7) as f64), 1e-6 * ((i % 5) as f64 - 2.0))).collect();
        let blocks: Vec<&[C64]> = q.chunks(n * 4).collect();
        let e = [c(1e-4, 0.0), c(0.0, -1e-4), c(1e-5, 0.0), c(0.0, 1e-5), c(0.0, 1e-4), c(1e-4, 0.0), c(2e-5, 0.0), c(0.0, -1e-5), c(1e-4, 1e-4), c(1e-4, -1e-4), c(0.0, 0.0), c(0.0, 0.0), c(1e-4, 0.0), c(1e-4, 0.0), c(-1e-5, 0.0), c(1e-5, 0.0)];
        let gain: Vec<f64> = w.iter().map(|v| v * v).collect();
        let p = IdentProblem { rotor, w: &w, spin: &w, q: &blocks, e: &e, gain: &gain, sigma: &[], q_ped: &[], planes: None, batch: 1, runs: 4, identical: false };
        let (mut k, mut cc, mut cond, mut res, mut amp) = (vec![0.0; 8 * n], vec![0.0; 8 * n], vec![0.0; 2 * n], vec![0.0; n], vec![0.0; n]);
        let t_id = best_s(|| {
            for _ in 0..50 {
                let o = IdentOut { k: &mut k, c: &mut cc, cond: &mut cond, resid: &mut res, amp: &mut amp, k_std: None, c_std: None, rel_std: None };
                black_box(identify_forces(&p, o).unwrap());
            }
        }) / (50 * n) as f64;

        // the parts on arrays of 4096 values (in L1/L2, as in the kernel's blocks), 250 times
        let m = 4096;
        let reps = 250;
        let (mut a, mut b) = (vec![0.0; m], vec![0.0; m]);
        let t: Vec<f64> = (0..m).map(|i| i as f64 * 1e-4 - 0.2).collect();
        let ev: Vec<f64> = (0..m).map(|i| (i as f64 - 2048.0) * 1e-5).collect();
        let mut bo = vec![0u32; m];
        let per_value = (m * reps) as f64;
        #[cfg(target_arch = "x86_64")]
        let at_avx2 = if avx2 {
            // SAFETY: the CPU has AVX2 and FMA (checked above)
            unsafe {
                Some((
                    best_s(|| (0..reps).for_each(|r| pairs_avx2(black_box(r as u64), &mut a, &mut b))) / per_value,
                    best_s(|| (0..reps).for_each(|_| rotations_avx2(black_box(&t), &mut a, &mut b))) / per_value,
                    best_s(|| (0..reps).for_each(|_| bins_avx2(black_box(&ev), &mut bo))) / per_value,
                ))
            }
        } else {
            None
        };
        #[cfg(not(target_arch = "x86_64"))]
        let at_avx2: Option<(f64, f64, f64)> = None;
        let (t_pair, t_rot, t_bin) = at_avx2.unwrap_or_else(|| {
            (
                best_s(|| (0..reps).for_each(|r| pairs(black_box(r as u64), &mut a, &mut b))) / per_value,
                best_s(|| (0..reps).for_each(|_| rotations(black_box(&t), &mut a, &mut b))) / per_value,
                best_s(|| (0..reps).for_each(|_| bins(black_box(&ev), &mut bo))) / per_value,
            )
        });
        black_box((&a, &b, &bo));
        let floor = 16.0 * t_pair + 16.0 * t_rot + t_id + 16.0 * t_bin;
        println!("one thread, {} SIMD level for the parts", if avx2 { "AVX2 + FMA" } else { "baseline" });
        println!("study, 200 trials x 1000 speeds x 4 runs, no errors:          {:6.0} ns per trial-speed", t_zero * 1e9);
        println!("study, same with 1 % amplitude and 0.5 deg phase errors:     {:6.0} ns per trial-speed", t_ap * 1e9);
        println!("  normal pair (Box-Muller on the counter stream):            {:6.2} ns", t_pair * 1e9);
        println!("  rotation (sin and cos of one angle):                       {:6.2} ns", t_rot * 1e9);
        println!("  identification of one point from 4 runs:                  {:6.1} ns", t_id * 1e9);
        println!("  histogram bin of one error:                                {:6.2} ns", t_bin * 1e9);
        println!("  sum of the parts of a trial-speed (16 + 16 + 1 + 16):       {:6.0} ns", floor * 1e9);
    });
}
