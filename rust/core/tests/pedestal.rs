//! Rigid rotor on bearings in flexible pedestals (8 DOF): the pedestal kernels against an 8 x 8
//! reference written here from the equations of motion term by term.
//!
//! Physics of the reference: q = [x1, x2, y1, y2] is the absolute rotor motion at the bearings,
//! p = [xp1, xp2, yp1, yp2] the pedestal motion; the rotor's inertia and gyroscopic moments act on
//! q, the bearing force f_b = (K_b + s C_b)(q_b - p_b) acts on the rotor (restoring) and, reversed,
//! on the pedestal: (K_p + s C_p + s^2 M_p) p_b = f_b.

mod common;

use common::*;
use proptest::prelude::*;
use rotorid_core::identify::{bearing_forces, identify_forces, identify_report, IdentOut, IdentProblem};
use rotorid_core::forced::Gain;
use rotorid_core::pedestal::{self, Pedestals, RotorMotion};
use rotorid_core::{forced, modal, CoreError, Rotor, C64};

type C2 = [[C64; 2]; 2];

// ---------------------------------------------------------------------------------------------
// Test rig: the NSF rotor, anisotropic cross-coupled bearings, two different pedestals.

/// Bearing stiffness [bearing][i][j], N/m.
const KB: [f64; 8] = [3.0e6, 5.0e4, 3.0e4, 3.5e6, 2.5e6, -4.0e4, 6.0e4, 3.2e6];
/// Bearing damping [bearing][i][j], N s/m.
const CB: [f64; 8] = [2000.0, 250.0, 800.0, 2200.0, 1800.0, -150.0, 300.0, 2500.0];

/// Pedestal parameters `[m (4), k (8), c (8)]`: stiffness of the order of the bearings', so the
/// pedestal moves by ~10 % of the journal.
fn ped_values() -> [f64; 20] {
    [
        12.0, 15.0, 14.0, 11.0, // m [ped][x, y]
        2.0e7, 1.0e6, -5.0e5, 1.5e7, 1.8e7, -2.0e6, 1.0e6, 2.5e7, // k [ped][i][j]
        3.0e3, 200.0, -100.0, 2.5e3, 4.0e3, 100.0, 300.0, 3.0e3, // c [ped][i][j]
    ]
}

/// Nearly rigid pedestals: 1e14 N/m direct stiffness (the rotor's bearings are ~3e6).
fn stiff_ped_values() -> [f64; 20] {
    let mut v = [0.0; 20];
    v[..4].copy_from_slice(&[10.0, 10.0, 10.0, 10.0]);
    v[4..12].copy_from_slice(&[1e14, 0.0, 0.0, 1e14, 1e14, 0.0, 0.0, 1e14]);
    v[12..20].copy_from_slice(&[1e3, 0.0, 0.0, 1e3, 1e3, 0.0, 0.0, 1e3]);
    v
}

/// Speeds across the rotor modes (~300-500 rad/s) and the pedestal modes (~1100-1500 rad/s).
const SPEEDS: [f64; 7] = [60.0, 210.0, 380.0, 520.0, 900.0, 1250.0, 1900.0];

fn zero() -> C64 {
    c(0.0, 0.0)
}

fn vmax(v: &[C64]) -> f64 {
    v.iter().fold(0.0f64, |a, z| a.max(z.norm()))
}

// ---------------------------------------------------------------------------------------------
// Reference: equations of motion of the coupled system, dense complex solve.

/// Impedance K + s C of bearing (or pedestal) b from 8 coefficients [b][i][j].
fn imp(k: &[f64], cc: &[f64], b: usize, s: C64) -> C2 {
    let z = |i: usize, j: usize| c(k[4 * b + 2 * i + j], 0.0) + s * cc[4 * b + 2 * i + j];
    [[z(0, 0), z(0, 1)], [z(1, 0), z(1, 1)]]
}

fn mv2(a: &C2, x: C64, y: C64) -> [C64; 2] {
    [a[0][0] * x + a[0][1] * y, a[1][0] * x + a[1][1] * y]
}

/// Residual of the 8 equations of motion at the Laplace variable s for x = [q (4), p (4)] and the
/// generalized rotor force f: rows 0-3 the rotor's (force balance in x and y with the CG
/// acceleration, moment balance about the CG with tilts and gyroscopic moments, as
/// `common::motion_residual`, with inertia on the absolute motion and bearing forces on the
/// relative motion), rows 4-7 the pedestals' in the order [xp1, xp2, yp1, yp2].
#[allow(clippy::too_many_arguments)]
fn coupled_residual(r: &Rotor, kb: &[f64], cb: &[f64], pv: &[f64; 20], spin: f64, s: C64, x: &[C64; 8], f: &[C64; 4]) -> [C64; 8] {
    let (x1, x2, y1, y2) = (x[0], x[1], x[2], x[3]);
    let (xp1, xp2, yp1, yp2) = (x[4], x[5], x[6], x[7]);
    let span = r.l1 + r.l2;
    let s2 = s * s;
    let xg = (x1 * r.l2 + x2 * r.l1) / span;
    let yg = (y1 * r.l2 + y2 * r.l1) / span;
    let tx = (x2 - x1) / span;
    let ty = (y2 - y1) / span;
    // bearing forces on the journal's motion relative to its housing
    let f1 = mv2(&imp(kb, cb, 0, s), x1 - xp1, y1 - yp1);
    let f2 = mv2(&imp(kb, cb, 1, s), x2 - xp2, y2 - yp2);
    // pedestal dynamic stiffness K_p + s C_p + s^2 M_p
    let (pm, pk, pc) = (&pv[..4], &pv[4..12], &pv[12..20]);
    let dp = |b: usize| -> C2 {
        let mut d = imp(pk, pc, b, s);
        d[0][0] += s2 * pm[2 * b];
        d[1][1] += s2 * pm[2 * b + 1];
        d
    };
    let g1 = mv2(&dp(0), xp1, yp1);
    let g2 = mv2(&dp(1), xp2, yp2);
    [
        s2 * r.m * xg + f1[0] + f2[0] - f[0],
        s2 * r.m * yg + f1[1] + f2[1] - f[1],
        s2 * r.it * tx + s * spin * r.ip * ty - r.l1 * f1[0] + r.l2 * f2[0] - f[2],
        -(s2 * r.it * ty) + s * spin * r.ip * tx + r.l1 * f1[1] - r.l2 * f2[1] - f[3],
        g1[0] - f1[0], // xp1
        g2[0] - f2[0], // xp2
        g1[1] - f1[1], // yp1
        g2[1] - f2[1], // yp2
    ]
}

/// H(s) of the coupled system, column j = residual of the unit vector e_j without force.
fn coupled_h(r: &Rotor, kb: &[f64], cb: &[f64], pv: &[f64; 20], spin: f64, s: C64) -> [[C64; 8]; 8] {
    let mut h = [[zero(); 8]; 8];
    for j in 0..8 {
        let mut e = [zero(); 8];
        e[j] = c(1.0, 0.0);
        let col = coupled_residual(r, kb, cb, pv, spin, s, &e, &[zero(); 4]);
        for i in 0..8 {
            h[i][j] = col[i];
        }
    }
    h
}

