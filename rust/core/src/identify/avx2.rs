//! [`super::registers`]' kernel on AVX2 registers: 4 points per group, every value of the group
//! in a `__m256d`. Lane masks are all-ones lanes of a `__m256d`.
//!
//! Instructions per point (callgrind on `examples/identify_points 4096 5 nostd R`, kernel and
//! solver) and time per point (one thread, best of 10 interleaved runs, AMD EPYC) against the
//! generic kernel on AVX2: 2 runs 571 -> 346 and 46.3 -> 27.0 ns, 4 runs 1,181 -> 851 and 86.7 ->
//! 63.4 ns. Tried and dropped: the same code with AVX-512VL's 32 registers (no faster: 63.5
//! against 62.9 ns with 4 runs, 25.3 against 27.0 with 2), and the lane pointers in a function of
//! their own (inlined, 4 runs took 74 ns).

use super::registers::{one_intrinsic_ops, store_group, Regs, C};
use super::{Consts, IdentProblem, Outs};
use crate::lanes::V;
use std::arch::x86_64::*;

const N: usize = 4;

/// AVX2 + FMA (the fused multiply-adds of [`super::registers`] are FMA instructions).
pub(crate) struct Avx2;

/// 4 x 4 transpose of doubles: row l of the output is lane l of the inputs.
#[inline(always)]
unsafe fn transpose(a: [__m256d; 4]) -> [__m256d; 4] {
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

impl Regs<N> for Avx2 {
    type V = __m256d;
    one_intrinsic_ops!(__m256d, N, _mm256_set1_pd, _mm256_add_pd, _mm256_sub_pd, _mm256_mul_pd, _mm256_div_pd, _mm256_sqrt_pd, _mm256_loadu_pd,
        _mm256_fmadd_pd, _mm256_fnmadd_pd, _mm256_fmsub_pd);
    type M = __m256d;
    #[inline(always)]
    unsafe fn neg(a: __m256d) -> __m256d {
        _mm256_xor_pd(a, _mm256_set1_pd(-0.0))
    }
    #[inline(always)]
    unsafe fn abs(a: __m256d) -> __m256d {
        _mm256_andnot_pd(_mm256_set1_pd(-0.0), a)
    }
    #[inline(always)]
    unsafe fn max_nan(a: __m256d, b: __m256d) -> __m256d {
        // a + b is NaN where either is
        _mm256_blendv_pd(_mm256_max_pd(a, b), _mm256_add_pd(a, b), _mm256_cmp_pd::<_CMP_UNORD_Q>(a, b))
    }
    #[inline(always)]
    unsafe fn lanes_of(f: impl Fn(usize) -> f64) -> __m256d {
        _mm256_setr_pd(f(0), f(1), f(2), f(3))
    }
    #[inline(always)]
    unsafe fn load_points(ptr: &[*const f64; N]) -> [C<__m256d>; 4] {
        let lo = transpose([_mm256_loadu_pd(ptr[0]), _mm256_loadu_pd(ptr[1]), _mm256_loadu_pd(ptr[2]), _mm256_loadu_pd(ptr[3])]);
        let hi = transpose([
            _mm256_loadu_pd(ptr[0].add(4)),
            _mm256_loadu_pd(ptr[1].add(4)),
            _mm256_loadu_pd(ptr[2].add(4)),
            _mm256_loadu_pd(ptr[3].add(4)),
        ]);
        [C { re: lo[0], im: lo[1] }, C { re: lo[2], im: lo[3] }, C { re: hi[0], im: hi[1] }, C { re: hi[2], im: hi[3] }]
    }
    #[inline(always)]
    unsafe fn put_rows(dst: &mut [f64], g0: usize, nl: usize, v: &[__m256d; 8]) {
        let lo = transpose([v[0], v[1], v[2], v[3]]);
        let hi = transpose([v[4], v[5], v[6], v[7]]);
        store_group::<{ 8 * N }>(dst, 8 * g0, 8 * nl, |d| {
            for l in 0..N {
                // d holds 32 doubles; row l is d[8 l..8 l + 8]
                _mm256_storeu_pd(d.add(8 * l), lo[l]);
                _mm256_storeu_pd(d.add(8 * l + 4), hi[l]);
            }
        });
    }
    #[inline(always)]
    unsafe fn put_lanes(dst: &mut [f64], g0: usize, nl: usize, v: __m256d) {
        if nl == N {
            _mm256_storeu_pd(dst[g0..g0 + N].as_mut_ptr(), v);
        } else {
            dst[g0..g0 + nl].copy_from_slice(&Self::to_lanes(v).0[..nl]);
        }
    }
    #[inline(always)]
    unsafe fn put_pairs(dst: &mut [f64], g0: usize, nl: usize, a: __m256d, b: __m256d) {
        let (lo, hi) = (_mm256_unpacklo_pd(a, b), _mm256_unpackhi_pd(a, b));
        let pairs = [_mm256_permute2f128_pd::<0x20>(lo, hi), _mm256_permute2f128_pd::<0x31>(lo, hi)];
        store_group::<{ 2 * N }>(dst, 2 * g0, 2 * nl, |d| {
            // d holds 8 doubles
            _mm256_storeu_pd(d, pairs[0]);
            _mm256_storeu_pd(d.add(4), pairs[1]);
        });
    }
    #[inline(always)]
    unsafe fn finite(x: __m256d) -> __m256d {
        _mm256_cmp_pd::<_CMP_LT_OQ>(Self::abs(x), _mm256_set1_pd(f64::INFINITY))
    }
    #[inline(always)]
    unsafe fn eq(a: __m256d, b: __m256d) -> __m256d {
        _mm256_cmp_pd::<_CMP_EQ_OQ>(a, b)
    }
    #[inline(always)]
    unsafe fn not_lt(a: __m256d, b: __m256d) -> __m256d {
        _mm256_cmp_pd::<_CMP_NLT_UQ>(a, b)
    }
    #[inline(always)]
    unsafe fn not_gt(a: __m256d, b: __m256d) -> __m256d {
        _mm256_cmp_pd::<_CMP_NGT_UQ>(a, b)
    }
    #[inline(always)]
    unsafe fn m_or(a: __m256d, b: __m256d) -> __m256d {
        _mm256_or_pd(a, b)
    }
    #[inline(always)]
    unsafe fn m_not(a: __m256d) -> __m256d {
        _mm256_xor_pd(a, _mm256_castsi256_pd(_mm256_set1_epi64x(-1)))
    }
    #[inline(always)]
    unsafe fn m_andnot(a: __m256d, b: __m256d) -> __m256d {
        _mm256_andnot_pd(a, b)
    }
    #[inline(always)]
    unsafe fn m_bits(a: __m256d) -> u32 {
        _mm256_movemask_pd(a) as u32
    }
    #[inline(always)]
    unsafe fn blend(a: __m256d, b: __m256d, m: __m256d) -> __m256d {
        _mm256_blendv_pd(a, b, m)
    }
}

/// [`super::forces_chunk`] on AVX2 registers (see [`super::registers`]).
#[target_feature(enable = "avx2,fma")]
pub(super) fn forces_chunk(p: &IdentProblem, kc: &Consts, start: usize, out: Outs) -> usize {
    // SAFETY: this function is compiled for and called on AVX2 + FMA CPUs only
    unsafe { super::registers::forces_chunk_instance::<N, Avx2>(p, kc, start, out) }
}
