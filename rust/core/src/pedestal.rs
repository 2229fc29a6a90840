//! The rigid rotor on bearings mounted in flexible pedestals (8 degrees of freedom).
//!
//! Each bearing housing (pedestal) b is a point mass on springs and dampers to ground, moving
//! with p_b = (xp_b, yp_b). The bearing force acts on the relative motion r_b = q_b - p_b of the
//! journal in its housing, on the rotor with one sign and on the pedestal with the other:
//!
//! ```text
//!   rotor     M q'' + Omega G q' + A(K_b r + C_b r') = F            (report eq. 1, q absolute)
//!   pedestal  M_p p_b'' + C_p p_b' + K_p p_b        = K_b r_b + C_b r_b'
//! ```
//!
//! with A the map of the bearing forces onto the rotor's force and moment rows (eq. 3). At a
//! vibration frequency w the bearing impedance Z_b = K_b + j w C_b and the pedestal dynamic
//! stiffness D_b = K_p - w^2 M_p + j w C_p act in series, so the rotor sees
//!
//! ```text
//!   Z_eff = (Z_b^-1 + D_b^-1)^-1 = D_b (Z_b + D_b)^-1 Z_b,    p_b = T_b q_b,   T_b = (Z_b + D_b)^-1 Z_b,
//! ```
//!
//! (the form without inverses of Z_b or D_b holds when either is singular: a pedestal at its own
//! undamped resonance, a bearing without stiffness). The forced response is the 4-DOF one with
//! Z_eff; the modal analysis works on the full 16-state system.
//!
//! Pedestal parameters of one call: 20 numbers `[m (4): [pedestal][x, y]; k (8), c (8):
//! [pedestal][i][j]]`, pedestal 1 at bearing 1.

use crate::eig8;
use crate::error::{expect_len, expect_len_or_broadcast, product, CoreError};
use crate::forced;
use crate::model::{assemble, Rotor, C64};
use crate::modal::{modes_of, ModeShapes};
use crate::series::C2;
use rayon::prelude::*;

/// Mass, stiffness and damping of the two pedestals.
#[derive(Clone, Copy, Debug)]
pub struct Pedestals {
    /// mass [pedestal][x, y], kg
    pub m: [f64; 4],
    /// stiffness [pedestal][i][j] to ground, N/m
    pub k: [f64; 8],
    /// damping [pedestal][i][j] to ground, N s/m
    pub c: [f64; 8],
}


impl Pedestals {
    /// From `[m (4), k (8), c (8)]`; masses must be >= 0, every value finite.
    pub fn from_slice(p: &[f64]) -> Result<Pedestals, CoreError> {
        expect_len("pedestals", p, 20)?;
        if p.iter().any(|v| !v.is_finite()) {
            return Err(CoreError::value("pedestals", "must be finite"));
        }
        if p[..4].iter().any(|&m| m < 0.0) {
            return Err(CoreError::value("pedestals", "masses must be >= 0"));
        }
        let mut out = Pedestals { m: [0.0; 4], k: [0.0; 8], c: [0.0; 8] };
        out.m.copy_from_slice(&p[..4]);
        out.k.copy_from_slice(&p[4..12]);
        out.c.copy_from_slice(&p[12..20]);
        Ok(out)
    }

    /// D_b(w) = K_p - w^2 M_p + j w C_p of pedestal `b`.
    #[inline]
    pub fn dynamic_stiffness(&self, b: usize, w: f64) -> C2 {
        let mut d = [[C64::new(0.0, 0.0); 2]; 2];
        for i in 0..2 {
            for j in 0..2 {
                let o = 4 * b + 2 * i + j;
                let mass = if i == j { self.m[2 * b + i] } else { 0.0 };
                d[i][j] = C64::new(self.k[o] - w * w * mass, w * self.c[o]);
            }
        }
        d
    }
}

pub use crate::series::series;

/// Bearing impedance Z_b = K_b + j w C_b from 8 coefficients [bearing][i][j].
#[inline]
fn bearing_impedance(kb: &[f64], cb: &[f64], b: usize, w: f64) -> C2 {
    let o = 4 * b;
    [
        [C64::new(kb[o], w * cb[o]), C64::new(kb[o + 1], w * cb[o + 1])],
        [C64::new(kb[o + 2], w * cb[o + 2]), C64::new(kb[o + 3], w * cb[o + 3])],
    ]
}

