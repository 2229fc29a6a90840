//! Batched forced response: H(Omega, omega) q = F with H = -w^2 M + j w Omega G + j w C + K
//! (report eq. 13-14 for imbalance, eq. 27-28 for impacts).

use crate::error::{expect_len, expect_len_or_broadcast, product, CoreError};
use crate::lanes::L;
use crate::model::{assemble, planes_point, Rotor, C64};

#[cfg(target_arch = "x86_64")]
mod registers;

/// Points per group: two sets of [`L`] lanes. Lane loop 1 works on lanes l and l + L together,
/// step by step in alternation, so that the dependency chain of one matrix (pivot search,
/// division, update) overlaps the other's. One thread, 4,096 points in cache, best of 400 calls
/// (2026-11-26): 26.2 -> 22.7 ns per point at AVX-512, 31.6 -> 28.6 ns at AVX2, against groups of
/// `L` lanes one matrix at a time.
const G: usize = 2 * L;
type V = crate::lanes::V<G>;
type Z = crate::lanes::Z<G>;

/// Solve a 4x4 complex system in place by LU with partial pivoting, for `nrhs` right-hand sides
/// stored consecutively in `rhs` (each of length 4). Returns false if the matrix is singular
/// (a zero pivot, or for a forced response a pivot spread beyond 1e10); the right-hand sides are
/// then set to NaN.
#[inline(always)]
pub fn solve4(h: &mut [[C64; 4]; 4], rhs: &mut [C64]) -> bool {
    solve4_impl(h, rhs, 1e-10)
}

/// As [`solve4`] but accepting nearly singular matrices (inverse iteration solves with a shifted
/// matrix that is singular to rounding on purpose); only an exactly zero pivot fails.
#[inline(always)]
pub fn solve4_near_singular(h: &mut [[C64; 4]; 4], rhs: &mut [C64]) -> bool {
    solve4_impl(h, rhs, 0.0)
}

/// |re| + |im|: within a factor sqrt(2) of the modulus, enough to choose pivots and measure their
/// spread, and without the `hypot` call that took 42 % of a forced response.
#[inline(always)]
fn mag(z: C64) -> f64 {
    z.re.abs() + z.im.abs()
}

#[inline(always)]
fn solve4_impl(h: &mut [[C64; 4]; 4], rhs: &mut [C64], max_spread: f64) -> bool {
    match Lu4::factor(h, max_spread) {
        Some(lu) => {
            for b in rhs.chunks_exact_mut(4) {
                lu.solve(b);
            }
            true
        }
        None => {
            for v in rhs.iter_mut() {
                *v = C64::new(f64::NAN, f64::NAN);
            }
            false
        }
    }
}

/// The LU factors of [`solve4`] (partial pivoting), kept to solve right-hand sides one after
/// another: the inverse iteration of the modal analysis solves twice with one shifted matrix.
/// Solving with them performs, on each right-hand side, the operations `solve4` performs on it,
/// in the same order, so the results are the same bits.
#[derive(Clone, Copy, Debug)]
pub struct Lu4 {
    /// U in the upper triangle (rows in pivot order; below it, values no solve reads)
    u: [[C64; 4]; 4],
    /// row exchanged with row k at step k
    piv: [usize; 4],
    /// multiplier of row i at step k (`mult[k][i]`, i > k; zero when the update was skipped)
    mult: [[C64; 4]; 4],
    /// 1 / |U_kk|^2
    ins: [f64; 4],
}

impl Lu4 {
    /// Factor `h` in place (left as `solve4` leaves it). None when a pivot is not above 1e-15 of
    /// the largest |re| + |im| of H, or when the pivots' spread (smallest / largest) falls below
    /// `max_spread` (0 accepts any nonzero pivot: [`Lu4::near_singular`]).
    #[inline(always)]
    fn factor(h: &mut [[C64; 4]; 4], max_spread: f64) -> Option<Lu4> {
        let mut scale = 0.0f64;
        for row in h.iter() {
            for v in row.iter() {
                scale = scale.max(mag(*v));
            }
        }
        let tiny = scale * 1e-15;
        // the pivots' spread bounds the condition number from below: at an undamped resonance the last
        // pivot is rounding noise (1e-16 of the others), which must not pass as a huge response; a spread
        // beyond 1e10 (a damping ratio below ~1e-10) is treated as singular
        let (mut pmin, mut pmax) = (f64::INFINITY, 0.0f64);
        let mut lu = Lu4 { u: [[C64::new(0.0, 0.0); 4]; 4], piv: [0, 1, 2, 3], mult: [[C64::new(0.0, 0.0); 4]; 4], ins: [0.0; 4] };
        for k in 0..4 {
            // pivot
            let mut p = k;
            let mut best = mag(h[k][k]);
            for i in (k + 1)..4 {
                let v = mag(h[i][k]);
                if v > best {
                    best = v;
                    p = i;
                }
            }
            pmin = pmin.min(best);
            pmax = pmax.max(best);
            if !(best > tiny) || pmin < max_spread * pmax {
                return None;
            }
            lu.piv[k] = p;
            if p != k {
                h.swap(p, k);
            }
            // 1 / U_kk from one division (also used by the back substitution): the same operations
            // as the lanes' `elim_step`, so both give the same bits
            let d = h[k][k];
            lu.ins[k] = 1.0 / d.norm_sqr();
            let inv = C64::new(d.re * lu.ins[k], 0.0 - d.im * lu.ins[k]);
            for i in (k + 1)..4 {
                let f = h[i][k] * inv;
                if f == C64::new(0.0, 0.0) {
                    continue;
                }
                lu.mult[k][i] = f;
                for j in (k + 1)..4 {
                    let t = h[k][j];
                    h[i][j] -= f * t;
                }
            }
        }
        lu.u = *h;
        Some(lu)
    }

    /// The factors of `h` as [`solve4_near_singular`] forms them (only a zero pivot fails).
    ///
    /// ```
    /// use rotorid_core::forced::{solve4_near_singular, Lu4};
    /// use rotorid_core::C64;
    /// let z = |re: f64, im: f64| C64::new(re, im);
    /// let h = [[z(4.0, 1.0), z(1.0, 0.0), z(0.0, 0.5), z(0.0, 0.0)],
    ///          [z(1.0, 0.0), z(3.0, -1.0), z(0.0, 0.0), z(0.2, 0.0)],
    ///          [z(0.0, 0.5), z(0.0, 0.0), z(5.0, 0.0), z(1.0, 1.0)],
    ///          [z(0.0, 0.0), z(0.2, 0.0), z(1.0, 1.0), z(2.0, 0.0)]];
    /// let lu = Lu4::near_singular(&mut h.clone()).unwrap();
    /// let mut x = [z(1.0, 0.0), z(0.0, 1.0), z(2.0, 0.0), z(0.0, 0.0)];
    /// let mut y = x;
    /// lu.solve(&mut x);
    /// solve4_near_singular(&mut h.clone(), &mut y);
    /// assert_eq!(x, y);
    /// ```
    #[inline(always)]
    pub fn near_singular(h: &mut [[C64; 4]; 4]) -> Option<Lu4> {
        Lu4::factor(h, 0.0)
    }

    /// Solve H x = b in place (`b`: 4 values): the exchanges and updates of each step, then
    /// back substitution x_k = (b_k - sum_{j>k} U_kj x_j) / U_kk, the division as
    /// (a + j b) (c - j d) / (c^2 + d^2) with the step's 1 / (c^2 + d^2).
    #[inline(always)]
    pub fn solve(&self, b: &mut [C64]) {
        for k in 0..4 {
            b.swap(self.piv[k], k);
            for i in (k + 1)..4 {
                let f = self.mult[k][i];
                if f == C64::new(0.0, 0.0) {
                    continue;
                }
                let t = b[k];
                b[i] -= f * t;
            }
        }
        for k in (0..4).rev() {
            let mut s = b[k];
            for j in (k + 1)..4 {
                s -= self.u[k][j] * b[j];
            }
            let d = self.u[k][k];
            b[k] = C64::new((s.re * d.re + s.im * d.im) * self.ins[k], (s.im * d.re - s.re * d.im) * self.ins[k]);
        }
    }
}

/// Dynamic stiffness H at one point (M and G precomputed by the caller).
#[inline(always)]
pub fn dynamic_stiffness(rotor: &Rotor, m: &[[f64; 4]; 4], g: &[[f64; 4]; 4], kb: &[f64], cb: &[f64], spin: f64, w: f64) -> [[C64; 4]; 4] {
    let k = assemble(kb, rotor.l1, rotor.l2);
    let c = assemble(cb, rotor.l1, rotor.l2);
    let mut h = [[C64::new(0.0, 0.0); 4]; 4];
    for i in 0..4 {
        for j in 0..4 {
            h[i][j] = C64::new(k[i][j] - w * w * m[i][j], w * spin * g[i][j] + w * c[i][j]);
        }
    }
    h
}

/// For every point i: solve H_i q = F_i for `nrhs` force vectors, with
/// H_i = K_i - w_i^2 M + j w_i (C_i + Omega_i G).
///
/// `kb`, `cb`: (n, 8) or (1, 8) broadcast, order [bearing][i][j]; `spin` (Omega), `w`: (n,),
/// rad/s; `force`: (n, nrhs, 4) or (1, nrhs, 4) broadcast; `out`: (n, nrhs, 4). Returns the
/// number of singular points (their output is NaN).
///
/// The points are solved 16 at a time in SIMD lanes (AVX2 or AVX-512 chosen at run time), each
/// lane with its own pivots, or, on AVX-512 with one right-hand side and shared bearings, 8 at a
/// time on registers ([`registers`]); the results are those of [`dynamic_stiffness`] + [`solve4`]
/// point by point (up to the sign of an exact zero).
#[allow(clippy::too_many_arguments)]
pub fn forced_response(
    rotor: &Rotor,
    kb: &[f64],
    cb: &[f64],
    spin: &[f64],
    w: &[f64],
    force: &[C64],
    nrhs: usize,
    out: &mut [C64],
) -> Result<usize, CoreError> {
    forced_response_with(rotor, kb, cb, spin, w, force, nrhs, Gain::One, None, out)
}

