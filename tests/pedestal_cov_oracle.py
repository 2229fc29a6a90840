"""The pedestal fit with measurement covariances as it was written in NumPy (rotorid until
2026-11-27, sixth session): the force Jacobian by unit perturbations through the core's bearing
forces, each point's residual covariance by batched matrix products, whitening by
``np.linalg.solve`` and ``np.linalg.lstsq``. Used only by the tests, as the oracle of
``rotorid_core::pedestal_cov`` (``_core.pedestal_fit(covs=...)``)."""

import numpy as np

from rotorid._corecall import core as _core


def _gram(A, weight=None):
    """A.T @ A, or A.T @ diag(weight) @ A, (u, u) and exactly symmetric, of a tall matrix with a
    few columns (contiguous, Fortran order, is best): one ``einsum`` sum per pair of columns. For
    this shape that is faster than the matrix product, as accurate, and starts no BLAS threads
    (whose wake-up costs milliseconds on a busy machine)."""
    u = A.shape[1]
    G = np.empty((u, u))
    for j in range(u):
        aj = A[:, j] if weight is None else weight * A[:, j]
        for k in range(j, u):
            G[j, k] = G[k, j] = np.einsum("i,i->", aj, A[:, k])
    return G


def _matvec(A, x):
    """A @ x of a tall matrix, one pass over A without BLAS (see :func:`_gram`)."""
    return np.einsum("ij,j->i", A, x)


def _split(z):
    """[Re; Im] of a complex array, raveled (C order): the right-hand side of a real least-squares
    problem, rows as :func:`_design`'s."""
    half = z.size
    out = np.empty(2 * half)
    out[:half] = z.real.reshape(half)
    out[half:] = z.imag.reshape(half)
    return out


def _design(s, s2, p, b, i, cross):
    """Real design matrix of pedestal b, direction i, (2 R n, u) in Fortran order (its columns
    contiguous, as the column sums of :func:`_gram` want them): unknowns [k_ii,
    m_i, c_ii (, k_ij, c_ij)]; rows [Re of each (run, point) (run-major), then Im]. ``s`` (R n,) =
    sigma + j w of each row, ``s2`` = s ** 2, ``p`` (R, n, 4) pedestal motion: f = (k + s² m + s c)
    p_own (+ (k_ij + s c_ij) p_other)."""
    half = s.size
    own = p[..., 2 * i + b].reshape(half)
    cols = [(own, None), (own, s2), (own, s)]
    if cross:
        other = p[..., 2 * (1 - i) + b].reshape(half)
        cols += [(other, None), (other, s)]
    X = np.empty((2 * half, len(cols)), order="F")
    t = np.empty(half, complex)
    for j, (v, factor) in enumerate(cols):
        if factor is not None:
            v = np.multiply(factor, v, out=t)
        X[:half, j] = v.real
        X[half:, j] = v.imag
    return X


def force_jacobian(forces, q, p):
    """J (R, n, 16, 4): the bearing forces' change per unit of each real input [Re q, Im q, Re p,
    Im p] (the forces are complex-linear in them), by unit perturbations of ``forces(q, p)``."""
    R, n = q.shape[:2]
    zero_q, zero_p = np.zeros_like(q), np.zeros_like(p)
    F0 = forces(zero_q, zero_p)
    J = np.empty((R, n, 16, 4), complex)
    for comp in range(16):
        dq, dp = zero_q.copy(), zero_p.copy()
        (dq if comp < 8 else dp)[..., comp % 4] = 1j if comp % 8 >= 4 else 1.0
        J[:, :, comp] = forces(dq, dp) - F0
    return J


