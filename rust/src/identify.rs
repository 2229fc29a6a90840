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

/// Upper-triangular 2x2 complex R, Q^H b for two right-hand sides, and running residuals.
#[derive(Clone, Copy)]
struct Givens2 {
    r11: C64,
    r12: C64,
    r22: C64,
    qb: [[C64; 2]; 2], // qb[row][rhs]
    res2: [f64; 2],
    rhs2: [f64; 2],
    rows: u32,
}

#[inline(always)]
fn rot(a: C64, b: C64) -> Option<(f64, C64)> {
    // unitary [[c, s], [-conj(s), c]] with c real, mapping (a, b) -> (r, 0)
    let nb = b.norm();
    if nb == 0.0 {
        return None;
    }
    let na = a.norm();
    if na == 0.0 {
        return Some((0.0, b.conj() / nb));
    }
    let r = na.hypot(nb);
    Some((na / r, (a / na) * b.conj() / r))
}

impl Givens2 {
    #[inline(always)]
    fn new() -> Self {
        let z = C64::new(0.0, 0.0);
        Givens2 { r11: z, r12: z, r22: z, qb: [[z; 2]; 2], res2: [0.0; 2], rhs2: [0.0; 2], rows: 0 }
    }

    /// Add one equation a1 z1 + a2 z2 = b (two right-hand sides b[0], b[1]).
    #[inline(always)]
    fn push(&mut self, a1: C64, mut a2: C64, mut b: [C64; 2]) {
        self.rows += 1;
        self.rhs2[0] += b[0].norm_sqr();
        self.rhs2[1] += b[1].norm_sqr();
        if let Some((c, s)) = rot(self.r11, a1) {
            let sc = s.conj();
            self.r11 = self.r11 * c + s * a1;
            let t12 = self.r12;
            self.r12 = t12 * c + s * a2;
            a2 = a2 * c - sc * t12;
            for k in 0..2 {
                let t = self.qb[0][k];
                self.qb[0][k] = t * c + s * b[k];
                b[k] = b[k] * c - sc * t;
            }
        }
        if let Some((c, s)) = rot(self.r22, a2) {
            let sc = s.conj();
            self.r22 = self.r22 * c + s * a2;
            for k in 0..2 {
                let t = self.qb[1][k];
                self.qb[1][k] = t * c + s * b[k];
                b[k] = b[k] * c - sc * t;
            }
        }
        self.res2[0] += b[0].norm_sqr();
        self.res2[1] += b[1].norm_sqr();
    }