/// [`forced_response`] with the force of point i scaled by `gain[i]`: q_i = gain_i H_i^-1 F,
/// e.g. an imbalance (F = generalized imbalance vector, gain = Omega^2) without building the
/// (n, 4) force array. `gain`: (n,). Each chunk of points is scaled while it is in cache.
#[allow(clippy::too_many_arguments)]
pub fn forced_response_scaled(
    rotor: &Rotor,
    kb: &[f64],
    cb: &[f64],
    spin: &[f64],
    w: &[f64],
    force: &[C64],
    nrhs: usize,
    gain: &[f64],
    out: &mut [C64],
) -> Result<usize, CoreError> {
    forced_response_with(rotor, kb, cb, spin, w, force, nrhs, Gain::PerPoint(gain), None, out)
}

/// The synchronous response to an imbalance at every speed Omega_i of `spin`: w_i = Omega_i and
/// q_i = Omega_i^2 H_i^-1 F (eq. 13-14 with F the generalized imbalance vector of eq. 4), i.e.
/// [`forced_response_scaled`] with `w = spin` and `gain = spin^2`, the gains formed chunk by chunk
/// (the caller builds no array of w or of Omega^2).
pub fn forced_response_imbalance(rotor: &Rotor, kb: &[f64], cb: &[f64], spin: &[f64], force: &[C64], nrhs: usize, out: &mut [C64]) -> Result<usize, CoreError> {
    forced_response_with(rotor, kb, cb, spin, spin, force, nrhs, Gain::SpinSquared, None, out)
}

/// The general form of the forced responses above: q_i = T (g_i H_i^-1 F_i) with the gains
/// `gain` and, with `planes` = Some(t), every solution moved to another pair of measurement planes
/// by the real 2x2 t = [T11, T12, T21, T22] (report eq. 19, [`crate::model::planes_point`]; e.g.
/// from the bearings to the probe planes), chunk by chunk while it is in cache: the values of
/// [`crate::model::apply_planes`] on the response at the bearings, without a second pass over it.
#[allow(clippy::too_many_arguments)]
pub fn forced_response_with(
    rotor: &Rotor,
    kb: &[f64],
    cb: &[f64],
    spin: &[f64],
    w: &[f64],
    force: &[C64],
    nrhs: usize,
    gain: Gain,
    planes: Option<&[f64; 4]>,
    out: &mut [C64],
) -> Result<usize, CoreError> {
    if let Gain::PerPoint(g) = gain {
        expect_len("gain", g, w.len())?;
    }
    check_forced(kb, cb, spin, w, force, nrhs, out)?;
    Ok(forced_kernel(rotor, kb, cb, spin, w, force, nrhs, gain, planes, out))
}

/// The scaling of each point's solution: q_i = g_i H_i^-1 F_i.
#[derive(Clone, Copy, Debug)]
pub enum Gain<'a> {
    /// g_i = 1 (forces per point as given)
    One,
    /// g_i = `gain[i]`, (n,)
    PerPoint(&'a [f64]),
    /// g_i = Omega_i^2 from `spin` (an imbalance; no array of gains is built)
    SpinSquared,
}

/// The argument checks of [`forced_response_with`] (and of the pedestal forced response).
pub(crate) fn check_forced(kb: &[f64], cb: &[f64], spin: &[f64], w: &[f64], force: &[C64], nrhs: usize, out: &[C64]) -> Result<(), CoreError> {
    let n = w.len();
    if nrhs == 0 {
        return Err(CoreError::value("nrhs", "must be at least 1 (one force vector per point)"));
    }
    expect_len("spin", spin, n)?;
    expect_len_or_broadcast("k", kb, 8, product("k", &[n, 8])?)?;
    expect_len_or_broadcast("c", cb, 8, product("c", &[n, 8])?)?;
    expect_len_or_broadcast("force", force, 4 * nrhs, product("force", &[n, nrhs, 4])?)?;
    expect_len("out", out, product("out", &[n, nrhs, 4])?)?;
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Lane-parallel kernel: G = 2 L points in lock-step.
//
// The points are processed in groups of G. Each group goes through lane loops over the lanes
// whose body is the computation of one point written without branches (the pivot choice and the
// row exchanges are selects), so that LLVM's loop vectorizer turns every scalar operation of the
// body into one SIMD operation over the lanes (4 lanes per AVX2 register, 8 per AVX-512 register).
// The body performs exactly the IEEE operations of `dynamic_stiffness` + `solve4` in the same order
// (no fused multiply-adds), so every lane reproduces the per-point solution: same pivots, same
// singular points, same values. The only difference is that `solve4` skips an elimination when its
// multiplier is exactly zero, which can only change the sign of an exact zero. Lane loop 1 runs
// over l = 0..L (in sweeps of one register's width, [`sweeps`]) and computes lanes l and l + L
// in its body, one step of each in turn.

/// Points per parallel task.
const CHUNK: usize = 1024;
/// Below this many points one thread is faster than waking the pool.
const SERIAL_BELOW: usize = 2048;
/// Smallest admissible ratio min |pivot| / max |pivot| (the rule of [`solve4`]).
const MAX_SPREAD: f64 = 1e-10;

/// Arguments of one batched forced response, shared by every chunk.
struct Batch<'a> {
    rotor: Rotor,
    m: [[f64; 4]; 4],
    g: [[f64; 4]; 4],
    kb: &'a [f64],
    cb: &'a [f64],
    spin: &'a [f64],
    w: &'a [f64],
    force: &'a [C64],
    nrhs: usize,
    /// the scaling of each solution, applied to each lane's values as they are stored
    gain: Gain<'a>,
    /// eq. 19 transform of each solution (after the gain), or None
    planes: Option<[f64; 4]>,
    /// bearing stiffness, damping, forces shared by all points
    kbc: bool,
    cbc: bool,
    fbc: bool,
}

impl<'a> Batch<'a> {
    #[allow(clippy::too_many_arguments)]
    fn new(rotor: &Rotor, kb: &'a [f64], cb: &'a [f64], spin: &'a [f64], w: &'a [f64], force: &'a [C64], nrhs: usize, gain: Gain<'a>, planes: Option<&[f64; 4]>) -> Self {
        let n = w.len();
        Batch {
            rotor: *rotor,
            m: rotor.mass_matrix(),
            g: rotor.gyro_matrix(),
            kb,
            cb,
            spin,
            w,
            force,
            nrhs,
            gain,
            planes: planes.copied(),
            kbc: kb.len() == 8,
            cbc: cb.len() == 8,
            fbc: force.len() == nrhs * 4 && n != 1,
        }
    }

    /// Point `i` alone through [`dynamic_stiffness`] and [`solve4`], then its gain and plane
    /// transform: the reference the lanes reproduce, and the path of groups holding a non-finite
    /// number. Returns true if singular.
    fn point(&self, i: usize, o: &mut [C64]) -> bool {
        let s = 4 * self.nrhs;
        o.copy_from_slice(if self.fbc { self.force } else { &self.force[i * s..(i + 1) * s] });
        let ki = if self.kbc { 0 } else { 8 * i };
        let ci = if self.cbc { 0 } else { 8 * i };
        let mut h = dynamic_stiffness(&self.rotor, &self.m, &self.g, &self.kb[ki..ki + 8], &self.cb[ci..ci + 8], self.spin[i], self.w[i]);
        let singular = !solve4(&mut h, o);
        let g = match self.gain {
            Gain::One => None,
            Gain::PerPoint(g) => Some(g[i]),
            Gain::SpinSquared => Some(self.spin[i] * self.spin[i]),
        };
        for p in o.chunks_exact_mut(4) {
            let v = self.finish(g, [p[0], p[1], p[2], p[3]]);
            p.copy_from_slice(&v);
        }
        singular
    }

    /// One solution times its gain `g`, then moved by the plane transform: the operations of the
    /// per-point path and of the lanes' scatter alike (so both give the same bits).
    #[inline(always)]
    fn finish(&self, g: Option<f64>, mut v: [C64; 4]) -> [C64; 4] {
        if let Some(g) = g {
            v.iter_mut().for_each(|x| *x *= g);
        }
        match &self.planes {
            Some(t) => planes_point(t, v),
            None => v,
        }
    }

    /// The gains of the points `idx` as lanes (None for unit gains).
    #[inline(always)]
    fn gain_lanes(&self, idx: &[usize; G], spin: V) -> Option<V> {
        match self.gain {
            Gain::One => None,
            Gain::PerPoint(g) => Some(crate::lanes::V(std::array::from_fn(|l| g[idx[l]]))),
            Gain::SpinSquared => Some(spin * spin),
        }
    }
}

/// Inputs of one group, lane-major: w, Omega and the 8 stiffness and 8 damping coefficients.
struct GroupIn {
    w: V,
    spin: V,
    k: [V; 8],
    c: [V; 8],
}

/// The eliminations of the G matrices of a group, as left by [`elim_step`]: U in the upper
/// triangle of `h`, below it the multiplier of each row at the step that eliminated it, `piv[k]`
/// the row (as f64) exchanged with row k at step k, `ins[k]` = 1 / |U_kk|^2; the singular lanes, and
/// the lanes whose H holds a non-finite number.
struct LaneLu {
    h: [[Z; 4]; 4],
    ins: [V; 4],
    piv: [V; 4],
    bad: [bool; G],
    finite: [bool; G],
}

