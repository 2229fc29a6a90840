//! The bearing-force kernel of [`super::forces_chunk`] written on AVX2 registers: 4 points per
//! group, every value of the group in a `__m256d`.
//!
//! It performs the generic kernel's operations in the generic kernel's order (separate multiplies
//! and adds, no fused multiply-add), so its outputs are bit for bit those of the 2-lane baseline
//! (NaN for NaN: which NaN an operation on two NaNs returns depends on operand order, which IEEE
//! leaves open). The property test below and CI's `examples/bit_digest` compare them. What
//! differs is the data movement, which the generic kernel leaves to LLVM and which cost more
//! instructions than its arithmetic:
//! - inputs: each point's four complex responses are two 256-bit loads; a 4 x 4 transpose
//!   (unpack + 128-bit permute) turns four points into the lane vectors x_re, x_im, ...;
//! - outputs: k, c and their standard errors leave as 4 x 4 transposes and 256-bit stores, cond as
//!   an interleave, residual and amplitude as one store each; the flags that choose NaN or inf
//!   are lane masks, not per-lane branches;
//! - groups that wrap across batch rows or end a chunk read their points through per-lane
//!   pointers and write through a scratch block, so one code path serves every group.
//!
//! The bearing systems are solved on registers too: two rows (two runs, the impact case) by
//! Cramer's rule inlined in the group loop, more by the corrected semi-normal equations
//! ([`super::solve_lanes`]'s operations), whose row loops run once per right-hand side so that
//! their accumulators fit the 16 registers. Instructions per point (callgrind on
//! `examples/identify_points 4096 5 nostd R`, kernel and solver) and time per point (one thread,
//! best of 10 interleaved runs) against the generic kernel on AVX2: 2 runs 571 -> 346 and 46.3
//! -> 27.0 ns, 4 runs 1,181 -> 851 and 86.7 -> 63.4 ns. Tried and dropped: the same code with
//! AVX-512VL's 32 registers (no faster: 63.5 against 62.9 ns with 4 runs, 25.3 against 27.0
//! with 2), and the lane pointers in a function of their own (inlined, 4 runs took 74 ns).

use super::{givens_lane, relative_std_rows, Consts, IdentProblem, LaneSol, Outs, CSNE_COND, SINGULAR_COND};
use crate::lanes::{V, Z};
use std::arch::x86_64::*;

const N: usize = 4;

#[inline(always)]
fn mv(x: V<N>) -> __m256d {
    // SAFETY: V<4> is repr(transparent) over [f64; 4], the same 32 bytes as __m256d
    unsafe { std::mem::transmute::<V<N>, __m256d>(x) }
}

#[inline(always)]
fn vm(x: __m256d) -> V<N> {
    // SAFETY: as in `mv`
    unsafe { std::mem::transmute::<__m256d, V<N>>(x) }
}

/// A complex lane vector in registers (`repr(C)`: the layout of a `Z<4>`, more strictly aligned).
#[derive(Clone, Copy)]
#[repr(C)]
struct C {
    re: __m256d,
    im: __m256d,
}

#[target_feature(enable = "avx2,fma")]
#[inline]
fn zc(c: C) -> Z<N> {
    Z { re: vm(c.re), im: vm(c.im) }
}

// The operations of lanes.rs, in the same order.
#[target_feature(enable = "avx2,fma")]
#[inline]
fn add(a: C, b: C) -> C {
    C { re: _mm256_add_pd(a.re, b.re), im: _mm256_add_pd(a.im, b.im) }
}
#[target_feature(enable = "avx2,fma")]
#[inline]
fn sub(a: C, b: C) -> C {
    C { re: _mm256_sub_pd(a.re, b.re), im: _mm256_sub_pd(a.im, b.im) }
}
#[target_feature(enable = "avx2,fma")]
#[inline]
fn scale(a: C, s: __m256d) -> C {
    C { re: _mm256_mul_pd(a.re, s), im: _mm256_mul_pd(a.im, s) }
}
/// j s a = (-(a.im s), a.re s); subtracting it is adding a.im s to the real part (x - (-y) and
/// x + y are the same IEEE operation).
#[target_feature(enable = "avx2,fma")]
#[inline]
fn sub_jscale(x: C, a: C, s: __m256d) -> C {
    C { re: _mm256_add_pd(x.re, _mm256_mul_pd(a.im, s)), im: _mm256_sub_pd(x.im, _mm256_mul_pd(a.re, s)) }
}

