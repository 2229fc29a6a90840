"""Moving a response between the probe planes and the bearings moves its covariance with it: the
core's ``covariance::move_covariances`` forms A C Aᵀ, or with pedestal motion the blocks of the
joint congruence M Σ Mᵀ (M = [[A, B], [0, I]]), without an (n, 16, 16) array. The oracle is the
NumPy form rotorid used before (the joint matrix moved whole, ``simulate._joint_moved``).

A moved pedestal run is built unchecked (its covariances are valid when the source's are), so the
source's own fields are checked again on the way: a covariance set after construction is caught.
"""

import dataclasses

import numpy as np
import pytest
import rotorid
from rotorid import _core
from rotorid.errors import RotoridError
from rotorid.simulate import (
    ImpactResponse,
    SyncResponse,
    _joint_moved,
    _pedestal_transform,
    _plane_matrix,
    _plane_matrix8,
    joint_cov,
)

RIG = rotorid.nsf_rig()
PED = rotorid.example_pedestals()


def _spd(rng, n, m=8, scale=1e-12):
    a = rng.standard_normal((n, m, m))
    return scale * (a @ np.swapaxes(a, 1, 2) + 0.1 * np.eye(m))


def _pedestal_run(rng, *, cross=False, nan_at=None, n=40):
    rpm = np.linspace(2000.0, 7000.0, n)
    r = rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances["A"], speed_rpm=rpm, at="probes",
                                   pedestals=PED)
    joint = _spd(rng, n, 16)
    cov, pcov = joint[:, :8, :8].copy(), joint[:, 8:, 8:].copy()
    if nan_at is not None:
        cov[nan_at] = np.nan
        pcov[nan_at] = np.nan
    return SyncResponse(rpm, r.q, r.imbalance, "probes", None, cov, np.full(n, 12.0), r.pedestal, pcov,
                        joint[:, :8, 8:].copy() if cross else None)


def _oracle(run, where):
    out = _joint_moved(RIG.rotor, joint_cov(run), where)
    return out[:, :8, :8], out[:, :8, 8:]


@pytest.mark.parametrize("cross", [False, True])
def test_pedestal_runs_move_their_covariance_as_the_joint_congruence(cross):
    run = _pedestal_run(np.random.default_rng(1), cross=cross, nan_at=7)
    cov_before = run.cov
    moved = run.at_bearings(RIG.rotor)
    assert run.cov is cov_before                # the source keeps its own arrays
    want_cov, want_cross = _oracle(run, "bearings")
    big = np.nanmax(np.abs(want_cov))
    np.testing.assert_allclose(moved.cov, want_cov, rtol=1e-12, atol=1e-14 * big)
    np.testing.assert_allclose(moved.pedestal_cross, want_cross, rtol=1e-12, atol=1e-14 * big)
    np.testing.assert_array_equal(moved.cov, np.swapaxes(moved.cov, 1, 2))     # exactly symmetric
    assert np.isnan(moved.cov[7]).all() and np.isnan(moved.pedestal_cross[7]).all()
    assert np.isfinite(np.delete(moved.cov, 7, 0)).all()
    assert moved.at == "bearings" and moved.pedestal is run.pedestal
    np.testing.assert_array_equal(moved.dof, run.dof)
    # the move back gives the source's covariance
    back = moved.at_probes(RIG.rotor)
    np.testing.assert_allclose(np.delete(back.cov, 7, 0), np.delete(run.cov, 7, 0), rtol=1e-9, atol=1e-13 * big)


def test_runs_without_pedestal_motion_move_as_a_c_at():
    rng = np.random.default_rng(2)
    r = rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances["B"], speed_rpm=[3000.0, 4000.0, 5000.0],
                                   at="probes")
    cov = _spd(rng, 3)
    cov[1, 2, 5] = cov[1, 5, 2] = np.nan
    run = SyncResponse(r.speed_rpm, r.q, r.imbalance, "probes", None, cov)
    A8 = _plane_matrix8(_plane_matrix(RIG.rotor, "bearings"))
    want = A8 @ run.cov @ A8.T
    got = run.at_bearings(RIG.rotor).cov
    np.testing.assert_allclose(got[[0, 2]], want[[0, 2]], rtol=1e-12, atol=1e-14 * np.abs(want[0]).max())
    assert np.isnan(got[1]).all()


