"""The ROSS bridge (rotorid.ross): rotors, imbalances, responses and bearings moved between rotorid
and ROSS, checked by simulating in ROSS and identifying in rotorid (a round trip)."""

import dataclasses
import doctest
import re
import subprocess
import sys
import warnings

import numpy as np
import pytest

ross = pytest.importorskip("ross")

import rotorid  # noqa: E402
from rotorid import RotoridError  # noqa: E402
from rotorid.ross import (  # noqa: E402
    imbalance_from_ross,
    imbalance_to_ross,
    mass_properties,
    rigid_rotor_from_ross,
    sync_response_from_ross,
    to_ross,
)

STEEL_E = 2.0e11
RHO = 7800.0
#: stepped shaft (length m, outer diameter m): nodes 0..6 at z = 0, 0.1, ..., 0.6
SEGMENTS = [(0.1, 0.04), (0.1, 0.06), (0.1, 0.06), (0.1, 0.06), (0.1, 0.06), (0.1, 0.04)]
DISKS = [(2, 12.0, 0.05, 0.09), (4, 7.0, 0.03, 0.05)]  # node, m, Id, Ip
BEARING_NODES = (1, 5)
PROBE_NODES = (0, 6)           # overhung probes, outside the bearings
IMBALANCE_NODES = (2, 4)
RADII = (0.05, 0.04)
RPM = np.linspace(1000.0, 9000.0, 17)
SETS = {"A": rotorid.Imbalance((2e-3, 2e-3), (0.0, 0.0)),
        "B": rotorid.Imbalance((2e-3, 3e-3), (90.0, 0.0)),
        "C": rotorid.Imbalance((1e-3, 2e-3), (0.0, -120.0))}


def shaft(E):
    mat = ross.Material(name=f"Stiff{int(E / STEEL_E)}", rho=RHO, E=E, G_s=E / 2.6)
    return [ross.ShaftElement(L, 0.0, od, material=mat) for L, od in SEGMENTS]


def disks():
    return [ross.DiskElement(n=n, m=m, Id=i_d, Ip=i_p) for n, m, i_d, i_p in DISKS]


def build(E, bearings):
    return ross.Rotor(shaft(E), disks(), list(bearings))


def truth_bearings():
    """Speed-dependent bearings with cross-coupling, different at the two bearings (ROSS tables)."""
    wt = np.linspace(50.0, 1000.0, 8)
    f = wt / 1000.0
    b1 = ross.BearingElement(n=1, kxx=3e6 * (1 + 0.3 * f), kxy=4e5 * f, kyx=-3e5 * f, kyy=4e6 * (1 + 0.2 * f),
                             cxx=1200.0 - 300 * f, cxy=150.0 * f, cyx=90.0 * f, cyy=1500.0 - 200 * f, frequency=wt)
    b2 = ross.BearingElement(n=5, kxx=2e6 * (1 + 0.5 * f), kxy=-2e5 * f, kyx=5e5 * f, kyy=2.6e6 * (1 + 0.1 * f),
                             cxx=900.0 - 100 * f, cxy=-60.0 * f, cyx=200.0 * f, cyy=1100.0 + 100 * f, frequency=wt)
    return b1, b2


def coefficients_of(bearings, w):
    """(n, 2, 2, 2) K and C of ROSS bearing elements at speeds w (rad/s), as ROSS uses them."""
    k = np.array([[b.K(x)[:2, :2] for b in bearings] for x in w])
    c = np.array([[b.C(x)[:2, :2] for b in bearings] for x in w])
    return k, c


def experiment(E):
    """ROSS rotor with the truth bearings, its rigid rotorid model, and the ROSS unbalance runs."""
    bearings = truth_bearings()
    rot = build(E, bearings)
    rr = rigid_rotor_from_ross(rot, BEARING_NODES, [rot.nodes_pos[n] for n in PROBE_NODES],
                               imbalance_nodes=IMBALANCE_NODES, imbalance_radii=RADII)
    w = RPM * np.pi / 30
    runs = {}
    for name, imb in SETS.items():
        resp = rot.run_unbalance_response(frequency=w, **imbalance_to_ross(imb, rotor=rr, ross_rotor=rot))
        runs[name] = sync_response_from_ross(resp, rotor=rr, at="probes", name=name)
    k, c = coefficients_of(bearings, w)
    truth = rotorid.BearingCoefficients(k, c, speed_rpm=RPM)
    # the rigid model's own error: rotorid's rigid rotor on the true bearings vs ROSS's flexible one
    eps = max(np.abs(rotorid.imbalance_response(rr, truth, r.imbalance, speed_rpm=RPM, at="probes").q - r.q).max()
              / np.abs(r.q).max() for r in runs.values())
    return dict(rot=rot, rr=rr, runs=runs, k=k, c=c, eps=eps, bearings=bearings)


