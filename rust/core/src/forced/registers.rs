//! The forced response's common case on SIMD registers: one right-hand side, the bearing
//! coefficients shared by every point (the imbalance response and the impact FRF of a rotor on
//! its bearings). `N` points per group, every value of the group in one register of [`Regs`],
//! where the lane loops of [`super::factor_solve_lanes`] keep their values in lane arrays that
//! LLVM's vectorizer loads and stores around each operation. Used with AVX-512's 32 registers
//! (8 points per `__m512d`), where the group's 4 x 4 complex matrix fits: 14.5 -> 12.0 ns per
//! point for an imbalance response, one thread (`examples/forced_points 4096 2000 imbalance`,
//! best of 5 interleaved runs, AMD EPYC of family 26). With AVX2's 16 it spills and was slower
//! than the lanes (18.0 against 16.1 ns); two groups in alternation, to overlap their chains of
//! divisions, spilled at AVX-512 too (16.7 against 13.3 ns).
//!
//! What bounds it: each group is one chain of dependent steps (four pivots, each a division, then
//! four back substitutions), 280-350 cycles by an estimate from the operations' latencies against
//! the ~390 measured per group of 8.
//!
//! Each lane performs the operations of [`super::dynamic_stiffness`] and of the exchange-free
//! elimination ([`super::elim_step`] with `EXCHANGE` false, rows in the order (Fx, Mx, Fy, My)),
//! its substitution and [`super::Batch::finish`], in their order and without fused multiply-adds,
//! so every lane holds the lane path's bits (those of the per-point solution up to the sign of an
//! exact zero: [`super::solve4`] skips zero multipliers). A group in which some lane needs a row
//! exchange (a candidate below the diagonal not smaller than the diagonal's pivot), or whose
//! matrix holds a non-finite number, is handed whole to the lane path (`rest`), as is a chunk's
//! last, partial group: the lane path decides those exactly as before. (A non-finite point now
//! sends the 8 points of its register group to the per-point path, where the lane path's groups
//! are 16: the points between differ from before at most in the sign of an exact zero.)
//!
//! Like [`crate::identify::registers`], everything here is `#[inline(always)]` and compiled only
//! inside the `#[target_feature]` functions of [`super`], with plain loops around the intrinsics.

use super::{Batch, Gain, MAX_SPREAD};
use crate::identify::registers::{add, mul as cmul, scale as cscale, sub as csub, Regs, C};
use crate::model::{assemble, C64};

/// Whether the register kernel serves `b`: one right-hand side, and stiffness and damping shared
/// by every point.
#[inline(always)]
pub(super) fn serves(b: &Batch) -> bool {
    b.nrhs == 1 && b.kbc && b.cbc
}

/// |re| + |im| (the pivot measure of [`super::solve4`])
#[inline(always)]
unsafe fn mag<const N: usize, R: Regs<N>>(z: C<R::V>) -> R::V {
    R::add(R::abs(z.re), R::abs(z.im))
}

/// `if x > y { x } else { y }` (y for NaN and ties)
#[inline(always)]
unsafe fn keep_greater<const N: usize, R: Regs<N>>(x: R::V, y: R::V) -> R::V {
    R::blend(x, y, R::not_gt(x, y))
}

/// `if x < y { x } else { y }` (y for NaN and ties)
#[inline(always)]
unsafe fn keep_less<const N: usize, R: Regs<N>>(x: R::V, y: R::V) -> R::V {
    R::blend(x, y, R::not_lt(x, y))
}