/// Effective (series) coefficients of bearing + pedestal at every point, as the rotor sees them:
/// K_eff = Re Z_eff, C_eff = Im Z_eff / w, and the transfer T_b (p_b = T_b q_b).
///
/// `kb`, `cb`: (n, 8) or (1, 8); `w`: (n,) rad/s, non-zero. Outputs: `k_eff`, `c_eff` (n, 8),
/// `transfer` (n, 8) complex [bearing][i][j]. Returns the number of points where Z + D is
/// singular (NaN there).
pub fn effective_coefficients(
    kb: &[f64],
    cb: &[f64],
    ped: &Pedestals,
    w: &[f64],
    k_eff: &mut [f64],
    c_eff: &mut [f64],
    transfer: &mut [C64],
) -> Result<usize, CoreError> {
    let n = w.len();
    expect_len_or_broadcast("k", kb, 8, product("k", &[n, 8])?)?;
    expect_len_or_broadcast("c", cb, 8, n * 8)?;
    expect_len("k_eff", k_eff, n * 8)?;
    expect_len("c_eff", c_eff, n * 8)?;
    expect_len("transfer", transfer, n * 8)?;
    check_w(w)?;
    // k and c broadcast each on its own: either may be one row for every point
    let (bk, bcc) = (kb.len() == 8, cb.len() == 8);
    let nbad = (k_eff.par_chunks_mut(8), c_eff.par_chunks_mut(8), transfer.par_chunks_mut(8))
        .into_par_iter()
        .with_min_len(256)
        .enumerate()
        .map(|(i, (ke, ce, tr))| {
            let (ok, oc) = (if bk { 0 } else { 8 * i }, if bcc { 0 } else { 8 * i });
            effective_point(&kb[ok..ok + 8], &cb[oc..oc + 8], ped, w[i], ke, ce, tr)
        })
        .sum();
    Ok(nbad)
}

/// The vibration frequencies of [`effective_coefficients`] and [`forced_response`]: finite and
/// non-zero (C_eff = Im Z_eff / w).
fn check_w(w: &[f64]) -> Result<(), CoreError> {
    if w.iter().any(|&x| !(x.is_finite() && x != 0.0)) {
        return Err(CoreError::value("w", "(vibration frequency) must be finite and non-zero"));
    }
    Ok(())
}

/// [`effective_coefficients`] at one point: `kb`, `cb` its 8 bearing coefficients, `ke`, `ce`,
/// `tr` its 8 outputs each; 1 when Z + D of a bearing is singular (its outputs NaN), else 0.
#[inline(always)]
fn effective_point(kb: &[f64], cb: &[f64], ped: &Pedestals, w: f64, ke: &mut [f64], ce: &mut [f64], tr: &mut [C64]) -> usize {
    let mut bad = 0usize;
    for b in 0..2 {
        let z = bearing_impedance(kb, cb, b, w);
        let d = ped.dynamic_stiffness(b, w);
        match series(&z, &d) {
            Some((t, ze)) => {
                for r in 0..2 {
                    for s in 0..2 {
                        let q = 4 * b + 2 * r + s;
                        ke[q] = ze[r][s].re;
                        ce[q] = ze[r][s].im / w;
                        tr[q] = t[r][s];
                    }
                }
            }
            None => {
                bad = 1;
                for q in 4 * b..4 * b + 4 {
                    ke[q] = f64::NAN;
                    ce[q] = f64::NAN;
                    tr[q] = C64::new(f64::NAN, f64::NAN);
                }
            }
        }
    }
    bad
}

/// Which rotor motion [`forced_response`] writes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RotorMotion {
    /// q, the rotor's motion in space
    Absolute,
    /// q - p, the rotor's motion relative to its pedestals (what pedestal-mounted probes read at
    /// the bearings), formed in the same pass as p: no second array for the caller to subtract
    Relative,
    /// T q - p with the plane transform T = [T11, T12, T21, T22] from the bearings to the probe
    /// planes ([`crate::model::planes_point`] on x and on y): what probes riding on the
    /// pedestals read at the probe planes (the pedestal motion is measured at the bearings), in
    /// the same pass, with the bits of moving q first and subtracting p after
    RelativeAtPlanes([f64; 4]),
}