/// Gaussian elimination with partial pivoting (row exchanges by largest modulus).
fn gauss<const N: usize>(a: &[[C64; N]; N], b: &[C64; N]) -> Option<[C64; N]> {
    let mut m = *a;
    let mut x = *b;
    for k in 0..N {
        let p = (k..N).fold(k, |p, i| if m[i][k].norm() > m[p][k].norm() { i } else { p });
        if m[p][k].norm() == 0.0 {
            return None;
        }
        m.swap(p, k);
        x.swap(p, k);
        for i in k + 1..N {
            let f = m[i][k] / m[k][k];
            for j in k..N {
                let t = m[k][j];
                m[i][j] -= f * t;
            }
            let t = x[k];
            x[i] -= f * t;
        }
    }
    for k in (0..N).rev() {
        let mut s = x[k];
        for j in k + 1..N {
            s -= m[k][j] * x[j];
        }
        x[k] = s / m[k][k];
    }
    Some(x)
}

fn fro<const N: usize>(a: &[[C64; N]; N]) -> f64 {
    a.iter().flatten().map(|z| z.norm_sqr()).sum::<f64>().sqrt()
}

/// Direct 8 x 8 solve of the forced response at one point: (q_abs, p).
fn direct(r: &Rotor, pv: &[f64; 20], spin: f64, w: f64, f: &[C64]) -> ([C64; 4], [C64; 4]) {
    let h = coupled_h(r, &KB, &CB, pv, spin, c(0.0, w));
    let b = [f[0], f[1], f[2], f[3], zero(), zero(), zero(), zero()];
    let x = gauss(&h, &b).expect("coupled system singular");
    ([x[0], x[1], x[2], x[3]], [x[4], x[5], x[6], x[7]])
}

fn assert_close(got: &[C64], want: &[C64], rel: f64, what: &str) {
    let scale = vmax(want);
    assert!(scale > 0.0 && scale.is_finite(), "{what}: reference scale {scale}");
    for (i, (a, b)) in got.iter().zip(want).enumerate() {
        assert!((a - b).norm() <= rel * scale, "{what}[{i}]: {a} vs {b} (|diff| {:e}, scale {scale:e})", (a - b).norm());
    }
}

// ---------------------------------------------------------------------------------------------
// 1. Pedestals::from_slice

#[test]
fn from_slice_checks_length_finiteness_and_masses() {
    let good = ped_values();
    let p = Pedestals::from_slice(&good).unwrap();
    assert_eq!(p.m[..], good[..4]);
    assert_eq!(p.k[..], good[4..12]);
    assert_eq!(p.c[..], good[12..20]);
    // a massless pedestal is allowed by from_slice (the forced response has no use for its mass)
    let mut massless = good;
    massless[..4].copy_from_slice(&[0.0; 4]);
    assert!(Pedestals::from_slice(&massless).is_ok());

    for len in [0usize, 1, 4, 19, 21, 40] {
        let v = vec![1.0; len];
        match Pedestals::from_slice(&v) {
            Err(CoreError::Length { name, got, .. }) => {
                assert_eq!(name, "pedestals");
                assert_eq!(got, len);
            }
            other => panic!("length {len}: expected a length error, got {other:?}"),
        }
    }
    for i in 0..20 {
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut v = good;
            v[i] = bad;
            match Pedestals::from_slice(&v) {
                Err(CoreError::Value { name, .. }) => assert_eq!(name, "pedestals"),
                other => panic!("value {bad} at {i}: expected a value error, got {other:?}"),
            }
        }
    }
    for i in 0..4 {
        for m in [-1e-300, -1.0, -12.0] {
            let mut v = good;
            v[i] = m;
            match Pedestals::from_slice(&v) {
                Err(CoreError::Value { name, .. }) => assert_eq!(name, "pedestals"),
                other => panic!("mass {m} at {i}: expected a value error, got {other:?}"),
            }
        }
    }
}

