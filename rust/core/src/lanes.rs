//! Lane vectors for the data-parallel kernels: `L` independent points processed in lock-step so
//! that LLVM turns every lane loop into SIMD instructions (AVX2/AVX-512 via runtime dispatch).
//! `V<N>` and `Z<N>` take other lane counts: the identification kernel uses one register's width
//! (8 lanes at AVX-512, 4 at AVX2, 2 at the baseline), since a group wider than the registers
//! holds two or more of them per value and spills.

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
/// wider registers where available (LLVM fuses nothing on its own: the same bits at every level).
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
/// (`repr(transparent)`: an `[f64; N]`, so an AVX2 kernel may move a `V<4>` to and from a register.)
#[derive(Clone, Copy, Debug)]
#[repr(transparent)]
pub struct V<const N: usize = L>(pub [f64; N]);

/// `N` complex values in lock-step, real and imaginary parts in separate lane vectors.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
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
    /// self * b + c per lane, rounded once (a fused multiply-add: the FMA instruction where the
    /// code is compiled with it, else the C library's `fma`, which glibc rounds correctly in
    /// software: the same bits either way; some other C libraries' `fma` is not correctly rounded
    /// on CPUs without FMA).
    #[inline(always)]
    pub fn mul_add(self, b: Self, c: Self) -> Self {
        V(std::array::from_fn(|l| self.0[l].mul_add(b.0[l], c.0[l])))
    }
    /// c - self * b per lane, rounded once (as [`V::mul_add`]).
    #[inline(always)]
    pub fn neg_mul_add(self, b: Self, c: Self) -> Self {
        V(std::array::from_fn(|l| (-self.0[l]).mul_add(b.0[l], c.0[l])))
    }
    /// self * b - c per lane, rounded once (as [`V::mul_add`]).
    #[inline(always)]
    pub fn mul_sub(self, b: Self, c: Self) -> Self {
        V(std::array::from_fn(|l| self.0[l].mul_add(b.0[l], -c.0[l])))
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
    /// acc + |self|^2 in two fused multiply-adds: re^2 + (im^2 + acc).
    #[inline(always)]
    pub fn norm_sqr_add(self, acc: V<N>) -> V<N> {
        self.re.mul_add(self.re, self.im.mul_add(self.im, acc))
    }
    /// acc + conj(self) * b in four fused multiply-adds (re: self.re b.re + (self.im b.im +
    /// acc.re); im: self.re b.im + (acc.im - self.im b.re)).
    #[inline(always)]
    pub fn cmul_add(self, b: Self, acc: Self) -> Self {
        Z { re: self.re.mul_add(b.re, self.im.mul_add(b.im, acc.re)), im: self.re.mul_add(b.im, self.im.neg_mul_add(b.re, acc.im)) }
    }
    /// f - x z0 - y z1 in eight fused multiply-adds, from f's parts inwards: each product's real
    /// and imaginary terms are taken off (or added) in the order x.re, x.im, y.re, y.im.
    #[inline(always)]
    pub fn sub_two_products(f: Self, x: Self, z0: Self, y: Self, z1: Self) -> Self {
        let re = y.im.mul_add(z1.im, y.re.neg_mul_add(z1.re, x.im.mul_add(z0.im, x.re.neg_mul_add(z0.re, f.re))));
        let im = y.im.neg_mul_add(z1.re, y.re.neg_mul_add(z1.im, x.im.neg_mul_add(z0.re, x.re.neg_mul_add(z0.im, f.im))));
        Z { re, im }
    }
    /// acc + self * s, each part in one fused multiply-add.
    #[inline(always)]
    pub fn scale_add(self, s: V<N>, acc: Self) -> Self {
        Z { re: self.re.mul_add(s, acc.re), im: self.im.mul_add(s, acc.im) }
    }
    /// self * s - c, each part in one fused multiply-add.
    #[inline(always)]
    pub fn scale_sub(self, s: V<N>, c: Self) -> Self {
        Z { re: self.re.mul_sub(s, c.re), im: self.im.mul_sub(s, c.im) }
    }
    /// self - j s a, each part in one fused multiply-add (re: a.im s + self.re; im: self.im -
    /// a.re s).
    #[inline(always)]
    pub fn sub_jscale(self, a: Self, s: V<N>) -> Self {
        Z { re: a.im.mul_add(s, self.re), im: a.re.neg_mul_add(s, self.im) }
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
            // the fused forms: the complex value they stand for, and each part rounded once
            // (a fused multiply-add is exact before its rounding: f64::mul_add lane by lane)
            let zc = Z { re: lanes(&a[3 * L..]), im: lanes(&a[L..]) };
            let (nsa, cma) = (za.norm_sqr_add(s), za.cmul_add(zb, zc));
            let (sa, ss, sj) = (za.scale_add(s, zb), za.scale_sub(s, zb), zc.sub_jscale(za, s));
            let two = Z::sub_two_products(zc, za, zb, zb, za);
            for l in 0..L {
                let x = C64::new(za.re.0[l], za.im.0[l]);
                let y = C64::new(zb.re.0[l], zb.im.0[l]);
                let c = C64::new(zc.re.0[l], zc.im.0[l]);
                let sl = s.0[l];
                let close = |z: C64, re: f64, im: f64| (z.re - re).abs() <= 1e-9 * (1.0 + z.norm()) && (z.im - im).abs() <= 1e-9 * (1.0 + z.norm());
                prop_assert!((x.norm_sqr() + sl - nsa.0[l]).abs() <= 1e-9 * (1.0 + x.norm_sqr() + sl.abs()));
                prop_assert!(close(x.conj() * y + c, cma.re.0[l], cma.im.0[l]));
                prop_assert!(close(x * sl + y, sa.re.0[l], sa.im.0[l]));
                prop_assert!(close(x * sl - y, ss.re.0[l], ss.im.0[l]));
                prop_assert!(close(c - C64::new(0.0, sl) * x, sj.re.0[l], sj.im.0[l]));
                prop_assert!(close(c - x * y - y * x, two.re.0[l], two.im.0[l]));
                let (xr, xi, yr, yi, cr, ci) = (x.re, x.im, y.re, y.im, c.re, c.im);
                let bits = |u: f64, v: f64| u.to_bits() == v.to_bits();
                prop_assert!(bits(nsa.0[l], xr.mul_add(xr, xi.mul_add(xi, sl))));
                prop_assert!(bits(cma.re.0[l], xr.mul_add(yr, xi.mul_add(yi, cr))) && bits(cma.im.0[l], xr.mul_add(yi, (-xi).mul_add(yr, ci))));
                prop_assert!(bits(sa.re.0[l], xr.mul_add(sl, yr)) && bits(ss.im.0[l], xi.mul_add(sl, -yi)));
                prop_assert!(bits(sj.re.0[l], xi.mul_add(sl, cr)) && bits(sj.im.0[l], (-xr).mul_add(sl, ci)));
                let re = yi.mul_add(xi, (-yr).mul_add(xr, xi.mul_add(yi, (-xr).mul_add(yr, cr))));
                let im = (-yi).mul_add(xr, (-yr).mul_add(xi, (-xi).mul_add(yr, (-xr).mul_add(yi, ci))));
                prop_assert!(bits(two.re.0[l], re) && bits(two.im.0[l], im));
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