/// Forced response of the rotor on bearings in flexible pedestals: for every point i and force
/// vector, the rotor motion at the bearings q (solved with the series impedance) and the
/// pedestal motion p = T q, both [x1, x2, y1, y2]; `motion` says whether `q_rotor` receives q or
/// q - p.
///
/// Arguments as [`forced::forced_response`]; `gain` scales each point's solution
/// ([`forced::Gain`]); `q_rotor`, `q_ped`: (n, nrhs, 4). Returns the number of singular points
/// (NaN output).
#[allow(clippy::too_many_arguments)]
pub fn forced_response(
    rotor: &Rotor,
    kb: &[f64],
    cb: &[f64],
    ped: &Pedestals,
    spin: &[f64],
    w: &[f64],
    force: &[C64],
    nrhs: usize,
    gain: forced::Gain,
    motion: RotorMotion,
    q_rotor: &mut [C64],
    q_ped: &mut [C64],
) -> Result<usize, CoreError> {
    let n = w.len();
    let total = product("q", &[n, nrhs, 4])?;
    expect_len("q_ped", q_ped, total)?;
    if let forced::Gain::PerPoint(g) = gain {
        expect_len("gain", g, n)?;
    }
    forced::check_forced(kb, cb, spin, w, force, nrhs, q_rotor)?;
    check_w(w)?;
    let args = ForcedArgs { rotor, kb, cb, ped, spin, w, force, nrhs, gain, motion };
    let size = FORCED_CHUNK * 4 * nrhs;
    let (qa, qp) = (crate::par::Disjoint::new(q_rotor), crate::par::Disjoint::new(q_ped));
    // SAFETY: sum_tasks hands each chunk index j to one task
    Ok(crate::par::sum_tasks(n.div_ceil(FORCED_CHUNK), |j| {
        forced_chunk_simd(&args, j * FORCED_CHUNK, unsafe { qa.chunk(j, size) }, unsafe { qp.chunk(j, size) })
    }))
}

/// Points per task of [`forced_response`]. A task forms its points' effective coefficients in
/// buffers of its own (256 KB), solves them and turns the solutions into pedestal motion while
/// they are in cache; the rigid forced response's tasks are as long, so the lane groups and their
/// bits are those of solving every point's effective coefficients at once.
const FORCED_CHUNK: usize = 1024;

/// The arguments of [`forced_response`], shared by its tasks.
struct ForcedArgs<'a> {
    rotor: &'a Rotor,
    kb: &'a [f64],
    cb: &'a [f64],
    ped: &'a Pedestals,
    spin: &'a [f64],
    w: &'a [f64],
    force: &'a [C64],
    nrhs: usize,
    gain: forced::Gain<'a>,
    motion: RotorMotion,
}

crate::lanes::simd_dispatch! {
    /// [`forced_chunk`] compiled for the widest instruction set of this CPU (the same operations
    /// at every level: the same bits).
    fn forced_chunk_simd(a: &ForcedArgs, first: usize, q_rotor: &mut [C64], q_ped: &mut [C64]) -> usize => forced_chunk
}

/// The points `first..` of [`forced_response`] whose outputs are `q_rotor`, `q_ped`: their
/// effective coefficients ([`effective_point`]), the rigid forced response on them
/// ([`forced::forced_kernel`], one thread at this size), then p = T q and the motion asked for.
/// Returns the number of singular points.
#[inline(always)]
fn forced_chunk(a: &ForcedArgs, first: usize, q_rotor: &mut [C64], q_ped: &mut [C64]) -> usize {
    let nrhs = a.nrhs;
    let np = q_rotor.len() / (4 * nrhs);
    let pts = first..first + np;
    let mut ke = vec![0.0; 8 * np];
    let mut ce = vec![0.0; 8 * np];
    let mut tr = vec![C64::new(0.0, 0.0); 8 * np];
    let (bk, bc) = (a.kb.len() == 8, a.cb.len() == 8);
    for i in 0..np {
        let (ok, oc) = (if bk { 0 } else { 8 * (first + i) }, if bc { 0 } else { 8 * (first + i) });
        let o = 8 * i..8 * i + 8;
        effective_point(&a.kb[ok..ok + 8], &a.cb[oc..oc + 8], a.ped, a.w[first + i], &mut ke[o.clone()], &mut ce[o.clone()], &mut tr[o]);
    }
    let force = if a.force.len() == 4 * nrhs { a.force } else { &a.force[4 * nrhs * pts.start..4 * nrhs * pts.end] };
    let gain = match a.gain {
        forced::Gain::PerPoint(g) => forced::Gain::PerPoint(&g[pts.clone()]),
        other => other,
    };
    let nsing = forced::forced_kernel(a.rotor, &ke, &ce, &a.spin[pts.clone()], &a.w[pts], force, nrhs, gain, None, q_rotor);
    for (i, (po, qa)) in q_ped.chunks_mut(4 * nrhs).zip(q_rotor.chunks_mut(4 * nrhs)).enumerate() {
        let t = &tr[8 * i..8 * i + 8];
        for r in 0..nrhs {
            let q = &mut qa[4 * r..4 * r + 4];
            let mut p = [C64::new(0.0, 0.0); 4];
            for b in 0..2 {
                let (x, y) = (q[b], q[2 + b]);
                p[b] = t[4 * b] * x + t[4 * b + 1] * y;
                p[2 + b] = t[4 * b + 2] * x + t[4 * b + 3] * y;
            }
            po[4 * r..4 * r + 4].copy_from_slice(&p);
            let seen = match a.motion {
                RotorMotion::Absolute => continue,
                RotorMotion::Relative => [q[0], q[1], q[2], q[3]],
                RotorMotion::RelativeAtPlanes(tp) => crate::model::planes_point(&tp, [q[0], q[1], q[2], q[3]]),
            };
            for d in 0..4 {
                q[d] = seen[d] - p[d];
            }
        }
    }
    nsing
}