impl LaneLu {
    fn new() -> Self {
        LaneLu { h: [[Z::zero(); 4]; 4], ins: [V::zero(); 4], piv: [V::zero(); 4], bad: [false; G], finite: [true; G] }
    }
}

/// Gaussian elimination of one matrix, in the state the steps share.
struct Elim {
    a: [[C64; 4]; 4],
    ins: [f64; 4],
    piv: [f64; 4],
    tiny: f64,
    pmin: f64,
    pmax: f64,
    bad: bool,
    /// some step's pivot is not on the diagonal (set by the exchange-free steps, which then
    /// leave the factors unusable: the lane is factored again with exchanges)
    exchange: bool,
}

impl Elim {
    /// The state before step 0, and sum_ij |H_ij| (finite iff every entry of H is, short of an
    /// overflow).
    #[inline(always)]
    fn new(h: [[C64; 4]; 4]) -> (Elim, f64) {
        let mut scale = 0.0f64;
        let mut total = 0.0f64;
        for row in h.iter() {
            for v in row.iter() {
                let m = mag(*v);
                scale = if m > scale { m } else { scale };
                total += m;
            }
        }
        (Elim { a: h, ins: [0.0; 4], piv: [0.0; 4], tiny: scale * 1e-15, pmin: f64::INFINITY, pmax: 0.0, bad: false, exchange: false }, total)
    }
}

/// Step K of the LU factorization with partial pivoting of one matrix, as `solve4` but without
/// branches (steps 0 to 3 in order, after [`Elim::new`]).
///
/// Step k: the pivot is the first row i >= k of largest |re| + |im| in column k (strict `>` over
/// i = k+1..3 against the running best), and rows k and p are exchanged by selects (columns
/// k..3; columns < k hold multipliers, which the exchange in `solve4` moves but never reads
/// again). The matrix is singular when a pivot is not > 1e-15 max_ij |H_ij|, or when the running
/// min |pivot| < 1e-10 max |pivot| (for a forced response a condition number beyond ~1e10, i.e. a
/// damping ratio below ~1e-10 at a resonance). Multipliers f_i = H_ik (1 / H_kk) with
/// 1 / (c + j d) = (c - j d) r, r = 1 / (c^2 + d^2) (one division per step, r kept for the back
/// substitution; `solve4` does the same, so both give the same bits), then H_ij -= f_i H_kj
/// for i, j > k, the multiplier f_i being kept in place of H_ik.
///
/// `EXCHANGE` false: the step as it is when the pivot is on the diagonal (no row exchange, no
/// selects), recording in `e.exchange` whether some row below would have been chosen instead.
/// When no step records one, the factors, pivots and flags are those of the step with exchanges,
/// bit for bit (the exchanges would all have been of a row with itself); when one does, they are
/// not, and the lane is factored again with `EXCHANGE` true.
#[inline(always)]
fn elim_step<const K: usize, const EXCHANGE: bool>(e: &mut Elim) {
    let a = &mut e.a;
    let diag = mag(a[K][K]);
    let mut best = diag;
    let mut p = K as f64;
    for i in (K + 1)..4 {
        let v = mag(a[i][K]);
        let gt = v > best;
        if EXCHANGE {
            best = if gt { v } else { best };
            p = if gt { i as f64 } else { p };
        } else {
            // a tie too: the first of equal rows is the pivot, which depends on the row order
            e.exchange |= !(v < diag);
        }
    }
    e.pmin = if best < e.pmin { best } else { e.pmin };
    e.pmax = if best > e.pmax { best } else { e.pmax };
    e.bad |= !(best > e.tiny) | (e.pmin < MAX_SPREAD * e.pmax);
    e.piv[K] = p;
    if EXCHANGE && K < 3 {
        let rk = a[K];
        for i in (K + 1)..4 {
            let t = p == i as f64;
            for j in K..4 {
                let ai = a[i][j];
                a[K][j] = if t { ai } else { a[K][j] };
                a[i][j] = if t { rk[j] } else { ai };
            }
        }
    }
    let d = a[K][K];
    let ins = 1.0 / d.norm_sqr();
    e.ins[K] = ins;
    let inv = C64::new(d.re * ins, 0.0 - d.im * ins);
    for i in (K + 1)..4 {
        let f = a[i][K] * inv;
        a[i][K] = f;
        for j in (K + 1)..4 {
            let t = a[K][j];
            a[i][j] -= f * t;
        }
    }
}

/// Solve H q = b with the elimination of [`elim_step`]: its exchanges and eliminations applied to
/// b step by step (b_i -= f_i b_k after exchanging b_k and b_p), then back substitution
/// q_k = (b_k - sum_{j>k} U_kj q_j) / U_kk, the division as (a + j b) / (c + j d) =
/// ((a c + b d) + j (b c - a d)) r with the step's r = 1 / (c^2 + d^2): 4 divisions per point
/// instead of 14 (5 % less time per forced response, median of 20 whole-process pairs of
/// `examples/forced_points`).
#[inline(always)]
fn substitute(a: &[[C64; 4]; 4], ins: &[f64; 4], piv: &[f64; 4], b: &mut [C64; 4]) {
    forward_step::<0, true>(a, piv, b);
    forward_step::<1, true>(a, piv, b);
    forward_step::<2, true>(a, piv, b);
    back_step::<3>(a, ins, b);
    back_step::<2>(a, ins, b);
    back_step::<1>(a, ins, b);
    back_step::<0>(a, ins, b);
}

/// `EXCHANGE` false: the factors come from exchange-free steps (`piv[K]` = K, nothing to swap).
#[inline(always)]
fn forward_step<const K: usize, const EXCHANGE: bool>(a: &[[C64; 4]; 4], piv: &[f64; 4], b: &mut [C64; 4]) {
    if EXCHANGE {
        let bk = b[K];
        for i in (K + 1)..4 {
            let t = piv[K] == i as f64;
            let bi = b[i];
            b[K] = if t { bi } else { b[K] };
            b[i] = if t { bk } else { bi };
        }
    }
    for i in (K + 1)..4 {
        let t = b[K];
        b[i] -= a[i][K] * t;
    }
}

#[inline(always)]
fn back_step<const K: usize>(a: &[[C64; 4]; 4], ins: &[f64; 4], b: &mut [C64; 4]) {
    let mut s = b[K];
    for j in (K + 1)..4 {
        s -= a[K][j] * b[j];
    }
    let (c, d) = (a[K][K].re, a[K][K].im);
    b[K] = C64::new((s.re * c + s.im * d) * ins[K], (s.im * c - s.re * d) * ins[K]);
}

#[inline(always)]
fn lane_get(z: &[Z; 4], l: usize) -> [C64; 4] {
    let mut o = [C64::new(0.0, 0.0); 4];
    for d in 0..4 {
        o[d] = C64::new(z[d].re.0[l], z[d].im.0[l]);
    }
    o
}

#[inline(always)]
fn lane_put(z: &mut [Z; 4], l: usize, v: &[C64; 4]) {
    for d in 0..4 {
        z[d].re.0[l] = v[d].re;
        z[d].im.0[l] = v[d].im;
    }
}

/// Lane loop 1: H = K - w^2 M + j w (C + Omega G) of every lane (`dynamic_stiffness`), its
/// factors (stored in `lu` for further right-hand sides if `KEEP`) and the solution q of the
/// first right-hand side f, in sweeps of `W` lanes ([`sweeps`]).
///
/// Each sweep runs first without row exchanges ([`elim_step`] with `EXCHANGE` false), which is
/// the elimination with partial pivoting itself wherever every pivot is on the diagonal (the
/// usual case: H's rows are ordered with the direct terms of x1, x2, y1, y2 on it); a sweep in
/// which some lane needed an exchange runs again with exchanges. Either way the results are
/// those of the pivoting elimination, bit for bit.
#[inline(always)]
fn factor_solve_lanes<const KEEP: bool, const W: usize>(b: &Batch, gi: &GroupIn, f: &[Z; 4], lu: &mut LaneLu, q: &mut [Z; 4]) {
    for (lo, hi) in sweeps::<W>(L) {
        let mut exchange = [true; W];
        if !KEEP {
            factor_solve_sweep::<KEEP, W, false>(b, gi, f, lu, q, lo, hi, &mut exchange);
        }
        if exchange.iter().any(|&x| x) {
            #[cfg(test)]
            tests::SWEEPS_WITH_EXCHANGES.with(|c| c.set(c.get() + 1));
            factor_solve_sweep::<KEEP, W, true>(b, gi, f, lu, q, lo, hi, &mut exchange);
        }
        #[cfg(test)]
        tests::SWEEPS.with(|c| c.set(c.get() + 1));
    }
}

/// Lanes lo..hi and lo + L..hi + L of [`factor_solve_lanes`], with or without row exchanges;
/// `exchange[l - lo]`: lane l or l + L needed one (set only when `EXCHANGE` is false).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn factor_solve_sweep<const KEEP: bool, const W: usize, const EXCHANGE: bool>(
    b: &Batch,
    gi: &GroupIn,
    f: &[Z; 4],
    lu: &mut LaneLu,
    q: &mut [Z; 4],
    lo: usize,
    hi: usize,
    exchange: &mut [bool; W],
) {
    for l0 in lo..hi {
        let l1 = l0 + L;
        let (mut e0, t0) = Elim::new(lane_h(b, gi, l0));
        let (mut e1, t1) = Elim::new(lane_h(b, gi, l1));
        let mut x0 = lane_get(f, l0);
        let mut x1 = lane_get(f, l1);
        eliminate_pair::<EXCHANGE>(&mut e0, &mut e1, &mut x0, &mut x1);
        if !EXCHANGE {
            exchange[l0 - lo] = e0.exchange | e1.exchange;
        }
        solve_pair::<EXCHANGE>(&e0, &e1, &mut x0, &mut x1);
        keep_lane::<KEEP>(lu, q, l0, &e0, t0, &x0);
        keep_lane::<KEEP>(lu, q, l1, &e1, t1, &x1);
    }
}

