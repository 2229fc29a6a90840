"""``uncertainty.propagate`` takes the points a chunk at a time with reused buffers and sums the
independent runs' blocks J_r Σ_r J_rᵀ; ``propagate_oracle.propagate_dense`` is the first version
(every point at once, the dense Σ). The public identifications must give the same covariances,
standard errors and bias corrections with either, across chunk boundaries, for synchronous runs
(with and without a shared baseline, with pedestal motion) and impacts (broadcast spin, gain and
window), with unknown covariances at some points."""

import numpy as np
import pytest

import rotorid
from rotorid import uncertainty
from rotorid.simulate import ImpactResponse, SyncResponse

from propagate_oracle import propagate_dense

RIG = rotorid.nsf_rig()


def _both(monkeypatch, call, chunk):
    monkeypatch.setattr(uncertainty, "PROPAGATE_CHUNK", chunk)
    new = call()
    with monkeypatch.context() as m:
        m.setattr(uncertainty, "propagate", propagate_dense)
        old = call()
    return new, old


def _same(new, old):
    """Equal to rounding: 1e-10 of each value, or 1e-13 of the array's largest (entries that cancel
    to near zero, e.g. small covariances between coefficients); NaN at the same places."""
    for name in ("k", "c", "k_std", "c_std", "cov", "k_bias", "c_bias", "rel_std", "flag_code"):
        a, b = getattr(new, name), getattr(old, name)
        if a is None:
            assert b is None, name
            continue
        assert np.array_equal(np.isnan(a), np.isnan(b)), name
        big = np.nanmax(np.abs(b)) if np.isfinite(b).any() else 0.0
        np.testing.assert_allclose(np.nan_to_num(a), np.nan_to_num(b), rtol=1e-10, atol=1e-13 * big, err_msg=name)


def _runs(n, *, probes=False, pedestals=None, nan_at=()):
    rpm = np.linspace(2500.0, 6000.0, n)
    rng = np.random.default_rng(n)
    out = []
    for s in "ABCD":
        kw = {} if pedestals is None else dict(pedestals=pedestals)
        r = rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances[s], speed_rpm=rpm,
                                       at="probes" if probes else "bearings", **kw)
        a = rng.standard_normal((n, 8, 8)) * 1e-7
        cov = a @ np.transpose(a, (0, 2, 1)) + np.eye(8) * 1e-15
        cov[list(nan_at)] = np.nan
        q = r.q * (1 + 0.003 * rng.standard_normal(r.q.shape))
        extra = {}
        if pedestals is not None:
            extra = dict(pedestal=r.pedestal, pedestal_cov=cov * 0.5)
        out.append(SyncResponse(rpm, q, r.imbalance, r.at, None, cov, np.full(n, 20.0), **extra))
    return out


@pytest.mark.parametrize("n, chunk", [(1, 7), (23, 7), (23, 2048), (64, 16)])
def test_synchronous_runs_give_the_dense_propagation(monkeypatch, n, chunk):
    runs = _runs(n, nan_at=(n // 2,) if n > 2 else ())
    for estimator in ("ls", "bias-corrected"):
        _same(*_both(monkeypatch, lambda: rotorid.identify_synchronous(RIG.rotor, runs, estimator=estimator), chunk))


def test_a_shared_baseline_and_probe_planes_give_the_dense_propagation(monkeypatch):
    runs = _runs(19, probes=True)
    shared = np.broadcast_to(np.eye(8) * 2e-15, (19, 8, 8))
    _same(*_both(monkeypatch, lambda: rotorid.identify_synchronous(RIG.rotor, runs, shared_cov=shared), 5))


def test_pedestal_motion_gives_the_dense_propagation(monkeypatch):
    runs = _runs(17, pedestals=rotorid.example_pedestals(), nan_at=(3,))
    _same(*_both(monkeypatch, lambda: rotorid.identify_synchronous(RIG.rotor, runs), 6))


@pytest.mark.parametrize("sigma", [0.0, 4.0])
def test_impacts_give_the_dense_propagation(monkeypatch, sigma):
    f = np.linspace(20.0, 200.0, 29)
    rng = np.random.default_rng(3)
    tests = []
    for plane, d in ((0.0, "x"), (0.0, "y"), (0.05, "x")):
        t = rotorid.impact_frf(RIG.rotor, RIG.bearings, speed_rpm=2000.0, freq_hz=f, plane=plane, direction=d)
        a = rng.standard_normal((f.size, 8, 8)) * 1e-9
        tests.append(ImpactResponse(2000.0, f, t.q, None, plane, d, sigma=sigma,
                                    cov=a @ np.transpose(a, (0, 2, 1)), dof=np.full(f.size, 10.0)))
    _same(*_both(monkeypatch, lambda: rotorid.identify_impact(RIG.rotor, tests), 8))


@pytest.mark.parametrize("lead", [(), (5,), (3, 7)])
def test_the_report_order_is_eq9s(lead):
    """The strided copy into eq. 9 order equals indexing with the report's order table."""
    from rotorid.model import _REPORT_TO_BIJ

    rng = np.random.default_rng(len(lead))
    k, c = rng.standard_normal(lead + (2, 2, 2)), rng.standard_normal(lead + (2, 2, 2))
    k[(0,) * len(lead) + (1, 0, 1)] = np.nan
    want = np.concatenate([k.reshape(lead + (8,))[..., _REPORT_TO_BIJ], c.reshape(lead + (8,))[..., _REPORT_TO_BIJ]],
                          axis=-1)
    np.testing.assert_array_equal(uncertainty._report_order(k, c), want)
    np.testing.assert_array_equal(uncertainty.report_vector(k, c), want)
    names = rotorid.model.REPORT_ORDER
    assert names[:4] == ("Kxx1", "Kxx2", "Kxy1", "Kxy2") and names[8] == "Cxx1"