/// Number of degrees of freedom of the coupled system: [x1, x2, y1, y2, xp1, xp2, yp1, yp2].
pub const DOF: usize = 8;
const NS: usize = 2 * DOF;

/// Mass, stiffness and damping (+ Omega G) matrices of the coupled system, rows = equations.
fn coupled_matrices(rotor: &Rotor, kb: &[f64], cb: &[f64], ped: &Pedestals, spin: f64) -> [[[f64; DOF]; DOF]; 3] {
    let m = rotor.mass_matrix();
    let g = rotor.gyro_matrix();
    let ak = assemble(kb, rotor.l1, rotor.l2);
    let ac = assemble(cb, rotor.l1, rotor.l2);
    let mut mm = [[0.0; DOF]; DOF];
    let mut kk = [[0.0; DOF]; DOF];
    let mut cc = [[0.0; DOF]; DOF];
    for r in 0..4 {
        for s in 0..4 {
            mm[r][s] = m[r][s];
            kk[r][s] = ak[r][s];
            kk[r][4 + s] = -ak[r][s];
            cc[r][s] = ac[r][s] + spin * g[r][s];
            cc[r][4 + s] = -ac[r][s];
        }
    }
    // pedestal rows in the order [xp1, xp2, yp1, yp2]: row of (bearing b, direction i) is
    // 4 + 2 i + b, column of (b, j) is 2 j + b (relative: rotor column, minus pedestal column)
    for b in 0..2 {
        for i in 0..2 {
            let row = 4 + 2 * i + b;
            mm[row][row] = ped.m[2 * b + i];
            for j in 0..2 {
                let o = 4 * b + 2 * i + j;
                let col = 2 * j + b;
                kk[row][col] -= kb[o];
                kk[row][4 + col] += kb[o] + ped.k[o];
                cc[row][col] -= cb[o];
                cc[row][4 + col] += cb[o] + ped.c[o];
            }
        }
    }
    [mm, kk, cc]
}

/// Solve an N x N complex system in place by LU with partial pivoting; false on a zero pivot.
/// Inlined into its callers, which run at the CPU's SIMD level ([`modal_points_simd`]): out of
/// line it was compiled for the build's baseline.
#[inline(always)]
fn solve_n<const N: usize>(a: &mut [[C64; N]; N], b: &mut [C64; N]) -> bool {
    for k in 0..N {
        // the first row of largest |a_ik|, each modulus taken once (a libm `hypot`: taken twice
        // per comparison they were a quarter of the pedestal modal analysis' instructions)
        let (mut p, mut top) = (k, a[k][k].norm());
        for i in k + 1..N {
            let m = a[i][k].norm();
            if m > top {
                (p, top) = (i, m);
            }
        }
        if top == 0.0 {
            return false;
        }
        a.swap(p, k);
        b.swap(p, k);
        let inv = 1.0 / a[k][k];
        for i in k + 1..N {
            let f = a[i][k] * inv;
            for j in k + 1..N {
                let t = a[k][j];
                a[i][j] -= f * t;
            }
            let t = b[k];
            b[i] -= f * t;
        }
    }
    for k in (0..N).rev() {
        let mut s = b[k];
        for j in k + 1..N {
            s -= a[k][j] * b[j];
        }
        b[k] = s / a[k][k];
    }
    true
}

