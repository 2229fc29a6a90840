"""``uncertainty.propagate`` is one core call (``identify::propagate``: the perturbed copies of a
few points at a time, the runs' blocks J_r Σ_r J_rᵀ, the sigma points from Cholesky factors);
``propagate_oracle.propagate_dense`` is the NumPy version it replaced (every point at once, the
dense Σ). The public identifications must give the same covariances, standard errors and bias
corrections with either, across the core's task boundaries (a task takes 2,048 perturbed copies:
15 points at 4 runs, 7 with pedestal motion), for synchronous runs (with and without a shared
baseline, with pedestal motion, both solvers) and impacts (broadcast spin, gain and window), with
unknown covariances at some points."""

import numpy as np
import pytest

import rotorid
from rotorid import uncertainty
from rotorid.simulate import ImpactResponse, SyncResponse

from propagate_oracle import propagate_dense, psd_cholesky

RIG = rotorid.nsf_rig()


def _dense(rotor, w, spin, qs, e, gain, sigma, covs, *, identical, method, bias, shared=None, q_ped=None,
           w_scale=None, calibration=None, meas_std=False):
    """The oracle with the arguments of ``uncertainty._propagate`` (as the core takes them; the
    accelerometers' calibration is tested in test_calibration_core.py)."""
    assert calibration is None
    if isinstance(covs, list):  # pedestal runs: (cov, pedestal_cov, cross) blocks, as the joint covariance
        covs = np.stack([np.block([[c, np.zeros_like(c) if x is None else x],
                                   [np.zeros_like(c) if x is None else np.swapaxes(x, 1, 2), p]]) for c, p, x in covs])
    w = w if w_scale is None else w_scale * w
    spin = w if spin is None else spin
    gain = spin ** 2 if gain is None else gain
    cov, b = propagate_dense(rotor, w, spin, np.stack(qs), e, gain, sigma, covs, identical=identical, method=method,
                             bias=True, shared=shared, q_ped=None if q_ped is None else np.stack(q_ped))
    unknown = np.isnan(cov).any(axis=(1, 2))
    k_std, c_std = uncertainty.std_from_cov(cov)
    k_std[unknown] = np.nan
    c_std[unknown] = np.nan
    return cov, (b if bias else None), unknown, k_std, c_std, None


def _both(monkeypatch, call):
    new = call()
    with monkeypatch.context() as m:
        m.setattr(uncertainty, "_propagate", _dense)
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


