"""The measurement covariances' checks (``simulate.check_covs``, one core call): what passes, what
is refused with which message, and which run and point the message names."""

import numpy as np
import pytest

import rotorid
from rotorid import RotoridError
from rotorid.simulate import SyncResponse, check_cov, check_covs

RIG = rotorid.nsf_rig()


def _with_eigenvalues(lam, seed):
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.standard_normal((len(lam), len(lam))))
    a = q @ np.diag(lam) @ q.T
    return 0.5 * (a + a.T)


def _stack(n, size=8, seed=0):
    rng = np.random.default_rng(seed)
    a = rng.standard_normal((n, size, size))
    return a @ np.transpose(a, (0, 2, 1)) * 1e-12


@pytest.mark.parametrize("neg, ok", [(1e-12, True), (1e-10, True), (1e-8, False), (1e-3, False)])
def test_definiteness_to_1e9_of_the_matrix(neg, ok):
    """A negative eigenvalue of neg times the largest passes below ~1e-9 (rounding of a real
    covariance estimate), and is refused above, at the point that has it."""
    lam = np.array([1.0, 0.5, 0.2, 0.1, 0.0, 3e-3, 1e-6, -neg]) * 1e-12
    covs = _stack(5)
    covs[3] = _with_eigenvalues(lam, 1)
    if ok:
        out = check_cov("cov", covs, 5)
        np.testing.assert_array_equal(out, covs)
        assert out is not covs
    else:
        with pytest.raises(RotoridError, match=r"cov is not positive semi-definite at point 3 \(smallest eigenvalue "
                                               r"-\d"):
            check_cov("cov", covs, 5)


def test_faults_name_the_run_and_come_in_order():
    good = _stack(4)
    asym = good.copy()
    asym[2, 1, 5] += 1e-15
    indef = good.copy()
    indef[1] = _with_eigenvalues(np.r_[np.ones(7), -0.1] * 1e-12, 2)
    inf = good.copy()
    inf[0, 0, 0] = np.inf
    names = ["cov of A", "cov of B", "cov of C"]
    with pytest.raises(RotoridError, match="cov of B must be symmetric"):
        check_covs(names, [good, asym, indef], 4)
    both = asym.copy()
    both[0] = indef[1]            # point 0 indefinite, point 2 asymmetric: the asymmetric one is named
    with pytest.raises(RotoridError, match="cov of C must be symmetric"):
        check_covs(names, [good, good, both], 4)
    with pytest.raises(RotoridError, match="cov of A is not positive semi-definite at point 1"):
        check_covs(names, [indef, asym, good], 4)
    with pytest.raises(RotoridError, match="cov of B contains inf"):
        check_covs(names, [good, inf, indef], 4)
    with pytest.raises(RotoridError, match=r"cov of C has shape \(4, 8, 7\), expected \(4, 8, 8\)"):
        check_covs(names, [good, good, good[..., :7]], 4)
    with pytest.raises(RotoridError, match="cov of A must be a real array"):
        check_covs(names, [good * 1j, good, good], 4)


def test_unknown_points_become_all_nan_and_the_rest_is_copied():
    covs = _stack(6)
    covs[2, 3, 4] = np.nan
    runs = [covs, _stack(6, seed=1)]
    out = check_covs(["a", "b"], runs, 6)
    assert out.shape == (2, 6, 8, 8) and out.flags.c_contiguous
    assert np.isnan(out[0, 2]).all() and not np.isnan(np.delete(out[0], 2, axis=0)).any()
    np.testing.assert_array_equal(out[1], runs[1])
    # strided and integer input is taken as it is
    ints = np.zeros((6, 8, 8), int)
    ints[:, np.arange(8), np.arange(8)] = 2
    np.testing.assert_array_equal(check_cov("cov", ints, 6), ints.astype(float))
    big = np.zeros((6, 16, 16))
    big[:, ::2, ::2] = np.eye(8)
    np.testing.assert_array_equal(check_cov("cov", big[:, ::2, ::2], 6), big[:, ::2, ::2])


def test_constructors_and_identification_use_the_check():
    rpm = np.array([4000.0, 4500.0, 5000.0])
    r = rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances["A"], speed_rpm=rpm)
    bad = _stack(3)
    bad[1] = _with_eigenvalues(np.r_[np.ones(7), -0.5] * 1e-12, 4)
    with pytest.raises(RotoridError, match="cov is not positive semi-definite at point 1"):
        SyncResponse(rpm, r.q, r.imbalance, cov=bad)
    run = SyncResponse(rpm, r.q, r.imbalance, cov=_stack(3))
    other = SyncResponse(rpm, rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances["B"],
                                                         speed_rpm=rpm).q, RIG.imbalances["B"], cov=_stack(3, seed=2))
    run.cov = bad                  # set after construction: identification checks again, naming the run
    with pytest.raises(RotoridError, match="is not positive semi-definite at point 1"):
        rotorid.identify_synchronous(RIG.rotor, [run, other])
