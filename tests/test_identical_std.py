"""Residual-based standard errors of identical bearings (identify::identical): each row of Z is
fitted to both bearings' equations, whose errors differ and correlate; the standard errors and
their degrees of freedom follow from that structure (a NumPy oracle here, and Monte Carlo
coverage)."""

import dataclasses

import numpy as np
import pytest
from scipy import stats

import rotorid
from rotorid import BearingCoefficients, ImpactResponse, RotoridError
from rotorid._corecall import core as _core
from rotorid.identify import NEGATIVE_DAMPING

RIG = rotorid.nsf_rig()
RPM = np.arange(2000.0, 9001.0, 250.0)


def _identical_bearings(zero_cxx=False):
    k = np.array(RIG.bearings.k, float)
    c = np.array(RIG.bearings.c, float)
    k[1], c[1] = k[0], c[0]
    if zero_cxx:
        c[:, 0, 0] = 0.0
    return BearingCoefficients(k=k, c=c)


def _forces(rotor, q, e, w, sigma, spin):
    """[f1x, f2x, f1y, f2y] of responses q (..., 4) [x1, x2, y1, y2] and excitations e (..., 4)
    (gain included): the four rotor equations R = E - s^2 M q - s Omega G q (eq. 10 / 26) solved for
    the bearing reactions."""
    m, it, ip, l1, l2 = rotor.core_params()
    span = l1 + l2
    s = sigma + 1j * w
    m_q = np.stack([(q[..., 0] * l2 + q[..., 1] * l1) * m / span, (q[..., 2] * l2 + q[..., 3] * l1) * m / span,
                    (q[..., 1] - q[..., 0]) * it / span, (q[..., 2] - q[..., 3]) * it / span], -1)
    g_q = np.stack([0 * q[..., 0], 0 * q[..., 0], q[..., 3] - q[..., 2], q[..., 1] - q[..., 0]], -1)
    r = e - (s ** 2)[..., None] * m_q - (s * spin * ip / span)[..., None] * g_q
    return np.stack([(r[..., 0] * l2 - r[..., 2]) / span, (r[..., 2] + r[..., 0] * l1) / span,
                     (r[..., 1] * l2 + r[..., 3]) / span, (r[..., 1] * l1 - r[..., 3]) / span], -1)


def _oracle(rotor, qs, es, w, sigma, spin, k, c, planes=None):
    """(k_std, c_std (n, 2, 2, 2), dof (n, 2)) written out with dense matrices: the sandwich
    G^-1 X^H (I kron sigma^2 P) X G^-1 of least squares, sigma^2 from the residual over
    tr((I - H)(I kron P)), Satterthwaite's dof. ``qs`` (R, n, 4) at the bearings, ``planes`` the
    (2, 2) transform from where the noise is white (the probes) to the bearings."""
    R, n = qs.shape[:2]
    z = (k[:, 0] + sigma[:, None, None] * c[:, 0]) + 1j * w[:, None, None] * c[:, 0]  # (n, row, col)
    f = np.stack([_forces(rotor, qs[r], es[r], w, sigma, spin) for r in range(R)], 1)  # (n, R, 4)
    X = np.empty((n, 2 * R, 2), complex)
    X[:, 0::2] = qs.transpose(1, 0, 2)[:, :, [0, 2]]
    X[:, 1::2] = qs.transpose(1, 0, 2)[:, :, [1, 3]]
    G = np.conj(X.transpose(0, 2, 1)) @ X
    Gi = np.linalg.inv(G)
    H = X @ Gi @ np.conj(X.transpose(0, 2, 1))
    jac = np.stack([_forces(rotor, np.broadcast_to(np.eye(4)[j], (n, 4)).astype(complex), np.zeros((n, 4)), w, sigma,
                            spin) for j in range(4)], -1)  # (n, force, q)
    T4 = np.eye(4) if planes is None else np.kron(np.eye(2), np.asarray(planes))
    ks, cs, dof = np.empty((n, 2, 2)), np.empty((n, 2, 2)), np.empty((n, 2))
    for row in range(2):
        rhs = np.empty((n, 2 * R), complex)
        rhs[:, 0::2], rhs[:, 1::2] = f[:, :, 2 * row], f[:, :, 2 * row + 1]
        rss = (np.abs(rhs - (X @ z[:, row, :, None])[..., 0]) ** 2).sum(1)
        B = jac[:, 2 * row:2 * row + 2].copy()
        B[:, 0, 0] -= z[:, row, 0]
        B[:, 0, 2] -= z[:, row, 1]
        B[:, 1, 1] -= z[:, row, 0]
        B[:, 1, 3] -= z[:, row, 1]
        B = B @ T4
        P = B @ np.conj(B.transpose(0, 2, 1))
        Omega = np.einsum("ij,nab->niajb", np.eye(R), P).reshape(n, 2 * R, 2 * R)
        M = (np.eye(2 * R) - H) @ Omega
        tr_m = np.trace(M, axis1=1, axis2=2).real
        tr_m2 = np.trace(M @ M, axis1=1, axis2=2).real
        V = Gi @ np.conj(X.transpose(0, 2, 1)) @ Omega @ X @ Gi
        sd = np.sqrt(0.5 * (rss / tr_m)[:, None] * np.diagonal(V, axis1=1, axis2=2).real)
        ks[:, row] = sd * np.sqrt(1 + (sigma / w) ** 2)[:, None]
        cs[:, row] = sd / w[:, None]
        dof[:, row] = 2 * tr_m ** 2 / tr_m2
    return np.stack([ks, ks], 1), np.stack([cs, cs], 1), dof