@pytest.fixture(scope="module")
def stiff():
    return experiment(1e4 * STEEL_E)


@pytest.fixture(scope="module")
def softer():
    return experiment(1e3 * STEEL_E)


def errors(ident, k, c):
    """Largest error of the points flagged ok, relative to each bearing's largest coefficient."""
    ok = ident.ok
    ek = np.abs(ident.k - k) / np.abs(k).max(axis=(2, 3), keepdims=True)
    ec = np.abs(ident.c - c) / np.abs(c).max(axis=(2, 3), keepdims=True)
    return ek[ok].max(), ec[ok].max()


def quiet(fn, *a, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*a, **kw)


# -- rotor --------------------------------------------------------------------------------------------------------
def test_rigid_rotor_matches_hand_calculation():
    """Stepped solid shaft (cylinders: m, It = m(3r² + L²)/12, Ip = m r²/2) plus disks, by hand."""
    rot = build(1e4 * STEEL_E, truth_bearings())
    z = np.concatenate([[0.0], np.cumsum([L for L, _ in SEGMENTS])])
    parts = []  # (m, z, It about own centre, Ip)
    for i, (L, od) in enumerate(SEGMENTS):
        r = od / 2
        m = RHO * np.pi * r * r * L
        parts.append((m, z[i] + L / 2, m * (3 * r * r + L * L) / 12, m * r * r / 2))
    parts += [(m, z[n], i_d, i_p) for n, m, i_d, i_p in DISKS]
    mass = sum(p[0] for p in parts)
    cg = sum(p[0] * p[1] for p in parts) / mass
    it = sum(p[2] + p[0] * (p[1] - cg) ** 2 for p in parts)
    ip = sum(p[3] for p in parts)
    zp = (0.03, 0.55)
    rr = rigid_rotor_from_ross(rot, BEARING_NODES, zp, imbalance_nodes=IMBALANCE_NODES, imbalance_radii=RADII)
    assert rr.mass_kg == pytest.approx(mass, rel=1e-12)
    assert rr.it_kgm2 == pytest.approx(it, rel=1e-12)
    assert rr.ip_kgm2 == pytest.approx(ip, rel=1e-12)
    assert (rr.l1, rr.l2) == pytest.approx((cg - z[1], z[5] - cg), rel=1e-12)
    assert rr.s == pytest.approx((cg - zp[0], zp[1] - cg), rel=1e-12)
    assert rr.d == pytest.approx((cg - z[2], z[4] - cg), rel=1e-12)
    assert rr.r == RADII
    p = mass_properties(rot)
    assert p["it_yz_kgm2"] == pytest.approx(p["it_kgm2"], rel=1e-12)  # both tilt planes agree
    # probes default to the bearings
    assert rigid_rotor_from_ross(rot, BEARING_NODES).s == pytest.approx((rr.l1, rr.l2))


# -- phase convention -----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("masses, angles", [((2e-3, 0.0), (90.0, 0.0)), ((0.0, 3e-3), (0.0, -45.0)),
                                            ((1e-3, 2e-3), (30.0, 200.0))])
def test_phase_convention_by_simulation(stiff, masses, angles):
    """rotorid's angle φ is ROSS's unbalance_phase -φ: ROSS's response of the converted imbalance is
    rotorid's; the naive phase +φ comes out mirrored (a 90° mass 180° off)."""
    rot, rr = stiff["rot"], stiff["rr"]
    imb = rotorid.Imbalance(masses, angles)
    truth = rotorid.BearingCoefficients(stiff["k"], stiff["c"], speed_rpm=RPM)
    q = rotorid.imbalance_response(rr, truth, imb, speed_rpm=RPM, at="probes").q
    kw = imbalance_to_ross(imb, rotor=rr, ross_rotor=rot)
    np.testing.assert_allclose(kw["unbalance_phase"], -np.deg2rad(angles))
    np.testing.assert_allclose(kw["unbalance_magnitude"], np.multiply(masses, RADII))
    w = RPM * np.pi / 30
    got = sync_response_from_ross(rot.run_unbalance_response(frequency=w, **kw), rotor=rr).q
    scale = np.abs(q).max()
    assert np.abs(got - q).max() < 10 * stiff["eps"] * scale
    naive = dict(kw, unbalance_phase=list(np.deg2rad(angles)))
    bad = sync_response_from_ross(rot.run_unbalance_response(frequency=w, **naive), rotor=rr, imbalance=imb).q
    if any(a % 180 for a, m in zip(angles, masses) if m):
        assert np.abs(bad - q).max() > 0.1 * scale


