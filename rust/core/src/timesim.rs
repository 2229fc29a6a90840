//! Time stepping of a discretized linear time-invariant system (exact for piecewise-linear input):
//!     x[k+1] = Phi x[k] + G0 u[k] + G1 (u[k+1] - u[k]),
//! with Phi, G0, G1 from the matrix exponential of the augmented continuous system (Python side),
//! and optional output equations y_i[k] = C_i x[k] + D_i u[k] written instead of the states.

use crate::error::{expect_len, product, CoreError};

/// One output equation y[k] = C x[k] + D u[k]: `c` (p, n) and `d` (p, m), row-major, written to
/// `out` (N, p).
pub struct Output<'a> {
    pub p: usize,
    pub c: &'a [f64],
    pub d: &'a [f64],
    pub out: &'a mut [f64],
}

/// The sample times t_i = i dt of `out.len()` samples (`np.arange(n, dtype=float) * dt`, the same
/// bits), written in parallel chunks: the time axis of a time response, in memory the core's
/// allocator reuses from call to call (`np.arange` took ~2.4 ms per call for 2 million samples
/// inside `impact_time_response`, 1.3 ms alone; this 0.5 ms).
///
/// ```
/// let mut t = [0.0; 4];
/// rotorid_core::timesim::sample_times(0.25, &mut t);
/// assert_eq!(t, [0.0, 0.25, 0.5, 0.75]);
/// ```
pub fn sample_times(dt: f64, out: &mut [f64]) {
    const CHUNK: usize = 1 << 16;
    let n = out.len();
    let chunks = crate::par::Disjoint::new(out);
    crate::par::for_each_task(n.div_ceil(CHUNK), |j| {
        // SAFETY: for_each_task hands each chunk index j to one task
        for (t, o) in unsafe { chunks.chunk(j, CHUNK) }.iter_mut().enumerate() {
            *o = (j * CHUNK + t) as f64 * dt;
        }
    });
}

/// `phi`: (n, n), `g0`, `g1`: (n, m), `u`: (N, m), `x0`: (n) -> states (N, n), row-major.
/// Returns the first step whose state is not finite (None when all are).
#[allow(clippy::too_many_arguments)]
pub fn lti_run(n: usize, m: usize, phi: &[f64], g0: &[f64], g1: &[f64], u: &[f64], x0: &[f64], out: &mut [f64]) -> Result<Option<usize>, CoreError> {
    let steps = check(n, m, phi, g0, g1, u, x0)?;
    expect_len("out", out, product("out", &[steps, n])?)?;
    if m == 1 && (n == 8 || n == 16) {
        return Ok(if n == 8 { states_8(phi, g0, g1, u, x0, out) } else { states_16(phi, g0, g1, u, x0, out) });
    }
    Ok(lti_kernel(n, m, phi, g0, g1, u, x0, |k, x, _| out[k * n..(k + 1) * n].copy_from_slice(x)))
}

/// [`lti_run`] writing the outputs y_i = C_i x + D_i u of `outputs` at every step instead of the
/// states (the caller reads no (N, n) array of states to form them): e.g. a rotor's motion
/// relative to its pedestals, the pedestals' motion and their acceleration from a 16-state model.
/// Returns the first step whose state is not finite (None when all are).
#[allow(clippy::too_many_arguments)]
pub fn lti_outputs(
    n: usize,
    m: usize,
    phi: &[f64],
    g0: &[f64],
    g1: &[f64],
    u: &[f64],
    x0: &[f64],
    outputs: &mut [Output],
) -> Result<Option<usize>, CoreError> {
    let steps = check(n, m, phi, g0, g1, u, x0)?;
    for o in outputs.iter() {
        expect_len("c (output)", o.c, product("c", &[o.p, n])?)?;
        expect_len("d (output)", o.d, product("d", &[o.p, m])?)?;
        expect_len("out (output)", o.out, product("out", &[steps, o.p])?)?;
    }
    let rows: usize = outputs.iter().map(|o| o.p).sum();
    if m == 1 && (n == 8 || n == 16) && rows <= n {
        // all outputs stacked into one (n, n) matrix (rows beyond theirs zero), stored by columns
        let mut c_cols = vec![0.0; n * n];
        let mut d_all = vec![0.0; n];
        let mut r0 = 0;
        for o in outputs.iter() {
            for i in 0..o.p {
                for j in 0..n {
                    c_cols[j * n + r0 + i] = o.c[i * n + j];
                }
                d_all[r0 + i] = o.d[i];
            }
            r0 += o.p;
        }
        let mut emit = |k: usize, y: &[f64]| {
            let mut r0 = 0;
            for o in outputs.iter_mut() {
                o.out[k * o.p..(k + 1) * o.p].copy_from_slice(&y[r0..r0 + o.p]);
                r0 += o.p;
            }
        };
        return Ok(if n == 8 {
            outputs_8(phi, g0, g1, u, x0, &c_cols, &d_all, &mut emit)
        } else {
            outputs_16(phi, g0, g1, u, x0, &c_cols, &d_all, &mut emit)
        });
    }
    Ok(lti_kernel(n, m, phi, g0, g1, u, x0, |k, x, uk| {
        for o in outputs.iter_mut() {
            for i in 0..o.p {
                let mut s = 0.0;
                for (cij, xj) in o.c[i * n..(i + 1) * n].iter().zip(x) {
                    s += cij * xj;
                }
                for (dij, uj) in o.d[i * m..(i + 1) * m].iter().zip(uk) {
                    s += dij * uj;
                }
                o.out[k * o.p + i] = s;
            }
        }
    }))
}

