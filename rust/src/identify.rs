//! Identification of bearing impedances Z = K + j w C from responses to known excitations.
//!
//! Both identification methods of the report reduce, at every point (speed or frequency), to the
//! complex equation (eq. 10 / eq. 26)
//!     Q(q) P = R,   R = E + w^2 M q - j w Omega G q,
//! per run. Two solvers are provided:
//! - `identify_forces` (default): the four rotor equations give the reaction force of each
//!   bearing, and each bearing becomes a complex least-squares problem [x_b y_b] z = f_b with two
//!   unknowns and two right-hand sides (x row and y row of Z_b). Solved by a streaming complex
//!   Givens QR: one pass over the runs, no normal equations, O(1) memory per point.
//! - `identify_report`: the report's 16-unknown real formulation (eq. 8-12, 16-18) solved with
//!   faer's QR. Kept as the reference; it equals the default exactly for two runs.

use crate::model::{bearing_forces, Rotor, C64};
use faer::linalg::solvers::SolveLstsq;
use faer::Mat;
use rayon::prelude::*;

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

/// Solution of one bearing system: z[rhs][unknown], variance factors diag((A^H A)^-1),
/// condition number, residual and right-hand-side sums of squares per rhs, number of rows.
#[derive(Clone, Copy)]
struct Sol {
    z: [[C64; 2]; 2],
    g: [f64; 2],
    cond: f64,
    res2: [f64; 2],
    rhs2: [f64; 2],
    rows: usize,
}

/// Largest condition number solved through the corrected semi-normal equations; above it the
/// rows go through the Givens QR (backward stable up to SINGULAR_COND).
const CSNE_COND: f64 = 1e6;

/// Solve rows [x, y, f_x, f_y] (x z0 + y z1 = f_k) in the least-squares sense.
///
/// Fast path: 2x2 Hermitian normal equations in closed form plus one step of refinement with the
/// residual of the original rows (corrected semi-normal equations; as accurate as QR for
/// cond^2 * eps << 1, hence the CSNE_COND limit). No square root or division inside the loop.
#[inline(always)]
fn solve_rows(rows: &[[C64; 4]]) -> Sol {
    let (mut a, mut d) = (0.0f64, 0.0f64);
    let mut gxy = C64::new(0.0, 0.0);
    let mut h = [[C64::new(0.0, 0.0); 2]; 2]; // h[rhs][unknown] = A^H f
    let mut rhs2 = [0.0f64; 2];
    for r in rows {
        let (xc, yc) = (r[0].conj(), r[1].conj());
        a += r[0].norm_sqr();
        d += r[1].norm_sqr();
        gxy += xc * r[1];
        for k in 0..2 {
            h[k][0] += xc * r[2 + k];
            h[k][1] += yc * r[2 + k];
            rhs2[k] += r[2 + k].norm_sqr();
        }
    }
    let det = a * d - gxy.norm_sqr();
    let half = 0.5 * (a + d);
    let lmax = half + (0.25 * (a - d) * (a - d) + gxy.norm_sqr()).sqrt();
    let cond = if det > 0.0 { (lmax * lmax / det).sqrt() } else { f64::INFINITY };
    if !(cond < CSNE_COND) {
        let mut gv = Givens2::new();
        for r in rows {
            gv.push(r[0], r[1], [r[2], r[3]]);
        }
        let (z, g, cn) = gv.solve();
        return Sol { z, g, cond: cn, res2: gv.res2, rhs2: gv.rhs2, rows: rows.len() };
    }
    let idet = 1.0 / det;
    let solve = |v: [C64; 2]| -> [C64; 2] {
        [(v[0] * d - gxy * v[1]) * idet, (v[1] * a - gxy.conj() * v[0]) * idet]
    };
    let mut z = [solve(h[0]), solve(h[1])];
    // one refinement step with the residual of the original equations
    let mut ahr = [[C64::new(0.0, 0.0); 2]; 2];
    let mut res2 = [0.0f64; 2];
    for r in rows {
        let (xc, yc) = (r[0].conj(), r[1].conj());
        for k in 0..2 {
            let res = r[2 + k] - r[0] * z[k][0] - r[1] * z[k][1];
            res2[k] += res.norm_sqr();
            ahr[k][0] += xc * res;
            ahr[k][1] += yc * res;
        }
    }
    for k in 0..2 {
        let dz = solve(ahr[k]);
        z[k][0] += dz[0];
        z[k][1] += dz[1];
    }
    Sol { z, g: [d * idet, a * idet], cond, res2, rhs2, rows: rows.len() }
}

