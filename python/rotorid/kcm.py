"""K-C-M fit of frequency-dependent impact results: Z(w) = K - w^2 M + j w C per coefficient.

Impacts identify an impedance at every frequency; a support whose coefficients do not depend on
frequency (or a narrow band of one that does) is summarized by stiffness K, damping C and an
apparent mass M. With the identified k(w) = Re Z and c(w) = Im Z / w and their standard errors,

    k(w_n) = K - w_n^2 M        weighted least squares in (K, M), weights 1 / k_std^2
    c(w_n) = C                   weighted mean, weights 1 / c_std^2

per coefficient (xx, xy, yx, yy of each bearing). When the scatter about the fit exceeds the
standard errors (reduced chi-square above 1, model error or underestimated errors) the intervals
are widened by sqrt(chi-square) (Birge ratio); the quantiles are Student's t with n - 2 (K, M)
and n - 1 (C) degrees of freedom. Neighbouring frequencies are not independent (windows, zero
padding): the standard errors are the larger of the model-based ones and a Newey-West (HAC)
estimate from the residuals' autocorrelation.

The apparent masses are a diagnostic: the rotor's own inertia is in the model, so a direct mass
that is significant and large (the sum over both bearings a sizeable fraction of the rotor mass)
points at a rotor model (mass, inertia, probe positions) that does not fit the data, or at real
inertia in the support (a squeeze film's added mass, a pedestal). A significantly negative direct
mass is unphysical for a support and says the same.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import RotoridError


@dataclass
class KCMFit:
    """Result of :func:`fit_kcm`: arrays (2, 2, 2) = [bearing, i, j] in SI (N/m, N·s/m, kg)."""

    band_hz: tuple
    n_points: int
    K: np.ndarray
    M: np.ndarray
    C: np.ndarray
    K_std: np.ndarray
    M_std: np.ndarray
    C_std: np.ndarray
    r2: np.ndarray
    chi2_k: np.ndarray
    chi2_c: np.ndarray
    weighted: bool
    mass_check: str
    std_method: str = "model and HAC"
    dof: float | None = None

    def interval(self, level: float = 0.95) -> dict:
        """{"K": (lower, upper), "M": ..., "C": ...} at the confidence ``level``."""
        from ._validate import number
        from .uncertainty import t_quantile

        level = number("level", level)
        tk = float(t_quantile(level, self.dof if self.dof is not None else self.n_points - 2))
        tc = float(t_quantile(level, self.dof if self.dof is not None else self.n_points - 1))
        return {"K": (self.K - tk * self.K_std, self.K + tk * self.K_std),
                "M": (self.M - tk * self.M_std, self.M + tk * self.M_std),
                "C": (self.C - tc * self.C_std, self.C + tc * self.C_std)}

    def to_dataframe(self):
        """One row per coefficient: bearing, ij, K, K_std, M, M_std, C, C_std, R² of k(w), chi²."""
        import pandas as pd

        rows = []
        for b in range(2):
            for i in range(2):
                for j in range(2):
                    ij = "xy"[i] + "xy"[j]
                    rows.append(dict(coefficient=f"{ij}{b + 1}", K=self.K[b, i, j], K_std=self.K_std[b, i, j],
                                     M=self.M[b, i, j], M_std=self.M_std[b, i, j], C=self.C[b, i, j],
                                     C_std=self.C_std[b, i, j], r2_k=self.r2[b, i, j],
                                     chi2_k=self.chi2_k[b, i, j], chi2_c=self.chi2_c[b, i, j]))
        return pd.DataFrame(rows)


def fit_kcm(ident, *, band_hz=None, rotor=None, only_ok: bool = True) -> KCMFit:
    """Fit K, C and an apparent mass M to each coefficient of an impact identification.

    Parameters
    ----------
    ident : Identification
        Over ``freq_hz`` (from :func:`rotorid.identify_impact` or the impact chain).
    band_hz : (float, float), optional
        Frequencies to fit (default: all).
    rotor : RigidRotor, optional
        For the plausibility check of the direct masses against the rotor mass.
    only_ok : bool
        Use only the points flagged ok.

    Returns
    -------
    KCMFit

    Examples
    --------
    >>> import numpy as np, rotorid
    >>> rig = rotorid.nsf_rig()
    >>> f = np.arange(10.0, 120.0, 2.0)
    >>> tests = [rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=1000, freq_hz=f, direction=d) for d in "xy"]
    >>> fit = rotorid.fit_kcm(rotorid.identify_impact(rig.rotor, tests), rotor=rig.rotor)
    >>> float(round(fit.K[0, 0, 0] / 1e6, 3)), float(round(fit.C[0, 0, 0], 1)), bool(abs(fit.M[0, 0, 0]) < 1e-6)
    (3.0, 2000.0, True)
    """
    from .model import RigidRotor

    if getattr(ident, "axis_name", None) != "freq_hz":
        raise RotoridError("fit_kcm needs an identification over freq_hz (impact results)")
    from ._validate import flag

    only_ok = flag("only_ok", only_ok)
    if rotor is not None and not isinstance(rotor, RigidRotor):
        raise RotoridError(f"rotor must be a rotorid.RigidRotor (or None), got {type(rotor).__name__}")
    f = ident.axis
    sel = np.ones(f.size, bool)
    if band_hz is not None:
        try:
            lo, hi = (float(v) for v in band_hz)
        except (TypeError, ValueError):
            raise RotoridError(f"band_hz must be (low, high) in Hz, got {band_hz!r}") from None
        if not (0 <= lo < hi):
            raise RotoridError(f"band_hz must be (low, high) with 0 <= low < high, got {band_hz!r}")
        sel &= (f >= lo) & (f <= hi)
    if only_ok:
        sel &= ident.ok
    sel &= np.all(np.isfinite(ident.k.reshape(f.size, -1)), axis=1)
    n = int(sel.sum())
    if n < 3:
        raise RotoridError(f"the K-C-M band holds {n} usable point(s) (ok and finite); at least 3 are needed for "
                           "K and M with one degree of freedom to spare: widen band_hz or check the flags")
    w = 2 * np.pi * f[sel]
    k = ident.k[sel].reshape(n, 8)
    c = ident.c[sel].reshape(n, 8)
    ks = ident.k_std[sel].reshape(n, 8)
    cs = ident.c_std[sel].reshape(n, 8)
    weighted = bool(np.all(np.isfinite(ks)) and np.all(ks > 0) and np.all(np.isfinite(cs)) and np.all(cs > 0))
    if not weighted:
        ks = np.ones_like(k)
        cs = np.ones_like(c)
    A = np.stack([np.ones(n), -w ** 2], axis=1)
    A1 = np.ones((n, 1))
    K = np.empty(8)
    M = np.empty(8)
    C = np.empty(8)
    Ks, Ms, Cs, r2, chik, chic = (np.empty(8) for _ in range(6))
    for j in range(8):
        p, cov_m, cov_h, res, wt, chi = _wls(A, k[:, j], 1.0 / ks[:, j] ** 2, weighted)
        K[j], M[j] = p
        Ks[j], Ms[j] = np.sqrt(np.maximum(np.diag(cov_m), np.diag(cov_h)))
        kbar = np.sum(wt * k[:, j]) / np.sum(wt)
        ss_tot = float(np.sum(wt * (k[:, j] - kbar) ** 2))
        r2[j] = 1.0 - float(np.sum(wt * res ** 2)) / ss_tot if ss_tot > 0 else 1.0
        chik[j] = chi
        pc, cov_mc, cov_hc, _, _, chic[j] = _wls(A1, c[:, j], 1.0 / cs[:, j] ** 2, weighted)
        C[j] = pc[0]
        Cs[j] = np.sqrt(max(cov_mc[0, 0], cov_hc[0, 0]))
    shape = (2, 2, 2)
    out = KCMFit((float(f[sel].min()), float(f[sel].max())), n, K.reshape(shape), M.reshape(shape), C.reshape(shape),
                 Ks.reshape(shape), Ms.reshape(shape), Cs.reshape(shape), r2.reshape(shape), chik.reshape(shape),
                 chic.reshape(shape), weighted, "")
    out.mass_check = _mass_check(out, rotor)
    return out


def with_jackknife(fit: KCMFit, replicates, groups, rotor=None) -> KCMFit:
    """The fit with standard errors from a stratified delete-one jackknife over impacts.

    ``replicates``: KCMFit of the same band with one impact left out, ``groups``: the test (group)
    each replicate left an impact of. Resampling whole impacts carries every correlation between
    frequencies (windows, zero padding, the common force spectrum) into the standard errors,
    which a fit of independent points cannot; dof = smallest group size - 1."""
    from ._validate import instance
    from .model import RigidRotor

    instance("fit", fit, KCMFit, what="KCMFit")
    instance("rotor", rotor, RigidRotor, allow_none=True, what="rotorid.RigidRotor")
    if isinstance(replicates, (KCMFit, str, bytes)):
        raise RotoridError(f"replicates must be a list of KCMFit (one per left-out impact), got one "
                           f"{type(replicates).__name__}")
    try:
        replicates = list(replicates)
    except TypeError:
        raise RotoridError(f"replicates must be a list of KCMFit, got {type(replicates).__name__}") from None
    for i, r in enumerate(replicates):
        instance(f"replicates[{i}]", r, KCMFit, what="KCMFit")
    if isinstance(groups, (str, bytes)):
        raise RotoridError(f"groups must list the group of each replicate, got {groups!r}")
    groups = np.asarray(groups)
    if groups.ndim != 1 or groups.size != len(replicates) or groups.size < 2:
        raise RotoridError(f"groups must give the group of each of the {len(replicates)} replicates (at least 2), got "
                           f"shape {groups.shape}")
    if groups.dtype.kind not in "iuUS":
        raise RotoridError(f"groups must be whole numbers or names, got dtype {groups.dtype}")
    var = {name: np.zeros((2, 2, 2)) for name in ("K", "M", "C")}
    sizes = []
    for g in np.unique(groups):
        reps = [r for r, gg in zip(replicates, groups) if gg == g]
        n = len(reps)
        sizes.append(n)
        for name in var:
            vals = np.stack([getattr(r, name) for r in reps])
            var[name] += (n - 1.0) / n * np.sum((vals - vals.mean(axis=0)) ** 2, axis=0)
    out = KCMFit(fit.band_hz, fit.n_points, fit.K, fit.M, fit.C, np.sqrt(var["K"]), np.sqrt(var["M"]),
                 np.sqrt(var["C"]), fit.r2, fit.chi2_k, fit.chi2_c, fit.weighted, "",
                 f"delete-one jackknife over {sum(sizes)} impacts", float(max(min(sizes) - 1, 1)))
    out.mass_check = _mass_check(out, rotor)
    return out


def _wls(A, y, wt, weighted):
    """Weighted least squares y ~ A p: (p, model covariance (Birge-widened), HAC covariance,
    residuals, weights, reduced chi-square). The HAC (Newey-West) covariance accounts for
    residuals correlated between neighbouring frequencies (windows, zero padding, smoothing), which
    a covariance of independent points cannot see."""
    n, m = A.shape
    AtW = A.T * wt
    Hinv = np.linalg.inv(AtW @ A)
    p = Hinv @ (AtW @ y)
    res = y - A @ p
    chi = float(np.sum(wt * res ** 2) / max(n - m, 1))
    cov_m = Hinv * (max(chi, 1.0) if weighted else chi)
    scores = A * (wt * res)[:, None]                     # (n, m)
    lag = _hac_lag(res * np.sqrt(wt), n)
    meat = scores.T @ scores
    for l in range(1, lag + 1):
        g = scores[l:].T @ scores[:-l]
        meat += (1.0 - l / (lag + 1.0)) * (g + g.T)
    cov_h = Hinv @ meat @ Hinv * n / max(n - m, 1)
    return p, cov_m, cov_h, res, wt, chi


def _hac_lag(r, n) -> int:
    """Bandwidth of the Newey-West estimator: the usual 4 (n/100)^(2/9), or farther while the
    residuals' autocorrelation stays above 0.2 (oversampled spectra), at most n/4."""
    lag = int(np.floor(4 * (n / 100.0) ** (2.0 / 9.0)))
    r = r - r.mean()
    den = float(np.dot(r, r))
    if den > 0:
        for l in range(1, max(n // 4, 1)):
            if float(np.dot(r[l:], r[:-l])) / den < 0.2:
                break
            lag = max(lag, l)
    return max(min(lag, n // 4), 0)


def _mass_check(fit, rotor) -> str:
    """Plausibility of the apparent direct masses (empty when nothing stands out)."""
    notes = []
    for i, ax in enumerate("xy"):
        m = fit.M[:, i, i]
        s = fit.M_std[:, i, i]
        total, total_s = float(m.sum()), float(np.sqrt(np.sum(s ** 2)))
        significant = abs(total) > 3 * total_s
        for b in range(2):
            if m[b] < -3 * s[b]:
                notes.append(f"M{ax}{ax}{b + 1} = {m[b]:.3g} kg is significantly negative (unphysical for a support)")
        if rotor is not None and significant and abs(total) > 0.05 * rotor.mass_kg:
            notes.append(f"the direct {ax} masses add up to {total:.3g} ± {total_s:.2g} kg, "
                         f"{100 * total / rotor.mass_kg:.0f} % of the rotor mass: the rotor model (mass, inertia, probe "
                         "positions) may not fit the data, or the supports carry real inertia")
    return "; ".join(notes)
