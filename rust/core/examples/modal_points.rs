//! Modal analysis of `n` speeds, `reps` times on one thread: a fixed workload for instruction
//! counts (`valgrind --tool=callgrind`) and whole-process timing.
//!
//!     cargo build --release -p rotorid-core --example modal_points
//!     valgrind --tool=callgrind target/release/examples/modal_points 2000 2
use rotorid_core::modal::modal;
use rotorid_core::{Rotor, C64};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(2000);
    let reps: usize = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(5);
    let rotor = Rotor::from_slice(&[30.7, 0.62, 0.062, 0.146, 0.137]).unwrap();
    let k = [3.2e6, 4e5, -3e5, 2.9e6, 3.5e6, 2e5, -2e5, 3.1e6];
    let c = [2.1e3, 1e2, 1e2, 2.3e3, 2.2e3, 0.0, 0.0, 2.0e3];
    let kb: Vec<f64> = (0..n).flat_map(|_| k).collect();
    let cb: Vec<f64> = (0..n).flat_map(|_| c).collect();
    let spin: Vec<f64> = (0..n).map(|i| 1250.0 * i as f64 / n as f64).collect();
    let mut lam = vec![C64::new(0.0, 0.0); 4 * n];
    let mut shapes = vec![C64::new(0.0, 0.0); 16 * n];
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let t = Instant::now();
    pool.install(|| {
        for _ in 0..reps {
            modal(&rotor, &kb, &cb, &spin, &mut lam, &mut shapes).unwrap();
        }
    });
    let per = t.elapsed().as_secs_f64() / (n * reps) as f64;
    println!("{n} speeds x {reps}: {:.0} ns per speed (1 thread); lam[4] {:.9e}", per * 1e9, lam[4].im);
}
