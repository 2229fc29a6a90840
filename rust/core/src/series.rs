//! Supports in series: an impedance Z (the bearing film) acting through an intermediate mass on a
//! second impedance to ground (a damper, a pedestal).
//!
//! The journal moves x, the intermediate body (damper journal: ring + bearing shell; or a bearing
//! housing) y. At a vibration frequency w, with D the dynamic stiffness of the intermediate body
//! on its support, D = Z_d - w^2 m_j I,
//!
//! ```text
//!   body     D y = Z (x - y)             =>  y = T x,   T = (Z + D)^-1 Z
//!   journal  f = Z (x - y) = Z_eq x,          Z_eq = Z - Z (Z + D)^-1 Z = D (Z + D)^-1 Z
//! ```
//!
//! (the last form is (Z^-1 + D^-1)^-1 when both are invertible, and needs neither inverse). Z_eq
//! depends on w even where Z and Z_d do not, so a synchronous identification (w = Omega) and an
//! impact identification (w != Omega) measure different things. Report: "an equivalent impedance
//! formulation derived from the equations of motion of the support elements" (sec. 1, 5).

use crate::error::{expect_len, expect_len_or_broadcast, product, CoreError};
use crate::model::C64;

/// A 2 x 2 complex matrix [i][j] over (x, y).
pub type C2 = [[C64; 2]; 2];

#[inline(always)]
pub(crate) fn mul2(a: &C2, b: &C2) -> C2 {
    let mut o = [[C64::new(0.0, 0.0); 2]; 2];
    for i in 0..2 {
        for j in 0..2 {
            o[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j];
        }
    }
    o
}

/// T = (Z + D)^-1 Z and Z_eq = D T; None when Z + D is singular (|det| at or below 1e-14 of the
/// squared scale of Z and D: their sum may cancel to rounding, a resonance) or not finite.
/// Inlined into its callers, some of which run at the CPU's SIMD level (the pedestal model's
/// forced response): out of line it was compiled for the build's baseline.
#[inline(always)]
pub fn series(z: &C2, d: &C2) -> Option<(C2, C2)> {
    let s = [[z[0][0] + d[0][0], z[0][1] + d[0][1]], [z[1][0] + d[1][0], z[1][1] + d[1][1]]];
    let det = s[0][0] * s[1][1] - s[0][1] * s[1][0];
    let scale = z.iter().chain(d.iter()).flatten().map(|v| v.norm_sqr()).sum::<f64>();
    if !(det.norm() > 1e-14 * scale) || !det.is_finite() {
        return None;
    }
    let inv = [[s[1][1] / det, -s[0][1] / det], [-s[1][0] / det, s[0][0] / det]];
    let t = mul2(&inv, z);
    Some((t, mul2(d, &t)))
}

#[inline]
fn c2_at(a: &[C64], o: usize) -> C2 {
    [[a[o], a[o + 1]], [a[o + 2], a[o + 3]]]
}

/// Z_eq of a bearing film in series with a damper through the damper journal's mass, at every
/// point i:
///
/// ```text
///   Z_eq,i = Z_b,i - Z_b,i (Z_b,i + Z_d,i - w_i^2 m_j,i I)^-1 Z_b,i
/// ```
///
/// `z_bearing`, `z_damper`: (n, 2, 2) complex row-major, or (1, 2, 2) for every point;
/// `journal_mass`: (n,) or (1,) kg, >= 0; `w`: (n,) rad/s, finite. `z_eq`: (n, 2, 2). Returns the
/// number of points where Z_b + D is singular (NaN there).
pub fn series_impedance(
    z_bearing: &[C64],
    z_damper: &[C64],
    journal_mass: &[f64],
    w: &[f64],
    z_eq: &mut [C64],
) -> Result<usize, CoreError> {
    series_impedance_scaled(z_bearing, z_damper, journal_mass, w, 1.0, z_eq)
}

