//! Digests (FNV-1a over the bits of every output value) of the identification, forward-response
//! and modal kernels on fixed inputs that reach their awkward paths: NaN and inf inputs, singular
//! points, groups that wrap across batch rows, tail groups, windowed spectra, the probe-plane
//! transform, per-point coefficients and several right-hand sides.
//!
//! The kernels promise the same IEEE operations at every SIMD level and on every architecture, so
//! these digests must not change with `ROTORID_SIMD` (avx512, avx2, baseline), with the number of
//! threads, or between x86-64 and aarch64:
//!
//!     cargo run --profile test -p rotorid-core --example bit_digest
//!     ROTORID_SIMD=baseline cargo run --profile test -p rotorid-core --example bit_digest
//!     CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc \
//!     CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_RUNNER="qemu-aarch64 -L /usr/aarch64-linux-gnu" \
//!         cargo run --release -p rotorid-core --example bit_digest --target aarch64-unknown-linux-gnu
//!
//! The modal digest is printed apart: the eigen-solver calls `sqrt` only, but its iteration count
//! depends on comparisons of rounded values, and it is not part of the SIMD promise (no lanes).
use rotorid_core::forced::{forced_response_with, Gain};
use rotorid_core::identify::{identify_forces, IdentOut, IdentProblem};
use rotorid_core::modal::modal;
use rotorid_core::{Rotor, C64};

/// FNV-1a state, values seen, finite values seen.
struct Digest(u64, usize, usize);

impl Digest {
    fn new() -> Self {
        Digest(0xcbf2_9ce4_8422_2325, 0, 0)
    }
    fn add(&mut self, values: &[f64]) {
        for v in values {
            self.1 += 1;
            self.2 += v.is_finite() as usize;
            // one pattern for every NaN: which NaN an operation on two NaNs returns (sign,
            // payload) depends on the order LLVM gives its operands, which IEEE leaves open
            let bits = if v.is_nan() { f64::NAN.to_bits() } else { v.to_bits() };
            for b in bits.to_le_bytes() {
                self.0 = (self.0 ^ b as u64).wrapping_mul(0x0100_0000_01b3);
            }
        }
    }
    fn add_c(&mut self, values: &[C64]) {
        for v in values {
            self.add(&[v.re, v.im]);
        }
    }
}

fn c(re: f64, im: f64) -> C64 {
    C64::new(re, im)
}

/// A deterministic value in [-1, 1) from an index (no RNG crate, same on every platform).
fn val(i: usize, salt: usize) -> f64 {
    let x = (i.wrapping_mul(2_654_435_761) ^ salt.wrapping_mul(40_503)) % 10_007;
    x as f64 / 5003.5 - 1.0
}

fn identification(d: &mut Digest, rotor: Rotor) {
    for &(n, batch, runs, identical, windowed, probes) in &[
        (37usize, 3usize, 4usize, false, false, false),
        (10, 2, 2, false, true, false),
        (13, 1, 3, true, false, false),
        (5000, 2, 4, false, false, true),
        (7, 5, 2, true, true, false),
        (4099, 1, 2, false, false, false),
    ] {
        let w: Vec<f64> = (0..n).map(|i| 50.0 + 1000.0 * i as f64 / n as f64).collect();
        let mut q: Vec<C64> = (0..batch * runs * n * 4).map(|i| c(1e-6 * val(i, 1), 1e-6 * val(i, 2))).collect();
        q[4 * 3 + 1] = c(f64::NAN, 0.0);
        if n > 9 {
            q[4 * 9 + 2] = c(0.0, f64::INFINITY);
        }
        // a singular point: the first two runs equal at point 5 of batch 0
        for dd in 0..4 {
            q[n * 4 + 4 * 5 + dd] = q[4 * 5 + dd];
        }
        // no response at all at point 6 of the last batch
        for r in 0..runs {
            for dd in 0..4 {
                q[((batch - 1) * runs + r) * n * 4 + 4 * 6 + dd] = c(0.0, 0.0);
            }
        }
        let blocks: Vec<&[C64]> = q.chunks(n * 4).collect();
        let e: Vec<C64> = (0..4 * runs * batch).map(|i| c(1e-4 * val(i, 3), 1e-5 * val(i, 4))).collect();
        let gain: Vec<f64> = w.iter().map(|v| v * v).collect();
        let sigma: Vec<f64> = w.iter().map(|v| 0.01 * v).collect();
        for per_batch_e in [false, true] {
            let p = IdentProblem {
                rotor,
                w: &w,
                spin: &w,
                q: &blocks,
                e: if per_batch_e { &e } else { &e[..4 * runs] },
                gain: if per_batch_e { &gain } else { &[] },
                sigma: if windowed { &sigma } else { &[] },
                q_ped: &[],
                planes: if probes { Some([1.2, -0.2, -0.3, 1.3]) } else { None },
                batch,
                runs,
                identical,
            };
            let m = batch * n;
            let (mut k, mut cc, mut cond, mut res, mut amp) = (vec![0.0; 8 * m], vec![0.0; 8 * m], vec![0.0; 2 * m], vec![0.0; m], vec![0.0; m]);
            let (mut ks, mut cs, mut rel) = (vec![0.0; 8 * m], vec![0.0; 8 * m], vec![0.0; m]);
            let out = IdentOut { k: &mut k, c: &mut cc, cond: &mut cond, resid: &mut res, amp: &mut amp, k_std: Some(&mut ks), c_std: Some(&mut cs), rel_std: Some(&mut rel) };
            let nbad = identify_forces(&p, out).expect("valid problem");
            for a in [&k, &cc, &cond, &res, &amp, &ks, &cs, &rel] {
                d.add(a);
            }
            d.add(&[nbad as f64]);
        }
    }
}