def _noisy(q, rng, level):
    return q + level * (rng.standard_normal(q.shape) + 1j * rng.standard_normal(q.shape))


@pytest.mark.parametrize("sets", ["AB", "ABCD"])
@pytest.mark.parametrize("at", ["bearings", "probes"])
def test_synchronous_identical_std_matches_the_dense_oracle(sets, at):
    brg = _identical_bearings()
    rng = np.random.default_rng(4)
    runs = []
    for s in sets:
        r = rotorid.imbalance_response(RIG.rotor, brg, RIG.imbalances[s], speed_rpm=RPM)
        r = r.at_probes(RIG.rotor) if at == "probes" else r
        r.q = _noisy(r.q, rng, 5e-8)
        runs.append(r)
    ident = rotorid.identify_synchronous(RIG.rotor, runs, identical=True)
    assert ident.std_source == "residual"
    w = RPM * np.pi / 30
    at_b = np.stack([r.at_bearings(RIG.rotor).q if at == "probes" else r.q for r in runs])
    es = np.stack([RIG.imbalances[s]._generalized(RIG.rotor) * (w ** 2)[:, None] for s in sets])
    planes = rotorid.simulate.probes_to_bearings_matrix(RIG.rotor) if at == "probes" else None
    ks, cs, dof = _oracle(RIG.rotor, at_b, es, w, np.zeros_like(w), w, ident.k, ident.c, planes=planes)
    np.testing.assert_allclose(ident.k_std, ks, rtol=1e-9)
    np.testing.assert_allclose(ident.c_std, cs, rtol=1e-9)
    # the intervals take each point's smaller dof (x or y row)
    np.testing.assert_allclose(ident.dof, dof.min(axis=1), rtol=1e-9)
    # at most the plain pooled count 2 (2R - 2), more than 2
    assert np.all(dof <= 2 * (2 * len(sets) - 2) + 1e-9) and np.all(dof > 2)


@pytest.mark.parametrize("windowed", [False, True])
def test_impact_identical_std_matches_the_dense_oracle(windowed):
    brg = _identical_bearings()
    f = np.linspace(10.0, 150.0, 15)
    rng = np.random.default_rng(8)
    sigma = 4.0 if windowed else 0.0
    tests = []
    for d, z in (("x", 0.0), ("y", 0.0), ("x", 0.05)):
        t = rotorid.impact_frf(RIG.rotor, brg, speed_rpm=3000.0, freq_hz=f, direction=d, plane=z)
        tests.append(ImpactResponse(speed_rpm=3000.0, freq_hz=f, q=_noisy(t.q, rng, 1e-10), plane=z, direction=d,
                                    sigma=sigma))
    ident = rotorid.identify_impact(RIG.rotor, tests, identical=True)
    w = 2 * np.pi * f
    es = np.stack([np.broadcast_to(t.excitation(), (f.size, 4)) for t in tests])
    ks, cs, dof = _oracle(RIG.rotor, np.stack([t.q for t in tests]), es, w, np.full_like(w, sigma),
                          3000.0 * np.pi / 30, ident.k, ident.c)
    np.testing.assert_allclose(ident.k_std, ks, rtol=1e-9)
    np.testing.assert_allclose(ident.c_std, cs, rtol=1e-9)
    np.testing.assert_allclose(ident.dof, dof.min(axis=1), rtol=1e-9)