@pytest.mark.parametrize("n", [1, 15, 16, 23, 64])
def test_synchronous_runs_give_the_dense_propagation(monkeypatch, n):
    runs = _runs(n, nan_at=(n // 2,) if n > 2 else ())
    for estimator in ("ls", "bias-corrected"):
        _same(*_both(monkeypatch, lambda: rotorid.identify_synchronous(RIG.rotor, runs, estimator=estimator)))


def test_the_bias_is_the_propagated_one_in_bearing_order_and_zero_where_unknown(monkeypatch):
    """k_bias / c_bias (n, 2, 2, 2) are the oracle's bias vector (eq. 9 order: Kxx1, Kxx2, Kxy1, ...)
    put in [point, bearing, i, j] order, 0 at the points whose covariance is unknown (NaN there)."""
    runs = _runs(23, nan_at=(5, 17))
    seen = {}

    def dense_kept(*a, **kw):
        out = _dense(*a, **kw)
        seen["b"] = out[1]
        return out

    monkeypatch.setattr(uncertainty, "_propagate", dense_kept)
    ident = rotorid.identify_synchronous(RIG.rotor, runs)
    b = seen["b"]
    assert np.isnan(b[[5, 17]]).all() and np.isfinite(np.delete(b, [5, 17], 0)).all()
    names = ("xx", "xy", "yx", "yy")
    for j, name in enumerate(rotorid.REPORT_ORDER[:8]):
        bearing, ij = int(name[-1]) - 1, names.index(name[1:3])
        for half, got in ((0, ident.k_bias), (8, ident.c_bias)):
            want = np.nan_to_num(b[:, half + j])
            np.testing.assert_array_equal(got[:, bearing, ij // 2, ij % 2], want, err_msg=name)
    assert not ident.k_bias[[5, 17]].any()


def test_a_shared_baseline_and_probe_planes_give_the_dense_propagation(monkeypatch):
    runs = _runs(19, probes=True)
    shared = np.broadcast_to(np.eye(8) * 2e-15, (19, 8, 8))
    _same(*_both(monkeypatch, lambda: rotorid.identify_synchronous(RIG.rotor, runs, shared_cov=shared)))


def test_pedestal_motion_gives_the_dense_propagation(monkeypatch):
    runs = _runs(17, pedestals=rotorid.example_pedestals(), nan_at=(3,))
    _same(*_both(monkeypatch, lambda: rotorid.identify_synchronous(RIG.rotor, runs)))


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
    _same(*_both(monkeypatch, lambda: rotorid.identify_impact(RIG.rotor, tests)))


def test_the_report_solver_gives_the_dense_propagation(monkeypatch):
    runs = _runs(17, nan_at=(4,))
    _same(*_both(monkeypatch, lambda: rotorid.identify_synchronous(RIG.rotor, runs, method="report")))
    _same(*_both(monkeypatch, lambda: rotorid.identify_synchronous(RIG.rotor, runs[:2], method="report",
                                                                    estimator="bias-corrected")))


@pytest.mark.parametrize("rank", [0, 1, 3, 7])
def test_semi_definite_covariances_give_the_dense_propagation(monkeypatch, rank):
    """Covariances of rank below 8 (from fewer blocks than entries, or a run known exactly: rank 0)
    have Cholesky factors too: the same bias as the oracle's, finite."""
    runs = _runs(19)
    rng = np.random.default_rng(rank)
    for i, r in enumerate(runs):
        a = rng.standard_normal((19, 8, rank)) * 1e-7
        r.cov = a @ np.transpose(a, (0, 2, 1)) if i != 1 else np.zeros((19, 8, 8))
    new, old = _both(monkeypatch, lambda: rotorid.identify_synchronous(RIG.rotor, runs, estimator="bias-corrected"))
    _same(new, old)
    assert np.isfinite(new.k_bias).all() and np.isfinite(new.cov).all()
    if rank == 0:
        assert not new.k_bias.any() and not new.cov.any()


def test_the_oracles_cholesky_factor_reproduces_the_covariance():
    rng = np.random.default_rng(5)
    for m, rank in ((8, 8), (8, 3), (16, 5), (16, 0)):
        a = rng.standard_normal((40, m, rank)) * 10.0 ** rng.uniform(-20, 3, (40, 1, 1))
        cov = a @ np.transpose(a, (0, 2, 1))
        L = psd_cholesky(cov)
        assert not np.triu(L, 1).any()
        big = np.abs(cov).max(axis=(1, 2), keepdims=True)
        assert np.all(np.abs(L @ np.transpose(L, (0, 2, 1)) - cov) <= 1e-10 * big)


def test_cholesky_and_eigenvector_sigma_points_give_one_bias_to_second_order():
    """The bias is ½ tr(H Σ) + O(|l|⁴) for any L with L Lᵀ = Σ: the Cholesky and the eigenvector
    sigma points differ by the fourth-order terms, a hundredth for a tenth of the noise. (At 1e-3
    relative noise they differ by 48 % at 2500 rpm on this rig, 16 % at 2940 rpm: there the bias is
    not a second-order effect, as the README says of ill-conditioned points.)"""
    rpm = np.linspace(2500.0, 6000.0, 9)
    rng = np.random.default_rng(11)
    qs = np.stack([rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances[s], speed_rpm=rpm).q
                   for s in "ABC"])
    e = np.stack([RIG.imbalances[s].generalized(RIG.rotor) for s in "ABC"])
    w = rpm * np.pi / 30.0
    a = rng.standard_normal((3, rpm.size, 8, 8))
    unit = a @ np.transpose(a, (0, 1, 3, 2)) * np.abs(qs).mean() ** 2
    gaps = []
    for rel in (1e-4, 1e-5):
        out = [propagate_dense(RIG.rotor, w, w, qs, e, w ** 2, None, unit * rel ** 2, identical=False,
                               method="forces", bias=True, sigma_points=sp)[1] for sp in ("cholesky", "eigh")]
        gaps.append(np.abs(out[0] - out[1]).max(axis=1) / np.abs(out[1]).max(axis=1))
    assert gaps[0].max() < 0.03
    # a hundredth, over a rounding floor of the bias' second differences (~1e-7 of it)
    assert np.all(gaps[1] < 0.012 * gaps[0] + 2e-7)
    assert 0.008 < np.median(gaps[1] / gaps[0]) < 0.012


def test_the_core_refuses_bad_arguments_by_name():
    from rotorid._corecall import core

    n = 3
    q = [np.full((n, 4), 1e-6 + 0j) for _ in range(2)]
    args = dict(rotor=RIG.rotor.core_params(), w=np.array([100.0, 200.0, 300.0]), spin=None, q=q,
                e=np.ones((1, 2, 4), complex) * 1e-4, gain=None, covs=np.zeros((2, n, 8, 8)))
    core.propagate(**args)
    for change, match in ((dict(covs=np.zeros((2, n, 16, 16))), "covs has shape"),
                          (dict(q=np.zeros((2, 2, n, 4), complex), covs=np.zeros((2, n, 8, 8))), "one problem"),
                          (dict(shared=np.zeros((n, 8, 9))), "shared has shape"),
                          (dict(method="lsq"), "method must be"),
                          (dict(q_ped=q[:1]), "q_ped"),
                          (dict(w=np.array([100.0, 0.0, 300.0])), "w"),
                          (dict(q=q[:1], e=np.ones((1, 1, 4), complex), covs=np.zeros((1, n, 8, 8)), method="report"),
                           "at least two runs")):
        with pytest.raises(ValueError, match=match):
            core.propagate(**{**args, **change})


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
