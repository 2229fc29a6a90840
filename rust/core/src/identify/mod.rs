//! Identification of bearing impedances Z = K + j w C from responses to known excitations.
//!
//! Both identification methods of the report reduce, at every point (speed or frequency), to the
//! complex equation (eq. 10 / eq. 26)
//!     Q(q) P = R,   R = E - s^2 M q - s Omega G q,   s = sigma + j w (sigma = 0 unless windowed),
//! per run. Two solvers are provided:
//! - `identify_forces` (default): the four rotor equations give the reaction force of each
//!   bearing, and each bearing becomes a complex least-squares problem [x_b y_b] z = f_b with two
//!   unknowns and two right-hand sides (x row and y row of Z_b). Points are solved in lock-step
//!   (SIMD lanes: 8 on AVX-512 and 4 on AVX2 CPUs in `registers.rs`, 2 in the generic kernel
//!   here elsewhere, the same bits): two rows by Cramer's rule, more rows by the semi-normal
//!   equations (corrected by one refinement step from cond = 1e3 on, [`REFINE_COND`]), and any
//!   lane with cond > 1e6 again by a complex Givens QR.
//! - `identify_report`: the report's 16-unknown real formulation (eq. 8-12, 16-18) solved with
//!   faer's QR. Kept as the reference; it equals the default exactly for two runs.

use crate::error::{expect_len, expect_len_or_broadcast, product, CoreError};
use crate::lanes::{Z, V};
use crate::model::{Rotor, C64};
use crate::par::Disjoint;
use faer::linalg::solvers::SolveLstsq;
use faer::Mat;
use rayon::prelude::*;

#[cfg(target_arch = "x86_64")]
pub(crate) mod avx2;
#[cfg(target_arch = "x86_64")]
pub(crate) mod avx512;
pub mod identical;
pub mod propagate;
#[cfg(target_arch = "x86_64")]
pub(crate) mod registers;

const SINGULAR_COND: f64 = 1e14;

/// Streaming QR of an m x 2 complex least-squares problem with two right-hand sides.
/// R = [[r11, r12], [0, r22]] with r11, r22 real >= 0 (the rotations keep the diagonal real),
/// qb = Q^H b for the two right-hand sides, and the running residual and right-hand-side norms.
#[derive(Clone, Copy)]
struct Givens2 {
    r11: f64,
    r12: C64,
    r22: f64,
    qb: [[C64; 2]; 2], // qb[row][rhs]
    res2: [f64; 2],
    rhs2: [f64; 2],
    rows: u32,
}

/// Unitary [[c, s], [-conj(s), c]] mapping (a, b) -> (r, 0) for real a >= 0: c = a/r, s = conj(b)/r.
#[inline(always)]
fn rot(a: f64, b: C64) -> Option<(f64, C64, f64)> {
    let nb2 = b.norm_sqr();
    if nb2 == 0.0 {
        return None;
    }
    let r = (a * a + nb2).sqrt();
    let ir = 1.0 / r;
    Some((a * ir, b.conj() * ir, r))
}

impl Givens2 {
    #[inline(always)]
    fn new() -> Self {
        let z = C64::new(0.0, 0.0);
        Givens2 { r11: 0.0, r12: z, r22: 0.0, qb: [[z; 2]; 2], res2: [0.0; 2], rhs2: [0.0; 2], rows: 0 }
    }

    /// Add one equation a1 z1 + a2 z2 = b (two right-hand sides b[0], b[1]).
    #[inline(always)]
    fn push(&mut self, a1: C64, mut a2: C64, mut b: [C64; 2]) {
        self.rows += 1;
        self.rhs2[0] += b[0].norm_sqr();
        self.rhs2[1] += b[1].norm_sqr();
        if let Some((c, s, r)) = rot(self.r11, a1) {
            let sc = s.conj();
            self.r11 = r;
            let t12 = self.r12;
            self.r12 = t12 * c + s * a2;
            a2 = a2 * c - sc * t12;
            for k in 0..2 {
                let t = self.qb[0][k];
                self.qb[0][k] = t * c + s * b[k];
                b[k] = b[k] * c - sc * t;
            }
        }
        if let Some((c, s, r)) = rot(self.r22, a2) {
            let sc = s.conj();
            self.r22 = r;
            for k in 0..2 {
                let t = self.qb[1][k];
                self.qb[1][k] = t * c + s * b[k];
                b[k] = b[k] * c - sc * t;
            }
        }
        self.res2[0] += b[0].norm_sqr();
        self.res2[1] += b[1].norm_sqr();
    }

    /// Condition number of the 2-column response matrix (ratio of the singular values of R).
    #[inline(always)]
    fn cond(&self) -> f64 {
        let a = self.r11 * self.r11;
        let n12 = self.r12.norm_sqr();
        let d = n12 + self.r22 * self.r22;
        let det = self.r11 * self.r22;
        if det == 0.0 {
            return f64::INFINITY;
        }
        let lmax = 0.5 * (a + d) + (0.25 * (a - d) * (a - d) + a * n12).sqrt();
        lmax / det // sqrt(lmax / lmin) with lmin = det^2 / lmax
    }

    /// Solution z[rhs][unknown], variance factors diag((A^H A)^-1), condition number.
    #[inline(always)]
    fn solve(&self) -> ([[C64; 2]; 2], [f64; 2], f64) {
        let cond = self.cond();
        if !(cond < SINGULAR_COND) {
            let nan = C64::new(f64::NAN, f64::NAN);
            return ([[nan; 2]; 2], [f64::NAN; 2], f64::INFINITY);
        }
        let (i11, i22) = (1.0 / self.r11, 1.0 / self.r22);
        let mut z = [[C64::new(0.0, 0.0); 2]; 2];
        for k in 0..2 {
            let z2 = self.qb[1][k] * i22;
            let z1 = (self.qb[0][k] - self.r12 * z2) * i11;
            z[k] = [z1, z2];
        }
        let g = [i11 * i11 * (1.0 + self.r12.norm_sqr() * i22 * i22), i22 * i22];
        (z, g, cond)
    }
}

/// Lane-parallel solution of one bearing system for N points: z[rhs][unknown], variance factors
/// diag((A^H A)^-1), condition number, residual and right-hand-side sums of squares per rhs.
#[derive(Clone, Copy)]
struct LaneSol<const N: usize> {
    z: [[Z<N>; 2]; 2],
    g: [V<N>; 2],
    cond: V<N>,
    res2: [V<N>; 2],
    rhs2: [V<N>; 2],
    /// sum of squares of every entry: non-finite exactly when an input was NaN or inf
    total: V<N>,
    /// sum of |x|^2 + |y|^2 over the rows
    qq: V<N>,
}

impl<const N: usize> LaneSol<N> {
    fn zero() -> Self {
        let (v, z) = (V::<N>::zero(), Z::<N>::zero());
        LaneSol { z: [[z; 2]; 2], g: [v; 2], cond: v, res2: [v; 2], rhs2: [v; 2], total: v, qq: v }
    }
}

/// Largest condition number solved through the corrected semi-normal equations; lanes above it
/// go through the Givens QR (backward stable up to SINGULAR_COND).
const CSNE_COND: f64 = 1e6;
/// Smallest condition number at which a lane takes the refinement step. Below it the semi-normal
/// equations alone are accurate to about cond^2 eps <= 1e6 * 1.1e-16 ~ 1e-10 relative (the
/// identification's inputs are measured to 1e-3 at best); the step then only costs time: 12-13 %
/// of the kernel's (4 runs, `identify_points 4096 300 nostd 4`: AVX2 62 -> 54 ns per point,
/// AVX-512 44.5 -> 39). Per lane, so every lane width gives the same bits.
pub const REFINE_COND: f64 = 1e3;

/// Solve rows [x, y, f_x, f_y] (x z0 + y z1 = f_k, k = 0, 1) in the least-squares sense for N
/// points at once: 2x2 Hermitian normal equations in closed form plus, where cond >= REFINE_COND,
/// one refinement step with the residual of the original rows (corrected semi-normal equations:
/// as accurate as QR while cond^2 * eps << 1, hence CSNE_COND). No square root or division inside
/// the row loops.
#[inline(always)]
fn solve_lanes<const N: usize>(rows: &[[Z<N>; 4]], refine_cond: f64) -> LaneSol<N> {
    if rows.len() == 2 {
        return solve_square(rows);
    }
    let (mut a, mut d) = (V::<N>::zero(), V::<N>::zero());
    let mut gxy = Z::<N>::zero();
    let mut h = [[Z::<N>::zero(); 2]; 2];
    let mut rhs2 = [V::<N>::zero(); 2];
    for r in rows {
        a = r[0].norm_sqr_add(a);
        d = r[1].norm_sqr_add(d);
        gxy = r[0].cmul_add(r[1], gxy);
        for k in 0..2 {
            h[k][0] = r[0].cmul_add(r[2 + k], h[k][0]);
            h[k][1] = r[1].cmul_add(r[2 + k], h[k][1]);
            rhs2[k] = r[2 + k].norm_sqr_add(rhs2[k]);
        }
    }
    let g2 = gxy.norm_sqr();
    let det = a * d - g2;
    let amd = a - d;
    let lmax = (a + d) * V::<N>::splat(0.5) + (amd * amd * V::<N>::splat(0.25) + g2).sqrt();
    let idet = det.recip();
    let cond = (lmax * lmax * idet).sqrt();
    let gc = gxy.conj();
    let solve = |v: &[Z<N>; 2]| -> [Z<N>; 2] { solve_gram(v, a, d, gxy, gc, idet) };
    let mut z = [solve(&h[0]), solve(&h[1])];
    let mut ahr = [[Z::<N>::zero(); 2]; 2];
    let mut res2 = [V::<N>::zero(); 2];
    // the refinement step only in lanes whose cond reaches REFINE_COND (and NaN lanes); the
    // residual in every lane
    let refine: [bool; N] = std::array::from_fn(|l| !(cond.0[l] < refine_cond));
    let any = refine.iter().any(|&b| b);
    for r in rows {
        for k in 0..2 {
            let res = Z::sub_two_products(r[2 + k], r[0], z[k][0], r[1], z[k][1]);
            res2[k] = res.norm_sqr_add(res2[k]);
            if any {
                ahr[k][0] = r[0].cmul_add(res, ahr[k][0]);
                ahr[k][1] = r[1].cmul_add(res, ahr[k][1]);
            }
        }
    }
    if any {
        for k in 0..2 {
            let dz = solve(&ahr[k]);
            for l in (0..N).filter(|&l| refine[l]) {
                for u in 0..2 {
                    z[k][u].re.0[l] += dz[u].re.0[l];
                    z[k][u].im.0[l] += dz[u].im.0[l];
                }
            }
        }
    }
    let total = a + d + rhs2[0] + rhs2[1];
    LaneSol { z, g: [d * idet, a * idet], cond, res2, rhs2, total, qq: a + d }
}