def _covered(ident, truth_k, truth_c):
    """(points, 16): whether each coefficient's 95 % interval holds the truth."""
    iv = ident.interval(0.95)
    n = ident.k.shape[0]
    return np.concatenate([((iv.k_lower <= truth_k) & (truth_k <= iv.k_upper)).reshape(n, -1),
                           ((iv.c_lower <= truth_c) & (truth_c <= iv.c_upper)).reshape(n, -1)], 1)


def _negative_damping_bits(ident):
    """(points,): 1 where the point is flagged for a negative direct damping."""
    return (ident.flag_code.astype(int) >> ident.flag_reasons.index(NEGATIVE_DAMPING)) & 1


def _monte_carlo(sets, draws=300, noise=5e-8, probes=False):
    brg = _identical_bearings(zero_cxx=True)
    clean = []
    for s in sets:
        r = rotorid.imbalance_response(RIG.rotor, brg, RIG.imbalances[s], speed_rpm=RPM)
        clean.append(r.at_probes(RIG.rotor) if probes else r)
    rng = np.random.default_rng(21)
    inside, flagged, scale = [], [], []
    truth_k, truth_c = np.asarray(brg.k), np.asarray(brg.c)
    for _ in range(draws):
        runs = []
        for r0 in clean:
            r = rotorid.imbalance_response(RIG.rotor, brg, r0.imbalance, speed_rpm=RPM)
            r = r.at_probes(RIG.rotor) if probes else r
            r.q = _noisy(r0.q, rng, noise)
            runs.append(r)
        ident = rotorid.identify_synchronous(RIG.rotor, runs, identical=True)
        inside.append(_covered(ident, truth_k, truth_c))
        flagged.append(_negative_damping_bits(ident))
        scale.append((ident.c[:, 0, 0, 0], ident.c_std[:, 0, 0, 0]))
    c_xx = np.array([s[0] for s in scale])
    c_std = np.array([s[1] for s in scale])
    spread = c_xx.std(axis=0) / np.sqrt((c_std ** 2).mean(axis=0))
    return np.mean(inside), np.mean(flagged), spread


@pytest.mark.parametrize("sets,probes", [("AB", False), ("ABC", False), ("ABC", True)])
def test_identical_intervals_cover_the_truth(sets, probes):
    """95 % intervals of identical bearings cover the truth 95 % of the time (pooled least squares
    with the plain s² covered 89-90 %: its standard errors were 0.56-1.46 times the spread), and a
    zero direct damping is flagged negative about Phi(-2) = 2.3 % of the time (4.5-5.2 % before)."""
    cover, flag_rate, spread = _monte_carlo(sets, probes=probes)
    assert 0.935 <= cover <= 0.965, cover
    assert 0.013 <= flag_rate <= 0.035, flag_rate
    # the standard errors match the spread of the estimates at every speed
    assert np.all((spread > 0.85) & (spread < 1.18)), spread


def test_identical_single_run_has_no_residual_errors():
    brg = _identical_bearings()
    run = rotorid.imbalance_response(RIG.rotor, brg, RIG.imbalances["A"], speed_rpm=RPM)
    ident = rotorid.identify_synchronous(RIG.rotor, [run], identical=True)
    assert ident.std_source == "none" and np.isnan(ident.c_std).all()


