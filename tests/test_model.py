import numpy as np
import pytest

import rotorid
from rotorid import BearingCoefficients, Imbalance, RigidRotor, RotoridError

import oracle


def test_nsf_rig_tables_2_to_4():
    rig = rotorid.nsf_rig()
    r = rig.rotor
    assert (r.mass_kg, r.it_kgm2, r.ip_kgm2, r.l1, r.l2) == (45.3, 0.704, 0.299, 0.189, 0.217)
    assert (r.d, r.r, r.s) == ((0.067, 0.102), (0.114, 0.095), (0.119, 0.146))
    assert rig.bearings.k[0, 0, 1] == 5.0e4 and rig.bearings.k[1, 1, 0] == 3.0e4
    assert rig.bearings.c[0, 1, 0] == 800 and rig.bearings.c[1, 1, 1] == 2200
    assert set(rig.imbalances) == {"A", "B", "C", "D"}
    b = rig.imbalances["B"]
    assert b.mass_kg == (4.1e-3, 5.1e-3) and b.angle_deg == (90.0, 0.0)


def test_matrices_match_oracle():
    rig = rotorid.nsf_rig()
    r = rig.rotor
    M, G, K, C = r.matrices(rig.bearings.k, rig.bearings.c)
    Mo, Go, Ko, Co = oracle.matrices(r.mass_kg, r.it_kgm2, r.ip_kgm2, r.l1, r.l2, rig.bearings.k, rig.bearings.c)
    for a, b in [(M, Mo), (G, Go), (K, Ko), (C, Co)]:
        np.testing.assert_allclose(a, b)


def test_imbalance_vector_is_eq4_and_matches_physical_forces():
    rig = rotorid.nsf_rig()
    r = rig.rotor
    imb = Imbalance((2e-3, 3e-3), (30.0, -120.0))
    F = imb.generalized(r)
    np.testing.assert_allclose(F, oracle.imbalance_vector(imb.mass_kg, imb.angle_deg, r.r, r.d))
    # physical check: a mass at angle -phi (rotation x -> y) gives Fx = Re(f e^{jwt}), Fy = Re(-j f e^{jwt});
    # rows 3-4 are sum(z Fx) and -sum(z Fy) with planes at z = -d1, +d2
    f = imb.forcing(r)
    z = np.array([-r.d1, r.d2])
    fx, fy = f, -1j * f
    np.testing.assert_allclose(F, [fx.sum(), fy.sum(), (z * fx).sum(), -(z * fy).sum()])


def test_report_vector_roundtrip_and_order():
    p = np.arange(1.0, 17.0)
    b = BearingCoefficients.from_report_vector(p)
    np.testing.assert_array_equal(b.to_report_vector(), p)
    assert b.k[0, 0, 0] == 1 and b.k[1, 0, 0] == 2 and b.k[0, 0, 1] == 3 and b.k[1, 1, 1] == 8
    assert b.c[1, 1, 0] == 14


def test_table_interpolation_and_range():
    k = np.stack([np.full((2, 2, 2), 1e6), np.full((2, 2, 2), 3e6)])
    c = np.stack([np.full((2, 2, 2), 100.0), np.full((2, 2, 2), 300.0)])
    b = BearingCoefficients(k, c, speed_rpm=[1000, 3000])
    kk, cc = b.at(speed_rpm=[1000, 2000, 3000])
    np.testing.assert_allclose(kk[:, 0, 0, 0], [1e6, 2e6, 3e6])
    np.testing.assert_allclose(cc[:, 1, 1, 1], [100, 200, 300])
    with pytest.raises(RotoridError, match="outside the coefficient table"):
        b.at(speed_rpm=[4000])
    with pytest.raises(RotoridError, match="tabulated over speed_rpm"):
        b.at(freq_hz=[10])


@pytest.mark.parametrize("kw, match", [
    (dict(mass_kg=0), "mass_kg"),
    (dict(mass_kg=-1), "mass_kg"),
    (dict(it_kgm2=0), "it_kgm2"),
    (dict(ip_kgm2=-0.1), "ip_kgm2"),
    (dict(mass_kg=float("nan")), "mass_kg"),
    (dict(l1=-0.3), "span"),
    (dict(s=(0.1, -0.1)), "coincide"),
    (dict(r=(0.1, 0.0)), "radii"),
    (dict(d=(0.1,)), "imbalance planes"),
])
def test_rotor_bad_input(kw, match):
    base = dict(mass_kg=10.0, it_kgm2=0.2, ip_kgm2=0.05, l1=0.2, l2=0.2)
    base.update(kw)
    with pytest.raises(RotoridError, match=match):
        RigidRotor(**base)


def test_bearing_and_imbalance_bad_input():
    with pytest.raises(RotoridError, match="k has shape"):
        BearingCoefficients(np.zeros((2, 2)), np.zeros((2, 2, 2)))
    with pytest.raises(RotoridError, match="c contains NaN"):
        BearingCoefficients(np.zeros((2, 2, 2)), np.full((2, 2, 2), np.nan))
    with pytest.raises(RotoridError, match="mass_kg"):
        Imbalance((-1e-3, 0.0))
    with pytest.raises(RotoridError, match="angle_deg"):
        Imbalance((1e-3, 1e-3), (0.0, float("inf")))
    with pytest.raises(RotoridError, match="strictly increasing"):
        BearingCoefficients(np.zeros((2, 2, 2, 2)), np.zeros((2, 2, 2, 2)), speed_rpm=[2000, 1000])