/// Inputs shared by both solvers.
pub struct IdentProblem<'a> {
    pub rotor: Rotor,
    /// vibration frequency w at each point (= spin speed for synchronous identification), rad/s
    pub w: &'a [f64],
    /// spin speed Omega at each point, rad/s
    pub spin: &'a [f64],
    /// responses, (batch, runs, n, 4), order [x1, x2, y1, y2]
    pub q: &'a [C64],
    /// excitation base vectors, (batch_e, runs, 4) with batch_e in {1, batch}
    pub e: &'a [C64],
    /// gain applied to e at each point (Omega^2 for imbalance, 1 for unit-force FRFs), (n,)
    pub gain: &'a [f64],
    pub batch: usize,
    pub runs: usize,
    /// all bearing coefficients equal on both sides (8 unknowns instead of 16)
    pub identical: bool,
}

/// Outputs, all (batch, n, ...).
pub struct IdentOut<'a> {
    pub k: &'a mut [f64],      // (B, n, 8)
    pub c: &'a mut [f64],      // (B, n, 8)
    pub cond: &'a mut [f64],   // (B, n, 2)
    pub resid: &'a mut [f64],  // (B, n)
    pub k_std: Option<&'a mut [f64]>, // (B, n, 8)
    pub c_std: Option<&'a mut [f64]>, // (B, n, 8)
}

/// Per-call constants of the rotor equations.
#[derive(Clone, Copy)]
struct Consts {
    ml2: f64,
    ml1: f64,
    it: f64,
    ip: f64,
    il: f64,
    l1: f64,
    l2: f64,
}

impl Consts {
    fn new(r: &Rotor) -> Self {
        let il = 1.0 / r.span();
        Consts { ml2: r.m * r.l2 * il, ml1: r.m * r.l1 * il, it: r.it * il, ip: r.ip * il, il, l1: r.l1, l2: r.l2 }
    }
}

#[inline(always)]
fn excitation<'a>(p: &'a IdentProblem, b: usize, r: usize) -> &'a [C64] {
    let be = if p.e.len() == p.runs * 4 { 0 } else { b };
    &p.e[(be * p.runs + r) * 4..(be * p.runs + r) * 4 + 4]
}

/// R = E + w^2 M q - j w Omega G q (right-hand side of eq. 10 / 26).
#[inline(always)]
fn rhs_point(k: &Consts, e: &[C64], gain: f64, w: f64, spin: f64, q: &[C64; 4]) -> [C64; 4] {
    let w2 = w * w;
    let wg = w * spin * k.ip;
    // M q (eq. 3, sparse) and -j w Omega G q
    let mq = [q[0] * k.ml2 + q[1] * k.ml1, q[2] * k.ml2 + q[3] * k.ml1, (q[1] - q[0]) * k.it, (q[2] - q[3]) * k.it];
    let g2 = q[3] - q[2];
    let g3 = q[1] - q[0];
    [
        e[0] * gain + mq[0] * w2,
        e[1] * gain + mq[1] * w2,
        e[2] * gain + mq[2] * w2 - C64::new(-g2.im * wg, g2.re * wg),
        e[3] * gain + mq[3] * w2 - C64::new(-g3.im * wg, g3.re * wg),
    ]
}

