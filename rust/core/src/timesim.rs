//! Time stepping of a discretized linear time-invariant system (exact for piecewise-linear input):
//!     x[k+1] = Phi x[k] + G0 u[k] + G1 (u[k+1] - u[k]),
//! with Phi, G0, G1 from the matrix exponential of the augmented continuous system (Python side).

use crate::error::{expect_len, product, CoreError};

/// `phi`: (n, n), `g0`, `g1`: (n, m), `u`: (N, m), `x0`: (n) -> states (N, n), row-major.
#[allow(clippy::too_many_arguments)]
pub fn lti_run(n: usize, m: usize, phi: &[f64], g0: &[f64], g1: &[f64], u: &[f64], x0: &[f64], out: &mut [f64]) -> Result<(), CoreError> {
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
    let steps = u.len() / m;
    expect_len("out", out, product("out", &[steps, n])?)?;
    lti_kernel(n, m, phi, g0, g1, u, x0, out);
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn lti_kernel(n: usize, m: usize, phi: &[f64], g0: &[f64], g1: &[f64], u: &[f64], x0: &[f64], out: &mut [f64]) {
    let steps = u.len() / m;
    if steps == 0 {
        return;
    }
    out[..n].copy_from_slice(x0);
    let mut x = x0.to_vec();
    let mut nx = vec![0.0; n];
    for k in 0..steps - 1 {
        let uk = &u[k * m..(k + 1) * m];
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
        out[(k + 1) * n..(k + 2) * n].copy_from_slice(&x);
    }
}