def test_identical_std_core_refuses_bad_arguments():
    w = RPM * np.pi / 30
    runs = [rotorid.imbalance_response(RIG.rotor, _identical_bearings(), RIG.imbalances[s], speed_rpm=RPM).q
            for s in "AB"]
    e = np.stack([RIG.imbalances[s]._generalized(RIG.rotor) for s in "AB"])[None].astype(complex)
    k, c, *_ = _core.identify(RIG.rotor.core_params(), w, None, runs, e, None, identical=True)
    ks, cs, dof = _core.identical_std(RIG.rotor.core_params(), w, None, runs, e, None, k, c)
    assert ks.shape == (1, RPM.size, 2, 2, 2) and dof.shape == (1, RPM.size, 2)
    with pytest.raises(RotoridError, match="k has shape"):
        _core.identical_std(RIG.rotor.core_params(), w, None, runs, e, None, k[:, :-1], c)
    with pytest.raises(RotoridError, match="c has shape"):
        _core.identical_std(RIG.rotor.core_params(), w, None, runs, e, None, k, c[..., 0])
    # a NaN estimate (a singular point) gives NaN errors and dof, not a number
    k2 = k.copy()
    k2[0, 3] = np.nan
    ks, cs, dof = _core.identical_std(RIG.rotor.core_params(), w, None, runs, e, None, k2, c)
    assert np.isnan(ks[0, 3]).all() and np.isnan(dof[0, 3]).all() and np.isfinite(ks[0, 4]).all()
    # one run: no residual degree of freedom
    ks, cs, dof = _core.identical_std(RIG.rotor.core_params(), w, None, runs[:1], e[:, :1], None, k, c)
    assert np.isnan(ks).all() and np.isnan(dof).all()


def test_identical_bearings_with_a_stated_uncertainty_keep_per_row_dof():
    """With a phase-reference uncertainty the estimated part's dof (per row) grows by
    Welch-Satterthwaite coefficient by coefficient; the intervals take the point's smallest."""
    brg = _identical_bearings()
    rng = np.random.default_rng(2)
    runs = []
    for s in "ABC":
        r = rotorid.imbalance_response(RIG.rotor, brg, RIG.imbalances[s], speed_rpm=RPM)
        r.q = _noisy(r.q, rng, 5e-8)
        runs.append(r)
    plain = rotorid.identify_synchronous(RIG.rotor, runs, identical=True)
    phased = rotorid.identify_synchronous(RIG.rotor, runs, identical=True, keyphasor_angle_std_deg=1.0)
    assert phased.std_source == "residual + phase reference"
    assert np.all(phased.dof >= plain.dof - 1e-9) and np.any(phased.dof > plain.dof * 1.5)
    assert np.all(phased.c_std >= plain.c_std)


def test_batch_identification_gives_the_same_identical_errors():
    """identify_synchronous_batch (Monte Carlo) with identical=True and with_std: the standard
    errors and dof of identify_synchronous, trial by trial."""
    brg = _identical_bearings()
    rng = np.random.default_rng(6)
    clean = np.stack([rotorid.imbalance_response(RIG.rotor, brg, RIG.imbalances[s], speed_rpm=RPM).q for s in "ABC"])
    trials = np.stack([_noisy(clean, rng, 5e-8) for _ in range(3)])
    imbs = [RIG.imbalances[s] for s in "ABC"]
    out = rotorid.identify_synchronous_batch(RIG.rotor, RPM, trials, imbs, identical=True, with_std=True)
    assert out["dof"].shape == (3, RPM.size, 2)
    for t in range(3):
        runs = []
        for i, s in enumerate("ABC"):
            r = rotorid.imbalance_response(RIG.rotor, brg, RIG.imbalances[s], speed_rpm=RPM)
            r.q = trials[t, i]
            runs.append(r)
        one = rotorid.identify_synchronous(RIG.rotor, runs, identical=True)
        np.testing.assert_allclose(out["k_std"][t], one.k_std, rtol=1e-12)
        np.testing.assert_allclose(out["c_std"][t], one.c_std, rtol=1e-12)
        np.testing.assert_allclose(out["dof"][t].min(axis=1), one.dof, rtol=1e-12)
    # one run: no residual errors (NaN), as before
    single = rotorid.identify_synchronous_batch(RIG.rotor, RPM, trials[:, :1], imbs[:1], identical=True, with_std=True)
    assert np.isnan(single["k_std"]).all()
    # trials recorded at the probes: the noise white there, as identify_synchronous takes such runs
    at_p = np.stack([[rotorid.imbalance_response(RIG.rotor, brg, RIG.imbalances[s], speed_rpm=RPM).at_probes(RIG.rotor).q
                      for s in "ABC"]])
    at_p = at_p + 5e-8 * (rng.standard_normal(at_p.shape) + 1j * rng.standard_normal(at_p.shape))
    out = rotorid.identify_synchronous_batch(RIG.rotor, RPM, at_p, imbs, identical=True, with_std=True, at="probes")
    runs = []
    for i, s in enumerate("ABC"):
        r = rotorid.imbalance_response(RIG.rotor, brg, RIG.imbalances[s], speed_rpm=RPM).at_probes(RIG.rotor)
        r.q = at_p[0, i]
        runs.append(r)
    one = rotorid.identify_synchronous(RIG.rotor, runs, identical=True)
    np.testing.assert_allclose(out["c_std"][0], one.c_std, rtol=1e-8)


