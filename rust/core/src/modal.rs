//! Batched eigen-analysis of the rotor-bearing system (state-space form of eq. 1 without forcing).

use crate::error::{expect_len, product, CoreError};
use crate::forced::Lu4;
use crate::model::{assemble, Rotor, C64};
use nalgebra::{Matrix4, SMatrix, Schur};
use rayon::prelude::*;

/// The 8 x 8 state matrix of one point, A = [[0, I], [-M^-1 K, -M^-1 (C + Omega G)]].
pub type StateMatrix = SMatrix<f64, 8, 8>;

/// State matrix of eq. 1 without forcing, x = [q, q'], x' = A x. `minv` is M^-1.
#[inline(always)]
pub fn state_matrix(minv: &Matrix4<f64>, k: &[[f64; 4]; 4], c: &[[f64; 4]; 4], g: &[[f64; 4]; 4], spin: f64) -> StateMatrix {
    let mut a = StateMatrix::zeros();
    for r in 0..4 {
        a[(r, 4 + r)] = 1.0;
        for col in 0..4 {
            let mut sk = 0.0;
            let mut sc = 0.0;
            for t in 0..4 {
                sk += minv[(r, t)] * k[t][col];
                sc += minv[(r, t)] * (c[t][col] + spin * g[t][col]);
            }
            a[(4 + r, col)] = -sk;
            a[(4 + r, 4 + col)] = -sc;
        }
    }
    a
}

/// Balance a state matrix in place by a diagonal similarity D^-1 A D with powers of two (see
/// [`balance_array`]). Returns D.
#[inline(always)]
pub fn balance(a: &mut StateMatrix) -> [f64; 8] {
    let mut rows: [[f64; 8]; 8] = std::array::from_fn(|r| std::array::from_fn(|c| a[(r, c)]));
    let d = balance_array(&mut rows);
    for r in 0..8 {
        for c in 0..8 {
            a[(r, c)] = rows[r][c];
        }
    }
    d
}

/// Balance a square matrix (row-major) in place by a diagonal similarity D^-1 A D with powers of
/// two (the scaling loop of LAPACK's dgebal, without permutations). Returns D.
#[inline(always)]
pub fn balance_array<const N: usize>(a: &mut [[f64; N]; N]) -> [f64; N] {
    let mut d = [1.0; N];
    let radix = 2.0f64;
    for _ in 0..100 {
        let mut done = true;
        for i in 0..N {
            let (mut c, mut r) = (0.0, 0.0);
            for j in 0..N {
                if j != i {
                    c += a[j][i].abs();
                    r += a[i][j].abs();
                }
            }
            if c == 0.0 || r == 0.0 {
                continue;
            }
            let s = c + r;
            let mut f = 1.0;
            let (mut cc, mut rr) = (c, r);
            while cc < rr / radix {
                cc *= radix;
                rr /= radix;
                f *= radix;
            }
            while cc >= rr * radix {
                cc /= radix;
                rr *= radix;
                f /= radix;
            }
            if (cc + rr) < 0.95 * s {
                done = false;
                d[i] *= f;
                for j in 0..N {
                    a[i][j] /= f;
                    a[j][i] *= f;
                }
            }
        }
        if done {
            break;
        }
    }
    d
}

/// Eigenvalues of a state matrix: Householder reduction to Hessenberg form and Francis
/// double-shift QR without accumulating transformations ([`crate::eig8`], on the stack; ~1.6x
/// faster than nalgebra's real Schur decomposition, which also forms the orthogonal factor, see
/// benches/small_algebra.rs), with nalgebra's Schur as the fallback when that QR iteration does
/// not converge within its budget. None if neither converges.
#[inline(always)]
pub fn eigenvalues(a: StateMatrix) -> Option<[C64; 8]> {
    crate::eig8::eigenvalues(&rows_of(&a)).or_else(|| schur_eigenvalues(a))
}