#[inline(always)]
fn load_q(p: &IdentProblem, b: usize, r: usize, i: usize) -> [C64; 4] {
    let n = p.w.len();
    let o = ((b * p.runs + r) * n + i) * 4;
    [p.q[o], p.q[o + 1], p.q[o + 2], p.q[o + 3]]
}

const CHUNK: usize = 2048;

/// One chunk of consecutive points starting at flat index `start` (= b * n + i).
#[allow(clippy::too_many_arguments)]
fn forces_chunk(
    p: &IdentProblem,
    kc: &Consts,
    start: usize,
    k: &mut [f64],
    c: &mut [f64],
    cond: &mut [f64],
    resid: &mut [f64],
    mut ks: Option<&mut [f64]>,
    mut cs: Option<&mut [f64]>,
) -> usize {
    let n = p.w.len();
    let mut nbad = 0;
    // row buffers of the two bearing systems, reused for every point of the chunk
    let zero = [C64::new(0.0, 0.0); 4];
    let mut rows = [vec![zero; 2 * p.runs], vec![zero; 2 * p.runs]];
    for t in 0..resid.len() {
        let idx = start + t;
        let (b, i) = (idx / n, idx % n);
        let (w, spin, gain) = (p.w[i], p.spin[i], p.gain[i]);
        let mut bad = false;
        // rows of the two bearing systems (or of the single system for identical bearings)
        let mut nr = [0usize; 2];
        let s2 = if p.identical { 0 } else { 1 };
        for r in 0..p.runs {
            let q = load_q(p, b, r, i);
            bad |= !(q.iter().all(|v| v.re.is_finite() && v.im.is_finite()));
            let rv = rhs_point(kc, excitation(p, b, r), gain, w, spin, &q);
            let f = bearing_forces(&rv, kc.l1, kc.l2, kc.il);
            rows[0][nr[0]] = [q[0], q[2], f[0], f[1]];
            nr[0] += 1;
            rows[s2][nr[s2]] = [q[1], q[3], f[2], f[3]];
            nr[s2] += 1;
        }
        let sols = if p.identical {
            let s0 = solve_rows(&rows[0][..nr[0]]);
            [s0, s0]
        } else {
            [solve_rows(&rows[0][..nr[0]]), solve_rows(&rows[1][..nr[1]])]
        };
        let nsys = if p.identical { 1 } else { 2 };
        let (mut res_tot, mut rhs_tot) = (0.0, 0.0);
        let iw = 1.0 / w;
        for sb in 0..2 {
            let s = &sols[if p.identical { 0 } else { sb }];
            let (z, g) = (s.z, s.g);
            cond[2 * t + sb] = s.cond;
            // z[rhs][unknown]: rhs 0 = x row (Zxx, Zxy), rhs 1 = y row (Zyx, Zyy)
            for row in 0..2 {
                for col in 0..2 {
                    let o = 8 * t + 4 * sb + 2 * row + col;
                    k[o] = z[row][col].re;
                    c[o] = z[row][col].im * iw;
                }
            }
            if let (Some(ks), Some(cs)) = (ks.as_deref_mut(), cs.as_deref_mut()) {
                let dof = s.rows as f64 - 2.0;
                for row in 0..2 {
                    let var_c = if dof > 0.0 { s.res2[row] / dof } else { f64::NAN };
                    for col in 0..2 {
                        let o = 8 * t + 4 * sb + 2 * row + col;
                        let sd = (0.5 * var_c * g[col]).sqrt();
                        ks[o] = sd;
                        cs[o] = sd * iw;
                    }
                }
            }
            if sb < nsys {
                res_tot += s.res2[0] + s.res2[1];
                rhs_tot += s.rhs2[0] + s.rhs2[1];
            }
        }
        resid[t] = if rhs_tot > 0.0 { (res_tot / rhs_tot).sqrt() } else { f64::NAN };
        if bad {
            for v in k[8 * t..8 * t + 8].iter_mut().chain(c[8 * t..8 * t + 8].iter_mut()) {
                *v = f64::NAN;
            }
            nbad += 1;
        }
    }
    nbad
}

