//! Identify `n` points from `runs` runs (default 4) `reps` times on one thread: a fixed workload for instruction
//! counts (`valgrind --tool=callgrind`, repeatable whatever else the machine is doing) and timing.
//!
//!     cargo build --release -p rotorid-core --example identify_points
//!     valgrind --tool=callgrind target/release/examples/identify_points 4096 5 [std|nostd] [runs] [planes]
//!
//! `planes`: the responses at probe planes (an eq. 19 transform), which the kernels' general
//! instance serves instead of the fixed-run ones.
use num_complex::Complex64 as C64;
use rotorid_core::identify::{identify_forces, IdentOut, IdentProblem};
use rotorid_core::Rotor;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(4096);
    let reps: usize = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(5);
    let want_std = args.get(3).map_or(false, |a| a == "std");
    let runs: usize = args.get(4).and_then(|a| a.parse().ok()).unwrap_or(4);
    let planes = (args.get(5).map(String::as_str) == Some("planes")).then_some([1.1, -0.1, -0.1, 1.1]);
    let rotor = Rotor::from_slice(&[30.7, 0.62, 0.062, 0.146, 0.137]).unwrap();
    let c = C64::new;
    let w: Vec<f64> = (0..n).map(|i| 50.0 + 1000.0 * i as f64 / n as f64).collect();
    let q: Vec<C64> = (0..runs * n * 4).map(|i| c(1e-6 * (1.0 + (i % 7) as f64), 1e-6 * ((i % 5) as f64 - 2.0))).collect();
    let blocks: Vec<&[C64]> = q.chunks(n * 4).collect();
    let e: Vec<C64> = (0..4 * runs).map(|i| c(1e-4 * ((i % 3) as f64 - 1.0), 1e-5 * (i % 4) as f64)).collect();
    let gain: Vec<f64> = w.iter().map(|v| v * v).collect();
    let p = IdentProblem { rotor, w: &w, spin: &w, q: &blocks, e: &e, gain: &gain, sigma: &[], q_ped: &[], planes, batch: 1, runs, identical: false };
    let (mut k, mut cc, mut cond, mut res, mut amp) = (vec![0.0; 8 * n], vec![0.0; 8 * n], vec![0.0; 2 * n], vec![0.0; n], vec![0.0; n]);
    let (mut ks, mut cs, mut rel) = (vec![0.0; 8 * n], vec![0.0; 8 * n], vec![0.0; n]);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    // one hand-off to the pool for all repetitions (one per call cost ~30 µs, 7 ns per point at 4,096)
    let t = Instant::now();
    pool.install(|| for _ in 0..reps {
        let o = IdentOut {
            k: &mut k,
            c: &mut cc,
            cond: &mut cond,
            resid: &mut res,
            amp: &mut amp,
            k_std: if want_std { Some(&mut ks) } else { None },
            c_std: if want_std { Some(&mut cs) } else { None },
            rel_std: if want_std { Some(&mut rel) } else { None },
        };
        identify_forces(&p, o).unwrap();
    });
    let per = t.elapsed().as_secs_f64() / (reps * n) as f64;
    let worst = cond.iter().cloned().fold(0.0, f64::max);
    println!("{n} points x {reps}, {runs} runs, std {want_std}: {:.1} ns per point (one thread); k[0] {:.3e}, largest cond {worst:.2e}", per * 1e9, k[0]);
}