def test_imbalance_round_trip(stiff):
    rot, rr = stiff["rot"], stiff["rr"]
    for imb in [rotorid.Imbalance((2e-3, 3e-3), (90.0, -30.0)), rotorid.Imbalance((0.0, 1e-3), (0.0, 170.0))]:
        back = imbalance_from_ross(**imbalance_to_ross(imb, rotor=rr, ross_rotor=rot), rotor=rr, ross_rotor=rot)
        np.testing.assert_allclose(back.mass_kg, imb.mass_kg, rtol=1e-12)
        on = np.asarray(imb.mass_kg) > 0
        np.testing.assert_allclose(np.exp(1j * np.deg2rad(back.angle_deg))[on], np.exp(1j * np.deg2rad(imb.angle_deg))[on])
    # two unbalances in one plane add as vectors; a negative magnitude is turned by 180°
    imb = imbalance_from_ross([2, 2, 4], [1e-4, 1e-4, -1e-4], [0.0, np.pi / 2, 0.0], rotor=rr, ross_rotor=rot)
    assert imb.mass_kg == pytest.approx((np.sqrt(2) * 1e-4 / RADII[0], 1e-4 / RADII[1]))
    assert imb.angle_deg[0] == pytest.approx(-45.0)
    assert abs(imb.angle_deg[1]) == pytest.approx(180.0)
    # explicit nodes are checked against the planes
    assert imbalance_to_ross(SETS["B"], rotor=rr, ross_rotor=rot, nodes=(2, 4))["node"] == [2, 4]


# -- round trip ----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("names", ["AB", "ABC"])
def test_round_trip_identifies_ross_bearings(stiff, softer, names):
    """ROSS simulates, rotorid identifies: the known bearings come back. The tolerance is set by the
    shaft's finite stiffness, measured as eps = the rigid model's own response error (ROSS's flexible
    rotor vs rotorid's rigid one on the true bearings); a 10x softer shaft gives 10x the errors."""
    errs = {}
    for case, ex in (("stiff", stiff), ("softer", softer)):
        ident = rotorid.identify_synchronous(ex["rr"], [ex["runs"][n] for n in names])
        assert ident.ok.sum() >= 12  # all but the lowest-amplitude speeds
        errs[case] = errors(ident, ex["k"], ex["c"])
    eps = stiff["eps"]
    assert eps < 3e-5, "the 'rigid' ROSS rotor is not rigid enough to test against"
    ek, ec = errs["stiff"]
    # measured: ek ≈ 8 eps, ec ≈ 21 eps (damping is Im(Z)/Ω: the error grows at low speed)
    assert ek < 30 * eps and ec < 60 * eps, (ek, ec, eps)
    assert softer["eps"] / eps == pytest.approx(10, rel=0.2)
    for i in range(2):
        assert errs["softer"][i] / errs["stiff"][i] == pytest.approx(10, rel=0.3)


def test_round_trip_to_ross_reproduces_response(stiff):
    """The identified bearings, moved back to ROSS with to_ross, reproduce ROSS's original response."""
    ident = rotorid.identify_synchronous(stiff["rr"], list(stiff["runs"].values()))
    nflag = int((~ident.ok).sum())
    assert nflag > 0
    with pytest.warns(UserWarning, match=rf"dropped {nflag} of {RPM.size} points"):
        bearings = to_ross(ident, nodes=BEARING_NODES, tags=("DE", "FE"), rotor=stiff["rot"])
    assert [b.tag for b in bearings] == ["DE", "FE"] and [b.n for b in bearings] == list(BEARING_NODES)
    w = RPM[ident.ok] * np.pi / 30
    np.testing.assert_allclose(bearings[0].frequency, w)
    # the tables ROSS holds are the identified coefficients
    k, c = coefficients_of(bearings, w)
    np.testing.assert_allclose(k, ident.k[ident.ok], rtol=0, atol=1e-6 * np.abs(ident.k).max())
    np.testing.assert_allclose(c, ident.c[ident.ok], rtol=0, atol=1e-3 * np.abs(ident.c).max())
    rot2 = build(1e4 * STEEL_E, bearings)
    for name, imb in SETS.items():
        kw = imbalance_to_ross(imb, rotor=stiff["rr"], ross_rotor=stiff["rot"])
        a = stiff["rot"].run_unbalance_response(frequency=w, **kw).forced_resp
        b = rot2.run_unbalance_response(frequency=w, **kw).forced_resp
        assert np.abs(a - b).max() < 10 * stiff["eps"] * np.abs(a).max(), name  # measured ≈ 2 eps


