//! The pedestal fit with the runs' measurement covariances: weighted least squares, or the
//! sandwich covariance of the unweighted fit ([`crate::pedestal_fit`] gives that fit and its HC3
//! covariance).
//!
//! Fit (b, i) has, per selected point k and run r, the complex equation (two real rows)
//!     y_r = F_r,col = x_rᵀ θ,   x_r = [p_own, s² p_own, s p_own (, p_oth, s p_oth)],
//! col = 2 i + b the coordinate of pedestal b, direction i. The residual e_r = F_r,col - x_rᵀ θ
//! moves with the run's measured inputs z_r = [Re q, Im q, Re p, Im p] (16 real values): the
//! forces through the rotor equations (F = F_0 + A (q + p), A the 4 x 4 complex map of
//! [`crate::identify::motion_forces`]) and the pedestal terms through D = k + s² m + s c:
//!     ∂e_r/∂Re q_d = A_col,d,  ∂e_r/∂Im q_d = j A_col,d,
//!     ∂e_r/∂Re p_d = A_col,d - D_own [d = own] - D_oth [d = oth],  ∂e_r/∂Im p_d = j (the same).
//! With G_r = [Re; Im] of that gradient (2 x 16) and Σ_rt the covariance of z_r and z_t (the run's
//! own for r = t, the shared one otherwise), the residuals of a point have the covariance
//!     V (2R x 2R),   V_rt = G_r Σ_rt G_tᵀ.
//! - [`weighted_step`]: with L Lᵀ = V + 1e-300 I, the rows L⁻¹ X_k, L⁻¹ y_k of every point folded
//!   into one QR factor ([`crate::lsq::TallQr`]): θ, (X_wᵀ X_w)⁻¹, χ² = |y_w - X_w θ|² / (m - u).
//!   V depends on θ (D p carries the pedestal noise): [`cov_fit`] takes [`WEIGHTED_STEPS`].
//! - [`sandwich`]: (XᵀX)⁻¹ (Σ_k X_kᵀ V_k X_k) (XᵀX)⁻¹ at the given θ.
//!
//! Each pass over the points serves the four fits at once (the forces, A and the runs' covariances
//! of a point are formed once). The columns are scaled by their largest magnitude in X after the
//! fold (Householder QR commutes with column scaling up to rounding), as in
//! [`crate::pedestal_fit`]. Points go in fixed tasks merged in order: the same bits on any number of
//! threads.

use crate::covariance::cholesky_lower;
use crate::error::{expect_len, CoreError};
use crate::identify::{force_point, motion_forces, Consts};
pub use crate::covariance::RunCov;
use crate::lsq::{Solution, TallQr};
use crate::model::C64;
use crate::par::{for_each_task, Disjoint};
use crate::pedestal_fit::PedestalFitProblem;

/// Points per parallel task.
const POINTS_PER_TASK: usize = 512;

/// The fit's problem and the runs' covariances.
pub struct CovFitProblem<'a> {
    /// forces, pedestal motion, selected points, the model (3 or 5 unknowns)
    pub fit: PedestalFitProblem<'a>,
    /// each run's covariance; the selected points must have known (finite) ones
    pub covs: &'a [RunCov<'a>],
    /// covariance common to every pair of runs, (n, 16, 16), or empty (NaN entries count as zero)
    pub shared: &'a [f64],
}

/// One weighted step.
#[derive(Clone, Debug)]
pub struct WeightedStep {
    /// θ in N/m, kg, N s/m; NaN when the whitened design is rank deficient
    pub theta: Vec<f64>,
    /// (X_wᵀ X_w)⁻¹ in the units of θ, (u × u) row-major
    pub cov: Vec<f64>,
    /// |y_w - X_w θ|² / max(m - u, 1)
    pub chi2: f64,
    /// unweighted |y - X θ| / |y| at the new θ
    pub resid: f64,
    /// numerical rank of the scaled whitened design
    pub rank: usize,
}