fn forward(d: &mut Digest, rotor: Rotor) {
    let kb = [3.2e6, 4e5, -3e5, 2.9e6, 3.5e6, 2e5, -2e5, 3.1e6];
    let cb = [2.1e3, 1e2, 1e2, 2.3e3, 2.2e3, 0.0, 0.0, 2.0e3];
    for &(n, nrhs, per_point) in &[(4099usize, 1usize, false), (33, 3, true), (2500, 2, false), (17, 1, true)] {
        let w: Vec<f64> = (0..n).map(|i| 50.0 + 1250.0 * i as f64 / n as f64).collect();
        let (kp, cp): (Vec<f64>, Vec<f64>) = if per_point {
            let mut kp: Vec<f64> = (0..8 * n).map(|j| kb[j % 8] * (1.0 + 0.3 * val(j, 5))).collect();
            kp[8 * (n / 2) + 3] = f64::NAN;
            (kp, (0..8 * n).map(|j| cb[j % 8] * (1.0 + 0.3 * val(j, 6))).collect())
        } else {
            (kb.to_vec(), cb.to_vec())
        };
        let f: Vec<C64> = (0..4 * nrhs).map(|i| c(val(i, 7), val(i, 8))).collect();
        let gains: Vec<f64> = (0..n).map(|i| 1.0 + val(i, 9)).collect();
        for (gain, planes) in [(Gain::One, None), (Gain::SpinSquared, None), (Gain::PerPoint(&gains), Some([1.2, -0.2, -0.3, 1.3]))] {
            let mut q = vec![c(0.0, 0.0); n * 4 * nrhs];
            let nbad = forced_response_with(&rotor, &kp, &cp, &w, &w, &f, nrhs, gain, planes.as_ref(), &mut q).expect("valid problem");
            d.add_c(&q);
            d.add(&[nbad as f64]);
        }
    }
}

fn modes(d: &mut Digest, rotor: Rotor) {
    let n = 300;
    let spin: Vec<f64> = (0..n).map(|i| 10.0 * i as f64).collect();
    let kb: Vec<f64> = (0..8 * n).map(|j| [3.2e6, 4e5, -3e5, 2.9e6, 3.5e6, 2e5, -2e5, 3.1e6][j % 8] * (1.0 + 0.2 * val(j, 10))).collect();
    let cb: Vec<f64> = (0..8 * n).map(|j| [2.1e3, 1e2, 1e2, 2.3e3, 2.2e3, 0.0, 0.0, 2.0e3][j % 8] * (1.0 + 0.2 * val(j, 11))).collect();
    let (mut lam, mut shapes) = (vec![c(0.0, 0.0); 4 * n], vec![c(0.0, 0.0); 16 * n]);
    let nbad = modal(&rotor, &kb, &cb, &spin, &mut lam, &mut shapes).expect("valid problem");
    d.add_c(&lam);
    d.add_c(&shapes);
    d.add(&[nbad as f64]);
}

fn main() {
    let rotor = Rotor::from_slice(&[30.7, 0.62, 0.062, 0.146, 0.137]).expect("valid rotor");
    let (mut id, mut fw, mut md) = (Digest::new(), Digest::new(), Digest::new());
    identification(&mut id, rotor);
    forward(&mut fw, rotor);
    modes(&mut md, rotor);
    let arch = std::env::consts::ARCH;
    let level = rotorid_core::lanes::simd().name();
    println!("{arch} {level}: identification {:016x}  forward {:016x}  modal {:016x}", id.0, fw.0, md.0);
    for (name, dg) in [("identification", &id), ("forward", &fw), ("modal", &md)] {
        println!("  {name}: {} values, {} finite", dg.1, dg.2);
    }
}