def test_to_ross_keeps_flagged_points_on_request_and_one_point_is_constant(stiff):
    ident = rotorid.identify_synchronous(stiff["rr"], list(stiff["runs"].values()))
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        b1, _ = to_ross(ident, nodes=BEARING_NODES, drop_flagged=False)
    assert not [w for w in seen if "dropped" in str(w.message)]
    np.testing.assert_allclose(b1.frequency, RPM * np.pi / 30)
    one = dataclasses.replace(ident, ok=np.arange(RPM.size) == 8)
    b1, b2 = quiet(to_ross, one, nodes=BEARING_NODES)
    assert b1.frequency is None
    for b, i in ((b1, 0), (b2, 1)):
        for x in (100.0, 900.0):  # constant
            np.testing.assert_allclose(b.K(x)[:2, :2], ident.k[8, i])
            np.testing.assert_allclose(b.C(x)[:2, :2], ident.c[8, i])


# -- stochastic ----------------------------------------------------------------------------------------------------
def nsf_runs(n_runs, cov_um=None):
    rig = rotorid.nsf_rig()
    rpm = np.linspace(3000.0, 5000.0, 5)
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm) for s in "ABCD"[:n_runs]]
    if cov_um is not None:
        for r in runs:
            r.cov = np.broadcast_to(np.eye(8) * (cov_um * 1e-6) ** 2, (rpm.size, 8, 8)).copy()
    return rig, rpm, runs


def test_stochastic_samples_follow_the_measurement_covariance():
    rig, rpm, runs = nsf_runs(2, cov_um=0.005)
    ident = rotorid.identify_synchronous(rig.rotor, runs)
    assert ident.cov is not None and ident.ok.all()
    st = to_ross(ident, nodes=(1, 5), stochastic=True, n_samples=400, seed=3)
    assert all(isinstance(s, ross.stochastic.ST_BearingElement) for s in st)
    w = rpm * np.pi / 30
    for b, s in enumerate(st):
        els = list(iter(s))
        assert len(els) == 400 and all(e.n == (1, 5)[b] for e in els)
        k = np.array([[e.K(x)[:2, :2] for x in w] for e in els])   # (samples, points, 2, 2)
        c = np.array([[e.C(x)[:2, :2] for x in w] for e in els])
        # mean within 5 standard errors of the mean, spread within 20 % of the identified std
        assert np.all(np.abs(k.mean(0) - ident.k[:, b]) < 5 * ident.k_std[:, b] / np.sqrt(400))
        np.testing.assert_allclose(k.std(0), ident.k_std[:, b], rtol=0.2)
        np.testing.assert_allclose(c.std(0), ident.c_std[:, b], rtol=0.2)
        # correlated as the covariance says: Kxx1 and Kxx2 (report order 0, 1), for bearing 1 and 2
    kxx = np.array([[e.K(w[2])[0, 0] for e in s] for s in st])
    rho = np.corrcoef(kxx)[0, 1]
    cov = ident.cov[2]
    assert rho == pytest.approx(cov[0, 1] / np.sqrt(cov[0, 0] * cov[1, 1]), abs=0.15)
    # same seed, same samples
    again = to_ross(ident, nodes=(1, 5), stochastic=True, n_samples=400, seed=3)
    assert [e.K(w[0])[0, 0] for e in again[0]] == [e.K(w[0])[0, 0] for e in st[0]]


def test_stochastic_residual_errors_and_st_rotor():
    rig, rpm, runs = nsf_runs(3)
    noisy = rotorid.ProbeResolution(noise_m=0.02e-6)
    rng = np.random.default_rng(0)
    runs = [noisy.measure(r, rng) for r in runs]
    ident = rotorid.identify_synchronous(rig.rotor, runs)
    assert ident.std_source == "residual" and ident.cov is None
    st = quiet(to_ross, ident, nodes=(2, 4), stochastic=True, n_samples=300, seed=1, drop_flagged=False)
    w = rpm * np.pi / 30
    k = np.array([[e.K(x)[:2, :2] for x in w] for e in st[1]])
    np.testing.assert_allclose(k.std(0), ident.k_std[:, 1], rtol=0.25)
    # ROSS's stochastic rotor takes them
    st5 = quiet(to_ross, ident, nodes=(2, 4), stochastic=True, n_samples=4, seed=1, drop_flagged=False)
    srot = ross.stochastic.ST_Rotor(shaft(1e4 * STEEL_E), disks(), list(st5))
    res = srot.run_unbalance_response(node=[2], unbalance_magnitude=[1e-4], unbalance_phase=[0.0], frequency_range=w)
    assert res.forced_resp.shape[0] == 4 and np.isfinite(res.forced_resp).all()