impl CovFitProblem<'_> {
    fn check(&self, thetas: &[Vec<f64>]) -> Result<usize, CoreError> {
        let f = &self.fit.forces;
        f.check()?;
        if f.batch != 1 {
            return Err(CoreError::value("batch", format!("must be 1 for a pedestal fit, got {}", f.batch)));
        }
        if f.q_ped.is_empty() {
            return Err(CoreError::value("q_ped", "is needed: the pedestals cannot be identified without their motion"));
        }
        let n = f.points();
        if !self.fit.select.is_empty() && self.fit.select.len() != n {
            return Err(CoreError::length("select", self.fit.select.len(), format!("{n} (one per point) or 0 (all)")));
        }
        RunCov::check_all(self.covs, f.runs, n)?;
        if !self.shared.is_empty() {
            expect_len("shared", self.shared, n * 256)?;
        }
        expect_len("thetas", thetas, 4)?;
        let u = if self.fit.cross { 5 } else { 3 };
        for theta in thetas {
            expect_len("theta", theta, u)?;
            if theta.iter().any(|v| !v.is_finite()) {
                return Err(CoreError::value("theta", "must be finite"));
            }
        }
        Ok(u)
    }
}

/// What one point gives every fit: the forces of each run, A (the forces per unit absolute motion),
/// s, and the runs' joint covariances (when V is wanted).
struct PointData {
    s: C64,
    /// a[row][d]: force `row` per unit motion of coordinate d
    a: [[C64; 4]; 4],
    /// per run: the forces at the bearings and the pedestal motion
    force: Vec<[C64; 4]>,
    ped: Vec<[C64; 4]>,
    /// per run: the joint 16 x 16 covariance (only when V is wanted)
    cov: Vec<[f64; 256]>,
}

impl PointData {
    fn load(p: &CovFitProblem, kc: &Consts, k: usize, need_v: bool, out: &mut PointData) {
        let f = &p.fit.forces;
        let w = f.w[k];
        let sigma = if f.sigma.is_empty() { 0.0 } else { f.sigma[k] };
        let spin = f.spin[if f.spin.len() == 1 { 0 } else { k }];
        out.s = C64::new(sigma, w);
        for d in 0..4 {
            let mut unit = [C64::new(0.0, 0.0); 4];
            unit[d] = C64::new(1.0, 0.0);
            let col = motion_forces(kc, w, sigma, spin, &unit);
            for row in 0..4 {
                out.a[row][d] = col[row];
            }
        }
        out.force.clear();
        out.ped.clear();
        for r in 0..f.runs {
            out.force.push(force_point(f, kc, 0, r, k));
            let q = &f.q_ped[r][4 * k..4 * k + 4];
            out.ped.push([q[0], q[1], q[2], q[3]]);
        }
        out.cov.resize(if need_v { f.runs } else { 0 }, [0.0; 256]);
        for (r, c) in out.cov.iter_mut().enumerate() {
            p.covs[r].joint(k, c);
        }
    }
}

/// The rows [X y] (2R x (u + 1), unscaled) of fit `fi` at one point, and (with `need_v`) the
/// residuals' covariance V (2R x 2R) at θ.
#[allow(clippy::too_many_arguments)]
fn fit_rows(p: &CovFitProblem, pd: &PointData, k: usize, fi: usize, theta: &[f64], need_v: bool, xy: &mut Vec<f64>, v: &mut Vec<f64>) {
    let (b, i) = (fi / 2, fi % 2);
    let (own, oth) = (2 * i + b, 2 * (1 - i) + b);
    let cross = p.fit.cross;
    let u = if cross { 5 } else { 3 };
    let runs = pd.force.len();
    let nr = 2 * runs;
    let s = pd.s;
    if need_v {
        let d_own = theta[0] + s * s * theta[1] + s * theta[2];
        let d_oth = if cross { theta[3] + s * theta[4] } else { C64::new(0.0, 0.0) };
        // G (2 x 16), the same for every run (A and D do not depend on the run)
        let mut g = [[0.0f64; 16]; 2];
        let j = C64::new(0.0, 1.0);
        for d in 0..4 {
            let a = pd.a[own][d];
            let mut gp = a;
            if d == own {
                gp -= d_own;
            }
            if cross && d == oth {
                gp -= d_oth;
            }
            for (col, val) in [(d, a), (4 + d, j * a), (8 + d, gp), (12 + d, j * gp)] {
                g[0][col] = val.re;
                g[1][col] = val.im;
            }
        }
        // V_rt = G Σ_rt Gᵀ: G Σ_rt row by row, then against G's rows
        v.clear();
        v.resize(nr * nr, 0.0);
        let shared = if p.shared.is_empty() { None } else { Some(&p.shared[256 * k..256 * (k + 1)]) };
        for r in 0..runs {
            for t in 0..runs {
                let blk: &[f64] = if r == t {
                    &pd.cov[r]
                } else if let Some(sh) = shared {
                    sh
                } else {
                    continue;
                };
                for (ra, ga) in g.iter().enumerate() {
                    let mut gs = [0.0f64; 16];
                    for (u1, &gu) in ga.iter().enumerate() {
                        let row: &[f64; 16] = blk[16 * u1..16 * u1 + 16].try_into().unwrap();
                        for (gsv, &sv) in gs.iter_mut().zip(row) {
                            // NaN entries of the shared covariance count as zero
                            *gsv += gu * if sv.is_nan() { 0.0 } else { sv };
                        }
                    }
                    for (cb, gb) in g.iter().enumerate() {
                        v[(2 * r + ra) * nr + 2 * t + cb] = gs.iter().zip(gb).map(|(x, y)| x * y).sum();
                    }
                }
            }
        }
    }
    xy.clear();
    xy.resize(nr * (u + 1), 0.0);
    for r in 0..runs {
        let ped = &pd.ped[r];
        let mut x = [C64::new(0.0, 0.0); 6];
        x[0] = ped[own];
        x[1] = s * s * ped[own];
        x[2] = s * ped[own];
        if cross {
            x[3] = ped[oth];
            x[4] = s * ped[oth];
        }
        x[u] = pd.force[r][own];
        for c in 0..=u {
            xy[(2 * r) * (u + 1) + c] = x[c].re;
            xy[(2 * r + 1) * (u + 1) + c] = x[c].im;
        }
    }
}

