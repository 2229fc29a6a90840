//! Identification of the pedestals' mass, stiffness and damping from runs that carry pedestal
//! motion: an unweighted least-squares fit per pedestal b and direction i with
//! heteroscedasticity-consistent (HC3) standard errors.
//!
//! The bearing force on housing b in direction i (from the rotor equations with the absolute
//! motion, [`crate::identify::bearing_forces`]) obeys
//!
//! `f_bi = (k_ii + s² m_i + s c_ii) p_bi (+ (k_ij + s c_ij) p_bj)`,  s = σ + jω,
//!
//! with p the pedestal motion. Every run and selected point gives two real equations (Re, Im) in
//! the unknowns θ = [k_ii, m_i, c_ii (, k_ij, c_ij)]. The columns are scaled by their largest
//! magnitude before the fit (the rank is judged on the scaled design, as `numpy.linalg.lstsq`
//! would judge it), the rows are folded into a QR factor as they are computed
//! ([`crate::lsq::TallQr`]) and the HC3 sums come from a second pass: no design matrix is ever
//! stored. Chunks of points are fixed (not by thread count) and merged in order, so results repeat
//! bit for bit on any number of threads.

use rayon::prelude::*;

use crate::error::CoreError;
use crate::identify::{force_point, Consts, IdentProblem};
use crate::lsq::{Hc3Meat, Solution, TallQr};
use crate::model::C64;

/// One task's QR factors of the four fits and its columns' largest magnitudes.
type TaskFactors = (Vec<TallQr>, [[f64; 5]; 4]);

/// Points per parallel task.
const POINTS_PER_TASK: usize = 1024;

/// A pedestal fit: the bearing forces' problem (one batch member, pedestal motion in `q_ped`),
/// the points used and the model.
pub struct PedestalFitProblem<'a> {
    pub forces: IdentProblem<'a>,
    /// points used, (n,), or empty for all
    pub select: &'a [bool],
    /// fit the cross-coupled k_ij, c_ij as well (5 unknowns instead of 3)
    pub cross: bool,
}

/// The fit of pedestal `b`, direction `i` (index `2 b + i` in [`fit`]'s result).
#[derive(Clone, Debug)]
pub struct DirectionFit {
    /// [k_ii, m_i, c_ii (, k_ij, c_ij)] in N/m, kg, N s/m; NaN when rank deficient
    pub theta: Vec<f64>,
    /// HC3 covariance of θ, (u × u) row-major, in the units of θ
    pub cov: Vec<f64>,
    /// numerical rank of the scaled design (below u: not identifiable)
    pub rank: usize,
    /// equations (2 × runs × selected points)
    pub rows: usize,
    /// |y - X θ| / |y|
    pub resid: f64,
    /// the column scales (largest magnitude of each column of X)
    pub scale: Vec<f64>,
}

/// Columns of the design, complex (Re and Im give the two rows), for pedestal b, direction i at
/// one (run, point): `own` = p_bi, `other` = p_bj, `s` the Laplace variable.
#[inline(always)]
fn columns(own: C64, other: C64, s: C64, cross: bool) -> ([C64; 5], usize) {
    let s2 = s * s;
    if cross {
        ([own, s2 * own, s * own, other, s * other], 5)
    } else {
        ([own, s2 * own, s * own, C64::new(0.0, 0.0), C64::new(0.0, 0.0)], 3)
    }
}

#[inline(always)]
fn s_at(p: &IdentProblem, k: usize) -> C64 {
    C64::new(if p.sigma.is_empty() { 0.0 } else { p.sigma[k] }, p.w[k])
}

/// Index of (pedestal b, direction i) in [x1, x2, y1, y2].
#[inline(always)]
fn coord(b: usize, i: usize) -> usize {
    2 * i + b
}