/// 4 x 4 transpose of doubles: row l of the output is lane l of the inputs.
#[target_feature(enable = "avx2,fma")]
#[inline]
fn transpose(a: [__m256d; 4]) -> [__m256d; 4] {
    let t0 = _mm256_unpacklo_pd(a[0], a[1]);
    let t1 = _mm256_unpackhi_pd(a[0], a[1]);
    let t2 = _mm256_unpacklo_pd(a[2], a[3]);
    let t3 = _mm256_unpackhi_pd(a[2], a[3]);
    [
        _mm256_permute2f128_pd::<0x20>(t0, t2),
        _mm256_permute2f128_pd::<0x20>(t1, t3),
        _mm256_permute2f128_pd::<0x31>(t0, t2),
        _mm256_permute2f128_pd::<0x31>(t1, t3),
    ]
}

/// The four complex values at each of four points (pointers to [x1, x2, y1, y2]) as lane vectors.
///
/// # Safety
/// Each pointer must be valid for 8 doubles.
#[target_feature(enable = "avx2,fma")]
#[inline]
unsafe fn load_points(ptr: [*const f64; N]) -> [C; 4] {
    let lo = transpose([_mm256_loadu_pd(ptr[0]), _mm256_loadu_pd(ptr[1]), _mm256_loadu_pd(ptr[2]), _mm256_loadu_pd(ptr[3])]);
    let hi = transpose([
        _mm256_loadu_pd(ptr[0].add(4)),
        _mm256_loadu_pd(ptr[1].add(4)),
        _mm256_loadu_pd(ptr[2].add(4)),
        _mm256_loadu_pd(ptr[3].add(4)),
    ]);
    [C { re: lo[0], im: lo[1] }, C { re: lo[2], im: lo[3] }, C { re: hi[0], im: hi[1] }, C { re: hi[2], im: hi[3] }]
}

#[target_feature(enable = "avx2,fma")]
#[inline]
fn norm_sqr(a: C) -> __m256d {
    _mm256_add_pd(_mm256_mul_pd(a.re, a.re), _mm256_mul_pd(a.im, a.im))
}
/// a b
#[target_feature(enable = "avx2,fma")]
#[inline]
fn mul(a: C, b: C) -> C {
    C {
        re: _mm256_sub_pd(_mm256_mul_pd(a.re, b.re), _mm256_mul_pd(a.im, b.im)),
        im: _mm256_add_pd(_mm256_mul_pd(a.re, b.im), _mm256_mul_pd(a.im, b.re)),
    }
}
/// conj(a) b
#[target_feature(enable = "avx2,fma")]
#[inline]
fn cmul(a: C, b: C) -> C {
    C {
        re: _mm256_add_pd(_mm256_mul_pd(a.re, b.re), _mm256_mul_pd(a.im, b.im)),
        im: _mm256_sub_pd(_mm256_mul_pd(a.re, b.im), _mm256_mul_pd(a.im, b.re)),
    }
}
#[target_feature(enable = "avx2,fma")]
#[inline]
fn conj(a: C) -> C {
    C { re: a.re, im: _mm256_xor_pd(a.im, _mm256_set1_pd(-0.0)) }
}

/// [`LaneSol`] in registers.
#[derive(Clone, Copy)]
struct Sol {
    z: [[C; 2]; 2],
    g: [__m256d; 2],
    cond: __m256d,
    res2: [__m256d; 2],
    rhs2: [__m256d; 2],
    total: __m256d,
    qq: __m256d,
}

impl Sol {
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    fn to_lanes(self) -> LaneSol<N> {
        let z = self.z.map(|r| r.map(|c| zc(c)));
        LaneSol { z, g: self.g.map(vm), cond: vm(self.cond), res2: self.res2.map(vm), rhs2: self.rhs2.map(vm), total: vm(self.total), qq: vm(self.qq) }
    }

    #[target_feature(enable = "avx2,fma")]
    #[inline]
    fn from_lanes(s: &LaneSol<N>) -> Sol {
        let z = s.z.map(|r| r.map(|v| C { re: mv(v.re), im: mv(v.im) }));
        Sol { z, g: s.g.map(mv), cond: mv(s.cond), res2: s.res2.map(mv), rhs2: s.rhs2.map(mv), total: mv(s.total), qq: mv(s.qq) }
    }
}

/// Rows of C as the generic kernel's rows (for the Givens fallback).
fn as_lane_rows(rows: &[[C; 4]]) -> &[[Z<N>; 4]] {
    // SAFETY: C is repr(C) with the two 32-byte vectors of a repr(C) Z<4> (V<4> is
    // repr(transparent) over [f64; 4]); C's alignment (32) is stricter than Z<4>'s (8)
    unsafe { std::slice::from_raw_parts(rows.as_ptr() as *const [Z<N>; 4], rows.len()) }
}

