//! Hand-written small dense algebra against nalgebra's fixed-size types and faer, single thread:
//!
//!     cargo bench -p rotorid-core --bench small_algebra
//!
//! - 4x4 complex solve with one right-hand side (the forced response per point): `solve4` vs
//!   nalgebra `Matrix4<Complex64>::lu().solve()`;
//! - eigenvalues of the 8x8 real state matrix (modal analysis per point): nalgebra's fixed-size
//!   real Schur vs faer's dynamic-size eigen-decomposition vs the hand-written Hessenberg
//!   reduction + Francis double-shift QR without transformations (`eig8`).
//! Prints ns per system and the largest difference between the answers.

use nalgebra::{Matrix4, Schur, Vector4};
use rotorid_core::eig8;
use rotorid_core::forced::{dynamic_stiffness, solve4};
use rotorid_core::modal::{balance, state_matrix};
use rotorid_core::model::assemble;
use rotorid_core::{Rotor, C64};
use std::hint::black_box;
use std::time::Instant;

fn best_ns<F: FnMut() -> f64>(n: usize, mut f: F) -> (f64, f64) {
    let mut best = f64::INFINITY;
    let mut sink = 0.0;
    for _ in 0..7 {
        let t0 = Instant::now();
        sink += f();
        best = best.min(t0.elapsed().as_secs_f64());
    }
    (best / n as f64 * 1e9, sink)
}

fn main() {
    let rotor = Rotor::from_slice(&[30.7, 0.62, 0.062, 0.146, 0.137]).unwrap();
    let (m, g) = (rotor.mass_matrix(), rotor.gyro_matrix());
    let n = 100_000;
    let kb = [3.2e6, 4e5, -3e5, 2.9e6, 3.5e6, 2e5, -2e5, 3.1e6];
    let cb = [2.1e3, 1e2, 1e2, 2.3e3, 2.2e3, 0.0, 0.0, 2.0e3];
    let w: Vec<f64> = (0..n).map(|i| 50.0 + 1250.0 * i as f64 / n as f64).collect();
    let f = [C64::new(1.0, 0.0), C64::new(0.5, 0.2), C64::new(0.0, -1.0), C64::new(-0.2, 0.1)];

    // --- 4x4 complex solve
    let (t_hand, s1) = best_ns(n, || {
        let mut acc = 0.0;
        for &wi in &w {
            let mut h = dynamic_stiffness(&rotor, &m, &g, &kb, &cb, wi, wi);
            let mut q = f;
            solve4(&mut h, &mut q);
            acc += q[0].re;
        }
        black_box(acc)
    });
    let (t_na, s2) = best_ns(n, || {
        let mut acc = 0.0;
        for &wi in &w {
            let h = dynamic_stiffness(&rotor, &m, &g, &kb, &cb, wi, wi);
            let hm = Matrix4::from_fn(|r, c| h[r][c]);
            let q = hm.lu().solve(&Vector4::from_column_slice(&f)).unwrap_or(Vector4::zeros());
            acc += q[0].re;
        }
        black_box(acc)
    });
    println!("4x4 complex solve (forced response), {n} systems, 1 thread:");
    println!("  hand-written solve4 (partial pivoting) {t_hand:8.1} ns/system");
    println!("  nalgebra Matrix4<Complex64>::lu       {t_na:8.1} ns/system   ({:.2}x the hand-written time)", t_na / t_hand);
    println!("  same answers: sum difference {:.2e} (relative)", (s1 - s2).abs() / s1.abs());

    // --- 8x8 eigenvalues
    let ne = 10_000;
    let minv = Matrix4::from_fn(|r, c| m[r][c]).try_inverse().unwrap();
    let (k, c) = (assemble(&kb, rotor.l1, rotor.l2), assemble(&cb, rotor.l1, rotor.l2));
    let mats: Vec<_> = (0..ne)
        .map(|i| {
            let mut a = state_matrix(&minv, &k, &c, &g, 1300.0 * i as f64 / ne as f64);
            balance(&mut a);
            a
        })
        .collect();
    let (t_schur, e1) = best_ns(ne, || {
        let mut acc = 0.0;
        for a in &mats {
            let ev = Schur::try_new(*a, f64::EPSILON, 10_000).unwrap().complex_eigenvalues();
            acc += ev.iter().map(|z| z.im.abs()).sum::<f64>();
        }
        black_box(acc)
    });
    let (t_faer, e2) = best_ns(ne, || {
        let mut acc = 0.0;
        for a in &mats {
            let fm = faer::Mat::<f64>::from_fn(8, 8, |r, c| a[(r, c)]);
            let ev = fm.eigenvalues().unwrap();
            acc += ev.iter().map(|z| z.im.abs()).sum::<f64>();
        }
        black_box(acc)
    });
    let (t_eig8, e3) = best_ns(ne, || {
        let mut acc = 0.0;
        for a in &mats {
            let rows: [[f64; 8]; 8] = std::array::from_fn(|r| std::array::from_fn(|c| a[(r, c)]));
            let ev = eig8::eigenvalues(&rows).unwrap();
            acc += ev.iter().map(|z| z.im.abs()).sum::<f64>();
        }
        black_box(acc)
    });
    println!("8x8 real eigenvalues (modal analysis), {ne} matrices, 1 thread:");
    println!("  nalgebra SMatrix<f64, 8, 8> Schur      {t_schur:8.0} ns/matrix");
    println!("  faer Mat<f64> eigenvalues             {t_faer:8.0} ns/matrix   ({:.2}x the nalgebra time)", t_faer / t_schur);
    println!("  hand-written Hessenberg + Francis QR  {t_eig8:8.0} ns/matrix   ({:.2}x the nalgebra time)", t_eig8 / t_schur);
    println!(
        "  same answers: sum |Im| difference {:.2e} (faer), {:.2e} (hand-written) (relative)",
        (e1 - e2).abs() / e1.abs(),
        (e1 - e3).abs() / e1.abs()
    );
}