/// What a pass gives each fit: the QR factor of its whitened (or plain) rows, its columns' largest
/// magnitudes, Σ_k X_kᵀ V_k X_k (sandwich only), Σ (y - x θ)², Σ y².
struct FitSums {
    qr: TallQr,
    mx: [f64; 5],
    meat: Vec<f64>,
    rr: f64,
    yy: f64,
}

impl FitSums {
    fn new(u: usize) -> Result<FitSums, CoreError> {
        Ok(FitSums { qr: TallQr::new(u + 1)?, mx: [0.0; 5], meat: vec![0.0; u * u], rr: 0.0, yy: 0.0 })
    }

    fn merge(&mut self, other: FitSums) -> Result<(), CoreError> {
        self.qr.merge(other.qr)?;
        for (a, b) in self.mx.iter_mut().zip(&other.mx) {
            *a = a.max(*b);
        }
        for (a, b) in self.meat.iter_mut().zip(&other.meat) {
            *a += b;
        }
        self.rr += other.rr;
        self.yy += other.yy;
        Ok(())
    }
}

/// What a pass does with each point's rows.
#[derive(Clone, Copy, PartialEq)]
enum Pass {
    /// whiten by V and fold
    Weighted,
    /// fold as they are and sum X_kᵀ V_k X_k
    Sandwich,
    /// only the residual sums at θ
    Residual,
}

