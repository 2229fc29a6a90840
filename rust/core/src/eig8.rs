//! Eigenvalues (only) of a small dense real matrix, on the stack: reduction to upper Hessenberg
//! form by Householder reflections, then the Francis implicit double-shift QR iteration on the
//! Hessenberg matrix without accumulating the transformations (the algorithm of EISPACK `hqr`,
//! Wilkinson & Reinsch, *Handbook for Automatic Computation* vol. II, contribution II/14; Golub &
//! Van Loan, *Matrix Computations*, 4th ed., §7.4-7.5). Written for the 8 x 8 state matrix of the
//! modal analysis ([`crate::modal`]), generic over the size `N`.
//!
//! # Hessenberg reduction
//!
//! For k = 0 .. N-3, with x = A(k+1.., k) (the part of column k below the subdiagonal), the
//! Householder reflector P = I - beta v v^T with
//!
//! - alpha = -sign(x_0) ||x||_2, v = x - alpha e_1, beta = 2 / (v^T v) = -1 / (alpha v_0)
//!
//! maps x to alpha e_1 (the sign choice avoids cancellation in v_0 = x_0 - alpha). The similarity
//! A <- P A P (P acting on rows / columns k+1..) zeroes column k below the subdiagonal and leaves
//! the earlier columns alone. P is orthogonal, so the reduction is backward stable: the Hessenberg
//! matrix H is exactly similar to A + E with ||E|| = O(eps ||A||). ||x||^2 is formed directly when
//! it lies safely inside the floating-point range, else after scaling x by its largest entry.
//!
//! # Francis double-shift QR on H (active window l..=en)
//!
//! - **Deflation.** A subdiagonal entry h(k, k-1) is set to zero when it is negligible. First
//!   test (the classical one): |h(k, k-1)| <= eps (|h(k-1, k-1)| + |h(k, k)|). It is then refined
//!   by the criterion of Ahues & Tisseur (1997, used in LAPACK `dlahqr`), which keeps small but
//!   significant entries of graded matrices: with ab = max(|h(k, k-1)|, |h(k-1, k)|),
//!   ba = min(..), aa = max(|h(k, k)|, |h(k-1, k-1) - h(k, k)|), bb = min(..), s = aa + ab, the
//!   entry is negligible when ba (ab / s) <= eps bb (aa / s). The window's lower end l is the
//!   largest k with a negligible h(k, k-1) (or 0); the upper end en is the last undeflated row.
//! - **Convergence.** When l = en, h(en, en) is an eigenvalue. When l = en - 1, the trailing
//!   2 x 2 block [[a, b], [c, d]] gives two: with p = (a - d) / 2 and q = p^2 + b c, a complex
//!   pair (a + d) / 2 ± i sqrt(-q) when q < 0, else the real pair lambda_1 = d + z,
//!   lambda_2 = d - b c / z with z = p + sign(p) sqrt(q) (the second from the product of the
//!   roots, which avoids cancellation). The window then shrinks by one or two rows.
//! - **Shifts.** The double shift is the pair of eigenvalues sigma_1, sigma_2 of the trailing
//!   2 x 2 block of the window, used only through the real quantities x = h(en, en),
//!   y = h(en-1, en-1) and w = h(en, en-1) h(en-1, en) (so sigma_1 + sigma_2 = x + y and
//!   sigma_1 sigma_2 = x y - w): one double step equals two single QR steps with shifts sigma_1
//!   and sigma_2, or with a complex-conjugate pair, in real arithmetic. Two refinements of
//!   LAPACK `dlahqr` over EISPACK: when the 2 x 2 eigenvalues are real, the one closer to
//!   h(en, en) is used twice (x = y = sigma, w = 0; with two distinct real shifts, a window holding
//!   two 2 x 2 Jordan blocks with exactly those eigenvalues never converges), and an
//!   *exceptional shift* breaks cycles (the cyclic permutation matrix, nearly nilpotent windows)
//!   every 10th step without deflation instead of only at the 10th and 20th: with
//!   s = |h(en, en-1)| + |h(en-1, en-2)| (every 20th step) or s = |h(l+1, l)| + |h(l+2, l+1)|
//!   (the others), x = y = h(en, en) + 0.75 s (resp. h(l, l) + 0.75 s) and w = -0.4375 s^2.
//! - **Implicit step (implicit Q theorem).** The first column of
//!   (H - sigma_1 I)(H - sigma_2 I) = H^2 - (x + y) H + (x y - w) I has three nonzero entries;
//!   at row m (the start of the sweep, below) they are
//!
//!   p = (x - h(m, m)) (y - h(m, m)) - w + h(m, m+1) h(m+1, m),
//!   q = h(m+1, m) (h(m+1, m+1) - h(m, m) - (x - h(m, m)) - (y - h(m, m))),
//!   r = h(m+1, m) h(m+2, m+1)
//!
//!   (EISPACK divides all three by h(m+1, m); only their direction matters). A 3 x 3 Householder
//!   reflector mapping (p, q, r) to a multiple of e_1 is applied as a similarity on rows /
//!   columns m..m+2; this creates a bulge below the subdiagonal that further 3 x 3 reflectors
//!   (2 x 2 for the last row) chase down to row en, restoring the Hessenberg form. With
//!   s = sign(p) ||(p, q, r)||, the reflector I - tau u u^T, u = (1, q / (p + s), r / (p + s)),
//!   tau = (p + s) / s, maps (p, q, r) to (-s, 0, 0); it is applied to a column c of three rows as
//!   c -= (u . c) tau u, and likewise to rows.
//! - **Starting row m.** The sweep starts at the lowest row m >= l where two consecutive
//!   subdiagonal entries are small enough (EISPACK's test: |h(m, m-1)| (|q| + |r|) negligible
//!   next to |p| (|h(m-1, m-1)| + |h(m, m)| + |h(m+1, m+1)|)), else at l; the reflector then
//!   changes h(m, m-1) only by the factor 1 - (p + s)/s = -p/s and the fill-in it would create
//!   below it is below rounding level. This is not only a saving: on a matrix with three zero rows
//!   and columns (a defective zero eigenvalue, subdiagonal entries at rounding level between tiny
//!   diagonal entries, which the local test does not deflate), sweeps started at l (with EISPACK's
//!   shifts) did not converge in 240 double steps, those started at m converged in 8 (kept as a
//!   case of the test `special_matrices`).
//! - **Eigenvalues only.** The eigenvalues of the window are those of the block
//!   H(l..=en, l..=en) (the matrix is block upper triangular around it), so each reflector is
//!   applied to columns k..=en of its rows and rows l..=min(en, k+3) of its columns only, not to
//!   the whole matrix, and no orthogonal factor is accumulated.
//! - **Order of the updates.** The chase is a chain: each reflector is formed from the column the
//!   previous one produced (a square root and two divisions). Each similarity therefore first
//!   updates the 3 x 3 block on its rows and columns (and row k+3), which holds the next
//!   reflector's column, and only then the rest of its rows and columns, which the processor
//!   overlaps with the next square root and divisions.
//! - **Two matrices at once** ([`eigenvalues_pair`], what the modal analysis uses for each pair
//!   of speeds). The chain above leaves the processor idle between a reflector's square root and
//!   divisions and the next one; the iterations of two independent matrices, advanced in turn
//!   reflector by reflector (`Francis` keeps each one's window, budget and eigenvalues between
//!   steps), give it a second chain to overlap with the first. Each matrix goes through exactly
//!   its own operations, so the results are those of [`eigenvalues`] bit for bit. One thread,
//!   `examples/modal_points 4000 10`, interleaved runs: 3.62-3.65 -> 3.37-3.39 µs per speed for
//!   the whole modal analysis at AVX-512, 3.61-3.64 -> 3.27-3.31 at AVX2.
//! - **Range.** When the entries of H leave [1e-100, 1e100] H is first scaled by a power of two
//!   (exactly; the eigenvalues are scaled back), and a reflector whose ||(p, q, r)||^2 leaves the
//!   safe range is formed from (p, q, r) / (|p| + |q| + |r|) instead (the first one in EISPACK's
//!   divided form), so that the products and squares above neither overflow nor underflow.
//!
//! Convergence is quadratic once the shifts are close; the 8 x 8 state matrices of a nearly
//! isotropic rotor (four close complex pairs) take about 14 double steps in all. The iteration
//! budget is 30 max(N, 10) double steps per deflation (LAPACK's). Each double step is a sequence of
//! orthogonal similarities, so the computed eigenvalues are the exact eigenvalues of a matrix A + E
//! with ||E|| = O(eps ||A||); their accuracy is then eps ||A|| times each eigenvalue's condition
//! number (balance the matrix first, see [`crate::modal::balance`], when its entries span many
//! decades; no balancing is done here).

