//! Forced response of `n` points with shared bearings, `reps` times on one thread: a fixed
//! workload for instruction counts (`valgrind --tool=callgrind`, repeatable whatever else the
//! machine is doing) and whole-process timing.
//!
//!     cargo build --release -p rotorid-core --example forced_points
//!     valgrind --tool=callgrind target/release/examples/forced_points 4096 5 [unit|imbalance|probes]
//!
//! `unit` (default): unit forces; `imbalance`: the forces scaled by Omega^2; `probes`: an
//! imbalance response moved to two other planes (eq. 19) as the API's `at="probes"` asks.
//! `THREADS=2` runs it on a pool of two threads (default one).
use rotorid_core::forced::{forced_response_with, Gain};
use rotorid_core::{Rotor, C64};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(4096);
    let reps: usize = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(5);
    let mode = args.get(3).map_or("unit", |a| a.as_str());
    let (gain, planes) = match mode {
        "unit" => (Gain::One, None),
        "imbalance" => (Gain::SpinSquared, None),
        "probes" => (Gain::SpinSquared, Some([1.2, -0.2, -0.3, 1.3])),
        _ => panic!("mode must be unit, imbalance or probes, got {mode:?}"),
    };
    let rotor = Rotor::from_slice(&[30.7, 0.62, 0.062, 0.146, 0.137]).unwrap();
    let kb = [3.2e6, 4e5, -3e5, 2.9e6, 3.5e6, 2e5, -2e5, 3.1e6];
    let cb = [2.1e3, 1e2, 1e2, 2.3e3, 2.2e3, 0.0, 0.0, 2.0e3];
    let w: Vec<f64> = (0..n).map(|i| 50.0 + 1250.0 * i as f64 / n as f64).collect();
    let f = [C64::new(1.0, 0.0), C64::new(0.5, 0.2), C64::new(0.0, -1.0), C64::new(-0.2, 0.1)];
    let mut q = vec![C64::new(0.0, 0.0); n * 4];
    let threads = std::env::var("THREADS").ok().and_then(|v| v.parse().ok()).unwrap_or(1);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    // one hand-off to the pool for all repetitions (one per call cost ~30 µs, 7 ns per point at 4,096)
    let t = Instant::now();
    pool.install(|| {
        for _ in 0..reps {
            forced_response_with(&rotor, &kb, &cb, &w, &w, &f, 1, gain, planes.as_ref(), &mut q).unwrap();
        }
    });
    let per = t.elapsed().as_secs_f64() / (n * reps) as f64;
    println!("{n} points x {reps}, {mode}: {:.1} ns per point ({threads} thread(s)); q[0] {:.6e}", per * 1e9, q[0].re);
}