/// Each pedestal's k, m, c (and cross-coupled k, c) with HC3 covariances: four fits, in the order
/// (b, i) = (1, x), (1, y), (2, x), (2, y), index `2 b + i`. `Err` for inconsistent arguments, for
/// non-finite forces or motion ("runs contain NaN or inf") and for fewer equations than unknowns;
/// a rank-deficient fit is returned with its rank (and NaN θ) for the caller to name.
pub fn fit(p: &PedestalFitProblem) -> Result<Vec<DirectionFit>, CoreError> {
    let f = &p.forces;
    f.check()?;
    if f.batch != 1 {
        return Err(CoreError::value("batch", format!("must be 1 for a pedestal fit, got {}", f.batch)));
    }
    if f.q_ped.is_empty() {
        return Err(CoreError::value("q_ped", "is needed: the pedestals cannot be identified without their motion"));
    }
    let n = f.points();
    if !p.select.is_empty() && p.select.len() != n {
        return Err(CoreError::length("select", p.select.len(), format!("{n} (one per point) or 0 (all)")));
    }
    let used = |k: usize| p.select.is_empty() || p.select[k];
    let nsel = (0..n).filter(|&k| used(k)).count();
    let u = if p.cross { 5 } else { 3 };
    let rows = 2 * f.runs * nsel;
    if rows <= u {
        return Err(CoreError::value("select", format!("leaves {rows} equations for {u} unknowns")));
    }
    let tasks: Vec<(usize, usize)> = (0..n).step_by(POINTS_PER_TASK).map(|a| (a, (a + POINTS_PER_TASK).min(n))).collect();
    let kc = Consts::new(&f.rotor);
    let ld = 2 * f.runs * POINTS_PER_TASK;

    // pass 1: per task, the QR factors of [X y] of the four fits and the columns' largest
    // magnitudes; merged in task order
    let parts: Vec<Result<TaskFactors, CoreError>> = tasks
        .par_iter()
        .map(|&(a, z)| {
            let mut qr = (0..4).map(|_| TallQr::new(u + 1)).collect::<Result<Vec<_>, _>>()?;
            let mut mx = [[0.0f64; 5]; 4];
            let mut eq = Equations::new(ld, u);
            eq.load(f, &kc, p, a, z);
            for fi in 0..4 {
                let m = eq.block(fi, p.cross);
                for (j, c) in mx[fi].iter_mut().enumerate().take(u) {
                    *c = eq.buf[j * ld..j * ld + m].iter().fold(0.0, |acc, v| acc.max(v.abs()));
                }
                qr[fi].fold_block(&mut eq.buf, ld, m)?;
            }
            Ok((qr, mx))
        })
        .collect();
    let mut total: Vec<TallQr> = (0..4).map(|_| TallQr::new(u + 1)).collect::<Result<_, _>>()?;
    let mut scale = [[0.0f64; 5]; 4];
    for part in parts {
        let (qr, mx) = part?;
        for (t, q) in total.iter_mut().zip(qr) {
            t.merge(q)?;
        }
        for (s, m) in scale.iter_mut().zip(&mx) {
            for (a, b) in s.iter_mut().zip(m) {
                *a = a.max(*b);
            }
        }
    }
    let factors: Vec<_> = total.iter_mut().map(|t| t.factor()).collect();
    if factors.iter().any(|r| (0..=u).any(|i| (i..=u).any(|j| !r[i][j].is_finite()))) {
        return Err(CoreError::value("runs", "contain NaN or inf"));
    }
    // the solution from the factor of the scaled design [X D⁻¹ y] = Q [R_x D⁻¹ z; 0 ρ]: scaling
    // the columns after the QR is exact up to rounding (Householder QR commutes with it)
    let d: Vec<Vec<f64>> = scale.iter().map(|s| s[..u].iter().map(|v| v.max(1e-300)).collect()).collect();
    let sols: Vec<Solution> = factors
        .iter()
        .zip(&d)
        .map(|(r, d)| {
            let mut rs = *r;
            for row in rs.iter_mut().take(u + 1) {
                for (j, dj) in d.iter().enumerate() {
                    row[j] /= dj;
                }
            }
            Solution::from_factor(&rs, u + 1, rows)
        })
        .collect::<Result<_, _>>()?;

    // pass 2: residuals, leverages and the HC3 sums (only for fits of full rank), on the scaled
    // design as the solution is
    let full: Vec<bool> = sols.iter().map(|s| s.rank == u).collect();
    let meats: Vec<Result<Vec<Hc3Meat>, CoreError>> = if full.iter().any(|&v| v) {
        tasks
            .par_iter()
            .map(|&(a, z)| {
                let mut acc: Vec<Hc3Meat> = (0..4).map(|_| Hc3Meat::new(u)).collect();
                let mut eq = Equations::new(ld, u);
                let mut scratch = Vec::new();
                eq.load(f, &kc, p, a, z);
                for fi in (0..4).filter(|&fi| full[fi]) {
                    let m = eq.block(fi, p.cross);
                    for (j, dj) in d[fi].iter().enumerate() {
                        eq.buf[j * ld..j * ld + m].iter_mut().for_each(|v| *v /= dj);
                    }
                    acc[fi].add_block(&sols[fi], &eq.buf, ld, m, &mut scratch)?;
                }
                Ok(acc)
            })
            .collect()
    } else {
        Vec::new()
    };
    let mut sums: Vec<Hc3Meat> = (0..4).map(|_| Hc3Meat::new(u)).collect();
    for part in meats {
        for (s, m) in sums.iter_mut().zip(&part?) {
            s.merge(m);
        }
    }

    Ok((0..4)
        .map(|fi| {
            let sol = &sols[fi];
            let sc = &scale[fi][..u];
            let d = &d[fi];
            let (theta, cov, resid) = if full[fi] {
                let c = sol.sandwich(&sums[fi].symmetric());
                let cov = (0..u * u).map(|ij| c[ij] / (d[ij / u] * d[ij % u])).collect();
                let theta = sol.theta.iter().zip(d).map(|(t, s)| t / s).collect();
                (theta, cov, (sums[fi].rr / sums[fi].yy.max(1e-300)).sqrt())
            } else {
                (vec![f64::NAN; u], vec![f64::NAN; u * u], f64::NAN)
            };
            DirectionFit { theta, cov, rank: sol.rank, rows, resid, scale: sc.to_vec() }
        })
        .collect())
}

