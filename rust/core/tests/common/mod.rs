//! Reference implementations for the kernel tests: written for clarity, not speed, and derived
//! independently of the kernels (equations of motion term by term, Gaussian elimination with
//! full pivoting).
#![allow(dead_code)]

use proptest::prelude::*;
use rotorid_core::{forced, Rotor, C64};

pub fn c(re: f64, im: f64) -> C64 {
    C64::new(re, im)
}

/// The NSF rig of the report (Table 1 and 2 order of magnitude): m, I_T, I_p, l1, l2.
pub fn nsf_rotor() -> Rotor {
    Rotor::from_slice(&[30.7, 0.62, 0.062, 0.146, 0.137]).unwrap()
}

/// Bearing force of bearing b on the rotor for displacement (x_b, y_b): the 2x2 impedance
/// Z = K + j w C times the displacement, [Fx, Fy].
fn bearing_force(k: &[f64], cc: &[f64], b: usize, w: f64, x: C64, y: C64) -> [C64; 2] {
    let z = |i: usize, j: usize| c(k[4 * b + 2 * i + j], w * cc[4 * b + 2 * i + j]);
    [z(0, 0) * x + z(0, 1) * y, z(1, 0) * x + z(1, 1) * y]
}

/// Residual of the four equations of motion (report eq. 1-3) at s = j w for a response q =
/// [x1, x2, y1, y2] and generalized force f, written from their mechanical meaning: force balance
/// in x and y with the CG acceleration, moment balance about the CG with the tilt accelerations and
/// the gyroscopic moments. With the tilts beta = (x2 - x1) / L about y and alpha = -(y2 - y1) / L
/// about x, the moment equations are I_T beta'' - I_p Omega alpha' = M_y and
/// I_T alpha'' + I_p Omega beta' = M_x (rotor spinning at Omega about z); rows 3 and 4 of eq. 3
/// are these with alpha written through the y displacements.
pub fn motion_residual(r: &Rotor, k: &[f64], cc: &[f64], spin: f64, w: f64, q: &[C64], f: &[C64]) -> [C64; 4] {
    let (x1, x2, y1, y2) = (q[0], q[1], q[2], q[3]);
    let span = r.l1 + r.l2;
    let s = c(0.0, w);
    let s2 = s * s;
    let xg = (x1 * r.l2 + x2 * r.l1) / span; // CG displacement
    let yg = (y1 * r.l2 + y2 * r.l1) / span;
    let tx = (x2 - x1) / span; // slope of the x plane
    let ty = (y2 - y1) / span;
    let f1 = bearing_force(k, cc, 0, w, x1, y1);
    let f2 = bearing_force(k, cc, 1, w, x2, y2);
    [
        s2 * r.m * xg + f1[0] + f2[0] - f[0],
        s2 * r.m * yg + f1[1] + f2[1] - f[1],
        s2 * r.it * tx + s * spin * r.ip * ty - r.l1 * f1[0] + r.l2 * f2[0] - f[2],
        -(s2 * r.it * ty) + s * spin * r.ip * tx + r.l1 * f1[1] - r.l2 * f2[1] - f[3],
    ]
}

/// Size of the dynamic stiffness terms at one point, for relative residuals.
pub fn motion_scale(r: &Rotor, k: &[f64], cc: &[f64], spin: f64, w: f64, q: &[C64]) -> f64 {
    let kmax = k.iter().chain(cc.iter().map(|v| v)).fold(0.0f64, |a, &b| a.max(b.abs()));
    let cmax = cc.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
    let qmax = q.iter().fold(0.0f64, |a, z| a.max(z.norm()));
    (kmax + w * cmax + w * w * (r.m + r.it) + w * spin.abs() * r.ip) * qmax
}

