//! Lane vectors for the data-parallel kernels: `L` independent points processed in lock-step so
//! that LLVM turns every lane loop into SIMD instructions (AVX2/AVX-512 via runtime dispatch).
//! `V<N>` and `Z<N>` take other lane counts: the identification kernel uses one register's width
//! (4 lanes of AVX2 code, also on AVX-512 CPUs, and 2 at the baseline), since a group wider than
//! the registers holds two or more of them per value and spills.

use std::ops::{Add, AddAssign, Mul, Neg, Sub};

pub const L: usize = 8;

/// The widest instruction set the kernels have a compiled version for, on this CPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Simd {
    /// AVX-512 F + DQ (with AVX2 and FMA)
    Avx512,
    /// AVX2 + FMA
    Avx2,
    /// the build's baseline (SSE2 on x86-64, or another architecture)
    Baseline,
}

/// Detect once which compiled version every SIMD kernel dispatches to. A kernel may call its
/// `#[target_feature]` version for the level returned here: the CPU has those features. The
/// environment variable `ROTORID_SIMD` (`avx512`, `avx2` or `baseline`) caps the level, e.g. to
/// measure the AVX2 kernels on an AVX-512 machine; it never raises it above what the CPU has,
/// and a value that is none of those is ignored here (the Python module refuses it at import,
/// see [`simd_cap_from_env`]).
pub fn simd() -> Simd {
    static LEVEL: std::sync::OnceLock<Simd> = std::sync::OnceLock::new();
    *LEVEL.get_or_init(|| {
        let cpu = simd_of_cpu();
        match simd_cap_from_env() {
            Ok(Some(cap)) if cap.rank() < cpu.rank() => cap,
            _ => cpu,
        }
    })
}

/// The widest level this CPU supports, whatever `ROTORID_SIMD` says.
pub fn simd_of_cpu() -> Simd {
    #[cfg(target_arch = "x86_64")]
    {
        if std::is_x86_feature_detected!("avx512f") && std::is_x86_feature_detected!("avx512dq") {
            return Simd::Avx512;
        }
        if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
            return Simd::Avx2;
        }
    }
    Simd::Baseline
}

/// The cap `ROTORID_SIMD` asks for: None when unset or empty, an error naming the accepted
/// values when it is something else.
pub fn simd_cap_from_env() -> Result<Option<Simd>, crate::error::CoreError> {
    match std::env::var("ROTORID_SIMD") {
        Err(_) => Ok(None),
        Ok(v) => match v.trim().to_ascii_lowercase().as_str() {
            "" => Ok(None),
            "avx512" => Ok(Some(Simd::Avx512)),
            "avx2" => Ok(Some(Simd::Avx2)),
            "baseline" => Ok(Some(Simd::Baseline)),
            _ => Err(crate::error::CoreError::value("ROTORID_SIMD", format!("must be avx512, avx2 or baseline (or unset), got {v:?}"))),
        },
    }
}

impl Simd {
    fn rank(self) -> u8 {
        match self {
            Simd::Baseline => 0,
            Simd::Avx2 => 1,
            Simd::Avx512 => 2,
        }
    }

    /// Lower-case name, as `ROTORID_SIMD` spells it.
    pub fn name(self) -> &'static str {
        match self {
            Simd::Avx512 => "avx512",
            Simd::Avx2 => "avx2",
            Simd::Baseline => "baseline",
        }
    }
}

