//! Monte Carlo identification studies in one pass: simulate, perturb, identify, accumulate.
//!
//! A study repeats a test many times with random measurement errors (docs/studies.md) and
//! summarizes the error of every identified coefficient at every point (speed or frequency). The
//! core does a whole trial without handing anything back: for each trial and block of points it
//! draws the trial's errors from counter-based random numbers ([`rng`]), builds the measured 1X
//! vectors (or FRFs) from the exact responses, identifies as rotorid does on measured data, and
//! adds the 16 relative errors to streaming statistics ([`StudyStats`]). Memory is that of the
//! statistics, whatever the number of trials.
//!
//! Determinism: every random number depends only on (seed, trial, point); each point's statistics
//! are accumulated by one task in trial order; so the result of a call does not depend on the
//! number of threads. Calls over consecutive trial ranges merge exactly (integer counts) and,
//! if merged in range order, reproduce the sums of one call over the union bit for bit when the
//! ranges are the same (fixed-size blocks).
//!
//! Exact responses: with H(Ω, ω) = K − ω²M + jω(C + ΩG) (true coefficients at each point),
//! imbalance in plane p at axial position z_p of run r gives q = Ω² H⁻¹ Σ_p u_p [1, −j, z_p, j z_p]ᵀ
//! (report eq. 4, 13), a unit impact at z in x (y) gives q = H⁻¹ [1, 0, z, 0]ᵀ ([0, 1, 0, −z]ᵀ).
//! A probe at axial position z reads x(z) = ((l2 − z) x1 + (l1 + z) x2) / (l1 + l2).

pub mod rng;
pub mod stats;

use crate::error::{expect_len, expect_len_or_broadcast, product, CoreError};
use crate::forced::forced_response;
use crate::identify::{identify_forces, identify_report, IdentOut, IdentProblem, REPORT_TO_BIJ};
use crate::model::{Rotor, C64};
use rayon::prelude::*;
use rng::{normal_pair, stream_key};
pub use stats::{bin_edges, percentiles_of_counts, StudyStats, BINS, E0};

/// Coefficients per point: K and C of both bearings in the report's order (eq. 9).
pub const NCOEF: usize = 16;
/// Points identified together by one task (one call of the identification kernel per trial).
const POINT_BLOCK: usize = 32;
/// Stride of the histograms while they are filled (BINS plus one cache line).
const HIST_STRIDE: usize = BINS + 16;

/// Errors of a synchronous study: standard deviations (0 switches an error off).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SyncErrors {
    /// relative error of each 1X amplitude
    pub amplitude_rel: f64,
    /// error of each 1X phase, rad
    pub phase_rad: f64,
    /// complex noise added to each 1X vector, rms of the modulus, m
    pub noise_m: f64,
    /// keyphasor mark offset, common to every vector of a trial, rad
    pub keyphasor_rad: f64,
    /// delay of each probe channel, s
    pub delay_s: f64,
    /// axial position error of each probe, m
    pub probe_position_m: f64,
    /// relative error of each trial mass (m r)
    pub mass_rel: f64,
    /// angular error of each trial mass, rad
    pub angle_rad: f64,
    /// relative error of the speed told to the identification
    pub speed_rel: f64,
}

/// Errors of an impact study: standard deviations (0 switches an error off).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImpactErrors {
    /// normalized random error of each H1 FRF, ε = sqrt((1 − γ²) / (2 n γ²))
    pub frf_rel: f64,
    /// relative error of the force sensor gain of each test
    pub force_cal_rel: f64,
    /// axial error of where each test's impacts land, m
    pub impact_position_m: f64,
    /// delay of each probe channel, s
    pub delay_s: f64,
    /// axial position error of each probe, m
    pub probe_position_m: f64,
}

/// What excites the rotor in every run.
#[derive(Clone, Copy, Debug)]
pub enum Excitation<'a> {
    /// Imbalance runs: `u` (runs, 2) = m r e^{−jφ} in planes 1 and 2 at axial positions `planes_z`;
    /// the points are running speeds.
    Imbalance { u: &'a [C64], planes_z: [f64; 2], errors: SyncErrors },
    /// Impact tests at axial positions `planes_z` in directions `dirs` (0 = x, 1 = y), at the
    /// running speed `spin` (rad/s); the points are vibration frequencies.
    Impact { planes_z: &'a [f64], dirs: &'a [u8], spin: f64, errors: ImpactErrors },
}