/// Dense complex solve by Gaussian elimination with full pivoting (reference for `solve4`).
pub fn solve_full_pivot(a: &[[C64; 4]; 4], b: &[C64; 4]) -> Option<[C64; 4]> {
    let mut m = *a;
    let mut rhs = *b;
    let mut col_of = [0usize, 1, 2, 3];
    for k in 0..4 {
        let (mut pi, mut pj, mut best) = (k, k, 0.0);
        for i in k..4 {
            for j in k..4 {
                if m[i][j].norm() > best {
                    best = m[i][j].norm();
                    pi = i;
                    pj = j;
                }
            }
        }
        if best == 0.0 {
            return None;
        }
        m.swap(k, pi);
        rhs.swap(k, pi);
        for row in m.iter_mut() {
            row.swap(k, pj);
        }
        col_of.swap(k, pj);
        for i in k + 1..4 {
            let f = m[i][k] / m[k][k];
            for j in k..4 {
                let t = m[k][j];
                m[i][j] -= f * t;
            }
            let t = rhs[k];
            rhs[i] -= f * t;
        }
    }
    let mut y = [c(0.0, 0.0); 4];
    for k in (0..4).rev() {
        let mut s = rhs[k];
        for j in k + 1..4 {
            s -= m[k][j] * y[j];
        }
        y[k] = s / m[k][k];
    }
    let mut x = [c(0.0, 0.0); 4];
    for k in 0..4 {
        x[col_of[k]] = y[k];
    }
    Some(x)
}

/// Responses of `runs` imbalance runs at the speeds `w` (synchronous, spin = w), laid out
/// (runs, n, 4) as the identification expects. `e`: (runs, 4) generalized imbalance vectors.
pub fn imbalance_responses(r: &Rotor, k: &[f64], cc: &[f64], w: &[f64], e: &[C64]) -> Vec<C64> {
    let n = w.len();
    let runs = e.len() / 4;
    let mut q = vec![c(0.0, 0.0); runs * n * 4];
    for run in 0..runs {
        let force: Vec<C64> = w.iter().flat_map(|&wi| e[4 * run..4 * run + 4].iter().map(move |&v| v * wi * wi)).collect();
        let mut out = vec![c(0.0, 0.0); n * 4];
        let bad = forced::forced_response(r, k, cc, w, w, &force, 1, &mut out).unwrap();
        assert_eq!(bad, 0);
        q[run * n * 4..(run + 1) * n * 4].copy_from_slice(&out);
    }
    q
}

prop_compose! {
    /// Physical bearings: direct stiffness 1e5-1e8 N/m, direct damping 1e2-1e5 N s/m, cross
    /// terms up to half the direct ones, both bearings independent.
    pub fn bearings()(kd in proptest::collection::vec(5.0f64..8.0, 4),
                      cd in proptest::collection::vec(2.0f64..5.0, 4),
                      kx in proptest::collection::vec(-0.5f64..0.5, 4),
                      cx in proptest::collection::vec(-0.5f64..0.5, 4)) -> ([f64; 8], [f64; 8]) {
        let mut k = [0.0; 8];
        let mut cc = [0.0; 8];
        for b in 0..2 {
            let (kx_, ky_) = (10f64.powf(kd[2 * b]), 10f64.powf(kd[2 * b + 1]));
            let (cx_, cy_) = (10f64.powf(cd[2 * b]), 10f64.powf(cd[2 * b + 1]));
            k[4 * b] = kx_;
            k[4 * b + 3] = ky_;
            k[4 * b + 1] = kx[2 * b] * kx_.min(ky_);
            k[4 * b + 2] = kx[2 * b + 1] * kx_.min(ky_);
            cc[4 * b] = cx_;
            cc[4 * b + 3] = cy_;
            cc[4 * b + 1] = cx[2 * b] * cx_.min(cy_);
            cc[4 * b + 2] = cx[2 * b + 1] * cx_.min(cy_);
        }
        (k, cc)
    }
}

prop_compose! {
    /// Rigid rotors from 1 kg to 1 t with an asymmetric bearing span.
    pub fn rotors()(m in 1.0f64..1000.0, rg in 0.1f64..0.6, ipr in 0.05f64..1.5,
                    l1 in 0.05f64..1.0, l2 in 0.05f64..1.0) -> Rotor {
        let span = l1 + l2;
        let it = m * (rg * span).powi(2);
        Rotor::from_slice(&[m, it, ipr * it, l1, l2]).unwrap()
    }
}