/// [`super::solve_square`] on registers: Cramer's rule for two rows [x, y, f_0, f_1].
///
/// # Safety
/// Only for CPUs with AVX2 (an `unsafe fn` rather than `#[target_feature]`, so that it can be
/// `inline(always)`: left to itself LLVM called it and passed its solution through memory).
#[inline(always)]
unsafe fn solve_square(r0: &[C; 4], r1: &[C; 4]) -> Sol {
    let sp = _mm256_set1_pd;
    let det = sub(mul(r0[0], r1[1]), mul(r1[0], r0[1]));
    let dn2 = norm_sqr(det);
    let a = _mm256_add_pd(norm_sqr(r0[0]), norm_sqr(r1[0]));
    let d = _mm256_add_pd(norm_sqr(r0[1]), norm_sqr(r1[1]));
    let fro = _mm256_add_pd(a, d);
    let idn = _mm256_div_pd(sp(1.0), dn2);
    let inv = scale(conj(det), idn);
    let mut z = [[r0[0]; 2]; 2];
    let mut rhs2 = [fro; 2];
    for k in 0..2 {
        let (f0, f1) = (r0[2 + k], r1[2 + k]);
        z[k][0] = mul(sub(mul(r1[1], f0), mul(r0[1], f1)), inv);
        z[k][1] = mul(sub(mul(r0[0], f1), mul(r1[0], f0)), inv);
        rhs2[k] = _mm256_add_pd(norm_sqr(f0), norm_sqr(f1));
    }
    let adet = _mm256_sqrt_pd(dn2);
    let disc = _mm256_sqrt_pd(_mm256_sub_pd(_mm256_mul_pd(fro, fro), _mm256_mul_pd(sp(4.0), dn2)));
    let cond = _mm256_mul_pd(_mm256_add_pd(fro, disc), _mm256_div_pd(sp(1.0), _mm256_mul_pd(sp(2.0), adet)));
    let zero = _mm256_setzero_pd();
    let total = _mm256_add_pd(_mm256_add_pd(fro, rhs2[0]), rhs2[1]);
    Sol { z, g: [_mm256_mul_pd(d, idn), _mm256_mul_pd(a, idn)], cond, res2: [zero; 2], rhs2, total, qq: fro }
}

/// [`super::solve_gram`] on registers.
#[target_feature(enable = "avx2,fma")]
#[inline]
fn solve_gram(v: [C; 2], a: __m256d, d: __m256d, gxy: C, gc: C, idet: __m256d) -> [C; 2] {
    [scale(sub(scale(v[0], d), mul(gxy, v[1])), idet), scale(sub(scale(v[1], a), mul(gc, v[0])), idet)]
}

/// [`super::solve_lanes`] on registers for more than two rows: the corrected semi-normal
/// equations.
#[target_feature(enable = "avx2,fma")]
#[inline]
fn solve(rows: &[[C; 4]], out: &mut Sol) {
    let sp = _mm256_set1_pd;
    let zero = _mm256_setzero_pd();
    let zc0 = C { re: zero, im: zero };
    // The row loops run once per right-hand side, each with the accumulators that side needs
    // (9 and 5 values, then 9 twice): together they are 22 and 26 registers, over AVX2's 16, and
    // the single loops spilled them. Each sum still adds the rows in order: the same bits.
    let (mut a, mut d, mut gxy) = (zero, zero, zc0);
    let mut h = [[zc0; 2]; 2];
    let mut rhs2 = [zero; 2];
    for r in rows {
        a = _mm256_add_pd(a, norm_sqr(r[0]));
        d = _mm256_add_pd(d, norm_sqr(r[1]));
        gxy = add(gxy, cmul(r[0], r[1]));
        h[0][0] = add(h[0][0], cmul(r[0], r[2]));
        h[0][1] = add(h[0][1], cmul(r[1], r[2]));
        rhs2[0] = _mm256_add_pd(rhs2[0], norm_sqr(r[2]));
    }
    for r in rows {
        h[1][0] = add(h[1][0], cmul(r[0], r[3]));
        h[1][1] = add(h[1][1], cmul(r[1], r[3]));
        rhs2[1] = _mm256_add_pd(rhs2[1], norm_sqr(r[3]));
    }
    let g2 = norm_sqr(gxy);
    let det = _mm256_sub_pd(_mm256_mul_pd(a, d), g2);
    let amd = _mm256_sub_pd(a, d);
    let lmax = _mm256_add_pd(
        _mm256_mul_pd(_mm256_add_pd(a, d), sp(0.5)),
        _mm256_sqrt_pd(_mm256_add_pd(_mm256_mul_pd(_mm256_mul_pd(amd, amd), sp(0.25)), g2)),
    );
    let idet = _mm256_div_pd(sp(1.0), det);
    let cond = _mm256_sqrt_pd(_mm256_mul_pd(_mm256_mul_pd(lmax, lmax), idet));
    let gc = conj(gxy);
    let mut z = [solve_gram(h[0], a, d, gxy, gc, idet), solve_gram(h[1], a, d, gxy, gc, idet)];
    let mut res2 = [zero; 2];
    for k in 0..2 {
        let mut ahr = [zc0; 2];
        for r in rows {
            let res = sub(sub(r[2 + k], mul(r[0], z[k][0])), mul(r[1], z[k][1]));
            res2[k] = _mm256_add_pd(res2[k], norm_sqr(res));
            ahr[0] = add(ahr[0], cmul(r[0], res));
            ahr[1] = add(ahr[1], cmul(r[1], res));
        }
        let dz = solve_gram(ahr, a, d, gxy, gc, idet);
        z[k][0] = add(z[k][0], dz[0]);
        z[k][1] = add(z[k][1], dz[1]);
    }
    let ad = _mm256_add_pd(a, d);
    let total = _mm256_add_pd(_mm256_add_pd(ad, rhs2[0]), rhs2[1]);
    *out = Sol { z, g: [_mm256_mul_pd(d, idet), _mm256_mul_pd(a, idet)], cond, res2, rhs2, total, qq: ad };
}