/// Identification method (see [`crate::identify`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    Forces,
    Report,
}

/// A study: the true system, the test, the errors and the seed.
#[derive(Clone, Copy, Debug)]
pub struct Study<'a> {
    pub rotor: Rotor,
    /// points: running speeds (imbalance) or vibration frequencies (impacts), rad/s, (n,)
    pub w: &'a [f64],
    /// true coefficients at each point, (n, 8) or (1, 8), order [bearing][i][j]
    pub kb: &'a [f64],
    pub cb: &'a [f64],
    /// nominal axial positions of the channels x1, x2, y1, y2 (m from the CG)
    pub probes_z: [f64; 4],
    pub excitation: Excitation<'a>,
    pub method: Method,
    pub seed: u64,
}

impl Study<'_> {
    /// Runs (imbalance) or tests (impacts).
    pub fn runs(&self) -> usize {
        match self.excitation {
            Excitation::Imbalance { u, .. } => u.len() / 2,
            Excitation::Impact { planes_z, .. } => planes_z.len(),
        }
    }

    /// Check every length and value.
    pub fn check(&self) -> Result<(), CoreError> {
        let n = self.w.len();
        if n == 0 {
            return Err(CoreError::value("w", "must hold at least one point"));
        }
        if self.w.iter().any(|&x| !(x.is_finite() && x > 0.0)) {
            return Err(CoreError::value("w", "(speeds or frequencies) must be finite and positive"));
        }
        expect_len_or_broadcast("kb", self.kb, 8, product("kb", &[n, 8])?)?;
        expect_len_or_broadcast("cb", self.cb, 8, product("cb", &[n, 8])?)?;
        if self.kb.iter().chain(self.cb).any(|v| !v.is_finite()) {
            return Err(CoreError::value("kb, cb", "(true coefficients) must be finite"));
        }
        let z = self.probes_z;
        if z.iter().any(|v| !v.is_finite()) || z[0] == z[1] || z[2] == z[3] {
            return Err(CoreError::value("probes_z", "must be finite, with the two x (and the two y) probes at different axial positions"));
        }
        let finite_nonneg = |name: &'static str, vals: &[f64]| -> Result<(), CoreError> {
            if vals.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(CoreError::value(name, "(standard deviations) must be finite and >= 0"));
            }
            Ok(())
        };
        let runs = self.runs();
        if runs < 2 {
            return Err(CoreError::value("runs", "must be at least 2"));
        }
        match self.excitation {
            Excitation::Imbalance { u, planes_z, errors: e } => {
                if u.len() % 2 != 0 {
                    return Err(CoreError::length("u", u.len(), "2 per run (planes 1 and 2)"));
                }
                if u.iter().any(|v| !v.is_finite()) || planes_z.iter().any(|v| !v.is_finite()) {
                    return Err(CoreError::value("u, planes_z", "must be finite"));
                }
                finite_nonneg(
                    "errors",
                    &[e.amplitude_rel, e.phase_rad, e.noise_m, e.keyphasor_rad, e.delay_s, e.probe_position_m, e.mass_rel, e.angle_rad, e.speed_rel],
                )?;
            }
            Excitation::Impact { planes_z, dirs, spin, errors: e } => {
                expect_len("dirs", dirs, planes_z.len())?;
                if dirs.iter().any(|&d| d > 1) {
                    return Err(CoreError::value("dirs", "must be 0 (x) or 1 (y)"));
                }
                if planes_z.iter().any(|v| !v.is_finite()) || !(spin.is_finite() && spin >= 0.0) {
                    return Err(CoreError::value("planes_z, spin", "must be finite (spin >= 0)"));
                }
                finite_nonneg("errors", &[e.frf_rel, e.force_cal_rel, e.impact_position_m, e.delay_s, e.probe_position_m])?;
            }
        }
        Ok(())
    }
}