/// Define `$name` calling `$kernel` compiled for AVX-512 (F, DQ), for AVX2 + FMA, or for the
/// build's baseline, whichever [`simd`] reports for this CPU: the same source and operations, with
/// wider registers (and fused multiply-adds) where available.
macro_rules! simd_dispatch {
    ($(#[$m:meta])* fn $name:ident($($arg:ident: $ty:ty),* $(,)?) -> $ret:ty => $kernel:ident) => {
        $(#[$m])*
        fn $name($($arg: $ty),*) -> $ret {
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx512f,avx512dq,avx2,fma")]
            fn avx512($($arg: $ty),*) -> $ret {
                $kernel($($arg),*)
            }
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2,fma")]
            fn avx2($($arg: $ty),*) -> $ret {
                $kernel($($arg),*)
            }
            match $crate::lanes::simd() {
                // SAFETY: simd() reports the CPU has the features these versions are compiled for.
                #[cfg(target_arch = "x86_64")]
                $crate::lanes::Simd::Avx512 => unsafe { avx512($($arg),*) },
                #[cfg(target_arch = "x86_64")]
                $crate::lanes::Simd::Avx2 => unsafe { avx2($($arg),*) },
                _ => $kernel($($arg),*),
            }
        }
    };
}
pub(crate) use simd_dispatch;

/// `N` values in lock-step, one per lane (`L` unless a kernel works on wider groups).
#[derive(Clone, Copy, Debug)]
pub struct V<const N: usize = L>(pub [f64; N]);

/// `N` complex values in lock-step, real and imaginary parts in separate lane vectors.
#[derive(Clone, Copy, Debug)]
pub struct Z<const N: usize = L> {
    pub re: V<N>,
    pub im: V<N>,
}

macro_rules! lanewise {
    ($a:expr, $b:expr, $op:tt) => {{
        let mut o = [0.0; N];
        for l in 0..N {
            o[l] = $a.0[l] $op $b.0[l];
        }
        V(o)
    }};
}

impl<const N: usize> V<N> {
    #[inline(always)]
    pub fn splat(x: f64) -> Self {
        V([x; N])
    }
    #[inline(always)]
    pub fn zero() -> Self {
        V([0.0; N])
    }
    #[inline(always)]
    pub fn sqrt(self) -> Self {
        let mut o = self.0;
        for v in o.iter_mut() {
            *v = v.sqrt();
        }
        V(o)
    }
    #[inline(always)]
    pub fn recip(self) -> Self {
        let mut o = self.0;
        for v in o.iter_mut() {
            *v = 1.0 / *v;
        }
        V(o)
    }
}

impl<const N: usize> V<N> {
    /// The first `N` values of `s` (which holds at least `N`).
    #[inline(always)]
    pub fn load(s: &[f64]) -> Self {
        let mut o = [0.0; N];
        o.copy_from_slice(&s[..N]);
        V(o)
    }
    /// Lane by lane: `a` where `m` is set, else `self` (a blend, no branch).
    #[inline(always)]
    pub fn or_where(self, m: M<N>, a: f64) -> Self {
        let mut o = self.0;
        for l in 0..N {
            o[l] = f64::from_bits((a.to_bits() & m.0[l]) | (o[l].to_bits() & !m.0[l]));
        }
        V(o)
    }
    /// Lane by lane: not (self < x), set for NaN.
    #[inline(always)]
    pub fn not_below(self, x: f64) -> M<N> {
        M::from_fn(|l| !(self.0[l] < x))
    }
    /// Lane by lane: not (self > x), set for NaN.
    #[inline(always)]
    pub fn not_above(self, x: f64) -> M<N> {
        M::from_fn(|l| !(self.0[l] > x))
    }
    /// Lane by lane: the value is NaN or infinite.
    #[inline(always)]
    pub fn non_finite(self) -> M<N> {
        M::from_fn(|l| !self.0[l].is_finite())
    }
}

/// A lane mask: all bits set (true) or none, per lane, as SIMD compares produce them (a
/// `[bool; N]` went through memory a byte per lane and came back as branches).
#[derive(Clone, Copy, Debug)]
pub struct M<const N: usize>(pub [u64; N]);

impl<const N: usize> M<N> {
    #[inline(always)]
    fn from_fn(f: impl Fn(usize) -> bool) -> Self {
        let mut m = [0u64; N];
        for l in 0..N {
            m[l] = (f(l) as u64).wrapping_neg();
        }
        M(m)
    }
    /// Lane-wise or.
    #[inline(always)]
    pub fn or(self, b: Self) -> Self {
        let mut m = self.0;
        for l in 0..N {
            m[l] |= b.0[l];
        }
        M(m)
    }
    /// Whether any lane is set.
    #[inline(always)]
    pub fn any(self) -> bool {
        self.0.iter().fold(0, |a, &m| a | m) != 0
    }
    /// Whether lane `l` is set.
    #[inline(always)]
    pub fn at(self, l: usize) -> bool {
        self.0[l] != 0
    }
}

/// Stores of lane vectors as rows of points, one row per lane: [`RowStore::rows8`] writes 8 values
/// per point into a (points, 8) block, [`RowStore::rows2`] 2 into a (points, 2) block; `dst`
/// holds exactly `N` rows. The generic version stores value by value; [`Avx2Rows`] transposes
/// in registers (4x4 blocks: two unpacks and a 128-bit permute per row) and stores whole rows.
pub(crate) trait RowStore<const N: usize>: Copy {
    #[inline(always)]
    fn rows8(self, dst: &mut [f64], src: &[V<N>; 8]) {
        for (l, row) in dst.chunks_exact_mut(8).enumerate() {
            for o in 0..8 {
                row[o] = src[o].0[l];
            }
        }
    }
    #[inline(always)]
    fn rows2(self, dst: &mut [f64], a: V<N>, b: V<N>) {
        for (l, row) in dst.chunks_exact_mut(2).enumerate() {
            row[0] = a.0[l];
            row[1] = b.0[l];
        }
    }
}

/// [`RowStore`] value by value, for any lane count.
#[derive(Clone, Copy)]
pub(crate) struct ScalarRows;
impl<const N: usize> RowStore<N> for ScalarRows {}

/// [`RowStore`] for 4 lanes with AVX2 transposes. Only made by [`Avx2Rows::new`], whose caller
/// vouches that the CPU has AVX2; its methods are meant to be inlined into AVX2 code.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(crate) struct Avx2Rows(());

#[cfg(target_arch = "x86_64")]
impl Avx2Rows {
    /// # Safety
    /// The CPU must support AVX2.
    #[inline(always)]
    pub(crate) unsafe fn new() -> Self {
        Avx2Rows(())
    }
}

#[cfg(target_arch = "x86_64")]
impl RowStore<4> for Avx2Rows {
    #[inline(always)]
    fn rows8(self, dst: &mut [f64], src: &[V<4>; 8]) {
        let dst: &mut [f64; 32] = dst.try_into().expect("rows8: 4 rows of 8");
        // SAFETY: an Avx2Rows exists only on a CPU with AVX2 (Avx2Rows::new)
        unsafe { avx2::rows8(dst, src) }
    }
    #[inline(always)]
    fn rows2(self, dst: &mut [f64], a: V<4>, b: V<4>) {
        let dst: &mut [f64; 8] = dst.try_into().expect("rows2: 4 rows of 2");
        // SAFETY: as above
        unsafe { avx2::rows2(dst, a, b) }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::V;
    use std::arch::x86_64::*;

    /// Rows l = 0..4 of [a, b, c, d] (lane l of each): the 4x4 transpose
    /// t0 = [a0 b0 a2 b2], t1 = [a1 b1 a3 b3], t2 = [c0 d0 c2 d2], t3 = [c1 d1 c3 d3];
    /// row 0 = low halves of (t0, t2), row 1 = low (t1, t3), row 2 = high (t0, t2), row 3 = high (t1, t3).
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn transpose4(a: __m256d, b: __m256d, c: __m256d, d: __m256d) -> [__m256d; 4] {
        let (t0, t1) = (_mm256_unpacklo_pd(a, b), _mm256_unpackhi_pd(a, b));
        let (t2, t3) = (_mm256_unpacklo_pd(c, d), _mm256_unpackhi_pd(c, d));
        [
            _mm256_permute2f128_pd(t0, t2, 0x20),
            _mm256_permute2f128_pd(t1, t3, 0x20),
            _mm256_permute2f128_pd(t0, t2, 0x31),
            _mm256_permute2f128_pd(t1, t3, 0x31),
        ]
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn rows8(dst: &mut [f64; 32], src: &[V<4>; 8]) {
        let v = |o: usize| _mm256_loadu_pd(src[o].0.as_ptr());
        let lo = transpose4(v(0), v(1), v(2), v(3));
        let hi = transpose4(v(4), v(5), v(6), v(7));
        let p = dst.as_mut_ptr();
        for l in 0..4 {
            _mm256_storeu_pd(p.add(8 * l), lo[l]);
            _mm256_storeu_pd(p.add(8 * l + 4), hi[l]);
        }
    }

    /// [a0 b0 a1 b1 a2 b2 a3 b3]
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn rows2(dst: &mut [f64; 8], a: V<4>, b: V<4>) {
        let (a, b) = (_mm256_loadu_pd(a.0.as_ptr()), _mm256_loadu_pd(b.0.as_ptr()));
        let (t0, t1) = (_mm256_unpacklo_pd(a, b), _mm256_unpackhi_pd(a, b)); // [a0 b0 a2 b2], [a1 b1 a3 b3]
        let p = dst.as_mut_ptr();
        _mm256_storeu_pd(p, _mm256_permute2f128_pd(t0, t1, 0x20));
        _mm256_storeu_pd(p.add(4), _mm256_permute2f128_pd(t0, t1, 0x31));
    }
}

impl<const N: usize> Add for V<N> {
    type Output = Self;
    #[inline(always)]
    fn add(self, b: Self) -> Self {
        lanewise!(self, b, +)
    }
}
impl<const N: usize> Sub for V<N> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, b: Self) -> Self {
        lanewise!(self, b, -)
    }
}
impl<const N: usize> Mul for V<N> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, b: Self) -> Self {
        lanewise!(self, b, *)
    }
}
impl<const N: usize> Neg for V<N> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        let mut o = self.0;
        for v in o.iter_mut() {
            *v = -*v;
        }
        V(o)
    }
}
impl<const N: usize> AddAssign for V<N> {
    #[inline(always)]
    fn add_assign(&mut self, b: Self) {
        for l in 0..N {
            self.0[l] += b.0[l];
        }
    }
}