/// The points `start..start + out.len() / 4` of `b` (which [`serves`]), `N` at a time on
/// registers; `rest(first, out)` solves the points `first..` of its `out` on the lane path and
/// returns how many are singular. Returns the number of singular points.
#[inline(always)]
// index loops, not iterator adapters, around the intrinsics (see the module's documentation)
#[allow(clippy::needless_range_loop)]
pub(super) unsafe fn forced_chunk<const N: usize, R: Regs<N>>(b: &Batch, start: usize, out: &mut [C64], rest: impl Fn(usize, &mut [C64]) -> usize) -> usize {
    debug_assert!(serves(b));
    let npts = out.len() / 4;
    let sp = |x: f64| R::splat(x);
    let zero = sp(0.0);
    let (l1, l2) = (b.rotor.l1, b.rotor.l2);
    // K, C, M and G of every lane: assembled once (the same operations give the same values in
    // every lane)
    let (ka, ca) = (assemble(&b.kb[..8], l1, l2), assemble(&b.cb[..8], l1, l2));
    let mut k = [[zero; 4]; 4];
    let mut c = [[zero; 4]; 4];
    let mut m = [[zero; 4]; 4];
    let mut g = [[zero; 4]; 4];
    for i in 0..4 {
        for j in 0..4 {
            (k[i][j], c[i][j], m[i][j], g[i][j]) = (sp(ka[i][j]), sp(ca[i][j]), sp(b.m[i][j]), sp(b.g[i][j]));
        }
    }
    let zc = C { re: zero, im: zero };
    let mut f_shared = [zc; 4];
    if b.fbc {
        for d in 0..4 {
            f_shared[d] = C { re: sp(b.force[d].re), im: sp(b.force[d].im) };
        }
    }
    let planes = b.planes.map(|t| [sp(t[0]), sp(t[1]), sp(t[2]), sp(t[3])]);
    let (tiny_factor, spread, one, nan) = (sp(1e-15), sp(MAX_SPREAD), sp(1.0), sp(f64::NAN));
    let whole = npts - npts % N;
    let mut nbad = 0;
    for g0 in (0..whole).step_by(N) {
        let i0 = start + g0;
        let w = R::load(b.w[i0..i0 + N].as_ptr());
        let spin = R::load(b.spin[i0..i0 + N].as_ptr());
        // H = K - w^2 M + j w (C + Omega G), as dynamic_stiffness: (w w) m, (w Omega) g + w c
        let (ww, ws) = (R::mul(w, w), R::mul(w, spin));
        let mut h = [[zc; 4]; 4];
        for i in 0..4 {
            for j in 0..4 {
                h[i][j] = C { re: R::sub(k[i][j], R::mul(ww, m[i][j])), im: R::add(R::mul(ws, g[i][j]), R::mul(w, c[i][j])) };
            }
        }
        let f = if b.fbc {
            f_shared
        } else {
            let mut f = [zc; 4];
            for d in 0..4 {
                f[d] = C { re: R::lanes_of(|l| b.force[4 * (i0 + l) + d].re), im: R::lanes_of(|l| b.force[4 * (i0 + l) + d].im) };
            }
            f
        };
        // Elim::new: the largest |re| + |im| and their sum, row by row
        let (mut scale, mut total) = (zero, zero);
        for row in &h {
            for &v in row {
                let mv = mag::<N, R>(v);
                scale = keep_greater::<N, R>(mv, scale);
                total = R::add(total, mv);
            }
        }
        let tiny = R::mul(scale, tiny_factor);
        // rows (Fx, Mx, Fy, My): the diagonal pivots of a rotor on bearings
        let mut a = [h[0], h[2], h[1], h[3]];
        let mut x = [f[0], f[2], f[1], f[3]];
        let (mut pmin, mut pmax) = (sp(f64::INFINITY), zero);
        let mut ins = [zero; 4];
        // no lane yet (NaN == NaN is false)
        let (mut exchange, mut bad) = (R::eq(nan, nan), R::eq(nan, nan));
        for kk in 0..4 {
            let diag = mag::<N, R>(a[kk][kk]);
            for row in a.iter().skip(kk + 1) {
                exchange = R::m_or(exchange, R::not_lt(mag::<N, R>(row[kk]), diag));
            }
            pmin = keep_less::<N, R>(diag, pmin);
            pmax = keep_greater::<N, R>(diag, pmax);
            let spread_low = R::m_not(R::not_lt(pmin, R::mul(spread, pmax)));
            bad = R::m_or(bad, R::m_or(R::not_gt(diag, tiny), spread_low));
            let d = a[kk][kk];
            let s = R::div(one, R::add(R::mul(d.re, d.re), R::mul(d.im, d.im)));
            ins[kk] = s;
            let inv = C { re: R::mul(d.re, s), im: R::sub(zero, R::mul(d.im, s)) };
            for i in kk + 1..4 {
                let fi = cmul::<N, R>(a[i][kk], inv);
                a[i][kk] = fi;
                for j in kk + 1..4 {
                    a[i][j] = csub::<N, R>(a[i][j], cmul::<N, R>(fi, a[kk][j]));
                }
            }
        }
        if R::m_bits(R::m_or(exchange, R::m_not(R::finite(total)))) != 0 {
            #[cfg(test)]
            super::tests::GROUPS_TO_LANES.with(|c| c.set(c.get() + 1));
            nbad += rest(i0, &mut out[4 * g0..4 * (g0 + N)]);
            continue;
        }
        #[cfg(test)]
        super::tests::REGISTER_GROUPS.with(|c| c.set(c.get() + 1));
        // the substitutions of `substitute` without exchanges
        for kk in 0..3 {
            for i in kk + 1..4 {
                x[i] = csub::<N, R>(x[i], cmul::<N, R>(a[i][kk], x[kk]));
            }
        }
        for kk in (0..4).rev() {
            let mut s = x[kk];
            for j in kk + 1..4 {
                s = csub::<N, R>(s, cmul::<N, R>(a[kk][j], x[j]));
            }
            let (cr, di) = (a[kk][kk].re, a[kk][kk].im);
            x[kk] = C {
                re: R::mul(R::add(R::mul(s.re, cr), R::mul(s.im, di)), ins[kk]),
                im: R::mul(R::sub(R::mul(s.im, cr), R::mul(s.re, di)), ins[kk]),
            };
        }
        // Batch::finish: the gain, then the plane transform
        let gain = match b.gain {
            Gain::One => None,
            Gain::PerPoint(gv) => Some(R::load(gv[i0..i0 + N].as_ptr())),
            Gain::SpinSquared => Some(R::mul(spin, spin)),
        };
        if let Some(gv) = gain {
            for d in 0..4 {
                x[d] = cscale::<N, R>(x[d], gv);
            }
        }
        if let Some(t) = &planes {
            let sc = |v: C<R::V>, s: R::V| cscale::<N, R>(v, s);
            let ad = |u: C<R::V>, v: C<R::V>| add::<N, R>(u, v);
            x = [
                ad(sc(x[0], t[0]), sc(x[1], t[1])),
                ad(sc(x[0], t[2]), sc(x[1], t[3])),
                ad(sc(x[2], t[0]), sc(x[3], t[1])),
                ad(sc(x[2], t[2]), sc(x[3], t[3])),
            ];
        }
        let mut rows = [zero; 8];
        for d in 0..4 {
            rows[2 * d] = R::blend(x[d].re, nan, bad);
            rows[2 * d + 1] = R::blend(x[d].im, nan, bad);
        }
        let group = &mut out[4 * g0..4 * (g0 + N)];
        // SAFETY: Complex<f64> is repr(C) {re, im}: the group's points as (N, 8) doubles
        let group = std::slice::from_raw_parts_mut(group.as_mut_ptr() as *mut f64, 8 * N);
        R::put_rows(group, 0, N, &rows);
        let bits = R::m_bits(bad);
        if bits != 0 {
            nbad += bits.count_ones() as usize;
        }
    }
    if whole < npts {
        nbad += rest(start + whole, &mut out[4 * whole..]);
    }
    nbad
}
