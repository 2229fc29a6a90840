"""Uncertainty of identified coefficients: measurement covariance propagated through the estimator.

The identification maps the measured responses q (runs x 4 complex per point) to the 16 real
coefficients p. Both sides of the equations hold measured responses (the regressor Q(q) as well as
the inertia term), so this is an errors-in-variables problem; to first order the coefficient
covariance is

    Cov(p) = J Σ Jᵀ,   J = ∂p/∂[Re q, Im q]  (16 x 8R),   Σ = blockdiag(Σ_1, ..., Σ_R),

with Σ_r the 8 x 8 covariance of run r's [Re q, Im q] at that point (from the data: order tracking
batch means, single-impact scatter, a DAQ's stated accuracy). J is taken by central differences
of the estimator itself, all 16R perturbed copies of every point in one batched core call, so it
is exact for whichever solver ("forces" or "report", two runs or many) produced p. The
linearization holds while the relative response errors times the condition number stay small;
beyond that the points are flagged (relative standard error above ``max_rel_std``).

Intervals use Student's t with the degrees of freedom of the covariance estimates (the smallest
over the runs at that point; a covariance known exactly has infinite dof).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ._corecall import core as _core
from .errors import RotoridError
from .model import _REPORT_TO_BIJ

#: relative perturbation of the responses for the finite-difference Jacobian
_H_REL = 1e-6


class Interval(NamedTuple):
    """Lower and upper bounds of k and c (each (n, 2, 2, 2)) at a confidence level."""

    k_lower: np.ndarray
    k_upper: np.ndarray
    c_lower: np.ndarray
    c_upper: np.ndarray
    level: float


def report_vector(k, c):
    """(..., 16) in report eq. 9 order from k, c (..., 2, 2, 2) (NaN where unknown stays NaN)."""
    k, c = _coefficients(k=k, c=c)
    return _report_order(k, c)


def _report_order(k, c):
    """:func:`report_vector` of arrays rotorid made itself (not checked again). Eq. 9 lists the
    two bearings' values of each term in turn (Kxx1, Kxx2, Kxy1, ...): position 2 t + b holds
    [b, i, j] flat 4 b + t, so each half is the transpose of the (2, 4) [bearing, term] block (a
    strided copy; an index array on the last axis took twice as long as the core call)."""
    lead = k.shape[:-3]
    out = np.empty(lead + (2, 4, 2))
    out[..., 0, :, :] = k.reshape(lead + (2, 4)).swapaxes(-1, -2)
    out[..., 1, :, :] = c.reshape(lead + (2, 4)).swapaxes(-1, -2)
    return out.reshape(lead + (16,))


def _coefficients(**arrays):
    """Real arrays (..., 2, 2, 2) of one shape (NaN allowed: unknown), in the order given."""
    from ._validate import real_array

    out = []
    for name, v in arrays.items():
        a = real_array(name, v, finite=False)
        if a.ndim < 3 or a.shape[-3:] != (2, 2, 2):
            raise RotoridError(f"{name} must have shape (..., 2, 2, 2) = [bearing, i, j], got {a.shape}")
        if out and a.shape != out[0].shape:
            raise RotoridError(f"{name} has shape {a.shape}, {next(iter(arrays))} has {out[0].shape}")
        out.append(a)
    return out


def _eval(rotor, w, spin, qb, e, gain, sigma, identical, method, pb=None):
    k, c, *_ = _core.identify(rotor.core_params(), w, spin, np.ascontiguousarray(qb), np.ascontiguousarray(e[None],
                              dtype=complex), gain, identical=identical, method=method, with_std=False, sigma=sigma,
                              q_ped=None if pb is None else np.ascontiguousarray(pb))
    return _report_order(k, c)


#: points per pass of :func:`propagate`: its 2 m R perturbed copies of the runs (17 MB at 4 runs
#: without pedestals) are reused from pass to pass instead of one array for every point (164 MB at
#: 10,000 points, most of its time in page faults)
PROPAGATE_CHUNK = 2048


def propagate(rotor, w, spin, qs, e, gain, sigma, covs, *, identical, method, bias=False, shared=None, q_ped=None):
    """Covariance (n, 16, 16) of the report vector from run covariances ``covs`` (R, n, 8, 8) of
    the responses ``qs`` (R, n, 4) at the bearings. NaN at points where a run's covariance is
    unknown or the estimator is singular.

    With pedestal motion ``q_ped`` (R, n, 4), ``qs`` is the relative motion and ``covs`` is
    (R, n, 16, 16), the joint covariance of [Re q, Im q, Re q_ped, Im q_ped] of each run: the
    accelerometers' errors reach the coefficients through the inertia term.

    With ``bias=True`` also the estimator's second-order bias (n, 16): the noise turns a nonlinear
    estimator's mean away from the truth (least squares with noisy regressors shrinks toward zero,
    the classic errors-in-variables attenuation), by b = ½ Σ_k [p(q + l_k) + p(q - l_k) - 2 p(q)]
    over the sigma points l_k (the columns of Σ^½, one run at a time). Returns (cov, bias).

    ``shared`` (n, 8, 8), or (n, 16, 16) with pedestal motion: a covariance common to every pair
    of runs (all runs less the same baseline run): the off-diagonal blocks of Σ.

    The points are independent: they are taken ``PROPAGATE_CHUNK`` at a time, with the same
    buffers for every pass."""
    from ._validate import complex_array, flag, real_array

    qs = complex_array("qs", qs, shape=(None, None, 4))
    R, n, _ = qs.shape
    ped = q_ped is not None
    if ped:
        q_ped = complex_array("q_ped", q_ped, shape=(R, n, 4))
    m = 16 if ped else 8                                                 # real inputs per run and point
    covs = real_array("covs", covs, shape=(R, n, m, m), finite=False)
    if shared is not None:
        shared = real_array("shared", shared, shape=(n, m, m), finite=False)
    bias = flag("bias", bias)
    cov = np.empty((n, 16, 16))
    b = np.empty((n, 16)) if bias else None
    size = max(1, min(n, PROPAGATE_CHUNK))
    qb = np.empty((2 * m * R, R, size, 4), dtype=complex)
    pb = np.empty_like(qb) if ped else None

    def at(a, sl):
        """A per-point argument of the core (n,) for the points ``sl``; broadcast ones as they are."""
        return a if a is None or np.ndim(a) == 0 or a.shape[0] != n or n == 1 else a[sl]

    for s0 in range(0, n, size):
        sl = slice(s0, min(n, s0 + size))
        c = sl.stop - sl.start
        out = _propagate_points(rotor, at(w, sl), at(spin, sl), qs[:, sl], e, at(gain, sl), at(sigma, sl), covs[:, sl],
                                identical, method, bias, None if shared is None else shared[sl],
                                None if q_ped is None else q_ped[:, sl], qb[:, :, :c], None if pb is None else pb[:, :, :c])
        if bias:
            cov[sl], b[sl] = out
        else:
            cov[sl] = out
    return (cov, b) if bias else cov


def _propagate_points(rotor, w, spin, qs, e, gain, sigma, covs, identical, method, bias, shared, q_ped, qb, pb):
    """:func:`propagate` for a few points, in the buffers ``qb`` (and ``pb`` with pedestal motion),
    (2 m R, R, points, 4)."""
    R, n, _ = qs.shape
    ped = q_ped is not None
    m = 16 if ped else 8
    scale = np.sqrt(np.mean(np.abs(qs) ** 2, axis=(0, 2)))
    h = _H_REL * np.where(scale > 0, scale, 1.0)
    qb[:] = qs[None]
    if ped:
        pb[:] = q_ped[None]

    def target(comp):
        return qb if comp < 8 else pb

    col = 0
    for r in range(R):
        for comp in range(m):
            d = h * (1j if comp % 8 >= 4 else 1.0)
            target(comp)[2 * col, r, :, comp % 4] += d
            target(comp)[2 * col + 1, r, :, comp % 4] -= d
            col += 1
    rv = _eval(rotor, w, spin, qb, e, gain, sigma, identical, method, pb)   # (2 m R, n, 16)
    J = (rv[0::2] - rv[1::2]) / (2.0 * h[None, :, None])                # (mR, n, 16)
    J = np.transpose(J, (1, 2, 0))                                       # (n, 16, mR)
    known = [np.nan_to_num(covs[r], nan=0.0) for r in range(R)]
    if shared is None:
        # the runs are independent: Σ is block diagonal, J Σ Jᵀ = Σ_r J_r Σ_r J_rᵀ
        cov = np.zeros((n, 16, 16))
        for r in range(R):
            Jr = J[:, :, m * r:m * r + m]
            cov += Jr @ known[r] @ np.transpose(Jr, (0, 2, 1))
    else:
        S = np.zeros((n, m * R, m * R))
        common = np.nan_to_num(shared, nan=0.0)
        for r in range(R):
            for t in range(R):
                S[:, m * r:m * r + m, m * t:m * t + m] = known[r] if t == r else common
        cov = J @ S @ np.transpose(J, (0, 2, 1))
    unknown = np.any(np.isnan(covs), axis=(0, 2, 3)) | ~np.all(np.isfinite(J), axis=(1, 2))
    cov[unknown] = np.nan
    if not bias:
        return cov
    # sigma points: +-l_k with l_k the scaled eigenvectors of each run's covariance
    p0 = _eval(rotor, w, spin, qs[None], e, gain, sigma, identical, method, None if pb is None else q_ped[None])[0]
    qb[:] = qs[None]
    if ped:
        pb[:] = q_ped[None]
    col = 0
    for r in range(R):
        ev, V = np.linalg.eigh(known[r])
        L = V * np.sqrt(np.clip(ev, 0.0, None))[:, None, :]              # (n, m, m): columns l_k
        for kk in range(m):
            lk = L[:, :4, kk] + 1j * L[:, 4:8, kk]                       # (n, 4) complex
            qb[2 * col, r] += lk
            qb[2 * col + 1, r] -= lk
            if ped:
                lp = L[:, 8:12, kk] + 1j * L[:, 12:16, kk]
                pb[2 * col, r] += lp
                pb[2 * col + 1, r] -= lp
            col += 1
    rs = _eval(rotor, w, spin, qb, e, gain, sigma, identical, method, pb)
    b = 0.5 * np.sum(rs[0::2] + rs[1::2] - 2.0 * p0[None], axis=0)
    b[unknown] = np.nan
    return cov, b


def t_quantile(level: float, dof):
    """Two-sided quantile of Student's t for a confidence ``level`` (normal where dof is inf; NaN
    where dof is NaN or <= 0: a covariance of unknown quality, no interval; inf where dof > 0 is
    so small that the quantile overflows)."""
    from ._validate import number, real_array

    level = number("level", level)
    if not (0.0 < level < 1.0):
        raise RotoridError(f"level must be between 0 and 1 (e.g. 0.95), got {level!r}")
    from scipy import stats

    dof = real_array("dof", dof, finite=False)
    q = (1.0 + level) / 2.0
    out = np.where(np.isfinite(dof), stats.t.ppf(q, np.where(np.isfinite(dof) & (dof > 0), dof, 1.0)),
                   stats.norm.ppf(q))
    out = np.where(np.isnan(out) & (dof > 0), np.inf, out)  # scipy gives NaN for sub-normal dof
    return np.where(dof > 0, out, np.nan)


def std_from_cov(cov):
    """(k_std, c_std) (n, 2, 2, 2) from the report-order covariance (n, 16, 16)."""
    from ._validate import real_array

    cov = real_array("cov", cov, shape=(None, 16, 16), finite=False)
    n = cov.shape[0]
    sd = np.sqrt(np.clip(np.diagonal(cov, axis1=1, axis2=2), 0.0, None))
    k = np.empty((n, 8))
    c = np.empty((n, 8))
    k[:, _REPORT_TO_BIJ] = sd[:, :8]
    c[:, _REPORT_TO_BIJ] = sd[:, 8:]
    return k.reshape(n, 2, 2, 2), c.reshape(n, 2, 2, 2)


def relative_std(k, c, k_std, c_std):
    """Largest standard error per point relative to its bearing's direct coefficients,
    sqrt(|Kxx Kyy|) for stiffnesses and sqrt(|Cxx Cyy|) for dampings (so cross-coupled terms that
    are small are judged on the bearing's scale, not their own)."""
    k, c, k_std, c_std = _coefficients(k=k, c=c, k_std=k_std, c_std=c_std)
    if k.ndim != 4:
        raise RotoridError(f"k must have shape (n, 2, 2, 2), got {k.shape}")
    return _core.relative_std(*(np.ascontiguousarray(a, dtype=float).reshape(-1, 8) for a in (k, c, k_std, c_std)))
