"""``identify_pedestals`` with measurement covariances: the weighted fit and the sandwich
covariance in the core (``rotorid_core::pedestal_cov``, through ``_core.pedestal_fit(covs=...)``)
against the NumPy version they replaced (``pedestal_cov_oracle``), through the public API: runs at
the probes and at the bearings, correlated probe-accelerometer errors, a shared baseline, the
cross-coupled model, a frequency range, unknown points, impacts with an exponential window."""

import numpy as np
import pytest

import rotorid
from rotorid import RotoridError, _corecall
from rotorid.simulate import ImpactResponse, SyncResponse

from pedestal_cov_oracle import cov_fit_numpy

RIG = rotorid.nsf_rig()
PED = rotorid.example_pedestals()


def _joint(blocks):
    cq, cp, cx = blocks
    out = np.zeros((cq.shape[0], 16, 16))
    out[:, :8, :8], out[:, 8:, 8:] = cq, cp
    if cx is not None:
        out[:, :8, 8:] = cx
        out[:, 8:, :8] = np.swapaxes(cx, 1, 2)
    return out


def _both(monkeypatch, call):
    """The call with the core's covariance fit, and with the oracle's in its place."""
    real = _corecall.core.pedestal_fit
    seen = []

    def oracle(params, axis, spin, qs, e, gain, ps, sigma=None, select=None, cross=False, w_scale=None, covs=None,
               shared=None, weighted=True):
        out = real(params, axis, spin, qs, e, gain, ps, sigma=sigma, select=select, cross=cross, w_scale=w_scale)
        if covs is None:
            return out
        seen.append(weighted)
        fit = cov_fit_numpy(params, axis, spin, qs, e, gain, ps, sigma=sigma, select=select, cross=cross,
                            w_scale=w_scale, covs=[_joint(b) for b in covs], shared=shared, weighted=weighted,
                            thetas=out[0])
        return (*out[:5], fit)

    new = call()
    with monkeypatch.context() as m:
        m.setattr(_corecall.core, "pedestal_fit", oracle)
        old = call()
    assert seen, "the covariance fit did not run"
    return new, old


def _same(new, old):
    assert new.std_source == old.std_source
    for name in ("mass_kg", "k", "c", "mass_std", "k_std", "c_std", "residual", "dof"):
        a, b = getattr(new, name), getattr(old, name)
        np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-12 * np.abs(b).max(), err_msg=name)


def _runs(dof, *, at="probes", cross_cov=False, nan_at=(), rpm=None, seed=0, shared=None):
    """Three runs with random covariances (each including ``shared``, the part common to all), at
    ``rpm`` (40 speeds from 1500 to 7000 rpm by default)."""
    rpm = np.linspace(1500.0, 7000.0, 40) if rpm is None else rpm
    rng = np.random.default_rng(seed)
    out = []
    for s in "ABD":
        r = rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances[s], speed_rpm=rpm, at=at,
                                       pedestals=PED)
        n = rpm.size
        a = rng.standard_normal((n, 16, 16)) * np.abs(r.q).mean() * 3e-3
        joint = a @ np.transpose(a, (0, 2, 1))
        joint[:, 8:, 8:] *= (np.abs(r.pedestal).mean() / np.abs(r.q).mean()) ** 2
        if not cross_cov:
            joint[:, :8, 8:] = joint[:, 8:, :8] = 0.0
        else:
            joint[:, :8, 8:] *= np.abs(r.pedestal).mean() / np.abs(r.q).mean()
            joint[:, 8:, :8] = np.swapaxes(joint[:, :8, 8:], 1, 2)
        if shared is not None:
            joint += np.nan_to_num(shared)
            cross_cov = True
        cov, pcov, xc = joint[:, :8, :8].copy(), joint[:, 8:, 8:].copy(), joint[:, :8, 8:].copy()
        cov[list(nan_at)] = np.nan
        noise = 1 + 1e-3 * rng.standard_normal(r.q.shape)
        out.append(SyncResponse(rpm, r.q * noise, r.imbalance, at, s, cov, np.full(n, dof), r.pedestal * noise,
                                pcov, xc if cross_cov else None))
    return out


@pytest.mark.parametrize("dof, at, cross", [(30.0, "probes", False), (30.0, "bearings", True), (4.0, "probes", False),
                                            (4.0, "bearings", True)])
def test_weighted_and_sandwich_fits_equal_the_numpy_version(monkeypatch, dof, at, cross):
    runs = _runs(dof, at=at, cross_cov=cross)
    new, old = _both(monkeypatch, lambda: rotorid.identify_pedestals(RIG.rotor, runs, cross_coupled=cross))
    _same(new, old)
    assert new.std_source == ("measurement covariance" if dof >= 10 else
                              "residual or measurement covariance, the larger (unweighted fit)")