/// Two matrices (`e0`, `e1` as [`Elim::new`] leaves them) eliminated step by step in alternation
/// (one matrix's dependency chain overlaps the other's), their right-hand sides `x0`, `x1`
/// reordered with them. `EXCHANGE` false: on rows (Fx, Mx, Fy, My), the order in which the pivots
/// of a rotor on bearings usually fall on the diagonal, without exchanges (see [`elim_step`]).
#[inline(always)]
fn eliminate_pair<const EXCHANGE: bool>(e0: &mut Elim, e1: &mut Elim, x0: &mut [C64; 4], x1: &mut [C64; 4]) {
    if !EXCHANGE {
    e0.a.swap(1, 2);
    e1.a.swap(1, 2);
    x0.swap(1, 2);
    x1.swap(1, 2);
    }
    elim_step::<0, EXCHANGE>(e0);
    elim_step::<0, EXCHANGE>(e1);
    elim_step::<1, EXCHANGE>(e0);
    elim_step::<1, EXCHANGE>(e1);
    elim_step::<2, EXCHANGE>(e0);
    elim_step::<2, EXCHANGE>(e1);
    elim_step::<3, EXCHANGE>(e0);
    elim_step::<3, EXCHANGE>(e1);
}

/// The right-hand sides of [`eliminate_pair`]'s two matrices solved, in alternation.
#[inline(always)]
fn solve_pair<const EXCHANGE: bool>(e0: &Elim, e1: &Elim, x0: &mut [C64; 4], x1: &mut [C64; 4]) {
    forward_step::<0, EXCHANGE>(&e0.a, &e0.piv, x0);
    forward_step::<0, EXCHANGE>(&e1.a, &e1.piv, x1);
    forward_step::<1, EXCHANGE>(&e0.a, &e0.piv, x0);
    forward_step::<1, EXCHANGE>(&e1.a, &e1.piv, x1);
    forward_step::<2, EXCHANGE>(&e0.a, &e0.piv, x0);
    forward_step::<2, EXCHANGE>(&e1.a, &e1.piv, x1);
    back_step::<3>(&e0.a, &e0.ins, x0);
    back_step::<3>(&e1.a, &e1.ins, x1);
    back_step::<2>(&e0.a, &e0.ins, x0);
    back_step::<2>(&e1.a, &e1.ins, x1);
    back_step::<1>(&e0.a, &e0.ins, x0);
    back_step::<1>(&e1.a, &e1.ins, x1);
    back_step::<0>(&e0.a, &e0.ins, x0);
    back_step::<0>(&e1.a, &e1.ins, x1);
}

/// H of lane `l` (`dynamic_stiffness`).
#[inline(always)]
fn lane_h(b: &Batch, gi: &GroupIn, l: usize) -> [[C64; 4]; 4] {
    let mut kl = [0.0; 8];
    let mut cl = [0.0; 8];
    for c in 0..8 {
        kl[c] = gi.k[c].0[l];
        cl[c] = gi.c[c].0[l];
    }
    dynamic_stiffness(&b.rotor, &b.m, &b.g, &kl, &cl, gi.spin.0[l], gi.w.0[l])
}

/// The end of lane `l` in lane loop 1: its factors (if `KEEP`), flags and solution.
#[inline(always)]
fn keep_lane<const KEEP: bool>(lu: &mut LaneLu, q: &mut [Z; 4], l: usize, e: &Elim, total: f64, x: &[C64; 4]) {
    if KEEP {
        for i in 0..4 {
            for j in 0..4 {
                lu.h[i][j].re.0[l] = e.a[i][j].re;
                lu.h[i][j].im.0[l] = e.a[i][j].im;
            }
            lu.ins[i].0[l] = e.ins[i];
            lu.piv[i].0[l] = e.piv[i];
        }
    }
    lu.bad[l] = e.bad;
    lu.finite[l] = total.is_finite();
    lane_put(q, l, x);
}

#[inline(always)]
fn substitute_lane(a: &[[C64; 4]; 4], ins: &[f64; 4], piv: &[f64; 4], f: &[Z; 4], q: &mut [Z; 4], l: usize) {
    let mut x = lane_get(f, l);
    substitute(a, ins, piv, &mut x);
    lane_put(q, l, &x);
}

/// The lanes 0..n in sweeps of `W` consecutive lanes: the lane loops run sweep by sweep, so that
/// LLVM vectorizes each sweep with one register per value (W = 8 for AVX-512, 4 for AVX2, 2 for
/// the baseline). A sweep wider than the registers (8 lanes on AVX2's 4-wide registers) keeps two
/// or more registers live for every value of the elimination and spills: at AVX2 the 4-lane
/// sweeps take 12 % less time per point than 8-lane ones (35.3 against 40.2 ns, best of 12
/// interleaved runs of `examples/forced_points 4096 200 imbalance`). The order of the lanes, and so
/// the result, does not depend on W.
#[inline(always)]
fn sweeps<const W: usize>(n: usize) -> impl Iterator<Item = (usize, usize)> {
    (0..n).step_by(W).map(move |lo| (lo, (lo + W).min(n)))
}

/// Right-hand sides per call of lane loop 2.
const MAX_RHS: usize = 3;

/// Lane loop 2: the solutions q[t] of R further right-hand sides f[t] with the factors of lane
/// loop 1 (R independent substitutions in one body, for the instruction-level parallelism).
#[inline(always)]
fn solve_lanes<const R: usize, const W: usize>(lu: &LaneLu, f: &[[Z; 4]; MAX_RHS], q: &mut [[Z; 4]; MAX_RHS]) {
    for (lo, hi) in sweeps::<W>(G) {
        for l in lo..hi {
            let mut a = [[C64::new(0.0, 0.0); 4]; 4];
            let mut ins = [0.0; 4];
            let mut piv = [0.0; 4];
            for i in 0..4 {
                for j in 0..4 {
                    a[i][j] = C64::new(lu.h[i][j].re.0[l], lu.h[i][j].im.0[l]);
                }
                ins[i] = lu.ins[i].0[l];
                piv[i] = lu.piv[i].0[l];
            }
            // written out (not a loop over t): the lane loop must stay the innermost loop
            substitute_lane(&a, &ins, &piv, &f[0], &mut q[0], l);
            if R > 1 {
                substitute_lane(&a, &ins, &piv, &f[1], &mut q[1], l);
            }
            if R > 2 {
                substitute_lane(&a, &ins, &piv, &f[2], &mut q[2], l);
            }
        }
    }
}

/// Right-hand side `r` of the points `idx` as lanes.
#[inline(always)]
fn load_force(b: &Batch, idx: &[usize; G], r: usize, f: &mut [Z; 4]) {
    if b.fbc {
        for d in 0..4 {
            let v = b.force[4 * r + d];
            f[d] = Z { re: V::splat(v.re), im: V::splat(v.im) };
        }
    } else {
        for l in 0..G {
            let o = (idx[l] * b.nrhs + r) * 4;
            let src = &b.force[o..o + 4];
            for d in 0..4 {
                f[d].re.0[l] = src[d].re;
                f[d].im.0[l] = src[d].im;
            }
        }
    }
}

/// Solution `r` of the first `nl` lanes, times its gain and moved by the plane transform of `b`,
/// into the points g0.. of `out` (NaN for singular lanes). The gain and the transform are applied
/// to each lane's values as they are scattered, by the per-point path's own [`Batch::finish`], so
/// the same bits, and no second pass over `out` (scaling a copy of the lane
/// vectors before the scatter took 26-35 more instructions per point).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn store(b: &Batch, gain: Option<V>, out: &mut [C64], bad: &[bool; G], g0: usize, nl: usize, r: usize, q: &[Z; 4]) {
    let stride = 4 * b.nrhs;
    let dst = &mut out[g0 * stride..(g0 + nl) * stride];
    for (l, p) in dst.chunks_exact_mut(stride).enumerate() {
        let v = b.finish(gain.map(|g| g.0[l]), lane_get(q, l));
        let p = &mut p[4 * r..4 * r + 4];
        p.copy_from_slice(&v);
        if bad[l] {
            p.fill(C64::new(f64::NAN, f64::NAN));
        }
    }
}