/// [`eigenvalues`] of two state matrices, their QR iterations interleaved
/// ([`crate::eig8::eigenvalues_pair`]; the same results as one by one).
#[inline(always)]
pub fn eigenvalues_pair(a: StateMatrix, b: StateMatrix) -> (Option<[C64; 8]>, Option<[C64; 8]>) {
    let (ea, eb) = crate::eig8::eigenvalues_pair(&rows_of(&a), &rows_of(&b));
    (ea.or_else(|| schur_eigenvalues(a)), eb.or_else(|| schur_eigenvalues(b)))
}

#[inline(always)]
fn rows_of(a: &StateMatrix) -> [[f64; 8]; 8] {
    std::array::from_fn(|r| std::array::from_fn(|c| a[(r, c)]))
}

/// The fallback of [`eigenvalues`]: nalgebra's real Schur decomposition.
#[cold]
fn schur_eigenvalues(a: StateMatrix) -> Option<[C64; 8]> {
    let schur = Schur::try_new(a, f64::EPSILON, 10_000)?;
    let ev = schur.complex_eigenvalues();
    let mut out = [C64::new(0.0, 0.0); 8];
    for (o, e) in out.iter_mut().zip(ev.iter()) {
        *o = C64::new(e.re, e.im);
    }
    Some(out)
}

/// Generic start vectors of the inverse iteration (no structure a rotor's mode shape could be
/// orthogonal to).
const START: [[C64; 4]; 2] = [
    [C64::new(1.0, 0.0), C64::new(0.71, 0.23), C64::new(0.37, -0.61), C64::new(-0.53, 0.47)],
    [C64::new(-0.29, 0.83), C64::new(0.61, -0.37), C64::new(1.0, 0.0), C64::new(0.19, 0.67)],
];

/// |z| as sqrt(re² + im²) where the square neither overflows nor underflows (every eigenvalue of
/// a physical rotor), else libm's `hypot`. Within 2 ulp of `hypot` (its 40 calls were ~5 % of a
/// speed's modal analysis); only compared with tolerances of 1e-9 relative here.
#[inline]
pub(crate) fn modulus(z: C64) -> f64 {
    let sq = z.norm_sqr();
    if sq > 1e-290 && sq < 1e290 {
        sq.sqrt()
    } else {
        z.norm()
    }
}

/// Whether eigenvalue `s` is a mode's (positive imaginary part, beyond rounding of |s|).
#[inline]
pub(crate) fn is_mode(s: C64) -> bool {
    s.im > 1e-9 * modulus(s).max(1e-300)
}

/// Whether eigenvalues `a` and `b` are the same to rounding (1e-9 of |b|): their shapes are kept
/// independent.
#[inline]
pub(crate) fn same_eigenvalue(a: C64, b: C64) -> bool {
    modulus(a - b) <= 1e-9 * modulus(b)
}

/// The component a mode shape of unit 2-norm is scaled by: the largest, by squared moduli (they
/// neither overflow nor lose the largest), the first of those within 1e-12 of it, so that
/// components equal in exact arithmetic (an isotropic rotor's x and y) do not take turns with
/// rounding.
pub(crate) fn pivot(v: &[C64]) -> usize {
    let top = v.iter().fold(0.0f64, |m, z| m.max(z.norm_sqr()));
    v.iter().position(|z| z.norm_sqr() >= top * (1.0 - 1e-12)).unwrap_or(0)
}

/// `out` = the mode shape `v` (unit 2-norm) divided by its [`pivot`] component (1 there), `v`
/// as it is when it is zero.
pub(crate) fn scale_to_pivot(v: &[C64], out: &mut [C64]) {
    let piv = v[pivot(v)];
    let scale = if piv.norm_sqr() > 0.0 { 1.0 / piv } else { C64::new(1.0, 0.0) };
    for (o, z) in out.iter_mut().zip(v) {
        *o = z * scale;
    }
}