/// One pass over the selected points for the four fits at `thetas`, in fixed tasks merged in order.
fn over_points(p: &CovFitProblem, thetas: &[Vec<f64>], u: usize, pass: Pass) -> Result<Vec<FitSums>, CoreError> {
    let f = &p.fit.forces;
    let n = f.points();
    let kc = Consts::new(&f.rotor);
    let need_v = pass != Pass::Residual;
    let ntasks = n.div_ceil(POINTS_PER_TASK);
    let mut parts: Vec<Option<Result<Vec<FitSums>, CoreError>>> = (0..ntasks).map(|_| None).collect();
    let slots = Disjoint::new(&mut parts);
    for_each_task(ntasks, |j| {
        let task = || -> Result<Vec<FitSums>, CoreError> {
            let mut sums = (0..4).map(|_| FitSums::new(u)).collect::<Result<Vec<_>, _>>()?;
            let mut pd = PointData { s: C64::new(0.0, 0.0), a: [[C64::new(0.0, 0.0); 4]; 4], force: Vec::new(), ped: Vec::new(), cov: Vec::new() };
            let (mut xy, mut v, mut l) = (Vec::new(), Vec::new(), Vec::new());
            let nr = 2 * f.runs;
            let (a, z) = (j * POINTS_PER_TASK, ((j + 1) * POINTS_PER_TASK).min(n));
            for k in (a..z).filter(|&k| p.fit.select.is_empty() || p.fit.select[k]) {
                PointData::load(p, &kc, k, need_v, &mut pd);
                for (fi, acc) in sums.iter_mut().enumerate() {
                    let theta = &thetas[fi];
                    fit_rows(p, &pd, k, fi, theta, need_v, &mut xy, &mut v);
                    for row in xy.chunks_exact(u + 1) {
                        for (m, x) in acc.mx.iter_mut().zip(&row[..u]) {
                            *m = m.max(x.abs());
                        }
                        let fit: f64 = row[..u].iter().zip(theta).map(|(x, t)| x * t).sum();
                        acc.rr += (row[u] - fit) * (row[u] - fit);
                        acc.yy += row[u] * row[u];
                    }
                    if pass == Pass::Sandwich {
                        for a1 in 0..u {
                            for b1 in 0..u {
                                let mut sum = 0.0;
                                for r1 in 0..nr {
                                    let xa = xy[r1 * (u + 1) + a1];
                                    for r2 in 0..nr {
                                        sum += xa * v[r1 * nr + r2] * xy[r2 * (u + 1) + b1];
                                    }
                                }
                                acc.meat[a1 * u + b1] += sum;
                            }
                        }
                    }
                    if pass == Pass::Weighted {
                        whiten(&v, nr, u, &mut l, &mut xy).map_err(|_| {
                            CoreError::value(
                                "covs",
                                format!("give point {k} a residual covariance that is not positive definite (a shared covariance larger than a run's own?)"),
                            )
                        })?;
                    }
                    if pass != Pass::Residual {
                        for row in xy.chunks_exact(u + 1) {
                            acc.qr.push(row)?;
                        }
                    }
                }
            }
            Ok(sums)
        };
        // SAFETY: for_each_task hands each task index j to one task
        let slot = unsafe { slots.chunk(j, 1) };
        slot[0] = Some(task());
    });
    let mut total = (0..4).map(|_| FitSums::new(u)).collect::<Result<Vec<_>, _>>()?;
    for part in parts {
        let part = part.unwrap_or_else(|| Err(CoreError::value("tasks", "a task did not run")))?;
        for (t, s) in total.iter_mut().zip(part) {
            t.merge(s)?;
        }
    }
    Ok(total)
}

/// Rows [X y] (nr x (u + 1)) replaced by L⁻¹ [X y], L Lᵀ = V + 1e-300 I (Cholesky from V's lower
/// triangle, as LAPACK reads it); `Err` when V is not positive definite.
fn whiten(v: &[f64], nr: usize, u: usize, l: &mut Vec<f64>, xy: &mut [f64]) -> Result<(), ()> {
    l.resize(nr * nr, 0.0);
    if cholesky_lower(v, nr, 1e-300, 0.0, l) > 0 {
        return Err(());
    }
    for c in 0..=u {
        for r1 in 0..nr {
            let mut s = xy[r1 * (u + 1) + c];
            for q in 0..r1 {
                s -= l[r1 * nr + q] * xy[q * (u + 1) + c];
            }
            xy[r1 * (u + 1) + c] = s / l[r1 * nr + r1];
        }
    }
    Ok(())
}

/// The solution of a fold of unscaled rows, on the columns scaled by `d`.
fn scaled_solution(qr: &mut TallQr, d: &[f64], u: usize) -> Result<Solution, CoreError> {
    let mut r = qr.factor();
    if (0..=u).any(|i| (i..=u).any(|j| !r[i][j].is_finite())) {
        return Err(CoreError::value("runs", "contain NaN or inf"));
    }
    for row in r.iter_mut().take(u + 1) {
        for (j, dj) in d.iter().enumerate() {
            row[j] /= dj;
        }
    }
    Solution::from_factor(&r, u + 1, qr.rows())
}