/// Points `start..start + out.len() / (4 nrhs)`, G at a time: gathers the inputs of a group into
/// lanes, runs the lane loops `factor_solve` and `solve` (compiled for the instruction set of the
/// caller) and scatters the solutions. Tail lanes repeat the last point and are not stored.
/// Returns the number of singular points.
#[inline(always)]
fn forced_chunk<Fs, So>(b: &Batch, start: usize, out: &mut [C64], factor_solve: Fs, solve: So) -> usize
where
    Fs: Fn(&Batch, &GroupIn, &[Z; 4], &mut LaneLu, &mut [Z; 4], bool),
    So: Fn(&LaneLu, &[[Z; 4]; MAX_RHS], &mut [[Z; 4]; MAX_RHS], usize),
{
    let nrhs = b.nrhs;
    let stride = 4 * nrhs;
    let npts = out.len() / stride;
    let mut gi = GroupIn { w: V::zero(), spin: V::zero(), k: [V::zero(); 8], c: [V::zero(); 8] };
    for c in 0..8 {
        if b.kbc {
            gi.k[c] = V::splat(b.kb[c]);
        }
        if b.cbc {
            gi.c[c] = V::splat(b.cb[c]);
        }
    }
    let mut lu = LaneLu::new();
    let mut f = [[Z::zero(); 4]; MAX_RHS];
    let mut q = [[Z::zero(); 4]; MAX_RHS];
    let mut nbad = 0;
    for g0 in (0..npts).step_by(G) {
        let nl = G.min(npts - g0);
        let mut idx = [0usize; G];
        for l in 0..G {
            idx[l] = start + g0 + l.min(nl - 1);
        }
        if nl == G {
            gi.w.0.copy_from_slice(&b.w[start + g0..start + g0 + G]);
            gi.spin.0.copy_from_slice(&b.spin[start + g0..start + g0 + G]);
        } else {
            for l in 0..G {
                gi.w.0[l] = b.w[idx[l]];
                gi.spin.0[l] = b.spin[idx[l]];
            }
        }
        for (per_point, src, dst) in [(!b.kbc, b.kb, &mut gi.k), (!b.cbc, b.cb, &mut gi.c)] {
            if per_point {
                for l in 0..G {
                    let row = &src[8 * idx[l]..8 * idx[l] + 8];
                    for c in 0..8 {
                        dst[c].0[l] = row[c];
                    }
                }
            }
        }
        load_force(b, &idx, 0, &mut f[0]);
        factor_solve(b, &gi, &f[0], &mut lu, &mut q[0], nrhs > 1);
        // NaN or inf in H (or an overflowing sum): the per-point path, whose handling is the rule
        if !lu.finite.iter().all(|&x| x) {
            for l in 0..nl {
                let t = g0 + l;
                nbad += b.point(start + t, &mut out[t * stride..(t + 1) * stride]) as usize;
            }
            continue;
        }
        let gain = b.gain_lanes(&idx, gi.spin);
        store(b, gain, out, &lu.bad, g0, nl, 0, &q[0]);
        let mut r = 1;
        while r < nrhs {
            let m = MAX_RHS.min(nrhs - r);
            for t in 0..m {
                load_force(b, &idx, r + t, &mut f[t]);
            }
            solve(&lu, &f, &mut q, m);
            for t in 0..m {
                store(b, gain, out, &lu.bad, g0, nl, r + t, &q[t]);
            }
            r += m;
        }
        nbad += lu.bad[..nl].iter().filter(|&&x| x).count();
    }
    nbad
}

// The lane loops are separate functions per instruction set. They are called from closures
// written inside the chunk functions: a `#[target_feature]` function's `#[inline(never)]` holds
// at call sites compiled with the same features, and inlined into the group loop the lane loops
// would be unrolled instead of vectorized.

#[inline(never)]
fn factor_solve_baseline<const KEEP: bool>(b: &Batch, gi: &GroupIn, f: &[Z; 4], lu: &mut LaneLu, q: &mut [Z; 4]) {
    factor_solve_lanes::<KEEP, 2>(b, gi, f, lu, q)
}

#[inline(never)]
fn solve_baseline<const R: usize>(lu: &LaneLu, f: &[[Z; 4]; MAX_RHS], q: &mut [[Z; 4]; MAX_RHS]) {
    solve_lanes::<R, 2>(lu, f, q)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline(never)]
fn factor_solve_avx2<const KEEP: bool>(b: &Batch, gi: &GroupIn, f: &[Z; 4], lu: &mut LaneLu, q: &mut [Z; 4]) {
    factor_solve_lanes::<KEEP, 4>(b, gi, f, lu, q)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline(never)]