def test_stochastic_needs_standard_errors():
    rig, rpm, runs = nsf_runs(2)
    ident = rotorid.identify_synchronous(rig.rotor, runs)
    assert ident.std_source == "none"
    with pytest.raises(RotoridError, match="standard errors"):
        to_ross(ident, nodes=(1, 5), stochastic=True)
    rig, rpm, runs = nsf_runs(2, cov_um=0.005)
    ident = rotorid.identify_synchronous(rig.rotor, runs)
    with pytest.raises(RotoridError, match="n_samples"):
        to_ross(ident, nodes=(1, 5), stochastic=True, n_samples=1)
    with pytest.raises(RotoridError, match="seed"):
        to_ross(ident, nodes=(1, 5), stochastic=True, seed=-1)


# -- impact identifications ----------------------------------------------------------------------------------------
def impact_ident():
    rig = rotorid.nsf_rig()
    f = np.linspace(20.0, 120.0, 21)
    grow = (1 + 0.3 * (f / 100.0) ** 2)[:, None, None, None]
    brg = rotorid.BearingCoefficients(rig.bearings.k[None] * grow, rig.bearings.c[None] / grow, freq_hz=f)
    tests = [rotorid.impact_frf(rig.rotor, brg, speed_rpm=3000.0, freq_hz=f, plane=0.0, direction=d) for d in "xy"]
    tests.append(rotorid.impact_frf(rig.rotor, brg, speed_rpm=3000.0, freq_hz=f, plane=0.1, direction="x"))
    return rotorid.identify_impact(rig.rotor, tests, min_rel_amplitude=0.0), brg


def test_impact_identification_exports_at_running_speed_or_as_table():
    ident, brg = impact_ident()
    assert ident.ok.all()
    b1, b2 = to_ross(ident, nodes=(1, 5), speed_rpm=3000.0)  # 50 Hz, between identified frequencies
    k50, c50 = brg.at(freq_hz=[50.0])
    for b, i in ((b1, 0), (b2, 1)):
        assert b.frequency is None
        np.testing.assert_allclose(b.K(0.0)[:2, :2], k50[0, i], rtol=1e-6, atol=1e-6 * np.abs(k50).max())
        np.testing.assert_allclose(b.C(1e3)[:2, :2], c50[0, i], rtol=1e-6, atol=1e-6 * np.abs(c50).max())
    s1, _ = to_ross(ident, nodes=(1, 5), speed_rpm=3000.0, stochastic=True, n_samples=5, seed=0)
    assert ident.std_source == "residual"
    for e in s1:  # noise-free tests: tiny residual errors, so every sample is the 1X coefficient
        assert e.frequency is None
        np.testing.assert_allclose(e.K(0.0)[:2, :2], k50[0, 0], rtol=1e-6, atol=1e-6 * np.abs(k50).max())
    t1, _ = to_ross(ident, nodes=(1, 5), impact_as="table")
    np.testing.assert_allclose(t1.frequency, 2 * np.pi * ident.freq_hz)
    np.testing.assert_allclose(t1.K(2 * np.pi * 70.0)[:2, :2], ident.k[10, 0], rtol=1e-6)
    with pytest.raises(RotoridError, match="speed_rpm"):
        to_ross(ident, nodes=(1, 5))
    with pytest.raises(RotoridError, match="outside the identified"):
        to_ross(ident, nodes=(1, 5), speed_rpm=9000.0)


# -- bad input -----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("nodes, match", [((1, 1), "same node"), ((-1, 5), "node number"), ((1.5, 5), "node number"),
                                          ((1,), "pair"), ("15", "pair"), ((True, 5), "node number")])
def test_to_ross_bad_nodes(stiff, nodes, match):
    ident = rotorid.identify_synchronous(stiff["rr"], list(stiff["runs"].values()))
    with pytest.raises(RotoridError, match=match):
        quiet(to_ross, ident, nodes=nodes)


def test_to_ross_node_not_in_rotor(stiff):
    ident = rotorid.identify_synchronous(stiff["rr"], list(stiff["runs"].values()))
    with pytest.raises(RotoridError, match="not a node of the ROSS rotor"):
        quiet(to_ross, ident, nodes=(1, 99), rotor=stiff["rot"])


