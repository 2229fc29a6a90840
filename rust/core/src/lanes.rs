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
            let v = lanes(&a[0..]).sqrt();
            let r = s.recip();
            for l in 0..L {
                prop_assert!(v.0[l].to_bits() == a[l].sqrt().to_bits());
                prop_assert!(r.0[l] == 1.0 / s.0[l]);
            }
        }
    }
}