/// Fast bearing-force solver. Returns the number of points whose input contained NaN/inf.
pub fn identify_forces(p: &IdentProblem, out: IdentOut) -> usize {
    let kc = Consts::new(&p.rotor);
    let IdentOut { k, c, cond, resid, k_std, c_std } = out;
    let base = (k.par_chunks_mut(8 * CHUNK), c.par_chunks_mut(8 * CHUNK), cond.par_chunks_mut(2 * CHUNK), resid.par_chunks_mut(CHUNK));
    match (k_std, c_std) {
        (Some(ks), Some(cs)) => (base.0, base.1, base.2, base.3, ks.par_chunks_mut(8 * CHUNK), cs.par_chunks_mut(8 * CHUNK))
            .into_par_iter()
            .enumerate()
            .map(|(j, (k, c, cond, resid, ks, cs))| forces_chunk(p, &kc, j * CHUNK, k, c, cond, resid, Some(ks), Some(cs)))
            .sum(),
        _ => base
            .into_par_iter()
            .enumerate()
            .map(|(j, (k, c, cond, resid))| forces_chunk(p, &kc, j * CHUNK, k, c, cond, resid, None, None))
            .sum(),
    }
}

/// Report index (eq. 9 order Kxx1, Kxx2, Kxy1, Kxy2, Kyx1, Kyx2, Kyy1, Kyy2) -> [bearing][i][j].
pub const REPORT_TO_BIJ: [usize; 8] = [0, 4, 1, 5, 2, 6, 3, 7];

/// The report's 16-unknown real least-squares formulation (eq. 8, 12, 16-18), solved by QR.
/// For `identical`, the 8-unknown variant (Z1 = Z2). cond receives the condition number of the
/// real stacked matrix (same value for both bearings). Returns the number of NaN/inf points.
pub fn identify_report(p: &IdentProblem, out: IdentOut) -> usize {
    let n = p.w.len();
    let IdentOut { k, c, cond, resid, .. } = out;
    let (l1, l2) = (p.rotor.l1, p.rotor.l2);
    let kc = Consts::new(&p.rotor);
    let nu = if p.identical { 8 } else { 16 };
    (k.par_chunks_mut(8), c.par_chunks_mut(8), cond.par_chunks_mut(2), resid.par_iter_mut())
        .into_par_iter()
        .with_min_len(64)
        .enumerate()
        .map(|(idx, (k, c, cond, resid))| {
            let (b, i) = (idx / n, idx % n);
            let rows = 8 * p.runs;
            let mut bm = Mat::<f64>::zeros(rows, nu);
            let mut fv = Mat::<f64>::zeros(rows, 1);
            let mut bad = false;
            for r in 0..p.runs {
                let q = load_q(p, b, r, i);
                for v in q.iter() {
                    bad |= !(v.re.is_finite() && v.im.is_finite());
                }
                let rv = rhs_point(&kc, excitation(p, b, r), p.gain[i], p.w[i], p.spin[i], &q);
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
            if bad {
                for v in k.iter_mut().chain(c.iter_mut()) {
                    *v = f64::NAN;
                }
                cond[0] = f64::NAN;
                cond[1] = f64::NAN;
                *resid = f64::NAN;
                return 1usize;
            }
            let sv = bm.singular_values().unwrap_or_default();
            let cn = match (sv.first(), sv.last()) {
                (Some(&a), Some(&z)) if z > 0.0 => a / z,
                _ => f64::INFINITY,
            };
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
                k[REPORT_TO_BIJ[t]] = pv[t];
                c[REPORT_TO_BIJ[t]] = pv[8 + t] / w;
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
        })
        .sum()
}