def test_to_ross_empty_or_all_flagged(stiff):
    ident = rotorid.identify_synchronous(stiff["rr"], list(stiff["runs"].values()))
    flagged = dataclasses.replace(ident, ok=np.zeros(RPM.size, bool))
    with pytest.raises(RotoridError, match=f"all {RPM.size} are flagged"):
        to_ross(flagged, nodes=BEARING_NODES)
    nan = dataclasses.replace(ident, k=np.full_like(ident.k, np.nan))
    with pytest.raises(RotoridError, match="no point"):
        to_ross(nan, nodes=BEARING_NODES, drop_flagged=False)
    empty = dataclasses.replace(ident, axis=ident.axis[:0], k=ident.k[:0], c=ident.c[:0], ok=ident.ok[:0])
    with pytest.raises(RotoridError, match="no points"):
        to_ross(empty, nodes=BEARING_NODES)
    with pytest.raises(RotoridError, match="Identification"):
        to_ross(ident.k, nodes=BEARING_NODES)
    with pytest.raises(RotoridError, match="speed_rpm= is for impact"):
        quiet(to_ross, ident, nodes=BEARING_NODES, speed_rpm=3000.0)
    with pytest.raises(RotoridError, match="impact_as"):
        quiet(to_ross, ident, nodes=BEARING_NODES, impact_as="both")


def test_rigid_rotor_bad_input(stiff):
    rot = stiff["rot"]
    with pytest.raises(RotoridError, match="not a node of the ROSS rotor"):
        rigid_rotor_from_ross(rot, (1, 9))
    with pytest.raises(RotoridError, match="must come before bearing 2"):
        rigid_rotor_from_ross(rot, (5, 1))
    with pytest.raises(RotoridError, match="ross.Rotor"):
        rigid_rotor_from_ross(stiff["rr"], (1, 5))
    with pytest.raises(RotoridError, match="off the rotor"):
        rigid_rotor_from_ross(rot, (1, 5), (0.0, 0.9))
    with pytest.raises(RotoridError, match="both probes"):
        rigid_rotor_from_ross(rot, (1, 5), (0.2, 0.2))
    with pytest.raises(RotoridError, match="probe_positions"):
        rigid_rotor_from_ross(rot, (1, 5), (0.0, 0.3, 0.6))
    with pytest.raises(RotoridError, match="probe 1"):
        rigid_rotor_from_ross(rot, (1, 5), (0.6, 0.0))
    with pytest.raises(RotoridError, match="imbalance_radii"):
        rigid_rotor_from_ross(rot, (1, 5), imbalance_nodes=(2, 4), imbalance_radii=(0.05, 0.0))


def test_mismatched_positions_between_the_rotors(stiff):
    rot, rr = stiff["rot"], stiff["rr"]
    resp = rot.run_unbalance_response(frequency=RPM[:3] * np.pi / 30, **imbalance_to_ross(SETS["A"], rotor=rr,
                                                                                         ross_rotor=rot))
    with pytest.raises(RotoridError, match="do not match the rotor's probe positions"):
        sync_response_from_ross(resp, rotor=rr, at="probes", nodes=(1, 5))
    ok = sync_response_from_ross(resp, rotor=rr, at="bearings", nodes=(1, 5))
    np.testing.assert_allclose(ok.at_probes(rr).q, sync_response_from_ross(resp, rotor=rr).q,
                               rtol=0, atol=10 * stiff["eps"] * np.abs(ok.q).max())
    at_bearings = rigid_rotor_from_ross(rot, BEARING_NODES, imbalance_nodes=IMBALANCE_NODES)
    with pytest.raises(RotoridError, match="no node of the ROSS rotor at probe 1"):
        sync_response_from_ross(resp, rotor=dataclasses.replace(at_bearings, s=(0.25, 0.3)))
    with pytest.raises(RotoridError, match="do not match the rotor's imbalance plane positions"):
        imbalance_to_ross(SETS["A"], rotor=rr, ross_rotor=rot, nodes=(1, 4))
    with pytest.raises(RotoridError, match="at neither imbalance plane"):
        imbalance_from_ross([3], [1e-4], [0.0], rotor=rr, ross_rotor=rot)
    with pytest.raises(RotoridError, match="same length"):
        imbalance_from_ross([2, 4], [1e-4], [0.0], rotor=rr, ross_rotor=rot)
    zero = rot.run_unbalance_response(frequency=np.array([0.0, 100.0]),
                                      **imbalance_to_ross(SETS["A"], rotor=rr, ross_rotor=rot))
    with pytest.raises(RotoridError, match="> 0 rad/s"):
        sync_response_from_ross(zero, rotor=rr)
    with pytest.raises(RotoridError, match="forced response"):
        sync_response_from_ross(rot, rotor=rr)