/// Eight lane vectors -> rows of 8 values for the `nl` points from `g0` on, in `dst` ((points, 8)).
#[target_feature(enable = "avx2,fma")]
#[inline]
fn put_rows(dst: &mut [f64], g0: usize, nl: usize, v: &[__m256d; 8]) {
    let lo = transpose([v[0], v[1], v[2], v[3]]);
    let hi = transpose([v[4], v[5], v[6], v[7]]);
    if nl == N {
        let d = &mut dst[8 * g0..8 * g0 + 8 * N];
        for l in 0..N {
            // SAFETY: d holds 32 doubles; row l is d[8 l..8 l + 8]
            unsafe {
                _mm256_storeu_pd(d.as_mut_ptr().add(8 * l), lo[l]);
                _mm256_storeu_pd(d.as_mut_ptr().add(8 * l + 4), hi[l]);
            }
        }
    } else {
        let mut tmp = [0.0f64; 8 * N];
        for l in 0..N {
            // SAFETY: tmp holds 32 doubles
            unsafe {
                _mm256_storeu_pd(tmp.as_mut_ptr().add(8 * l), lo[l]);
                _mm256_storeu_pd(tmp.as_mut_ptr().add(8 * l + 4), hi[l]);
            }
        }
        dst[8 * g0..8 * (g0 + nl)].copy_from_slice(&tmp[..8 * nl]);
    }
}

/// Store the `nl` first lanes of `v` at `dst[g0..]`.
#[target_feature(enable = "avx2,fma")]
#[inline]
fn put_lanes(dst: &mut [f64], g0: usize, nl: usize, v: __m256d) {
    if nl == N {
        let d = &mut dst[g0..g0 + N];
        // SAFETY: d holds 4 doubles
        unsafe { _mm256_storeu_pd(d.as_mut_ptr(), v) };
    } else {
        dst[g0..g0 + nl].copy_from_slice(&vm(v).0[..nl]);
    }
}

/// Lane values chosen by `f(lane)` (headers of groups whose points are not one contiguous run).
#[target_feature(enable = "avx2,fma")]
#[inline]
fn lanes_of(f: impl Fn(usize) -> f64) -> __m256d {
    _mm256_setr_pd(f(0), f(1), f(2), f(3))
}

/// The excitation e[o..o + 4] in every lane.
#[target_feature(enable = "avx2,fma")]
#[inline]
fn splat_e(e: &[crate::model::C64], o: usize) -> [C; 4] {
    std::array::from_fn(|dd| C { re: _mm256_set1_pd(e[o + dd].re), im: _mm256_set1_pd(e[o + dd].im) })
}

/// Lanes where x is neither NaN nor +-inf, as an all-ones mask.
#[target_feature(enable = "avx2,fma")]
#[inline]
fn finite(x: __m256d) -> __m256d {
    let abs = _mm256_andnot_pd(_mm256_set1_pd(-0.0), x);
    _mm256_cmp_pd::<_CMP_LT_OQ>(abs, _mm256_set1_pd(f64::INFINITY))
}