impl<const N: usize> Z<N> {
    #[inline(always)]
    pub fn zero() -> Self {
        Z { re: V::zero(), im: V::zero() }
    }
    #[inline(always)]
    pub fn norm_sqr(self) -> V<N> {
        self.re * self.re + self.im * self.im
    }
    #[inline(always)]
    pub fn scale(self, s: V<N>) -> Self {
        Z { re: self.re * s, im: self.im * s }
    }
    /// conj(self) * b
    #[inline(always)]
    pub fn cmul(self, b: Self) -> Self {
        Z { re: self.re * b.re + self.im * b.im, im: self.re * b.im - self.im * b.re }
    }
    /// j * s * self
    #[inline(always)]
    pub fn jscale(self, s: V<N>) -> Self {
        Z { re: -(self.im * s), im: self.re * s }
    }
    #[inline(always)]
    pub fn conj(self) -> Self {
        Z { re: self.re, im: -self.im }
    }
}

impl<const N: usize> Add for Z<N> {
    type Output = Self;
    #[inline(always)]
    fn add(self, b: Self) -> Self {
        Z { re: self.re + b.re, im: self.im + b.im }
    }
}
impl<const N: usize> Sub for Z<N> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, b: Self) -> Self {
        Z { re: self.re - b.re, im: self.im - b.im }
    }
}
impl<const N: usize> Mul for Z<N> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, b: Self) -> Self {
        Z { re: self.re * b.re - self.im * b.im, im: self.re * b.im + self.im * b.re }
    }
}
impl<const N: usize> AddAssign for Z<N> {
    #[inline(always)]
    fn add_assign(&mut self, b: Self) {
        self.re += b.re;
        self.im += b.im;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::C64;
    use proptest::prelude::*;

    fn lanes(v: &[f64]) -> V {
        let mut o = [0.0; L];
        o.copy_from_slice(&v[..L]);
        V(o)
    }

    /// The AVX2 transposed stores write what the value-by-value stores write.
    #[test]
    fn avx2_row_stores_equal_the_scalar_ones() {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            let src: [V<4>; 8] = std::array::from_fn(|o| V(std::array::from_fn(|l| (10 * o + l) as f64 + 0.5)));
            let (mut a, mut b) = ([0.0; 32], [0.0; 32]);
            // SAFETY: the CPU has AVX2 (checked above)
            let fast = unsafe { Avx2Rows::new() };
            fast.rows8(&mut a, &src);
            RowStore::<4>::rows8(ScalarRows, &mut b, &src);
            assert_eq!(a, b);
            assert_eq!(&a[8..16], &[1.5, 11.5, 21.5, 31.5, 41.5, 51.5, 61.5, 71.5]); // point 1's row
            let (mut a2, mut b2) = ([0.0; 8], [0.0; 8]);
            fast.rows2(&mut a2, src[0], src[1]);
            RowStore::<4>::rows2(ScalarRows, &mut b2, src[0], src[1]);
            assert_eq!(a2, b2);
            assert_eq!(a2, [0.5, 10.5, 1.5, 11.5, 2.5, 12.5, 3.5, 13.5]);
        }
    }