use crate::model::C64;

const EPS: f64 = f64::EPSILON;
/// Below this a subdiagonal entry is negligible in absolute terms (LAPACK's safe minimum times
/// N / ulp, taken for N = 64: only matters for matrices near the underflow threshold).
const SMALL: f64 = f64::MIN_POSITIVE * (64.0 / f64::EPSILON);

/// All N eigenvalues of a real N x N matrix (row-major `a[row][col]`), complex pairs as
/// conjugates (positive imaginary part first). None when the QR iteration has not converged
/// (30 max(N, 10) double steps without a deflation), or when the matrix has non-finite entries.
///
/// ```
/// use rotorid_core::eig8::eigenvalues;
/// // rotation by 90 degrees scaled by 2 (eigenvalues ±2i) and 3 on the diagonal
/// let a = [[0.0, -2.0, 0.0], [2.0, 0.0, 0.0], [1.0, 1.0, 3.0]];
/// let ev = eigenvalues(&a).unwrap();
/// assert!(ev.iter().any(|z| (z.re - 3.0).abs() < 1e-14 && z.im == 0.0));
/// assert!(ev.iter().any(|z| z.re.abs() < 1e-14 && (z.im - 2.0).abs() < 1e-14));
/// ```
#[inline(always)]
pub fn eigenvalues<const N: usize>(a: &[[f64; N]; N]) -> Option<[C64; N]> {
    if !a.iter().flatten().all(|v| v.is_finite()) {
        return None;
    }
    let mut h = *a;
    hessenberg(&mut h);
    hqr(&mut h)
}

/// Reduce `h` in place to upper Hessenberg form by a similarity of N - 2 Householder reflectors
/// (not accumulated). Entries below the subdiagonal are set to zero.
#[inline(always)]
pub fn hessenberg<const N: usize>(h: &mut [[f64; N]; N]) {
    let mut k = 0;
    while k + 2 < N {
        // x = h[k+1.., k]; ||x||^2 unscaled when it is safely representable
        let mut v = [0.0f64; N];
        let (mut s0, mut s1) = (0.0, 0.0);
        for i in k + 1..N {
            v[i] = h[i][k];
        }
        for i in (k + 2..N).step_by(2) {
            s0 += v[i] * v[i];
            if i + 1 < N {
                s1 += v[i + 1] * v[i + 1];
            }
        }
        let below = s0 + s1;
        if below == 0.0 && v[k + 2..].iter().all(|x| *x == 0.0) {
            // already zero below the subdiagonal
            k += 1;
            continue;
        }
        let mut ss = below + v[k + 1] * v[k + 1];
        let mut scale = 1.0;
        if !(below > SAFE_LO && ss < SAFE_HI) {
            // rare: entries so small or large that their squares leave the floating-point range
            scale = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            ss = 0.0;
            for x in v.iter_mut() {
                *x /= scale;
                ss += *x * *x;
            }
        }
        let alpha = -ss.sqrt().copysign(v[k + 1]);
        v[k + 1] -= alpha;
        let beta = -1.0 / (alpha * v[k + 1]);
        // left: rows k+1.., columns k+1..
        let mut t = [0.0f64; N];
        let mut t2 = [0.0f64; N];
        let mut i = k + 1;
        while i + 1 < N {
            let (vi, vi1) = (v[i], v[i + 1]);
            for j in k + 1..N {
                t[j] += vi * h[i][j];
                t2[j] += vi1 * h[i + 1][j];
            }
            i += 2;
        }
        if i < N {
            for j in k + 1..N {
                t[j] += v[i] * h[i][j];
            }
        }
        for j in k + 1..N {
            t[j] = beta * (t[j] + t2[j]);
        }
        for i in k + 1..N {
            let vi = v[i];
            for j in k + 1..N {
                h[i][j] -= vi * t[j];
            }
        }
        // right: all rows, columns k+1..
        for row in h.iter_mut() {
            let (mut a, mut b) = (0.0, 0.0);
            let mut j = k + 1;
            while j + 1 < N {
                a += row[j] * v[j];
                b += row[j + 1] * v[j + 1];
                j += 2;
            }
            if j < N {
                a += row[j] * v[j];
            }
            let f = beta * (a + b);
            for j in k + 1..N {
                row[j] -= f * v[j];
            }
        }
        h[k + 1][k] = alpha * scale;
        for row in h.iter_mut().skip(k + 2) {
            row[k] = 0.0;
        }
        k += 1;
    }
}

/// Whether the subdiagonal entry h(k, k-1) (k >= 1) of the window ending at row `en` is negligible
/// (classical test, refined by Ahues & Tisseur's; see the module documentation).
#[inline(always)]
fn negligible<const N: usize>(h: &[[f64; N]; N], k: usize, en: usize) -> bool {
    let sub = h[k][k - 1].abs();
    if sub <= SMALL {
        return true;
    }
    let mut tst = h[k - 1][k - 1].abs() + h[k][k].abs();
    if tst == 0.0 {
        if k >= 2 {
            tst += h[k - 1][k - 2].abs();
        }
        if k < en {
            tst += h[k + 1][k].abs();
        }
    }
    if sub > EPS * tst {
        return false;
    }
    let sup = h[k - 1][k].abs();
    let (ab, ba) = if sub > sup { (sub, sup) } else { (sup, sub) };
    let diag = h[k][k].abs();
    let diff = (h[k - 1][k - 1] - h[k][k]).abs();
    let (aa, bb) = if diag > diff { (diag, diff) } else { (diff, diag) };
    let s = aa + ab;
    ba * (ab / s) <= SMALL.max(EPS * (bb * (aa / s)))
}

/// Eigenvalues of the upper Hessenberg matrix `h` (entries below the subdiagonal are ignored and
/// set to zero) by
/// the Francis double-shift QR iteration, without accumulating transformations; `h` is
/// overwritten. None when it has not converged (30 max(N, 10) double steps without a deflation).
#[inline(always)]
pub fn hqr<const N: usize>(h: &mut [[f64; N]; N]) -> Option<[C64; N]> {
    alone(Francis::new(h))
}

/// The iteration of [`hqr`] from a prepared state.
#[inline(always)]
fn alone<const N: usize>(mut qr: Francis<'_, N>) -> Option<[C64; N]> {
    loop {
        match qr.prepare() {
            Next::Done(ev) => return ev,
            Next::Deflated => {}
            Next::Sweep(mut sw) => {
                for k in sw.m..qr.en {
                    qr.reflect(&mut sw, k);
                }
            }
        }
    }
}

/// Whether every entry of `m` is finite (a function, not a closure: see
/// [`crate::modal::ModeShapes`]).
#[inline(always)]
fn all_finite<const N: usize>(m: &[[f64; N]; N]) -> bool {
    m.iter().flatten().all(|v| v.is_finite())
}

/// [`eigenvalues`] of two matrices at once: their QR iterations advance in turn, reflector by
/// reflector, so that the processor overlaps the two chains of dependent steps (each reflector
/// waits for the square root and divisions of the one before it). Each matrix goes through the
/// same operations as alone: the same results, bit for bit.
#[inline(always)]
pub fn eigenvalues_pair<const N: usize>(a: &[[f64; N]; N], b: &[[f64; N]; N]) -> (Option<[C64; N]>, Option<[C64; N]>) {
    match (all_finite(a), all_finite(b)) {
        (true, true) => {}
        (true, false) => return (eigenvalues(a), None),
        (false, true) => return (None, eigenvalues(b)),
        (false, false) => return (None, None),
    }
    let (mut ha, mut hb) = (*a, *b);
    hessenberg(&mut ha);
    hessenberg(&mut hb);
    pair(Francis::new(&mut ha), Francis::new(&mut hb))
}