/// Mode shape of eigenvalue `lam` by inverse iteration on D(s) = s^2 M + s (C + Omega G) + K with a
/// small relative shift (singular to rounding on purpose: each step multiplies the wanted
/// direction by ~1/shift against the others), starting from `v`; `avoid`: shapes of eigenvalues
/// equal to this one, projected out so that a repeated eigenvalue gets independent shapes.
/// The shift starts at 1e-12 and grows (1e-10, 1e-8) while the shifted matrix is singular to
/// working precision (a pivot below 1e-15 of its largest entry: seen for heavily damped modes,
/// where the mass and stiffness terms cancel). None if no shift gives two steps.
#[inline(always)]
fn mode_shape(m: &[[f64; 4]; 4], cg: &[[f64; 4]; 4], k: &[[f64; 4]; 4], lam: C64, start: [C64; 4], avoid: &[[C64; 4]]) -> Option<[C64; 4]> {
    'shift: for shift in [1e-12, 1e-10, 1e-8] {
        let lam_s = lam * (1.0 + shift);
        let mut dm0 = [[C64::new(0.0, 0.0); 4]; 4];
        for r in 0..4 {
            for col in 0..4 {
                dm0[r][col] = lam_s * lam_s * m[r][col] + lam_s * cg[r][col] + k[r][col];
            }
        }
        // factored once for both steps (each step factored it anew before: the same factors)
        let Some(lu) = Lu4::near_singular(&mut dm0) else {
            continue 'shift;
        };
        let mut v = start;
        // two steps: the first leaves the other directions at ~shift relative, the second at
        // ~shift^2 (the projection against `avoid` is repeated before each)
        for _ in 0..2 {
            for u in avoid {
                // u has unit 2-norm
                let dot: C64 = (0..4).map(|d| u[d].conj() * v[d]).sum();
                for d in 0..4 {
                    v[d] -= dot * u[d];
                }
            }
            let mut y = v;
            lu.solve(&mut y);
            let nrm = y.iter().map(|z| z.norm_sqr()).sum::<f64>().sqrt();
            if !(nrm > 0.0 && nrm.is_finite()) {
                continue 'shift;
            }
            for d in 0..4 {
                v[d] = y[d] / nrm;
            }
        }
        return Some(v);
    }
    None
}

/// For each point: eigenvalues with positive imaginary part (up to 4, sorted by damped natural
/// frequency, NaN-padded when a mode is overdamped) and the displacement part of their
/// eigenvectors (order [x1, x2, y1, y2], normalized to unit largest component, real at that
/// component). `lam`: (n, 4); `shapes`: (n, 4 modes, 4 dofs). Returns the number of points where
/// the eigen-solver failed (NaN output).
pub fn modal(rotor: &Rotor, kb: &[f64], cb: &[f64], spin: &[f64], lam: &mut [C64], shapes: &mut [C64]) -> Result<usize, CoreError> {
    let n = spin.len();
    expect_len("k", kb, product("k", &[n, 8])?)?;
    expect_len("c", cb, n * 8)?;
    expect_len("lam", lam, product("lam", &[n, 4])?)?;
    expect_len("shapes", shapes, product("shapes", &[n, 16])?)?;
    Ok(modal_kernel(rotor, kb, cb, spin, lam, shapes))
}

fn modal_kernel(rotor: &Rotor, kb: &[f64], cb: &[f64], spin: &[f64], lam: &mut [C64], shapes: &mut [C64]) -> usize {
    let m = rotor.mass_matrix();
    let g = rotor.gyro_matrix();
    let minv = match Matrix4::from_fn(|r, c| m[r][c]).try_inverse() {
        Some(v) => v,
        None => {
            for v in lam.iter_mut().chain(shapes.iter_mut()) {
                *v = C64::new(f64::NAN, f64::NAN);
            }
            return spin.len();
        }
    };
    // two points per task: their eigenvalue iterations interleave (eigenvalues_pair)
    lam.par_chunks_mut(8)
        .zip(shapes.par_chunks_mut(32))
        .with_min_len(8)
        .enumerate()
        .map(|(i, (lo, so))| {
            let np = lo.len() / 4;
            let pts = 2 * i..2 * i + np;
            modal_points_simd(rotor, &minv, &m, &g, &kb[8 * pts.start..8 * pts.end], &cb[8 * pts.start..8 * pts.end], &spin[pts], lo, so)
        })
        .sum()
}

