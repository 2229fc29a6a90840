//! Rigid-rotor model matrices (report eq. 3) and their assembly from bearing coefficients.
//!
//! Layout conventions shared by every kernel:
//! - response vector q = [x1, x2, y1, y2] (report eq. 2);
//! - bearing coefficients of one point are 8 numbers ordered [bearing][i][j] with i, j in (x, y),
//!   i.e. index = 4*bearing + 2*i + j.

use crate::lanes::{Z, V};

pub type C64 = num_complex::Complex64;

/// Rigid rotor: mass, transverse and polar inertia, bearing distances from the CG.
#[derive(Clone, Copy, Debug)]
pub struct Rotor {
    pub m: f64,
    pub it: f64,
    pub ip: f64,
    pub l1: f64,
    pub l2: f64,
}

impl Rotor {
    pub fn from_slice(p: &[f64]) -> Result<Rotor, String> {
        if p.len() != 5 {
            return Err(format!("rotor parameters must be [m, I_T, I_p, l1, l2], got {} values", p.len()));
        }
        let r = Rotor { m: p[0], it: p[1], ip: p[2], l1: p[3], l2: p[4] };
        if !(r.m > 0.0 && r.it > 0.0 && r.ip >= 0.0 && r.l1.is_finite() && r.l2.is_finite()) {
            return Err("rotor: mass and inertias must be positive and finite".into());
        }
        if !(r.span().abs() > 0.0) {
            return Err("rotor: bearing span l1 + l2 must be non-zero".into());
        }
        Ok(r)
    }

    #[inline(always)]
    pub fn span(&self) -> f64 {
        self.l1 + self.l2
    }

    /// Inertia matrix M of eq. 3.
    pub fn mass_matrix(&self) -> [[f64; 4]; 4] {
        let (m, it, l1, l2, il) = (self.m, self.it, self.l1, self.l2, 1.0 / self.span());
        [
            [m * l2 * il, m * l1 * il, 0.0, 0.0],
            [0.0, 0.0, m * l2 * il, m * l1 * il],
            [-it * il, it * il, 0.0, 0.0],
            [0.0, 0.0, it * il, -it * il],
        ]
    }

    /// Gyroscopic matrix G of eq. 3 (multiplied by the spin speed in eq. 1).
    pub fn gyro_matrix(&self) -> [[f64; 4]; 4] {
        let g = self.ip / self.span();
        [
            [0.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, -g, g],
            [-g, g, 0.0, 0.0],
        ]
    }
}

/// Assemble the 4x4 stiffness (or damping) matrix of eq. 3 from the 8 bearing coefficients.
#[inline(always)]
pub fn assemble(b: &[f64], l1: f64, l2: f64) -> [[f64; 4]; 4] {
    let (xx1, xy1, yx1, yy1) = (b[0], b[1], b[2], b[3]);
    let (xx2, xy2, yx2, yy2) = (b[4], b[5], b[6], b[7]);
    [
        [xx1, xx2, xy1, xy2],
        [yx1, yx2, yy1, yy2],
        [-xx1 * l1, xx2 * l2, -xy1 * l1, xy2 * l2],
        [yx1 * l1, -yx2 * l2, yy1 * l1, -yy2 * l2],
    ]
}

/// [`apply_planes`] for one point: [t11 x1 + t12 x2, t21 x1 + t22 x2, t11 y1 + t12 y2,
/// t21 y1 + t22 y2] with real-times-complex products.
#[inline(always)]
pub fn planes_point(t: &[f64; 4], q: [C64; 4]) -> [C64; 4] {
    [q[0] * t[0] + q[1] * t[1], q[0] * t[2] + q[1] * t[3], q[2] * t[0] + q[3] * t[1], q[2] * t[2] + q[3] * t[3]]
}

/// [`planes_point`] on N points at once (SIMD lanes): the same operations lane by lane, so each
/// lane holds the bits [`planes_point`] gives for its point.
#[inline(always)]
pub fn planes_lanes<const N: usize>(t: &[f64; 4], q: [Z<N>; 4]) -> [Z<N>; 4] {
    let (t0, t1, t2, t3) = (V::splat(t[0]), V::splat(t[1]), V::splat(t[2]), V::splat(t[3]));
    [
        q[0].scale(t0) + q[1].scale(t1),
        q[0].scale(t2) + q[1].scale(t3),
        q[2].scale(t0) + q[3].scale(t1),
        q[2].scale(t2) + q[3].scale(t3),
    ]
}

/// Points per parallel task of [`apply_planes`] (memory-bound: large tasks).
const PLANES_CHUNK: usize = 1 << 14;

/// Move responses between two pairs of measurement planes (report eq. 19): for every point,
/// [x_a, x_b] = T [x_1, x_2] and [y_a, y_b] = T [y_1, y_2] with the real 2x2 `t` = [T11, T12,
/// T21, T22] (row-major), e.g. from the probe planes to the bearings. `q`, `out`: (n, 4) as
/// [x1, x2, y1, y2]. Each output is t_i1 q_1 + t_i2 q_2 with real-times-complex products. A
/// non-finite response gives non-finite outputs (NaN where an inf meets a zero entry of `t`).
/// Returns the flat index of the first non-finite value of `q` (None when all are finite), found
/// on the way: the caller needs no separate scan to refuse or mark them.
pub fn apply_planes(t: &[f64; 4], q: &[C64], out: &mut [C64]) -> Result<Option<usize>, crate::CoreError> {
    if q.len() % 4 != 0 {
        return Err(crate::CoreError::length("q", q.len(), "a multiple of 4 ([x1, x2, y1, y2] per point)".to_string()));
    }
    crate::error::expect_len("out", out, q.len())?;
    // (chunk offset, values) -> first non-finite index in it
    // (x - x is the finiteness test below, on purpose: clippy's eq_op does not apply)
    #[allow(clippy::eq_op)]
    let pass = |at: usize, q: &[C64], out: &mut [C64]| -> Option<usize> {
        let mut all_finite = true;
        for (p, o) in q.chunks_exact(4).zip(out.chunks_exact_mut(4)) {
            o.copy_from_slice(&planes_point(t, [p[0], p[1], p[2], p[3]]));
            // x - x is 0 for a finite x and NaN for inf or NaN: a sum of them is 0 iff all are finite
            all_finite &= p.iter().fold(0.0, |acc, z| acc + (z.re - z.re) + (z.im - z.im)) == 0.0;
        }
        if all_finite {
            return None;
        }
        q.iter().position(|z| !(z.re.is_finite() && z.im.is_finite())).map(|i| at + i)
    };
    if q.len() <= 4 * PLANES_CHUNK {
        return Ok(pass(0, q, out));
    }
    // tasks shared with the calling thread (crate::par); the smallest index found in any chunk
    let first_bad = std::sync::atomic::AtomicUsize::new(usize::MAX);
    let out = crate::par::Disjoint::new(out);
    crate::par::for_each_task(q.len().div_ceil(4 * PLANES_CHUNK), |j| {
        let lo = j * 4 * PLANES_CHUNK;
        // SAFETY: for_each_task hands each chunk index j to one task
        let o = unsafe { out.chunk(j, 4 * PLANES_CHUNK) };
        if let Some(i) = pass(lo, &q[lo..lo + o.len()], o) {
            first_bad.fetch_min(i, std::sync::atomic::Ordering::Relaxed);
        }
    });
    Ok(Some(first_bad.into_inner()).filter(|&i| i != usize::MAX))
}