/// The argument checks shared by both entry points; returns the number of steps.
fn check(n: usize, m: usize, phi: &[f64], g0: &[f64], g1: &[f64], u: &[f64], x0: &[f64]) -> Result<usize, CoreError> {
    if m == 0 {
        return Err(CoreError::value("m", "(number of inputs) must be at least 1"));
    }
    expect_len("phi", phi, product("phi", &[n, n])?)?;
    expect_len("g0", g0, product("g0", &[n, m])?)?;
    expect_len("g1", g1, n * m)?;
    expect_len("x0", x0, n)?;
    if u.len() % m != 0 {
        return Err(CoreError::length("u", u.len(), format!("a multiple of m = {m}")));
    }
    Ok(u.len() / m)
}

/// Step the recursion, handing `emit(k, x[k], u[k])` every state; returns the first step whose
/// state is not finite.
#[allow(clippy::too_many_arguments)]
fn lti_kernel(n: usize, m: usize, phi: &[f64], g0: &[f64], g1: &[f64], u: &[f64], x0: &[f64], mut emit: impl FnMut(usize, &[f64], &[f64])) -> Option<usize> {
    let steps = u.len() / m;
    let mut first_bad = None;
    let mut x = x0.to_vec();
    let mut nx = vec![0.0; n];
    for k in 0..steps {
        let uk = &u[k * m..(k + 1) * m];
        emit(k, &x, uk);
        if first_bad.is_none() && !x.iter().all(|v| v.is_finite()) {
            first_bad = Some(k);
        }
        if k + 1 == steps {
            break;
        }
        let uk1 = &u[(k + 1) * m..(k + 2) * m];
        for i in 0..n {
            let row = &phi[i * n..(i + 1) * n];
            let mut s = 0.0;
            for j in 0..n {
                s += row[j] * x[j];
            }
            for j in 0..m {
                s += g0[i * m + j] * uk[j] + g1[i * m + j] * (uk1[j] - uk[j]);
            }
            nx[i] = s;
        }
        std::mem::swap(&mut x, &mut nx);
    }
    first_bad
}

// ---------------------------------------------------------------------------------------------
// Fixed sizes: the rotor's 8 states (16 with pedestals) and one input (the impact force). The
// products run column by column over all rows at once, so they vectorize; each row is still
// summed in the order of `lti_kernel` (over j, then the input terms), so both give the same bits.

/// `phi` (N, N) row-major -> its columns.
#[inline(always)]
fn columns<const N: usize>(phi: &[f64]) -> [[f64; N]; N] {
    let mut t = [[0.0; N]; N];
    for i in 0..N {
        for j in 0..N {
            t[j][i] = phi[i * N + j];
        }
    }
    t
}

/// Step x[k+1] = Phi x[k] + g0 u[k] + g1 (u[k+1] - u[k]) for N states and one input, handing
/// `emit(k, x[k], u[k])` every state; returns the first step whose state is not finite.
#[inline(always)]
fn fixed_kernel<const N: usize>(phi: &[f64], g0: &[f64], g1: &[f64], u: &[f64], x0: &[f64], mut emit: impl FnMut(usize, &[f64; N], f64)) -> Option<usize> {
    let cols = columns::<N>(phi);
    let (g0, g1): ([f64; N], [f64; N]) = (g0.try_into().unwrap(), g1.try_into().unwrap());
    let mut x: [f64; N] = x0.try_into().unwrap();
    let mut first_bad = None;
    for k in 0..u.len() {
        let uk = u[k];
        emit(k, &x, uk);
        if first_bad.is_none() && !x.iter().all(|v| v.is_finite()) {
            first_bad = Some(k);
        }
        if k + 1 == u.len() {
            break;
        }
        let du = u[k + 1] - uk;
        let mut nx = [0.0; N];
        for j in 0..N {
            let xj = x[j];
            for i in 0..N {
                nx[i] += cols[j][i] * xj;
            }
        }
        for i in 0..N {
            nx[i] += g0[i] * uk + g1[i] * du;
        }
        x = nx;
    }
    first_bad
}

