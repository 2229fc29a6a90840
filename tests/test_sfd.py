"""Integral squeeze film damper (rotorid.support.sfd): closed-form short-length coefficients against
independent numerical solutions of the same Reynolds equation, the classical full-film values, the
cavitated (pi) film, fluid inertia, the NSF damper of the report's Table 1, bad input and validity
warnings."""

import math
import warnings

import numpy as np
import pytest
from scipy.integrate import simpson
from scipy.linalg import solve_banded

from rotorid.errors import RotoridError
from rotorid.support.sfd import (INERTIA_NEGLIGIBLE_RE, INERTIA_RE_LIMIT, SHORT_LENGTH_MIN_ARC_RATIO,
                                 TEMPORAL_INERTIA_FACTOR, SFDCoefficients, SFDValidityWarning,
                                 SqueezeFilmDamper, nsf_damper)

# a geometry well inside the short-length limits (no validity warning): R = 60 mm, L = 8 mm
GEO = dict(radius_m=0.06, clearance_m=1.5e-4, length_m=0.008, viscosity_pa_s=0.02, spring_stiffness_n_m=1e6)


def damper(lands, **kw):
    p = dict(GEO)
    p.update(kw)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the test geometries must not be outside the model's validity
        return SqueezeFilmDamper(land_arcs_deg=lands, **p)


# --------------------------------------------------------------------------------------------
# Oracle: finite differences in z of the short-length Reynolds equation
#     d/dz (h^3 dp/dz) = 12 mu dh/dt + kappa rho h^2 d2h/dt2,  p(+-L/2) = 0,
# at every angle of a Gauss-Legendre rule over each land, h = c - x cos - y sin; pressures
# integrated numerically over z (Simpson) and theta (Gauss) into the force on the journal.
# --------------------------------------------------------------------------------------------
def film_force(d, lands, disp, vel, acc, *, kappa, nz=41, ngauss=48, clip=False):
    """Force (Fx, Fy) on the journal for the given displacement, velocity and acceleration; each
    of disp, vel, acc is (2,) or (2, nt) (time samples); with clip negative pressures are set to 0."""
    R, c, L, mu, rho = d.radius_m, d.clearance_m, d.length_m, d.viscosity_pa_s, d.density_kg_m3
    disp, vel, acc = (np.asarray(a, float).reshape(2, -1) for a in (disp, vel, acc))
    z = np.linspace(-L / 2, L / 2, nz)
    dz = z[1] - z[0]
    m = nz - 2  # interior nodes; second difference matrix
    A = (np.diag(-2.0 * np.ones(m)) + np.diag(np.ones(m - 1), 1) + np.diag(np.ones(m - 1), -1)) / dz**2
    xg, wg = np.polynomial.legendre.leggauss(ngauss)
    F = np.zeros((2, disp.shape[1]))
    for start, extent in lands:
        t1, t2 = math.radians(start), math.radians(start + extent)
        th = 0.5 * (t2 - t1) * xg + 0.5 * (t1 + t2)
        wt = 0.5 * (t2 - t1) * wg
        cos, sin = np.cos(th)[:, None], np.sin(th)[:, None]  # (ntheta, 1)
        h = c - disp[0] * cos - disp[1] * sin  # (ntheta, nt)
        ht = -(vel[0] * cos + vel[1] * sin)
        htt = -(acc[0] * cos + acc[1] * sin)
        rhs = (12.0 * mu * ht + kappa * rho * h**2 * htt) / h**3  # p'' = rhs (h independent of z)
        P = np.linalg.solve(A, np.ones((m, 1)))[:, :, None] * rhs[None]  # (m, ntheta, nt)
        P = np.concatenate([np.zeros((1,) + P.shape[1:]), P, np.zeros((1,) + P.shape[1:])])
        if clip:
            P = np.maximum(P, 0.0)
        pz = simpson(P, x=z, axis=0)  # (ntheta, nt)
        F[0] -= R * np.sum(wt[:, None] * pz * cos, axis=0)
        F[1] -= R * np.sum(wt[:, None] * pz * sin, axis=0)
    return F