crate::lanes::simd_dispatch! {
    /// [`modal_points`] compiled for the widest instruction set of this CPU (the same operations
    /// in the same order at every level, so the same bits; three-operand encodings cut the
    /// instructions by 14 %).
    #[allow(clippy::too_many_arguments)]
    fn modal_points_simd(rotor: &Rotor, minv: &Matrix4<f64>, m: &[[f64; 4]; 4], g: &[[f64; 4]; 4], kb: &[f64], cb: &[f64], spin: &[f64], lo: &mut [C64], so: &mut [C64]) -> usize => modal_points
}

/// Eigenvalues and mode shapes of one or two points (`kb`, `cb`: their 8 bearing coefficients
/// each; `lo`: their 4 eigenvalues each, `so`: their 4 x 4 shapes each); the number of points
/// where the eigen-solver failed (all NaN).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn modal_points(rotor: &Rotor, minv: &Matrix4<f64>, m: &[[f64; 4]; 4], g: &[[f64; 4]; 4], kb: &[f64], cb: &[f64], spin: &[f64], lo: &mut [C64], so: &mut [C64]) -> usize {
    if spin.len() == 2 {
        let ((k0, c0, a0), (k1, c1, a1)) = (point(rotor, minv, g, kb, cb, spin, 0), point(rotor, minv, g, kb, cb, spin, 1));
        let (s0, s1) = eigenvalues_pair(a0, a1);
        let (lo0, lo1) = lo.split_at_mut(4);
        let (so0, so1) = so.split_at_mut(16);
        modes(m, g, &k0, &c0, spin[0], s0, lo0, so0) + modes(m, g, &k1, &c1, spin[1], s1, lo1, so1)
    } else {
        let (k, c, a) = point(rotor, minv, g, kb, cb, spin, 0);
        modes(m, g, &k, &c, spin[0], eigenvalues(a), lo, so)
    }
}

/// Point `p` of [`modal_points`]: its stiffness and damping matrices and its balanced state matrix.
/// A function, not a closure: a closure LLVM leaves out of line is compiled without the CPU's
/// features (this one was: 6 % of the instructions, `examples/modal_points`; see [`ModeShapes`]).
#[inline(always)]
fn point(rotor: &Rotor, minv: &Matrix4<f64>, g: &[[f64; 4]; 4], kb: &[f64], cb: &[f64], spin: &[f64], p: usize) -> ([[f64; 4]; 4], [[f64; 4]; 4], StateMatrix) {
    let k = assemble(&kb[8 * p..8 * p + 8], rotor.l1, rotor.l2);
    let c = assemble(&cb[8 * p..8 * p + 8], rotor.l1, rotor.l2);
    let mut a = state_matrix(minv, &k, &c, g, spin[p]);
    // balance (LAPACK-style diagonal similarity with powers of 2): the state matrix of a
    // stiff, heavily damped rotor spans many decades, and unbalanced eigenvalues came
    // out ~3e-7 relative off (checked against 40-digit mpmath)
    balance(&mut a);
    (k, c, a)
}

/// The modes of one point of the rigid rotor from its eigenvalues `s` (None: the eigen-solver
/// failed) into `lo`, `so` ([`modes_of`] with D = 4, the shapes by [`mode_shape`] on C + Omega G).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn modes(m: &[[f64; 4]; 4], g: &[[f64; 4]; 4], k: &[[f64; 4]; 4], c: &[[f64; 4]; 4], spin: f64, s: Option<[C64; 8]>, lo: &mut [C64], so: &mut [C64]) -> usize {
    let mut cg = *c;
    for r in 0..4 {
        for col in 0..4 {
            cg[r][col] += spin * g[r][col];
        }
    }
    modes_of(s, lo, so, &RigidShapes { m, cg: &cg, k })
}

/// The rigid rotor's mode shapes for [`modes_of`]: [`mode_shape`] with C + Omega G, from
/// [`START`]'s two vectors in turn.
struct RigidShapes<'a> {
    m: &'a [[f64; 4]; 4],
    cg: &'a [[f64; 4]; 4],
    k: &'a [[f64; 4]; 4],
}