def test_the_noise_is_white_where_the_runs_were_measured_however_they_are_stored():
    """Runs at the probes reach the core as they are, or moved to the bearings first (q replaced by
    a list, a covariance, pedestal motion): the identical-bearing errors take the noise as white at
    the probes either way (a list gave standard errors 0.82-1.05 times as large, found in review)."""
    brg = _identical_bearings()
    rng = np.random.default_rng(12)
    runs = []
    for s in "ABC":
        r = rotorid.imbalance_response(RIG.rotor, brg, RIG.imbalances[s], speed_rpm=RPM).at_probes(RIG.rotor)
        r.q = _noisy(r.q, rng, 5e-8)
        runs.append(r)
    direct = rotorid.identify_synchronous(RIG.rotor, runs, identical=True)
    listed = [dataclasses.replace(r) for r in runs]
    for r in listed:
        r.q = r.q.tolist()  # not the checked array: the runs are moved to the bearings in Python
    moved = rotorid.identify_synchronous(RIG.rotor, listed, identical=True)
    np.testing.assert_allclose(moved.k, direct.k, rtol=1e-9)
    np.testing.assert_allclose(moved.c_std, direct.c_std, rtol=1e-8)
    np.testing.assert_allclose(moved.dof, direct.dof, rtol=1e-8)
    # the same noise taken at the bearings differs (the user moved the runs: measured there)
    at_b = rotorid.identify_synchronous(RIG.rotor, [r.at_bearings(RIG.rotor) for r in runs], identical=True)
    assert np.max(np.abs(at_b.c_std / direct.c_std - 1)) > 0.05


def test_impact_identical_intervals_cover_the_truth():
    """Two impacts (x and y at the CG plane) with noise of one level on every FRF: 95 % intervals of
    identical bearings cover the truth (80 % with the pooled errors)."""
    brg = _identical_bearings(zero_cxx=True)
    f = np.linspace(10.0, 150.0, 30)
    base = [rotorid.impact_frf(RIG.rotor, brg, speed_rpm=2000.0, freq_hz=f, plane=0.0, direction=d) for d in "xy"]
    level = 0.005 * np.mean([np.abs(b.q).mean(axis=1) for b in base], axis=0)[:, None]
    rng = np.random.default_rng(9)
    inside, flagged = [], []
    truth_k, truth_c = np.asarray(brg.k), np.asarray(brg.c)
    for _ in range(300):
        tests = [ImpactResponse(speed_rpm=2000.0, freq_hz=f, q=b.q + level * (rng.standard_normal(b.q.shape) + 1j *
                                                                      rng.standard_normal(b.q.shape)),
                                plane=0.0, direction=b.direction) for b in base]
        ident = rotorid.identify_impact(RIG.rotor, tests, identical=True)
        inside.append(_covered(ident, truth_k, truth_c))
        flagged.append(_negative_damping_bits(ident))
    assert 0.935 <= np.mean(inside) <= 0.975, np.mean(inside)
    assert 0.008 <= np.mean(flagged) <= 0.035, np.mean(flagged)