#[test]
fn dynamic_stiffness_layout() {
    let pv = ped_values();
    let p = Pedestals::from_slice(&pv).unwrap();
    for w in [0.0, 77.0, 1234.5] {
        for b in 0..2 {
            let d = p.dynamic_stiffness(b, w);
            for i in 0..2 {
                for j in 0..2 {
                    let o = 4 * b + 2 * i + j;
                    let mass = if i == j { pv[2 * b + i] } else { 0.0 };
                    let want = c(pv[4 + o] - w * w * mass, w * pv[12 + o]);
                    assert!((d[i][j] - want).norm() <= 1e-15 * want.norm(), "b {b} [{i}][{j}] at w {w}: {} vs {want}", d[i][j]);
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// 2. series: springs in series

fn inv2(a: &C2) -> C2 {
    let det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
    [[a[1][1] / det, -a[0][1] / det], [-a[1][0] / det, a[0][0] / det]]
}

fn add2(a: &C2, b: &C2) -> C2 {
    [[a[0][0] + b[0][0], a[0][1] + b[0][1]], [a[1][0] + b[1][0], a[1][1] + b[1][1]]]
}

fn mul2(a: &C2, b: &C2) -> C2 {
    let mut o = [[zero(); 2]; 2];
    for i in 0..2 {
        for j in 0..2 {
            o[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j];
        }
    }
    o
}

fn norm2f(a: &C2) -> f64 {
    a.iter().flatten().map(|z| z.norm_sqr()).sum::<f64>().sqrt()
}

/// Frobenius condition number ||A|| ||A^-1||.
fn cond2(a: &C2) -> f64 {
    norm2f(a) * norm2f(&inv2(a))
}

fn c2_from(v: &[f64]) -> C2 {
    [[c(v[0], v[1]), c(v[2], v[3])], [c(v[4], v[5]), c(v[6], v[7])]]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, failure_persistence: None, ..ProptestConfig::default() })]

    /// T = (Z + D)^-1 Z and Z_eff = D T: (Z + D) T = Z, Z_eff = Z (I - T) (the same spring seen
    /// from the other side), and Z_eff^-1 = Z^-1 + D^-1.
    #[test]
    fn series_is_springs_in_series(zv in proptest::collection::vec(-1.0f64..1.0, 8),
                                   dv in proptest::collection::vec(-1.0f64..1.0, 8),
                                   zs in -3.0f64..3.0, ds in -3.0f64..3.0) {
        let z0 = c2_from(&zv);
        let d0 = c2_from(&dv);
        // scales over six decades each: the identities are scale-free
        let (fz, fd) = (10f64.powf(zs + 6.0), 10f64.powf(ds + 6.0));
        let z = [[z0[0][0] * fz, z0[0][1] * fz], [z0[1][0] * fz, z0[1][1] * fz]];
        let d = [[d0[0][0] * fd, d0[0][1] * fd], [d0[1][0] * fd, d0[1][1] * fd]];
        let (cz, cd, cs) = (cond2(&z), cond2(&d), cond2(&add2(&z, &d)));
        prop_assume!(cz < 1e4 && cd < 1e4 && cs < 1e4);
        let (t, ze) = pedestal::series(&z, &d).expect("well-conditioned Z + D reported singular");
        // rounding bounds: each product is checked against the size of its factors (Z (I - T)
        // cancels when D << Z, D T when Z << D)
        let tol = 1e-13 * cz * cd * cs;
        let nt = norm2f(&t);
        // (Z + D) T = Z
        let lhs = mul2(&add2(&z, &d), &t);
        for i in 0..2 { for j in 0..2 {
            prop_assert!((lhs[i][j] - z[i][j]).norm() <= tol * (norm2f(&add2(&z, &d)) * nt + norm2f(&z)), "(Z+D)T != Z");
        }}
        // Z_eff = D T = Z (I - T)
        let dt = mul2(&d, &t);
        let i_t = [[c(1.0, 0.0) - t[0][0], -t[0][1]], [-t[1][0], c(1.0, 0.0) - t[1][1]]];
        let zi = mul2(&z, &i_t);
        for i in 0..2 { for j in 0..2 {
            prop_assert!((ze[i][j] - dt[i][j]).norm() <= tol * norm2f(&d) * nt, "Z_eff != D T");
            prop_assert!((ze[i][j] - zi[i][j]).norm() <= tol * norm2f(&z) * (2.0 + nt), "Z_eff != Z (I - T)");
        }}
        // Z_eff^-1 = Z^-1 + D^-1, checked as Z_eff (Z^-1 + D^-1) = I
        let (zinv, dinv) = (inv2(&z), inv2(&d));
        let want = add2(&zinv, &dinv);
        let prod = mul2(&ze, &want);
        let bound = tol * (norm2f(&d) * nt * norm2f(&want) + norm2f(&ze) * (norm2f(&zinv) + norm2f(&dinv)));
        for i in 0..2 { for j in 0..2 {
            let id = if i == j { c(1.0, 0.0) } else { zero() };
            prop_assert!((prod[i][j] - id).norm() <= bound,
                "Z_eff (Z^-1 + D^-1) = {:?}, not I (bound {:e})", prod, bound);
        }}
        // and where Z_eff is well conditioned, its inverse directly
        if cond2(&ze) < 1e4 {
            let got = inv2(&ze);
            for i in 0..2 { for j in 0..2 {
                prop_assert!((got[i][j] - want[i][j]).norm() <= tol * cond2(&ze) * norm2f(&want),
                    "Z_eff^-1 {:?} vs Z^-1 + D^-1 {:?}", got, want);
            }}
        }
    }
}

#[test]
fn series_limits_and_singular_sum() {
    let z = [[c(3e6, 2e5), c(5e4, 1e4)], [c(3e4, 8e4), c(3.5e6, 2.2e5)]];
    let d = [[c(2e7, 3e5), c(1e6, 2e4)], [c(-5e5, -1e4), c(1.5e7, 2.5e5)]];
    let o = [[zero(); 2]; 2];
    let id = [[c(1.0, 0.0), zero()], [zero(), c(1.0, 0.0)]];
    // a bearing without stiffness or damping transmits nothing
    let (t, ze) = pedestal::series(&o, &d).unwrap();
    assert_eq!((t, ze), (o, o));
    // a pedestal with zero dynamic stiffness (at its undamped resonance): it follows the journal
    let (t, ze) = pedestal::series(&z, &o).unwrap();
    for i in 0..2 {
        for j in 0..2 {
            assert!((t[i][j] - id[i][j]).norm() < 1e-15, "T = {t:?}");
            assert_eq!(ze[i][j], zero());
        }
    }
    // Z + D = 0: singular
    let mz = [[-z[0][0], -z[0][1]], [-z[1][0], -z[1][1]]];
    assert!(pedestal::series(&z, &mz).is_none());
    // non-finite input: None rather than NaN
    let mut zn = z;
    zn[0][1] = c(f64::NAN, 0.0);
    assert!(pedestal::series(&zn, &d).is_none());
    // scalar limit: two springs in series
    let zd = [[c(3e6, 0.0), zero()], [zero(), c(1e6, 0.0)]];
    let dd = [[c(1e6, 0.0), zero()], [zero(), c(1e6, 0.0)]];
    let (t, ze) = pedestal::series(&zd, &dd).unwrap();
    assert!((ze[0][0] - c(0.75e6, 0.0)).norm() < 1e-9 && (ze[1][1] - c(0.5e6, 0.0)).norm() < 1e-9, "{ze:?}");
    assert!((t[0][0] - c(0.75, 0.0)).norm() < 1e-15 && (t[1][1] - c(0.5, 0.0)).norm() < 1e-15, "{t:?}");
}

#[test]
fn effective_coefficients_are_the_series_impedance() {
    let pv = ped_values();
    let ped = Pedestals::from_slice(&pv).unwrap();
    let n = SPEEDS.len();
    let (mut ke, mut ce, mut tr) = (vec![0.0; 8 * n], vec![0.0; 8 * n], vec![zero(); 8 * n]);
    let bad = pedestal::effective_coefficients(&KB, &CB, &ped, &SPEEDS, &mut ke, &mut ce, &mut tr).unwrap();
    assert_eq!(bad, 0);
    for (i, &w) in SPEEDS.iter().enumerate() {
        let s = c(0.0, w);
        for b in 0..2 {
            let z = imp(&KB, &CB, b, s);
            let mut d = imp(&pv[4..12], &pv[12..20], b, s);
            d[0][0] += s * s * pv[2 * b];
            d[1][1] += s * s * pv[2 * b + 1];
            let zeff = inv2(&add2(&inv2(&z), &inv2(&d)));
            let t = mul2(&inv2(&add2(&z, &d)), &z);
            let scale = norm2f(&zeff);
            for r in 0..2 {
                for q in 0..2 {
                    let o = 8 * i + 4 * b + 2 * r + q;
                    let got = c(ke[o], w * ce[o]);
                    assert!((got - zeff[r][q]).norm() <= 1e-10 * scale, "w {w} b {b} [{r}][{q}]: {got} vs {}", zeff[r][q]);
                    assert!((tr[o] - t[r][q]).norm() <= 1e-10 * norm2f(&t), "T w {w} b {b}");
                }
            }
        }
    }
    // a point where Z + D is singular (negative pedestal damping cancelling the bearing's, at the
    // undamped frequency of bearing + pedestal) is counted and NaN
    let kd = [1e6, 0.0, 0.0, 1e6, 1e6, 0.0, 0.0, 1e6];
    let cd = [1e3, 0.0, 0.0, 1e3, 1e3, 0.0, 0.0, 1e3];
    let mut pz = [0.0; 20];
    pz[..4].copy_from_slice(&[10.0; 4]);
    pz[4..12].copy_from_slice(&[9e6, 0.0, 0.0, 9e6, 9e6, 0.0, 0.0, 9e6]);
    pz[12..20].copy_from_slice(&[-1e3, 0.0, 0.0, -1e3, -1e3, 0.0, 0.0, -1e3]);
    let ped0 = Pedestals::from_slice(&pz).unwrap();
    let w = [1000.0, 500.0]; // (1e6 + 9e6) / 10 = 1000^2
    let (mut ke, mut ce, mut tr) = (vec![0.0; 16], vec![0.0; 16], vec![zero(); 16]);
    let bad = pedestal::effective_coefficients(&kd, &cd, &ped0, &w, &mut ke, &mut ce, &mut tr).unwrap();
    assert_eq!(bad, 1);
    assert!(ke[..8].iter().all(|v| v.is_nan()) && ke[8..].iter().all(|v| v.is_finite()));
    assert!(pedestal::effective_coefficients(&kd, &cd, &ped0, &[0.0], &mut ke[..8], &mut ce[..8], &mut tr[..8]).is_err());
}

/// Outcome of a call that may panic: Ok(value), Err(message) for an error or a panic.
fn guarded<T>(f: impl FnOnce() -> Result<T, CoreError>) -> Result<T, String> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(format!("rejected: {e}")),
        Err(_) => Err("panicked".into()),
    }
}