/// (A^H A)^-1 v for the 2x2 Hermitian Gram matrix [[a, gxy], [conj(gxy), d]] with 1/det = `idet`.
#[inline(always)]
fn solve_gram<const N: usize>(v: &[Z<N>; 2], a: V<N>, d: V<N>, gxy: Z<N>, gc: Z<N>, idet: V<N>) -> [Z<N>; 2] {
    [(v[0].scale(d) - gxy * v[1]).scale(idet), (v[1].scale(a) - gc * v[0]).scale(idet)]
}

/// Exactly determined systems (two rows): Cramer's rule on the 2x2 complex matrix (forward stable
/// for 2x2), condition number from ||A||_F^2 = s1^2 + s2^2 and |det A| = s1 s2. Residual is zero.
#[inline(always)]
fn solve_square<const N: usize>(rows: &[[Z<N>; 4]]) -> LaneSol<N> {
    let (r0, r1) = (&rows[0], &rows[1]);
    let det = r0[0] * r1[1] - r1[0] * r0[1];
    let dn2 = det.norm_sqr();
    let a = r0[0].norm_sqr() + r1[0].norm_sqr();
    let d = r0[1].norm_sqr() + r1[1].norm_sqr();
    let fro = a + d;
    let idn = dn2.recip();
    // 1/det = conj(det) / |det|^2
    let inv = det.conj().scale(idn);
    let mut z = [[Z::<N>::zero(); 2]; 2];
    let mut rhs2 = [V::<N>::zero(); 2];
    for k in 0..2 {
        let (f0, f1) = (r0[2 + k], r1[2 + k]);
        z[k][0] = (r1[1] * f0 - r0[1] * f1) * inv;
        z[k][1] = (r0[0] * f1 - r1[0] * f0) * inv;
        rhs2[k] = f0.norm_sqr() + f1.norm_sqr();
    }
    let adet = dn2.sqrt();
    let disc = (fro * fro - V::<N>::splat(4.0) * dn2).sqrt();
    let cond = (fro + disc) * (V::<N>::splat(2.0) * adet).recip();
    // variance factors diag((A^H A)^-1) = diag(adj adj^H) / |det|^2 (unused: no redundancy)
    let g = [d * idn, a * idn];
    LaneSol { z, g, cond, res2: [V::<N>::zero(); 2], rhs2, total: fro + rhs2[0] + rhs2[1], qq: fro }
}

/// Re-solve lane `l` of `sol` with the Givens QR (ill-conditioned or degenerate lanes): a rare
/// path, kept out of the lane kernel's code.
#[cold]
#[inline(never)]
fn givens_lane<const N: usize>(rows: &[[Z<N>; 4]], l: usize, sol: &mut LaneSol<N>) {
    let mut gv = Givens2::new();
    let at = |z: &Z<N>| C64::new(z.re.0[l], z.im.0[l]);
    for r in rows {
        gv.push(at(&r[0]), at(&r[1]), [at(&r[2]), at(&r[3])]);
    }
    let (z, g, cn) = gv.solve();
    for k in 0..2 {
        for u in 0..2 {
            sol.z[k][u].re.0[l] = z[k][u].re;
            sol.z[k][u].im.0[l] = z[k][u].im;
        }
        sol.g[k].0[l] = g[k];
        sol.res2[k].0[l] = gv.res2[k];
    }
    sol.cond.0[l] = cn;
}

/// Inputs shared by both solvers.
#[derive(Clone, Copy)]
pub struct IdentProblem<'a> {
    pub rotor: Rotor,
    /// vibration frequency w at each point (= spin speed for synchronous identification), rad/s
    pub w: &'a [f64],
    /// spin speed Omega at each point, rad/s, (n,) or (1,) for one running speed
    pub spin: &'a [f64],
    /// responses: `batch * runs` blocks (batch-major), each (n, 4) in the order [x1, x2, y1, y2].
    /// Blocks rather than one array so that separately stored runs are used where they are,
    /// without being stacked into a new array first.
    pub q: &'a [&'a [C64]],
    /// excitation base vectors, (batch_e, runs, 4) with batch_e in {1, batch}
    pub e: &'a [C64],
    /// gain applied to e at each point (Omega^2 for imbalance, 1 for unit-force FRFs), (n,) or
    /// (1,); empty: Omega_i^2 from `spin` (an imbalance, without an (n,) array of the caller's)
    pub gain: &'a [f64],
    /// real part of the Laplace variable s = sigma + j w at each point, (n,) or empty for s = j w
    /// (an exponential window exp(-sigma t) on force and response gives FRFs at sigma + j w)
    pub sigma: &'a [f64],
    /// pedestal motion at the bearings, laid out as `q` (`batch * runs` blocks of (n, 4)), or
    /// empty for rigid pedestals. With it `q` is the journal's motion relative to its housing:
    /// the bearing forces act on `q`, the rotor's inertia on the absolute motion `q + q_ped`
    /// (`Q(q) P = E - s^2 M (q + q_ped) - s Omega G (q + q_ped)`).
    pub q_ped: &'a [&'a [C64]],
    /// `q` measured at two other planes per direction (the probes): the responses at the bearings
    /// are [x1, x2] = T [x_a, x_b] and [y1, y2] = T [y_a, y_b] (report eq. 19) with T = [T11, T12,
    /// T21, T22], formed as each point is loaded (as [`crate::model::apply_planes`] forms them,
    /// bit for bit, without an array of moved responses). None: `q` is at the bearings. Not with
    /// `q_ped` (probes on moving pedestals need the pedestal motion too).
    pub planes: Option<[f64; 4]>,
    pub batch: usize,
    pub runs: usize,
    /// all bearing coefficients equal on both sides (8 unknowns instead of 16)
    pub identical: bool,
}

impl IdentProblem<'_> {
    /// Number of points (speeds or frequencies) per batch member.
    pub fn points(&self) -> usize {
        self.w.len()
    }

    /// Check every length and the values the solvers divide by.
    pub fn check(&self) -> Result<(), CoreError> {
        let n = self.w.len();
        if self.runs == 0 {
            return Err(CoreError::value("runs", "must be at least 1"));
        }
        expect_len_or_broadcast("spin", self.spin, 1, n)?;
        if !self.gain.is_empty() {
            expect_len_or_broadcast("gain", self.gain, 1, n)?;
        }
        expect_len("q (blocks)", self.q, product("q", &[self.batch, self.runs])?)?;
        let block = product("q", &[n, 4])?;
        if let Some(bad) = self.q.iter().position(|b| b.len() != block) {
            return Err(CoreError::length("q", self.q[bad].len(), format!("{block} in every block (block {bad} differs)")));
        }
        if let Some(t) = self.planes {
            if !self.q_ped.is_empty() {
                return Err(CoreError::value("planes", "cannot be combined with pedestal motion (q_ped)"));
            }
            if t.iter().any(|v| !v.is_finite()) {
                return Err(CoreError::value("planes", "must be finite"));
            }
        }
        if !self.q_ped.is_empty() {
            expect_len("q_ped (blocks)", self.q_ped, self.q.len())?;
            if let Some(bad) = self.q_ped.iter().position(|b| b.len() != block) {
                return Err(CoreError::length("q_ped", self.q_ped[bad].len(), format!("{block} in every block (block {bad} differs)")));
            }
        }
        if self.e.len() != 4 * self.runs && self.e.len() != product("e", &[self.batch, self.runs, 4])? {
            return Err(CoreError::length("e", self.e.len(), format!("{} (shared) or {}", 4 * self.runs, 4 * self.runs * self.batch)));
        }
        if !self.sigma.is_empty() {
            expect_len("sigma", self.sigma, n)?;
            if self.sigma.iter().any(|v| !v.is_finite()) {
                return Err(CoreError::value("sigma", "must be finite"));
            }
        }
        if !all_finite_nonzero(self.w) {
            return Err(CoreError::value("w", "(vibration frequency) must be finite and non-zero"));
        }
        Ok(())
    }
}