def fd_coefficients(d, *, kappa):
    """C and M (2, 2) by unit velocity and acceleration in x then y (F = -C v - M a)."""
    C = np.zeros((2, 2))
    M = np.zeros((2, 2))
    for j in range(2):
        e = np.eye(2)[j]
        C[:, j] = -film_force(d, d.land_arcs_deg, (0, 0), e, (0, 0), kappa=kappa)[:, 0]
        M[:, j] = -film_force(d, d.land_arcs_deg, (0, 0), (0, 0), e, kappa=kappa)[:, 0]
    return C, M


LAND_SETS = {
    "full": [(0.0, 360.0)],
    "one land at 20 deg": [(20.0, 75.0)],
    "three uneven": [(-10.0, 50.0), (100.0, 80.0), (230.0, 40.0)],
    "four nsf-like": [(-26.0, 52.0), (64.0, 52.0), (154.0, 52.0), (244.0, 52.0)],
    "two wrapping": [(300.0, 100.0), (150.0, 60.0)],
}


@pytest.mark.parametrize("name", list(LAND_SETS))
def test_closed_form_matches_finite_difference_oracle(name):
    d = damper(LAND_SETS[name], density_kg_m3=870.0)
    C_fd, M_fd = fd_coefficients(d, kappa=TEMPORAL_INERTIA_FACTOR)
    scale_c, scale_m = np.abs(C_fd).max(), np.abs(M_fd).max()
    assert np.allclose(d.damping_matrix(), C_fd, rtol=1e-6, atol=1e-6 * scale_c)
    assert np.allclose(d.added_mass_matrix(), M_fd, rtol=1e-6, atol=1e-6 * scale_m)


def test_small_displacement_gives_no_film_stiffness_and_same_damping():
    """Off-center by 1e-6 c the oracle's force for a pure displacement is zero (no squeeze), so the
    film stiffness at the centered position is zero; K is the springs alone."""
    d = damper(LAND_SETS["three uneven"], spring_stiffness_n_m=[[1e6, 2e4], [-3e4, 2e6]])
    eps = 1e-6 * d.clearance_m
    F0 = film_force(d, d.land_arcs_deg, (eps, -eps), (0, 0), (0, 0), kappa=1.2)
    assert np.all(F0 == 0.0)
    F1 = film_force(d, d.land_arcs_deg, (eps, -eps), (1e-3, 0), (0, 0), kappa=1.2)[:, 0]
    assert np.allclose(-F1 / 1e-3, d.damping_matrix()[:, 0], rtol=1e-5, atol=1e-5 * d.damping_matrix().max())
    co = d.coefficients([10.0, 100.0])
    assert np.array_equal(co.K[1], [[1e6, 2e4], [-3e4, 2e6]])


def test_full_film_classical_damping_constant():
    """Full 360 deg open-ends short film: C = pi mu R L^3 / c^3 per axis, no cross terms (the
    axial integral of the parabolic pressure gives L^3/6, times 6 mu / c^3 from the solution)."""
    d = damper([(0.0, 360.0)])
    C = d.damping_matrix()
    expect = math.pi * d.viscosity_pa_s * d.radius_m * d.length_m**3 / d.clearance_m**3
    assert C[0, 0] == pytest.approx(expect, rel=1e-12)
    assert C[1, 1] == pytest.approx(expect, rel=1e-12)
    assert abs(C[0, 1]) < 1e-12 * expect and abs(C[1, 0]) < 1e-12 * expect
    M = d.added_mass_matrix()
    assert M[0, 0] == pytest.approx(math.pi * d.density_kg_m3 * d.radius_m * d.length_m**3 / (10 * d.clearance_m),
                                    rel=1e-12)


def test_touching_lands_make_a_full_film_and_any_start_angle():
    ring = damper([(0.0, 360.0)]).damping_matrix()
    four = damper([(10.0, 90.0), (100.0, 90.0), (190.0, 90.0), (280.0, 90.0)]).damping_matrix()
    shifted = damper([(-725.0, 360.0)]).damping_matrix()
    assert np.allclose(four, ring, rtol=1e-12, atol=1e-12 * ring[0, 0])
    assert np.allclose(shifted, ring, rtol=1e-12, atol=1e-12 * ring[0, 0])