/// Mode shape of eigenvalue `lam` by two steps of inverse iteration on
/// D(s) = s^2 M + s C + K shifted by a relative 1e-12 (1e-10, 1e-8 if that is singular to
/// working precision), projected against `avoid` (shapes of an equal eigenvalue).
#[inline(always)]
fn mode_shape(mats: &[[[f64; DOF]; DOF]; 3], lam: C64, seed: usize, avoid: &[[C64; DOF]]) -> Option<[C64; DOF]> {
    let [mm, kk, cc] = mats;
    'shift: for shift in [1e-12, 1e-10, 1e-8] {
        let s = lam * (1.0 + shift);
        let mut d0 = [[C64::new(0.0, 0.0); DOF]; DOF];
        for r in 0..DOF {
            for c in 0..DOF {
                d0[r][c] = s * s * mm[r][c] + s * cc[r][c] + kk[r][c];
            }
        }
        // a generic start vector (no rotor structure is orthogonal to it)
        let mut v: [C64; DOF] = std::array::from_fn(|d| {
            let t = (d as f64 + 1.0) * (0.61 + 0.17 * seed as f64);
            C64::new(t.cos(), (1.3 * t).sin())
        });
        for _ in 0..2 {
            for u in avoid {
                let dot: C64 = (0..DOF).map(|d| u[d].conj() * v[d]).sum();
                for d in 0..DOF {
                    v[d] -= dot * u[d];
                }
            }
            let mut a = d0;
            if !solve_n(&mut a, &mut v) {
                continue 'shift;
            }
            let nrm = v.iter().map(|z| z.norm_sqr()).sum::<f64>().sqrt();
            if !(nrm > 0.0 && nrm.is_finite()) {
                continue 'shift;
            }
            for z in v.iter_mut() {
                *z /= nrm;
            }
        }
        return Some(v);
    }
    None
}

/// Modal analysis of the coupled rotor-pedestal system at each spin speed: eigenvalues with
/// positive imaginary part (up to 8, by damped natural frequency, NaN-padded) and their shapes
/// over [x1, x2, y1, y2, xp1, xp2, yp1, yp2] (absolute motions), normalized to a unit largest
/// component. Pedestal masses must be > 0. `kb`, `cb`: (n, 8); `lam`: (n, 8); `shapes`: (n, 8, 8).
/// Returns the number of points where the eigen-solver failed (NaN output).
pub fn modal(rotor: &Rotor, kb: &[f64], cb: &[f64], ped: &Pedestals, spin: &[f64], lam: &mut [C64], shapes: &mut [C64]) -> Result<usize, CoreError> {
    let n = spin.len();
    expect_len("k", kb, product("k", &[n, 8])?)?;
    expect_len("c", cb, n * 8)?;
    expect_len("lam", lam, product("lam", &[n, DOF])?)?;
    expect_len("shapes", shapes, product("shapes", &[n, DOF * DOF])?)?;
    if ped.m.iter().any(|&m| !(m > 0.0)) {
        return Err(CoreError::value("pedestals", "masses must be > 0 for a modal analysis (a massless pedestal has no mode)"));
    }
    // two points per task: their eigenvalue iterations interleave (eig8::eigenvalues_pair)
    Ok(lam
        .par_chunks_mut(2 * DOF)
        .zip(shapes.par_chunks_mut(2 * DOF * DOF))
        .enumerate()
        .map(|(i, (lo, so))| {
            let pts = 2 * i..2 * i + lo.len() / DOF;
            modal_points_simd(rotor, &kb[8 * pts.start..8 * pts.end], &cb[8 * pts.start..8 * pts.end], ped, &spin[pts], lo, so)
        })
        .sum())
}

crate::lanes::simd_dispatch! {
    /// [`modal_points`] compiled for the widest instruction set of this CPU (no fused operations:
    /// the same bits at every level).
    fn modal_points_simd(rotor: &Rotor, kb: &[f64], cb: &[f64], ped: &Pedestals, spin: &[f64], lo: &mut [C64], so: &mut [C64]) -> usize => modal_points
}