/// True when every value is finite and non-zero, in one vectorized pass with no early exit: per
/// lane of eight the smallest |x| (minpd's rule: a NaN is not taken) and the sum of x * 0, which is
/// NaN once an x is inf or NaN. Written in floating point, since flags in integers (is_finite as
/// bit tests) were left scalar. (`iter().any` tested one value per iteration: 3-7 µs of a
/// 10,000-frequency identification, on the calling thread alone.)
fn all_finite_nonzero(v: &[f64]) -> bool {
    let (mut small, mut nonfinite) = ([f64::INFINITY; 8], [0.0f64; 8]);
    let chunks = v.chunks_exact(8);
    let rest = chunks.remainder();
    for c in chunks {
        for l in 0..8 {
            let a = c[l].abs();
            small[l] = if a < small[l] { a } else { small[l] };
            nonfinite[l] += c[l] * 0.0;
        }
    }
    small.iter().all(|&a| a > 0.0) && nonfinite.iter().all(|&s| s == 0.0) && rest.iter().all(|&x| x.is_finite() && x != 0.0)
}

/// Outputs, all (batch, n, ...).
pub struct IdentOut<'a> {
    pub k: &'a mut [f64],      // (B, n, 8)
    pub c: &'a mut [f64],      // (B, n, 8)
    pub cond: &'a mut [f64],   // (B, n, 2)
    pub resid: &'a mut [f64],  // (B, n)
    /// rms response amplitude over runs and the four coordinates, (B, n)
    pub amp: &'a mut [f64],
    pub k_std: Option<&'a mut [f64]>, // (B, n, 8)
    pub c_std: Option<&'a mut [f64]>, // (B, n, 8)
    /// [`relative_std`] of `k_std`, `c_std`, (B, n), filled in the same pass (no second read of the
    /// four (B, n, 8) arrays); only with `k_std` and `c_std`, and only by [`identify_forces`]
    pub rel_std: Option<&'a mut [f64]>,
}

impl IdentOut<'_> {
    fn check(&self, points: usize) -> Result<(), CoreError> {
        expect_len("k", self.k, product("k", &[points, 8])?)?;
        expect_len("c", self.c, points * 8)?;
        expect_len("cond", self.cond, points * 2)?;
        expect_len("resid", self.resid, points)?;
        expect_len("amp", self.amp, points)?;
        if let Some(ks) = &self.k_std {
            expect_len("k_std", ks, points * 8)?;
        }
        if let Some(cs) = &self.c_std {
            expect_len("c_std", cs, points * 8)?;
        }
        if let Some(rs) = &self.rel_std {
            if self.k_std.is_none() || self.c_std.is_none() {
                return Err(CoreError::value("rel_std", "needs k_std and c_std"));
            }
            expect_len("rel_std", rs, points)?;
        }
        Ok(())
    }
}

/// Per-call constants of the rotor equations.
#[derive(Clone, Copy)]
pub(crate) struct Consts {
    /// lanes from this condition number on take the refinement step ([`REFINE_COND`]; 0 in
    /// [`identify_serial`]: every lane)
    refine_cond: f64,
    ml2: f64,
    ml1: f64,
    it: f64,
    ip: f64,
    il: f64,
    l1: f64,
    l2: f64,
}

impl Consts {
    pub(crate) fn new(r: &Rotor) -> Self {
        let il = 1.0 / r.span();
        Consts { refine_cond: REFINE_COND, ml2: r.m * r.l2 * il, ml1: r.m * r.l1 * il, it: r.it * il, ip: r.ip * il, il, l1: r.l1, l2: r.l2 }
    }
}

#[inline(always)]
fn excitation<'a>(p: &'a IdentProblem, b: usize, r: usize) -> &'a [C64] {
    let be = if p.e.len() == p.runs * 4 { 0 } else { b };
    &p.e[(be * p.runs + r) * 4..(be * p.runs + r) * 4 + 4]
}

/// R = E - s^2 M q - s Omega G q with s = sigma + j w (right-hand side of eq. 10 / 26; for
/// sigma = 0 this is E + w^2 M q - j w Omega G q).
#[inline(always)]
fn rhs_point(k: &Consts, e: &[C64], gain: f64, w: f64, sigma: f64, spin: f64, q: &[C64; 4]) -> [C64; 4] {
    let ms2 = -C64::new(sigma * sigma - w * w, 2.0 * sigma * w); // -s^2
    let sg = -C64::new(sigma, w) * (spin * k.ip); // -s Omega (I_p / L)
    // M q (eq. 3, sparse) and G q
    let mq = [q[0] * k.ml2 + q[1] * k.ml1, q[2] * k.ml2 + q[3] * k.ml1, (q[1] - q[0]) * k.it, (q[2] - q[3]) * k.it];
    [
        e[0] * gain + mq[0] * ms2,
        e[1] * gain + mq[1] * ms2,
        e[2] * gain + mq[2] * ms2 + (q[3] - q[2]) * sg,
        e[3] * gain + mq[3] * ms2 + (q[1] - q[0]) * sg,
    ]
}

/// The gain of point `i`: gain[i], gain[0] broadcast, or Omega_i^2 when `gain` is empty.
#[inline(always)]
fn gain_at(p: &IdentProblem, i: usize) -> f64 {
    match p.gain.len() {
        0 => {
            let s = p.spin[if p.spin.len() == 1 { 0 } else { i }];
            s * s
        }
        1 => p.gain[0],
        _ => p.gain[i],
    }
}

#[inline(always)]
fn sigma_at(p: &IdentProblem, i: usize) -> f64 {
    if p.sigma.is_empty() {
        0.0
    } else {
        p.sigma[i]
    }
}

/// The response of (batch b, run r, point i) at the bearings.
#[inline(always)]
fn load_q(p: &IdentProblem, b: usize, r: usize, i: usize) -> [C64; 4] {
    let blk = p.q[b * p.runs + r];
    let o = i * 4;
    let q = [blk[o], blk[o + 1], blk[o + 2], blk[o + 3]];
    match &p.planes {
        None => q,
        Some(t) => crate::model::planes_point(t, q),
    }
}

/// Absolute motion q + q_ped of (batch b, run r, point i); q itself without pedestals.
#[inline(always)]
fn load_abs(p: &IdentProblem, b: usize, r: usize, i: usize) -> [C64; 4] {
    let mut q = load_q(p, b, r, i);
    if !p.q_ped.is_empty() {
        let blk = p.q_ped[b * p.runs + r];
        for d in 0..4 {
            q[d] += blk[i * 4 + d];
        }
    }
    q
}

const CHUNK: usize = 1024;
/// Below this many points one thread is faster than waking the pool.
const SERIAL_BELOW: usize = 4096;

/// Output slices of one chunk.
struct Outs<'a> {
    k: &'a mut [f64],
    c: &'a mut [f64],
    cond: &'a mut [f64],
    resid: &'a mut [f64],
    amp: &'a mut [f64],
    ks: Option<&'a mut [f64]>,
    cs: Option<&'a mut [f64]>,
    rel: Option<&'a mut [f64]>,
}

/// Lanes -> rows of 8 values per point (an 8 x N transpose) for the `nl` points from `g0` on,
/// stored straight into `dst` ((points, 8)).
#[inline(always)]
fn put_rows<const N: usize>(dst: &mut [f64], g0: usize, nl: usize, src: &[V<N>; 8]) {
    for (l, row) in dst[8 * g0..8 * (g0 + nl)].chunks_exact_mut(8).enumerate() {
        for o in 0..8 {
            row[o] = src[o].0[l];
        }
    }
}

#[inline(always)]
fn put_row<const N: usize>(row: &mut [Z<N>; 4], x: Z<N>, y: Z<N>, fx: Z<N>, fy: Z<N>) {
    row[0] = x;
    row[1] = y;
    row[2] = fx;
    row[3] = fy;
}