/// The interleaved iterations of [`eigenvalues_pair`] from two prepared states.
#[inline(always)]
fn pair<const N: usize>(mut qa: Francis<'_, N>, mut qb: Francis<'_, N>) -> (Option<[C64; N]>, Option<[C64; N]>) {
    let (mut ra, mut rb) = (None, None);
    while ra.is_none() || rb.is_none() {
        let sa = if ra.is_none() { step(&mut qa, &mut ra) } else { None };
        let sb = if rb.is_none() { step(&mut qb, &mut rb) } else { None };
        match (sa, sb) {
            (Some(mut sa), Some(mut sb)) => {
                let (ea, eb) = (qa.en, qb.en);
                let (mut ka, mut kb) = (sa.m, sb.m);
                while ka < ea || kb < eb {
                    if ka < ea {
                        qa.reflect(&mut sa, ka);
                        ka += 1;
                    }
                    if kb < eb {
                        qb.reflect(&mut sb, kb);
                        kb += 1;
                    }
                }
            }
            (Some(mut sa), None) => {
                for k in sa.m..qa.en {
                    qa.reflect(&mut sa, k);
                }
            }
            (None, Some(mut sb)) => {
                for k in sb.m..qb.en {
                    qb.reflect(&mut sb, k);
                }
            }
            (None, None) => {}
        }
    }
    (ra.unwrap_or(None), rb.unwrap_or(None))
}

/// One [`Francis::prepare`] of a pair's matrix: its sweep, or None after a deflation or the end
/// (then `done` holds the result).
#[inline(always)]
fn step<const N: usize>(qr: &mut Francis<'_, N>, done: &mut Option<Option<[C64; N]>>) -> Option<Sweep> {
    match qr.prepare() {
        Next::Done(ev) => {
            *done = Some(ev);
            None
        }
        Next::Deflated => None,
        Next::Sweep(sw) => Some(sw),
    }
}

/// The state of the Francis iteration on one Hessenberg matrix between its steps (see the
/// module's documentation): the active window's ends, the double steps since the last deflation,
/// the eigenvalues found so far.
struct Francis<'a, const N: usize> {
    h: &'a mut [[f64; N]; N],
    ev: [C64; N],
    /// upper end of the active window: rows/columns > en are done
    en: usize,
    /// lower end of the window found by the last deflation scan
    l: usize,
    /// double steps since the last deflation at the bottom
    its: usize,
    /// the power of two the matrix was scaled by, undone on the eigenvalues
    unscale: f64,
}

/// What [`Francis::prepare`] found.
enum Next<const N: usize> {
    /// every eigenvalue found (Some), or no convergence within the budget (None)
    Done(Option<[C64; N]>),
    /// one or two eigenvalues split off at the bottom: prepare again
    Deflated,
    /// a double step is due: its reflectors at rows m..en
    Sweep(Sweep),
}

/// One double step's shifts (through x, y, w), starting row and the first reflector's column
/// (p, q, r) at that row (the later ones come from the bulge in `h`).
#[derive(Clone, Copy)]
struct Sweep {
    m: usize,
    x: f64,
    y: f64,
    w: f64,
    p: f64,
    q: f64,
    r: f64,
}

impl<'a, const N: usize> Francis<'a, N> {
    /// Double steps allowed per deflation (LAPACK dlahqr's budget).
    const BUDGET: usize = 30 * if N > 10 { N } else { 10 };

    #[inline(always)]
    fn new(h: &'a mut [[f64; N]; N]) -> Self {
        let ev = [C64::new(0.0, 0.0); N];
        if N == 0 {
            return Francis { h, ev, en: 0, l: 0, its: 0, unscale: 1.0 };
        }
        for (i, row) in h.iter_mut().enumerate().skip(2) {
            row[..i - 1].fill(0.0);
        }
        // exact power-of-two scaling of the largest entry to about 1 when the entries are far from 1,
        // so that the unscaled reflector arithmetic below can neither overflow nor underflow
        let mut big = 0.0f64;
        for (i, row) in h.iter().enumerate() {
            for v in &row[i.saturating_sub(1)..] {
                big = big.max(v.abs());
            }
        }
        let unscale = if big > 1e100 || (big < 1e-100 && big > 0.0) {
            let e = big.log2().round() as i32;
            let f = 2f64.powi(-e);
            for (i, row) in h.iter_mut().enumerate() {
                for v in &mut row[i.saturating_sub(1)..] {
                    *v *= f;
                }
            }
            2f64.powi(e)
        } else {
            1.0
        };
        Francis { h, ev, en: N - 1, l: 0, its: 0, unscale }
    }

    /// The deflation scan of the window ending at `en`, then either the eigenvalues it split off
    /// or the next double step's shifts, starting row and first column.
    #[inline(always)]
    fn prepare(&mut self) -> Next<N> {
        if N == 0 {
            return Next::Done(Some(self.ev));
        }
        let itmax = Self::BUDGET;
        let (h, en, unscale) = (&mut *self.h, self.en, self.unscale);
        // lower end: the nearest negligible subdiagonal entry at or above en
        let mut k = en;
        while k > self.l {
            if negligible(h, k, en) {
                h[k][k - 1] = 0.0;
                break;
            }
            k -= 1;
        }
        let l = k;
        self.l = l;
        let x = h[en][en];
        if l == en {
            // one real eigenvalue
            self.ev[en] = C64::new(x * unscale, 0.0);
            if en == 0 {
                return Next::Done(Some(self.ev));
            }
            self.deflated(en - 1);
            return Next::Deflated;
        }
        let na = en - 1;
        let y = h[na][na];
        let w = h[en][na] * h[na][en];
        if l == na {
            // trailing 2 x 2 block: a pair
            let p = 0.5 * (y - x);
            let q = p * p + w;
            let z = q.abs().sqrt();
            if q >= 0.0 {
                let z = p + z.copysign(p);
                let l1 = x + z;
                let l2 = if z != 0.0 { x - w / z } else { l1 };
                self.ev[na] = C64::new(l1 * unscale, 0.0);
                self.ev[en] = C64::new(l2 * unscale, 0.0);
            } else {
                self.ev[na] = C64::new((x + p) * unscale, z * unscale);
                self.ev[en] = C64::new((x + p) * unscale, -z * unscale);
            }
            if na == 0 {
                return Next::Done(Some(self.ev));
            }
            self.deflated(na - 1);
            return Next::Deflated;
        }
        let its = self.its;
        if its == itmax {
            return Next::Done(None);
        }
        // shifts, through x + y = sigma_1 + sigma_2 and x y - w = sigma_1 sigma_2
        let (x, y, w) = if its > 0 && its % 10 == 0 {
            // exceptional: every 20th step from the bottom of the window, every other 10th
            // from its top
            let (s, d) = if its % 20 == 0 {
                (h[en][na].abs() + h[na][na - 1].abs(), h[en][en])
            } else {
                (h[l + 1][l].abs() + h[l + 2][l + 1].abs(), h[l][l])
            };
            let x = d + 0.75 * s;
            (x, x, -0.4375 * s * s)
        } else {
            let p = 0.5 * (y - x);
            let q = p * p + w;
            if q > 0.0 {
                // real eigenvalues of the trailing 2 x 2 block: the one closer to h[en][en],
                // twice
                // (x + p -+ sqrt(q) for p >= 0 / p < 0, written as x - w / (p +- sqrt(q)))
                let sigma = x - w / (p + q.sqrt().copysign(p));
                (sigma, sigma, 0.0)
            } else {
                (x, y, w)
            }
        };
        self.its = its + 1;
        // starting row m: the lowest row with two consecutive small subdiagonal entries, or l;
        // (p, q, r) is the first column of (H - sigma_1)(H - sigma_2) at row m (not divided
        // by h[m+1][m]: the test compares ratios)
        let mut m = en - 2;
        let (mut p, mut q, mut r);
        loop {
            let zz = h[m][m];
            let h10 = h[m + 1][m];
            let rr = x - zz;
            let ss = y - zz;
            p = rr * ss - w + h[m][m + 1] * h10;
            q = h10 * (h[m + 1][m + 1] - zz - rr - ss);
            r = h10 * h[m + 2][m + 1];
            if m == l {
                break;
            }
            let tst1 = p.abs() * (h[m - 1][m - 1].abs() + zz.abs() + h[m + 1][m + 1].abs());
            let tst2 = h[m][m - 1].abs() * (q.abs() + r.abs());
            if tst2 <= EPS * tst1 {
                break;
            }
            m -= 1;
        }
        // double step: reflectors on rows/columns k..k+2 for k = m ..= en-1
        Next::Sweep(Sweep { m, x, y, w, p, q, r })
    }