#[test]
fn k_and_c_broadcast_independently() {
    // k and c are each checked as (n, 8) or (1, 8) on their own, so every combination is a valid
    // call and must give the answer of one row per point (as forced::forced_response does)
    let r = nsf_rotor();
    let ped = Pedestals::from_slice(&ped_values()).unwrap();
    let w = [150.0, 700.0, 1300.0];
    let n = w.len();
    let (mut kb2, mut cb2) = (KB, CB);
    kb2[0] *= 1.5;
    cb2[3] *= 0.5;
    let rows = |a: [f64; 8], b: [f64; 8]| -> Vec<f64> { (0..n).flat_map(|i| if i == 0 { a } else { b }).collect() };
    let eff = |k: &[f64], cc: &[f64]| {
        guarded(|| {
            let (mut ke, mut ce, mut tr) = (vec![0.0; 8 * n], vec![0.0; 8 * n], vec![zero(); 8 * n]);
            pedestal::effective_coefficients(k, cc, &ped, &w, &mut ke, &mut ce, &mut tr).map(|_| (ke, ce, tr))
        })
    };
    let forced = |k: &[f64], cc: &[f64]| {
        guarded(|| {
            let (mut qa, mut qp) = (vec![zero(); 4 * n], vec![zero(); 4 * n]);
            let gain: Vec<f64> = w.iter().map(|x| x * x).collect();
            pedestal::forced_response(&r, k, cc, &ped, &w, &w, &E2[..4], 1, Gain::PerPoint(&gain), RotorMotion::Absolute, &mut qa, &mut qp).map(|_| (qa, qp))
        })
    };
    let mut failures = Vec::new();
    // (k rows, c rows) per point vs the same with one of them broadcast
    let cases: [(&str, Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>); 2] = [
        ("k (n, 8), c (1, 8)", rows(KB, kb2), CB.to_vec(), rows(KB, kb2), rows(CB, CB)),
        ("k (1, 8), c (n, 8)", KB.to_vec(), rows(CB, cb2), rows(KB, KB), rows(CB, cb2)),
    ];
    for (what, k, cc, kf, cf) in cases.iter() {
        let want = eff(kf, cf).unwrap();
        match eff(k, cc) {
            Ok(got) if got == want => {}
            Ok(_) => failures.push(format!("effective_coefficients, {what}: wrong coefficients")),
            Err(e) => failures.push(format!("effective_coefficients, {what}: {e}")),
        }
        let want = forced(kf, cf).unwrap();
        match forced(k, cc) {
            Ok(got) if got == want => {}
            Ok(_) => failures.push(format!("pedestal::forced_response, {what}: wrong response")),
            Err(e) => failures.push(format!("pedestal::forced_response, {what}: {e}")),
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

// ---------------------------------------------------------------------------------------------
// 3. forced response

#[test]
fn forced_response_equals_the_coupled_8dof_solve() {
    let r = nsf_rotor();
    let pv = ped_values();
    let ped = Pedestals::from_slice(&pv).unwrap();
    let n = SPEEDS.len();
    let nrhs = 2;

    // (a) a force per point and right-hand side, spin != w (asynchronous, gyroscopic coupling)
    let spin: Vec<f64> = SPEEDS.iter().map(|w| 0.6 * w + 40.0).collect();
    let force: Vec<C64> = (0..n * nrhs * 4).map(|t| c((0.37 * t as f64).sin() * 50.0, (1.3 * t as f64).cos() * 20.0)).collect();
    let (mut qa, mut qp) = (vec![zero(); n * nrhs * 4], vec![zero(); n * nrhs * 4]);
    let bad = pedestal::forced_response(&r, &KB, &CB, &ped, &spin, &SPEEDS, &force, nrhs, Gain::One, RotorMotion::Absolute, &mut qa, &mut qp).unwrap();
    assert_eq!(bad, 0);
    for i in 0..n {
        for k in 0..nrhs {
            let o = (i * nrhs + k) * 4;
            let (q_ref, p_ref) = direct(&r, &pv, spin[i], SPEEDS[i], &force[o..o + 4]);
            assert_close(&qa[o..o + 4], &q_ref, 1e-9, &format!("force: q_abs at w {} rhs {k}", SPEEDS[i]));
            assert_close(&qp[o..o + 4], &p_ref, 1e-9, &format!("force: q_ped at w {} rhs {k}", SPEEDS[i]));
            // the pedestal really moves (this is not the rigid answer)
            assert!(vmax(&p_ref) > 1e-3 * vmax(&q_ref));
        }
    }

    // (b) imbalance: shared generalized imbalance vectors scaled by gain = w^2, spin = w
    let e = [c(3e-4, 0.0), c(0.0, -3e-4), c(1e-5, 2e-5), c(-2e-5, 1e-5), c(2e-4, 1e-4), c(1e-4, -2e-4), c(0.0, 0.0), c(3e-5, 0.0)];
    let gain: Vec<f64> = SPEEDS.iter().map(|w| w * w).collect();
    let bad = pedestal::forced_response(&r, &KB, &CB, &ped, &SPEEDS, &SPEEDS, &e, nrhs, Gain::PerPoint(&gain), RotorMotion::Absolute, &mut qa, &mut qp).unwrap();
    assert_eq!(bad, 0);
    for (i, &w) in SPEEDS.iter().enumerate() {
        for k in 0..nrhs {
            let o = (i * nrhs + k) * 4;
            let f: Vec<C64> = e[4 * k..4 * k + 4].iter().map(|v| v * (w * w)).collect();
            let (q_ref, p_ref) = direct(&r, &pv, w, w, &f);
            assert_close(&qa[o..o + 4], &q_ref, 1e-9, &format!("imbalance: q_abs at w {w} run {k}"));
            assert_close(&qp[o..o + 4], &p_ref, 1e-9, &format!("imbalance: q_ped at w {w} run {k}"));
        }
    }

    // wrong q_ped length is an error naming it
    let err = pedestal::forced_response(&r, &KB, &CB, &ped, &SPEEDS, &SPEEDS, &e, nrhs, Gain::PerPoint(&gain), RotorMotion::Absolute, &mut qa, &mut qp[..4]).unwrap_err();
    assert_eq!(err.name(), "q_ped");
}

/// A long batch (tasks of 1,024 points, a partial last one) gives every point the bits of that
/// point solved alone: per-point stiffness, damping, forces and gains, two right-hand sides,
/// every rotor motion, and a point whose bearing and pedestal cancel (Z + D singular: NaN, and
/// counted).
#[test]
fn long_batches_give_every_point_its_own_bits() {
    let r = nsf_rotor();
    let ped = Pedestals::from_slice(&ped_values()).unwrap();
    let (n, nrhs) = (2_600, 2);
    let w: Vec<f64> = (0..n).map(|i| 20.0 + 1.7 * i as f64).collect();
    let spin: Vec<f64> = w.iter().map(|x| 0.8 * x + 5.0).collect();
    let mut kb: Vec<f64> = (0..n * 8).map(|t| KB[t % 8] * (1.0 + 0.3 * (0.01 * t as f64).sin())).collect();
    let cb: Vec<f64> = (0..n * 8).map(|t| CB[t % 8] * (1.0 + 0.2 * (0.013 * t as f64).cos())).collect();
    // point 1500: bearing 1's stiffness the negative of its pedestal's dynamic stiffness, damping
    // aside: with no damping there, Z + D is the zero matrix
    let (sing, mut cb) = (1500, cb);
    let d = ped.dynamic_stiffness(0, w[sing]);
    for (q, (i, j)) in [(0, 0), (0, 1), (1, 0), (1, 1)].into_iter().enumerate() {
        kb[8 * sing + q] = -d[i][j].re;
        cb[8 * sing + q] = -d[i][j].im / w[sing];
    }
    let force: Vec<C64> = (0..n * nrhs * 4).map(|t| c((0.37 * t as f64).sin() * 50.0, (1.3 * t as f64).cos() * 20.0)).collect();
    let gain: Vec<f64> = w.iter().map(|x| 1.0 + 1e-3 * x).collect();
    let planes = [1.1, -0.1, 0.2, 0.8];
    for motion in [RotorMotion::Absolute, RotorMotion::Relative, RotorMotion::RelativeAtPlanes(planes)] {
        let (mut qa, mut qp) = (vec![zero(); n * nrhs * 4], vec![zero(); n * nrhs * 4]);
        let bad = pedestal::forced_response(&r, &kb, &cb, &ped, &spin, &w, &force, nrhs, Gain::PerPoint(&gain), motion, &mut qa, &mut qp).unwrap();
        let mut alone_bad = 0;
        for i in 0..n {
            let (o, s) = (i * nrhs * 4, nrhs * 4);
            let (mut a1, mut p1) = (vec![zero(); s], vec![zero(); s]);
            alone_bad += pedestal::forced_response(&r, &kb[8 * i..8 * i + 8], &cb[8 * i..8 * i + 8], &ped, &spin[i..=i], &w[i..=i], &force[o..o + s], nrhs, Gain::PerPoint(&gain[i..=i]), motion, &mut a1, &mut p1).unwrap();
            for (what, got, want) in [("q_rotor", &qa[o..o + s], &a1[..]), ("q_ped", &qp[o..o + s], &p1[..])] {
                for (x, y) in got.iter().zip(want) {
                    let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()) || (a == 0.0 && b == 0.0);
                    assert!(same(x.re, y.re) && same(x.im, y.im), "{motion:?} point {i} {what}: {x} in the batch, {y} alone");
                }
            }
        }
        assert_eq!(bad, alone_bad, "{motion:?}: singular points");
        assert_eq!(bad, 1, "{motion:?}: the point where Z + D vanishes");
        assert!(qa[sing * nrhs * 4].re.is_nan() && qp[sing * nrhs * 4].re.is_nan());
    }
}

#[test]
fn stiff_pedestals_approach_the_rigid_forced_response() {
    let r = nsf_rotor();
    let pv = stiff_ped_values();
    let ped = Pedestals::from_slice(&pv).unwrap();
    let n = SPEEDS.len();
    let e = [c(3e-4, 0.0), c(0.0, -3e-4), c(1e-5, 2e-5), c(-2e-5, 1e-5)];
    let gain: Vec<f64> = SPEEDS.iter().map(|w| w * w).collect();
    let (mut qa, mut qp, mut q0) = (vec![zero(); 4 * n], vec![zero(); 4 * n], vec![zero(); 4 * n]);
    assert_eq!(pedestal::forced_response(&r, &KB, &CB, &ped, &SPEEDS, &SPEEDS, &e, 1, Gain::PerPoint(&gain), RotorMotion::Absolute, &mut qa, &mut qp).unwrap(), 0);
    assert_eq!(forced::forced_response_scaled(&r, &KB, &CB, &SPEEDS, &SPEEDS, &e, 1, &gain, &mut q0).unwrap(), 0);
    for (i, &w) in SPEEDS.iter().enumerate() {
        let sl = 4 * i..4 * i + 4;
        // relative compliance of the pedestal ~ 3.5e6 / 1e14: the responses agree to ~1e-7
        assert_close(&qa[sl.clone()], &q0[sl.clone()], 1e-6, &format!("stiff pedestal vs rigid at w {w}"));
        assert!(vmax(&qp[sl.clone()]) < 1e-6 * vmax(&q0[sl.clone()]), "pedestal motion at w {w}: {:?}", &qp[sl.clone()]);
        let (q_ref, p_ref) = direct(&r, &pv, w, w, &e.iter().map(|v| v * (w * w)).collect::<Vec<_>>());
        assert_close(&qa[sl.clone()], &q_ref, 1e-9, &format!("stiff: q_abs at w {w}"));
        assert_close(&qp[sl.clone()], &p_ref, 1e-6, &format!("stiff: q_ped at w {w}"));
    }
}

// ---------------------------------------------------------------------------------------------
// 4-5. identification and bearing forces with pedestal motion

/// Imbalance vectors of two runs (independent distributions).
const E2: [C64; 8] = [
    C64::new(3e-4, 0.0),
    C64::new(2e-4, 1e-4),
    C64::new(0.0, -3e-4),
    C64::new(1e-4, -2e-4),
    C64::new(-1e-4, 3e-4),
    C64::new(3e-4, 0.0),
    C64::new(2e-5, -4e-5),
    C64::new(-3e-5, 1e-5),
];

/// Exact responses of the two runs from the 8 x 8 reference: per run (n, 4) blocks of the
/// journal motion relative to its housing and of the pedestal motion.
fn exact_runs(r: &Rotor, pv: &[f64; 20], w: &[f64]) -> (Vec<C64>, Vec<C64>) {
    let n = w.len();
    let (mut rel, mut ped) = (vec![zero(); 2 * n * 4], vec![zero(); 2 * n * 4]);
    for run in 0..2 {
        for (i, &wi) in w.iter().enumerate() {
            let f: Vec<C64> = E2[4 * run..4 * run + 4].iter().map(|v| v * (wi * wi)).collect();
            let (q, p) = direct(r, pv, wi, wi, &f);
            let o = (run * n + i) * 4;
            for d in 0..4 {
                rel[o + d] = q[d] - p[d];
                ped[o + d] = p[d];
            }
        }
    }
    (rel, ped)
}

fn identify(p: &IdentProblem, report: bool) -> (Vec<f64>, Vec<f64>, usize) {
    let npts = p.w.len();
    let (mut k, mut cc, mut cond, mut resid, mut amp) = (vec![0.0; npts * 8], vec![0.0; npts * 8], vec![0.0; npts * 2], vec![0.0; npts], vec![0.0; npts]);
    let out = IdentOut { k: &mut k, c: &mut cc, cond: &mut cond, resid: &mut resid, amp: &mut amp, k_std: None, c_std: None, rel_std: None };
    let nbad = if report { identify_report(p, out).unwrap() } else { identify_forces(p, out).unwrap() };
    (k, cc, nbad)
}

/// Largest error of K and of C per bearing, relative to that bearing's largest |K| resp. |C|.
fn coef_error(k: &[f64], cc: &[f64], n: usize) -> f64 {
    let mut worst = 0.0f64;
    for i in 0..n {
        for b in 0..2 {
            let ks = (0..4).map(|t| KB[4 * b + t].abs()).fold(0.0, f64::max);
            let cs = (0..4).map(|t| CB[4 * b + t].abs()).fold(0.0, f64::max);
            for t in 0..4 {
                let o = 8 * i + 4 * b + t;
                worst = worst.max((k[o] - KB[4 * b + t]).abs() / ks).max((cc[o] - CB[4 * b + t]).abs() / cs);
                if k[o].is_nan() || cc[o].is_nan() {
                    worst = f64::INFINITY;
                }
            }
        }
    }
    worst
}

#[test]
fn identification_with_pedestal_motion_recovers_the_bearings() {
    let r = nsf_rotor();
    let pv = ped_values();
    let w = SPEEDS;
    let n = w.len();
    let (rel, ped) = exact_runs(&r, &pv, &w);
    let qb: Vec<&[C64]> = rel.chunks(4 * n).collect();
    let pb: Vec<&[C64]> = ped.chunks(4 * n).collect();
    let gain: Vec<f64> = w.iter().map(|x| x * x).collect();
    let p = IdentProblem { rotor: r, w: &w, spin: &w, q: &qb, e: &E2, gain: &gain, sigma: &[], q_ped: &pb, planes: None, batch: 1, runs: 2, identical: false };
    for report in [false, true] {
        let (k, cc, nbad) = identify(&p, report);
        assert_eq!(nbad, 0);
        let err = coef_error(&k, &cc, n);
        assert!(err < 1e-8, "report {report}: relative error {err:e}\nK {k:?}\nC {cc:?}");
    }
    // the same relative motions without the pedestal motion: the inertia then acts on the wrong
    // (relative) motion, and the coefficients are wrong
    let p0 = IdentProblem { q_ped: &[], ..p };
    for report in [false, true] {
        let (k, cc, _) = identify(&p0, report);
        let err = coef_error(&k, &cc, n);
        assert!(err > 0.1, "report {report}: ignoring the pedestal changes the coefficients by only {err:e}");
    }
    // q_ped blocks must match q's
    let short: Vec<&[C64]> = pb.iter().map(|b| &b[..4]).collect();
    let npts = n;
    let (mut k, mut cc, mut cond, mut resid, mut amp) = (vec![0.0; npts * 8], vec![0.0; npts * 8], vec![0.0; npts * 2], vec![0.0; npts], vec![0.0; npts]);
    let out = IdentOut { k: &mut k, c: &mut cc, cond: &mut cond, resid: &mut resid, amp: &mut amp, k_std: None, c_std: None, rel_std: None };
    assert_eq!(identify_forces(&IdentProblem { q_ped: &short, ..p }, out).unwrap_err().name(), "q_ped");
    let out = IdentOut { k: &mut k, c: &mut cc, cond: &mut cond, resid: &mut resid, amp: &mut amp, k_std: None, c_std: None, rel_std: None };
    assert_eq!(identify_forces(&IdentProblem { q_ped: &pb[..1], ..p }, out).unwrap_err().name(), "q_ped (blocks)");
}

#[test]
fn identification_from_the_kernel_forward_response() {
    // the same as above with the data of pedestal::forced_response itself (q_rel = q_abs - q_ped)
    let r = nsf_rotor();
    let ped = Pedestals::from_slice(&ped_values()).unwrap();
    let w = SPEEDS;
    let n = w.len();
    let gain: Vec<f64> = w.iter().map(|x| x * x).collect();
    let (mut qa, mut qp) = (vec![zero(); n * 2 * 4], vec![zero(); n * 2 * 4]);
    assert_eq!(pedestal::forced_response(&r, &KB, &CB, &ped, &w, &w, &E2, 2, Gain::PerPoint(&gain), RotorMotion::Absolute, &mut qa, &mut qp).unwrap(), 0);
    // (n, runs, 4) -> runs blocks of (n, 4)
    let (mut rel, mut pm) = (vec![zero(); 2 * n * 4], vec![zero(); 2 * n * 4]);
    for i in 0..n {
        for run in 0..2 {
            for d in 0..4 {
                let src = (i * 2 + run) * 4 + d;
                let dst = (run * n + i) * 4 + d;
                rel[dst] = qa[src] - qp[src];
                pm[dst] = qp[src];
            }
        }
    }
    let qb: Vec<&[C64]> = rel.chunks(4 * n).collect();
    let pb: Vec<&[C64]> = pm.chunks(4 * n).collect();
    let p = IdentProblem { rotor: r, w: &w, spin: &w, q: &qb, e: &E2, gain: &gain, sigma: &[], q_ped: &pb, planes: None, batch: 1, runs: 2, identical: false };
    let (k, cc, nbad) = identify(&p, false);
    assert_eq!(nbad, 0);
    let err = coef_error(&k, &cc, n);
    assert!(err < 1e-8, "relative error {err:e}");
}

#[test]
fn bearing_forces_are_the_bearing_impedance_times_the_relative_motion() {
    let r = nsf_rotor();
    let pv = ped_values();
    let w = SPEEDS;
    let n = w.len();
    let (rel, ped) = exact_runs(&r, &pv, &w);
    let qb: Vec<&[C64]> = rel.chunks(4 * n).collect();
    let pb: Vec<&[C64]> = ped.chunks(4 * n).collect();
    let gain: Vec<f64> = w.iter().map(|x| x * x).collect();
    let p = IdentProblem { rotor: r, w: &w, spin: &w, q: &qb, e: &E2, gain: &gain, sigma: &[], q_ped: &pb, planes: None, batch: 1, runs: 2, identical: false };
    let mut f = vec![zero(); 2 * n * 4];
    bearing_forces(&p, &mut f).unwrap();
    let mut f_rigid = vec![zero(); 2 * n * 4];
    bearing_forces(&IdentProblem { q_ped: &[], ..p }, &mut f_rigid).unwrap();
    let mut worst_rigid = 0.0f64;
    for run in 0..2 {
        for (i, &wi) in w.iter().enumerate() {
            let o = (run * n + i) * 4;
            let q = &rel[o..o + 4];
            let s = c(0.0, wi);
            let f1 = mv2(&imp(&KB, &CB, 0, s), q[0], q[2]);
            let f2 = mv2(&imp(&KB, &CB, 1, s), q[1], q[3]);
            let want = [f1[0], f2[0], f1[1], f2[1]]; // [f1x, f2x, f1y, f2y]
            assert_close(&f[o..o + 4], &want, 1e-9, &format!("bearing forces run {run} w {wi}"));
            // the same force loads the pedestal: D_b p_b
            let p = &ped[o..o + 4];
            let mut d = [imp(&pv[4..12], &pv[12..20], 0, s), imp(&pv[4..12], &pv[12..20], 1, s)];
            for (b, db) in d.iter_mut().enumerate() {
                db[0][0] += s * s * pv[2 * b];
                db[1][1] += s * s * pv[2 * b + 1];
            }
            let g1 = mv2(&d[0], p[0], p[2]);
            let g2 = mv2(&d[1], p[1], p[3]);
            assert_close(&f[o..o + 4], &[g1[0], g2[0], g1[1], g2[1]], 1e-9, &format!("pedestal load run {run} w {wi}"));
            let scale = vmax(&want);
            for d in 0..4 {
                worst_rigid = worst_rigid.max((f_rigid[o + d] - want[d]).norm() / scale);
            }
        }
    }
    // without the pedestal motion the forces are those of the wrong inertia
    assert!(worst_rigid > 0.1, "forces without q_ped differ by only {worst_rigid:e}");
    let mut short = vec![zero(); 5];
    assert_eq!(bearing_forces(&p, &mut short).unwrap_err().name(), "out");
}

// ---------------------------------------------------------------------------------------------
// 6. modal analysis

/// Upper bound of the smallest singular value of H relative to ||H||_F, by two steps of inverse
/// iteration from a generic vector: ~1e-16 at an eigenvalue, O(1) away from one.
fn near_singularity(h: &[[C64; 8]; 8]) -> f64 {
    let mut v: [C64; 8] = std::array::from_fn(|d| c((0.7 * d as f64 + 0.3).cos(), (1.1 * d as f64 + 0.2).sin()));
    let mut ratio = f64::INFINITY;
    for _ in 0..2 {
        let nv = v.iter().map(|z| z.norm_sqr()).sum::<f64>().sqrt();
        let x = match gauss(h, &v) {
            Some(x) => x,
            None => return 0.0,
        };
        let nx = x.iter().map(|z| z.norm_sqr()).sum::<f64>().sqrt();
        if !nx.is_finite() {
            return 0.0;
        }
        ratio = ratio.min(nv / nx);
        v = std::array::from_fn(|d| x[d] / nx);
    }
    ratio / fro(h)
}

/// Real M, C (+ spin G), K of the reference from H(s) = s^2 M + s C + K.
fn reference_mck(r: &Rotor, pv: &[f64; 20], kb: &[f64], cb: &[f64], spin: f64) -> [[[C64; 8]; 8]; 3] {
    let h0 = coupled_h(r, kb, cb, pv, spin, zero());
    let hp = coupled_h(r, kb, cb, pv, spin, c(1.0, 0.0));
    let hm = coupled_h(r, kb, cb, pv, spin, c(-1.0, 0.0));
    let mut out = [[[zero(); 8]; 8]; 3];
    for i in 0..8 {
        for j in 0..8 {
            out[0][i][j] = (hp[i][j] + hm[i][j]) * 0.5 - h0[i][j];
            out[1][i][j] = (hp[i][j] - hm[i][j]) * 0.5;
            out[2][i][j] = h0[i][j];
        }
    }
    out
}

#[test]
fn modal_eigenvalues_are_roots_of_the_coupled_characteristic_equation() {
    let r = nsf_rotor();
    let pv = ped_values();
    let ped = Pedestals::from_slice(&pv).unwrap();
    let spin = [0.0, 300.0, 800.0, 2000.0];
    let n = spin.len();
    let kb: Vec<f64> = (0..n).flat_map(|_| KB).collect();
    let cb: Vec<f64> = (0..n).flat_map(|_| CB).collect();
    let (mut lam, mut sh) = (vec![zero(); 8 * n], vec![zero(); 64 * n]);
    assert_eq!(pedestal::modal(&r, &kb, &cb, &ped, &spin, &mut lam, &mut sh).unwrap(), 0);
    for (i, &om) in spin.iter().enumerate() {
        let l = &lam[8 * i..8 * i + 8];
        // every mode is underdamped here: 8 eigenvalues with positive imaginary part
        assert!(l.iter().all(|z| z.re.is_finite() && z.im > 0.0), "spin {om}: {l:?}");
        for m in 1..8 {
            assert!(l[m].im >= l[m - 1].im, "not sorted by damped frequency: {l:?}");
        }
        for (m, &s) in l.iter().enumerate() {
            let h = coupled_h(&r, &KB, &CB, &pv, om, s);
            let sing = near_singularity(&h);
            assert!(sing < 1e-11, "spin {om} mode {m} ({s}): sigma_min / ||H|| <= {sing:e}");
            // not vacuous: a point next to the eigenvalue is far from singular
            let off = coupled_h(&r, &KB, &CB, &pv, om, s * c(1.0, 1e-3));
            assert!(near_singularity(&off) > 1e3 * sing.max(1e-16));
            // the shape is a null vector of H(lambda), unit largest component
            let v: [C64; 8] = std::array::from_fn(|d| sh[64 * i + 8 * m + d]);
            let big = vmax(&v);
            assert!((big - 1.0).abs() < 1e-12, "shape not normalized: {v:?}");
            let hv: Vec<C64> = (0..8).map(|a| (0..8).map(|b| h[a][b] * v[b]).sum::<C64>()).collect();
            let res = hv.iter().map(|z| z.norm_sqr()).sum::<f64>().sqrt();
            assert!(res < 1e-9 * fro(&h), "spin {om} mode {m}: |H v| = {res:e}, ||H|| = {:e}", fro(&h));
        }
        // completeness: the 16 eigenvalues (these 8 and their conjugates) sum to -tr(M^-1 C)
        let [mm, cc, _] = reference_mck(&r, &pv, &KB, &CB, om);
        let mut tr = 0.0;
        for j in 0..8 {
            let col: [C64; 8] = std::array::from_fn(|a| cc[a][j]);
            tr += gauss(&mm, &col).unwrap()[j].re;
        }
        let sum: f64 = l.iter().map(|z| 2.0 * z.re).sum();
        assert!((sum + tr).abs() < 1e-9 * tr.abs(), "spin {om}: sum of eigenvalues {sum} vs -tr(M^-1 C) {}", -tr);
    }
    // modal needs pedestal masses
    let mut pz = pv;
    pz[2] = 0.0;
    let ped0 = Pedestals::from_slice(&pz).unwrap();
    assert_eq!(pedestal::modal(&r, &kb, &cb, &ped0, &spin, &mut lam, &mut sh).unwrap_err().name(), "pedestals");
}

/// Points analysed two at a time (their eigenvalue iterations interleaved) get the bits each
/// gets alone: an odd number of points (the last alone), different bearings per point, and
/// failing points (NaN, inf coefficients) next to good ones, in either position of a pair.
#[test]
fn modal_pairs_of_points_give_each_point_its_own_bits() {
    let r = nsf_rotor();
    let ped = Pedestals::from_slice(&ped_values()).unwrap();
    let n = 9;
    let mut kb = Vec::new();
    let mut cb = Vec::new();
    for i in 0..n {
        let f = 0.6 + 0.23 * ((i * 5) % 7) as f64;
        kb.extend(KB.iter().enumerate().map(|(j, &v)| if j % 3 == 0 { v * f } else { v }));
        cb.extend(CB.iter().enumerate().map(|(j, &v)| if j % 2 == 1 { v / f } else { v }));
    }
    kb[8 * 2 + 1] = f64::NAN;
    cb[8 * 5 + 6] = f64::INFINITY;
    let spin: Vec<f64> = (0..n).map(|i| 230.0 * i as f64).collect();
    let (mut lam, mut sh) = (vec![zero(); 8 * n], vec![zero(); 64 * n]);
    assert_eq!(pedestal::modal(&r, &kb, &cb, &ped, &spin, &mut lam, &mut sh).unwrap(), 2);
    let bits = |v: &[C64]| v.iter().map(|z| (z.re.to_bits(), z.im.to_bits())).collect::<Vec<_>>();
    for i in 0..n {
        let (mut l1, mut s1) = (vec![zero(); 8], vec![zero(); 64]);
        let failed = pedestal::modal(&r, &kb[8 * i..8 * i + 8], &cb[8 * i..8 * i + 8], &ped, &spin[i..i + 1], &mut l1, &mut s1).unwrap();
        assert_eq!(failed, usize::from(i == 2 || i == 5), "point {i}");
        assert_eq!(bits(&lam[8 * i..8 * i + 8]), bits(&l1), "eigenvalues of point {i}");
        assert_eq!(bits(&sh[64 * i..64 * i + 64]), bits(&s1), "shapes of point {i}");
    }
}

#[test]
fn stiff_pedestal_modes_approach_the_rigid_modes() {
    let r = nsf_rotor();
    let pv = stiff_ped_values();
    let ped = Pedestals::from_slice(&pv).unwrap();
    let spin = [0.0, 500.0, 1500.0];
    let n = spin.len();
    let kb: Vec<f64> = (0..n).flat_map(|_| KB).collect();
    let cb: Vec<f64> = (0..n).flat_map(|_| CB).collect();
    let (mut lam, mut sh) = (vec![zero(); 8 * n], vec![zero(); 64 * n]);
    assert_eq!(pedestal::modal(&r, &kb, &cb, &ped, &spin, &mut lam, &mut sh).unwrap(), 0);
    let (mut l4, mut s4) = (vec![zero(); 4 * n], vec![zero(); 16 * n]);
    assert_eq!(modal::modal(&r, &kb, &cb, &spin, &mut l4, &mut s4).unwrap(), 0);
    for i in 0..n {
        for m in 0..4 {
            let (a, b) = (lam[8 * i + m], l4[4 * i + m]);
            assert!(b.im > 0.0);
            assert!((a - b).norm() < 1e-6 * b.norm(), "spin {}: mode {m}: {a} vs rigid {b}", spin[i]);
            // rotor modes: the pedestal hardly moves
            let v = &sh[64 * i + 8 * m..64 * i + 8 * m + 8];
            assert!(vmax(&v[4..]) < 1e-6, "spin {} mode {m}: pedestal part {:?}", spin[i], &v[4..]);
        }
        // the pedestal modes are far above: sqrt(1e14 / 10) ~ 3.2e6 rad/s
        for m in 4..8 {
            let a = lam[8 * i + m];
            assert!((a.im - 3.16e6).abs() < 0.05e6, "spin {}: pedestal mode {a}", spin[i]);
        }
    }
}

/// The relative motion the core forms (q - p in the pass that forms p) is the absolute motion
/// less the pedestal motion, bit for bit, and the imbalance gain formed from spin (no array) is
/// the per-point gain spin^2; a per-point gain of the wrong length is refused.
#[test]
fn relative_motion_and_imbalance_gain_match_their_definitions() {
    let r = nsf_rotor();
    let ped = Pedestals::from_slice(&ped_values()).unwrap();
    let w: Vec<f64> = (0..777).map(|i| 30.0 + 1.7 * i as f64).collect();
    let n = w.len();
    let run = |gain: Gain, motion: RotorMotion| {
        let (mut q, mut p) = (vec![zero(); 8 * n], vec![zero(); 8 * n]);
        pedestal::forced_response(&r, &KB, &CB, &ped, &w, &w, &E2, 2, gain, motion, &mut q, &mut p).unwrap();
        (q, p)
    };
    let w2: Vec<f64> = w.iter().map(|x| x * x).collect();
    let (qa, pa) = run(Gain::PerPoint(&w2), RotorMotion::Absolute);
    let (qs, ps) = run(Gain::SpinSquared, RotorMotion::Absolute);
    assert_eq!((&qa, &pa), (&qs, &ps));
    let (qr, pr) = run(Gain::SpinSquared, RotorMotion::Relative);
    assert_eq!(pr, pa);
    for i in 0..qa.len() {
        assert_eq!(qr[i], qa[i] - pa[i], "value {i}");
    }
    // at the probe planes: T q moved as the plane transform moves it, minus p, bit for bit
    let t = [1.3, -0.3, -0.2, 1.2];
    let (qt, pt) = run(Gain::SpinSquared, RotorMotion::RelativeAtPlanes(t));
    assert_eq!(pt, pa);
    for (j, (got, (q, p))) in qt.chunks_exact(4).zip(qa.chunks_exact(4).zip(pa.chunks_exact(4))).enumerate() {
        let moved = rotorid_core::model::planes_point(&t, [q[0], q[1], q[2], q[3]]);
        for d in 0..4 {
            assert_eq!(got[d], moved[d] - p[d], "point/force {j}, coordinate {d}");
        }
    }
    assert!(pa.iter().all(|z| z.re.is_finite()) && pa.iter().any(|z| z.norm() > 0.0));
    let (mut q, mut p) = (vec![zero(); 8 * n], vec![zero(); 8 * n]);
    let err = pedestal::forced_response(&r, &KB, &CB, &ped, &w, &w, &E2, 2, Gain::PerPoint(&w2[1..]), RotorMotion::Relative, &mut q, &mut p);
    assert_eq!(err.unwrap_err().name(), "gain");
}