/// One chunk of consecutive points starting at flat index `start` (= b * n + i), N at a time
/// (one register's width: 2 at the baseline, see [`forces_chunk_dispatch`]; [`registers`] is this
/// function on AVX2 and AVX-512 registers); each bearing system is solved by `S`'s
/// [`SolveApart::solve`].
///
/// # Safety
/// `S` = [`WithFma`] only on a CPU with FMA ([`Plain`] anywhere).
#[inline(always)]
unsafe fn forces_chunk<const N: usize, S: SolveApart>(p: &IdentProblem, kc: &Consts, start: usize, out: Outs) -> usize {
    let Outs { k, c, cond, resid, amp, mut ks, mut cs, rel: mut rel_out } = out;
    let n = p.w.len();
    let npts = resid.len();
    let shared_e = p.e.len() == p.runs * 4;
    let windowed = !p.sigma.is_empty(); // s = sigma + j w: extra terms only when asked for
    let nsys = if p.identical { 1 } else { 2 };
    let mut nbad = 0;
    let zrow = [Z::<N>::zero(); 4];
    let mut rows = [vec![zrow; 2 * p.runs], vec![zrow; 2 * p.runs]];
    let mut sols = [LaneSol::<N>::zero(); 2];
    let (ml2, ml1, it) = (V::<N>::splat(kc.ml2), V::<N>::splat(kc.ml1), V::<N>::splat(kc.it));
    let (l1, l2, il) = (V::<N>::splat(kc.l1), V::<N>::splat(kc.l2), V::<N>::splat(kc.il));
    for g0 in (0..npts).step_by(N) {
        let nl = N.min(npts - g0);
        let mut bi = [(0usize, 0usize); N];
        let (mut w, mut spin, mut gain, mut sig) = (V::<N>::zero(), V::<N>::zero(), V::<N>::zero(), V::<N>::zero());
        // (batch, point) of each lane: one division per group, then step with wrap-around
        let first = start + g0;
        let (mut b, mut i) = (first / n, first % n);
        for l in 0..N {
            bi[l] = (b, i);
            w.0[l] = p.w[i];
            spin.0[l] = p.spin[if p.spin.len() == 1 { 0 } else { i }];
            gain.0[l] = gain_at(p, i);
            sig.0[l] = sigma_at(p, i);
            if l + 1 < nl {
                i += 1;
                if i == n {
                    i = 0;
                    b += 1;
                }
            }
        }
        // all lanes are consecutive points of one batch row: contiguous loads
        let contiguous = nl == N && bi[0].0 == bi[N - 1].0;
        // -s^2 = (w^2 - sigma^2) - j 2 sigma w and -s Omega I_p/L = -(sigma + j w) Omega I_p/L
        let a2 = w * w - sig * sig;
        let b2 = V::<N>::splat(2.0) * sig * w;
        let wg = w * spin * V::<N>::splat(kc.ip);
        let sgg = sig * spin * V::<N>::splat(kc.ip);
        let mut nr = [0usize; 2];
        for r in 0..p.runs {
            let mut q = [Z::<N>::zero(); 4];
            let mut e = [Z::<N>::zero(); 4];
            if contiguous {
                let o = bi[0].1 * 4;
                let src = &p.q[bi[0].0 * p.runs + r][o..o + 4 * N];
                for l in 0..N {
                    for dd in 0..4 {
                        q[dd].re.0[l] = src[4 * l + dd].re;
                        q[dd].im.0[l] = src[4 * l + dd].im;
                    }
                }
            } else {
                for l in 0..N {
                    let (b, i) = bi[l];
                    let blk = p.q[b * p.runs + r];
                    for dd in 0..4 {
                        let v = blk[i * 4 + dd];
                        q[dd].re.0[l] = v.re;
                        q[dd].im.0[l] = v.im;
                    }
                }
            }
            if let Some(t) = &p.planes {
                q = crate::model::planes_lanes(t, q);
            }
            if shared_e {
                for dd in 0..4 {
                    let ev = p.e[r * 4 + dd];
                    e[dd] = Z { re: V::<N>::splat(ev.re), im: V::<N>::splat(ev.im) };
                }
            } else {
                for l in 0..N {
                    let eo = (bi[l].0 * p.runs + r) * 4;
                    for dd in 0..4 {
                        e[dd].re.0[l] = p.e[eo + dd].re;
                        e[dd].im.0[l] = p.e[eo + dd].im;
                    }
                }
            }
            // the inertia acts on the absolute motion: q + q_ped with flexible pedestals
            let mut qa = q;
            if !p.q_ped.is_empty() {
                for l in 0..N {
                    let (b, i) = bi[l];
                    let blk = p.q_ped[b * p.runs + r];
                    for dd in 0..4 {
                        let v = blk[i * 4 + dd];
                        qa[dd].re.0[l] += v.re;
                        qa[dd].im.0[l] += v.im;
                    }
                }
            }
            // R = E + w^2 M q - j w Omega G q (eq. 10 / 26), M and G sparse (eq. 3)
            // (products that are added or subtracted are fused multiply-adds, as in `registers`)
            let m0 = qa[0].scale_add(ml2, qa[1].scale(ml1));
            let m1 = qa[2].scale_add(ml2, qa[3].scale(ml1));
            let m2 = (qa[1] - qa[0]).scale(it);
            let m3 = (qa[2] - qa[3]).scale(it);
            let (g2, g3) = (qa[3] - qa[2], qa[1] - qa[0]);
            let mut rv0 = m0.scale_add(a2, e[0].scale(gain));
            let mut rv1 = m1.scale_add(a2, e[1].scale(gain));
            let mut rv2 = m2.scale_add(a2, e[2].scale(gain)).sub_jscale(g2, wg);
            let mut rv3 = m3.scale_add(a2, e[3].scale(gain)).sub_jscale(g3, wg);
            if windowed {
                rv0 = rv0 - m0.jscale(b2);
                rv1 = rv1 - m1.jscale(b2);
                rv2 = rv2 - m2.jscale(b2) - g2.scale(sgg);
                rv3 = rv3 - m3.jscale(b2) - g3.scale(sgg);
            }
            // Bearing reaction forces from the four rotor equations: rows 1 and 3 give
            // f1x + f2x = R1, -l1 f1x + l2 f2x = R3; rows 2 and 4 give f1y + f2y = R2,
            // l1 f1y - l2 f2y = R4 (eq. 3 and 10).
            let f1x = rv0.scale_sub(l2, rv2).scale(il);
            let f1y = rv1.scale_add(l2, rv3).scale(il);
            let f2x = rv0.scale_add(l1, rv2).scale(il);
            let f2y = rv1.scale_sub(l1, rv3).scale(il);
            // stored field by field (a whole [Z; 4] temporary went through memcpy)
            put_row(&mut rows[0][nr[0]], q[0], q[2], f1x, f1y);
            nr[0] += 1;
            let s2 = if p.identical { 0 } else { 1 };
            put_row(&mut rows[s2][nr[s2]], q[1], q[3], f2x, f2y);
            nr[s2] += 1;
        }
        // SAFETY: S is Plain, or WithFma on an FMA CPU (this function's contract)
        unsafe {
            S::solve(&rows[0][..nr[0]], kc.refine_cond, &mut sols[0]);
            S::solve(&rows[1][..nr[1]], kc.refine_cond, &mut sols[1]);
        }
        // rows of the systems together hold every entry of q and E: a NaN/inf input shows up here
        let mut bad = [false; N];
        for l in 0..N {
            bad[l] = !(sols[0].total.0[l] + if p.identical { 0.0 } else { sols[1].total.0[l] }).is_finite();
        }
        for sb in 0..nsys {
            for l in 0..nl {
                if !(sols[sb].cond.0[l] < CSNE_COND) {
                    givens_lane(&rows[sb][..nr[sb]], l, &mut sols[sb]);
                }
            }
        }
        if p.identical {
            sols[1] = sols[0];
        }
        // lane-form outputs, then one scatter per lane
        let iw = w.recip();
        let mut kv = [V::<N>::zero(); 8];
        let mut cv = [V::<N>::zero(); 8];
        let mut sv = [V::<N>::zero(); 8];
        let want_std = ks.is_some() && cs.is_some();
        for sb in 0..2 {
            let s = &sols[sb];
            let dof = nr[if p.identical { 0 } else { sb }] as f64 - 2.0;
            for row in 0..2 {
                let var_half = s.res2[row] * V::<N>::splat(if dof > 0.0 { 0.5 / dof } else { f64::NAN });
                for col in 0..2 {
                    let o = 4 * sb + 2 * row + col;
                    // Z = K + s C = (K + sigma C) + j w C
                    cv[o] = s.z[row][col].im * iw;
                    kv[o] = s.z[row][col].re - sig * cv[o];
                    if want_std {
                        sv[o] = (var_half * s.g[col]).sqrt();
                    }
                }
            }
        }
        let res_tot = sols[0].res2[0] + sols[0].res2[1] + if p.identical { V::<N>::zero() } else { sols[1].res2[0] + sols[1].res2[1] };
        let rhs_tot = sols[0].rhs2[0] + sols[0].rhs2[1] + if p.identical { V::<N>::zero() } else { sols[1].rhs2[0] + sols[1].rhs2[1] };
        let rel = (res_tot * rhs_tot.recip()).sqrt();
        let qsum = sols[0].qq + if p.identical { V::<N>::zero() } else { sols[1].qq };
        let rms = (qsum * V::<N>::splat(1.0 / (4.0 * p.runs as f64))).sqrt();
        // singular systems and non-finite input give NaN coefficients
        let mut nanm = [[false; N]; 2];
        for sb in 0..2 {
            for l in 0..N {
                nanm[sb][l] = !(sols[sb].cond.0[l] < SINGULAR_COND) || bad[l];
            }
        }
        if nanm.iter().flatten().any(|&m| m) {
            for o in 0..8 {
                for l in 0..N {
                    if nanm[o / 4][l] {
                        kv[o].0[l] = f64::NAN;
                        cv[o].0[l] = f64::NAN;
                        sv[o].0[l] = f64::NAN;
                    }
                }
            }
        }
        let mut csv = [V::<N>::zero(); 8];
        let kfac = (V::<N>::splat(1.0) + sig * sig * iw * iw).sqrt(); // var(K) = var(Re Z) (1 + (sigma/w)^2)
        for o in 0..8 {
            csv[o] = sv[o] * iw;
            sv[o] = sv[o] * kfac;
        }
        // lanes -> rows of 8 values per point (an 8 x N transpose), stored as one block
        put_rows(k, g0, nl, &kv);
        put_rows(c, g0, nl, &cv);
        if let (Some(ks), Some(cs)) = (ks.as_deref_mut(), cs.as_deref_mut()) {
            put_rows(ks, g0, nl, &sv);
            put_rows(cs, g0, nl, &csv);
            if let Some(rel_out) = rel_out.as_deref_mut() {
                relative_std_rows(rel_out, k, c, ks, cs, g0..g0 + nl);
            }
        }
        for l in 0..nl {
            let t = g0 + l;
            let nan = [nanm[0][l], nanm[1][l]];
            for sb in 0..2 {
                cond[2 * t + sb] = if nan[sb] && !bad[l] { f64::INFINITY } else if bad[l] { f64::NAN } else { sols[sb].cond.0[l] };
            }
            resid[t] = if bad[l] || !(rhs_tot.0[l] > 0.0) { f64::NAN } else { rel.0[l] };
            amp[t] = rms.0[l];
            if bad[l] {
                nbad += 1;
            }
        }
    }
    nbad
}