/// The equations of one task's points: forces and pedestal motion loaded once, then the design
/// block `[X y]` of each fit written column-major (leading dimension `ld`), rows (Re, Im) per
/// (point, run).
struct Equations {
    ld: usize,
    u: usize,
    /// per (selected point, run): s, the bearing forces, the pedestal motion
    s: Vec<C64>,
    force: Vec<[C64; 4]>,
    ped: Vec<[C64; 4]>,
    buf: Vec<f64>,
}

impl Equations {
    fn new(ld: usize, u: usize) -> Equations {
        Equations { ld, u, s: Vec::new(), force: Vec::new(), ped: Vec::new(), buf: vec![0.0; (u + 1) * ld] }
    }

    fn load(&mut self, f: &IdentProblem, kc: &Consts, p: &PedestalFitProblem, a: usize, z: usize) {
        self.s.clear();
        self.force.clear();
        self.ped.clear();
        for k in (a..z).filter(|&k| p.select.is_empty() || p.select[k]) {
            let s = s_at(f, k);
            for r in 0..f.runs {
                self.s.push(s);
                self.force.push(force_point(f, kc, 0, r, k));
                let q = &f.q_ped[r][4 * k..4 * k + 4];
                self.ped.push([q[0], q[1], q[2], q[3]]);
            }
        }
    }

    /// Write the block of fit `fi` = 2 b + i; returns its number of rows.
    fn block(&mut self, fi: usize, cross: bool) -> usize {
        let (b, i) = (fi / 2, fi % 2);
        let (own, oth) = (coord(b, i), coord(b, 1 - i));
        let (ld, u) = (self.ld, self.u);
        for (e, ((s, force), ped)) in self.s.iter().zip(&self.force).zip(&self.ped).enumerate() {
            let (cols, _) = columns(ped[own], ped[oth], *s, cross);
            for (j, c) in cols.iter().enumerate().take(u) {
                self.buf[j * ld + 2 * e] = c.re;
                self.buf[j * ld + 2 * e + 1] = c.im;
            }
            self.buf[u * ld + 2 * e] = force[own].re;
            self.buf[u * ld + 2 * e + 1] = force[own].im;
        }
        2 * self.s.len()
    }
}