#[inline(always)]
fn states_fixed<const N: usize>(phi: &[f64], g0: &[f64], g1: &[f64], u: &[f64], x0: &[f64], out: &mut [f64]) -> Option<usize> {
    fixed_kernel::<N>(phi, g0, g1, u, x0, |k, x, _| out[k * N..(k + 1) * N].copy_from_slice(x))
}

/// The stacked outputs y = C x + d u of every step, up to N rows (`c_cols`: the columns of C, N
/// values each, rows beyond the outputs' zero; `d`: N values).
#[inline(always)]
fn outputs_fixed<const N: usize>(phi: &[f64], g0: &[f64], g1: &[f64], u: &[f64], x0: &[f64], c_cols: &[f64], d: &[f64], emit: &mut dyn FnMut(usize, &[f64])) -> Option<usize> {
    let mut cc = [[0.0; N]; N];
    for j in 0..N {
        cc[j].copy_from_slice(&c_cols[j * N..(j + 1) * N]);
    }
    let d: [f64; N] = d.try_into().unwrap();
    fixed_kernel::<N>(phi, g0, g1, u, x0, |k, x, uk| {
        let mut y = [0.0; N];
        for j in 0..N {
            let xj = x[j];
            for i in 0..N {
                y[i] += cc[j][i] * xj;
            }
        }
        for i in 0..N {
            y[i] += d[i] * uk;
        }
        emit(k, &y);
    })
}

fn states_8_k(phi: &[f64], g0: &[f64], g1: &[f64], u: &[f64], x0: &[f64], out: &mut [f64]) -> Option<usize> {
    states_fixed::<8>(phi, g0, g1, u, x0, out)
}

fn states_16_k(phi: &[f64], g0: &[f64], g1: &[f64], u: &[f64], x0: &[f64], out: &mut [f64]) -> Option<usize> {
    states_fixed::<16>(phi, g0, g1, u, x0, out)
}

#[allow(clippy::too_many_arguments)]
fn outputs_8_k(phi: &[f64], g0: &[f64], g1: &[f64], u: &[f64], x0: &[f64], c_cols: &[f64], d: &[f64], emit: &mut dyn FnMut(usize, &[f64])) -> Option<usize> {
    outputs_fixed::<8>(phi, g0, g1, u, x0, c_cols, d, emit)
}

#[allow(clippy::too_many_arguments)]
fn outputs_16_k(phi: &[f64], g0: &[f64], g1: &[f64], u: &[f64], x0: &[f64], c_cols: &[f64], d: &[f64], emit: &mut dyn FnMut(usize, &[f64])) -> Option<usize> {
    outputs_fixed::<16>(phi, g0, g1, u, x0, c_cols, d, emit)
}

crate::lanes::simd_dispatch! {
    /// The 8-state recursion at the widest SIMD level of this CPU.
    fn states_8(phi: &[f64], g0: &[f64], g1: &[f64], u: &[f64], x0: &[f64], out: &mut [f64]) -> Option<usize> => states_8_k
}

crate::lanes::simd_dispatch! {
    /// The 16-state recursion at the widest SIMD level of this CPU.
    fn states_16(phi: &[f64], g0: &[f64], g1: &[f64], u: &[f64], x0: &[f64], out: &mut [f64]) -> Option<usize> => states_16_k
}

crate::lanes::simd_dispatch! {
    /// 8 states, stacked outputs, at the widest SIMD level of this CPU.
    #[allow(clippy::too_many_arguments)]
    fn outputs_8(phi: &[f64], g0: &[f64], g1: &[f64], u: &[f64], x0: &[f64], c_cols: &[f64], d: &[f64], emit: &mut dyn FnMut(usize, &[f64])) -> Option<usize> => outputs_8_k
}

crate::lanes::simd_dispatch! {
    /// 16 states, stacked outputs, at the widest SIMD level of this CPU.
    #[allow(clippy::too_many_arguments)]
    fn outputs_16(phi: &[f64], g0: &[f64], g1: &[f64], u: &[f64], x0: &[f64], c_cols: &[f64], d: &[f64], emit: &mut dyn FnMut(usize, &[f64])) -> Option<usize> => outputs_16_k
}