/// [`solve_lanes`] as a function of its own: inlined into the group loop, its values spilled.
#[inline(never)]
fn solve_apart<const N: usize>(rows: &[[Z<N>; 4]], refine_cond: f64, out: &mut LaneSol<N>) {
    *out = solve_lanes(rows, refine_cond);
}

/// [`solve_apart`] compiled with the FMA instruction, which its fused multiply-adds then are (in
/// [`solve_apart`] they are calls of the C library's `fma`: with glibc the same bits, 10x slower).
///
/// # Safety
/// Only on a CPU with FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "fma")]
#[inline(never)]
unsafe fn solve_apart_fma<const N: usize>(rows: &[[Z<N>; 4]], refine_cond: f64, out: &mut LaneSol<N>) {
    *out = solve_lanes(rows, refine_cond);
}

/// Which [`solve_apart`] the generic kernel calls.
trait SolveApart {
    /// # Safety
    /// As the implementation's function.
    unsafe fn solve<const N: usize>(rows: &[[Z<N>; 4]], refine_cond: f64, out: &mut LaneSol<N>);
}

/// [`solve_apart`], for any CPU.
struct Plain;
impl SolveApart for Plain {
    unsafe fn solve<const N: usize>(rows: &[[Z<N>; 4]], refine_cond: f64, out: &mut LaneSol<N>) {
        solve_apart(rows, refine_cond, out)
    }
}

/// [`solve_apart_fma`], for CPUs with FMA only.
#[cfg(target_arch = "x86_64")]
struct WithFma;
#[cfg(target_arch = "x86_64")]
impl SolveApart for WithFma {
    unsafe fn solve<const N: usize>(rows: &[[Z<N>; 4]], refine_cond: f64, out: &mut LaneSol<N>) {
        solve_apart_fma(rows, refine_cond, out)
    }
}

/// The generic kernel (2 lanes) compiled with the FMA instruction, for the baseline level on an
/// x86-64 CPU that has it.
///
/// # Safety
/// Only on a CPU with FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "fma")]
unsafe fn forces_chunk_fma(p: &IdentProblem, kc: &Consts, start: usize, out: Outs) -> usize {
    // SAFETY: the caller's contract: the CPU has FMA
    unsafe { forces_chunk::<2, WithFma>(p, kc, start, out) }
}

/// [`forces_chunk`] for this CPU: the kernel written on registers ([`registers`]) with 8 lanes
/// of AVX-512 ([`avx512`]) or 4 of AVX2 ([`avx2`]), 2 lanes of the build's baseline elsewhere
/// (compiled with the FMA instruction on an x86-64 CPU that has it, [`forces_chunk_fma`]); the
/// same operations lane by lane, fused multiply-adds included, so the same values (property
/// tests and CI's bit digest compare them, on aarch64 too; the property tests' generic kernel is
/// this `Plain` path, which an x86-64 CPU without FMA runs). On such a CPU the baseline's fused
/// multiply-adds are the C library's `fma`: with glibc (correctly rounded in software) the same
/// bits, about 10x slower; some other C libraries' `fma` is not correctly rounded there
/// (measured as calls on this FMA CPU: 98 against 885 ns per point).
///
/// History (one thread, 4,096 points from 4 runs, `examples/identify_points`, ns per point):
/// - AMD EPYC (Zen 4), best of 12-20 interleaved runs: generic lanes, 8 wide with the solver
///   inlined (the first kernel): AVX-512 code 112-120, AVX2 code 115-125 (every value in two AVX2
///   registers: the loop spilled them); generic lanes, 4 wide with the solver a function of its
///   own: AVX2 code 89-92 (compiled for AVX-512 on the same CPU 133; 8 wide, AVX-512 code
///   146-149); baseline 159-161 with 2 lanes; [`avx2`], transposes in and out, the flags as lane
///   masks, the solver on registers: 63.4 (1,181 -> 851 instructions per point); with 2 runs
///   46.3 -> 27.0 (571 -> 346). So the AVX-512 CPUs ran the AVX2 code until the register kernel
///   had an 8-lane version.
/// - Intel Xeon (eighth session), best of 3-5 interleaved runs: the register kernel at 4 lanes of
///   AVX2 63-65, at 8 lanes of AVX-512 47-49 (with standard errors 78-80 and 63-65; 2 runs 27.5
///   and 20.8); with the pointers' closure inlined 61-65 and 44-45; with the refinement step
///   only from [`REFINE_COND`] on 54-57 and 39-41 (2 runs, no refinement there: 28-30 and
///   20-21). Not measured on Zen 4, whose 512-bit operations are two 256-bit halves.
/// - Intel Xeon (thirteenth session), min of 7 interleaved runs: 49.3 (AVX2) and 33 (AVX-512);
///   the layout branches out of the common case, the rows' responses stored before the forces
///   and the solve inlined 43.5-44.5 and 33; fused multiply-adds in the row loops 37.4-38.7 and
///   28.5-29.2, and in the forces too 36.8 and 28.1. Baseline 91 -> 98.
fn forces_chunk_dispatch(p: &IdentProblem, kc: &Consts, start: usize, out: Outs) -> usize {
    match crate::lanes::simd() {
        // SAFETY: simd() reports AVX2 and FMA at the Avx2 level; CPUs with AVX-512 F and DQ have
        // them too (every kernel's AVX-512 version is compiled with them enabled).
        #[cfg(target_arch = "x86_64")]
        crate::lanes::Simd::Avx512 => unsafe { avx512::forces_chunk(p, kc, start, out) },
        #[cfg(target_arch = "x86_64")]
        crate::lanes::Simd::Avx2 => unsafe { avx2::forces_chunk(p, kc, start, out) },
        _ => {
            // SAFETY: the CPU has FMA
            #[cfg(target_arch = "x86_64")]
            if std::is_x86_feature_detected!("fma") {
                return unsafe { forces_chunk_fma(p, kc, start, out) };
            }
            // SAFETY: Plain needs no CPU feature
            unsafe { forces_chunk::<2, Plain>(p, kc, start, out) }
        }
    }
}

/// Fast bearing-force solver. Returns the number of points whose input contained NaN/inf.
pub fn identify_forces(p: &IdentProblem, out: IdentOut) -> Result<usize, CoreError> {
    identify_forces_refined(p, out, REFINE_COND)
}

/// [`identify_forces`] with the refinement step in the lanes whose condition number reaches
/// `refine_cond` (0: in every lane, as the uncertainty propagation's central differences take
/// it; [`REFINE_COND`] is the default).
pub fn identify_forces_refined(p: &IdentProblem, out: IdentOut, refine_cond: f64) -> Result<usize, CoreError> {
    p.check()?;
    out.check(product("batch x points", &[p.batch, p.points()])?)?;
    if refine_cond.is_nan() {
        return Err(CoreError::value("refine_cond", "must not be NaN"));
    }
    Ok(forces_all(p, out, refine_cond))
}

fn forces_all(p: &IdentProblem, out: IdentOut, refine_cond: f64) -> usize {
    let kc = Consts { refine_cond, ..Consts::new(&p.rotor) };
    let IdentOut { k, c, cond, resid, amp, k_std, c_std, rel_std } = out;
    let npts = resid.len();
    if npts < SERIAL_BELOW {
        return forces_chunk_dispatch(p, &kc, 0, Outs { k, c, cond, resid, amp, ks: k_std, cs: c_std, rel: rel_std });
    }
    // tasks of CHUNK points, the calling thread working from the start (crate::par)
    let (k, c, cond, resid, amp) = (Disjoint::new(k), Disjoint::new(c), Disjoint::new(cond), Disjoint::new(resid), Disjoint::new(amp));
    let (ks, cs, rs) = (k_std.map(Disjoint::new), c_std.map(Disjoint::new), rel_std.map(Disjoint::new));
    crate::par::sum_tasks(npts.div_ceil(CHUNK), |j| {
        // SAFETY: sum_tasks hands each chunk index j to one task
        let outs = unsafe {
            Outs {
                k: k.chunk(j, 8 * CHUNK),
                c: c.chunk(j, 8 * CHUNK),
                cond: cond.chunk(j, 2 * CHUNK),
                resid: resid.chunk(j, CHUNK),
                amp: amp.chunk(j, CHUNK),
                ks: ks.as_ref().map(|d| d.chunk(j, 8 * CHUNK)),
                cs: cs.as_ref().map(|d| d.chunk(j, 8 * CHUNK)),
                rel: rs.as_ref().map(|d| d.chunk(j, CHUNK)),
            }
        };
        forces_chunk_dispatch(p, &kc, j * CHUNK, outs)
    })
}