/// [`series_impedance`] at w_i = `w_scale` * `axis`_i, formed point by point (the bits of scaling
/// the axis first): an axis in Hz with `w_scale` = 2 pi needs no (n,) array of w. `w_scale` must
/// be finite and > 0, `axis` finite.
pub fn series_impedance_scaled(
    z_bearing: &[C64],
    z_damper: &[C64],
    journal_mass: &[f64],
    axis: &[f64],
    w_scale: f64,
    z_eq: &mut [C64],
) -> Result<usize, CoreError> {
    if !(w_scale.is_finite() && w_scale > 0.0) {
        return Err(CoreError::value("w_scale", "must be finite and > 0"));
    }
    let n = axis.len();
    let total = product("z_eq", &[n, 4])?;
    expect_len_or_broadcast("z_bearing", z_bearing, 4, total)?;
    expect_len_or_broadcast("z_damper", z_damper, 4, total)?;
    expect_len_or_broadcast("journal_mass", journal_mass, 1, n)?;
    expect_len("z_eq", z_eq, total)?;
    if axis.iter().any(|x| !(w_scale * x).is_finite()) {
        let what = if w_scale == 1.0 { "(vibration frequency) must be finite" } else { "(vibration frequency axis) times w_scale must be finite" };
        return Err(CoreError::value("w", what));
    }
    if journal_mass.iter().any(|m| !(m.is_finite() && *m >= 0.0)) {
        return Err(CoreError::value("journal_mass", "must be finite and >= 0"));
    }
    let (bb, bd, bm) = (z_bearing.len() == 4, z_damper.len() == 4, journal_mass.len() == 1);
    /// points per task
    const TASK: usize = 1024;
    let point = |i: usize, out: &mut [C64]| -> usize {
        let zb = c2_at(z_bearing, if bb { 0 } else { 4 * i });
        let mut d = c2_at(z_damper, if bd { 0 } else { 4 * i });
        let m = journal_mass[if bm { 0 } else { i }];
        let wi = w_scale * axis[i];
        d[0][0] -= wi * wi * m;
        d[1][1] -= wi * wi * m;
        match series(&zb, &d) {
            Some((_, ze)) => {
                out.copy_from_slice(&[ze[0][0], ze[0][1], ze[1][0], ze[1][1]]);
                0
            }
            None => {
                out.fill(C64::new(f64::NAN, f64::NAN));
                1
            }
        }
    };
    let z_eq = crate::par::Disjoint::new(z_eq);
    // tasks shared with the calling thread (crate::par)
    let nbad = crate::par::sum_tasks(n.div_ceil(TASK), |j| {
        // SAFETY: sum_tasks hands each task index j to one task
        let o = unsafe { z_eq.chunk(j, 4 * TASK) };
        o.chunks_exact_mut(4).enumerate().map(|(t, out)| point(j * TASK + t, out)).sum()
    });
    Ok(nbad)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(re: f64, im: f64) -> C64 {
        C64::new(re, im)
    }

    #[test]
    fn scalar_springs_in_series() {
        // k1 and k2 in series, no mass: k1 k2 / (k1 + k2)
        let zb = [c(3e6, 0.0), c(0.0, 0.0), c(0.0, 0.0), c(3e6, 0.0)];
        let zd = [c(1e6, 0.0), c(0.0, 0.0), c(0.0, 0.0), c(1e6, 0.0)];
        let mut out = [c(0.0, 0.0); 4];
        let nb = series_impedance(&zb, &zd, &[0.0], &[100.0], &mut out).unwrap();
        assert_eq!(nb, 0);
        assert!((out[0] - c(0.75e6, 0.0)).norm() < 1e-6 && out[1].norm() < 1e-9);
    }

    #[test]
    fn rigid_damper_gives_the_bearing() {
        let zb = [c(2e6, 3e3), c(1e5, -2e2), c(-4e4, 7e2), c(2.5e6, 4e3)];
        let zd = [c(1e15, 0.0), c(0.0, 0.0), c(0.0, 0.0), c(1e15, 0.0)];
        let mut out = [c(0.0, 0.0); 4];
        series_impedance(&zb, &zd, &[1.0], &[300.0], &mut out).unwrap();
        for k in 0..4 {
            assert!((out[k] - zb[k]).norm() < 1e-7 * zb[0].norm());
        }
    }

    #[test]
    fn bad_arguments_are_errors() {
        let z = [c(1.0, 0.0); 4];
        let mut out = [c(0.0, 0.0); 8];
        assert!(series_impedance(&z, &z, &[-1.0], &[1.0, 2.0], &mut out).is_err());
        assert!(series_impedance(&z, &z, &[1.0], &[1.0, f64::NAN], &mut out).is_err());
        assert!(series_impedance(&z[..3], &z, &[1.0], &[1.0, 2.0], &mut out).is_err());
        assert!(series_impedance(&z, &z, &[1.0, 1.0, 1.0], &[1.0, 2.0], &mut out).is_err());
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(series_impedance_scaled(&z, &z, &[1.0], &[1.0, 2.0], bad, &mut out).is_err(), "w_scale {bad}");
        }
        assert!(series_impedance_scaled(&z, &z, &[1.0], &[1.0, 1e308], 1e10, &mut out).is_err());
    }

    #[test]
    fn a_scaled_axis_gives_the_bits_of_scaling_first() {
        let zb = [c(2e6, 3e3), c(1e5, -2e2), c(-4e4, 7e2), c(2.5e6, 4e3)];
        let zd = [c(8e5, 1e3), c(0.0, 0.0), c(0.0, 0.0), c(9e5, 2e3)];
        let scale = 2.0 * std::f64::consts::PI;
        let f: Vec<f64> = (0..3000).map(|i| 0.37 * i as f64).collect();
        let w: Vec<f64> = f.iter().map(|x| scale * x).collect();
        let (mut a, mut b) = (vec![c(0.0, 0.0); 4 * f.len()], vec![c(0.0, 0.0); 4 * f.len()]);
        let na = series_impedance(&zb, &zd, &[12.0], &w, &mut a).unwrap();
        let nb = series_impedance_scaled(&zb, &zd, &[12.0], &f, scale, &mut b).unwrap();
        assert_eq!(na, nb);
        assert!(a.iter().zip(&b).all(|(x, y)| x.re.to_bits() == y.re.to_bits() && x.im.to_bits() == y.im.to_bits()));
    }
}
