//! Lane vectors for the data-parallel kernels: `L` independent points processed in lock-step so
//! that LLVM turns every lane loop into SIMD instructions (AVX2/AVX-512 via runtime dispatch).

use std::ops::{Add, AddAssign, Mul, Neg, Sub};

pub const L: usize = 8;

#[derive(Clone, Copy, Debug)]
pub struct V(pub [f64; L]);

#[derive(Clone, Copy, Debug)]
pub struct Z {
    pub re: V,
    pub im: V,
}

macro_rules! lanewise {
    ($a:expr, $b:expr, $op:tt) => {{
        let mut o = [0.0; L];
        for l in 0..L {
            o[l] = $a.0[l] $op $b.0[l];
        }
        V(o)
    }};
}

impl V {
    #[inline(always)]
    pub fn splat(x: f64) -> V {
        V([x; L])
    }
    #[inline(always)]
    pub fn zero() -> V {
        V([0.0; L])
    }
    #[inline(always)]
    pub fn sqrt(self) -> V {
        let mut o = self.0;
        for v in o.iter_mut() {
            *v = v.sqrt();
        }
        V(o)
    }
    #[inline(always)]
    pub fn recip(self) -> V {
        let mut o = self.0;
        for v in o.iter_mut() {
            *v = 1.0 / *v;
        }
        V(o)
    }
}

impl Add for V {
    type Output = V;
    #[inline(always)]
    fn add(self, b: V) -> V {
        lanewise!(self, b, +)
    }
}
impl Sub for V {
    type Output = V;
    #[inline(always)]
    fn sub(self, b: V) -> V {
        lanewise!(self, b, -)
    }
}
impl Mul for V {
    type Output = V;
    #[inline(always)]
    fn mul(self, b: V) -> V {
        lanewise!(self, b, *)
    }
}
impl Neg for V {
    type Output = V;
    #[inline(always)]
    fn neg(self) -> V {
        let mut o = self.0;
        for v in o.iter_mut() {
            *v = -*v;
        }
        V(o)
    }
}
impl AddAssign for V {
    #[inline(always)]
    fn add_assign(&mut self, b: V) {
        for l in 0..L {
            self.0[l] += b.0[l];
        }
    }
}

impl Z {
    #[inline(always)]
    pub fn zero() -> Z {
        Z { re: V::zero(), im: V::zero() }
    }
    #[inline(always)]
    pub fn norm_sqr(self) -> V {
        self.re * self.re + self.im * self.im
    }
    #[inline(always)]
    pub fn scale(self, s: V) -> Z {
        Z { re: self.re * s, im: self.im * s }
    }
    /// conj(self) * b
    #[inline(always)]
    pub fn cmul(self, b: Z) -> Z {
        Z { re: self.re * b.re + self.im * b.im, im: self.re * b.im - self.im * b.re }
    }
    /// j * s * self
    #[inline(always)]
    pub fn jscale(self, s: V) -> Z {
        Z { re: -(self.im * s), im: self.re * s }
    }
    #[inline(always)]
    pub fn conj(self) -> Z {
        Z { re: self.re, im: -self.im }
    }
}

impl Add for Z {
    type Output = Z;
    #[inline(always)]
    fn add(self, b: Z) -> Z {
        Z { re: self.re + b.re, im: self.im + b.im }
    }
}
impl Sub for Z {
    type Output = Z;
    #[inline(always)]
    fn sub(self, b: Z) -> Z {
        Z { re: self.re - b.re, im: self.im - b.im }
    }
}
impl Mul for Z {
    type Output = Z;
    #[inline(always)]
    fn mul(self, b: Z) -> Z {
        Z { re: self.re * b.re - self.im * b.im, im: self.re * b.im + self.im * b.re }
    }
}
impl AddAssign for Z {
    #[inline(always)]
    fn add_assign(&mut self, b: Z) {
        self.re += b.re;
        self.im += b.im;
    }
}