/// 2-norm condition number of a real matrix from its singular values. faer's SVD has been seen to
/// return an error (no convergence) on a well-conditioned 16 x 16 case; fall back to the
/// eigenvalues of B^T B (squares the condition number, adequate for a diagnostic below 1e7).
fn real_cond(bm: &Mat<f64>) -> f64 {
    if let Ok(sv) = bm.singular_values() {
        let (a, z) = (sv.iter().cloned().fold(0.0, f64::max), sv.iter().cloned().fold(f64::INFINITY, f64::min));
        return if z > 0.0 { a / z } else { f64::INFINITY };
    }
    let btb = bm.transpose() * bm;
    match btb.self_adjoint_eigenvalues(faer::Side::Lower) {
        Ok(ev) => {
            let (a, z) = (ev.iter().cloned().fold(0.0, f64::max), ev.iter().cloned().fold(f64::INFINITY, f64::min));
            if z > 0.0 {
                (a / z).sqrt()
            } else {
                f64::INFINITY
            }
        }
        Err(_) => f64::INFINITY,
    }
}

/// Report index (eq. 9 order Kxx1, Kxx2, Kxy1, Kxy2, Kyx1, Kyx2, Kyy1, Kyy2) -> [bearing][i][j].
pub const REPORT_TO_BIJ: [usize; 8] = [0, 4, 1, 5, 2, 6, 3, 7];

/// The report's 16-unknown real least-squares formulation (eq. 8, 12, 16-18), solved by QR.
/// For `identical`, the 8-unknown variant (Z1 = Z2). cond receives the condition number of the
/// real stacked matrix (same value for both bearings). Returns the number of NaN/inf points.
/// Standard errors are not computed (`k_std`, `c_std` are left untouched).
pub fn identify_report(p: &IdentProblem, out: IdentOut) -> Result<usize, CoreError> {
    p.check()?;
    if !p.identical && p.runs < 2 {
        // 8 real equations for 16 unknowns: the least-squares solver would fail an assertion
        return Err(CoreError::value("runs", "the report formulation needs at least two runs (one with identical bearings)"));
    }
    out.check(product("batch x points", &[p.batch, p.points()])?)?;
    Ok(report_all(p, out))
}

fn report_all(p: &IdentProblem, out: IdentOut) -> usize {
    let IdentOut { k, c, cond, resid, amp, .. } = out;
    let kc = Consts::new(&p.rotor);
    (k.par_chunks_mut(8), c.par_chunks_mut(8), cond.par_chunks_mut(2), resid.par_iter_mut(), amp.par_iter_mut())
        .into_par_iter()
        .with_min_len(64)
        .enumerate()
        .map(|(idx, (k, c, cond, resid, amp))| report_point(p, &kc, idx, k, c, cond, resid, amp))
        .sum()
}

/// Both solvers on one thread, for callers that are tasks of a parallel loop themselves (the
/// perturbed copies of [`propagate`]); the values of [`identify_forces`] with the refinement step
/// in every lane (below [`REFINE_COND`] the semi-normal equations' rounding, ~cond^2 eps, would
/// be divided by the central differences' step, ~1e-6: the refined solution is smooth in the
/// inputs to ~cond eps), and of [`identify_report`] (each point is solved alone). Standard errors
/// are not computed. Returns the number of NaN/inf points. `p` must have passed
/// [`IdentProblem::check`].
pub(crate) fn identify_serial(p: &IdentProblem, report: bool, out: IdentOut) -> usize {
    let kc = Consts { refine_cond: 0.0, ..Consts::new(&p.rotor) };
    let IdentOut { k, c, cond, resid, amp, .. } = out;
    if !report {
        return forces_chunk_dispatch(p, &kc, 0, Outs { k, c, cond, resid, amp, ks: None, cs: None, rel: None });
    }
    let mut nbad = 0;
    for (idx, (((k, c), cond), (resid, amp))) in k.chunks_mut(8).zip(c.chunks_mut(8)).zip(cond.chunks_mut(2)).zip(resid.iter_mut().zip(amp.iter_mut())).enumerate() {
        nbad += report_point(p, &kc, idx, k, c, cond, resid, amp);
    }
    nbad
}

/// [`identify_report`] at flat point `idx` (= b n + i) into its outputs (8, 8, 2, 1, 1 values).
#[allow(clippy::too_many_arguments)]
fn report_point(p: &IdentProblem, kc: &Consts, idx: usize, k: &mut [f64], c: &mut [f64], cond: &mut [f64], resid: &mut f64, amp: &mut f64) -> usize {
    let n = p.w.len();
    let (l1, l2) = (p.rotor.l1, p.rotor.l2);
    let nu = if p.identical { 8 } else { 16 };
    let (b, i) = (idx / n, idx % n);
    let rows = 8 * p.runs;
    let mut bm = Mat::<f64>::zeros(rows, nu);
    let mut fv = Mat::<f64>::zeros(rows, 1);
    let mut bad = false;
    let mut qq = 0.0;
    for r in 0..p.runs {
        let q = load_q(p, b, r, i);
        for v in q.iter() {
            bad |= !(v.re.is_finite() && v.im.is_finite());
            qq += v.norm_sqr();
        }
        let si = if p.spin.len() == 1 { 0 } else { i };
        let qa = load_abs(p, b, r, i);
        bad |= !qa.iter().all(|v| v.re.is_finite() && v.im.is_finite());
        let rv = rhs_point(kc, excitation(p, b, r), gain_at(p, i), p.w[i], sigma_at(p, i), p.spin[si], &qa);
        // Q of eq. 8 (4 x 16 complex), columns in eq. 9 order
        let lq = [-l1 * q[0], l2 * q[1], -l1 * q[2], l2 * q[3]];
        let mut qm = [[C64::new(0.0, 0.0); 16]; 4];
        let jj = C64::new(0.0, 1.0);
        for t in 0..4 {
            qm[0][t] = q[t];
            qm[0][8 + t] = jj * q[t];
            qm[1][4 + t] = q[t];
            qm[1][12 + t] = jj * q[t];
            qm[2][t] = lq[t];
            qm[2][8 + t] = jj * lq[t];
            qm[3][4 + t] = -lq[t];
            qm[3][12 + t] = -jj * lq[t];
        }
        for row in 0..4 {
            for col in 0..16 {
                // identical bearings: Kxx1 = Kxx2 etc., i.e. columns 2m and 2m+1 merge
                let cc = if p.identical { col / 2 } else { col };
                bm[(8 * r + row, cc)] += qm[row][col].re;
                bm[(8 * r + 4 + row, cc)] += qm[row][col].im;
            }
            fv[(8 * r + row, 0)] = rv[row].re;
            fv[(8 * r + 4 + row, 0)] = rv[row].im;
        }
    }
    *amp = (qq / (4.0 * p.runs as f64)).sqrt();
    if bad {
        for v in k.iter_mut().chain(c.iter_mut()) {
            *v = f64::NAN;
        }
        cond[0] = f64::NAN;
        cond[1] = f64::NAN;
        *resid = f64::NAN;
        return 1usize;
    }
    let cn = real_cond(&bm);
    cond[0] = cn;
    cond[1] = cn;
    let w = p.w[i];
    if !(cn < SINGULAR_COND) {
        for v in k.iter_mut().chain(c.iter_mut()) {
            *v = f64::NAN;
        }
        *resid = f64::NAN;
        return 0usize;
    }
    let sol = bm.qr().solve_lstsq(&fv);
    let pv: Vec<f64> = if p.identical {
        (0..16).map(|t| sol[(t / 2, 0)]).collect()
    } else {
        (0..16).map(|t| sol[(t, 0)]).collect()
    };
    for t in 0..8 {
        c[REPORT_TO_BIJ[t]] = pv[8 + t] / w;
        k[REPORT_TO_BIJ[t]] = pv[t] - sigma_at(p, i) * pv[8 + t] / w;
    }
    let fit = &bm * &sol;
    let mut rr = 0.0;
    let mut ff = 0.0;
    for row in 0..rows {
        rr += (fit[(row, 0)] - fv[(row, 0)]).powi(2);
        ff += fv[(row, 0)].powi(2);
    }
    *resid = if ff > 0.0 { (rr / ff).sqrt() } else { f64::NAN };
    0usize
}

/// Bearing reaction forces from the rotor equations, per (batch, run, point):
/// [f1x, f2x, f1y, f2y] (N, or N per newton of impact for unit-force FRFs), the force each
/// bearing exerts on the journal's housing (and, reversed, on the rotor): rows 1 and 3 of eq. 3
/// give f1x + f2x = R1, -l1 f1x + l2 f2x = R3, rows 2 and 4 f1y + f2y = R2, l1 f1y - l2 f2y = R4,
/// with R = E - s^2 M q_abs - s Omega G q_abs and q_abs = q + q_ped. `out`: (batch, runs, n, 4).
pub fn bearing_forces(p: &IdentProblem, out: &mut [C64]) -> Result<(), CoreError> {
    p.check()?;
    let n = p.points();
    expect_len("out", out, product("out", &[p.batch, p.runs, n, 4])?)?;
    let kc = Consts::new(&p.rotor);
    let fill = |first: usize, o: &mut [C64]| {
        for (t, f) in o.chunks_exact_mut(4).enumerate() {
            let idx = first + t;
            let (br, i) = (idx / n, idx % n);
            let (b, r) = (br / p.runs, br % p.runs);
            f.copy_from_slice(&force_point(p, &kc, b, r, i));
        }
    };
    let out = Disjoint::new(out);
    // SAFETY: for_each_task hands each chunk index j to one task
    crate::par::for_each_task((p.batch * p.runs * n).div_ceil(CHUNK), |j| fill(j * CHUNK, unsafe { out.chunk(j, 4 * CHUNK) }));
    Ok(())
}