fn solve_avx2<const R: usize>(lu: &LaneLu, f: &[[Z; 4]; MAX_RHS], q: &mut [[Z; 4]; MAX_RHS]) {
    solve_lanes::<R, 4>(lu, f, q)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq,avx2,fma")]
#[inline(never)]
fn factor_solve_avx512<const KEEP: bool>(b: &Batch, gi: &GroupIn, f: &[Z; 4], lu: &mut LaneLu, q: &mut [Z; 4]) {
    factor_solve_lanes::<KEEP, 8>(b, gi, f, lu, q)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq,avx2,fma")]
#[inline(never)]
fn solve_avx512<const R: usize>(lu: &LaneLu, f: &[[Z; 4]; MAX_RHS], q: &mut [[Z; 4]; MAX_RHS]) {
    solve_lanes::<R, 8>(lu, f, q)
}

/// `forced_chunk` with the lane loops `$factor_solve::<KEEP>` and `$solve::<R>`, called from
/// closures of the calling function.
macro_rules! chunk_with {
    ($b:expr, $start:expr, $out:expr, $factor_solve:ident, $solve:ident) => {{
        let factor_solve = |b: &Batch, gi: &GroupIn, f: &[Z; 4], lu: &mut LaneLu, q: &mut [Z; 4], keep: bool| {
            if keep {
                $factor_solve::<true>(b, gi, f, lu, q)
            } else {
                $factor_solve::<false>(b, gi, f, lu, q)
            }
        };
        let solve = |lu: &LaneLu, f: &[[Z; 4]; MAX_RHS], q: &mut [[Z; 4]; MAX_RHS], m: usize| match m {
            1 => $solve::<1>(lu, f, q),
            2 => $solve::<2>(lu, f, q),
            _ => $solve::<3>(lu, f, q),
        };
        forced_chunk($b, $start, $out, factor_solve, solve)
    }};
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq,avx2,fma")]
fn forced_chunk_avx512(b: &Batch, start: usize, out: &mut [C64]) -> usize {
    // the common case on registers ([`registers`]): 14.5 -> 12.0 ns per point (imbalance) and
    // 15.2 -> 12.3 (at the probe planes), `examples/forced_points 4096 2000`, best of 5
    // interleaved runs, AMD EPYC of family 26
    if registers::serves(b) {
        let rest = |first: usize, o: &mut [C64]| chunk_with!(b, first, o, factor_solve_avx512, solve_avx512);
        // SAFETY: compiled for and called on AVX-512 CPUs only (the register kernel's intrinsics)
        return unsafe { registers::forced_chunk::<8, crate::identify::avx512::Avx512>(b, start, out, rest) };
    }
    chunk_with!(b, start, out, factor_solve_avx512, solve_avx512)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn forced_chunk_avx2(b: &Batch, start: usize, out: &mut [C64]) -> usize {
    // not the register kernel: with AVX2's 16 registers its 4 x 4 complex matrix spills, and it
    // took 18.0 against 16.1 ns per point (the lanes 4 wide; `examples/forced_points 4096 2000
    // imbalance`, best of 5 interleaved runs, AMD EPYC of family 26)
    chunk_with!(b, start, out, factor_solve_avx2, solve_avx2)
}

fn forced_chunk_baseline(b: &Batch, start: usize, out: &mut [C64]) -> usize {
    chunk_with!(b, start, out, factor_solve_baseline, solve_baseline)
}

/// Runtime dispatch to the widest SIMD the CPU has (same operations, same results).
fn forced_chunk_dispatch(b: &Batch, start: usize, out: &mut [C64]) -> usize {
    match crate::lanes::simd() {
        // SAFETY: simd() reports the CPU has the features these versions are compiled for.
        #[cfg(target_arch = "x86_64")]
        crate::lanes::Simd::Avx512 => unsafe { forced_chunk_avx512(b, start, out) },
        #[cfg(target_arch = "x86_64")]
        crate::lanes::Simd::Avx2 => unsafe { forced_chunk_avx2(b, start, out) },
        _ => forced_chunk_baseline(b, start, out),
    }
}

#[allow(clippy::too_many_arguments)]
pub(crate) fn forced_kernel(rotor: &Rotor, kb: &[f64], cb: &[f64], spin: &[f64], w: &[f64], force: &[C64], nrhs: usize, gain: Gain, planes: Option<&[f64; 4]>, out: &mut [C64]) -> usize {
    let b = Batch::new(rotor, kb, cb, spin, w, force, nrhs, gain, planes);
    let chunk = |start: usize, o: &mut [C64]| forced_chunk_dispatch(&b, start, o);
    if w.len() < SERIAL_BELOW {
        return chunk(0, out);
    }
    // tasks of CHUNK points, the calling thread working from the start (crate::par)
    let out = crate::par::Disjoint::new(out);
    // SAFETY: sum_tasks hands each chunk index j to one task
    crate::par::sum_tasks(w.len().div_ceil(CHUNK), |j| chunk(j * CHUNK, unsafe { out.chunk(j, CHUNK * 4 * nrhs) }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn cfg(cases: u32) -> ProptestConfig {
        ProptestConfig { cases, failure_persistence: None, ..ProptestConfig::default() }
    }

    /// Every point alone through `dynamic_stiffness` + `solve4` (the former per-point kernel).
    fn per_point(b: &Batch, out: &mut [C64]) -> usize {
        let s = 4 * b.nrhs;
        (0..b.w.len()).map(|i| b.point(i, &mut out[i * s..(i + 1) * s]) as usize).sum()
    }

    /// The lane kernel without SIMD dispatch (the path of CPUs without AVX2).
    fn lanes_baseline(b: &Batch, out: &mut [C64]) -> usize {
        forced_chunk_baseline(b, 0, out)
    }

    /// Largest |lane - reference| / max_point |reference| over all points, and whether every
    /// value is equal (`==`, or NaN in both).
    fn compare(lanes: &[C64], reference: &[C64], stride: usize) -> (f64, bool) {
        let mut worst = 0.0f64;
        let mut equal = true;
        for (pa, pb) in lanes.chunks(stride).zip(reference.chunks(stride)) {
            let scale = pb.iter().fold(0.0f64, |m, z| m.max(z.norm()));
            for (x, y) in pa.iter().zip(pb) {
                let nan = (x.re.is_nan(), x.im.is_nan(), y.re.is_nan(), y.im.is_nan());
                if nan.0 || nan.1 || nan.2 || nan.3 {
                    if nan != (true, true, true, true) {
                        worst = f64::INFINITY;
                        equal = false;
                    }
                    continue;
                }
                equal &= x == y;
                let d = (x - y).norm();
                worst = worst.max(if d == 0.0 { 0.0 } else { d / scale });
            }
        }
        (worst, equal)
    }

    fn rotors() -> impl Strategy<Value = Rotor> {
        (1.0f64..1000.0, 0.1f64..0.6, 0.0f64..1.5, 0.05f64..1.0, 0.05f64..1.0).prop_map(|(m, rg, ipr, l1, l2)| {
            let it = m * (rg * (l1 + l2)).powi(2);
            Rotor { m, it, ip: ipr * it, l1, l2 }
        })
    }

    /// Bearing coefficients [bearing][i][j]: direct terms 10^lo..10^hi, cross terms up to half of
    /// the smaller direct one.
    fn coefficients(lo: f64, hi: f64) -> impl Strategy<Value = [f64; 8]> {
        (proptest::collection::vec(lo..hi, 4), proptest::collection::vec(-0.5f64..0.5, 4)).prop_map(|(d, x)| {
            let mut v = [0.0; 8];
            for b in 0..2 {
                let (dx, dy) = (10f64.powf(d[2 * b]), 10f64.powf(d[2 * b + 1]));
                v[4 * b] = dx;
                v[4 * b + 3] = dy;
                v[4 * b + 1] = x[2 * b] * dx.min(dy);
                v[4 * b + 2] = x[2 * b + 1] * dx.min(dy);
            }
            v
        })
    }

    /// One batch's inputs: bearings shared or per point (scaled point by point), forces shared or
    /// per point, w from 0 to 5 times the bounce frequency, Omega/w in [-2, 2].
    #[derive(Debug, Clone)]
    struct Inputs {
        rotor: Rotor,
        kb: Vec<f64>,
        cb: Vec<f64>,
        spin: Vec<f64>,
        w: Vec<f64>,
        force: Vec<C64>,
        nrhs: usize,
    }

    fn inputs(max_n: usize) -> impl Strategy<Value = Inputs> {
        (1usize..max_n, 1usize..5, rotors(), coefficients(5.0, 8.0), coefficients(1.0, 4.5), any::<[bool; 3]>(), any::<u64>()).prop_map(
            |(n, nrhs, rotor, k, c, shared, seed)| {
                // small deterministic generator for the per-point values
                let mut state = seed | 1;
                let mut unit = move || {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    (state >> 11) as f64 / (1u64 << 53) as f64
                };
                let wn = (2.0 * (k[0] + k[3] + k[4] + k[7]) / 4.0 / rotor.m).sqrt();
                let w: Vec<f64> = (0..n).map(|_| 5.0 * wn * unit()).collect();
                let spin: Vec<f64> = w.iter().map(|&x| x * (4.0 * unit() - 2.0)).collect();
                let per_point = |v: &[f64; 8], unit: &mut dyn FnMut() -> f64| -> Vec<f64> {
                    (0..n).flat_map(|_| v.map(|x| x * (0.5 + unit()))).collect()
                };
                let kb = if shared[0] { k.to_vec() } else { per_point(&k, &mut unit) };
                let cb = if shared[1] { c.to_vec() } else { per_point(&c, &mut unit) };
                let nf = if shared[2] { nrhs * 4 } else { n * nrhs * 4 };
                let force = (0..nf).map(|_| C64::new(2.0 * unit() - 1.0, 2.0 * unit() - 1.0)).collect();
                Inputs { rotor, kb, cb, spin, w, force, nrhs }
            },
        )
    }

    /// Lane kernel (dispatched and baseline) and per-point path on the same inputs:
    /// (largest relative difference, all equal, singular counts equal, singular count).
    fn run(p: &Inputs) -> (f64, bool, bool, usize) {
        let n = p.w.len();
        let mut lanes = vec![C64::new(0.0, 0.0); n * p.nrhs * 4];
        let bad_lanes = forced_response(&p.rotor, &p.kb, &p.cb, &p.spin, &p.w, &p.force, p.nrhs, &mut lanes).unwrap();
        let b = Batch::new(&p.rotor, &p.kb, &p.cb, &p.spin, &p.w, &p.force, p.nrhs, Gain::One, None);
        let mut base = vec![C64::new(0.0, 0.0); lanes.len()];
        let bad_base = lanes_baseline(&b, &mut base);
        let mut reference = vec![C64::new(0.0, 0.0); lanes.len()];
        let bad_ref = per_point(&b, &mut reference);
        let (d1, e1) = compare(&lanes, &reference, 4 * p.nrhs);
        let (d2, e2) = compare(&base, &reference, 4 * p.nrhs);
        (d1.max(d2), e1 && e2, bad_lanes == bad_ref && bad_base == bad_ref, bad_ref)
    }

    thread_local! {
        /// Sweeps of the lane loop 1 run on this thread, and those of them run again with row
        /// exchanges (serial calls only: below SERIAL_BELOW points the caller does all the work).
        pub(super) static SWEEPS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
        pub(super) static SWEEPS_WITH_EXCHANGES: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
        /// Whole groups solved on registers ([`registers`]), and those handed to the lane path.
        pub(super) static REGISTER_GROUPS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
        pub(super) static GROUPS_TO_LANES: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
    }

    type Counter = std::thread::LocalKey<std::cell::Cell<usize>>;

    /// How much two of the counters above grow in one serial forced response.
    fn counts(p: &Inputs, a: &'static Counter, b: &'static Counter) -> (usize, usize) {
        let before = (a.with(|c| c.get()), b.with(|c| c.get()));
        let mut q = vec![C64::new(0.0, 0.0); p.w.len() * p.nrhs * 4];
        forced_response(&p.rotor, &p.kb, &p.cb, &p.spin, &p.w, &p.force, p.nrhs, &mut q).unwrap();
        (a.with(|c| c.get()) - before.0, b.with(|c| c.get()) - before.1)
    }

    /// (sweeps, sweeps run again with exchanges) of one serial forced response.
    fn sweep_counts(p: &Inputs) -> (usize, usize) {
        counts(p, &SWEEPS, &SWEEPS_WITH_EXCHANGES)
    }

    /// The exchange-free first pass: the NSF rotor on its bearings needs no row exchange at any
    /// speed (rows Fx, Mx, Fy, My), so no sweep runs twice; a bearing with one direct stiffness
    /// far below its cross-coupled ones puts a pivot off the diagonal, so sweeps run again; and
    /// both give the pivoting solve's values to the bit.
    /// (The bearing coefficients are given per point, all equal, so that the lane path serves
    /// the points rather than the register kernel, which takes shared ones; see the next test.)
    #[test]
    fn exchange_free_pass_covers_a_rotor_on_bearings_and_falls_back_otherwise() {
        let rotor = Rotor { m: 30.7, it: 0.62, ip: 0.062, l1: 0.146, l2: 0.137 };
        let k = [3.2e6, 4e5, -3e5, 2.9e6, 3.5e6, 2e5, -2e5, 3.1e6];
        let c = [2.1e3, 1e2, 1e2, 2.3e3, 2.2e3, 0.0, 0.0, 2.0e3];
        let n = 200;
        let w: Vec<f64> = (0..n).map(|i| 1.0 + 1500.0 * i as f64 / n as f64).collect();
        let force = vec![C64::new(1.0, 0.5); 4];
        let per_point = |v: &[f64]| -> Vec<f64> { (0..n).flat_map(|_| v.iter().copied()).collect() };
        let mut p = Inputs { rotor, kb: per_point(&k), cb: c.to_vec(), spin: w.clone(), w, force, nrhs: 1 };
        let (sweeps, again) = sweep_counts(&p);
        assert!(sweeps > 0 && again == 0, "{again} of {sweeps} sweeps ran again");
        let (diff, equal, same_count, _) = run(&p);
        assert!(diff == 0.0 && equal && same_count);
        p.kb = per_point(&[1e3, 4e6, -4e6, 1e3, 3.5e6, 2e5, -2e5, 3.1e6]);
        let (sweeps, again) = sweep_counts(&p);
        assert!(again > 0 && again <= sweeps);
        let (diff, equal, same_count, _) = run(&p);
        assert!(diff <= 1e-12 && equal && same_count);
    }

    /// H q = b by the steps of the lane loop: with exchanges on H as it is, or exchange-free on
    /// H with rows 1 and 2 swapped (None when a step found its diagonal not the unique largest).
    /// (the kernel's own sequence, `eliminate_pair` + `solve_pair`, with H as both matrices)
    fn solve_by_steps<const EXCHANGE: bool>(h: [[C64; 4]; 4], b: [C64; 4]) -> Option<[C64; 4]> {
        let ((mut e0, _), (mut e1, _)) = (Elim::new(h), Elim::new(h));
        let (mut x0, mut x1) = (b, b);
        eliminate_pair::<EXCHANGE>(&mut e0, &mut e1, &mut x0, &mut x1);
        solve_pair::<EXCHANGE>(&e0, &e1, &mut x0, &mut x1);
        assert_eq!(x0.map(|z| (z.re.to_bits(), z.im.to_bits())), x1.map(|z| (z.re.to_bits(), z.im.to_bits())));
        (EXCHANGE || !e0.exchange).then_some(x0)
    }

    proptest! {
        #![proptest_config(cfg(500))]

        /// Wherever each pivot of rows (Fx, Mx, Fy, My) is the unique largest candidate, the
        /// exchange-free steps give the pivoting solve's bits; else they decline. Random complex
        /// H with a diagonal boost of 10^0..10^2 after the row swap (so both cases occur).
        #[test]
        fn exchange_free_steps_give_the_pivoting_bits_or_decline(
            v in proptest::collection::vec(-1.0f64..1.0, 40), boost in 0.0f64..2.0)
        {
            let mut h = [[C64::new(0.0, 0.0); 4]; 4];
            for i in 0..4 {
                for j in 0..4 {
                    h[i][j] = C64::new(v[8 * i + 2 * j], v[8 * i + 2 * j + 1]);
                }
            }
            // the diagonal of the swapped rows: H[0][0], H[2][1], H[1][2], H[3][3]
            for (i, j) in [(0, 0), (2, 1), (1, 2), (3, 3)] {
                h[i][j] *= 10f64.powf(boost);
            }
            let b = [C64::new(v[32], v[33]), C64::new(v[34], v[35]), C64::new(v[36], v[37]), C64::new(v[38], v[39])];
            let pivoting = solve_by_steps::<true>(h, b).unwrap();
            if let Some(x) = solve_by_steps::<false>(h, b) {
                for (a, r) in x.iter().zip(&pivoting) {
                    prop_assert!(a.re.to_bits() == r.re.to_bits() && a.im.to_bits() == r.im.to_bits(), "{x:?} vs {pivoting:?}");
                }
            }
        }
    }

    proptest! {
        #![proptest_config(cfg(300))]

        /// Factors kept for later right-hand sides (`Lu4`): each solve satisfies H x = b to
        /// rounding, the kept factors solve as freshly formed ones do (to the bit: the modal
        /// analysis factors once for two solves), and `solve4_near_singular` fails exactly where
        /// they cannot be formed. Random H, some with zero entries, a zero row or rank one.
        #[test]
        fn kept_factors_solve_the_system(v in proptest::collection::vec(-1.0f64..1.0, 48), zeros in any::<u16>(),
                                         kind in 0usize..3) {
            let mut h = [[C64::new(0.0, 0.0); 4]; 4];
            for i in 0..4 {
                for j in 0..4 {
                    if zeros >> (4 * i + j) & 1 == 0 {
                        h[i][j] = C64::new(v[8 * i + 2 * j], v[8 * i + 2 * j + 1]);
                    }
                }
            }
            match kind {
                1 => h[2] = [C64::new(0.0, 0.0); 4],
                2 => for i in 1..4 { h[i] = h[0].map(|z| z * C64::new(i as f64, 0.5)); },
                _ => {}
            }
            let bs: Vec<[C64; 4]> = (0..2).map(|r| std::array::from_fn(|d| C64::new(v[32 + 8 * r + 2 * d], v[33 + 8 * r + 2 * d]))).collect();
            let lu = Lu4::near_singular(&mut h.clone());
            for b in &bs {
                let mut via = *b;
                prop_assert_eq!(solve4_near_singular(&mut h.clone(), &mut via), lu.is_some());
                let Some(lu) = &lu else { continue };
                let mut x = *b;
                lu.solve(&mut x);
                let fresh = Lu4::near_singular(&mut h.clone()).unwrap();
                let mut y = *b;
                fresh.solve(&mut y);
                for (a, r) in x.iter().zip(&y).chain(x.iter().zip(&via)) {
                    prop_assert!(a.re.to_bits() == r.re.to_bits() && a.im.to_bits() == r.im.to_bits());
                }
                // H x = b to rounding, against |H| |x| + |b| (a singular-to-rounding H gives a
                // huge x: the bound scales with it)
                for i in 0..4 {
                    let (mut r, mut size) = (b[i], b[i].norm());
                    for j in 0..4 {
                        r -= h[i][j] * x[j];
                        size += h[i][j].norm() * x[j].norm();
                    }
                    prop_assert!(r.norm() <= 1e-12 * size, "row {i}: residual {} of {size}", r.norm());
                }
            }
        }
    }

    /// A tie between the diagonal and a row below it: the pivoting steps take the first of the
    /// tied rows in their own order (Fy before Mx), the exchange-free steps would take Mx, so they
    /// must decline; without the tie they go ahead.
    #[test]
    fn exchange_free_steps_decline_a_tied_pivot() {
        let z = |re: f64, im: f64| C64::new(re, im);
        // step 0 pivots on Fx (row 0); at step 1 Fy and Mx both have |re| + |im| = 4 in column 1
        let mut h = [
            [z(8.0, 0.0), z(0.0, 0.0), z(0.3, 0.1), z(0.2, 0.0)],
            [z(0.0, 0.0), z(3.0, 1.0), z(0.5, 0.0), z(0.1, 0.2)],
            [z(0.0, 0.0), z(1.0, 3.0), z(0.2, 0.4), z(0.3, 0.0)],
            [z(0.0, 0.0), z(0.5, 0.0), z(0.1, 0.0), z(6.0, 0.5)],
        ];
        let b = [z(1.0, 0.0), z(0.0, 1.0), z(-1.0, 0.5), z(0.25, 0.0)];
        assert!(solve_by_steps::<false>(h, b).is_none());
        h[1][1] = z(2.5, 1.0); // Mx alone is the largest: no exchange needed
        let x = solve_by_steps::<false>(h, b).unwrap();
        assert_eq!(x, solve_by_steps::<true>(h, b).unwrap());
    }

    /// Undamped rotor with equal isotropic bearings and l1 = l2: w = sqrt(2k/m) is its bounce
    /// resonance, where H is singular.
    fn resonant(m: f64, it: f64, ip: f64, l: f64, k: f64) -> (Rotor, [f64; 8], f64) {
        let rotor = Rotor { m, it, ip, l1: l, l2: l };
        (rotor, [k, 0.0, 0.0, k, k, 0.0, 0.0, k], (2.0 * k / m).sqrt())
    }

    proptest! {
        #![proptest_config(cfg(300))]

        /// The lane kernel equals the per-point solve on random rotors, bearings, speeds, tails
        /// (n = 1..40), 1 to 4 right-hand sides, shared and per-point bearings and forces.
        #[test]
        fn lanes_equal_per_point_solve(p in inputs(41)) {
            let (diff, _, same_count, _) = run(&p);
            prop_assert!(diff <= 1e-12, "relative difference {diff:e}");
            prop_assert!(same_count);
        }

        /// Stronger: the lanes perform the operations of `solve4` in the same order, so the
        /// values are identical (up to the sign of zeros).
        #[test]
        fn lanes_are_the_per_point_values(p in inputs(41)) {
            let (_, equal, _, _) = run(&p);
            prop_assert!(equal);
        }

        /// Points exactly at an undamped resonance, mixed with regular points in the same groups
        /// of 8: the same points are singular (NaN) in both paths, the others equal.
        #[test]
        fn singular_points_in_mixed_groups(m in 1.0f64..500.0, rg in 0.1f64..0.6, ipr in 0.0f64..1.5,
                                           l in 0.05f64..0.8, lk in 5.0f64..8.0, n in 1usize..41,
                                           nrhs in 1usize..5, which in any::<u64>(),
                                           ratios in proptest::collection::vec(0.1f64..3.0, 40),
                                           spins in proptest::collection::vec(-2.0f64..2.0, 40)) {
            let it = m * (rg * 2.0 * l).powi(2);
            let (rotor, k, wr) = resonant(m, it, ipr * it, l, 10f64.powf(lk));
            let at = |i: usize| which >> (i % 64) & 1 == 1;
            let w: Vec<f64> = (0..n).map(|i| if at(i) { wr } else { wr * ratios[i] }).collect();
            let spin: Vec<f64> = (0..n).map(|i| w[i] * spins[i]).collect();
            let force: Vec<C64> = (0..4 * nrhs).map(|j| C64::new(1.0 + j as f64, -0.5)).collect();
            let p = Inputs { rotor, kb: k.to_vec(), cb: vec![0.0; 8], spin, w, force, nrhs };
            let (diff, equal, same_count, bad) = run(&p);
            prop_assert!(diff <= 1e-12, "relative difference {diff:e}");
            prop_assert!(equal);
            prop_assert!(same_count);
            let resonant = (0..n).filter(|&i| at(i)).count();
            prop_assert!(bad >= resonant, "{bad} singular points, {resonant} at the resonance");
        }

        /// Ties between candidate pivots (l1 = 1 m, so a moment row equals a force row in
        /// magnitude; coefficients and speeds of a few significant digits, so entries repeat
        /// exactly) and forced exchanges: the first of equal rows is the pivot, which depends on
        /// the order of the rows, so the exchange-free pass (rows in another order) must give way
        /// to the pivoting one; the values are the per-point solve's.
        #[test]
        fn pivot_ties_and_exchanges_give_the_per_point_values(
            m in 1u32..50, it in 1u32..20, ip in 0u32..5, l2 in prop::sample::select(vec![1.0f64, 0.5, 2.0]),
            kb in proptest::collection::vec(-4i32..5, 8), cb in proptest::collection::vec(-2i32..3, 8),
            ws in proptest::collection::vec(0u32..4, 1..41), spin_ratio in -2i32..3)
        {
            let rotor = Rotor { m: m as f64, it: it as f64, ip: ip as f64, l1: 1.0, l2 };
            let kb: Vec<f64> = kb.iter().map(|&v| 1e6 * v as f64).collect();
            let cb: Vec<f64> = cb.iter().map(|&v| 1e3 * v as f64).collect();
            let w: Vec<f64> = ws.iter().map(|&v| 100.0 * v as f64).collect();
            let spin: Vec<f64> = w.iter().map(|&x| x * spin_ratio as f64).collect();
            let force = vec![C64::new(1.0, 0.0), C64::new(0.0, 1.0), C64::new(-1.0, 0.0), C64::new(0.5, 0.5)];
            let p = Inputs { rotor, kb, cb, spin, w, force, nrhs: 1 };
            let (diff, equal, same_count, _) = run(&p);
            prop_assert!(diff <= 1e-12, "relative difference {diff:e}");
            prop_assert!(equal);
            prop_assert!(same_count);
        }

        /// NaN and inf inputs: the groups holding them take the per-point path, whose rules apply.
        #[test]
        fn non_finite_inputs_follow_the_per_point_rules(p in inputs(41), at in 0usize..40, what in 0usize..4) {
            let mut p = p;
            let n = p.w.len();
            let i = at % n;
            match what {
                0 => p.w[i] = f64::NAN,
                1 => p.spin[i] = f64::INFINITY,
                2 => { let j = p.kb.len() - 1 - (i % p.kb.len()); p.kb[j] = f64::NAN; }
                _ => p.w[i] = 1e200,
            }
            let (diff, equal, same_count, _) = run(&p);
            prop_assert!(diff <= 1e-12, "relative difference {diff:e}");
            prop_assert!(equal);
            prop_assert!(same_count);
        }
    }

    /// More points than SERIAL_BELOW: parallel chunks of CHUNK points, the last one partial.
    #[test]
    fn parallel_chunks_equal_per_point_solve() {
        let n = 2 * CHUNK + CHUNK / 2 + 3;
        let rotor = Rotor { m: 30.7, it: 0.62, ip: 0.062, l1: 0.146, l2: 0.137 };
        let k = [3.2e6, 4e5, -3e5, 2.9e6, 3.5e6, 2e5, -2e5, 3.1e6];
        let c = [2.1e3, 1e2, 1e2, 2.3e3, 2.2e3, 0.0, 0.0, 2.0e3];
        let w: Vec<f64> = (0..n).map(|i| 1.0 + 1500.0 * i as f64 / n as f64).collect();
        let kb: Vec<f64> = (0..n).flat_map(|i| k.map(|v| v * (1.0 + 1e-4 * i as f64))).collect();
        let force: Vec<C64> = (0..8).map(|j| C64::new(j as f64, 1.0)).collect();
        let p = Inputs { rotor, kb, cb: c.to_vec(), spin: w.clone(), w, force, nrhs: 2 };
        let (diff, equal, same_count, _) = run(&p);
        assert!(diff <= 1e-12 && equal && same_count);
        // shared bearings and one right-hand side: the register kernel's chunks (on AVX-512)
        let p = Inputs { kb: k.to_vec(), force: p.force[..4].to_vec(), nrhs: 1, ..p };
        let (diff, equal, same_count, _) = run(&p);
        assert!(diff <= 1e-12 && equal && same_count);
    }

    /// (groups on registers, groups handed to the lane path) of one serial forced response.
    fn register_counts(p: &Inputs) -> (usize, usize) {
        counts(p, &REGISTER_GROUPS, &GROUPS_TO_LANES)
    }

    /// The register kernel (one right-hand side, shared bearings, on AVX-512 CPUs) solves
    /// every whole group of the NSF rotor on its bearings itself, hands the groups that need a row
    /// exchange to the lane path, and gives the per-point values to the bit either way.
    #[test]
    fn register_kernel_serves_a_rotor_on_bearings_and_hands_exchanges_on() {
        let rotor = Rotor { m: 30.7, it: 0.62, ip: 0.062, l1: 0.146, l2: 0.137 };
        let k = [3.2e6, 4e5, -3e5, 2.9e6, 3.5e6, 2e5, -2e5, 3.1e6];
        let c = [2.1e3, 1e2, 1e2, 2.3e3, 2.2e3, 0.0, 0.0, 2.0e3];
        let w: Vec<f64> = (0..203).map(|i| 1.0 + 1500.0 * i as f64 / 203.0).collect();
        let force = vec![C64::new(1.0, 0.5); 4];
        let mut p = Inputs { rotor, kb: k.to_vec(), cb: c.to_vec(), spin: w.clone(), w, force, nrhs: 1 };
        let lanes = if crate::lanes::simd() == crate::lanes::Simd::Avx512 { 8 } else { 0 };
        let (on_registers, handed_on) = register_counts(&p);
        if lanes > 0 {
            assert_eq!((on_registers, handed_on), (203 / lanes, 0));
        }
        let (diff, equal, same_count, _) = run(&p);
        assert!(diff == 0.0 && equal && same_count);
        p.kb = vec![1e3, 4e6, -4e6, 1e3, 3.5e6, 2e5, -2e5, 3.1e6];
        let (on_registers, handed_on) = register_counts(&p);
        if lanes > 0 {
            assert!(handed_on > 0 && on_registers + handed_on == 203 / lanes, "{on_registers} + {handed_on}");
        }
        let (diff, equal, same_count, _) = run(&p);
        assert!(diff <= 1e-12 && equal && same_count);
    }

    /// The plane transform of the tests below.
    const PLANES: [f64; 4] = [1.2, -0.2, -0.3, 1.3];

    /// Gain `kind` of the tests below (0: one, 1: `gains`, else Omega^2).
    fn test_gain(kind: u8, gains: &[f64]) -> Gain<'_> {
        match kind {
            0 => Gain::One,
            1 => Gain::PerPoint(gains),
            _ => Gain::SpinSquared,
        }
    }

    /// `forced_response_with` (gain, plane transform) against the per-point path with the same
    /// gain and transform: (all equal, singular counts equal).
    fn run_with(p: &Inputs, gain_kind: u8, planes: bool) -> (bool, bool) {
        let n = p.w.len();
        let gains: Vec<f64> = (0..n).map(|i| 0.5 + i as f64).collect();
        let gain = test_gain(gain_kind, &gains);
        let planes = planes.then_some(&PLANES);
        let mut got = vec![C64::new(0.0, 0.0); n * p.nrhs * 4];
        let bad = forced_response_with(&p.rotor, &p.kb, &p.cb, &p.spin, &p.w, &p.force, p.nrhs, gain, planes, &mut got).unwrap();
        let b = Batch::new(&p.rotor, &p.kb, &p.cb, &p.spin, &p.w, &p.force, p.nrhs, gain, planes);
        let mut reference = vec![C64::new(0.0, 0.0); got.len()];
        let bad_ref = per_point(&b, &mut reference);
        (compare(&got, &reference, 4 * p.nrhs).1, bad == bad_ref)
    }

    proptest! {
        #![proptest_config(cfg(300))]

        /// The register kernel's case (one right-hand side, shared bearings) with every gain, with
        /// and without the plane transform, 1 to 80 points (whole groups, tails), shared or
        /// per-point forces, now and then a NaN, inf or huge value or a bearing that forces row
        /// exchanges: the per-point values, to the bit.
        #[test]
        fn register_kernel_gives_the_per_point_values(
            p in inputs(81), gain_kind in 0u8..3, planes in any::<bool>(), spoil in 0usize..8, at in 0usize..80,
        ) {
            let mut p = p;
            let n = p.w.len();
            p.nrhs = 1;
            p.kb.truncate(8);
            p.cb.truncate(8);
            p.force = if p.force.len() >= 4 * n { p.force[..4 * n].to_vec() } else { p.force[..4].to_vec() };
            let i = at % n;
            match spoil {
                0 => p.w[i] = f64::NAN,
                1 => p.spin[i] = f64::INFINITY,
                2 => p.w[i] = 1e200,
                3 => p.kb = vec![1e3, 4e6, -4e6, 1e3, 3.5e6, 2e5, -2e5, 3.1e6],
                _ => {}
            }
            let (equal, same_count) = run_with(&p, gain_kind, planes);
            prop_assert!(equal);
            prop_assert!(same_count);
            // on AVX-512 CPUs: the register kernel itself, from a point inside the batch on,
            // against the lane path (no FMA in either: the baseline's bits) bit for bit, zeros'
            // signs included
            #[cfg(target_arch = "x86_64")]
            if crate::lanes::simd_of_cpu() == crate::lanes::Simd::Avx512 {
                let gains: Vec<f64> = (0..n).map(|i| 0.5 + i as f64).collect();
                let gain = test_gain(gain_kind, &gains);
                let b = Batch::new(&p.rotor, &p.kb, &p.cb, &p.spin, &p.w, &p.force, 1, gain, planes.then_some(&PLANES));
                prop_assume!(registers::serves(&b));
                let first = at % n;
                let mut got = vec![C64::new(0.0, 0.0); 4 * (n - first)];
                let mut lanes = got.clone();
                // SAFETY: this CPU has AVX-512 F and DQ (checked above)
                let bad = unsafe { register_chunk(&b, first, &mut got) };
                let bad_lanes = forced_chunk_baseline(&b, first, &mut lanes);
                prop_assert_eq!(bad, bad_lanes);
                for (x, y) in got.iter().zip(&lanes) {
                    let same = |u: f64, v: f64| u.to_bits() == v.to_bits() || (u.is_nan() && v.is_nan());
                    prop_assert!(same(x.re, y.re) && same(x.im, y.im), "{x} (registers) vs {y} (lanes)");
                }
            }
        }
    }

    /// [`registers::forced_chunk`] on AVX-512, the lane path for the groups it hands on.
    ///
    /// # Safety
    /// Only on a CPU with AVX-512 F and DQ.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512dq,avx2,fma")]
    unsafe fn register_chunk(b: &Batch, start: usize, out: &mut [C64]) -> usize {
        registers::forced_chunk::<8, crate::identify::avx512::Avx512>(b, start, out, |first, o| forced_chunk_baseline(b, first, o))
    }

    /// The lane path takes the whole H from `dynamic_stiffness`; this pins down the singular
    /// example of the integration tests inside a full group of 8.
    #[test]
    fn resonance_is_singular_in_every_lane() {
        let (rotor, k, wr) = resonant(20.0, 0.5, 0.0, 0.2, 1e6);
        let w = [wr; 8];
        let force = [C64::new(1.0, 0.0), C64::new(0.0, 0.0), C64::new(0.0, 0.0), C64::new(0.0, 0.0)];
        let mut q = [C64::new(0.0, 0.0); 32];
        let bad = forced_response(&rotor, &k, &[0.0; 8], &w, &w, &force, 1, &mut q).unwrap();
        assert_eq!(bad, 8);
        assert!(q.iter().all(|z| z.re.is_nan() && z.im.is_nan()));
    }
}
