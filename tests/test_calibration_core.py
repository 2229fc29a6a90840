"""The accelerometers' calibration uncertainty is part of the core's propagation
(``identify::propagate``, ``Calibration``): Cov_cal = Σ_j σ² (J d_j)(J d_j)ᵀ with the Jacobian J
of the measurement propagation and d_j the input direction of accelerometer j's gain or phase.

The oracle is how rotorid computed it before (until 2026-11-27): every accelerometer's gain and
phase stepped by ±1e-4 on the runs as measured (``identify.calibration_perturbations``), each
stepped set identified through the public API, central differences of the report vector. It shares
nothing with the core's directions (the probe maps B, the pedestal channels), so it checks them for
runs at the probes and at the bearings, impacts, redundant runs without covariances, the report
solver and identical bearings.
"""

import dataclasses
import warnings

import numpy as np
import pytest
import rotorid
from rotorid.errors import RotoridError
from rotorid.identify import _CAL_STEP, calibration_perturbations

RIG = rotorid.nsf_rig()
PED = rotorid.example_pedestals()
GAIN_STD, PHASE_STD_DEG = 0.02, 1.0


def _plain(runs):
    """The runs without measurement covariances (the oracle's derivatives are at fixed weights)."""
    return [dataclasses.replace(r, cov=None, dof=None, pedestal_cov=None, pedestal_cross=None) for r in runs]


def calibration_cov_oracle(identify, runs):
    """Σ over accelerometers, gain and phase of σ² d dᵀ, d the central difference of the report
    vector (eq. 9 order, (n, 16)) over the stepped runs."""
    cov = 0.0
    for std, plus, minus in calibration_perturbations(_plain(runs), GAIN_STD, np.deg2rad(PHASE_STD_DEG)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            d = (identify(plus).report_vector() - identify(minus).report_vector()) / (2 * _CAL_STEP) * std
        cov = cov + d[:, :, None] * d[:, None, :]
    return cov


def _runs(n_runs=2, *, at="probes", cov=True):
    rpm = np.linspace(2500.0, 6500.0, 19)
    rng = np.random.default_rng(n_runs)
    out = []
    for s in "ABCD"[:n_runs]:
        r = rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances[s], speed_rpm=rpm, at=at, pedestals=PED)
        q = r.q * (1 + 0.002 * rng.standard_normal(r.q.shape))
        c = np.broadcast_to(np.eye(8) * 1e-16, (rpm.size, 8, 8)).copy() if cov else None
        out.append(rotorid.SyncResponse(rpm, q, r.imbalance, at, s, c, np.full(rpm.size, 30.0) if cov else None,
                                        r.pedestal, None if c is None else c * 0.1))
    return out


def _close(got, want):
    """Two central differences with different steps (the core's 1e-6 rms(q) per input, the
    oracle's 1e-4 per calibration factor): both carry truncation and rounding at ~1e-7 of the
    largest entry; a wrong direction is off by its whole size."""
    big = np.abs(want).max()
    np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-6 * big)


