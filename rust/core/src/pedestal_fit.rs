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
//! the unknowns θ = [k_ii, m_i, c_ii (, k_ij, c_ij)]. The rows are folded into a QR factor as
//! they are computed ([`crate::lsq::TallQr`]), the columns are then scaled by their largest
//! magnitude in the factor (X D⁻¹ = Q (R D⁻¹): Householder QR commutes with column scaling up to
//! rounding), so the rank is judged on the scaled design as `numpy.linalg.lstsq` would judge it,
//! and the HC3 sums come from a second pass on the scaled rows: no design matrix is ever stored. Chunks of points are fixed (not by thread count) and merged in order, so results repeat
//! bit for bit on any number of threads.

use rayon::prelude::*;

use crate::error::CoreError;
use crate::identify::{force_point, Consts, IdentProblem};
use crate::lsq::{Hc3Meat, Solution, TallQr};
use crate::model::C64;

/// One task's QR factors of the four fits, its columns' largest magnitudes and its bearing
/// forces (kept for the second pass).
type TaskFactors = (Vec<TallQr>, [[f64; 5]; 4], Vec<[C64; 4]>);

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
        let what = if p.select.is_empty() { "the points" } else { "the selected points" };
        return Err(CoreError::value("select", format!("({what}) leave {rows} equations for {u} unknowns")));
    }
    let tasks: Vec<(usize, usize)> = (0..n).step_by(POINTS_PER_TASK).map(|a| (a, (a + POINTS_PER_TASK).min(n))).collect();
    let kc = Consts::new(&f.rotor);
    let ld = 2 * f.runs * POINTS_PER_TASK;

    // pass 1: per task, the QR factors of [X y] of the four fits and the columns' largest
    // magnitudes; merged in task order
    let task = Task { f, kc: &kc, p, u, ld };
    let parts: Vec<Result<TaskFactors, CoreError>> = tasks
        .par_iter()
        .map_init(|| Equations::new(ld, u), |eq, &(a, z)| factor_task_dispatch(&task, eq, a, z))
        .collect();
    let mut total: Vec<TallQr> = (0..4).map(|_| TallQr::new(u + 1)).collect::<Result<_, _>>()?;
    let mut scale = [[0.0f64; 5]; 4];
    let mut forces = Vec::with_capacity(tasks.len());
    for part in parts {
        let (qr, mx, force) = part?;
        forces.push(force);
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
    let inv_d: Vec<Vec<f64>> = d.iter().map(|d| d.iter().map(|v| 1.0 / v).collect()).collect();
    let meats: Vec<Result<Vec<Hc3Meat>, CoreError>> = if full.iter().any(|&v| v) {
        let fits = Fits { sols: &sols, full: &full, inv_d: &inv_d };
        tasks
            .par_iter()
            .zip(forces.par_iter_mut())
            .map_init(|| Equations::new(ld, u), |eq, (&(a, z), force)| {
                eq.force = std::mem::take(force);
                hc3_task_dispatch(&task, &fits, eq, a, z)
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

/// What every task of a fit reads.
struct Task<'a> {
    f: &'a IdentProblem<'a>,
    kc: &'a Consts,
    p: &'a PedestalFitProblem<'a>,
    u: usize,
    ld: usize,
}

/// The solutions pass 2 evaluates the residuals and leverages of.
struct Fits<'a> {
    sols: &'a [Solution],
    full: &'a [bool],
    /// 1 / column scale per fit
    inv_d: &'a [Vec<f64>],
}

/// Pass 1 of the points `a..z`: the QR factors of the four fits' `[X y]` and the columns' largest
/// magnitudes.
#[inline(always)]
fn factor_task(t: &Task, eq: &mut Equations, a: usize, z: usize) -> Result<TaskFactors, CoreError> {
    let (u, ld) = (t.u, t.ld);
    let mut qr = (0..4).map(|_| TallQr::new(u + 1)).collect::<Result<Vec<_>, _>>()?;
    let mut mx = [[0.0f64; 5]; 4];
    eq.load(t.f, t.kc, t.p, a, z);
    for fi in 0..4 {
        let m = eq.block(fi, None);
        for (j, c) in mx[fi].iter_mut().enumerate().take(u) {
            *c = abs_max(&eq.buf[j * ld..j * ld + m]);
        }
        qr[fi].fold_block(&mut eq.buf, ld, m)?;
    }
    Ok((qr, mx, std::mem::take(&mut eq.force)))
}

/// Pass 2 of the points `a..z`: the HC3 sums of the fits of full rank, on the scaled design.
#[inline(always)]
fn hc3_task(t: &Task, fits: &Fits, eq: &mut Equations, a: usize, z: usize) -> Result<Vec<Hc3Meat>, CoreError> {
    let mut acc: Vec<Hc3Meat> = (0..4).map(|_| Hc3Meat::new(t.u)).collect();
    eq.load_motion(t.f, t.p, a, z);
    for fi in (0..4).filter(|&fi| fits.full[fi]) {
        let m = eq.block(fi, Some(&fits.inv_d[fi]));
        acc[fi].add_block(&fits.sols[fi], &eq.buf, t.ld, m)?;
    }
    Ok(acc)
}

crate::lanes::simd_dispatch! {
    /// [`factor_task`] at the widest SIMD level of this CPU.
    fn factor_task_dispatch(t: &Task, eq: &mut Equations, a: usize, z: usize) -> Result<TaskFactors, CoreError> => factor_task
}

crate::lanes::simd_dispatch! {
    /// [`hc3_task`] at the widest SIMD level of this CPU.
    fn hc3_task_dispatch(t: &Task, fits: &Fits, eq: &mut Equations, a: usize, z: usize) -> Result<Vec<Hc3Meat>, CoreError> => hc3_task
}

/// Largest |v| (eight running maxima, so that it vectorizes); NaN is not propagated (the QR
/// factor shows it).
#[inline(always)]
fn abs_max(v: &[f64]) -> f64 {
    let mut m = [0.0f64; 8];
    let chunks = v.chunks_exact(8);
    let rest = chunks.remainder();
    for c in chunks {
        for l in 0..8 {
            let x = c[l].abs();
            m[l] = if x > m[l] { x } else { m[l] };
        }
    }
    let mut out = m.iter().fold(0.0f64, |a, &b| if b > a { b } else { a });
    for &x in rest {
        let x = x.abs();
        out = if x > out { x } else { out };
    }
    out
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
        let pairs = ld / 2;
        Equations {
            ld,
            u,
            s: Vec::with_capacity(pairs),
            force: Vec::with_capacity(pairs),
            ped: Vec::with_capacity(pairs),
            buf: vec![0.0; (u + 1) * ld],
        }
    }

    /// s and the pedestal motion of the selected points `a..z` (the forces are the caller's).
    #[inline(always)]
    fn load_motion(&mut self, f: &IdentProblem, p: &PedestalFitProblem, a: usize, z: usize) {
        self.s.clear();
        self.ped.clear();
        for k in (a..z).filter(|&k| p.select.is_empty() || p.select[k]) {
            let s = s_at(f, k);
            for r in 0..f.runs {
                self.s.push(s);
                let q = &f.q_ped[r][4 * k..4 * k + 4];
                self.ped.push([q[0], q[1], q[2], q[3]]);
            }
        }
    }

    /// s, the bearing forces and the pedestal motion of the selected points `a..z`.
    #[inline(always)]
    fn load(&mut self, f: &IdentProblem, kc: &Consts, p: &PedestalFitProblem, a: usize, z: usize) {
        self.load_motion(f, p, a, z);
        self.force.clear();
        for k in (a..z).filter(|&k| p.select.is_empty() || p.select[k]) {
            for r in 0..f.runs {
                self.force.push(force_point(f, kc, 0, r, k));
            }
        }
    }

    /// Write the block of fit `fi` = 2 b + i, its columns times `mul` (per column) if given;
    /// returns its number of rows. Columns [p_own, s² p_own, s p_own (, p_other, s p_other)] as u
    /// (3 or 5) asks, Re and Im of each (run, point) on two rows.
    #[inline(always)]
    fn block(&mut self, fi: usize, mul: Option<&[f64]>) -> usize {
        let (b, i) = (fi / 2, fi % 2);
        let (own, oth) = (coord(b, i), coord(b, 1 - i));
        let (ld, u) = (self.ld, self.u);
        let m = 2 * self.s.len();
        let (xs, y) = self.buf.split_at_mut(u * ld);
        for (yv, force) in y[..m].chunks_exact_mut(2).zip(&self.force) {
            yv[0] = force[own].re;
            yv[1] = force[own].im;
        }
        for (j, col) in xs.chunks_exact_mut(ld).enumerate() {
            let k = mul.map_or(1.0, |v| v[j]);
            for (xv, (s, ped)) in col[..m].chunks_exact_mut(2).zip(self.s.iter().zip(&self.ped)) {
                let c = match j {
                    0 => ped[own],
                    1 => *s * *s * ped[own],
                    2 => *s * ped[own],
                    3 => ped[oth],
                    _ => *s * ped[oth],
                };
                if mul.is_some() {
                    xv[0] = c.re * k;
                    xv[1] = c.im * k;
                } else {
                    xv[0] = c.re;
                    xv[1] = c.im;
                }
            }
        }
        m
    }
}
