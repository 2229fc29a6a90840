//! [`super::registers`]' kernel on AVX-512 registers: 8 points per group, every value of the group
//! in a `__m512d`, lane masks in a `__mmask8`. The lanes do the AVX2 kernel's operations, fused
//! multiply-adds included (FMA instructions), so the outputs are the same bits at every level.
//!
//! On the Intel Xeon this was written on it takes 39-41 ns per point against the AVX2 instance's
//! 54-57 (one thread, 4,096 points from 4 runs, `examples/identify_points`; see
//! [`super::forces_chunk_dispatch`] and the README's benchmarks, 2026-11-27, eighth session). On an AMD EPYC (Zen 4, 512-bit operations as two 256-bit
//! halves) the earlier lane-array kernels of 8 lanes were slower than 4 (see
//! [`super::forces_chunk_dispatch`]); this register kernel was not measured there.

use super::registers::{one_intrinsic_ops, store_group, Regs, C};
use super::{Consts, IdentProblem, Outs};
use crate::lanes::V;
use std::arch::x86_64::*;

const N: usize = 8;

/// AVX-512 F + DQ (DQ for the bitwise `xor` on doubles).
pub(crate) struct Avx512;

/// 8 x 8 transpose of doubles: row l of the output is lane l of the inputs (its own inverse).
#[inline(always)]
unsafe fn transpose(r: [__m512d; 8]) -> [__m512d; 8] {
    // t: pairs of rows interleaved by 128-bit lane: unpacklo(r0, r1) = [r0_0 r1_0 | r0_2 r1_2 | ...]
    let t = [
        _mm512_unpacklo_pd(r[0], r[1]),
        _mm512_unpackhi_pd(r[0], r[1]),
        _mm512_unpacklo_pd(r[2], r[3]),
        _mm512_unpackhi_pd(r[2], r[3]),
        _mm512_unpacklo_pd(r[4], r[5]),
        _mm512_unpackhi_pd(r[4], r[5]),
        _mm512_unpacklo_pd(r[6], r[7]),
        _mm512_unpackhi_pd(r[6], r[7]),
    ];
    // 0x88 takes 128-bit lanes (0, 2) of each operand, 0xDD lanes (1, 3)
    let u = [
        _mm512_shuffle_f64x2::<0x88>(t[0], t[2]), // columns 0, 4 of rows 0-3
        _mm512_shuffle_f64x2::<0xDD>(t[0], t[2]), // 2, 6
        _mm512_shuffle_f64x2::<0x88>(t[1], t[3]), // 1, 5
        _mm512_shuffle_f64x2::<0xDD>(t[1], t[3]), // 3, 7
        _mm512_shuffle_f64x2::<0x88>(t[4], t[6]), // columns 0, 4 of rows 4-7
        _mm512_shuffle_f64x2::<0xDD>(t[4], t[6]),
        _mm512_shuffle_f64x2::<0x88>(t[5], t[7]),
        _mm512_shuffle_f64x2::<0xDD>(t[5], t[7]),
    ];
    [
        _mm512_shuffle_f64x2::<0x88>(u[0], u[4]),
        _mm512_shuffle_f64x2::<0x88>(u[2], u[6]),
        _mm512_shuffle_f64x2::<0x88>(u[1], u[5]),
        _mm512_shuffle_f64x2::<0x88>(u[3], u[7]),
        _mm512_shuffle_f64x2::<0xDD>(u[0], u[4]),
        _mm512_shuffle_f64x2::<0xDD>(u[2], u[6]),
        _mm512_shuffle_f64x2::<0xDD>(u[1], u[5]),
        _mm512_shuffle_f64x2::<0xDD>(u[3], u[7]),
    ]
}

