//! Forced response per point, single thread: the per-point path (`dynamic_stiffness` + `solve4`,
//! one point at a time) against `forced_response` (8 points in lock-step, runtime SIMD dispatch)
//! on a rayon pool of one thread.
//!
//!     cargo bench -p rotorid-core --bench forced
//!
//! Prints ns per point (assembly of H included) for one and four right-hand sides, shared and
//! per-point bearing coefficients, and the largest difference between the two answers.

use rotorid_core::forced::{dynamic_stiffness, forced_response, solve4};
use rotorid_core::{Rotor, C64};
use std::hint::black_box;
use std::time::Instant;

fn best_ns<F: FnMut() -> f64>(n: usize, mut f: F) -> (f64, f64) {
    let mut best = f64::INFINITY;
    let mut sink = 0.0;
    for _ in 0..9 {
        let t0 = Instant::now();
        sink += f();
        best = best.min(t0.elapsed().as_secs_f64());
    }
    (best / n as f64 * 1e9, sink)
}

/// Largest |a - b| / max |b| over points (NaN outputs must match).
fn max_rel_diff(a: &[C64], b: &[C64], stride: usize) -> f64 {
    let mut worst = 0.0f64;
    for (pa, pb) in a.chunks(stride).zip(b.chunks(stride)) {
        let scale = pb.iter().fold(0.0f64, |m, z| m.max(z.norm()));
        for (x, y) in pa.iter().zip(pb) {
            if x.re.is_nan() || y.re.is_nan() {
                assert!(x.re.is_nan() && y.re.is_nan(), "singular points differ");
                continue;
            }
            worst = worst.max((x - y).norm() / scale);
        }
    }
    worst
}

fn main() {
    let rotor = Rotor::from_slice(&[30.7, 0.62, 0.062, 0.146, 0.137]).unwrap();
    let (m, g) = (rotor.mass_matrix(), rotor.gyro_matrix());
    let n = 100_000;
    let kb = [3.2e6, 4e5, -3e5, 2.9e6, 3.5e6, 2e5, -2e5, 3.1e6];
    let cb = [2.1e3, 1e2, 1e2, 2.3e3, 2.2e3, 0.0, 0.0, 2.0e3];
    let w: Vec<f64> = (0..n).map(|i| 50.0 + 1250.0 * i as f64 / n as f64).collect();
    // per-point coefficients: a speed-dependent bearing
    let kk: Vec<f64> = w.iter().flat_map(|&wi| kb.map(|v| v * (1.0 + 1e-4 * wi))).collect();
    let cc: Vec<f64> = w.iter().flat_map(|&wi| cb.map(|v| v * (1.0 - 1e-4 * wi))).collect();
    let f4 = [
        C64::new(1.0, 0.0),
        C64::new(0.5, 0.2),
        C64::new(0.0, -1.0),
        C64::new(-0.2, 0.1),
        C64::new(0.0, 1.0),
        C64::new(0.3, 0.0),
        C64::new(1.0, 1.0),
        C64::new(0.0, 0.0),
        C64::new(0.2, -0.4),
        C64::new(-1.0, 0.0),
        C64::new(0.0, 0.5),
        C64::new(0.7, 0.1),
        C64::new(0.1, 0.1),
        C64::new(0.0, 0.0),
        C64::new(-0.5, 0.5),
        C64::new(1.0, 0.0),
    ];
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();

    println!("forced response, {n} points, 1 thread (ns/point, assembly of H included):");
    for (label, per_point) in [("shared bearings   ", false), ("per-point bearings", true)] {
        for nrhs in [1usize, 4] {
            let force = &f4[..4 * nrhs];
            let (k, c): (&[f64], &[f64]) = if per_point { (&kk, &cc) } else { (&kb, &cb) };
            let mut q_scalar = vec![C64::new(0.0, 0.0); n * 4 * nrhs];
            let (t_scalar, _) = best_ns(n, || {
                for (i, o) in q_scalar.chunks_mut(4 * nrhs).enumerate() {
                    o.copy_from_slice(force);
                    let (ki, ci) = if per_point { (8 * i, 8 * i) } else { (0, 0) };
                    let mut h = dynamic_stiffness(&rotor, &m, &g, &k[ki..ki + 8], &c[ci..ci + 8], w[i], w[i]);
                    solve4(&mut h, o);
                }
                black_box(q_scalar[0].re)
            });
            let mut q_lanes = vec![C64::new(0.0, 0.0); n * 4 * nrhs];
            let (t_lanes, _) = best_ns(n, || {
                pool.install(|| forced_response(&rotor, k, c, &w, &w, force, nrhs, &mut q_lanes).unwrap());
                black_box(q_lanes[0].re)
            });
            println!(
                "  {label} nrhs={nrhs}: per-point solve4 {t_scalar:7.1}   lanes {t_lanes:6.1}   ({:.1}x)   max rel. diff {:.1e}",
                t_scalar / t_lanes,
                max_rel_diff(&q_lanes, &q_scalar, 4 * nrhs)
            );
        }
    }
    let threads = rayon::current_num_threads();
    let mut q = vec![C64::new(0.0, 0.0); n * 4];
    let (t_all, _) = best_ns(n, || {
        forced_response(&rotor, &kb, &cb, &w, &w, &f4[..4], 1, &mut q).unwrap();
        black_box(q[0].re)
    });
    println!("  shared bearings    nrhs=1, {threads} threads: lanes {t_all:6.1} ns/point");
}