/// [f1x, f2x, f1y, f2y] of (batch b, run r, point i), as [`bearing_forces`] (a checked problem).
#[inline(always)]
pub(crate) fn force_point(p: &IdentProblem, kc: &Consts, b: usize, r: usize, i: usize) -> [C64; 4] {
    let si = if p.spin.len() == 1 { 0 } else { i };
    let qa = load_abs(p, b, r, i);
    let rv = rhs_point(kc, excitation(p, b, r), gain_at(p, i), p.w[i], sigma_at(p, i), p.spin[si], &qa);
    [
        (rv[0] * kc.l2 - rv[2]) * kc.il,
        (rv[2] + rv[0] * kc.l1) * kc.il,
        (rv[1] * kc.l2 + rv[3]) * kc.il,
        (rv[1] * kc.l1 - rv[3]) * kc.il,
    ]
}

/// The part of the bearing forces [f1x, f2x, f1y, f2y] that moves with the absolute motion q_abs
/// of a point (as [`force_point`] forms them, the excitation left out):
/// R = -s^2 M q_abs - s Omega G q_abs mapped to the bearings, complex-linear in q_abs.
pub(crate) fn motion_forces(kc: &Consts, w: f64, sigma: f64, spin: f64, qa: &[C64; 4]) -> [C64; 4] {
    let rv = rhs_point(kc, &[C64::new(0.0, 0.0); 4], 0.0, w, sigma, spin, qa);
    [
        (rv[0] * kc.l2 - rv[2]) * kc.il,
        (rv[2] + rv[0] * kc.l1) * kc.il,
        (rv[1] * kc.l2 + rv[3]) * kc.il,
        (rv[1] * kc.l1 - rv[3]) * kc.il,
    ]
}

/// NaN-propagating maximum (as NumPy's `maximum`): a NaN anywhere makes the result NaN.
#[inline(always)]
fn max_nan(a: f64, b: f64) -> f64 {
    if a.is_nan() || b.is_nan() {
        f64::NAN
    } else if a > b {
        // `maxpd`'s rule, b when equal: f64::max may return either zero for (0, -0), and the
        // lanes' maximum (`Regs::max_nan`) must get the same bits
        a
    } else {
        b
    }
}

/// Largest standard error per point relative to its bearing's direct coefficients:
///     max over bearings b and over (K, C) of  max_ij std(Z_b,ij) / sqrt(|Z_b,xx Z_b,yy|),
/// so that small cross-coupled terms are judged on the bearing's scale (a zero standard error is
/// relative error 0, a non-zero one on zero direct coefficients is inf). `k`, `c`, `k_std`,
/// `c_std`: (points, 8) in [bearing][i][j] order; `out`: (points,). NaN where any input is NaN.
pub fn relative_std(k: &[f64], c: &[f64], k_std: &[f64], c_std: &[f64], out: &mut [f64]) -> Result<(), CoreError> {
    let n = out.len();
    for (name, a) in [("k", k), ("c", c), ("k_std", k_std), ("c_std", c_std)] {
        expect_len(name, a, product(name, &[n, 8])?)?;
    }
    let out = Disjoint::new(out);
    crate::par::for_each_task(n.div_ceil(CHUNK), |j| {
        // SAFETY: for_each_task hands each chunk index j to one task
        for (t, o) in unsafe { out.chunk(j, CHUNK) }.iter_mut().enumerate() {
            let i = j * CHUNK + t;
            let at = |a: &[f64]| -> [f64; 8] { a[8 * i..8 * i + 8].try_into().unwrap() };
            *o = relative_std_point(&at(k), &at(c), &at(k_std), &at(c_std));
        }
    });
    Ok(())
}

/// [`relative_std_point`] of the points `pts` of the (points, 8) rows just written by a kernel.
#[inline(always)]
fn relative_std_rows(out: &mut [f64], k: &[f64], c: &[f64], ks: &[f64], cs: &[f64], pts: std::ops::Range<usize>) {
    for t in pts {
        let at = |a: &[f64]| -> [f64; 8] { a[8 * t..8 * t + 8].try_into().unwrap() };
        out[t] = relative_std_point(&at(k), &at(c), &at(ks), &at(cs));
    }
}

/// [`relative_std`] of one point (the identification kernel calls it on the values it has just
/// written, so both give the same bits).
#[inline(always)]
fn relative_std_point(k: &[f64; 8], c: &[f64; 8], k_std: &[f64; 8], c_std: &[f64; 8]) -> f64 {
    let mut worst = f64::NEG_INFINITY;
    for (v, sd) in [(k, k_std), (c, c_std)] {
        for b in 0..2 {
            let (z, s) = (&v[4 * b..4 * b + 4], &sd[4 * b..4 * b + 4]);
            let scale = (z[0] * z[3]).abs().sqrt();
            let top = max_nan(max_nan(s[0], s[1]), max_nan(s[2], s[3]));
            // no error at all is relative error 0 whatever the scale (0 / 0 is not unknown)
            worst = max_nan(worst, if top == 0.0 { 0.0 } else { top / scale });
        }
    }
    worst
}

/// Largest value, NaN if any value is NaN (as NumPy's `max`), -inf when empty. Eight independent
/// accumulators whose update is exactly `maxpd`, so the loop vectorizes; NaN is tracked apart.
fn max_propagating_nan(a: &[f64]) -> f64 {
    let mut acc = [f64::NEG_INFINITY; 8];
    let mut nan = [false; 8];
    let chunks = a.chunks_exact(8);
    let rest = chunks.remainder();
    for c in chunks {
        for l in 0..8 {
            acc[l] = if acc[l] > c[l] { acc[l] } else { c[l] };
            nan[l] |= c[l].is_nan();
        }
    }
    let mut top = f64::NEG_INFINITY;
    for &v in rest.iter().chain(acc.iter()) {
        if v.is_nan() {
            return f64::NAN;
        }
        top = top.max(v);
    }
    if nan.iter().any(|&x| x) {
        f64::NAN
    } else {
        top
    }
}

/// Points per parallel task of [`flag_codes`], and the fewest points it runs in parallel.
const PAR_CHUNK: usize = 1 << 13;
const PAR_FROM: usize = 1 << 15;

/// Flag bits of [`flag_codes`], in the order the reasons are reported.
pub const FLAG_SINGULAR: u8 = 1;
pub const FLAG_ILL_CONDITIONED: u8 = 2;
pub const FLAG_UNCERTAIN: u8 = 4;
pub const FLAG_LOW_AMPLITUDE: u8 = 8;
pub const FLAG_NEGATIVE_DAMPING: u8 = 16;

/// Thresholds of [`flag_codes`] and the peak amplitude.
struct FlagLimits {
    peak: f64,
    cond_max: f64,
    min_rel_amplitude: f64,
    max_rel_std: f64,
}

/// The flags of a run of points: branch-free per point (the comparisons are false for NaN) over
/// zipped slices (no bounds checks), so the loop vectorizes. `rs` None: the standard errors are
/// unknown (no point is "uncertain"; a separate loop, no buffer of NaN to read). `ok` receives
/// code == 0.
#[inline(always)]
fn flag_pass(lim: &FlagLimits, cond: &[f64], amp: &[f64], rs: Option<&[f64]>, rel: &mut [f64], code: &mut [u8], ok: &mut [bool]) {
    let peak = lim.peak;
    let has_peak = peak > 0.0; // every amplitude 0, or one NaN (no peak): relative amplitude 0
    let one = |c: &[f64], a: f64, s: f64, r: &mut f64, o: &mut u8, k: &mut bool| {
        let (c0, c1) = (c[0], c[1]);
        let finite = c0.is_finite() & c1.is_finite();
        let worst = if c0 > c1 { c0 } else { c1 };
        let ra = if has_peak { a / peak } else { 0.0 };
        *r = ra;
        let bits = (!finite as u8) * FLAG_SINGULAR
            | ((finite & (worst > lim.cond_max)) as u8) * FLAG_ILL_CONDITIONED
            | ((finite & (s > lim.max_rel_std)) as u8) * FLAG_UNCERTAIN
            | ((ra < lim.min_rel_amplitude) as u8) * FLAG_LOW_AMPLITUDE;
        *o = bits;
        *k = bits == 0;
    };
    match rs {
        Some(rs) => {
            for (((((c, &a), &s), r), o), k) in
                cond.chunks_exact(2).zip(amp).zip(rs).zip(rel.iter_mut()).zip(code.iter_mut()).zip(ok.iter_mut())
            {
                one(c, a, s, r, o, k);
            }
        }
        None => {
            for ((((c, &a), r), o), k) in cond.chunks_exact(2).zip(amp).zip(rel.iter_mut()).zip(code.iter_mut()).zip(ok.iter_mut()) {
                one(c, a, f64::NAN, r, o, k);
            }
        }
    }
}

/// The significance level of the "negative direct damping" test: Φ(−2) = 0.0228, the probability
/// that a normal estimate lies more than 2 standard errors below its mean (one-sided).
pub const NEGATIVE_DAMPING_LEVEL: f64 = 0.022_750_131_948_179_2;