@pytest.mark.parametrize("n", [3, 4, 5, 6])
@pytest.mark.parametrize("center", [0.0, 17.0, 45.0])
def test_symmetric_lands_are_isotropic(n, center):
    d = SqueezeFilmDamper.equal_lands(n, 40.0, first_center_deg=center, **GEO)
    C = d.damping_matrix()
    beta = math.radians(40.0)
    k = d.viscosity_pa_s * d.radius_m * d.length_m**3 / d.clearance_m**3
    assert C[0, 0] == pytest.approx(n * beta / 2 * k, rel=1e-12)
    assert C[1, 1] == pytest.approx(C[0, 0], rel=1e-12)
    assert abs(C[0, 1]) < 1e-12 * C[0, 0]
    assert np.allclose(d.land_arcs_deg[0], (center - 20.0, 40.0))


def test_single_land_anisotropy_and_rotation():
    beta = math.radians(52.0)
    k = GEO["viscosity_pa_s"] * GEO["radius_m"] * GEO["length_m"] ** 3 / GEO["clearance_m"] ** 3
    d = damper([(-26.0, 52.0)])  # centered on +x
    C = d.damping_matrix()
    assert C[0, 0] == pytest.approx(k * (beta + math.sin(beta)) / 2, rel=1e-12)  # stiff along the land normal
    assert C[1, 1] == pytest.approx(k * (beta - math.sin(beta)) / 2, rel=1e-12)
    assert abs(C[0, 1]) < 1e-12 * C[0, 0]
    assert C[0, 0] / C[1, 1] == pytest.approx(14.18, abs=0.01)  # (b + sin b)/(b - sin b)
    # the same land turned by phi: C' = Q C Q^T
    for phi in (30.0, 90.0, 200.0):
        Q = np.array([[math.cos(math.radians(phi)), -math.sin(math.radians(phi))],
                      [math.sin(math.radians(phi)), math.cos(math.radians(phi))]])
        Cr = damper([(-26.0 + phi, 52.0)]).damping_matrix()
        assert np.allclose(Cr, Q @ C @ Q.T, rtol=1e-12, atol=1e-12 * C[0, 0])
    # land centered at 45 deg: cross terms = k sin(beta) / 2, symmetric
    C45 = damper([(19.0, 52.0)]).damping_matrix()
    assert C45[0, 1] == pytest.approx(k * math.sin(beta) / 2, rel=1e-12)
    assert C45[1, 0] == C45[0, 1]


# --------------------------------------------------------------------------------------------
# cavitated (pi) film
# --------------------------------------------------------------------------------------------
def test_pi_film_halves_full_film():
    full = damper([(0.0, 360.0)])
    pi = damper([(0.0, 360.0)], cavitation="pi")
    k = math.pi * full.viscosity_pa_s * full.radius_m * full.length_m**3 / full.clearance_m**3
    assert pi.damping_matrix()[0, 0] == pytest.approx(k / 2, rel=1e-12)
    assert np.allclose(pi.damping_matrix(), full.damping_matrix() / 2, rtol=1e-14, atol=1e-14 * k)
    assert np.allclose(pi.added_mass_matrix(), full.added_mass_matrix() / 2, rtol=1e-14)


@pytest.mark.parametrize("name", ["full", "one land at 20 deg", "three uneven", "four nsf-like"])
@pytest.mark.parametrize("orbit", [(1.0, 0.0), (1.0, 1.0j), (0.3 + 0.2j, -0.7 + 0.5j)])
def test_pi_film_is_first_harmonic_of_rectified_pressure(name, orbit):
    """Time-domain oracle: a small harmonic orbit X e^{jwt} (line, circle, ellipse); at every instant
    the pressure is the full-film pressure with its negative part set to ambient (0); the first
    harmonic of the force must equal -(j w C_pi - w^2 M_pi) X."""
    lands = LAND_SETS[name]
    d = damper(lands, cavitation="pi", density_kg_m3=850.0)
    f = 120.0
    w = 2 * np.pi * f
    X = 1e-7 * np.asarray(orbit)  # (2,) complex amplitudes
    N = 64  # even: a half-wave rectified sinusoid has no odd harmonics above the first to alias
    t = np.arange(N) / (N * f)
    e = np.exp(1j * w * t)
    disp = np.zeros((2, N))  # centered (linearized) film
    vel = np.real(1j * w * X[:, None] * e)
    acc = np.real(-(w**2) * X[:, None] * e)
    F = film_force(d, lands, disp, vel, acc, kappa=TEMPORAL_INERTIA_FACTOR, clip=True)
    F1 = 2.0 / N * (F @ np.conj(e))  # first harmonic, complex amplitudes
    expect = -(1j * w * d.damping_matrix() - w**2 * d.added_mass_matrix()) @ X
    assert np.allclose(F1, expect, rtol=1e-9, atol=1e-9 * np.abs(expect).max())
    # and not the full film: the rectification really removes half
    full = damper(lands, density_kg_m3=850.0)
    assert np.allclose(2 * d.damping_matrix(), full.damping_matrix(), rtol=1e-14,
                       atol=1e-14 * full.damping_matrix().max())


