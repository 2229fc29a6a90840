//! The bearing-force kernel of [`super::forces_chunk`] written on AVX2 registers: 4 points per
//! group, every value of the group in a `__m256d`.
//!
//! It performs the generic kernel's operations in the generic kernel's order (separate multiplies
//! and adds, no fused multiply-add), so its outputs are bit for bit those of the 2-lane baseline
//! (CI compares `examples/bit_digest` across levels). What differs is the data movement, which
//! the generic kernel leaves to LLVM and which cost more instructions than its arithmetic:
//! - inputs: each point's four complex responses are two 256-bit loads; a 4 x 4 transpose
//!   (unpack + 128-bit permute) turns four points into the lane vectors x_re, x_im, ...;
//! - outputs: k, c and their standard errors leave as 4 x 4 transposes and 256-bit stores, cond as
//!   an interleave, residual and amplitude as one store each; the flags that choose NaN or inf
//!   are lane masks, not per-lane branches;
//! - groups that wrap across batch rows or end a chunk read their points through per-lane
//!   pointers and write through a scratch block, so one code path serves every group.
//!
//! The bearing systems are solved by the same `solve_avx2` as before (solution through memory:
//! inlined, its values spill).

use super::{givens_lane, relative_std_point, solve_avx2, Consts, IdentProblem, LaneSol, Outs, CSNE_COND, SINGULAR_COND};
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

/// A complex lane vector in registers.
#[derive(Clone, Copy)]
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
    let zrow = [Z::<N>::zero(); 4];
    let mut rows = [vec![zrow; 2 * p.runs], vec![zrow; 2 * p.runs]];
    let mut sols = [LaneSol::<N>::zero(); 2];
    let sp = _mm256_set1_pd;
    let (ml2, ml1, it) = (sp(kc.ml2), sp(kc.ml1), sp(kc.it));
    let (l1, l2, il, ip) = (sp(kc.l1), sp(kc.l2), sp(kc.il), sp(kc.ip));
    let planes = p.planes.map(|t| [sp(t[0]), sp(t[1]), sp(t[2]), sp(t[3])]);
    let zero = _mm256_setzero_pd();
    let nanv = sp(f64::NAN);
    let want_std = ks.is_some() && cs.is_some();
    let inv_4runs = sp(1.0 / (4.0 * p.runs as f64));
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
            let e: [C; 4] = if shared_e || one_row {
                let be = if shared_e { 0 } else { bi[0].0 };
                let eo = (be * p.runs + r) * 4;
                std::array::from_fn(|dd| C { re: sp(p.e[eo + dd].re), im: sp(p.e[eo + dd].im) })
            } else {
                std::array::from_fn(|dd| {
                    let ev = |l: usize| p.e[(bi[l].0 * p.runs + r) * 4 + dd];
                    C { re: lanes_of(|l| ev(l).re), im: lanes_of(|l| ev(l).im) }
                })
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
            rows[0][nr[0]] = [zc(q[0]), zc(q[2]), zc(f1x), zc(f1y)];
            nr[0] += 1;
            let s2 = if p.identical { 0 } else { 1 };
            rows[s2][nr[s2]] = [zc(q[1]), zc(q[3]), zc(f2x), zc(f2y)];
            nr[s2] += 1;
        }
        solve_avx2(&rows[0][..nr[0]], &mut sols[0]);
        solve_avx2(&rows[1][..nr[1]], &mut sols[1]);
        // rows of the systems together hold every entry of q and E: a NaN/inf input shows up here
        let total = _mm256_add_pd(mv(sols[0].total), if p.identical { zero } else { mv(sols[1].total) });
        let bad = _mm256_xor_pd(finite(total), _mm256_castsi256_pd(_mm256_set1_epi64x(-1)));
        for sb in 0..nsys {
            let redo = _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_NLT_UQ>(mv(sols[sb].cond), sp(CSNE_COND)));
            if redo != 0 {
                for l in 0..nl {
                    if redo & (1 << l) != 0 {
                        givens_lane(&rows[sb][..nr[sb]], l, &mut sols[sb]);
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
                let var_half = _mm256_mul_pd(mv(s.res2[row]), sp(if dof > 0.0 { 0.5 / dof } else { f64::NAN }));
                for col in 0..2 {
                    let o = 4 * sb + 2 * row + col;
                    // Z = K + s C = (K + sigma C) + j w C
                    cv[o] = _mm256_mul_pd(mv(s.z[row][col].im), iw);
                    kv[o] = _mm256_sub_pd(mv(s.z[row][col].re), _mm256_mul_pd(sig, cv[o]));
                    if want_std {
                        sv[o] = _mm256_sqrt_pd(_mm256_mul_pd(var_half, mv(s.g[col])));
                    }
                }
            }
        }
        let (s0, s1) = (&sols[0], &sols[1]);
        let pair = |a: V<N>, b: V<N>| _mm256_add_pd(mv(a), mv(b));
        let res_tot = _mm256_add_pd(pair(s0.res2[0], s0.res2[1]), if p.identical { zero } else { pair(s1.res2[0], s1.res2[1]) });
        let rhs_tot = _mm256_add_pd(pair(s0.rhs2[0], s0.rhs2[1]), if p.identical { zero } else { pair(s1.rhs2[0], s1.rhs2[1]) });
        let rel = _mm256_sqrt_pd(_mm256_mul_pd(res_tot, _mm256_div_pd(sp(1.0), rhs_tot)));
        let qsum = _mm256_add_pd(mv(s0.qq), if p.identical { zero } else { mv(s1.qq) });
        let rms = _mm256_sqrt_pd(_mm256_mul_pd(qsum, inv_4runs));
        // singular systems and non-finite input give NaN coefficients
        let sing = [0, 1].map(|sb| _mm256_cmp_pd::<_CMP_NLT_UQ>(mv(sols[sb].cond), sp(SINGULAR_COND)));
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
                for t in g0..g0 + nl {
                    let at = |a: &[f64]| -> [f64; 8] { a[8 * t..8 * t + 8].try_into().unwrap() };
                    rel_out[t] = relative_std_point(&at(k), &at(c), &at(ks), &at(cs));
                }
            }
        }
        // cond: inf for a singular system, NaN for non-finite input; (points, 2) by interleaving
        let cnd = [0, 1].map(|sb| {
            let v = _mm256_blendv_pd(mv(sols[sb].cond), sp(f64::INFINITY), _mm256_andnot_pd(bad, nanm[sb]));
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