def test_impacts_with_pedestal_motion_move_alike():
    rng = np.random.default_rng(3)
    f = np.linspace(20.0, 120.0, 12)
    t = rotorid.impact_frf(RIG.rotor, RIG.bearings, speed_rpm=2000.0, freq_hz=f, at="probes", pedestals=PED)
    test = dataclasses.replace(t, cov=_spd(rng, 12, scale=1e-18), pedestal_cov=_spd(rng, 12, scale=1e-18),
                               dof=np.full(12, 8.0))
    moved = test.at_bearings(RIG.rotor)
    assert isinstance(moved, ImpactResponse) and moved.sigma == test.sigma and moved.direction == test.direction
    want_cov, want_cross = _oracle(test, "bearings")
    np.testing.assert_allclose(moved.cov, want_cov, rtol=1e-12, atol=1e-14 * np.abs(want_cov).max())
    np.testing.assert_allclose(moved.pedestal_cross, want_cross, rtol=1e-12, atol=1e-14 * np.abs(want_cov).max())
    A, B = _pedestal_transform(_plane_matrix(RIG.rotor, "bearings"))
    np.testing.assert_allclose(moved.q, test.q @ np.kron(np.eye(2), A).T + test.pedestal @ np.kron(np.eye(2), B).T)


def test_a_covariance_set_after_construction_is_checked_on_the_move():
    run = _pedestal_run(np.random.default_rng(4))
    bad = run.cov.copy()
    bad[3, 0, 1] += 1e-6  # asymmetric
    run.cov = bad
    with pytest.raises(RotoridError, match="cov.*(symmetric|asymmetric)"):
        run.at_bearings(RIG.rotor)
    run = _pedestal_run(np.random.default_rng(4))
    run.pedestal_cov = -run.pedestal_cov  # negative definite
    with pytest.raises(RotoridError, match="pedestal_cov"):
        run.at_bearings(RIG.rotor)


def test_a_q_replaced_after_construction_takes_the_checked_constructor():
    run = _pedestal_run(np.random.default_rng(5))
    run.q = run.q.tolist()            # a list: the checked path converts and checks it
    moved = run.at_bearings(RIG.rotor)
    np.testing.assert_allclose(moved.cov, _oracle(dataclasses.replace(run, q=np.array(run.q)), "bearings")[0],
                               rtol=1e-12, atol=1e-26)
    run.q = np.array(run.q)[:-1]      # a wrong shape: refused by name
    with pytest.raises(RotoridError, match="q"):
        run.at_bearings(RIG.rotor)


@pytest.mark.parametrize("args, kw, match", [
    ((np.eye(8), None, np.zeros((3, 8, 7))), {}, "cov"),
    ((np.eye(4), None, np.zeros((3, 8, 8))), {}, "a"),
    ((np.eye(8), np.eye(8), np.zeros((3, 8, 8))), {}, "pedestal_cov"),
    ((np.eye(8), None, np.zeros((3, 8, 8))), {"pedestal_cov": np.zeros((3, 8, 8))}, "pedestal_cov"),
    ((np.eye(8), None, np.zeros((3, 8, 8))), {"cross": np.zeros((3, 8, 8))}, "cross"),
    ((np.eye(8), np.eye(8), np.zeros((3, 8, 8))), {"pedestal_cov": np.zeros((2, 8, 8))}, "pedestal_cov"),
    ((np.full((8, 8), np.inf), None, np.zeros((3, 8, 8))), {}, "maps"),
])
def test_the_core_refuses_bad_arguments_by_name(args, kw, match):
    with pytest.raises((ValueError, RotoridError), match=match):
        _core.move_covariances(*args, **kw)