/// Exact responses per point, independent of the trial: for imbalance the response to a unit
/// m r e^{−jφ} in each plane (2 vectors, Ω² included), for impacts the four columns of H⁻¹.
struct Exact {
    cols: Vec<C64>, // (n, ncol, 4)
}

fn exact_responses(s: &Study) -> Result<Exact, CoreError> {
    let n = s.w.len();
    let (ncol, force, spin): (usize, Vec<C64>, Vec<f64>) = match s.excitation {
        Excitation::Imbalance { planes_z, .. } => {
            let j = C64::new(0.0, 1.0);
            let mut f = Vec::with_capacity(8);
            for z in planes_z {
                f.extend_from_slice(&[C64::new(1.0, 0.0), -j, C64::new(z, 0.0), j * z]);
            }
            (2, f, s.w.to_vec())
        }
        Excitation::Impact { spin, .. } => {
            let mut f = vec![C64::new(0.0, 0.0); 16];
            for c in 0..4 {
                f[4 * c + c] = C64::new(1.0, 0.0);
            }
            (4, f, vec![spin; n])
        }
    };
    let mut cols = vec![C64::new(0.0, 0.0); n * ncol * 4];
    forced_response(&s.rotor, s.kb, s.cb, &spin, s.w, &force, ncol, &mut cols)?;
    if let Excitation::Imbalance { .. } = s.excitation {
        for (i, blk) in cols.chunks_mut(ncol * 4).enumerate() {
            let g = s.w[i] * s.w[i];
            blk.iter_mut().for_each(|v| *v *= g);
        }
    }
    Ok(Exact { cols })
}

/// Draws made once per trial (stream 0).
struct TrialDraws {
    /// channel delays (s) and true probe positions (m)
    tau: [f64; 4],
    zc: [f64; 4],
    /// keyphasor offset (rad, imbalance)
    kp: f64,
    /// true excitation per run: imbalance u (2 per run) or impact (plane, 1/force gain)
    u: Vec<C64>,
    plane: Vec<f64>,
    inv_cal: Vec<f64>,
}

fn trial_draws(s: &Study, trial: u64) -> TrialDraws {
    let key = stream_key(s.seed, trial, 0);
    let runs = s.runs();
    let npairs = match s.excitation {
        Excitation::Imbalance { .. } => (9 + 4 * runs).div_ceil(2),
        Excitation::Impact { .. } => (9 + 2 * runs).div_ceil(2),
    };
    let mut nv = vec![0.0; 2 * npairs];
    for j in 0..npairs {
        let (a, b) = normal_pair(key, j as u64);
        nv[2 * j] = a;
        nv[2 * j + 1] = b;
    }
    let (delay, pos) = match s.excitation {
        Excitation::Imbalance { errors: e, .. } => (e.delay_s, e.probe_position_m),
        Excitation::Impact { errors: e, .. } => (e.delay_s, e.probe_position_m),
    };
    let mut d = TrialDraws { tau: [0.0; 4], zc: s.probes_z, kp: 0.0, u: vec![], plane: vec![], inv_cal: vec![] };
    for c in 0..4 {
        d.tau[c] = delay * nv[1 + c];
        d.zc[c] += pos * nv[5 + c];
    }
    match s.excitation {
        Excitation::Imbalance { u, errors: e, .. } => {
            d.kp = e.keyphasor_rad * nv[0];
            d.u = (0..runs * 2)
                .map(|k| {
                    let (r, p) = (k / 2, k % 2);
                    let ang = -e.angle_rad * nv[11 + 4 * r + p];
                    let (sn, cs) = rng::sincos_turns(ang / std::f64::consts::TAU);
                    u[k] * (1.0 + e.mass_rel * nv[9 + 4 * r + p]) * C64::new(cs, sn)
                })
                .collect();
        }
        Excitation::Impact { planes_z, errors: e, .. } => {
            d.plane = (0..runs).map(|t| planes_z[t] + e.impact_position_m * nv[10 + 2 * t]).collect();
            d.inv_cal = (0..runs).map(|t| 1.0 / (1.0 + e.force_cal_rel * nv[9 + 2 * t])).collect();
        }
    }
    d
}