/// [`super::forces_chunk`] on AVX2 registers (see the module's documentation).
#[target_feature(enable = "avx2,fma")]
pub(super) fn forces_chunk(p: &IdentProblem, kc: &Consts, start: usize, out: Outs) -> usize {
    let Outs { k, c, cond, resid, amp, mut ks, mut cs, rel: mut rel_out } = out;
    let n = p.w.len();
    let npts = resid.len();
    let shared_e = p.e.len() == p.runs * 4;
    let windowed = !p.sigma.is_empty();
    let has_ped = !p.q_ped.is_empty();
    let nsys = if p.identical { 1 } else { 2 };
    let mut nbad = 0;
    let zero = _mm256_setzero_pd();
    let zero_c = C { re: zero, im: zero };
    let mut rows = [vec![[zero_c; 4]; 2 * p.runs], vec![[zero_c; 4]; 2 * p.runs]];
    let mut sols = [Sol { z: [[zero_c; 2]; 2], g: [zero; 2], cond: zero, res2: [zero; 2], rhs2: [zero; 2], total: zero, qq: zero }; 2];
    let sp = _mm256_set1_pd;
    let (ml2, ml1, it) = (sp(kc.ml2), sp(kc.ml1), sp(kc.it));
    let (l1, l2, il, ip) = (sp(kc.l1), sp(kc.l2), sp(kc.il), sp(kc.ip));
    let planes = p.planes.map(|t| [sp(t[0]), sp(t[1]), sp(t[2]), sp(t[3])]);
    let nanv = sp(f64::NAN);
    let want_std = ks.is_some() && cs.is_some();
    let inv_4runs = sp(1.0 / (4.0 * p.runs as f64));
    // excitations shared by every point: splat once per chunk (read by the multiplies from memory)
    let e_shared: Vec<[C; 4]> = if shared_e { (0..p.runs).map(|r| splat_e(p.e, 4 * r)).collect() } else { Vec::new() };
    for g0 in (0..npts).step_by(N) {
        let nl = N.min(npts - g0);
        // (batch, point) of each lane; lanes past the chunk's end repeat its last point
        let first = start + g0;
        let (b0, i0) = (first / n, first % n);
        let contiguous = nl == N && i0 + N <= n;
        let mut bi = [(b0, i0); N];
        if !contiguous {
            let (mut b, mut i) = (b0, i0);
            for (l, slot) in bi.iter_mut().enumerate() {
                *slot = (b, i);
                if l + 1 < nl {
                    i += 1;
                    if i == n {
                        i = 0;
                        b += 1;
                    }
                }
            }
        } else {
            for (l, slot) in bi.iter_mut().enumerate() {
                *slot = (b0, i0 + l);
            }
        }
        let one_row = bi[0].0 == bi[N - 1].0;
        let at = |a: &[f64]| -> __m256d {
            if contiguous {
                // SAFETY: i0 + 4 <= n = a.len()
                unsafe { _mm256_loadu_pd(a.as_ptr().add(i0)) }
            } else {
                lanes_of(|l| a[bi[l].1])
            }
        };
        let w = at(p.w);
        let spin = if p.spin.len() == 1 { sp(p.spin[0]) } else { at(p.spin) };
        let gain = match p.gain.len() {
            0 => _mm256_mul_pd(spin, spin),
            1 => sp(p.gain[0]),
            _ => at(p.gain),
        };
        let sig = if windowed { at(p.sigma) } else { zero };
        // -s^2 = (w^2 - sigma^2) - j 2 sigma w and -s Omega I_p/L = -(sigma + j w) Omega I_p/L
        let a2 = _mm256_sub_pd(_mm256_mul_pd(w, w), _mm256_mul_pd(sig, sig));
        let b2 = _mm256_mul_pd(_mm256_mul_pd(sp(2.0), sig), w);
        let wg = _mm256_mul_pd(_mm256_mul_pd(w, spin), ip);
        let sgg = _mm256_mul_pd(_mm256_mul_pd(sig, spin), ip);
        let mut nr = [0usize; 2];
        for r in 0..p.runs {
            let ptrs = |blocks: &[&[crate::model::C64]]| -> [*const f64; N] {
                if contiguous {
                    // one bounds check for the group: its points are 4 * i0.. 4 * (i0 + 4) of a block
                    let base = blocks[b0 * p.runs + r][4 * i0..4 * (i0 + N)].as_ptr() as *const f64;
                    // SAFETY: the slice above holds the 4 points' 32 doubles
                    return std::array::from_fn(|l| unsafe { base.add(8 * l) });
                }
                let mut o = [std::ptr::null(); N];
                for l in 0..N {
                    let (b, i) = bi[l];
                    o[l] = blocks[b * p.runs + r][4 * i..4 * i + 4].as_ptr() as *const f64;
                }
                o
            };
            // SAFETY: each pointer is the start of a point's 4 complex values (8 doubles)
            let mut q = unsafe { load_points(ptrs(p.q)) };
            if let Some(t) = &planes {
                q = [
                    add(scale(q[0], t[0]), scale(q[1], t[1])),
                    add(scale(q[0], t[2]), scale(q[1], t[3])),
                    add(scale(q[2], t[0]), scale(q[3], t[1])),
                    add(scale(q[2], t[2]), scale(q[3], t[3])),
                ];
            }
            let e_row: [C; 4];
            let e: &[C; 4] = if shared_e {
                &e_shared[r]
            } else if one_row {
                e_row = splat_e(p.e, (bi[0].0 * p.runs + r) * 4);
                &e_row
            } else {
                e_row = std::array::from_fn(|dd| {
                    let ev = |l: usize| p.e[(bi[l].0 * p.runs + r) * 4 + dd];
                    C { re: lanes_of(|l| ev(l).re), im: lanes_of(|l| ev(l).im) }
                });
                &e_row
            };
            // the inertia acts on the absolute motion: q + q_ped with flexible pedestals
            let qa = if has_ped {
                // SAFETY: as for q (q_ped has q's layout, checked by IdentProblem::check)
                let d = unsafe { load_points(ptrs(p.q_ped)) };
                [add(q[0], d[0]), add(q[1], d[1]), add(q[2], d[2]), add(q[3], d[3])]
            } else {
                q
            };
            // R = E + w^2 M q - j w Omega G q (eq. 10 / 26), M and G sparse (eq. 3)
            let m0 = add(scale(qa[0], ml2), scale(qa[1], ml1));
            let m1 = add(scale(qa[2], ml2), scale(qa[3], ml1));
            let m2 = scale(sub(qa[1], qa[0]), it);
            let m3 = scale(sub(qa[2], qa[3]), it);
            let (g2, g3) = (sub(qa[3], qa[2]), sub(qa[1], qa[0]));
            let mut rv0 = add(scale(e[0], gain), scale(m0, a2));
            let mut rv1 = add(scale(e[1], gain), scale(m1, a2));
            let mut rv2 = sub_jscale(add(scale(e[2], gain), scale(m2, a2)), g2, wg);
            let mut rv3 = sub_jscale(add(scale(e[3], gain), scale(m3, a2)), g3, wg);
            if windowed {
                rv0 = sub_jscale(rv0, m0, b2);
                rv1 = sub_jscale(rv1, m1, b2);
                rv2 = sub(sub_jscale(rv2, m2, b2), scale(g2, sgg));
                rv3 = sub(sub_jscale(rv3, m3, b2), scale(g3, sgg));
            }
            // bearing reaction forces from the four rotor equations (as in super::forces_chunk)
            let f1x = scale(sub(scale(rv0, l2), rv2), il);
            let f1y = scale(add(scale(rv1, l2), rv3), il);
            let f2x = scale(add(rv2, scale(rv0, l1)), il);
            let f2y = scale(sub(scale(rv1, l1), rv3), il);
            rows[0][nr[0]] = [q[0], q[2], f1x, f1y];
            nr[0] += 1;
            let s2 = if p.identical { 0 } else { 1 };
            rows[s2][nr[s2]] = [q[1], q[3], f2x, f2y];
            nr[s2] += 1;
        }
        // two rows (two runs, the impact case): Cramer's rule inlined here; more: `solve`
        for sb in 0..nsys {
            if nr[sb] == 2 {
                // SAFETY: this function runs on AVX2 CPUs only
                sols[sb] = unsafe { solve_square(&rows[sb][0], &rows[sb][1]) };
            } else {
                solve(&rows[sb][..nr[sb]], &mut sols[sb]);
            }
        }
        // rows of the systems together hold every entry of q and E: a NaN/inf input shows up here
        let total = _mm256_add_pd(sols[0].total, if p.identical { zero } else { sols[1].total });
        let bad = _mm256_xor_pd(finite(total), _mm256_castsi256_pd(_mm256_set1_epi64x(-1)));
        for sb in 0..nsys {
            let redo = _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_NLT_UQ>(sols[sb].cond, sp(CSNE_COND)));
            if redo != 0 {
                for l in 0..nl {
                    if redo & (1 << l) != 0 {
                        let mut lanes = sols[sb].to_lanes();
                        givens_lane(as_lane_rows(&rows[sb][..nr[sb]]), l, &mut lanes);
                        sols[sb] = Sol::from_lanes(&lanes);
                    }
                }
            }
        }
        if p.identical {
            sols[1] = sols[0];
        }
        let iw = _mm256_div_pd(sp(1.0), w);
        let mut kv = [zero; 8];
        let mut cv = [zero; 8];
        let mut sv = [zero; 8];
        for sb in 0..2 {
            let s = &sols[sb];
            let dof = nr[if p.identical { 0 } else { sb }] as f64 - 2.0;
            for row in 0..2 {
                let var_half = _mm256_mul_pd(s.res2[row], sp(if dof > 0.0 { 0.5 / dof } else { f64::NAN }));
                for col in 0..2 {
                    let o = 4 * sb + 2 * row + col;
                    // Z = K + s C = (K + sigma C) + j w C
                    cv[o] = _mm256_mul_pd(s.z[row][col].im, iw);
                    kv[o] = _mm256_sub_pd(s.z[row][col].re, _mm256_mul_pd(sig, cv[o]));
                    if want_std {
                        sv[o] = _mm256_sqrt_pd(_mm256_mul_pd(var_half, s.g[col]));
                    }
                }
            }
        }
        let (s0, s1) = (&sols[0], &sols[1]);
        let pair = |a: __m256d, b: __m256d| _mm256_add_pd(a, b);
        let res_tot = _mm256_add_pd(pair(s0.res2[0], s0.res2[1]), if p.identical { zero } else { pair(s1.res2[0], s1.res2[1]) });
        let rhs_tot = _mm256_add_pd(pair(s0.rhs2[0], s0.rhs2[1]), if p.identical { zero } else { pair(s1.rhs2[0], s1.rhs2[1]) });
        let rel = _mm256_sqrt_pd(_mm256_mul_pd(res_tot, _mm256_div_pd(sp(1.0), rhs_tot)));
        let qsum = _mm256_add_pd(s0.qq, if p.identical { zero } else { s1.qq });
        let rms = _mm256_sqrt_pd(_mm256_mul_pd(qsum, inv_4runs));
        // singular systems and non-finite input give NaN coefficients
        let sing = [0, 1].map(|sb| _mm256_cmp_pd::<_CMP_NLT_UQ>(sols[sb].cond, sp(SINGULAR_COND)));
        let nanm = [_mm256_or_pd(sing[0], bad), _mm256_or_pd(sing[1], bad)];
        for o in 0..8 {
            let m = nanm[o / 4];
            kv[o] = _mm256_blendv_pd(kv[o], nanv, m);
            cv[o] = _mm256_blendv_pd(cv[o], nanv, m);
            sv[o] = _mm256_blendv_pd(sv[o], nanv, m);
        }
        put_rows(k, g0, nl, &kv);
        put_rows(c, g0, nl, &cv);
        if let (Some(ks), Some(cs)) = (ks.as_deref_mut(), cs.as_deref_mut()) {
            // var(K) = var(Re Z) (1 + (sigma/w)^2)
            let kfac = _mm256_sqrt_pd(_mm256_add_pd(sp(1.0), _mm256_mul_pd(_mm256_mul_pd(_mm256_mul_pd(sig, sig), iw), iw)));
            let mut csv = [zero; 8];
            for o in 0..8 {
                csv[o] = _mm256_mul_pd(sv[o], iw);
                sv[o] = _mm256_mul_pd(sv[o], kfac);
            }
            put_rows(ks, g0, nl, &sv);
            put_rows(cs, g0, nl, &csv);
            if let Some(rel_out) = rel_out.as_deref_mut() {
                relative_std_rows(rel_out, k, c, ks, cs, g0..g0 + nl);
            }
        }
        // cond: inf for a singular system, NaN for non-finite input; (points, 2) by interleaving
        let cnd = [0, 1].map(|sb| {
            let v = _mm256_blendv_pd(sols[sb].cond, sp(f64::INFINITY), _mm256_andnot_pd(bad, nanm[sb]));
            _mm256_blendv_pd(v, nanv, bad)
        });
        let (lo, hi) = (_mm256_unpacklo_pd(cnd[0], cnd[1]), _mm256_unpackhi_pd(cnd[0], cnd[1]));
        let pairs = [_mm256_permute2f128_pd::<0x20>(lo, hi), _mm256_permute2f128_pd::<0x31>(lo, hi)];
        if nl == N {
            let d = &mut cond[2 * g0..2 * g0 + 2 * N];
            // SAFETY: d holds 8 doubles
            unsafe {
                _mm256_storeu_pd(d.as_mut_ptr(), pairs[0]);
                _mm256_storeu_pd(d.as_mut_ptr().add(4), pairs[1]);
            }
        } else {
            let mut tmp = [0.0f64; 2 * N];
            // SAFETY: tmp holds 8 doubles
            unsafe {
                _mm256_storeu_pd(tmp.as_mut_ptr(), pairs[0]);
                _mm256_storeu_pd(tmp.as_mut_ptr().add(4), pairs[1]);
            }
            cond[2 * g0..2 * (g0 + nl)].copy_from_slice(&tmp[..2 * nl]);
        }
        let no_rhs = _mm256_cmp_pd::<_CMP_NGT_UQ>(rhs_tot, zero);
        put_lanes(resid, g0, nl, _mm256_blendv_pd(rel, nanv, _mm256_or_pd(bad, no_rhs)));
        put_lanes(amp, g0, nl, rms);
        nbad += ((_mm256_movemask_pd(bad) as u32) & ((1u32 << nl) - 1)).count_ones() as usize;
    }
    nbad
}

