"""Series support impedance (issue 13 item 1): Z_eq = Z_b - Z_b (Z_b + Z_d - w² m_j I)⁻¹ Z_b."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import rotorid
from rotorid import RotoridError
from rotorid.support.series import coefficients_of


def _oracle(zb, zd, m, f):
    """The journal force per unit journal motion, solved with NumPy from the two equations of
    motion: the damper journal y = (Z_b + D)⁻¹ Z_b x with D = Z_d - w² m I, the force on the journal
    Z_b (x - y) = D y (the form without the cancellation of Z_b - Z_b A⁻¹ Z_b when the film is
    much stiffer than the damper)."""
    w = 2 * np.pi * np.asarray(f)
    zb, zd = np.broadcast_to(zb, (w.size, 2, 2)), np.broadcast_to(zd, (w.size, 2, 2))
    m = np.broadcast_to(m, w.shape)
    d = zd - (w ** 2 * m)[:, None, None] * np.eye(2)
    y = np.linalg.solve(zb + d, zb)
    return d @ y


def _random_z(rng, n, scale):
    k = rng.uniform(0.2, 1.0, (n, 2, 2)) * scale * np.array([[1.0, 0.1], [0.1, 1.0]])
    c = rng.uniform(0.2, 1.0, (n, 2, 2)) * scale * 1e-3
    return k + 1j * 2 * np.pi * 50.0 * c


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 40), mass=st.floats(0.0, 50.0),
       sb=st.floats(1e4, 1e9), sd=st.floats(1e4, 1e9))
def test_matches_the_definition(seed, n, mass, sb, sd):
    rng = np.random.default_rng(seed)
    zb, zd = _random_z(rng, n, sb), _random_z(rng, n, sd)
    f = rng.uniform(0.0, 300.0, n)
    got = rotorid.series_impedance(zb, zd, mass, f)
    ref = _oracle(zb, zd, mass, f)
    cond = np.linalg.cond(zb + zd - ((2 * np.pi * f) ** 2 * mass)[:, None, None] * np.eye(2))
    tol = 1e-12 * np.maximum(cond, 1.0)[:, None, None] * np.abs(ref).max(axis=(1, 2), keepdims=True) + 1e-300
    assert np.all(np.abs(got - ref) <= tol)


def test_broadcasting_of_one_matrix_and_one_mass():
    rng = np.random.default_rng(1)
    zb, zd, f = _random_z(rng, 1, 1e7)[0], _random_z(rng, 5, 1e6), np.linspace(10, 200, 5)
    np.testing.assert_allclose(rotorid.series_impedance(zb, zd, 3.0, f), _oracle(zb, zd, 3.0, f), rtol=1e-12)
    # and the definition Z_b - Z_b (Z_b + D)⁻¹ Z_b, where the film is not much stiffer
    d = zd - ((2 * np.pi * f) ** 2 * 3.0)[:, None, None] * np.eye(2)
    np.testing.assert_allclose(zb - zb @ np.linalg.solve(zb + d, np.broadcast_to(zb, d.shape)),
                               _oracle(zb, zd, 3.0, f), rtol=1e-9)
    masses = np.linspace(0.0, 5.0, 5)
    np.testing.assert_allclose(rotorid.series_impedance(zb, zd, masses, f), _oracle(zb, zd, masses, f), rtol=1e-12)


def test_limits():
    rng = np.random.default_rng(2)
    zb, f = _random_z(rng, 4, 3e6), np.array([5.0, 50.0, 100.0, 200.0])
    # a rigid damper passes the film through; a rigid film passes the damper and the journal mass
    rigid = np.broadcast_to(np.eye(2) * 1e16, (4, 2, 2))
    np.testing.assert_allclose(rotorid.series_impedance(zb, rigid, 2.0, f), zb, rtol=1e-7)
    zd = _random_z(rng, 4, 1e6)
    dyn = zd - ((2 * np.pi * f) ** 2 * 2.0)[:, None, None] * np.eye(2)
    np.testing.assert_allclose(rotorid.series_impedance(rigid, zd, 2.0, f), dyn, rtol=1e-7)
    # frequency dependence from the mass alone: constant Z_b, Z_d give a Z_eq that changes with w
    z = rotorid.series_impedance(zb[0], zd[0], 5.0, [10.0, 150.0])
    assert np.abs(z[0] - z[1]).max() > 1e-3 * np.abs(z[0]).max()


def test_agrees_with_the_pedestal_model():
    """A pedestal is a damper journal: the rotor on pedestals sees the series impedance."""
    from rotorid._corecall import core

    rig = rotorid.nsf_rig()
    ped = rotorid.Pedestals(mass_kg=[[12.0, 14.0], [9.0, 11.0]], k=[[[2e7, 1e6], [-2e6, 2.6e7]],
                                                                    [[2.2e7, 0.0], [3e5, 2.8e7]]], c=2500.0)
    f = np.linspace(5.0, 180.0, 30)
    w = 2 * np.pi * f
    k, c = rig.bearings.at()
    ke, ce, _, nb = core.effective_coefficients(np.ascontiguousarray(k.reshape(1, 8)),
                                                np.ascontiguousarray(c.reshape(1, 8)), ped.core_params(), w)
    assert nb == 0
    for b in range(2):
        zb = k[0, b] + 1j * w[:, None, None] * c[0, b]
        zd = ped.k[b] + 1j * w[:, None, None] * ped.c[b]
        # the pedestal's mass per direction: the series formula takes one mass; compare per axis
        # with the x and y masses in turn where they differ, through the full matrix below
        mass = np.diag(ped.mass_kg[b])
        a = zb + zd - w[:, None, None] ** 2 * mass
        ref = zb - zb @ np.linalg.solve(a, zb)
        got_k, got_c = ke.reshape(-1, 2, 2, 2)[:, b], ce.reshape(-1, 2, 2, 2)[:, b]
        np.testing.assert_allclose(got_k + 1j * w[:, None, None] * got_c, ref, rtol=1e-10)
    # with equal masses the public function gives the same
    ped_eq = rotorid.Pedestals(mass_kg=10.0, k=ped.k, c=ped.c)
    ke, ce, _, _ = core.effective_coefficients(np.ascontiguousarray(k.reshape(1, 8)),
                                               np.ascontiguousarray(c.reshape(1, 8)), ped_eq.core_params(), w)
    z = rotorid.series_impedance(k[0, 0] + 1j * w[:, None, None] * c[0, 0],
                                 ped.k[0] + 1j * w[:, None, None] * ped.c[0], 10.0, f)
    kk, cc = coefficients_of(z, f)
    np.testing.assert_allclose(kk, ke.reshape(-1, 2, 2, 2)[:, 0], rtol=1e-10)
    np.testing.assert_allclose(cc, ce.reshape(-1, 2, 2, 2)[:, 0], rtol=1e-10)


@pytest.mark.parametrize("kw, match", [
    (dict(z_bearing=np.ones((3, 2))), "z_bearing has shape"),
    (dict(z_damper=np.ones((2, 2, 2))), "z_damper has shape"),
    (dict(z_bearing=np.full((2, 2), np.nan)), "z_bearing"),
    (dict(journal_mass_kg=-1.0), "journal_mass_kg"),
    (dict(journal_mass_kg=[1.0, 2.0]), "one mass or one per point"),
    (dict(freq_hz=[-5.0, 10.0, 20.0]), "freq_hz"),
    (dict(freq_hz=[]), "freq_hz"),
    (dict(freq_hz=[[1.0]]), "freq_hz"),
    (dict(z_bearing="stiff"), "z_bearing"),
])
def test_bad_input(kw, match):
    args = dict(z_bearing=np.eye(2) * 1e6, z_damper=np.eye(2) * 1e5, journal_mass_kg=1.0, freq_hz=[10.0, 20.0, 30.0])
    with pytest.raises(RotoridError, match=match):
        rotorid.series_impedance(**{**args, **kw})


def test_an_undamped_journal_resonance_is_named():
    # Z_b + Z_d - w² m I = 0 at w² = (kb + kd) / m
    kb, kd, m = 3e6, 1e6, 10.0
    f0 = np.sqrt((kb + kd) / m) / (2 * np.pi)
    with pytest.raises(RotoridError, match="singular at freq_hz"):
        rotorid.series_impedance(np.eye(2) * kb, np.eye(2) * kd, m, [10.0, f0])


def test_coefficients_of_checks_its_arguments():
    with pytest.raises(RotoridError, match="freq_hz"):
        coefficients_of(np.zeros((1, 2, 2), complex), [0.0])
    with pytest.raises(RotoridError, match="expected"):
        coefficients_of(np.zeros((2, 2, 2), complex), [10.0])