/// Scratch arrays of one task, reused for every trial (lengths: runs * points * 4).
#[derive(Default)]
struct Scratch {
    keys: Vec<u64>,
    n1: Vec<f64>,
    n2: Vec<f64>,
    sin: Vec<f64>,
    cos: Vec<f64>,
    turns: Vec<f64>,
    amp: Vec<f64>,
}

impl Scratch {
    fn fit(&mut self, len: usize, np: usize) {
        for v in [&mut self.n1, &mut self.n2, &mut self.sin, &mut self.cos, &mut self.turns, &mut self.amp] {
            v.resize(len, 0.0);
        }
        self.keys.resize(np, 0);
    }
}

/// Normal pairs `pair(i)` of the streams `keys[i / per]` for i in 0..n1.len(), into n1, n2.
/// Written as one flat loop without branches so that it compiles to SIMD code.
#[inline(always)]
fn fill_normals(keys: &[u64], per: usize, pair: impl Fn(usize) -> u64, n1: &mut [f64], n2: &mut [f64]) {
    for (k, &key) in keys.iter().enumerate() {
        let (a, b) = (&mut n1[k * per..(k + 1) * per], &mut n2[k * per..(k + 1) * per]);
        for j in 0..per {
            let (x, y) = normal_pair(key, pair(j));
            a[j] = x;
            b[j] = y;
        }
    }
}

#[inline(always)]
fn fill_sincos(turns: &[f64], sin: &mut [f64], cos: &mut [f64]) {
    for i in 0..turns.len() {
        let (s, c) = rng::sincos_turns(turns[i]);
        sin[i] = s;
        cos[i] = c;
    }
}