#[cfg(test)]
mod tests {
    use super::super::forces_chunk as generic_chunk;
    use super::*;
    use crate::model::{Rotor, C64};
    use proptest::prelude::*;

    /// Every output of one chunk, from the AVX2 kernel or the 2-lane generic one.
    fn run(p: &IdentProblem, with_std: bool, avx2: bool) -> (usize, Vec<Vec<f64>>) {
        let np = p.batch * p.points();
        let mut o: Vec<Vec<f64>> = [8, 8, 2, 1, 1, 8, 8, 1].iter().map(|m| vec![0.0; m * np]).collect();
        let [k, c, cond, resid, amp, ks, cs, rel] = &mut o[..] else { unreachable!() };
        let outs = Outs {
            k,
            c,
            cond,
            resid,
            amp,
            ks: with_std.then_some(&mut ks[..]),
            cs: with_std.then_some(&mut cs[..]),
            rel: with_std.then_some(&mut rel[..]),
        };
        let kc = Consts::new(&p.rotor);
        // SAFETY: called only when the CPU has AVX2 and FMA
        let nbad = if avx2 { unsafe { forces_chunk(p, &kc, 0, outs) } } else { generic_chunk::<2>(p, &kc, 0, outs) };
        (nbad, o)
    }

    fn value(seed: u64, special: u8) -> f64 {
        match special {
            0 => f64::NAN,
            1 => f64::INFINITY,
            2 => 0.0,
            3 => 1e200,
            _ => (seed % 2001) as f64 * 1e-3 - 1.0,
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]
        /// The AVX2 kernel gives the bits of the generic one on every kind of group: whole and
        /// wrapping across batch rows, a chunk's short last group, one to five runs, identical
        /// bearings, windows, probe planes, pedestal motion, per-row excitations, broadcast and
        /// per-point gains and speeds, with and without standard errors, with NaN, inf, zero and
        /// huge entries (singular, Givens-solved and non-finite points). NaN is any NaN.
        #[test]
        fn avx2_kernel_gives_the_generic_kernels_bits(
            batch in 1usize..4, n in 1usize..14, runs in 1usize..6, identical in proptest::bool::ANY,
            windowed in proptest::bool::ANY, layout in 0u8..3, shared_e in proptest::bool::ANY,
            gain_kind in 0u8..3, spin_one in proptest::bool::ANY, with_std in proptest::bool::ANY,
            seeds in proptest::collection::vec(any::<u64>(), 1000),
            specials in proptest::collection::vec(0u8..60, 1001),
        ) {
            if !(std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")) {
                return Ok(());
            }
            let mut it = seeds.iter().zip(&specials).cycle().map(|(&s, &k)| value(s, k));
            let mut cplx = |m: usize| -> Vec<C64> { (0..m).map(|_| C64::new(it.next().unwrap(), it.next().unwrap())).collect() };
            let q = cplx(batch * runs * n * 4);
            let ped = cplx(if layout == 2 { batch * runs * n * 4 } else { 0 });
            let e = cplx(if shared_e { runs * 4 } else { batch * runs * 4 });
            let w: Vec<f64> = (0..n).map(|i| 30.0 + 17.0 * i as f64).collect();
            let spin: Vec<f64> = if spin_one { vec![90.0] } else { (0..n).map(|i| 10.0 + 3.0 * i as f64).collect() };
            let gain: Vec<f64> = match gain_kind { 0 => vec![], 1 => vec![2.5], _ => (0..n).map(|i| 1.0 + i as f64).collect() };
            let sigma: Vec<f64> = if windowed { (0..n).map(|i| 0.5 + 0.1 * i as f64).collect() } else { vec![] };
            let qb: Vec<&[C64]> = q.chunks(n * 4).collect();
            let pb: Vec<&[C64]> = ped.chunks(n * 4).collect();
            let p = IdentProblem {
                rotor: Rotor::from_slice(&[30.7, 0.62, 0.062, 0.146, 0.137]).unwrap(),
                w: &w, spin: &spin, q: &qb, e: &e, gain: &gain, sigma: &sigma, q_ped: &pb,
                planes: (layout == 1).then_some([1.2, -0.2, -0.3, 1.3]),
                batch, runs, identical,
            };
            p.check().unwrap();
            let (bad_a, a) = run(&p, with_std, true);
            let (bad_g, g) = run(&p, with_std, false);
            prop_assert_eq!(bad_a, bad_g);
            for (name, (x, y)) in ["k", "c", "cond", "resid", "amp", "k_std", "c_std", "rel_std"].iter().zip(a.iter().zip(&g)) {
                for (i, (u, v)) in x.iter().zip(y).enumerate() {
                    // NaN for NaN: which NaN an operation on two of them returns is left open
                    prop_assert!(u.to_bits() == v.to_bits() || (u.is_nan() && v.is_nan()), "{}[{}]: {} (AVX2) vs {} (generic)", name, i, u, v);
                }
            }
        }
    }
}