def test_a_shared_baseline_a_frequency_range_and_unknown_points(monkeypatch):
    n = 40
    rng = np.random.default_rng(7)
    a = rng.standard_normal((n, 16, 16)) * 1e-8
    shared = a @ np.transpose(a, (0, 2, 1))
    shared[0] = np.nan                           # unknown, at a point outside the range
    runs = _runs(30.0, nan_at=(13, 17), seed=1, shared=shared)
    with pytest.warns(UserWarning, match="2 of .* points have no measurement covariance"):
        new, old = _both(monkeypatch, lambda: rotorid.identify_pedestals(RIG.rotor, runs, shared_cov=shared,
                                                                         freq_range_hz=(30.0, 110.0)))
    _same(new, old)


@pytest.mark.parametrize("sigma", [0.0, 3.0])
def test_impacts_with_a_window_equal_the_numpy_version(monkeypatch, sigma):
    f = np.linspace(15.0, 160.0, 60)
    rng = np.random.default_rng(2)
    tests = []
    for d in "xy":
        t = rotorid.impact_frf(RIG.rotor, RIG.bearings, speed_rpm=2000.0, freq_hz=f, direction=d, pedestals=PED)
        a = rng.standard_normal((f.size, 8, 8)) * np.abs(t.q).mean() * 2e-3
        cov = a @ np.transpose(a, (0, 2, 1))
        pcov = cov * (np.abs(t.pedestal).mean() / np.abs(t.q).mean()) ** 2
        noise = 1 + 1e-3 * rng.standard_normal(t.q.shape)   # a residual above rounding
        tests.append(ImpactResponse(2000.0, f, t.q * noise, None, 0.0, d, sigma=sigma, cov=cov,
                                    dof=np.full(f.size, 30.0), pedestal=t.pedestal * noise, pedestal_cov=pcov))
    new, old = _both(monkeypatch, lambda: rotorid.identify_pedestals(RIG.rotor, tests))
    _same(new, old)


def test_the_core_refuses_bad_covariance_blocks():
    from rotorid._corecall import core

    runs = _runs(30.0, rpm=np.linspace(2000.0, 6000.0, 6))
    qs = [np.ascontiguousarray(r.q) for r in runs]
    ps = [np.ascontiguousarray(r.pedestal) for r in runs]
    args = (RIG.rotor.core_params(), np.linspace(2000.0, 6000.0, 6), None, qs,
            np.stack([r.imbalance.generalized(RIG.rotor) for r in runs])[None].astype(complex), None, ps)
    good = (np.zeros((6, 8, 8)), np.zeros((6, 8, 8)), None)
    with pytest.raises(RotoridError, match="covs has 2 entries, expected one per run"):
        core.pedestal_fit(*args, w_scale=np.pi / 30, covs=[good, good])
    with pytest.raises(RotoridError, match=r"covs\[1\]\[1\] has shape"):
        core.pedestal_fit(*args, w_scale=np.pi / 30, covs=[good, (good[0], np.zeros((6, 8, 7)), None), good])
    with pytest.raises(RotoridError, match=r"covs\[0\] must be"):
        core.pedestal_fit(*args, w_scale=np.pi / 30, covs=[np.zeros((6, 16, 16))] * 3)
    with pytest.raises(RotoridError, match="shared has shape"):
        core.pedestal_fit(*args, w_scale=np.pi / 30, covs=[good] * 3, shared=np.zeros((6, 8, 8)))


def test_the_covariance_fits_and_the_propagation_do_not_depend_on_the_thread_count():
    """Tasks of fixed points merged in order: one thread (RAYON_NUM_THREADS=1) gives the bits of
    the pool, for the pedestal fit with covariances (more points than a task holds) and for the
    synchronous identification's propagation (``identify::propagate``)."""
    from thread_runs import outputs_on_threads

    code = ("import numpy as np, sys, rotorid; sys.path.insert(0, 'tests'); "
            "from test_pedestal_cov_core import _runs, RIG; "
            "runs = _runs(30.0, rpm=np.linspace(1500.0, 7000.0, 1500), cross_cov=True); "
            "f = rotorid.identify_pedestals(RIG.rotor, runs); "
            "i = rotorid.identify_synchronous(RIG.rotor, [r.at_bearings(RIG.rotor) for r in runs], "
            "estimator='bias-corrected'); "
            "np.save(sys.argv[1], np.concatenate([f.k.ravel(), f.k_std.ravel(), f.mass_std.ravel(), i.k.ravel(), "
            "i.cov.ravel(), i.k_bias.ravel()]))")
    outs = outputs_on_threads(code)
    assert np.isfinite(outs[0]).mean() > 0.5
    np.testing.assert_array_equal(outs[0], outs[1])