/// Measured values of one trial at the points `p0..p0 + np`: `q` (runs, np, 4) at the channels,
/// `w_told` (np,) the point frequencies the identification is told. The random numbers and the
/// rotations are computed in flat arrays first (vectorized), then applied.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn realize_block(s: &Study, ex: &Exact, d: &TrialDraws, trial: u64, p0: usize, np: usize, q: &mut [C64], w_told: &mut [f64], sc: &mut Scratch) {
    let runs = s.runs();
    let per = runs * 4; // values per point
    let len = np * per;
    sc.fit(len, np);
    let (l1, l2) = (s.rotor.l1, s.rotor.l2);
    let il = 1.0 / s.rotor.span();
    // probe weights at the true positions: channel c = wa q[ia] + wb q[ia + 1]
    let mut wa = [0.0; 4];
    let mut wb = [0.0; 4];
    for c in 0..4 {
        wa[c] = (l2 - d.zc[c]) * il;
        wb[c] = (l1 + d.zc[c]) * il;
    }
    let tau_turns = d.tau.map(|t| t / std::f64::consts::TAU);
    for k in 0..np {
        sc.keys[k] = stream_key(s.seed, trial, 1 + (p0 + k) as u64);
    }
    let w = &s.w[p0..p0 + np];
    // value index i = k * per + r * 4 + c (point k, run r, channel c)
    match s.excitation {
        Excitation::Imbalance { errors: e, .. } => {
            if e.speed_rel > 0.0 {
                for k in 0..np {
                    w_told[k] = w[k] * (1.0 + e.speed_rel * normal_pair(sc.keys[k], 0).0);
                }
            } else {
                w_told[..np].copy_from_slice(w);
            }
            // amplitude factor and phase (turns) of every value
            if e.amplitude_rel > 0.0 || e.phase_rad > 0.0 {
                fill_normals(&sc.keys, per, |j| 1 + 2 * j as u64, &mut sc.n1[..len], &mut sc.n2[..len]);
            } else {
                sc.n1[..len].fill(0.0);
                sc.n2[..len].fill(0.0);
            }
            let (ph, kp) = (e.phase_rad / std::f64::consts::TAU, d.kp / std::f64::consts::TAU);
            for (k, (tr, n2)) in sc.turns[..len].chunks_exact_mut(per).zip(sc.n2[..len].chunks_exact(per)).enumerate() {
                let off = tau_turns.map(|t| kp - w[k] * t);
                for (j, (t, &nv)) in tr.iter_mut().zip(n2).enumerate() {
                    *t = ph * nv + off[j & 3];
                }
            }
            for (a, &nv) in sc.amp[..len].iter_mut().zip(&sc.n1[..len]) {
                *a = 1.0 + e.amplitude_rel * nv;
            }
            if e.phase_rad > 0.0 || e.keyphasor_rad > 0.0 || e.delay_s > 0.0 {
                fill_sincos(&sc.turns[..len], &mut sc.sin[..len], &mut sc.cos[..len]);
            } else {
                sc.sin[..len].fill(0.0);
                sc.cos[..len].fill(1.0);
            }
            let noise = e.noise_m > 0.0;
            if noise {
                fill_normals(&sc.keys, per, |j| 2 + 2 * j as u64, &mut sc.n1[..len], &mut sc.n2[..len]);
            }
            let g = e.noise_m * std::f64::consts::FRAC_1_SQRT_2;
            for k in 0..np {
                let cols = &ex.cols[(p0 + k) * 8..(p0 + k + 1) * 8];
                for r in 0..runs {
                    let (u1, u2) = (d.u[2 * r], d.u[2 * r + 1]);
                    let qb: [C64; 4] = std::array::from_fn(|i| u1 * cols[i] + u2 * cols[4 + i]);
                    for c in 0..4 {
                        let i = k * per + r * 4 + c;
                        let ia = if c < 2 { 0 } else { 2 };
                        let x = qb[ia] * wa[c] + qb[ia + 1] * wb[c];
                        let mut v = x * C64::new(sc.amp[i] * sc.cos[i], sc.amp[i] * sc.sin[i]);
                        if noise {
                            v += C64::new(sc.n1[i] * g, sc.n2[i] * g);
                        }
                        q[(r * np + k) * 4 + c] = v;
                    }
                }
            }
        }
        Excitation::Impact { dirs, errors: e, .. } => {
            w_told[..np].copy_from_slice(w);
            if e.frf_rel > 0.0 {
                fill_normals(&sc.keys, per, |j| 1 + j as u64, &mut sc.n1[..len], &mut sc.n2[..len]);
            } else {
                sc.n1[..len].fill(0.0);
                sc.n2[..len].fill(0.0);
            }
            for k in 0..np {
                for j in 0..per {
                    sc.turns[k * per + j] = -w[k] * tau_turns[j % 4];
                }
            }
            if e.delay_s > 0.0 {
                fill_sincos(&sc.turns[..len], &mut sc.sin[..len], &mut sc.cos[..len]);
            } else {
                sc.sin[..len].fill(0.0);
                sc.cos[..len].fill(1.0);
            }
            for k in 0..np {
                let cols = &ex.cols[(p0 + k) * 16..(p0 + k + 1) * 16];
                for t in 0..runs {
                    let z = d.plane[t];
                    let qb: [C64; 4] = if dirs[t] == 0 {
                        std::array::from_fn(|i| cols[i] + cols[8 + i] * z)
                    } else {
                        std::array::from_fn(|i| cols[4 + i] - cols[12 + i] * z)
                    };
                    for c in 0..4 {
                        let i = k * per + t * 4 + c;
                        let ia = if c < 2 { 0 } else { 2 };
                        let x = qb[ia] * wa[c] + qb[ia + 1] * wb[c];
                        let err = C64::new(1.0 + e.frf_rel * sc.n1[i], e.frf_rel * sc.n2[i]);
                        q[(t * np + k) * 4 + c] = x * err * C64::new(sc.cos[i], sc.sin[i]) * d.inv_cal[t];
                    }
                }
            }
        }
    }
}