# --------------------------------------------------------------------------------------------
# fluid inertia
# --------------------------------------------------------------------------------------------
def exact_film_factor(re_s, n=4001):
    """Linearized oscillating laminar flow across a film of thickness 1 (unsteady Stokes),
    mu U'' - j w rho U = G, U(0) = U(h) = 0, solved by finite differences in y; returns
    f = q / (-G h^3 / (12 mu)), so that the exact film impedance is (j w C_viscous) / f."""
    y = np.linspace(0.0, 1.0, n)
    dy = y[1] - y[0]
    m = n - 2
    ab = np.zeros((3, m), dtype=complex)  # mu = 1, h = 1: U'' - j Re_s U = 1
    ab[0, 1:] = 1.0 / dy**2
    ab[2, :-1] = 1.0 / dy**2
    ab[1, :] = -2.0 / dy**2 - 1j * re_s
    U = np.concatenate([[0.0], solve_banded((1, 1), ab, np.ones(m, dtype=complex)), [0.0]])
    q = simpson(U.real, x=y) + 1j * simpson(U.imag, x=y)
    return q / (-1.0 / 12.0)


def test_temporal_inertia_factor_is_small_re_limit_of_exact_laminar_film():
    """kappa = 12/10: 1/f = 1 + j kappa Re_s / 12 + O(Re_s^2) for the exact oscillating flow; a
    uniform-profile (momentum-averaged) model would give kappa = 1."""
    for re_s in (1e-3, 1e-2):
        inv = 1.0 / exact_film_factor(re_s)
        kappa = 12.0 * inv.imag / re_s
        assert kappa == pytest.approx(TEMPORAL_INERTIA_FACTOR, rel=1e-4)
        assert abs(kappa - 1.0) > 0.1


def test_constant_coefficients_track_exact_laminar_film_up_to_re_limit():
    """Below INERTIA_RE_LIMIT the constant C and M model stays within 1 % of the exact linearized
    laminar film impedance j w C / f(Re_s) (full film); above it the gap grows."""
    d = damper([(0.0, 360.0)], density_kg_m3=850.0)
    C, M = d.damping_matrix()[0, 0], d.added_mass_matrix()[0, 0]
    re_per_hz = d.squeeze_reynolds(1.0)[0]
    errs = {}
    for re_s in (0.5, 2.0, 5.0, INERTIA_RE_LIMIT, 50.0):
        fz = re_s / re_per_hz
        w = 2 * np.pi * fz
        exact = 1j * w * C / exact_film_factor(re_s)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SFDValidityWarning)
            model = d.impedance(fz)[0, 0, 0] - d.stiffness_matrix()[0, 0]
        assert model == pytest.approx(1j * w * C - w**2 * M, rel=1e-12)
        errs[re_s] = abs(model - exact) / abs(exact)
    assert all(errs[r] < 0.01 for r in (0.5, 2.0, 5.0, INERTIA_RE_LIMIT))
    assert errs[50.0] > 0.03