def _with_and_without(identify, runs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = identify(runs, accel_gain_std=GAIN_STD, accel_phase_std_deg=PHASE_STD_DEG)
        b = identify(runs)
    return a, b


@pytest.mark.parametrize("at", ["probes", "bearings"])
@pytest.mark.parametrize("method", ["forces", "report"])
def test_synchronous_runs_with_covariances_add_the_oracles_calibration(at, method):
    runs = _runs(2, at=at)
    a, b = _with_and_without(lambda rs, **kw: rotorid.identify_synchronous(RIG.rotor, rs, method=method, **kw), runs)
    assert a.std_source == "measurement covariance + accelerometer calibration"
    assert b.std_source == "measurement covariance"
    np.testing.assert_array_equal(a.k, b.k)
    np.testing.assert_array_equal(a.k_bias, b.k_bias)       # the bias is the measurement's alone
    want = calibration_cov_oracle(lambda rs: rotorid.identify_synchronous(RIG.rotor, rs, method=method), runs)
    _close(a.cov - b.cov, want)
    # the standard errors are the total covariance's
    d = np.sqrt(np.diagonal(a.cov, axis1=1, axis2=2))
    np.testing.assert_allclose(np.sort(np.concatenate([a.k_std.reshape(-1, 8), a.c_std.reshape(-1, 8)], 1), 1),
                               np.sort(d, 1), rtol=1e-14)


def test_redundant_runs_without_covariances_add_the_calibration_to_the_residual_errors():
    runs = _runs(3, cov=False)
    a, b = _with_and_without(lambda rs, **kw: rotorid.identify_synchronous(RIG.rotor, rs, **kw), runs)
    assert a.std_source == "residual + accelerometer calibration" and a.cov is None
    want = calibration_cov_oracle(lambda rs: rotorid.identify_synchronous(RIG.rotor, rs), runs)
    got = np.concatenate([(a.k_std ** 2 - b.k_std ** 2).reshape(-1, 8), (a.c_std ** 2 - b.c_std ** 2).reshape(-1, 8)], 1)
    from rotorid.model import _REPORT_TO_BIJ

    want_bij = np.empty_like(got)
    want_bij[:, _REPORT_TO_BIJ] = np.diagonal(want, axis1=1, axis2=2)[:, :8]
    want_bij[:, 8 + _REPORT_TO_BIJ] = np.diagonal(want, axis1=1, axis2=2)[:, 8:]
    np.testing.assert_allclose(got, want_bij, rtol=1e-4, atol=1e-6 * np.abs(want_bij).max())


def test_two_runs_without_covariances_have_no_errors_to_widen():
    a, _ = _with_and_without(lambda rs, **kw: rotorid.identify_synchronous(RIG.rotor, rs, **kw), _runs(2, cov=False))
    assert a.std_source == "none" and np.isnan(a.k_std).all()


def test_identical_bearings_are_tested_on_the_measurement_errors_alone():
    """identical=True with redundant equations checks the two bearings' agreement against the
    measurement's standard errors: the calibration, common to both, must not hide a mismatch."""
    runs = _runs(2)
    ident = lambda rs, **kw: rotorid.identify_synchronous(RIG.rotor, rs, identical=True, **kw)
    a, b = _with_and_without(ident, runs)
    why = "identical bearings rejected by the data"
    rejected = [r.flag_code >> r.flag_reasons.index(why) & 1 for r in (a, b)]
    assert 0 < rejected[1].sum() < rejected[1].size
    np.testing.assert_array_equal(rejected[0], rejected[1])  # the same points rejected
    _close(a.cov - b.cov, calibration_cov_oracle(ident, runs))


def test_impacts_with_pedestal_motion_add_the_oracles_calibration():
    f = np.linspace(20.0, 180.0, 17)
    rng = np.random.default_rng(3)
    tests = []
    for d, plane in (("x", 0.0), ("y", 0.0)):
        t = rotorid.impact_frf(RIG.rotor, RIG.bearings, speed_rpm=2000.0, freq_hz=f, direction=d, plane=plane,
                               at="probes", pedestals=PED)
        c = np.broadcast_to(np.eye(8) * 1e-18, (f.size, 8, 8)).copy()
        tests.append(dataclasses.replace(t, q=t.q * (1 + 0.002 * rng.standard_normal(t.q.shape)), cov=c,
                                         dof=np.full(f.size, 10.0), pedestal_cov=c))
    a, b = _with_and_without(lambda ts, **kw: rotorid.identify_impact(RIG.rotor, ts, **kw), tests)
    assert a.std_source == "measurement covariance + accelerometer calibration"
    _close(a.cov - b.cov, calibration_cov_oracle(lambda ts: rotorid.identify_impact(RIG.rotor, ts), tests))


def test_the_core_refuses_a_bad_calibration_by_name():
    from rotorid import _core

    runs = _runs(2)
    q = [np.ascontiguousarray(r.at_bearings(RIG.rotor).q) for r in runs]
    p = [np.ascontiguousarray(r.pedestal) for r in runs]
    om = runs[0].speed_rpm * np.pi / 30
    e = np.array([[r.imbalance._generalized(RIG.rotor) for r in runs]])
    args = {"rotor": RIG.rotor.core_params(), "w": om, "spin": None, "q": q, "e": e, "gain": None, "covs": None, "q_ped": p, "bias": False}
    ok = (0.02, 0.01, np.zeros((2, 4, 4)))
    _core.propagate(**args, calibration=ok)
    for change, match in (({"calibration": None}, "covs"), ({"calibration": (0.02, 0.01, np.zeros((3, 4, 4)))}, "probe_maps"),
                          ({"calibration": (-0.02, 0.01, np.zeros((2, 4, 4)))}, "gain_std"),
                          ({"calibration": (0.02, 0.01, np.full((2, 4, 4), np.nan))}, "probe_maps"),
                          ({"calibration": ok, "bias": True}, "bias"),
                          ({"calibration": ok, "q_ped": None}, "pedestal")):
        with pytest.raises((ValueError, RotoridError), match=match):
            _core.propagate(**{**args, **change})


def test_runs_at_different_places_and_unknown_points():
    """One run at the probes, one at the bearings (each its own probe map), a point whose
    covariance is unknown in one run (NaN there, with the measurement's own covariance), and a
    shared baseline covariance."""
    a_run, b_run = _runs(2, at="probes")[0], _runs(2, at="bearings")[1]
    cov = a_run.cov.copy()
    cov[4] = np.nan
    runs = [dataclasses.replace(a_run, cov=cov), b_run]
    shared = np.broadcast_to(np.eye(16) * 1e-18, (a_run.q.shape[0], 16, 16)).copy()
    ident = lambda rs, **kw: rotorid.identify_synchronous(RIG.rotor, rs, **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = ident(runs, accel_gain_std=GAIN_STD, accel_phase_std_deg=PHASE_STD_DEG)
        b = ident(runs)
    assert np.isnan(a.cov[4]).all() and np.isnan(a.k_std[4]).all()
    assert "uncertainty unknown" in a.flag_reasons
    want = calibration_cov_oracle(lambda rs: ident(rs), runs)
    known = np.arange(a.cov.shape[0]) != 4
    _close((a.cov - b.cov)[known], want[known])
    # a shared baseline adds to the measurement part only: the calibration's part is unchanged
    both = _runs(2, at="bearings")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = ident(both, accel_gain_std=GAIN_STD, accel_phase_std_deg=PHASE_STD_DEG, shared_cov=shared)
        b = ident(both, shared_cov=shared)
    _close(a.cov - b.cov, calibration_cov_oracle(lambda rs: ident(rs), both))


@pytest.mark.parametrize("sigma", [0.0, 3.0])
def test_windowed_impacts_one_direction_at_two_planes(sigma):
    """Impacts in one direction at two planes (the other independent pair), with and without an
    exponential window (the core solves at s = sigma + j w)."""
    f = np.linspace(25.0, 150.0, 13)
    rng = np.random.default_rng(7)
    tests = []
    for plane in (0.0, 0.25):
        t = rotorid.impact_frf(RIG.rotor, RIG.bearings, speed_rpm=1500.0, freq_hz=f, direction="x", plane=plane,
                               at="probes", pedestals=PED)
        c = np.broadcast_to(np.eye(8) * 1e-18, (f.size, 8, 8)).copy()
        tests.append(dataclasses.replace(t, q=t.q * (1 + 0.002 * rng.standard_normal(t.q.shape)), cov=c,
                                         dof=np.full(f.size, 10.0), pedestal_cov=c, sigma=sigma))
    ident = lambda ts, **kw: rotorid.identify_impact(RIG.rotor, ts, **kw)
    a, b = _with_and_without(ident, tests)
    _close(a.cov - b.cov, calibration_cov_oracle(ident, tests))


def pedestal_calibration_oracle(runs, **kw):
    """The variance the calibration adds to the pedestal fit's mass, k and c, by re-identifying the
    stepped runs through the public API (each stepped run constructed, moved and checked)."""
    var = None
    for std, plus, minus in calibration_perturbations(runs, GAIN_STD, np.deg2rad(PHASE_STD_DEG)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            est = [rotorid.identify_pedestals(RIG.rotor, side, **kw) for side in (plus, minus)]
        d = [(std * (getattr(est[0], f) - getattr(est[1], f)) / (2 * _CAL_STEP)) ** 2 for f in ("mass_kg", "k", "c")]
        var = d if var is None else [v + x for v, x in zip(var, d)]
    return var


@pytest.mark.parametrize("at, cov, cross", [("probes", True, False), ("bearings", False, False),
                                            ("probes", False, True)])
def test_pedestal_fits_step_the_motions_as_the_stepped_runs_would(at, cov, cross):
    runs = _runs(2, at=at, cov=cov)
    kw = {"cross_coupled": cross}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = rotorid.identify_pedestals(RIG.rotor, runs, accel_gain_std=GAIN_STD, accel_phase_std_deg=PHASE_STD_DEG, **kw)
        b = rotorid.identify_pedestals(RIG.rotor, runs, **kw)
    assert a.std_source == b.std_source + " + accelerometer calibration"
    want = pedestal_calibration_oracle(runs, **kw)
    for got, w in zip((a.mass_std ** 2 - b.mass_std ** 2, a.k_std ** 2 - b.k_std ** 2, a.c_std ** 2 - b.c_std ** 2), want):
        np.testing.assert_allclose(got, w, rtol=1e-6, atol=1e-9 * np.abs(w).max())
    assert (want[1] > 0).any()