def test_ross_missing_gives_a_clear_error(monkeypatch, stiff):
    import rotorid.ross as bridge

    ident = rotorid.identify_synchronous(stiff["rr"], list(stiff["runs"].values()))
    monkeypatch.setitem(sys.modules, "ross", None)  # import ross -> ImportError
    for call in (lambda: quiet(to_ross, ident, nodes=BEARING_NODES), lambda: rigid_rotor_from_ross(object(), (1, 5)),
                 lambda: imbalance_to_ross(SETS["A"], rotor=stiff["rr"], ross_rotor=object())):
        with pytest.raises(RotoridError, match=re.escape("ROSS is not installed: pip install 'rotorid[ross]'")):
            call()
    assert bridge.ROSS_MISSING == "ROSS is not installed: pip install 'rotorid[ross]'"


def test_import_rotorid_does_not_import_ross():
    code = ("import sys, rotorid, rotorid.ross; rotorid.nsf_rig(); "
            "assert 'ross' not in sys.modules, 'ross imported'")
    subprocess.run([sys.executable, "-c", code], check=True)


# -- documentation -------------------------------------------------------------------------------------------------
def test_docstring_examples():
    import rotorid.ross as bridge

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = doctest.testmod(bridge, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert res.attempted >= 6 and res.failed == 0


def test_docs_examples_run():
    """Every ```python block of docs/ross.md runs, in order, in one namespace (its asserts included)."""
    from docblocks import read, run_python_blocks

    run_python_blocks(read("docs/ross.md"), "docs/ross.md", min_blocks=4)


def test_methods_delegate_to_the_bridge(stiff):
    """RigidRotor.from_ross, Imbalance.to_ross/from_ross and Identification.to_ross are the module functions."""
    rot, rr = stiff["rot"], stiff["rr"]
    probes = [rot.nodes_pos[n] for n in PROBE_NODES]
    assert rotorid.RigidRotor.from_ross(rot, BEARING_NODES, probes, imbalance_nodes=IMBALANCE_NODES,
                                        imbalance_radii=RADII) == rr
    imb = SETS["B"]
    kw = imb.to_ross(rotor=rr, ross_rotor=rot)
    assert kw == imbalance_to_ross(imb, rotor=rr, ross_rotor=rot)
    back = rotorid.Imbalance.from_ross(**kw, rotor=rr, ross_rotor=rot)
    np.testing.assert_allclose(back.mass_kg, imb.mass_kg, rtol=1e-12)
    ident = rotorid.identify_synchronous(rr, list(stiff["runs"].values()))
    a = quiet(ident.to_ross, nodes=BEARING_NODES)
    b = quiet(to_ross, ident, nodes=BEARING_NODES)
    for ea, eb in zip(a, b):
        np.testing.assert_array_equal(ea.frequency, eb.frequency)
        np.testing.assert_array_equal(ea.kxx, eb.kxx)
        np.testing.assert_array_equal(ea.cxy, eb.cxy)


# -- regressions ---------------------------------------------------------------------------------------------------
def test_polar_inertia_is_what_ross_simulates():
    """Shaft elements built with gyroscopic=False have no gyroscopic terms in ROSS: the rigid rotor's Ip
    is then the disks' alone (it was rotor.Ip, shaft included: 5 % response error at 40 000 rpm)."""
    mat = ross.Material(name="StiffGyro", rho=RHO, E=1e4 * STEEL_E, G_s=1e4 * STEEL_E / 2.6)
    rpm = np.array([3000.0, 20000.0, 40000.0])
    imb = rotorid.Imbalance((2e-3, 1e-3), (30.0, 100.0))
    k = np.array([[[3e6, 4e5], [-3e5, 4e6]], [[2e6, 0.0], [0.0, 2.6e6]]])
    c = np.array([[[1200.0, 0.0], [0.0, 1500.0]], [[900.0, 0.0], [0.0, 1100.0]]])
    bc = rotorid.BearingCoefficients(k, c)
    for gyro in (True, False):
        sh = [ross.ShaftElement(0.1, 0.02, od, material=mat, gyroscopic=gyro) for od in (0.1, 0.12, 0.12, 0.12, 0.12, 0.1)]
        brg = [ross.BearingElement(n=n, kxx=kb[0, 0], kxy=kb[0, 1], kyx=kb[1, 0], kyy=kb[1, 1], cxx=cb[0, 0],
                                   cxy=cb[0, 1], cyx=cb[1, 0], cyy=cb[1, 1]) for n, kb, cb in zip((1, 5), k, c)]
        rot = ross.Rotor(sh, [ross.DiskElement(n=2, m=12.0, Id=0.05, Ip=0.01)], brg)
        rr = rigid_rotor_from_ross(rot, (1, 5), imbalance_nodes=(2, 4), imbalance_radii=(0.05, 0.05))
        assert rr.ip_kgm2 == pytest.approx(rot.Ip if gyro else 0.01, rel=1e-12)
        got = sync_response_from_ross(rot.run_unbalance_response(frequency=rpm * np.pi / 30,
                                                                  **imbalance_to_ross(imb, rotor=rr, ross_rotor=rot)),
                                      rotor=rr).q
        want = rotorid.imbalance_response(rr, bc, imb, speed_rpm=rpm, at="probes").q
        assert np.abs(got - want).max() < 1e-4 * np.abs(want).max(), gyro  # measured 1e-6 (the shaft's flexibility)


def test_multirotor_is_refused():
    from ross.multi_rotor import two_shaft_rotor_example

    multi = two_shaft_rotor_example()
    with pytest.raises(RotoridError, match="MultiRotor"):
        rigid_rotor_from_ross(multi, (0, 2))
    with pytest.raises(RotoridError, match="MultiRotor"):
        mass_properties(multi)


def test_bad_extra_arguments_are_refused(stiff):
    """Extra keywords ROSS's BearingElement would swallow silently (a typo) or that clash with what
    to_ross sets, non-sequence tags, non-numeric unbalances: RotoridError, not TypeError/ValueError."""
    ident = rotorid.identify_synchronous(stiff["rr"], list(stiff["runs"].values()))
    for kw, match in ((dict(tags=5), "tags"), (dict(n_lnk=3), "unknown keyword.*n_lnk"), (dict(n=3), "sets n"),
                      (dict(kxx=1.0), "sets kxx"), (dict(frequency=[1.0, 2.0]), "sets frequency"),
                      (dict(n_link="a"), "n_link"), (dict(stochastic=True, n_lnk=3), "ST_BearingElement")):
        with pytest.raises(RotoridError, match=match):
            quiet(to_ross, ident, nodes=BEARING_NODES, **kw)
    b1, _ = quiet(to_ross, ident, nodes=BEARING_NODES, mxx=1.5, scale_factor=2.0)
    assert b1.mxx[0] == 1.5
    rot, rr = stiff["rot"], stiff["rr"]
    with pytest.raises(RotoridError, match="unbalance_phase"):
        imbalance_from_ross([2], [1e-4], ["a"], rotor=rr, ross_rotor=rot)
    with pytest.raises(RotoridError, match=r"imbalance_nodes must be a pair .*\(imbalance plane 1, imbalance plane 2\)"):
        rigid_rotor_from_ross(rot, BEARING_NODES, imbalance_nodes=2)


def test_stochastic_impact_export_between_frequencies_keeps_the_standard_errors():
    """Exported at a speed between two identified frequencies, the samples' spread is the interpolated
    standard error (it was the average of two independent draws: 1/√2 of it midway)."""
    rig = rotorid.nsf_rig()
    f = np.linspace(20.0, 120.0, 21)
    rng = np.random.default_rng(0)
    tests = []
    for plane, d in ((0.0, "x"), (0.0, "y"), (0.1, "x"), (0.1, "y")):
        t = rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=3000.0, freq_hz=f, plane=plane, direction=d)
        t.q = t.q * (1 + 0.01 * (rng.standard_normal(t.q.shape) + 1j * rng.standard_normal(t.q.shape)))
        tests.append(t)
    ident = rotorid.identify_impact(rig.rotor, tests, min_rel_amplitude=0.0)
    assert ident.std_source == "residual"
    i = int(np.searchsorted(f, 52.5))  # 50 and 55 Hz bracket 3150 rpm, midway
    want_k = 0.5 * (ident.k_std[i - 1] + ident.k_std[i])
    want_c = 0.5 * (ident.c_std[i - 1] + ident.c_std[i])
    st = quiet(to_ross, ident, nodes=(1, 5), speed_rpm=3150.0, stochastic=True, n_samples=3000, seed=2,
               drop_flagged=False)
    for b, s in enumerate(st):
        els = list(iter(s))
        k = np.array([e.K(0.0)[:2, :2] for e in els])
        c = np.array([e.C(0.0)[:2, :2] for e in els])
        np.testing.assert_allclose(k.std(0), want_k[b], rtol=0.1)
        np.testing.assert_allclose(c.std(0), want_c[b], rtol=0.1)
        np.testing.assert_allclose(k.mean(0), 0.5 * (ident.k[i - 1, b] + ident.k[i, b]), rtol=0,
                                   atol=5 * want_k[b].max() / np.sqrt(3000))