impl Regs<N> for Avx512 {
    type V = __m512d;
    one_intrinsic_ops!(__m512d, N, _mm512_set1_pd, _mm512_add_pd, _mm512_sub_pd, _mm512_mul_pd, _mm512_div_pd, _mm512_sqrt_pd, _mm512_loadu_pd,
        _mm512_fmadd_pd, _mm512_fnmadd_pd, _mm512_fmsub_pd);
    type M = __mmask8;
    #[inline(always)]
    unsafe fn neg(a: __m512d) -> __m512d {
        _mm512_xor_pd(a, _mm512_set1_pd(-0.0))
    }
    #[inline(always)]
    unsafe fn abs(a: __m512d) -> __m512d {
        _mm512_abs_pd(a)
    }
    #[inline(always)]
    unsafe fn max_nan(a: __m512d, b: __m512d) -> __m512d {
        // a + b is NaN where either is
        _mm512_mask_blend_pd(_mm512_cmp_pd_mask::<_CMP_UNORD_Q>(a, b), _mm512_max_pd(a, b), _mm512_add_pd(a, b))
    }
    #[inline(always)]
    unsafe fn lanes_of(f: impl Fn(usize) -> f64) -> __m512d {
        _mm512_setr_pd(f(0), f(1), f(2), f(3), f(4), f(5), f(6), f(7))
    }
    #[inline(always)]
    unsafe fn load_points(ptr: &[*const f64; N]) -> [C<__m512d>; 4] {
        let ld = |l: usize| _mm512_loadu_pd(ptr[l]);
        let t = transpose([ld(0), ld(1), ld(2), ld(3), ld(4), ld(5), ld(6), ld(7)]);
        [C { re: t[0], im: t[1] }, C { re: t[2], im: t[3] }, C { re: t[4], im: t[5] }, C { re: t[6], im: t[7] }]
    }
    #[inline(always)]
    unsafe fn put_rows(dst: &mut [f64], g0: usize, nl: usize, v: &[__m512d; 8]) {
        let rows = transpose(*v);
        store_group::<{ 8 * N }>(dst, 8 * g0, 8 * nl, |d| {
            for (l, row) in rows.iter().enumerate() {
                // d holds 64 doubles; row l is d[8 l..8 l + 8]
                _mm512_storeu_pd(d.add(8 * l), *row);
            }
        });
    }
    #[inline(always)]
    unsafe fn put_lanes(dst: &mut [f64], g0: usize, nl: usize, v: __m512d) {
        if nl == N {
            _mm512_storeu_pd(dst[g0..g0 + N].as_mut_ptr(), v);
        } else {
            dst[g0..g0 + nl].copy_from_slice(&Self::to_lanes(v).0[..nl]);
        }
    }
    #[inline(always)]
    unsafe fn put_pairs(dst: &mut [f64], g0: usize, nl: usize, a: __m512d, b: __m512d) {
        // indices 0-7 pick a's lanes, 8-15 b's: [a0 b0 a1 b1 a2 b2 a3 b3], [a4 b4 ... a7 b7]
        let lo = _mm512_permutex2var_pd(a, _mm512_setr_epi64(0, 8, 1, 9, 2, 10, 3, 11), b);
        let hi = _mm512_permutex2var_pd(a, _mm512_setr_epi64(4, 12, 5, 13, 6, 14, 7, 15), b);
        store_group::<{ 2 * N }>(dst, 2 * g0, 2 * nl, |d| {
            // d holds 16 doubles
            _mm512_storeu_pd(d, lo);
            _mm512_storeu_pd(d.add(8), hi);
        });
    }
    #[inline(always)]
    unsafe fn finite(x: __m512d) -> __mmask8 {
        _mm512_cmp_pd_mask::<_CMP_LT_OQ>(_mm512_abs_pd(x), _mm512_set1_pd(f64::INFINITY))
    }
    #[inline(always)]
    unsafe fn eq(a: __m512d, b: __m512d) -> __mmask8 {
        _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(a, b)
    }
    #[inline(always)]
    unsafe fn not_lt(a: __m512d, b: __m512d) -> __mmask8 {
        _mm512_cmp_pd_mask::<_CMP_NLT_UQ>(a, b)
    }
    #[inline(always)]
    unsafe fn not_gt(a: __m512d, b: __m512d) -> __mmask8 {
        _mm512_cmp_pd_mask::<_CMP_NGT_UQ>(a, b)
    }
    #[inline(always)]
    unsafe fn m_or(a: __mmask8, b: __mmask8) -> __mmask8 {
        a | b
    }
    #[inline(always)]
    unsafe fn m_not(a: __mmask8) -> __mmask8 {
        !a
    }
    #[inline(always)]
    unsafe fn m_andnot(a: __mmask8, b: __mmask8) -> __mmask8 {
        !a & b
    }
    #[inline(always)]
    unsafe fn m_bits(a: __mmask8) -> u32 {
        a as u32
    }
    #[inline(always)]
    unsafe fn blend(a: __m512d, b: __m512d, m: __mmask8) -> __m512d {
        _mm512_mask_blend_pd(m, a, b)
    }
}

/// [`super::forces_chunk`] on AVX-512 registers (see [`super::registers`]).
#[target_feature(enable = "avx512f,avx512dq,avx2,fma")]
pub(super) fn forces_chunk(p: &IdentProblem, kc: &Consts, start: usize, out: Outs) -> usize {
    // SAFETY: this function is compiled for and called on AVX-512 F + DQ CPUs only
    unsafe { super::registers::forces_chunk_instance::<N, Avx512>(p, kc, start, out) }
}
