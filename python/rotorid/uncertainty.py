"""Uncertainty of identified coefficients: measurement covariance propagated through the estimator.

The identification maps the measured responses q (runs x 4 complex per point) to the 16 real
coefficients p. Both sides of the equations hold measured responses (the regressor Q(q) as well as
the inertia term), so this is an errors-in-variables problem; to first order the coefficient
covariance is

    Cov(p) = J Σ Jᵀ,   J = ∂p/∂[Re q, Im q]  (16 x 8R),   Σ = blockdiag(Σ_1, ..., Σ_R),

with Σ_r the 8 x 8 covariance of run r's [Re q, Im q] at that point (from the data: order tracking
batch means, single-impact scatter, a DAQ's stated accuracy). J is taken by central differences
of the estimator itself, all 16R perturbed copies of every point identified in one core call
(``rotorid_core::identify::propagate``, whose documentation has the formulas), so it is exact for
whichever solver ("forces" or "report", two runs or many) produced p. The linearization holds
while the relative response errors times the condition number stay small; beyond that the points
are flagged (relative standard error above ``max_rel_std``).

Intervals use Student's t with the degrees of freedom of the covariance estimates (the smallest
over the runs at that point; a covariance known exactly has infinite dof).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ._corecall import core as _core
from .errors import RotoridError
from .model import _REPORT_TO_BIJ

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
                              q_ped=None if pb is None else np.ascontiguousarray(pb), refine_all=True)
    return _report_order(k, c)


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
    over the sigma points l_k (the columns of a Cholesky factor L of each run's covariance, L Lᵀ =
    Σ_r, one run at a time; semi-definite covariances allowed). Returns (cov, bias).

    ``shared`` (n, 8, 8), or (n, 16, 16) with pedestal motion: a covariance common to every pair
    of runs (all runs less the same baseline run): the off-diagonal blocks of Σ.

    One core call (``rotorid_core::identify::propagate``): every point's perturbed copies are
    identified a few points at a time on the core's threads."""
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
    cov, b, *_ = _propagate(rotor, w, spin, list(qs), e, gain, sigma, covs, identical=identical, method=method,
                           bias=bias, shared=shared, q_ped=None if q_ped is None else list(q_ped))
    return (cov, b) if bias else cov


def _propagate(rotor, w, spin, qs, e, gain, sigma, covs, *, identical, method, bias, shared=None, q_ped=None,
               w_scale=None, calibration=None, meas_std=False):
    """:func:`propagate` of arguments rotorid made itself: ``qs`` (and ``q_ped``) lists of the runs'
    (n, 4) arrays, used where they are; ``w`` in the axis' unit times ``w_scale``, ``spin`` None
    for synchronous runs (spin = w), ``gain`` None for an imbalance (spin²), as the core's
    identification takes them. ``covs``: (R, n, m, m), or with pedestal motion a list of each
    run's (cov, pedestal_cov, cross or None) blocks (n, 8, 8). ``calibration``: the
    accelerometers' calibration uncertainty (gain std, phase std in radians, probe maps
    (R, 4, 4); ``identify._calibration_inputs``), added to the covariance; ``covs`` None then
    gives the calibration's alone. Returns (cov, bias or None, unknown (n,) bool, k_std, c_std,
    meas), the standard errors (n, 2, 2, 2) NaN where unknown, ``meas`` with ``meas_std`` and a
    calibration the standard errors of the measurement covariance alone (k_std, c_std), else
    None."""
    def arr(a):
        """A float64 array of at least one dimension (a 0-d value as (1,)), or None."""
        return None if a is None else np.ascontiguousarray(a, dtype=float).reshape(np.shape(a) or (1,))

    cov, b, unknown, k_std, c_std, mk, mc = _core.propagate(
        rotor.core_params(), arr(w), arr(spin), qs, np.ascontiguousarray(e[None], dtype=complex), arr(gain),
        covs if covs is None or isinstance(covs, list) else np.ascontiguousarray(covs, dtype=float),
        identical=identical, method=method, sigma=arr(sigma), q_ped=q_ped, w_scale=w_scale,
        shared=None if shared is None else np.ascontiguousarray(shared, dtype=float), bias=bias,
        calibration=calibration, meas_std=meas_std)
    return cov, b, unknown.view(bool), k_std, c_std, None if mk is None else (mk, mc)


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
