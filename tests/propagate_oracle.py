"""The uncertainty propagation as it was written first in NumPy: every point's 2 m R perturbed
copies in one array, one core identification, the dense block covariance S and J S Jᵀ. Used only by
the tests, as the oracle of ``uncertainty.propagate`` (since 2026-11-27 one call of the core's
``identify::propagate``).

The sigma points of the bias are the columns of each run's semi-definite Cholesky factor
(:func:`psd_cholesky`, the core's definition). Until the core took the propagation over they were
the scaled eigenvectors of ``np.linalg.eigh``; any L with L Lᵀ = Σ gives the same bias to second
order, but eigenvectors are not unique (a repeated eigenvalue, e.g. Σ = s² I, leaves LAPACK a free
basis), while the Cholesky factor is, and it costs a fraction of an 8 x 8 eigen-decomposition per
run and point.
"""

import numpy as np

from rotorid.uncertainty import _eval

#: relative step of the central differences (the core's ``identify::propagate::H_REL``)
_H_REL = 1e-6
#: a Cholesky pivot at most this times its diagonal entry is zero (``covariance::PSD_PIVOT_TOL``)
_PIVOT_TOL = 1e-12


def psd_cholesky(a):
    """Lower-triangular L (n, m, m) with L Lᵀ = a for symmetric positive semi-definite a (n, m, m),
    column by column from the lower triangle, a pivot <= _PIVOT_TOL a_jj leaving its column zero
    (the operations in the core's order, so the same bits)."""
    m = a.shape[1]
    L = np.zeros_like(a)
    for j in range(m):
        d = a[:, j, j].copy()
        for k in range(j):
            d = d - L[:, j, k] * L[:, j, k]
        ok = d > _PIVOT_TOL * a[:, j, j]
        ljj = np.sqrt(np.where(ok, d, 1.0))
        L[:, j, j] = np.where(ok, ljj, 0.0)
        for i in range(j + 1, m):
            v = a[:, i, j].copy()
            for k in range(j):
                v = v - L[:, i, k] * L[:, j, k]
            L[:, i, j] = np.where(ok, v / ljj, 0.0)
    return L


def propagate_dense(rotor, w, spin, qs, e, gain, sigma, covs, *, identical, method, bias=False, shared=None, q_ped=None,
                    sigma_points="cholesky"):
    """uncertainty.propagate as first written (its docstring says what it computes); with
    ``sigma_points="eigh"`` the bias from the scaled eigenvectors of each run's covariance, as
    before 2026-11-27."""
    # (the inputs come validated from the public identification)
    R, n, _ = qs.shape
    ped = q_ped is not None
    m = 16 if ped else 8                                                 # real inputs per run and point
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
    # sigma points: +-l_k with l_k the columns of each run's Cholesky factor
    p0 = _eval(rotor, w, spin, qs[None], e, gain, sigma, identical, method, None if pb is None else q_ped[None])[0]
    qb[:] = qs[None]
    if ped:
        pb[:] = q_ped[None]
    col = 0
    for r in range(R):
        if sigma_points == "eigh":
            ev, V = np.linalg.eigh(np.nan_to_num(covs[r], nan=0.0))
            L = V * np.sqrt(np.clip(ev, 0.0, None))[:, None, :]
        else:
            L = psd_cholesky(np.nan_to_num(covs[r], nan=0.0))            # (n, m, m): columns l_k
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