def test_inertia_scales_with_density_and_reynolds_number():
    lands = LAND_SETS["three uneven"]
    d1 = damper(lands, density_kg_m3=800.0)
    d2 = damper(lands, density_kg_m3=1600.0)
    assert np.allclose(d2.added_mass_matrix(), 2 * d1.added_mass_matrix(), rtol=1e-14)
    assert np.array_equal(d1.damping_matrix(), d2.damping_matrix())
    f = np.array([0.0, 5.0, 20.0, 60.0])
    co = d1.coefficients(f)
    re = 800.0 * 2 * np.pi * f * GEO["clearance_m"] ** 2 / GEO["viscosity_pa_s"]
    assert np.allclose(co.Re_s, re, rtol=1e-14)
    assert np.allclose(d2.coefficients(f).Re_s, 2 * re, rtol=1e-14)
    # inertia force / damping force = w M / C = Re_s / 10 (kappa / 12) for every land set
    w = 2 * np.pi * f[1:]
    ratio = w * co.M[1:, 0, 0] / co.C[1:, 0, 0]
    assert np.allclose(ratio, co.Re_s[1:] * TEMPORAL_INERTIA_FACTOR / 12, rtol=1e-12)
    # no inertia: M = 0, C unchanged
    d0 = damper(lands, density_kg_m3=800.0, inertia=False)
    assert np.all(d0.coefficients(f[:2]).M == 0.0)
    assert np.array_equal(d0.damping_matrix(), d1.damping_matrix())


def test_coefficients_shapes_and_impedance():
    d = damper(LAND_SETS["three uneven"], spring_stiffness_n_m=[[2e6, 1e5], [1e5, 3e6]])
    f = np.linspace(0.0, 80.0, 9)
    co = d.coefficients(f)
    assert isinstance(co, SFDCoefficients)
    assert co.K.shape == co.C.shape == co.M.shape == (9, 2, 2) and co.Re_s.shape == (9,)
    Z = d.impedance(f)
    assert Z.shape == (9, 2, 2) and np.iscomplexobj(Z)
    for i, fi in enumerate(f):
        w = 2 * np.pi * fi
        expect = np.array([[2e6, 1e5], [1e5, 3e6]]) + 1j * w * d.damping_matrix() - w**2 * d.added_mass_matrix()
        assert np.allclose(Z[i], expect, rtol=1e-14, atol=1e-9)
    assert d.coefficients(25.0).C.shape == (1, 2, 2)


# --------------------------------------------------------------------------------------------
# the NSF damper (report Table 1)
# --------------------------------------------------------------------------------------------
def test_nsf_damper_numbers():
    with pytest.warns(SFDValidityWarning, match=r"SHORT_LENGTH_MIN_ARC_RATIO") as rec:
        d = nsf_damper(spring_stiffness_n_m=4.0e6)
    assert "1.9" in str(rec[0].message) and "43.8 mm" in str(rec[0].message)
    assert d.radius_m == 48.26e-3 and d.clearance_m == 0.229e-3 and d.length_m == 23.0e-3
    assert d.viscosity_pa_s == 15.76e-3 and d.density_kg_m3 == 850.0
    assert len(d.land_arcs_deg) == 4 and all(e == 52.0 for _, e in d.land_arcs_deg)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no Re_s warning up to 150 Hz
        co = d.coefficients([50.0, 150.0])
    beta = math.radians(52.0)
    c_expect = 15.76e-3 * 48.26e-3 * 23e-3**3 / 0.229e-3**3 * 4 * beta / 2
    m_expect = 850.0 * 48.26e-3 * 23e-3**3 / (10 * 0.229e-3) * 4 * beta / 2
    assert co.C[0, 0, 0] == pytest.approx(c_expect, rel=1e-12)
    assert co.C[0, 0, 0] == pytest.approx(1398.7, abs=0.05)  # N s/m, docs/sfd.md
    assert co.C[0, 1, 1] == pytest.approx(1398.7, abs=0.05)
    assert abs(co.C[0, 0, 1]) < 1e-9
    assert co.M[0, 0, 0] == pytest.approx(m_expect, rel=1e-12)
    assert co.M[0, 0, 0] == pytest.approx(0.3956, abs=5e-5)  # kg
    assert co.Re_s == pytest.approx([0.8886, 2.6657], abs=5e-5)
    assert np.array_equal(co.K[1], 4e6 * np.eye(2))
    with pytest.warns(SFDValidityWarning):
        dpi = nsf_damper(spring_stiffness_n_m=4.0e6, cavitation="pi")
    assert dpi.damping_matrix()[0, 0] == pytest.approx(1398.7 / 2, abs=0.05)
    with pytest.raises(TypeError):
        nsf_damper()  # the spring stiffness is not in the report: no default