/// Nominal excitation vectors the identification is given, (runs, 4).
fn nominal_excitation(s: &Study) -> Vec<C64> {
    let j = C64::new(0.0, 1.0);
    match s.excitation {
        Excitation::Imbalance { u, planes_z, .. } => (0..s.runs())
            .flat_map(|r| {
                let sum = u[2 * r] + u[2 * r + 1];
                let mom = u[2 * r] * planes_z[0] + u[2 * r + 1] * planes_z[1];
                [sum, -j * sum, mom, j * mom]
            })
            .collect(),
        Excitation::Impact { planes_z, dirs, .. } => (0..s.runs())
            .flat_map(|t| {
                let z = planes_z[t];
                if dirs[t] == 0 {
                    [C64::new(1.0, 0.0), C64::new(0.0, 0.0), C64::new(z, 0.0), C64::new(0.0, 0.0)]
                } else {
                    [C64::new(0.0, 0.0), C64::new(1.0, 0.0), C64::new(0.0, 0.0), C64::new(-z, 0.0)]
                }
            })
            .collect(),
    }
}

/// Channel readings at the nominal probe positions -> bearing coordinates (report eq. 19, for
/// any probe positions): x(z) = a + b z through the two readings, evaluated at −l1 and +l2.
fn to_bearings(s: &Study, q: &mut [C64]) {
    let z = s.probes_z;
    let (l1, l2) = (s.rotor.l1, s.rotor.l2);
    if z == [-l1, l2, -l1, l2] {
        return;
    }
    let ix = 1.0 / (z[1] - z[0]);
    let iy = 1.0 / (z[3] - z[2]);
    for v in q.chunks_exact_mut(4) {
        let bx = (v[1] - v[0]) * ix;
        let by = (v[3] - v[2]) * iy;
        let (x0, y0) = (v[0], v[2]);
        v[0] = x0 + bx * (-l1 - z[0]);
        v[1] = x0 + bx * (l2 - z[0]);
        v[2] = y0 + by * (-l1 - z[2]);
        v[3] = y0 + by * (l2 - z[2]);
    }
}

/// The measured values of trials `t0..t1` at every point, as the identification would receive
/// them before the probe-to-bearing transform: `q` (trials, runs, n, 4) at the channels and
/// `w_told` (trials, n). For checking a study against another implementation of the same model.
pub fn realize(s: &Study, t0: u64, t1: u64, q: &mut [C64], w_told: &mut [f64]) -> Result<(), CoreError> {
    s.check()?;
    if t1 < t0 {
        return Err(CoreError::value("trials", "end before start"));
    }
    let (n, runs, nt) = (s.w.len(), s.runs(), (t1 - t0) as usize);
    expect_len("q", q, product("q", &[nt, runs, n, 4])?)?;
    expect_len("w_told", w_told, product("w_told", &[nt, n])?)?;
    let ex = exact_responses(s)?;
    q.par_chunks_mut(runs * n * 4).zip(w_told.par_chunks_mut(n)).enumerate().for_each(|(i, (qt, wt))| {
        let trial = t0 + i as u64;
        let d = trial_draws(s, trial);
        realize_block(s, &ex, &d, trial, 0, n, qt, wt, &mut Scratch::default());
    });
    Ok(())
}

/// Relative error of each coefficient (report order) against the truth: (p̂ − p) / ref with
/// ref = |p|, or for p = 0 the mean |direct coefficient| of the same kind and bearing.
fn references(s: &Study, p: usize) -> ([f64; NCOEF], [f64; NCOEF]) {
    let ko = if s.kb.len() == 8 { 0 } else { 8 * p };
    let co = if s.cb.len() == 8 { 0 } else { 8 * p };
    let (kb, cb) = (&s.kb[ko..ko + 8], &s.cb[co..co + 8]);
    let mut truth = [0.0; NCOEF];
    let mut inv_ref = [0.0; NCOEF];
    for o in 0..NCOEF {
        let src = if o < 8 { kb } else { cb };
        let bij = REPORT_TO_BIJ[o % 8];
        let b = bij / 4;
        let v = src[bij];
        let fallback = 0.5 * (src[4 * b].abs() + src[4 * b + 3].abs());
        let r = if v != 0.0 { v.abs() } else { fallback };
        truth[o] = v;
        inv_ref[o] = if r > 0.0 { 1.0 / r } else { f64::NAN };
    }
    (truth, inv_ref)
}