/// Whether a direct damping `d` with standard error `s` estimated with `dof` degrees of freedom is
/// significantly below zero: `F_t(d / s; dof) < Φ(−2)` (Student's t; the normal, d < −2 s, where
/// `dof` is +inf, NaN or ≤ 0, i.e. known or of unknown quality), or `d < 0` where `s` is unknown
/// (NaN). With 2 dof the threshold is 4.50 standard errors, with 4 dof 2.87: a fixed 2 flagged
/// 9 % and 6 % of zero dampings there instead of 2.3 %. False for NaN `d`. Where the same dof
/// comes twice in a row the threshold `t = F⁻¹(Φ(−2); dof)` is found (~100 evaluations of F) and
/// kept, so a pass where every point is a candidate (a probe reversed in every run) costs a
/// comparison per point; dof that change from point to point cost one evaluation of F each.
#[derive(Clone, Copy, Debug)]
pub struct NegativeDampingTest {
    dof: f64,
    threshold: f64,
    seen: f64,
}

impl Default for NegativeDampingTest {
    fn default() -> Self {
        NegativeDampingTest { dof: f64::INFINITY, threshold: -2.0, seen: f64::NAN }
    }
}

impl NegativeDampingTest {
    /// The test's threshold in standard errors at `dof` (−2 at +inf, NaN or ≤ 0).
    pub fn threshold(dof: f64) -> f64 {
        if !(dof > 0.0 && dof < f64::INFINITY) {
            return -2.0;
        }
        crate::student_t::student_t_quantile(NEGATIVE_DAMPING_LEVEL, dof)
    }

    /// Whether `d` (standard error `s`, `dof` degrees of freedom) is significantly below zero.
    #[inline(always)]
    pub fn is_negative(&mut self, d: f64, s: f64, dof: f64) -> bool {
        if s.is_nan() {
            return d < 0.0;
        }
        // Student's t quantile is never above the normal's: points within 2 standard errors pass
        // without the threshold
        let margin = d + 2.0 * s;
        if margin.is_nan() || margin >= 0.0 {
            return false;
        }
        let dof = if dof > 0.0 && dof < f64::INFINITY { dof } else { f64::INFINITY };
        if dof != self.dof {
            if dof != self.seen {
                self.seen = dof;
                return crate::student_t::student_t_cdf(d / s, dof) < NEGATIVE_DAMPING_LEVEL;
            }
            self.dof = dof;
            self.threshold = Self::threshold(dof);
        }
        d / s < self.threshold
    }
}

/// The "negative direct damping" bit over a run of points: C_xx or C_yy of either bearing (flat
/// positions 0, 3, 4, 7 of a point's [bearing, i, j]) significantly below zero
/// ([`NegativeDampingTest`]) with the degrees of freedom of its standard error (`dof`: empty =
/// +inf, one value for every point, one per point, or one per coefficient (n, 2, 2, 2)), or below
/// zero where the error is unknown (NaN, or `c_std` None); false for NaN coefficients.
#[inline(always)]
fn damping_pass(c: &[f64], c_std: Option<&[f64]>, dof: &[f64], code: &mut [u8], ok: &mut [bool]) {
    const DIRECT: [usize; 4] = [0, 3, 4, 7];
    let n = code.len();
    let dof_at = |i: usize, t: usize| match dof.len() {
        0 => f64::INFINITY,
        1 => dof[0],
        len if len == n => dof[i],
        _ => dof[8 * i + t],
    };
    let mut test = NegativeDampingTest::default();
    match c_std {
        Some(cs) => {
            for (i, (((cc, ss), o), k)) in c.chunks_exact(8).zip(cs.chunks_exact(8)).zip(code.iter_mut()).zip(ok.iter_mut()).enumerate() {
                let bad = DIRECT.iter().any(|&t| test.is_negative(cc[t], ss[t], dof_at(i, t)));
                *o |= (bad as u8) * FLAG_NEGATIVE_DAMPING;
                *k = *o == 0;
            }
        }
        None => {
            for ((cc, o), k) in c.chunks_exact(8).zip(code.iter_mut()).zip(ok.iter_mut()) {
                let bad = DIRECT.iter().any(|&t| cc[t] < 0.0);
                *o |= (bad as u8) * FLAG_NEGATIVE_DAMPING;
                *k = *o == 0;
            }
        }
    }
}

crate::lanes::simd_dispatch! {
    /// [`flag_pass`] at the widest SIMD level of this CPU.
    fn flag_pass_dispatch(lim: &FlagLimits, cond: &[f64], amp: &[f64], rs: Option<&[f64]>, rel: &mut [f64], code: &mut [u8], ok: &mut [bool]) -> () => flag_pass
}

/// Why each point should not be trusted, as bits, in one pass: singular (a condition number that
/// is inf or NaN), ill-conditioned (cond > `cond_max`), uncertain (`rel_std` > `max_rel_std`),
/// low amplitude (amp / max(amp) < `min_rel_amplitude`), negative direct damping (with `c`: a
/// direct damping coefficient significantly below zero, one-sided at the 2-standard-error level of
/// a normal with Student's t for the `dof` of `c_std` ([`NegativeDampingTest`]), or below zero
/// where the errors are unknown: a passive support dissipates, and a channel reversed in every run
/// leaves no residual but this). `cond`: (n, 2); `amp`: (n,); `rel_std`: (n,), or empty when the
/// standard errors are unknown (no point is then "uncertain"); `c`, `c_std`: (n, 2, 2, 2) damping
/// and its standard errors, or empty (no damping test; unknown errors); `dof`: the degrees of
/// freedom of `c_std`, empty (+inf), one for every point, (n,), or (n, 2, 2, 2) one per
/// coefficient; `rel_amp` receives
/// amp / max(amp) (0 when every amplitude is 0); `code`: (n,); `ok` (n,) receives code == 0 (the
/// points to trust).
#[allow(clippy::too_many_arguments)]
pub fn flag_codes(
    cond: &[f64],
    amp: &[f64],
    rel_std: &[f64],
    c: &[f64],
    c_std: &[f64],
    dof: &[f64],
    cond_max: f64,
    min_rel_amplitude: f64,
    max_rel_std: f64,
    rel_amp: &mut [f64],
    code: &mut [u8],
    ok: &mut [bool],
) -> Result<(), CoreError> {
    let n = code.len();
    expect_len("cond", cond, product("cond", &[n, 2])?)?;
    expect_len("amp", amp, n)?;
    if !rel_std.is_empty() {
        expect_len("rel_std", rel_std, n)?;
    }
    if !c.is_empty() {
        expect_len("c", c, product("c", &[n, 8])?)?;
    }
    if !c_std.is_empty() {
        expect_len("c_std", c_std, product("c_std", &[n, 8])?)?;
    }
    if dof.len() > 1 && dof.len() != n {
        expect_len("dof", dof, product("dof", &[n, 8])?)?;
    }
    expect_len("rel_amp", rel_amp, n)?;
    expect_len("ok", ok, n)?;
    let rel_std = if rel_std.is_empty() { None } else { Some(rel_std) };
    let c_std = if c_std.is_empty() { None } else { Some(c_std) };
    if n < PAR_FROM {
        // waking the pool costs more than the pass
        let lim = FlagLimits { peak: max_propagating_nan(amp), cond_max, min_rel_amplitude, max_rel_std };
        flag_pass_dispatch(&lim, cond, amp, rel_std, rel_amp, code, ok);
        if !c.is_empty() {
            damping_pass(c, c_std, dof, code, ok);
        }
        return Ok(());
    }
    // the peak in parallel too: a serial pass over amp was a third of the time at 100,000 points
    let nchunks = n.div_ceil(PAR_CHUNK);
    let mut peaks = vec![f64::NEG_INFINITY; nchunks];
    let chunk_peaks = Disjoint::new(&mut peaks);
    // SAFETY: for_each_task hands each chunk index j to one task
    crate::par::for_each_task(nchunks, |j| unsafe { chunk_peaks.chunk(j, 1) }[0] = max_propagating_nan(&amp[j * PAR_CHUNK..n.min((j + 1) * PAR_CHUNK)]));
    let peak = peaks.iter().fold(f64::NEG_INFINITY, |a, &b| max_nan(a, b));
    let lim = FlagLimits { peak, cond_max, min_rel_amplitude, max_rel_std };
    let (code, rel_amp, ok) = (Disjoint::new(code), Disjoint::new(rel_amp), Disjoint::new(ok));
    crate::par::for_each_task(nchunks, |j| {
        // SAFETY: as above
        let (oc, rc, ok) = unsafe { (code.chunk(j, PAR_CHUNK), rel_amp.chunk(j, PAR_CHUNK), ok.chunk(j, PAR_CHUNK)) };
        let (lo, hi) = (j * PAR_CHUNK, j * PAR_CHUNK + oc.len());
        flag_pass_dispatch(&lim, &cond[2 * lo..2 * hi], &amp[lo..hi], rel_std.map(|r| &r[lo..hi]), rc, oc, ok);
        if !c.is_empty() {
            let dof = match dof.len() {
                0 | 1 => dof,
                len if len == n => &dof[lo..hi],
                _ => &dof[8 * lo..8 * hi],
            };
            damping_pass(&c[8 * lo..8 * hi], c_std.map(|s| &s[8 * lo..8 * hi]), dof, oc, ok);
        }
    });
    Ok(())
}