/// One weighted step of the four fits (index 2 b + i) with V at `thetas` (physical units);
/// `with_resid`: also the unweighted relative residual at the new θ (a second pass; NaN without).
pub fn weighted_step(p: &CovFitProblem, thetas: &[Vec<f64>], with_resid: bool) -> Result<Vec<WeightedStep>, CoreError> {
    let u = p.check(thetas)?;
    let sums = over_points(p, thetas, u, Pass::Weighted)?;
    let mut steps = Vec::with_capacity(4);
    for mut fs in sums {
        let rows = fs.qr.rows();
        if rows <= u {
            return Err(CoreError::value("select", format!("leaves {rows} equations for {u} unknowns")));
        }
        let d: Vec<f64> = fs.mx[..u].iter().map(|v| v.max(1e-300)).collect();
        let sol = scaled_solution(&mut fs.qr, &d, u)?;
        let theta: Vec<f64> = sol.theta.iter().zip(&d).map(|(t, s)| t / s).collect();
        let xi = sol.xtx_inv();
        let cov = (0..u * u).map(|ij| xi[ij] / (d[ij / u] * d[ij % u])).collect();
        let chi2 = sol.residual_norm * sol.residual_norm / ((rows - u) as f64).max(1.0);
        steps.push(WeightedStep { theta, cov, chi2, resid: f64::NAN, rank: sol.rank });
    }
    if with_resid && steps.iter().all(|s| s.rank == u) {
        let thetas: Vec<Vec<f64>> = steps.iter().map(|s| s.theta.clone()).collect();
        for (st, fs) in steps.iter_mut().zip(over_points(p, &thetas, u, Pass::Residual)?) {
            st.resid = (fs.rr / fs.yy.max(1e-300)).sqrt();
        }
    }
    Ok(steps)
}

/// The sandwich covariances (u × u, units of θ) of the four unweighted fits (index 2 b + i) with
/// V at `thetas`; NaN for a fit whose design is rank deficient.
pub fn sandwich(p: &CovFitProblem, thetas: &[Vec<f64>]) -> Result<Vec<Vec<f64>>, CoreError> {
    let u = p.check(thetas)?;
    over_points(p, thetas, u, Pass::Sandwich)?
        .into_iter()
        .map(|mut fs| {
            let d: Vec<f64> = fs.mx[..u].iter().map(|v| v.max(1e-300)).collect();
            let sol = scaled_solution(&mut fs.qr, &d, u)?;
            if sol.rank < u {
                return Ok(vec![f64::NAN; u * u]);
            }
            let meat_s: Vec<f64> = (0..u * u).map(|ij| fs.meat[ij] / (d[ij / u] * d[ij % u])).collect();
            let c = sol.sandwich(&meat_s);
            Ok((0..u * u).map(|ij| c[ij] / (d[ij / u] * d[ij % u])).collect())
        })
        .collect()
}

/// The covariance fit of one (pedestal, direction).
#[derive(Clone, Debug)]
pub struct CovFit {
    /// θ: the weighted estimate, or the unweighted one given (sandwich)
    pub theta: Vec<f64>,
    /// weighted: (X_wᵀ X_w)⁻¹ max(χ², 1) (a misfit beyond the measurement errors widens it);
    /// sandwich: the sandwich covariance. Units of θ, (u × u) row-major.
    pub cov: Vec<f64>,
    /// weighted: |y - X θ| / |y| at the weighted θ; NaN for the sandwich
    pub resid: f64,
}

/// Weighted steps per fit: V depends on θ, so the weights of the second step come from the first
/// step's estimate.
pub const WEIGHTED_STEPS: usize = 2;

/// All four fits (index 2 b + i) from the unweighted estimates `thetas` (as [`crate::pedestal_fit::fit`]
/// gives them, of full rank): [`WEIGHTED_STEPS`] weighted steps each (`weighted`), or the sandwich
/// covariance at the unweighted estimate.
pub fn cov_fit(p: &CovFitProblem, thetas: &[Vec<f64>], weighted: bool) -> Result<Vec<CovFit>, CoreError> {
    if !weighted {
        let covs = sandwich(p, thetas)?;
        return Ok(thetas.iter().zip(covs).map(|(t, cov)| CovFit { theta: t.clone(), cov, resid: f64::NAN }).collect());
    }
    let mut steps = weighted_step(p, thetas, WEIGHTED_STEPS == 1)?;
    for step in 1..WEIGHTED_STEPS {
        if steps.iter().any(|s| s.rank < s.theta.len()) {
            break;
        }
        let next: Vec<Vec<f64>> = steps.iter().map(|s| s.theta.clone()).collect();
        steps = weighted_step(p, &next, step + 1 == WEIGHTED_STEPS)?;
    }
    Ok(steps
        .into_iter()
        .map(|s| {
            let widen = s.chi2.max(1.0);
            CovFit { cov: s.cov.iter().map(|c| c * widen).collect(), theta: s.theta, resid: s.resid }
        })
        .collect())
}