    /// The window now ends at `en`: a new budget, and the next scan starts from the top.
    #[inline(always)]
    fn deflated(&mut self, en: usize) {
        self.en = en;
        self.its = 0;
        self.l = 0;
    }

    /// The double step's reflector at row `k` (m <= k < en, in order), formed from (p, q, r) at
    /// k = m and from the bulge in column k-1 after. (`sw` is only read; taken as `&mut` because
    /// LLVM then kept the modal analysis 2-3 % faster than with `&`, interleaved runs.)
    #[inline(always)]
    fn reflect(&mut self, sw: &mut Sweep, k: usize) {
        let (h, l, en, m) = (&mut *self.h, self.l, self.en, sw.m);
        let last = k + 1 == en;
        let (mut p, mut q, mut r) = (sw.p, sw.q, sw.r);
        if k != m {
            p = h[k][k - 1];
            q = h[k + 1][k - 1];
            r = if last { 0.0 } else { h[k + 2][k - 1] };
        }
        let mut scale = 1.0;
        let mut nrm2 = p * p + q * q + r * r;
        if !(nrm2 > SAFE_LO && nrm2 < SAFE_HI) {
            // rare: rescale by the 1-norm (recomputing the first column in the form
            // divided by h[m+1][m] if the products over- or underflowed)
            if k == m {
                (p, q, r) = first_column_scaled(h, m, sw.x, sw.y, sw.w);
            }
            scale = p.abs() + q.abs() + r.abs();
            if scale == 0.0 || !scale.is_finite() {
                return;
            }
            p /= scale;
            q /= scale;
            r /= scale;
            nrm2 = p * p + q * q + r * r;
        }
        let s = nrm2.sqrt().copysign(p);
        if k != m {
            h[k][k - 1] = -s * scale;
            h[k + 1][k - 1] = 0.0;
            if !last {
                h[k + 2][k - 1] = 0.0;
            }
        } else if m != l {
            // the reflector acts on column m-1 only through h[m][m-1] (the fill-in below
            // it is negligible by the choice of m)
            h[k][k - 1] *= -p / s;
        }
        // reflector I - tau u u^T, u = (1, v1, v2): tau = (p + s) / s, v = (q, r) / (p + s)
        let p1 = p + s;
        let (inv_s, inv_p1) = (1.0 / s, 1.0 / p1);
        let (tx, ty, tz) = (p1 * inv_s, q * inv_s, r * inv_s);
        let (v1, v2) = (q * inv_p1, r * inv_p1);
        if last {
            reflect2(h, k, l, en, tx, ty, v1);
        } else {
            reflect3(h, k, l, en, tx, ty, tz, v1, v2);
        }
    }
}

const SAFE_LO: f64 = 1e-280;
const SAFE_HI: f64 = 1e280;

/// First column of (H - sigma_1)(H - sigma_2) at row m in EISPACK's form (divided by h(m+1, m),
/// then by its 1-norm): the fallback when the undivided products leave the safe range.
#[cold]
fn first_column_scaled<const N: usize>(h: &[[f64; N]; N], m: usize, x: f64, y: f64, w: f64) -> (f64, f64, f64) {
    let zz = h[m][m];
    let rr = x - zz;
    let ss = y - zz;
    let p = (rr * ss - w) / h[m + 1][m] + h[m][m + 1];
    let q = h[m + 1][m + 1] - zz - rr - ss;
    let r = h[m + 2][m + 1];
    let s = p.abs() + q.abs() + r.abs();
    (p / s, q / s, r / s)
}

/// Apply the 3 x 3 reflector I - tau u u^T, u = (1, v1, v2), (tx, ty, tz) = tau u, as a
/// similarity on rows / columns k..k+2: first the block that the next reflector reads (rows
/// k..k+2 x columns k..k+2 from both sides, and row k+3), then the rest (rows k..k+2 x columns
/// k+3..=en from the left, rows l..k-1 x columns k..k+2 from the right), which is independent of
/// the next reflector and overlaps with its square root and divisions.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn reflect3<const N: usize>(h: &mut [[f64; N]; N], k: usize, l: usize, en: usize, tx: f64, ty: f64, tz: f64, v1: f64, v2: f64) {
    let mut c = [[0.0f64; 3]; 3];
    for (i, ci) in c.iter_mut().enumerate() {
        ci.copy_from_slice(&h[k + i][k..k + 3]);
    }
    let [c0, c1, c2] = &mut c;
    for ((a, b), d) in c0.iter_mut().zip(c1.iter_mut()).zip(c2.iter_mut()) {
        let t = *a + v1 * *b + v2 * *d;
        *a -= t * tx;
        *b -= t * ty;
        *d -= t * tz;
    }
    for (i, ci) in c.iter_mut().enumerate() {
        let t = tx * ci[0] + ty * ci[1] + tz * ci[2];
        ci[0] -= t;
        ci[1] -= t * v1;
        ci[2] -= t * v2;
        h[k + i][k..k + 3].copy_from_slice(ci);
    }
    if k + 3 <= en {
        let row = &mut h[k + 3];
        let t = tz * row[k + 2];
        row[k] = -t;
        row[k + 1] = -t * v1;
        row[k + 2] -= t * v2;
    }
    {
        let (top, bot) = h.split_at_mut(k + 1);
        let (mid, bot) = bot.split_at_mut(1);
        let (r0, r1, r2) = (&mut top[k][k + 3..=en], &mut mid[0][k + 3..=en], &mut bot[0][k + 3..=en]);
        for ((a, b), c) in r0.iter_mut().zip(r1.iter_mut()).zip(r2.iter_mut()) {
            let t = *a + v1 * *b + v2 * *c;
            *a -= t * tx;
            *b -= t * ty;
            *c -= t * tz;
        }
    }
    for row in h[l..k].iter_mut() {
        let c = &mut row[k..k + 3];
        let t = tx * c[0] + ty * c[1] + tz * c[2];
        c[0] -= t;
        c[1] -= t * v1;
        c[2] -= t * v2;
    }
}