impl ModeShapes<4> for RigidShapes<'_> {
    #[inline(always)]
    fn shape(&self, lam: C64, mi: usize, same: &[[C64; 4]]) -> Option<[C64; 4]> {
        mode_shape(self.m, self.cg, self.k, lam, START[mi % 2], same)
    }
}

/// What [`modes_of`] asks of a model: the shape of its mode `mi` with eigenvalue `lam`, of unit
/// 2-norm and independent of the shapes `same`, or None.
///
/// A trait with `#[inline(always)]` methods rather than a closure: the per-point work is compiled
/// inside `#[target_feature]` functions ([`crate::lanes::simd_dispatch`]), and a closure that LLVM
/// does not inline is compiled without the CPU's features (here it was not: 168 -> 178 M
/// instructions and 3 % more time, `examples/modal_points`).
pub(crate) trait ModeShapes<const D: usize> {
    fn shape(&self, lam: C64, mi: usize, same: &[[C64; D]]) -> Option<[C64; D]>;
}

/// The modes of one point of a model with `D` degrees of freedom from its `S` = 2 `D` eigenvalues
/// `s` (None: the eigen-solver failed), for the rigid rotor (D = 4) and the rotor on pedestals
/// (D = 8, [`crate::pedestal`]): the eigenvalues with positive imaginary part ([`is_mode`]) by
/// damped frequency (ties by index), the first `D` into `lo`, and mode `mi`'s shape
/// `shapes.shape(s, mi, same)` (unit 2-norm, independent of the shapes `same` of the earlier
/// modes whose eigenvalue is the same to rounding, [`same_eigenvalue`]) divided by its pivot component
/// ([`scale_to_pivot`]) into `so[D mi..D mi + D]`. Everything not set is NaN. Returns 1 when the
/// point failed (no eigenvalues, or some mode without a shape: then all NaN), else 0. No
/// allocation.
#[inline(always)]
pub(crate) fn modes_of<const D: usize, const S: usize>(
    s: Option<[C64; S]>,
    lo: &mut [C64],
    so: &mut [C64],
    shapes: &impl ModeShapes<D>,
) -> usize {
    let nan = C64::new(f64::NAN, f64::NAN);
    for v in lo.iter_mut().chain(so.iter_mut()) {
        *v = nan;
    }
    let Some(s) = s else {
        return 1;
    };
    let mut idx = [0usize; S];
    let mut nidx = 0;
    for t in 0..S {
        if is_mode(s[t]) {
            idx[nidx] = t;
            nidx += 1;
        }
    }
    let idx = &mut idx[..nidx];
    idx.sort_unstable_by(|&x, &y| s[x].im.partial_cmp(&s[y].im).unwrap_or(std::cmp::Ordering::Equal).then(x.cmp(&y)));
    let mut found = [[C64::new(0.0, 0.0); D]; D];
    for (mi, &t) in idx.iter().take(D).enumerate() {
        lo[mi] = s[t];
        // shapes of earlier modes with the same eigenvalue (to rounding) are projected out
        let mut same = [[C64::new(0.0, 0.0); D]; D];
        let mut nsame = 0;
        for o in 0..mi {
            if same_eigenvalue(lo[o], s[t]) {
                same[nsame] = found[o];
                nsame += 1;
            }
        }
        let Some(v) = shapes.shape(s[t], mi, &same[..nsame]) else {
            for v in lo.iter_mut().chain(so.iter_mut()) {
                *v = nan;
            }
            return 1;
        };
        found[mi] = v;
        scale_to_pivot(&v, &mut so[D * mi..D * mi + D]);
    }
    0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `modulus` is `hypot` to within an ulp where it squares, and `hypot` itself where the
    /// squares would leave the floating-point range (large, tiny and subnormal parts, inf, NaN).
    #[test]
    fn modulus_is_hypot_within_an_ulp_and_hypot_outside_the_squares_range() {
        let parts = [0.0, 1e-300, 3e-160, 1e-150, 1e-20, 0.5, 1.0, 3.0, 7e5, 1e140, 1e150, 2e160, 1e300, f64::MIN_POSITIVE / 8.0];
        for &a in &parts {
            for &b in &parts {
                for (re, im) in [(a, b), (-a, b), (a, -b)] {
                    let z = C64::new(re, im);
                    let (got, want) = (modulus(z), z.norm());
                    let ulp = want * f64::EPSILON;
                    assert!((got - want).abs() <= ulp, "|{z}|: {got:e} against hypot {want:e}");
                    let sq = z.norm_sqr();
                    if !(sq > 1e-290 && sq < 1e290) {
                        assert_eq!(got.to_bits(), want.to_bits(), "|{z}| outside the squares' range");
                    }
                }
            }
        }
        assert!(modulus(C64::new(f64::NAN, 1.0)).is_nan());
        assert_eq!(modulus(C64::new(f64::INFINITY, f64::NAN)), f64::INFINITY);
    }

    /// Points analysed two at a time (their eigenvalue iterations interleaved) give the bits each
    /// gets alone, for an odd number of points (the last one alone), points that fail (NaN
    /// coefficients) next to ones that do not, and different bearings per point.
    #[test]
    fn pairs_of_points_give_each_point_its_own_bits() {
        let rotor = Rotor::from_slice(&[30.7, 0.62, 0.062, 0.146, 0.137]).unwrap();
        let n = 37;
        let mut kb = Vec::new();
        let mut cb = Vec::new();
        for i in 0..n {
            let f = 1.0 + 0.37 * ((i * 7) % 11) as f64;
            kb.extend([3.2e6 * f, 4e5, -3e5 * f, 2.9e6, 3.5e6, 2e5 * f, -2e5, 3.1e6 / f]);
            cb.extend([2.1e3, 1e2 * f, 1e2, 2.3e3 * f, 2.2e3 / f, 0.0, 0.0, 2.0e3]);
        }
        kb[8 * 5 + 2] = f64::NAN;
        cb[8 * 12] = f64::INFINITY;
        let spin: Vec<f64> = (0..n).map(|i| 40.0 * i as f64).collect();
        let nan = C64::new(f64::NAN, f64::NAN);
        let (mut lam, mut shapes) = (vec![nan; 4 * n], vec![nan; 16 * n]);
        let failed = modal(&rotor, &kb, &cb, &spin, &mut lam, &mut shapes).unwrap();
        assert_eq!(failed, 2);
        let bits = |v: &[C64]| v.iter().map(|z| (z.re.to_bits(), z.im.to_bits())).collect::<Vec<_>>();
        for i in 0..n {
            let (mut l1, mut s1) = (vec![nan; 4], vec![nan; 16]);
            let f1 = modal(&rotor, &kb[8 * i..8 * i + 8], &cb[8 * i..8 * i + 8], &spin[i..i + 1], &mut l1, &mut s1).unwrap();
            assert_eq!(f1, usize::from(i == 5 || i == 12), "point {i}");
            assert_eq!(bits(&lam[4 * i..4 * i + 4]), bits(&l1), "eigenvalues of point {i}");
            assert_eq!(bits(&shapes[16 * i..16 * i + 16]), bits(&s1), "shapes of point {i}");
        }
    }

    /// The pivot is the largest component, the first of those equal to within 1e-12 (not the one
    /// rounding happens to favour), and 0 for a zero vector.
    #[test]
    fn pivot_takes_the_first_of_the_largest_components() {
        let c = C64::new;
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert_eq!(pivot(&[c(0.1, 0.0), c(0.0, 0.9), c(0.3, 0.3), c(0.0, 0.0)]), 1);
        // equal in exact arithmetic, apart by rounding either way: the first
        let (a, b) = (c(h, 0.0), c(0.0, h * (1.0 + 4.0 * f64::EPSILON)));
        assert_eq!(pivot(&[c(0.0, 0.0), a, b, c(0.1, 0.0)]), 1);
        assert_eq!(pivot(&[c(0.0, 0.0), b, a, c(0.1, 0.0)]), 1);
        // apart by more than 1e-12: the larger
        assert_eq!(pivot(&[a, c(0.0, h * (1.0 + 1e-9)), c(0.0, 0.0), c(0.0, 0.0)]), 1);
        assert_eq!(pivot(&[c(0.0, 0.0); 4]), 0);
    }
}
