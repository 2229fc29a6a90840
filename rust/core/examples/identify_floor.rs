//! The memory floor of a synchronous identification: the time to read the responses of `runs` runs
//! at `n` speeds and write the outputs `identify_forces` writes (k, c: 8 values per speed, cond: 2,
//! residual and amplitude: 1 each), with almost no arithmetic, on the same threads and in the same
//! chunks of 1,024 points, against the identification itself.
//!
//!     cargo run --release -p rotorid-core --example identify_floor [n] [runs] [threads] [rounds]
//!
//! Both are timed as one `pool.install` each (one hand-off to the pool per call, ~30 µs, on
//! both sides; the Python API's calls make none: the calling thread works in the core).
//! No kernel that reads its inputs from memory and writes its outputs there can beat the floor;
//! the README's Benchmarks section compares it with the 10x target's time budget.
use rayon::prelude::*;
use rotorid_core::identify::{identify_forces, IdentOut, IdentProblem};
use rotorid_core::{Rotor, C64};
use std::time::Instant;

const CHUNK: usize = 1024;

/// Read every response value of points `i0..i0 + len` and write 20 values per point derived from
/// them (one addition per value read, one store per value written).
fn stream_chunk(blocks: &[&[C64]], i0: usize, k: &mut [f64], c: &mut [f64], cond: &mut [f64], res: &mut [f64], amp: &mut [f64]) {
    for t in 0..res.len() {
        let i = i0 + t;
        let mut s = [0.0f64; 8];
        for b in blocks {
            let q = &b[4 * i..4 * i + 4];
            for d in 0..4 {
                s[2 * d] += q[d].re;
                s[2 * d + 1] += q[d].im;
            }
        }
        k[8 * t..8 * t + 8].copy_from_slice(&s);
        for o in 0..8 {
            c[8 * t + o] = -s[o];
        }
        cond[2 * t] = s[0];
        cond[2 * t + 1] = s[1];
        res[t] = s[2];
        amp[t] = s[3];
    }
}

/// Wall time of one call of `f`, in ms.
fn time_ms(f: &mut impl FnMut()) -> f64 {
    let t = Instant::now();
    f();
    t.elapsed().as_secs_f64() * 1e3
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |i: usize, d: usize| args.get(i).and_then(|a| a.parse().ok()).unwrap_or(d);
    let (n, runs, threads, rounds) = (arg(1, 100_000), arg(2, 4), arg(3, 2), arg(4, 30));
    let rotor = Rotor::from_slice(&[30.7, 0.62, 0.062, 0.146, 0.137]).expect("valid rotor");
    let c = C64::new;
    let w: Vec<f64> = (0..n).map(|i| 50.0 + 1000.0 * i as f64 / n as f64).collect();
    let q: Vec<C64> = (0..runs * n * 4).map(|i| c(1e-6 * (1.0 + (i % 7) as f64), 1e-6 * ((i % 5) as f64 - 2.0))).collect();
    let blocks: Vec<&[C64]> = q.chunks(n * 4).collect();
    let e: Vec<C64> = (0..4 * runs).map(|i| c(1e-4 * ((i % 3) as f64 - 1.0), 1e-5 * (i % 4) as f64)).collect();
    let p = IdentProblem { rotor, w: &w, spin: &w, q: &blocks, e: &e, gain: &[], sigma: &[], q_ped: &[], planes: None, batch: 1, runs, identical: false };
    let (mut k, mut cc, mut cond, mut res, mut amp) = (vec![0.0; 8 * n], vec![0.0; 8 * n], vec![0.0; 2 * n], vec![0.0; n], vec![0.0; n]);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
    let mut identify = || {
        let out = IdentOut { k: &mut k, c: &mut cc, cond: &mut cond, resid: &mut res, amp: &mut amp, k_std: None, c_std: None, rel_std: None };
        pool.install(|| identify_forces(&p, out).expect("valid problem"));
    };
    let (mut k2, mut c2, mut cond2, mut res2, mut amp2) = (vec![0.0; 8 * n], vec![0.0; 8 * n], vec![0.0; 2 * n], vec![0.0; n], vec![0.0; n]);
    let mut stream = || {
        pool.install(|| {
            (k2.par_chunks_mut(8 * CHUNK), c2.par_chunks_mut(8 * CHUNK), cond2.par_chunks_mut(2 * CHUNK), res2.par_chunks_mut(CHUNK), amp2.par_chunks_mut(CHUNK))
                .into_par_iter()
                .enumerate()
                .for_each(|(j, (k, c, cond, res, amp))| stream_chunk(&blocks, j * CHUNK, k, c, cond, res, amp));
        })
    };
    identify();
    stream();
    // interleaved rounds, best of each
    let (mut t_id, mut t_floor) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..rounds {
        t_id = t_id.min(time_ms(&mut identify));
        t_floor = t_floor.min(time_ms(&mut stream));
    }
    let bytes = (runs * 4 * 16 + 20 * 8) as f64 * n as f64;
    println!(
        "{n} points x {runs} runs, {threads} thread(s), best of {rounds}: identify_forces {t_id:.2} ms, memory floor {t_floor:.2} ms \
         ({:.1} MB read + written once: {:.1} GB/s); floor / identification {:.0} %",
        bytes / 1e6,
        bytes / t_floor / 1e6,
        100.0 * t_floor / t_id
    );
}