    /// Condition number of the 2-column response matrix (ratio of singular values of R).
    #[inline(always)]
    fn cond(&self) -> f64 {
        let a = self.r11.norm_sqr();
        let d = self.r12.norm_sqr() + self.r22.norm_sqr();
        let c2 = a * self.r12.norm_sqr();
        let det = self.r11.norm() * self.r22.norm();
        let lmax = 0.5 * (a + d) + (0.25 * (a - d) * (a - d) + c2).sqrt();
        if det == 0.0 {
            return f64::INFINITY;
        }
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
        let mut z = [[C64::new(0.0, 0.0); 2]; 2];
        for k in 0..2 {
            let z2 = self.qb[1][k] / self.r22;
            let z1 = (self.qb[0][k] - self.r12 * z2) / self.r11;
            z[k] = [z1, z2];
        }
        let a11 = self.r11.norm_sqr();
        let a22 = self.r22.norm_sqr();
        let g = [1.0 / a11 + self.r12.norm_sqr() / (a11 * a22), 1.0 / a22];
        (z, g, cond)
    }
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

#[inline(always)]
fn generalized_force(p: &IdentProblem, b: usize, r: usize, i: usize, q: &[C64; 4]) -> [C64; 4] {
    let n = p.w.len();
    let be = if p.e.len() == p.runs * 4 { 0 } else { b };
    let e = &p.e[(be * p.runs + r) * 4..(be * p.runs + r) * 4 + 4];
    let (w, s, g) = (p.w[i], p.spin[i], p.gain[i]);
    let mq = p.rotor.m_times(q);
    let gq = p.rotor.g_times(q);
    let _ = n;
    let mut out = [C64::new(0.0, 0.0); 4];
    for k in 0..4 {
        // E + w^2 M q - j w Omega G q
        out[k] = e[k] * g + mq[k] * (w * w) - C64::new(0.0, w * s) * gq[k];
    }
    out
}

#[inline(always)]
fn load_q(p: &IdentProblem, b: usize, r: usize, i: usize) -> [C64; 4] {
    let n = p.w.len();
    let o = ((b * p.runs + r) * n + i) * 4;
    [p.q[o], p.q[o + 1], p.q[o + 2], p.q[o + 3]]
}

/// Fast bearing-force solver. Returns the number of points whose input contained NaN/inf.
pub fn identify_forces(p: &IdentProblem, out: IdentOut) -> usize {
    let n = p.w.len();
    let npts = p.batch * n;
    let IdentOut { k, c, cond, resid, k_std, c_std } = out;
    let want_std = k_std.is_some() && c_std.is_some();
    let mut dummy_k = Vec::new();
    let mut dummy_c = Vec::new();
    let (ks, cs): (&mut [f64], &mut [f64]) = match (k_std, c_std) {
        (Some(a), Some(b)) => (a, b),
        _ => {
            dummy_k.resize(npts * 8, 0.0);
            dummy_c.resize(npts * 8, 0.0);
            (&mut dummy_k[..], &mut dummy_c[..])
        }
    };
    (k.par_chunks_mut(8), c.par_chunks_mut(8), cond.par_chunks_mut(2), resid.par_iter_mut(), ks.par_chunks_mut(8), cs.par_chunks_mut(8))
        .into_par_iter()
        .with_min_len(1024)
        .enumerate()
        .map(|(idx, (k, c, cond, resid, ks, cs))| {
            let (b, i) = (idx / n, idx % n);
            let mut st = [Givens2::new(), Givens2::new()];
            let mut bad = false;
            for r in 0..p.runs {
                let q = load_q(p, b, r, i);
                for v in q.iter() {
                    bad |= !(v.re.is_finite() && v.im.is_finite());
                }
                let rv = generalized_force(p, b, r, i, &q);
                let f = bearing_forces(&rv, p.rotor.l1, p.rotor.l2);
                let s2 = if p.identical { 0 } else { 1 };
                st[0].push(q[0], q[2], [f[0], f[1]]);
                st[s2].push(q[1], q[3], [f[2], f[3]]);
            }
            let w = p.w[i];
            let nsys = if p.identical { 1 } else { 2 };
            let mut res_tot = 0.0;
            let mut rhs_tot = 0.0;
            for sb in 0..2 {
                let s = &st[if p.identical { 0 } else { sb }];
                let (z, g, cn) = s.solve();
                cond[sb] = cn;
                // z[rhs][unknown]: rhs 0 = x-row (Zxx, Zxy), rhs 1 = y-row (Zyx, Zyy)
                for row in 0..2 {
                    for col in 0..2 {
                        let zz = z[row][col];
                        k[4 * sb + 2 * row + col] = zz.re;
                        c[4 * sb + 2 * row + col] = zz.im / w;
                    }
                }
                if want_std {
                    let dof = s.rows as f64 - 2.0;
                    for row in 0..2 {
                        let var_c = if dof > 0.0 { s.res2[row] / dof } else { f64::NAN };
                        for col in 0..2 {
                            let sd = (0.5 * var_c * g[col]).sqrt();
                            ks[4 * sb + 2 * row + col] = sd;
                            cs[4 * sb + 2 * row + col] = sd / w;
                        }
                    }
                }
                if sb < nsys {
                    res_tot += s.res2[0] + s.res2[1];
                    rhs_tot += s.rhs2[0] + s.rhs2[1];
                }
            }
            *resid = if rhs_tot > 0.0 { (res_tot / rhs_tot).sqrt() } else { f64::NAN };
            if bad {
                for v in k.iter_mut().chain(c.iter_mut()) {
                    *v = f64::NAN;
                }
                1usize
            } else {
                0usize
            }
        })
        .sum()
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
                let rv = generalized_force(p, b, r, i, &q);
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