/// Eigenvalues and mode shapes of one or two points of [`modal`] (`kb`, `cb`: 8 coefficients per
/// point; `lo`: `DOF` eigenvalues per point, `so`: `DOF` x `DOF` shapes per point); the number of
/// points that failed (all NaN).
#[inline(always)]
fn modal_points(rotor: &Rotor, kb: &[f64], cb: &[f64], ped: &Pedestals, spin: &[f64], lo: &mut [C64], so: &mut [C64]) -> usize {
    let nan = C64::new(f64::NAN, f64::NAN);
    for v in lo.iter_mut().chain(so.iter_mut()) {
        *v = nan;
    }
    let np = spin.len();
    let mut mats = [[[[0.0; DOF]; DOF]; 3]; 2];
    let mut a = [[[0.0; NS]; NS]; 2];
    let mut ok = [false; 2];
    for p in 0..np {
        mats[p] = coupled_matrices(rotor, &kb[8 * p..8 * p + 8], &cb[8 * p..8 * p + 8], ped, spin[p]);
        ok[p] = state_matrix(&mats[p], &mut a[p]);
    }
    let s = if np == 2 && ok[0] && ok[1] {
        let (s0, s1) = eig8::eigenvalues_pair(&a[0], &a[1]);
        [s0, s1]
    } else {
        [if ok[0] { eig8::eigenvalues(&a[0]) } else { None }, if np == 2 && ok[1] { eig8::eigenvalues(&a[1]) } else { None }]
    };
    let (lo0, lo1) = lo.split_at_mut(DOF);
    let (so0, so1) = so.split_at_mut(DOF * DOF);
    let mut failed = modes(&mats[0], s[0], lo0, so0);
    if np == 2 {
        failed += modes(&mats[1], s[1], lo1, so1);
    }
    failed
}

/// The balanced 16 x 16 state matrix A = [[0, I], [-M^-1 K, -M^-1 C]] of `mats` into `a`; false
/// when M is singular to the LU's pivoting. M is the rotor's (invertible, l1 + l2 != 0) and a
/// positive diagonal for the pedestals.
#[inline(always)]
fn state_matrix(mats: &[[[f64; DOF]; DOF]; 3], a: &mut [[f64; NS]; NS]) -> bool {
    let [mm, kk, cc] = mats;
    let mut minv_k = [[C64::new(0.0, 0.0); DOF]; DOF];
    let mut minv_c = [[C64::new(0.0, 0.0); DOF]; DOF];
    for col in 0..DOF {
        let mut bk: [C64; DOF] = std::array::from_fn(|r| C64::new(kk[r][col], 0.0));
        let mut bc: [C64; DOF] = std::array::from_fn(|r| C64::new(cc[r][col], 0.0));
        let mut m1: [[C64; DOF]; DOF] = std::array::from_fn(|r| std::array::from_fn(|c| C64::new(mm[r][c], 0.0)));
        let mut m2 = m1;
        if !solve_n(&mut m1, &mut bk) || !solve_n(&mut m2, &mut bc) {
            return false;
        }
        for r in 0..DOF {
            minv_k[r][col] = bk[r];
            minv_c[r][col] = bc[r];
        }
    }
    for r in 0..DOF {
        a[r][DOF + r] = 1.0;
        for c in 0..DOF {
            a[DOF + r][c] = -minv_k[r][c].re;
            a[DOF + r][DOF + c] = -minv_c[r][c].re;
        }
    }
    crate::modal::balance_array(a);
    true
}

/// The modes of one point of [`modal`] from its eigenvalues `s` (None: the eigen-solver failed)
/// into `lo`, `so` ([`crate::modal::modes_of`] with D = 8, the shapes by [`mode_shape`]).
#[inline(always)]
fn modes(mats: &[[[f64; DOF]; DOF]; 3], s: Option<[C64; NS]>, lo: &mut [C64], so: &mut [C64]) -> usize {
    modes_of(s, lo, so, &PedestalShapes(mats))
}

/// The pedestal model's mode shapes for [`modes_of`] ([`mode_shape`]).
struct PedestalShapes<'a>(&'a [[[f64; DOF]; DOF]; 3]);

impl ModeShapes<DOF> for PedestalShapes<'_> {
    #[inline(always)]
    fn shape(&self, lam: C64, mi: usize, same: &[[C64; DOF]]) -> Option<[C64; DOF]> {
        mode_shape(self.0, lam, mi, same)
    }
}