def covariance_fit(theta, b, i, cross, R, sel, s_lap, w, F, p, J, S, Sh, weighted):
    """Pedestal b, direction i with the runs' measurement covariances, from the unweighted
    estimate ``theta`` (physical units): weighted least squares (``weighted``) or the sandwich
    covariance of the unweighted fit (the caller takes the larger of it and HC3). ``F`` (R, n, 4)
    bearing forces, ``p`` (R, n, 4) pedestal motion, ``J`` (R, n, 16, 4) the forces' Jacobian,
    ``S`` (R, n, 16, 16) and ``Sh`` the runs' and shared covariances (NaN-free), ``sel`` the points
    used (None: all). Returns (theta, covariance, relative residual of the weighted fit or None,
    std_source)."""
    nu = theta.size
    col = 2 * i + b                                               # index of (b, i) in [x1, x2, y1, y2]
    pick = slice(None) if sel is None else sel
    Fs, ps = F[:, pick], p[:, pick]
    s_rows = np.tile(s_lap[pick], R)                              # s of each (run, point), run-major
    Xs = _design(s_rows, s_rows ** 2, ps, b, i, cross)
    y = _split(Fs[..., col])
    scale = np.maximum(np.maximum(Xs.max(axis=0), -Xs.min(axis=0)), 1e-300)
    Xs /= scale                                                   # the core's scaling: the same fit
    theta = theta * scale
    m_rows = y.size
    ns = m_rows // (2 * R)
    # the equations of one point, all runs together: (ns, 2R, u) and (ns, 2R), rows [Re, Im] of
    # run 0, run 1, ... (the runs' errors may be correlated: shared_cov)
    Xp = np.stack([Xs[:m_rows // 2], Xs[m_rows // 2:]], 1).reshape(R, ns, 2, nu)
    Xp = Xp.transpose(1, 0, 2, 3).reshape(ns, 2 * R, nu)
    yp = np.stack([y[:m_rows // 2], y[m_rows // 2:]], 1).reshape(R, ns, 2)
    yp = yp.transpose(1, 0, 2).reshape(ns, 2 * R)

    def point_cov(theta):
        """(ns, 2R, 2R) covariance of each point's residuals r = F_col - D_own p_own - D_oth p_oth
        (Re, Im per run) at the estimate ``theta``."""
        th = theta / scale
        D_own = th[0] + s_lap ** 2 * th[1] + s_lap * th[2]
        D_oth = (th[3] + s_lap * th[4]) if cross else 0.0 * w
        g = J[:, :, :, col].copy()                                # (R, n, 16)
        g[:, :, 8 + col] -= D_own[None]
        g[:, :, 12 + col] -= 1j * D_own[None]
        if cross:
            oc = 2 * (1 - i) + b
            g[:, :, 8 + oc] -= D_oth[None]
            g[:, :, 12 + oc] -= 1j * D_oth[None]
        G2 = np.stack([g.real, g.imag], -2)[:, pick]              # (R, ns, 2, 16)
        V = np.zeros((ns, 2 * R, 2 * R))
        for r in range(R):
            for t in range(R):
                if r != t and Sh is None:
                    continue
                M = S[r][pick] if r == t else Sh[pick]
                V[:, 2 * r:2 * r + 2, 2 * t:2 * t + 2] = G2[r] @ M @ np.swapaxes(G2[t], -1, -2)
        return V

    resid = None
    if weighted:
        for _ in range(2):  # weights depend on the estimate (D p carries the pedestal noise)
            Lc = np.linalg.cholesky(point_cov(theta) + 1e-300 * np.eye(2 * R))
            Xw = np.linalg.solve(Lc, Xp).reshape(-1, nu)                          # whitened
            yw = np.linalg.solve(Lc, yp[..., None])[..., 0].ravel()
            theta, *_ = np.linalg.lstsq(Xw, yw, rcond=None)
        covt = np.linalg.inv(Xw.T @ Xw)
        rw = yw - Xw @ theta
        chi2 = float(rw @ rw) / max(Xw.shape[0] - nu, 1)
        # a misfit beyond the measurement errors (a wrong pedestal model) widens the errors
        covt = covt * max(chi2, 1.0)
        src = "measurement covariance"
        r = y - _matvec(Xs, theta)                                # at the weighted estimate
        resid = float(np.sqrt(np.sum(r ** 2) / max(np.sum(y ** 2), 1e-300)))
    else:
        # covariances from a few repeats (impacts: dof = impacts - 1) are too noisy to weigh with
        # (the inverse of a poorly estimated covariance overweights the rows whose variance happens
        # to come out small): unweighted least squares with the sandwich of the propagated
        # covariances, and the residual (HC3) covariance as well: it also sees errors the
        # measurement covariance misses (run-out filter leftovers, low-coherence bins); the larger
        # variance of the two counts
        XtXi = np.linalg.inv(_gram(Xs))
        meat = np.einsum("kau,kab,kbv->uv", Xp, point_cov(theta), Xp)
        covt = XtXi @ meat @ XtXi
        # (the larger of this and HC3 is taken by identify_pedestals, as before)
        src = "residual or measurement covariance, the larger (unweighted fit)"
    return theta / scale, covt / np.outer(scale, scale), resid, src



def cov_fit_numpy(params, axis, spin, qs, e, gain, ps, *, sigma=None, select=None, cross=False, w_scale=None,
                  covs, shared=None, weighted=True, thetas):
    """What ``_core.pedestal_fit(..., covs=covs, shared=shared, weighted=weighted)`` gives as its
    last element, (theta (4, u), cov (4, u, u), resid (4,)), from the unweighted fits ``thetas``
    (the arguments as the core takes them)."""
    w = (w_scale or 1.0) * np.asarray(axis, float)
    sig = 0.0 if sigma is None else float(np.asarray(sigma).ravel()[0])
    s_lap = sig + 1j * w
    spin = w if spin is None else spin
    q, p = np.stack(qs), np.stack(ps)
    R = q.shape[0]

    def forces(qq, pp):
        return _core.bearing_forces(params, w, spin, np.ascontiguousarray(qq[None]), e, gain, sigma=sigma,
                                    q_ped=np.ascontiguousarray(pp[None]))[0]

    F = forces(q, p)
    J = force_jacobian(forces, q, p)
    S = np.nan_to_num(np.stack(covs))
    Sh = None if shared is None else np.nan_to_num(shared)
    u = 5 if cross else 3
    th_out, cov_out, res_out = np.empty((4, u)), np.empty((4, u, u)), np.full(4, np.nan)
    for fi in range(4):
        b, i = fi // 2, fi % 2
        th, covt, r_w, _ = covariance_fit(thetas[fi], b, i, cross, R, select, s_lap, w, F, p, J, S, Sh,
                                           weighted)
        th_out[fi], cov_out[fi] = th, covt
        if r_w is not None:
            res_out[fi] = r_w
    return th_out, cov_out, res_out