    /// Masks follow the scalar comparisons, NaN included, and blends touch only their lanes.
    #[test]
    fn masks_follow_the_scalar_comparisons() {
        let v = V([1.0, f64::NAN, f64::INFINITY, -0.0]);
        let at = |m: M<4>| -> [bool; 4] { std::array::from_fn(|l| m.at(l)) };
        assert_eq!(at(v.not_below(1.0)), [true, true, true, false]);
        assert_eq!(at(v.not_above(0.0)), [false, true, false, true]);
        assert_eq!(at(v.non_finite()), [false, true, true, false]);
        assert!(!V([1.0, 2.0, 3.0, 4.0]).non_finite().any() && v.non_finite().any());
        let blended = V([1.0, 2.0, -0.0, 4.0]).or_where(v.non_finite(), 9.0);
        assert_eq!(blended.0.map(f64::to_bits), [1.0, 9.0, 9.0, 4.0].map(f64::to_bits));
        let kept = V([-0.0; 4]).or_where(v.non_finite().or(V([5.0; 4]).not_above(0.0)), 1.0);
        assert_eq!(kept.0.map(f64::to_bits), [-0.0, 1.0, 1.0, -0.0].map(f64::to_bits));
    }

    proptest! {
        /// Every lane operation equals the scalar complex arithmetic of num-complex, lane by lane.
        #[test]
        fn lane_ops_equal_scalar_complex(a in proptest::collection::vec(-1e3f64..1e3, 4 * L)) {
            let za = Z { re: lanes(&a[0..]), im: lanes(&a[L..]) };
            let zb = Z { re: lanes(&a[2 * L..]), im: lanes(&a[3 * L..]) };
            let s = lanes(&a[2 * L..]);
            let (prod, cprod, sum, diff) = (za * zb, za.cmul(zb), za + zb, za - zb);
            let (js, sc, cj, ns) = (za.jscale(s), za.scale(s), za.conj(), za.norm_sqr());
            for l in 0..L {
                let x = C64::new(za.re.0[l], za.im.0[l]);
                let y = C64::new(zb.re.0[l], zb.im.0[l]);
                let close = |z: C64, re: f64, im: f64| (z.re - re).abs() <= 1e-12 * (1.0 + z.norm()) && (z.im - im).abs() <= 1e-12 * (1.0 + z.norm());
                prop_assert!(close(x * y, prod.re.0[l], prod.im.0[l]));
                prop_assert!(close(x.conj() * y, cprod.re.0[l], cprod.im.0[l]));
                prop_assert!(close(x + y, sum.re.0[l], sum.im.0[l]));
                prop_assert!(close(x - y, diff.re.0[l], diff.im.0[l]));
                prop_assert!(close(C64::new(0.0, s.0[l]) * x, js.re.0[l], js.im.0[l]));
                prop_assert!(close(x * s.0[l], sc.re.0[l], sc.im.0[l]));
                prop_assert!(close(x.conj(), cj.re.0[l], cj.im.0[l]));
                prop_assert!((x.norm_sqr() - ns.0[l]).abs() <= 1e-12 * (1.0 + x.norm_sqr()));
            }
            let v = lanes(&a[0..]).sqrt();
            let r = s.recip();
            for l in 0..L {
                prop_assert!(v.0[l].to_bits() == a[l].sqrt().to_bits());
                prop_assert!(r.0[l] == 1.0 / s.0[l]);
            }
        }
    }
}