# --------------------------------------------------------------------------------------------
# validity warnings
# --------------------------------------------------------------------------------------------
def test_short_length_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        SqueezeFilmDamper(land_arcs_deg=[(0.0, 360.0)], **GEO)  # no arc ends, L/D = 0.067
        SqueezeFilmDamper(land_arcs_deg=[(0.0, 40.0)], **GEO)  # ratio 5.2
    ratio_ok = GEO["radius_m"] * math.radians(40.0) / GEO["length_m"]
    assert ratio_ok > SHORT_LENGTH_MIN_ARC_RATIO
    with pytest.warns(SFDValidityWarning, match=r"SHORT_LENGTH_MIN_ARC_RATIO"):
        SqueezeFilmDamper(land_arcs_deg=[(0.0, 25.0)], **GEO)  # ratio 3.3
    p = dict(GEO, length_m=0.08)
    with pytest.warns(SFDValidityWarning, match=r"SHORT_LENGTH_MAX_L_OVER_D"):
        SqueezeFilmDamper(land_arcs_deg=[(0.0, 360.0)], **p)  # L/D = 0.67


def test_reynolds_number_warnings():
    d = damper([(0.0, 360.0)], density_kg_m3=850.0)
    f_limit = INERTIA_RE_LIMIT / d.squeeze_reynolds(1.0)[0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        d.coefficients([0.5 * f_limit, 0.99 * f_limit])
    with pytest.warns(SFDValidityWarning, match=r"INERTIA_RE_LIMIT"):
        co = d.coefficients([0.5 * f_limit, 2 * f_limit])
    assert co.Re_s[1] == pytest.approx(2 * INERTIA_RE_LIMIT)  # still computed
    d0 = damper([(0.0, 360.0)], density_kg_m3=850.0, inertia=False)
    f1 = INERTIA_NEGLIGIBLE_RE / d.squeeze_reynolds(1.0)[0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        d0.coefficients(0.9 * f1)
    with pytest.warns(SFDValidityWarning, match=r"INERTIA_NEGLIGIBLE_RE"):
        d0.impedance(3 * f1)


# --------------------------------------------------------------------------------------------
# bad input
# --------------------------------------------------------------------------------------------
BAD = [
    (dict(radius_m=0.0), "radius_m"),
    (dict(radius_m=-0.05), "radius_m"),
    (dict(clearance_m=0.0), "clearance_m"),
    (dict(clearance_m=-1e-4), "clearance_m"),
    (dict(clearance_m=0.07), "clearance_m"),
    (dict(length_m=0.0), "length_m"),
    (dict(length_m=-0.01), "length_m"),
    (dict(viscosity_pa_s=0.0), "viscosity_pa_s"),
    (dict(viscosity_pa_s=-1e-3), "viscosity_pa_s"),
    (dict(density_kg_m3=-1.0), "density_kg_m3"),
    (dict(radius_m=float("nan")), "radius_m"),
    (dict(clearance_m=float("inf")), "clearance_m"),
    (dict(viscosity_pa_s=float("nan")), "viscosity_pa_s"),
    (dict(density_kg_m3=float("nan")), "density_kg_m3"),
    (dict(radius_m="0.05"), "radius_m"),
    (dict(length_m=None), "length_m"),
    (dict(viscosity_pa_s=True), "viscosity_pa_s"),
    (dict(density_kg_m3=[850.0]), "density_kg_m3"),
    (dict(spring_stiffness_n_m=-1.0), "spring_stiffness_n_m"),
    (dict(spring_stiffness_n_m=[1e6, 1e6]), "spring_stiffness_n_m"),
    (dict(spring_stiffness_n_m=[[1e6, 0.0], [0.0, float("nan")]]), "spring_stiffness_n_m"),
    (dict(spring_stiffness_n_m=[[-1e6, 0.0], [0.0, 1e6]]), "spring_stiffness_n_m"),
    (dict(spring_stiffness_n_m="stiff"), "spring_stiffness_n_m"),
    (dict(cavitation="half"), "cavitation"),
    (dict(cavitation=None), "cavitation"),
    (dict(inertia="yes"), "inertia"),
    (dict(inertia=1), "inertia"),
    (dict(land_arcs_deg=[]), "land_arcs_deg"),
    (dict(land_arcs_deg="0,360"), "land_arcs_deg"),
    (dict(land_arcs_deg=None), "land_arcs_deg"),
    (dict(land_arcs_deg=42.0), "land_arcs_deg"),
    (dict(land_arcs_deg=[(0.0, 40.0, 1.0)]), "land_arcs_deg[0]"),
    (dict(land_arcs_deg=[(0.0, 0.0)]), "extent_deg must be > 0"),
    (dict(land_arcs_deg=[(0.0, 40.0), (90.0, -10.0)]), "land_arcs_deg[1] extent_deg"),
    (dict(land_arcs_deg=[(0.0, 400.0)]), "extent_deg must be <= 360"),
    (dict(land_arcs_deg=[(0.0, 200.0), (200.0, 170.0)]), "more than 360"),
    (dict(land_arcs_deg=[(0.0, 60.0), (50.0, 40.0)]), "overlap"),
    (dict(land_arcs_deg=[(350.0, 40.0), (20.0, 40.0)]), "overlap"),  # across 0 deg
    (dict(land_arcs_deg=[(-30.0, 60.0), (690.0, 20.0)]), "overlap"),  # 690 = -30 (mod 360)
    (dict(land_arcs_deg=[(float("nan"), 40.0)]), "start_deg"),
    (dict(land_arcs_deg=[(0.0, "40")]), "extent_deg"),
    (dict(land_arcs_deg=np.zeros((2, 3))), "land_arcs_deg"),
]


@pytest.mark.parametrize("change,what", BAD, ids=[f"{i}-{w}" for i, (_, w) in enumerate(BAD)])
def test_bad_input_names_the_parameter(change, what):
    p = dict(GEO, land_arcs_deg=[(0.0, 360.0)])
    p.update(change)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SFDValidityWarning)
        with pytest.raises(RotoridError, match=__import__("re").escape(what)):
            SqueezeFilmDamper(**p)


@pytest.mark.parametrize("freq,what", [(-1.0, "freq_hz"), (float("nan"), "freq_hz"), ([[1.0, 2.0]], "freq_hz"),
                                       ([], "freq_hz"), ("50", "freq_hz"), (1j, "freq_hz")])
def test_bad_frequencies(freq, what):
    d = damper([(0.0, 360.0)])
    with pytest.raises(RotoridError, match=what):
        d.coefficients(freq)
    with pytest.raises(RotoridError, match=what):
        d.impedance(freq)


def test_equal_lands_bad_input_and_good_layout():
    with pytest.raises(RotoridError, match="more than 360"):
        SqueezeFilmDamper.equal_lands(4, 100.0, **GEO)
    with pytest.raises(RotoridError, match="n must"):
        SqueezeFilmDamper.equal_lands(0, 40.0, **GEO)
    with pytest.raises(RotoridError, match="n must"):
        SqueezeFilmDamper.equal_lands(2.5, 40.0, **GEO)
    with pytest.raises(RotoridError, match="extent_deg"):
        SqueezeFilmDamper.equal_lands(4, -40.0, **GEO)
    with pytest.raises(RotoridError, match="first_center_deg"):
        SqueezeFilmDamper.equal_lands(4, 40.0, first_center_deg=float("nan"), **GEO)
    with pytest.raises(RotoridError, match="land_arcs_deg"):
        SqueezeFilmDamper.equal_lands(4, 40.0, land_arcs_deg=[(0, 10)], **GEO)
    d = SqueezeFilmDamper.equal_lands(3, 40.0, first_center_deg=90.0, **GEO)
    assert d.land_arcs_deg == ((70.0, 40.0), (190.0, 40.0), (310.0, 40.0))
    # four 90-deg lands touching: a full film, no short-length warning (no arc ends)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        full = SqueezeFilmDamper.equal_lands(4, 90.0, **GEO)
    assert full.damping_matrix()[0, 0] == pytest.approx(damper([(0.0, 360.0)]).damping_matrix()[0, 0], rel=1e-12)


def test_frozen_and_normalized():
    d = damper(np.array([[0.0, 360.0]]), spring_stiffness_n_m=np.float64(2e6))
    assert d.land_arcs_deg == ((0.0, 360.0),)
    assert d.spring_stiffness_n_m == ((2e6, 0.0), (0.0, 2e6))
    with pytest.raises(Exception):
        d.radius_m = 1.0
    assert d == damper([(0, 360)], spring_stiffness_n_m=2e6)