/// Accumulate trials `t0..t1` at points `p0..p1` into fresh statistics (points p0..p1).
///
/// Each block of points is one parallel task that runs through the trials in order: per trial
/// it draws the errors, builds the measured values, identifies, and adds the 16 relative errors
/// to its points' statistics. Memory: the statistics and a few blocks, whatever the trial count.
pub fn accumulate(s: &Study, t0: u64, t1: u64, p0: usize, p1: usize) -> Result<StudyStats, CoreError> {
    let mut st = StudyStats::new(p1.saturating_sub(p0));
    let StudyStats { counts, finite, nonfinite, sum, sumsq, .. } = &mut st;
    accumulate_into(s, t0, t1, p0, p1, StatsMut { counts, finite, nonfinite, sum, sumsq })?;
    Ok(st)
}

/// Statistics to add to, (points, 16[, BINS]) row-major (e.g. a caller's running totals: the
/// counts of many calls can go into one array without a new allocation per call).
pub struct StatsMut<'a> {
    pub counts: &'a mut [u32],
    pub finite: &'a mut [u32],
    pub nonfinite: &'a mut [u32],
    pub sum: &'a mut [f64],
    pub sumsq: &'a mut [f64],
}

/// [`accumulate`] adding into existing statistics of the points `p0..p1`.
pub fn accumulate_into(s: &Study, t0: u64, t1: u64, p0: usize, p1: usize, out: StatsMut) -> Result<(), CoreError> {
    s.check()?;
    if t1 < t0 {
        return Err(CoreError::value("trials", "end before start"));
    }
    let n = s.w.len();
    if !(p0 < p1 && p1 <= n) {
        return Err(CoreError::value("points", format!("range {p0}..{p1} must be non-empty and within 0..{n}")));
    }
    let np = p1 - p0;
    expect_len("counts", out.counts, product("counts", &[np, NCOEF, BINS])?)?;
    for (name, len) in [("finite", out.finite.len()), ("nonfinite", out.nonfinite.len()), ("sum", out.sum.len()), ("sumsq", out.sumsq.len())] {
        if len != np * NCOEF {
            return Err(CoreError::length(name, len, (np * NCOEF).to_string()));
        }
    }
    let ex = exact_responses(s)?;
    let e_nom = nominal_excitation(s);
    let (hist_blk, rest) = (POINT_BLOCK * NCOEF * BINS, POINT_BLOCK * NCOEF);
    let StatsMut { counts, finite, nonfinite, sum, sumsq } = out;
    counts
        .par_chunks_mut(hist_blk)
        .zip(finite.par_chunks_mut(rest))
        .zip(nonfinite.par_chunks_mut(rest))
        .zip(sum.par_chunks_mut(rest))
        .zip(sumsq.par_chunks_mut(rest))
        .enumerate()
        .try_for_each(|(b, ((((cnt, fin), nonf), sm), sq))| {
            let blk = StatsMut { counts: cnt, finite: fin, nonfinite: nonf, sum: sm, sumsq: sq };
            run_block_dispatch(s, &ex, &e_nom, t0, t1, p0 + b * POINT_BLOCK, blk)
        })
}

/// All trials t0..t1 at the block of points starting at `bp0`, in trial order.
#[inline(always)]
fn run_block(s: &Study, ex: &Exact, e_nom: &[C64], t0: u64, t1: u64, bp0: usize, mut out: StatsMut) -> Result<(), CoreError> {
    let bnp = out.finite.len() / NCOEF;
    // the block's histograms with a padded stride: at a stride of exactly BINS u32 (4 KiB) the
    // same bin of every histogram maps to one L1 cache set, and the increments thrash it. The
    // buffer is the thread's own, kept between calls: a fresh 2 MB per block and call cost more in
    // page faults than the increments themselves.
    // (taken out of the thread-local and put back: the work must not run inside a closure, which
    // would not inherit the caller's #[target_feature] SIMD level)
    let mut hist = HIST.with(|cell| cell.take());
    hist.clear();
    hist.resize(bnp * NCOEF * HIST_STRIDE, 0);
    let res = run_trials(s, ex, e_nom, t0, t1, bp0, bnp, &mut hist, &mut out);
    if res.is_ok() {
        for (dst, src) in out.counts.chunks_exact_mut(BINS).zip(hist.chunks_exact(HIST_STRIDE)) {
            for (d, v) in dst.iter_mut().zip(&src[..BINS]) {
                *d += v;
            }
        }
    }
    HIST.with(|cell| cell.replace(hist));
    res
}

