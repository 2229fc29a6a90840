"""The uncertainty propagation as it was written first (rotorid 2026-11-27, before the points were
taken in chunks): every point's 2 m R perturbed copies in one array, one core call, the dense
block covariance S and J S Jᵀ. Used only by the tests, as the oracle of ``uncertainty.propagate``.
"""

import numpy as np

from rotorid.uncertainty import _H_REL, _eval


def propagate_dense(rotor, w, spin, qs, e, gain, sigma, covs, *, identical, method, bias=False, shared=None, q_ped=None):
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
    of runs (all runs less the same baseline run): the off-diagonal blocks of Σ."""
    from rotorid._validate import complex_array, flag, real_array

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
    scale = np.sqrt(np.mean(np.abs(qs) ** 2, axis=(0, 2)))
    h = _H_REL * np.where(scale > 0, scale, 1.0)
    nb = 2 * m * R
    qb = np.empty((nb, R, n, 4), dtype=complex)
    qb[:] = qs[None]
    pb = None
    if ped:
        pb = np.empty((nb, R, n, 4), dtype=complex)
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
    rv = _eval(rotor, w, spin, qb, e, gain, sigma, identical, method, pb)   # (nb, n, 16)
    J = (rv[0::2] - rv[1::2]) / (2.0 * h[None, :, None])                # (mR, n, 16)
    J = np.transpose(J, (1, 2, 0))                                       # (n, 16, mR)
    S = np.zeros((n, m * R, m * R))
    for r in range(R):
        S[:, m * r:m * r + m, m * r:m * r + m] = np.nan_to_num(covs[r], nan=0.0)
        if shared is not None:
            for t in range(R):
                if t != r:
                    S[:, m * r:m * r + m, m * t:m * t + m] = np.nan_to_num(shared, nan=0.0)
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
        ev, V = np.linalg.eigh(np.nan_to_num(covs[r], nan=0.0))
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
