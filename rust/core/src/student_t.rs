//! Student's t distribution: the cumulative distribution function for any real number of degrees
//! of freedom, for significance tests on estimates whose standard errors come from a few
//! redundant runs.
//!
//! For `ν` degrees of freedom and `x ≤ 0`
//!
//! ```text
//! F(x; ν) = ½ I_z(ν/2, ½),   z = ν / (ν + x²),
//! ```
//!
//! with `I_z(a, b)` the regularized incomplete beta function, and `F(x) = 1 − F(−x)` for `x > 0`.
//! `I_z(a, b)` is evaluated by its continued fraction (DLMF 8.17.22) with the modified Lentz
//! method, on the side where it converges (`z < (a + 1) / (a + b + 2)`, else through
//! `I_z(a, b) = 1 − I_{1−z}(b, a)`); `ln Γ` by the Lanczos approximation (g = 7, 9 terms).

use std::f64::consts::PI;

/// `ln Γ(x)` for `x > 0` (Lanczos, g = 7, nine coefficients; relative error ~1e-15), with the
/// reflection formula below ½.
pub fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const COEF: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Γ(x) Γ(1 − x) = π / sin(π x)
        return (PI / (PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut sum = COEF[0];
    for (i, &c) in COEF.iter().enumerate().skip(1) {
        sum += c / (x + i as f64);
    }
    let t = x + G + 0.5;
    0.5 * (2.0 * PI).ln() + (x + 0.5) * t.ln() - t + sum.ln()
}

/// `ln B(a, b) = ln Γ(a) + ln Γ(b) − ln Γ(a + b)`. Where the larger argument `x` is 20 or more,
/// `ln Γ(x) − ln Γ(x + s)` comes from Stirling's series of both,
/// `−s ln x − (x + s − ½) ln(1 + s/x) + s + r(x) − r(x + s)` with
/// `r(z) = 1/(12z) − 1/(360z³) + 1/(1260z⁵) − 1/(1680z⁷)` (truncation below 1e-15), instead of
/// the difference of two large logarithms (which lost 1e-8 of `F` at 1e9 degrees of freedom).
pub fn ln_beta(a: f64, b: f64) -> f64 {
    let (x, s) = if a >= b { (a, b) } else { (b, a) };
    if x < 20.0 {
        return ln_gamma(a) + ln_gamma(b) - ln_gamma(a + b);
    }
    let r = |z: f64| {
        let z2 = z * z;
        (1.0 / 12.0 - (1.0 / 360.0 - (1.0 / 1260.0 - 1.0 / (1680.0 * z2)) / z2) / z2) / z
    };
    ln_gamma(s) - s * x.ln() - (x + s - 0.5) * (s / x).ln_1p() + s + r(x) - r(x + s)
}

/// The continued fraction of `I_z(a, b)` (DLMF 8.17.22) by the modified Lentz method; converges
/// quickly for `z < (a + 1) / (a + b + 2)`.
fn beta_fraction(a: f64, b: f64, z: f64) -> f64 {
    const TINY: f64 = 1e-300;
    const EPS: f64 = 1e-15;
    let guard = |v: f64| if v.abs() < TINY { TINY } else { v };
    let mut c = 1.0;
    let mut d = 1.0 / guard(1.0 - (a + b) * z / (a + 1.0));
    let mut h = d;
    for m in 1..=1000 {
        let m = m as f64;
        let m2 = 2.0 * m;
        // even step: d_{2m} = m (b − m) z / ((a + 2m − 1)(a + 2m))
        let num = m * (b - m) * z / ((a + m2 - 1.0) * (a + m2));
        d = 1.0 / guard(1.0 + num * d);
        c = guard(1.0 + num / c);
        h *= d * c;
        // odd step: d_{2m+1} = −(a + m)(a + b + m) z / ((a + 2m)(a + 2m + 1))
        let num = -(a + m) * (a + b + m) * z / ((a + m2) * (a + m2 + 1.0));
        d = 1.0 / guard(1.0 + num * d);
        c = guard(1.0 + num / c);
        let step = d * c;
        h *= step;
        if (step - 1.0).abs() < EPS {
            break;
        }
    }
    h
}

/// The regularized incomplete beta function `I_z(a, b)`, `a, b > 0`, `0 ≤ z ≤ 1`; NaN outside.
pub fn incomplete_beta(a: f64, b: f64, z: f64) -> f64 {
    incomplete_beta_split(a, b, z, 1.0 - z)
}

/// `I_z(a, b)` with `zc = 1 − z` given as well (computed without cancellation by the caller where
/// `z` is near 1: `a ln z` with `a` large magnifies the rounding of `z`).
fn incomplete_beta_split(a: f64, b: f64, z: f64, zc: f64) -> f64 {
    if !(a > 0.0 && b > 0.0 && (0.0..=1.0).contains(&z) && (0.0..=1.0).contains(&zc)) {
        return f64::NAN;
    }
    if z == 0.0 || zc == 0.0 {
        return if z == 0.0 { 0.0 } else { 1.0 };
    }
    // z^a (1 − z)^b / B(a, b), the logarithms from whichever of z, 1 − z is the smaller
    let (ln_z, ln_zc) = if z < 0.5 { (z.ln(), (-z).ln_1p()) } else { ((-zc).ln_1p(), zc.ln()) };
    let front = (a * ln_z + b * ln_zc - ln_beta(a, b)).exp();
    if z < (a + 1.0) / (a + b + 2.0) {
        front * beta_fraction(a, b, z) / a
    } else {
        1.0 - front * beta_fraction(b, a, zc) / b
    }
}

/// Degrees of freedom above which [`student_t_cdf`] uses the normal with two corrections.
const LARGE_DOF: f64 = 1e5;

/// `P(T ≤ x)` for Student's t with `dof` degrees of freedom (`dof` > 0, real; the standard normal
/// where `dof` is +inf); NaN for NaN arguments or `dof ≤ 0`. Absolute error ~1e-14.
///
/// Closed forms for checking: `F(x; 1) = ½ + atan(x)/π`, `F(x; 2) = ½ + x / (2 √(2 + x²))`.
pub fn student_t_cdf(x: f64, dof: f64) -> f64 {
    if x.is_nan() || dof.is_nan() || dof <= 0.0 {
        return f64::NAN;
    }
    if dof == f64::INFINITY {
        return 0.5 * erfc(-x / std::f64::consts::SQRT_2);
    }
    if x.is_infinite() {
        return if x > 0.0 { 1.0 } else { 0.0 };
    }
    if dof > LARGE_DOF {
        let tail = 0.5 * erfc(-x / std::f64::consts::SQRT_2);
        let density = (-0.5 * x * x).exp() / (2.0 * std::f64::consts::PI).sqrt();
        if density == 0.0 {
            // |x| > 38: the corrections vanish with the density (their polynomials would overflow)
            return tail;
        }
        // Fisher's expansion F(x; ν) = Φ(x) − φ(x) [g₁(x)/ν + g₂(x)/ν² + O(ν⁻³)],
        // g₁ = (x³ + x)/4, g₂ = (3x⁷ − 7x⁵ − 5x³ − 3x)/96: the continued fraction near its switch
        // point needs ~√ν terms here, and the ν⁻³ term is below 1e-15
        let x2 = x * x;
        let g1 = (x2 + 1.0) * x / 4.0;
        let g2 = (((3.0 * x2 - 7.0) * x2 - 5.0) * x2 - 3.0) * x / 96.0;
        return tail - density * (g1 + g2 / dof) / dof;
    }
    let lower = if x.abs() > 1e150 {
        // z = ν / x² may underflow (a tiny ν keeps a heavy tail there): the leading term of the
        // series, I_z(a, b) = z^a / (a B(a, b)) (1 + O(z)), in logarithms
        let a = 0.5 * dof;
        let ln_z = dof.ln() - 2.0 * x.abs().ln();
        0.5 * (a * ln_z - ln_beta(a, 0.5)).exp() / a
    } else {
        // z = ν / (ν + x²) and 1 − z = x² / (ν + x²), each without cancellation
        let x2 = x * x;
        0.5 * incomplete_beta_split(0.5 * dof, 0.5, dof / (dof + x2), x2 / (dof + x2))
    };
    if x <= 0.0 {
        lower
    } else {
        1.0 - lower
    }
}

/// The `p` quantile of Student's t for `p < ½` (a lower tail, negative): the `x` with
/// `F(x; dof) = p`, by bisection on [`student_t_cdf`] (to the last bits of `x`; ~100 evaluations).
/// −inf where it lies beyond −1e300 (a tiny `dof`); NaN for `p` outside (0, ½) or `dof ≤ 0`.
pub fn student_t_quantile(p: f64, dof: f64) -> f64 {
    if !(p > 0.0 && p < 0.5) || dof.is_nan() || dof <= 0.0 {
        return f64::NAN;
    }
    let (mut lo, mut hi) = (-1.0f64, 0.0f64);
    while student_t_cdf(lo, dof) > p {
        hi = lo;
        lo *= 2.0;
        if lo < -1e300 {
            return f64::NEG_INFINITY;
        }
    }
    // F(lo) <= p < F(hi)
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if student_t_cdf(mid, dof) > p {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

/// The complementary error function, `erfc(x) = Q(½, x²)` for `x ≥ 0`: the regularized upper
/// incomplete gamma function by its series (`x² < 1.5`) or its continued fraction.
fn erfc(x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    if x < 0.0 {
        return 2.0 - erfc(-x);
    }
    if x > 40.0 {
        return 0.0; // below the smallest subnormal (erfc(27) is 5e-319)
    }
    // erfc(x) = Q(½, x²) (the regularized upper incomplete gamma function)
    let s = x * x;
    if s < 1.5 {
        // series of the lower function: P(a, s) = s^a e^-s / Γ(a + 1) Σ s^n / ((a + 1)…(a + n))
        let a = 0.5;
        let (mut term, mut sum) = (1.0 / a, 1.0 / a);
        for n in 1..500 {
            term *= s / (a + n as f64);
            sum += term;
            if term.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        1.0 - sum * (a * s.ln() - s - ln_gamma(a)).exp()
    } else {
        // continued fraction of the upper function (modified Lentz)
        let a = 0.5;
        const TINY: f64 = 1e-300;
        let mut b = s + 1.0 - a;
        let mut c = 1.0 / TINY;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..500 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < TINY {
                d = TINY;
            }
            c = b + an / c;
            if c.abs() < TINY {
                c = TINY;
            }
            d = 1.0 / d;
            let step = d * c;
            h *= step;
            if (step - 1.0).abs() < 1e-16 {
                break;
            }
        }
        (a * s.ln() - s - ln_gamma(a)).exp() * h
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_forms_at_one_and_two_degrees_of_freedom() {
        for i in -400..=400 {
            let x = i as f64 * 0.05;
            let one = 0.5 + x.atan() / PI;
            let two = 0.5 + x / (2.0 * (2.0 + x * x).sqrt());
            assert!((student_t_cdf(x, 1.0) - one).abs() < 1e-13, "dof 1 at {x}");
            assert!((student_t_cdf(x, 2.0) - two).abs() < 1e-13, "dof 2 at {x}");
        }
    }

    #[test]
    fn ln_gamma_at_integers_and_halves() {
        let mut fact = 1.0f64;
        for n in 1..30 {
            // Γ(n) = (n − 1)!
            assert!((ln_gamma(n as f64) - fact.ln()).abs() < 1e-12 * fact.ln().abs().max(1.0), "n = {n}");
            fact *= n as f64;
        }
        assert!((ln_gamma(0.5) - 0.5 * PI.ln()).abs() < 1e-14);
        assert!((ln_gamma(0.25) - 1.288_022_524_698_077_5).abs() < 1e-13);
    }

    #[test]
    fn normal_limit() {
        // Φ(−2) = erfc(√2)/2 and Φ(0) = ½; large dof approach the normal as
        // F(x; ν) = Φ(x) − φ(x) (x³ + x) / (4ν) + O(ν⁻²) (the ν⁻² term is 0.6/ν² at x = −2), on
        // both sides of the switch to the expansion at 1e5
        let phi_m2 = 0.022_750_131_948_179_2;
        assert!((student_t_cdf(-2.0, f64::INFINITY) - phi_m2).abs() < 1e-15);
        assert_eq!(student_t_cdf(0.0, f64::INFINITY), 0.5);
        let density = (-2.0f64).exp() / (2.0 * PI).sqrt();
        for nu in [3e4, 1e5, 1.0001e5, 1e7, 1e9, 1e12] {
            let want = phi_m2 + density * 10.0 / (4.0 * nu);
            let got = student_t_cdf(-2.0, nu);
            assert!((got - want).abs() < 1e-13 + 1.0 / (nu * nu), "dof {nu}: {got:e} against {want:e}");
        }
    }

    #[test]
    fn quantile_inverts_the_cdf_and_known_values() {
        // closed forms: dof 1 tan(pi (p - 1/2)) = -cot(pi p), dof 2 (2p - 1) / sqrt(2 p (1 - p))
        for &p in &[1e-6, 0.001, 0.022_750_131_948_179_2, 0.1, 0.4] {
            let one = -1.0 / (PI * p).tan(); // tan(pi (p - 1/2)) without the rounding near its pole
            let two = (2.0 * p - 1.0) / (2.0 * p * (1.0 - p)).sqrt();
            let (q1, q2) = (student_t_quantile(p, 1.0), student_t_quantile(p, 2.0));
            assert!((q1 / one - 1.0).abs() < 1e-13, "p {p}: {q1:e} against {one:e}");
            assert!((q2 / two - 1.0).abs() < 1e-13, "p {p}: {q2:e} against {two:e}");
            for &dof in &[0.3, 3.7, 50.0, 99_999.0, 1e5 * 1.5, 1e9] {
                let x = student_t_quantile(p, dof);
                assert!((student_t_cdf(x, dof) / p - 1.0).abs() < 1e-10, "p {p} dof {dof}");
            }
        }
        assert_eq!(student_t_quantile(0.01, 1e-4), f64::NEG_INFINITY);
        assert!(student_t_quantile(0.5, 3.0).is_nan() && student_t_quantile(0.1, 0.0).is_nan());
    }

    #[test]
    fn no_nan_far_in_the_tails() {
        // the expansion above 1e5 dof and tiny dof with |x| beyond 1e150 (x² would overflow)
        for &dof in &[1e-3, 0.5, 3.0, 1e5 * 1.0001, 1e9] {
            for &x in &[-1e300, -1e151, -1e45, -40.0] {
                let f = student_t_cdf(x, dof);
                assert!(f.is_finite() && (0.0..0.5).contains(&f), "dof {dof} x {x}: {f}");
            }
        }
        // dof 1: F(x) = 1/2 + atan(x)/pi, still 0.318/|x| at x = -1e151
        assert!((student_t_cdf(-1e151, 1.0) * PI * 1e151 - 1.0).abs() < 1e-12);
        // dof 1e-3 keeps a heavy tail: F(-1e151) is far from 0 (scipy 0.3525), and the two
        // sides of the switch at |x| = 1e150 agree
        let (inner, outer) = (student_t_cdf(-0.999_999e150, 1e-3), student_t_cdf(-1.000_001e150, 1e-3));
        assert!((inner - outer).abs() < 1e-9 && (student_t_cdf(-1e151, 1e-3) - 0.3525).abs() < 1e-3, "{inner} {outer}");
    }

    #[test]
    fn ln_beta_on_both_sides_of_the_stirling_switch() {
        // the recurrence B(a + 1, b) = B(a, b) a / (a + b), across the switch at 20, and the symmetry
        for &b in &[0.5, 1.0, 3.5] {
            for i in 0..60 {
                let a = 15.0 + 0.25 * i as f64;
                let step = ln_beta(a + 1.0, b) - ln_beta(a, b) - (a / (a + b)).ln();
                assert!(step.abs() < 1e-13, "a {a}, b {b}: {step:e}");
                assert_eq!(ln_beta(a, b), ln_beta(b, a));
            }
        }
        // B(1, b) = 1/b
        assert!((ln_beta(1.0, 40.0) + 40f64.ln()).abs() < 1e-14);
    }

    #[test]
    fn symmetric_and_nan_outside_the_domain() {
        for &dof in &[0.3, 1.7, 4.0, 33.3, 1e4] {
            for &x in &[0.1, 1.0, 3.0, 40.0] {
                let s = student_t_cdf(x, dof) + student_t_cdf(-x, dof);
                assert!((s - 1.0).abs() < 1e-14, "dof {dof} x {x}");
            }
        }
        assert!(student_t_cdf(1.0, 0.0).is_nan());
        assert!(student_t_cdf(1.0, -1.0).is_nan());
        assert!(student_t_cdf(f64::NAN, 3.0).is_nan());
        assert_eq!(student_t_cdf(f64::NEG_INFINITY, 3.0), 0.0);
        assert_eq!(student_t_cdf(f64::INFINITY, 3.0), 1.0);
    }
}