/// The 2 x 2 reflector I - tau u u^T, u = (1, v1), (tx, ty) = tau u, on rows k, k+1 (columns
/// k..=en) and columns k, k+1 (rows l..=en), k + 1 = en.
#[inline(always)]
fn reflect2<const N: usize>(h: &mut [[f64; N]; N], k: usize, l: usize, en: usize, tx: f64, ty: f64, v1: f64) {
    {
        let (top, bot) = h.split_at_mut(k + 1);
        let (r0, r1) = (&mut top[k][k..=en], &mut bot[0][k..=en]);
        for (a, b) in r0.iter_mut().zip(r1.iter_mut()) {
            let t = *a + v1 * *b;
            *a -= t * tx;
            *b -= t * ty;
        }
    }
    for row in h[l..=en].iter_mut() {
        let c = &mut row[k..k + 2];
        let t = tx * c[0] + ty * c[1];
        c[0] -= t;
        c[1] -= t * v1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::modal::{balance, state_matrix};
    use crate::model::assemble;
    use crate::Rotor;
    use nalgebra::{Matrix4, SMatrix, Schur};
    use proptest::prelude::*;

    type M8 = [[f64; 8]; 8];

    fn to_na(a: &M8) -> SMatrix<f64, 8, 8> {
        SMatrix::<f64, 8, 8>::from_fn(|r, c| a[r][c])
    }

    fn fro(a: &M8) -> f64 {
        a.iter().flatten().map(|v| v * v).sum::<f64>().sqrt()
    }

    /// nalgebra's eigenvalues (real Schur form, complex eigenvalues of its 2 x 2 blocks); faer's
    /// where nalgebra's QR does not converge (it has no exceptional shifts: the cyclic permutation
    /// matrix, some matrices with repeated imaginary pairs) or where it returns NaN (the
    /// imaginary part of a 2 x 2 block with a double real eigenvalue, seen with 1.5 three times).
    fn reference(a: &M8) -> [C64; 8] {
        let mut out = [C64::new(0.0, 0.0); 8];
        if let Some(schur) = Schur::try_new(to_na(a), f64::EPSILON, 100_000) {
            for (o, e) in out.iter_mut().zip(schur.complex_eigenvalues().iter()) {
                *o = C64::new(e.re, e.im);
            }
            if out.iter().all(|z| z.re.is_finite() && z.im.is_finite()) {
                return out;
            }
        }
        let ev = faer::Mat::<f64>::from_fn(8, 8, |r, c| a[r][c]).eigenvalues().expect("faer eigenvalues");
        for (o, e) in out.iter_mut().zip(ev.iter()) {
            *o = C64::new(e.re, e.im);
        }
        out
    }

    /// Pair every reference eigenvalue with one of ours, closest pairs first; returns the indices
    /// into `ours` in the order of `refs`.
    fn matching(ours: &[C64; 8], refs: &[C64; 8]) -> [usize; 8] {
        let mut pairs: Vec<(f64, usize, usize)> = Vec::with_capacity(64);
        for (i, r) in refs.iter().enumerate() {
            for (j, o) in ours.iter().enumerate() {
                pairs.push(((r - o).norm(), i, j));
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (mut used_r, mut used_o, mut out) = ([false; 8], [false; 8], [usize::MAX; 8]);
        for (_, i, j) in pairs {
            if !used_r[i] && !used_o[j] {
                used_r[i] = true;
                used_o[j] = true;
                out[i] = j;
            }
        }
        out
    }

    /// The two smallest singular values of A - lam I and |u^H v| for the singular vectors of the
    /// smallest: for a simple eigenvalue lam, u and v approximate its left and right eigenvectors
    /// and 1 / |u^H v| is its condition number.
    fn shifted_svd(a: &M8, lam: C64) -> (f64, f64, f64) {
        let m = SMatrix::<C64, 8, 8>::from_fn(|r, c| C64::new(a[r][c], 0.0) - if r == c { lam } else { C64::new(0.0, 0.0) });
        let svd = m.svd(true, true);
        let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
        let i = svd.singular_values.imin();
        let second = (0..8).filter(|&t| t != i).map(|t| svd.singular_values[t]).fold(f64::INFINITY, f64::min);
        // right singular vector: row i of V^H, conjugated
        let dot: C64 = (0..8).map(|t| u[(t, i)].conj() * vt[(i, t)].conj()).sum();
        (svd.singular_values[i], second, dot.norm())
    }

    /// Largest differences seen: (relative to |lambda| for simple eigenvalues, relative to ||A||).
    #[derive(Default, Debug)]
    struct Seen {
        rel: f64,
        abs: f64,
    }

    /// Compare ours with nalgebra's on one matrix; returns the differences (relative to |lambda|,
    /// relative to ||A||_F) over the simple eigenvalues, or a description of the failure.
    fn check(a: &M8) -> Result<Seen, String> {
        let ours = eigenvalues(a).ok_or("no convergence")?;
        let refs = reference(a);
        let na = fro(a);
        if na == 0.0 {
            return if ours.iter().all(|z| z.norm() == 0.0) { Ok(Seen::default()) } else { Err(format!("zero matrix: {ours:?}")) };
        }
        // complex eigenvalues come in conjugate pairs
        for z in ours.iter().filter(|z| z.im != 0.0) {
            if !ours.iter().any(|w| w.re == z.re && w.im == -z.im) {
                return Err(format!("{z} without its conjugate in {ours:?}"));
            }
        }
        let mut seen = Seen::default();
        // backward error: lam is an eigenvalue of A + E with ||E|| = sigma_min(A - lam I)
        let mut kappa = [f64::INFINITY; 8];
        for (i, &lam) in ours.iter().enumerate() {
            let (smin, second, dot) = shifted_svd(a, lam);
            if smin > 1e-13 * na {
                return Err(format!("residual: sigma_min(A - {lam} I) = {smin:e} of ||A|| = {na:e}"));
            }
            // simple (one singular value at rounding level, the next well above it) and isolated
            // (the copies of a perturbed multiple eigenvalue are close to each other): condition
            // number from the singular vectors; else left infinite
            let gap = ours.iter().enumerate().filter(|&(j, _)| j != i).map(|(_, z)| (z - lam).norm()).fold(f64::INFINITY, f64::min);
            if second > 1e3 * smin.max(EPS * na) && gap > 1e-4 * lam.norm().max(1e-8 * na) {
                kappa[i] = 1.0 / dot.max(1e-300);
            }
        }
        let map = matching(&ours, &refs);
        for (i, &r) in refs.iter().enumerate() {
            let o = ours[map[i]];
            let d = (o - r).norm();
            let kap = kappa[map[i]];
            if kap <= 1e4 {
                // simple, well-conditioned eigenvalue: perturbation theory gives kappa eps ||A||
                let tol = 1e-9 * r.norm() + 64.0 * kap * EPS * na;
                if d > tol {
                    return Err(format!("eigenvalue {i}: ours {o}, nalgebra {r}, |d| = {d:e} > {tol:e} (kappa {kap:e})"));
                }
                if kap < 1e3 {
                    seen.rel = seen.rel.max(d / r.norm().max(1e-6 * na));
                    seen.abs = seen.abs.max(d / na);
                }
            } else {
                // multiple, defective or ill-conditioned eigenvalue: ours and nalgebra's must lie in
                // the same component of the pseudospectrum {z : sigma_min(A - z I) <= 1e-11 ||A||}
                // (each is exact for a matrix within that distance of A), checked along the
                // segment between them
                for t in 1..16 {
                    let z = o + (r - o) * (t as f64 / 16.0);
                    let (smin, _, _) = shifted_svd(a, z);
                    if smin > 1e-11 * na {
                        return Err(format!(
                            "eigenvalue {i}: ours {o}, nalgebra {r}: sigma_min(A - z I) = {smin:e} at z = {z} between them (||A|| = {na:e})"
                        ));
                    }
                }
            }
        }
        Ok(seen)
    }

    fn dense_from(v: &[f64], scale: f64) -> M8 {
        std::array::from_fn(|r| std::array::from_fn(|c| v[8 * r + c] * scale))
    }

    /// A = V D V^-1 with D block diagonal: real eigenvalues, or 2 x 2 blocks [[a, b], [-b, a]]
    /// (a ± i b), and with `jordan` a 1 above the diagonal joining equal neighbours.
    fn similar(blocks: &[(bool, f64, f64)], vpert: &[f64], jordan: bool) -> (M8, Vec<C64>) {
        let mut d = [[0.0; 8]; 8];
        let mut exact = Vec::new();
        let mut i = 0;
        for &(cplx, a, b) in blocks {
            if i >= 8 {
                break;
            }
            if cplx && i + 1 < 8 {
                d[i][i] = a;
                d[i + 1][i + 1] = a;
                d[i][i + 1] = b;
                d[i + 1][i] = -b;
                exact.push(C64::new(a, b));
                exact.push(C64::new(a, -b));
                i += 2;
            } else {
                d[i][i] = a;
                exact.push(C64::new(a, 0.0));
                i += 1;
            }
        }
        if jordan {
            for i in 0..7 {
                if d[i][i] == d[i + 1][i + 1] && d[i][i + 1] == 0.0 && d[i + 1][i] == 0.0 {
                    // a 1 between equal real eigenvalues, or between two equal complex blocks
                    // (a coupling [[0, 0], [1, 0]], which is not in the range of X -> B X - X B)
                    d[i][i + 1] = 1.0;
                }
            }
        }
        let v = SMatrix::<f64, 8, 8>::from_fn(|r, c| if r == c { 1.0 } else { 0.0 } + 0.4 * vpert[8 * r + c]);
        let vi = v.try_inverse().unwrap();
        let a = v * to_na(&d) * vi;
        (std::array::from_fn(|r| std::array::from_fn(|c| a[(r, c)])), exact)
    }

    fn rotor_state(p: &[f64], kd: &[f64], cd: &[f64], x: &[f64], spin_r: f64, bal: bool) -> M8 {
        let (m, rg, ipr, l1, l2) = (p[0], p[1], p[2], p[3], p[4]);
        let it = m * (rg * (l1 + l2)).powi(2);
        let rotor = Rotor::from_slice(&[m, it, ipr * it, l1, l2]).unwrap();
        let (mut k, mut c) = ([0.0; 8], [0.0; 8]);
        for b in 0..2 {
            let (kx, ky) = (10f64.powf(kd[2 * b]), 10f64.powf(kd[2 * b + 1]));
            let (cx, cy) = (10f64.powf(cd[2 * b]), 10f64.powf(cd[2 * b + 1]));
            k[4 * b] = kx;
            k[4 * b + 3] = ky;
            k[4 * b + 1] = x[4 * b] * kx.min(ky);
            k[4 * b + 2] = x[4 * b + 1] * kx.min(ky);
            c[4 * b] = cx;
            c[4 * b + 3] = cy;
            c[4 * b + 1] = x[4 * b + 2] * cx.min(cy);
            c[4 * b + 2] = x[4 * b + 3] * cx.min(cy);
        }
        let mm = rotor.mass_matrix();
        let minv = Matrix4::from_fn(|r, c| mm[r][c]).try_inverse().unwrap();
        let (ka, ca) = (assemble(&k, l1, l2), assemble(&c, l1, l2));
        let spin = spin_r * (k[0] / m).sqrt();
        let mut a = state_matrix(&minv, &ka, &ca, &rotor.gyro_matrix(), spin);
        if bal {
            balance(&mut a);
        }
        std::array::from_fn(|r| std::array::from_fn(|c| a[(r, c)]))
    }

    fn assert_check(a: &M8) -> Seen {
        match check(a) {
            Ok(s) => s,
            Err(e) => panic!("{e}\nA = {a:?}"),
        }
    }

    fn exact_match(ours: &[C64; 8], exact: &[C64], tol: f64) -> Result<(), String> {
        let mut ex = [C64::new(0.0, 0.0); 8];
        ex[..exact.len()].copy_from_slice(exact);
        let map = matching(ours, &ex);
        for (i, e) in ex.iter().enumerate() {
            let d = (ours[map[i]] - e).norm();
            if d > tol {
                return Err(format!("exact {e}: ours {}, |d| = {d:e}", ours[map[i]]));
            }
        }
        Ok(())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(400))]

        /// Dense random matrices over six decades of scale.
        #[test]
        fn dense_matches_nalgebra(v in proptest::collection::vec(-1.0f64..1.0, 64), e in -3.0f64..3.0) {
            check(&dense_from(&v, 10f64.powf(e))).map_err(TestCaseError::fail)?;
        }

        /// Zero rows and columns (exact zero eigenvalues, reducible matrices).
        #[test]
        fn zero_rows_and_columns(v in proptest::collection::vec(-1.0f64..1.0, 64), rows in 0u8..=255, cols in 0u8..=255) {
            let mut a = dense_from(&v, 1.0);
            for i in 0..8 {
                if rows >> i & 1 == 1 && i % 2 == 0 {
                    a[i] = [0.0; 8];
                }
                if cols >> i & 1 == 1 && i % 3 == 0 {
                    for row in a.iter_mut() {
                        row[i] = 0.0;
                    }
                }
            }
            check(&a).map_err(TestCaseError::fail)?;
        }

        /// Rotor state matrices, balanced (as the modal analysis uses them) and raw (entries from
        /// ~1e-3 to ~1e8).
        #[test]
        fn rotor_state_matrices(m in 1.0f64..1000.0, rg in 0.1f64..0.6, ipr in 0.05f64..1.5, l1 in 0.05f64..1.0, l2 in 0.05f64..1.0,
                                kd in proptest::collection::vec(5.0f64..8.0, 4), cd in proptest::collection::vec(1.0f64..5.0, 4),
                                x in proptest::collection::vec(-0.5f64..0.5, 8), spin_r in 0.0f64..3.0) {
            let p = [m, rg, ipr, l1, l2];
            let a = rotor_state(&p, &kd, &cd, &x, spin_r, true);
            check(&a).map_err(TestCaseError::fail)?;
            let a = rotor_state(&p, &kd, &cd, &x, spin_r, false);
            check(&a).map_err(TestCaseError::fail)?;
        }

        /// Prescribed spectra with repeated real eigenvalues and repeated complex pairs, semisimple
        /// and defective (Jordan blocks).
        #[test]
        fn prescribed_spectra(blocks in proptest::collection::vec((any::<bool>(), 0usize..4, 1usize..3), 8),
                              vpert in proptest::collection::vec(-1.0f64..1.0, 64), jordan in any::<bool>()) {
            let re = [-2.0, -0.5, 0.0, 1.5];
            let b: Vec<(bool, f64, f64)> = blocks.iter().map(|&(c, r, i)| (c, re[r], i as f64)).collect();
            let (a, exact) = similar(&b, &vpert, jordan);
            check(&a).map_err(TestCaseError::fail)?;
            if !jordan {
                exact_match(&eigenvalues(&a).unwrap(), &exact, 1e-9 * fro(&a)).map_err(TestCaseError::fail)?;
            }
        }

        #[test]
        /// Two matrices through the interleaved iteration get the bits each gets alone, whatever
        /// their kinds (so whichever finishes first, with different deflation patterns and
        /// numbers of double steps), including a non-finite one.
        fn pair_gives_each_matrix_its_own_bits(va in proptest::collection::vec(-1.0f64..1.0, 64), vb in proptest::collection::vec(-1.0f64..1.0, 64),
                                               kinds in (0u8..5, 0u8..5), rows in 0u8..=255, p in proptest::collection::vec(0.1f64..0.6, 3),
                                               kd in proptest::collection::vec(5.0f64..8.0, 4), cd in proptest::collection::vec(1.0f64..5.0, 4),
                                               spin_r in 0.0f64..3.0) {
            let make = |kind: u8, v: &[f64]| -> M8 {
                match kind {
                    0 => dense_from(v, 1.0),
                    1 => {
                        // zero rows and columns: deflations at rounding level
                        let mut a = dense_from(v, 1.0);
                        for i in 0..8 {
                            if rows >> i & 1 == 1 {
                                a[i] = [0.0; 8];
                                for row in a.iter_mut() {
                                    row[i] = 0.0;
                                }
                            }
                        }
                        a
                    }
                    2 => rotor_state(&[30.0, p[0], p[1], p[2], 0.3], &kd, &cd, &v[..8], spin_r, true),
                    3 => {
                        // graded over 8 decades, unbalanced
                        let mut a = dense_from(v, 1.0);
                        for r in 0..8 {
                            for c in 0..8 {
                                a[r][c] *= 10f64.powi(r as i32 - c as i32);
                            }
                        }
                        a
                    }
                    _ => {
                        let mut a = dense_from(v, 1.0);
                        a[(rows % 8) as usize][3] = if rows % 2 == 0 { f64::NAN } else { f64::INFINITY };
                        a
                    }
                }
            };
            let (a, b) = (make(kinds.0, &va), make(kinds.1, &vb));
            let bits = |e: Option<[C64; 8]>| e.map(|e| e.map(|z| (z.re.to_bits(), z.im.to_bits())));
            let (pa, pb) = eigenvalues_pair(&a, &b);
            prop_assert_eq!(bits(pa), bits(eigenvalues(&a)));
            prop_assert_eq!(bits(pb), bits(eigenvalues(&b)));
            let (pb, pa) = eigenvalues_pair(&b, &a);
            prop_assert_eq!(bits(pa), bits(eigenvalues(&a)));
            prop_assert_eq!(bits(pb), bits(eigenvalues(&b)));
        }

        /// Graded matrices D A D^-1 (entries spanning up to 16 decades) with random complex pairs,
        /// balanced: same eigenvalues as A.
        #[test]
        fn graded_balanced(v in proptest::collection::vec(-1.0f64..1.0, 64), g in proptest::collection::vec(-4.0f64..4.0, 8)) {
            let mut a = dense_from(&v, 1.0);
            let plain = eigenvalues(&a).unwrap();
            for r in 0..8 {
                for c in 0..8 {
                    a[r][c] *= 10f64.powf(g[r] - g[c]);
                }
            }
            let mut na = to_na(&a);
            balance(&mut na);
            let a: M8 = std::array::from_fn(|r| std::array::from_fn(|c| na[(r, c)]));
            check(&a).map_err(TestCaseError::fail)?;
            let plain: Vec<C64> = plain.to_vec();
            exact_match(&eigenvalues(&a).unwrap(), &plain, 1e-9 * fro(&dense_from(&v, 1.0))).map_err(TestCaseError::fail)?;
        }
    }

    /// Largest differences with nalgebra over a fixed set of rotor and random matrices (printed with
    /// --nocapture).
    #[test]
    fn differences_with_nalgebra() {
        let (mut rotor, mut dense) = (Seen::default(), Seen::default());
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..2000 {
            let p = [1.0 + 999.0 * rnd(), 0.1 + 0.5 * rnd(), 0.05 + 1.45 * rnd(), 0.05 + 0.95 * rnd(), 0.05 + 0.95 * rnd()];
            let kd: Vec<f64> = (0..4).map(|_| 5.0 + 3.0 * rnd()).collect();
            let cd: Vec<f64> = (0..4).map(|_| 1.0 + 4.0 * rnd()).collect();
            let x: Vec<f64> = (0..8).map(|_| rnd() - 0.5).collect();
            let s = assert_check(&rotor_state(&p, &kd, &cd, &x, 3.0 * rnd(), true));
            rotor.rel = rotor.rel.max(s.rel);
            rotor.abs = rotor.abs.max(s.abs);
            let v: Vec<f64> = (0..64).map(|_| 2.0 * rnd() - 1.0).collect();
            let s = assert_check(&dense_from(&v, 1.0));
            dense.rel = dense.rel.max(s.rel);
            dense.abs = dense.abs.max(s.abs);
        }
        println!(
            "largest difference with nalgebra, balanced rotor state matrices: {:.2e} of |lambda|, {:.2e} of ||A||",
            rotor.rel, rotor.abs
        );
        println!(
            "largest difference with nalgebra, dense uniform matrices:        {:.2e} of |lambda|, {:.2e} of ||A||",
            dense.rel, dense.abs
        );
        assert!(rotor.rel < 1e-9 && dense.rel < 1e-9);
    }

    #[test]
    fn special_matrices() {
        // zero, identity, diagonal, triangular
        assert_check(&[[0.0; 8]; 8]);
        let id: M8 = std::array::from_fn(|r| std::array::from_fn(|c| if r == c { 1.0 } else { 0.0 }));
        assert_eq!(eigenvalues(&id).unwrap(), [C64::new(1.0, 0.0); 8]);
        let tri: M8 = std::array::from_fn(|r| std::array::from_fn(|c| if c >= r { (1 + r + 2 * c) as f64 } else { 0.0 }));
        let ev = eigenvalues(&tri).unwrap();
        exact_match(&ev, &(0..8).map(|r| C64::new((1 + 3 * r) as f64, 0.0)).collect::<Vec<_>>(), 0.0).unwrap();
        // cyclic permutation: the 8th roots of unity, where the standard shifts stall
        let mut p = [[0.0; 8]; 8];
        for r in 0..8 {
            p[(r + 1) % 8][r] = 1.0;
        }
        let ev = eigenvalues(&p).unwrap();
        let roots: Vec<C64> = (0..8).map(|t| C64::from_polar(1.0, std::f64::consts::PI * t as f64 / 4.0)).collect();
        exact_match(&ev, &roots, 1e-13).unwrap();
        assert_check(&p);
        // companion matrix of (x - 1)(x - 2)...(x - 8): ill-conditioned eigenvalues
        let mut coef = [1.0f64; 9]; // monic, coef[i] of x^i, built up root by root
        coef.iter_mut().for_each(|c| *c = 0.0);
        coef[0] = 1.0;
        for root in 1..=8 {
            for i in (0..=8).rev() {
                coef[i] = if i > 0 { coef[i - 1] } else { 0.0 } - root as f64 * coef[i];
            }
        }
        let mut comp = [[0.0; 8]; 8];
        for r in 1..8 {
            comp[r][r - 1] = 1.0;
        }
        for r in 0..8 {
            comp[r][7] = -coef[r];
        }
        let ev = eigenvalues(&comp).unwrap();
        exact_match(&ev, &(1..=8).map(|r| C64::new(r as f64, 0.0)).collect::<Vec<_>>(), 1e-6).unwrap();
        assert_check(&comp);
        // Hessenberg input with tiny subdiagonal entries (deflation), and an already split matrix
        let h: M8 = std::array::from_fn(|r| {
            std::array::from_fn(|c| if c + 1 >= r { ((r * 7 + c * 3) % 5) as f64 - 2.0 + if r == c { r as f64 } else { 0.0 } } else { 0.0 })
        });
        let mut h = h;
        h[3][2] = 1e-20;
        h[6][5] = 0.0;
        assert_check(&h);
        // three zero rows and columns: a defective zero eigenvalue behind subdiagonal entries at
        // rounding level (QR sweeps started at the top of the window do not converge here)
        let zr: M8 = [
            [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            [0.0, -0.8160921449050983, 0.3001482392034264, 0.0, -0.6945583087952119, -0.3857636986314645, 0.0, -0.7283717426334138],
            [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            [0.0, 0.44599032291744584, -0.5841442474583742, 0.0, -0.9751976915369347, -0.5484005667622428, 0.0, 0.717418628276643],
            [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            [0.0, 0.8124820755862315, 0.5778908498772457, 0.0, -0.8181970811867512, -0.76782586402353, 0.0, 0.7961935564761261],
            [0.0, -0.9257552912109521, 0.1177724111308266, 0.0, 0.10366162498629064, 0.6017946581884452, 0.0, -0.5383923460774156],
            [0.0, -0.4002453450444713, 0.5346595737472334, 0.0, 0.5317572980900525, -0.5106979944969907, 0.0, -0.790054417682752],
        ];
        assert_check(&zr);
        // zero rows 0, 2, 4 and columns 3, 6: after two deflations a nearly nilpotent 4 x 4 window
        // (entries ~1e-8) on which the shifts stall; converges with exceptional shifts every 10 steps
        let v: [f64; 64] = [
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.1610384178490016,
            -0.2397593968491066,
            -0.7852030599843699,
            0.0,
            -0.3900908648781167,
            -0.8419996725965303,
            0.0,
            -0.03919948580870205,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.754598372177727,
            0.2702727823216238,
            -0.671816375206717,
            0.0,
            0.9641319768104342,
            0.7769990323591174,
            0.0,
            0.022694647176355363,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            -0.33160275017398316,
            0.6013722485831201,
            -0.3125991986347108,
            0.0,
            -0.3359725767794092,
            0.6733422793417703,
            0.0,
            0.44723095596195006,
            -0.18312043417260476,
            -0.9379232426704429,
            -0.3750406727658152,
            0.0,
            -0.93819059704086,
            -0.7835876675732112,
            0.0,
            0.8594265030285282,
            0.1764115776704395,
            0.9358052598466312,
            0.6103188154148698,
            0.0,
            0.4347131049132219,
            -0.6009816260441044,
            0.0,
            0.6738284923556083,
        ];
        let mut a = dense_from(&v, 1.0);
        for row in a.iter_mut() {
            row[3] = 0.0;
            row[6] = 0.0;
        }
        assert_check(&a);
        // two 2 x 2 Jordan blocks (eigenvalues 1.5 and -0.5) in one window: standard shifts {1.5, -0.5}
        // never converge, the nearer real shift taken twice does
        let re = [-2.0, -0.5, 0.0, 1.5];
        let blocks = [(false, 1, 1), (false, 1, 1), (true, 0, 1), (true, 3, 2), (false, 3, 1), (false, 3, 1), (false, 0, 1), (false, 0, 1)];
        let blocks: Vec<(bool, f64, f64)> = blocks.iter().map(|&(c, r, i)| (c, re[r], i as f64)).collect();
        let (a, _) = similar(
            &blocks,
            &[
                -0.34578090418869245,
                -0.3930657117732974,
                -0.04308799239382577,
                0.1419696242012475,
                -0.18948683887203388,
                0.5547335565247765,
                -0.24070494333194323,
                -0.4688866178047188,
                0.024373521382383686,
                0.9142173769014506,
                -0.5803551794514905,
                0.3100730262512769,
                0.17828780628450086,
                0.0013142840384980422,
                -0.43090918622026897,
                0.12809137817452732,
                -0.07997605921322992,
                0.6744715696419454,
                -0.5346247595126319,
                0.4721561883795879,
                -0.5172331993172651,
                -0.2950033470735896,
                -0.9001966566269832,
                -0.03270068205694174,
                0.2405100229195007,
                0.834473806661574,
                0.8579994013421579,
                0.19839556832694472,
                0.9133956295948611,
                -0.5149408992099624,
                -0.9200554656703617,
                -0.4247081776815766,
                0.12457316046905101,
                0.304414514867347,
                0.7002857971214872,
                0.9522001762328144,
                0.07230673506566845,
                0.28609257150662526,
                -0.7778381763336164,
                0.5780647994661057,
                -0.3399208556560011,
                -0.5428628182987267,
                0.9460240606074359,
                0.005611501271545417,
                -0.9021441083921431,
                -0.7273672735726474,
                0.22720915249816195,
                -0.7624252551275936,
                -0.4826156015188157,
                0.0202567687774676,
                -0.23660285575782508,
                -0.28989498357688137,
                0.8686296883382794,
                -0.9587228204119127,
                0.2310845818979128,
                -0.1300395682611349,
                -0.043207222690091175,
                0.08745917516832741,
                0.49068220459821693,
                0.8497651495696715,
                -0.004468663668111907,
                -0.7840789212796645,
                0.16248057657659987,
                0.683907363785766,
            ],
            true,
        );
        assert_check(&a);
        // extreme scales (the power-of-two pre-scaling and the rescaled reflectors): the eigenvalues
        // scale with the matrix
        let v: Vec<f64> = (0..64).map(|i| ((i * 37 % 17) as f64 - 8.0) / 8.0).collect();
        let base = dense_from(&v, 1.0);
        let ev0 = eigenvalues(&base).unwrap();
        for e in [-1000, -830, -400, 400, 830, 1000] {
            let f = 2f64.powi(e);
            let ev = eigenvalues(&dense_from(&v, f)).unwrap();
            let scaled: Vec<C64> = ev0.iter().map(|z| z * f).collect();
            exact_match(&ev, &scaled, 1e-12 * f * fro(&base)).unwrap();
        }
        // hqr on a Hessenberg matrix with garbage below the subdiagonal
        let mut h = base;
        hessenberg(&mut h);
        for (i, row) in h.iter_mut().enumerate().skip(2) {
            row[0] = 1e3 * i as f64;
        }
        exact_match(&hqr(&mut h).unwrap(), &ev0, 1e-12 * fro(&base)).unwrap();
        // non-finite input
        let mut bad = id;
        bad[2][3] = f64::NAN;
        assert!(eigenvalues(&bad).is_none());
    }

    /// A matrix that runs out of its budget of double steps in the middle of the interleaved
    /// iteration gets None, as alone, and the other matrix still gets its own bits.
    #[test]
    fn pair_when_one_matrix_runs_out_of_its_budget() {
        let va: Vec<f64> = (0..64).map(|i| ((i * 37 + 11) % 23) as f64 / 11.0 - 1.0).collect();
        let vb: Vec<f64> = (0..64).map(|i| ((i * 53 + 5) % 29) as f64 / 14.0 - 1.0).collect();
        let (a, b) = (dense_from(&va, 1.0), dense_from(&vb, 1.0));
        let bits = |e: Option<[C64; 8]>| e.map(|e| e.map(|z| (z.re.to_bits(), z.im.to_bits())));
        let budget = Francis::<8>::BUDGET;
        assert_eq!(budget, 300);
        for used in [budget - 2, budget - 1, budget] {
            let (mut ha, mut hb) = (a, b);
            hessenberg(&mut ha);
            hessenberg(&mut hb);
            let (mut ha2, mut hb2) = (ha, hb);
            let mut qa = Francis::new(&mut ha);
            qa.its = used;
            let (pa, pb) = pair(qa, Francis::new(&mut hb));
            let mut qa2 = Francis::new(&mut ha2);
            qa2.its = used;
            assert_eq!(bits(pa), bits(alone(qa2)), "{used} steps used");
            assert!(pa.is_none(), "{used} steps used: converged anyway");
            assert_eq!(bits(pb), bits(eigenvalues(&b)));
            // the other way round: the failing matrix second
            let mut ha3 = a;
            hessenberg(&mut ha3);
            let mut qa3 = Francis::new(&mut ha3);
            qa3.its = used;
            let (pb2, pa2) = pair(Francis::new(&mut hb2), qa3);
            assert!(pa2.is_none());
            assert_eq!(bits(pb2), bits(eigenvalues(&b)));
        }
    }

    #[test]
    fn other_sizes() {
        assert_eq!(eigenvalues::<0>(&[]).unwrap().len(), 0);
        assert_eq!(eigenvalues(&[[-3.5]]).unwrap(), [C64::new(-3.5, 0.0)]);
        // 2 x 2: complex pair 1 ± 2i and a real pair with cancellation-prone roots
        let ev = eigenvalues(&[[1.0, -4.0], [1.0, 1.0]]).unwrap();
        assert!((ev[0] - C64::new(1.0, 2.0)).norm() < 1e-15 && (ev[1] - C64::new(1.0, -2.0)).norm() < 1e-15);
        let ev = eigenvalues(&[[1e8, 1.0], [1.0, 0.0]]).unwrap();
        let small = ev.iter().map(|z| z.re).fold(f64::INFINITY, f64::min);
        assert!((small + 1e-8).abs() < 1e-22, "{small:e}");
        // 5 x 5 with known spectrum: tridiagonal Toeplitz [1, 2, 1] has 2 + 2 cos(k pi / 6)
        let t: [[f64; 5]; 5] = std::array::from_fn(|r| {
            std::array::from_fn(|c| match r.abs_diff(c) {
                0 => 2.0,
                1 => 1.0,
                _ => 0.0,
            })
        });
        let mut ev: Vec<f64> = eigenvalues(&t).unwrap().iter().map(|z| z.re).collect();
        ev.sort_by(f64::total_cmp);
        for (k, e) in ev.iter().enumerate() {
            let exact = 2.0 + 2.0 * (std::f64::consts::PI * (5 - k) as f64 / 6.0).cos();
            assert!((e - exact).abs() < 1e-14, "{e} vs {exact}");
        }
        // the interleaved pair at other sizes: each matrix's own bits
        let bits = |e: &[C64]| e.iter().map(|z| (z.re.to_bits(), z.im.to_bits())).collect::<Vec<_>>();
        let (pa, pb) = eigenvalues_pair(&t, &[[0.0; 5]; 5]);
        assert_eq!(bits(&pa.unwrap()), bits(&eigenvalues(&t).unwrap()));
        assert_eq!(bits(&pb.unwrap()), bits(&[C64::new(0.0, 0.0); 5]));
        let (pa, pb) = eigenvalues_pair(&[[1.0, -4.0], [1.0, 1.0]], &[[1e8, 1.0], [1.0, 0.0]]);
        assert_eq!(bits(&pa.unwrap()), bits(&eigenvalues(&[[1.0, -4.0], [1.0, 1.0]]).unwrap()));
        assert_eq!(bits(&pb.unwrap()), bits(&eigenvalues(&[[1e8, 1.0], [1.0, 0.0]]).unwrap()));
        assert_eq!(eigenvalues_pair::<0>(&[], &[]), (Some([]), Some([])));
        // 16 x 16 dense against its trace and the 8 x 8 case's machinery via the residual
        let a: [[f64; 16]; 16] = std::array::from_fn(|r| std::array::from_fn(|c| ((r * 31 + c * 17) % 13) as f64 - 6.0));
        let ev = eigenvalues(&a).unwrap();
        let tr: f64 = (0..16).map(|i| a[i][i]).sum();
        let a2: [[f64; 16]; 16] = std::array::from_fn(|r| std::array::from_fn(|c| ((r * 7 + c * 29) % 11) as f64 - 5.0));
        let (pa, pb) = eigenvalues_pair(&a, &a2);
        assert_eq!(bits(&pa.unwrap()), bits(&ev));
        assert_eq!(bits(&pb.unwrap()), bits(&eigenvalues(&a2).unwrap()));
        let s: C64 = ev.iter().sum();
        assert!((s.re - tr).abs() < 1e-11 * 16.0 * 13.0 && s.im.abs() < 1e-11);
    }
}