thread_local! {
    /// Each thread's histogram buffer (see [`run_block`]).
    static HIST: std::cell::RefCell<Vec<u32>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// The trials of [`run_block`], counting into `hist` (padded stride) and adding to `out`'s sums.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn run_trials(s: &Study, ex: &Exact, e_nom: &[C64], t0: u64, t1: u64, bp0: usize, bnp: usize, hist: &mut [u32], out: &mut StatsMut) -> Result<(), CoreError> {
    let runs = s.runs();
    let mut sc = Scratch::default();
    let mut q = vec![C64::new(0.0, 0.0); runs * bnp * 4];
    let mut w_told = vec![0.0; bnp];
    let (mut k, mut c) = (vec![0.0; bnp * 8], vec![0.0; bnp * 8]);
    let (mut cond, mut resid, mut amp) = (vec![0.0; bnp * 2], vec![0.0; bnp], vec![0.0; bnp]);
    let mut gain = vec![0.0; bnp];
    let mut errs = vec![0.0; bnp * NCOEF];
    let mut bins = vec![0u32; bnp * NCOEF];
    let (mut truth, mut inv_ref) = (vec![0.0; bnp * NCOEF], vec![0.0; bnp * NCOEF]);
    for i in 0..bnp {
        let (t, r) = references(s, bp0 + i);
        truth[i * NCOEF..(i + 1) * NCOEF].copy_from_slice(&t);
        inv_ref[i * NCOEF..(i + 1) * NCOEF].copy_from_slice(&r);
    }
    let spin_imp = match s.excitation {
        Excitation::Impact { spin, .. } => [spin],
        _ => [0.0],
    };
    for trial in t0..t1 {
        let d = trial_draws(s, trial);
        realize_block(s, ex, &d, trial, bp0, bnp, &mut q, &mut w_told, &mut sc);
        to_bearings(s, &mut q);
        let blocks: Vec<&[C64]> = q.chunks_exact(bnp * 4).collect();
        let (spin, gain_s): (&[f64], &[f64]) = match s.excitation {
            Excitation::Imbalance { .. } => {
                for (g, w) in gain.iter_mut().zip(&w_told) {
                    *g = w * w;
                }
                (&w_told, &gain)
            }
            Excitation::Impact { .. } => (&spin_imp, &[1.0]),
        };
        let prob = IdentProblem { rotor: s.rotor, w: &w_told, spin, q: &blocks, e: e_nom, gain: gain_s, sigma: &[], q_ped: &[], planes: None, batch: 1, runs, identical: false };
        let o = IdentOut { k: &mut k, c: &mut c, cond: &mut cond, resid: &mut resid, amp: &mut amp, k_std: None, c_std: None, rel_std: None };
        match s.method {
            Method::Forces => identify_forces(&prob, o)?,
            Method::Report => identify_report(&prob, o)?,
        };
        // relative errors in report order, their bins (one flat loop each), then the counts
        for i in 0..bnp {
            for o in 0..NCOEF {
                let est = if o < 8 { k[8 * i + REPORT_TO_BIJ[o]] } else { c[8 * i + REPORT_TO_BIJ[o - 8]] };
                errs[i * NCOEF + o] = est;
            }
        }
        for j in 0..errs.len() {
            errs[j] = (errs[j] - truth[j]) * inv_ref[j];
            bins[j] = stats::bin(errs[j]);
        }
        stats::add_block(&errs, &bins, hist, HIST_STRIDE, out.finite, out.nonfinite, out.sum, out.sumsq);
    }
    Ok(())
}

crate::lanes::simd_dispatch! {
    /// [`run_block`] at the widest SIMD level of this CPU.
    fn run_block_dispatch(s: &Study, ex: &Exact, e_nom: &[C64], t0: u64, t1: u64, bp0: usize, out: StatsMut) -> Result<(), CoreError> => run_block
}
