"""Identification of bearing force coefficients.

Synchronous identification from imbalance runs (report eq. 4-18, probe transform eq. 19). The
heavy lifting is one call of the Rust core for the whole speed batch (and any leading Monte-Carlo
batch axis, see ``identify_synchronous_batch``).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from ._corecall import core as _core
from ._validate import all_finite, choice, complex_array, frozen, real_array
from .errors import IdentifiabilityError, RotoridError
from .model import _REPORT_TO_BIJ, REPORT_ORDER, BearingCoefficients, Imbalance, RigidRotor
from .simulate import RPM, ImpactResponse, SyncResponse, _plane_matrix, _q_as_checked, probes_to_bearings
from .speed_offsets import SPEED_OFFSETS_UNRESOLVED

#: default conditioning threshold above which a point is flagged as not trustworthy
COND_MAX = 1e4
#: default minimum response amplitude relative to the peak (report: identification is poor below ~8 %)
MIN_REL_AMPLITUDE = 0.08
#: FRFs naturally span decades over a band (1/(m w^2) above the modes), so impacts use a lower floor
MIN_REL_AMPLITUDE_IMPACT = 0.01
#: default largest standard error relative to the bearing's direct coefficients for a point to be ok
MAX_REL_STD = 0.1


@dataclass
class Identification:
    """Identified coefficients at each point of an axis (speed or frequency).

    ``k``, ``c``: (n, 2, 2, 2) = [point, bearing, i, j] in N/m and N·s/m. Diagnostics per point:
    ``cond`` (n, 2) condition number of each bearing's response matrix, ``residual`` (n,) relative
    least-squares residual (0 for exactly determined sets), ``rel_amplitude`` (n,) rms response
    amplitude (over runs and the four coordinates) relative to its maximum over the axis,
    ``ok`` (n,) False where the point should not be trusted and ``flag`` (n,) saying why ("" where
    ok; several reasons joined by "; ").

    Uncertainty: ``k_std``/``c_std`` (n, 2, 2, 2) standard errors, ``std_source`` saying where they
    come from ("measurement covariance": the responses' covariance propagated through the
    estimator; "residual": the least-squares misfit of redundant runs; "none": NaN, unknown),
    ``dof`` (n,) their degrees of freedom, ``cov`` (n, 16, 16) the covariance of the report
    vector (or None), ``rel_std`` (n,) the largest standard error relative to its bearing's direct
    coefficients, ``k_std_residual``/``c_std_residual`` the residual-based standard errors of
    redundant runs whatever was used (NaN without redundancy; much larger than ``k_std`` means the
    runs disagree more than their measurement errors explain). :meth:`interval` gives confidence
    bounds.
    """

    axis_name: str
    axis: np.ndarray
    k: np.ndarray
    c: np.ndarray
    cond: np.ndarray
    residual: np.ndarray
    rel_amplitude: np.ndarray
    k_std: np.ndarray
    c_std: np.ndarray
    ok: np.ndarray
    flag_code: np.ndarray
    method: str
    runs: list = field(default_factory=list)
    std_source: str = "none"
    dof: np.ndarray | None = None
    cov: np.ndarray | None = None
    rel_std: np.ndarray | None = None
    k_std_residual: np.ndarray | None = None
    c_std_residual: np.ndarray | None = None
    k_bias: np.ndarray | None = None
    c_bias: np.ndarray | None = None
    estimator: str = "ls"
    flag_reasons: tuple = ()

    @functools.cached_property
    def flag(self) -> np.ndarray:
        """Why each point is flagged (object array of str, "" where ok; reasons joined by "; ",
        "singular" alone); built from ``flag_code`` on first use."""
        return _flag_strings(self.flag_code, self.flag_reasons)

    def interval(self, level: float = 0.95):
        """Confidence bounds of k and c: coefficient ± t(level, dof) × standard error.

        Returns
        -------
        rotorid.uncertainty.Interval
            (k_lower, k_upper, c_lower, c_upper, level); NaN where the uncertainty is unknown.

        Examples
        --------
        >>> import numpy as np, rotorid
        >>> rig = rotorid.nsf_rig()
        >>> rpm = np.array([3500.0, 4000.0])
        >>> runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm) for s in "AB"]
        >>> for r in runs:
        ...     r.cov = np.broadcast_to(np.eye(8) * (0.1e-6) ** 2, (2, 8, 8))
        >>> ident = rotorid.identify_synchronous(rig.rotor, runs)
        >>> lo = ident.interval(0.95).k_lower
        >>> bool(np.all(lo[:, 0, 0, 0] < 3.0e6))
        True
        """
        from .uncertainty import Interval, t_quantile

        from ._validate import number

        level = number("level", level)
        dof = self.dof if self.dof is not None else np.full(self.axis.size, np.nan)
        t = t_quantile(level, dof)[:, None, None, None]
        hk, hc = t * self.k_std, t * self.c_std
        if self.k_bias is not None and self.estimator == "ls":
            # the estimator's own second-order bias (errors in variables), not corrected: the
            # interval is widened by it, so it covers where the linearization alone would not
            hk = hk + np.abs(self.k_bias)
            hc = hc + np.abs(self.c_bias)
        return Interval(self.k - hk, self.k + hk, self.c - hc, self.c + hc, level)

    @property
    def speed_rpm(self):
        if self.axis_name != "speed_rpm":
            raise AttributeError("this identification is over freq_hz")
        return self.axis

    @property
    def freq_hz(self):
        if self.axis_name != "freq_hz":
            raise AttributeError("this identification is over speed_rpm")
        return self.axis

    def report_vector(self):
        """(n, 16) coefficients in report eq. 9 order (K then C)."""
        n = self.axis.size
        return np.concatenate([self.k.reshape(n, 8)[:, _REPORT_TO_BIJ], self.c.reshape(n, 8)[:, _REPORT_TO_BIJ]], 1)

    def coefficient(self, name: str):
        """One coefficient over the axis by its report name, e.g. "Kxy1" or "Cyy2"."""
        if name not in REPORT_ORDER:
            raise RotoridError(f"unknown coefficient {name!r}; expected one of {REPORT_ORDER}")
        return self.report_vector()[:, REPORT_ORDER.index(name)]

    def bearings(self) -> BearingCoefficients:
        """The identified coefficients as a table (only points flagged ok)."""
        sel = self.ok
        if sel.sum() < 2:
            raise RotoridError("fewer than two trustworthy points to build a coefficient table")
        kw = {self.axis_name: self.axis[sel]}
        return BearingCoefficients(self.k[sel], self.c[sel], **kw)

    def to_xarray(self, *, units: str = "SI", level: float = 0.95):
        """Labeled arrays (see :func:`rotorid.exports.to_xarray`)."""
        from .exports import to_xarray

        return to_xarray(self, units=units, level=level)

    def to_netcdf(self, path, *, units: str = "SI", overwrite: bool = False) -> str:
        """NetCDF file of :meth:`to_xarray` (see :func:`rotorid.exports.to_netcdf`)."""
        from .exports import to_netcdf

        return to_netcdf(self, path, units=units, overwrite=overwrite)

    def to_excel(self, path, *, units: str = "SI", overwrite: bool = False) -> str:
        """Excel workbook with a units row (see :func:`rotorid.exports.to_excel`)."""
        from .exports import to_excel

        return to_excel(self, path, units=units, overwrite=overwrite)

    def to_json(self, path=None, *, units: str = "SI", overwrite: bool = False, context=None):
        """JSON document, or its text without ``path`` (see :func:`rotorid.exports.to_json`)."""
        from .exports import to_json

        return to_json(self, path, units=units, overwrite=overwrite, context=context)

    @classmethod
    def from_json(cls, source) -> "Identification":
        """An identification from a :meth:`to_json` document, path or text (see :func:`rotorid.exports.from_json`)."""
        from .exports import from_json

        return from_json(source)

    def to_ross(self, *, nodes, **kwargs):
        """Two ROSS bearing elements, or stochastic ones (see :func:`rotorid.ross.to_ross`; needs ``rotorid[ross]``)."""
        from .ross import to_ross

        return to_ross(self, nodes=nodes, **kwargs)

    def to_dataframe(self):
        import pandas as pd

        n = self.axis.size
        data = {self.axis_name: self.axis}
        rv = self.report_vector()
        for j, nm in enumerate(REPORT_ORDER):
            data[nm] = rv[:, j]
        ks = np.concatenate([self.k_std.reshape(n, 8)[:, _REPORT_TO_BIJ], self.c_std.reshape(n, 8)[:, _REPORT_TO_BIJ]], 1)
        for j, nm in enumerate(REPORT_ORDER):
            data[f"{nm}_std"] = ks[:, j]
        if self.k_std_residual is not None and np.any(np.isfinite(self.k_std_residual)):
            kr = np.concatenate([self.k_std_residual.reshape(n, 8)[:, _REPORT_TO_BIJ],
                                 self.c_std_residual.reshape(n, 8)[:, _REPORT_TO_BIJ]], 1)
            for j, nm in enumerate(REPORT_ORDER):
                data[f"{nm}_std_residual"] = kr[:, j]
        if np.any(np.isfinite(self.k_std)):
            iv = self.interval(0.95)
            lo = np.concatenate([iv.k_lower.reshape(n, 8)[:, _REPORT_TO_BIJ], iv.c_lower.reshape(n, 8)[:, _REPORT_TO_BIJ]], 1)
            hi = np.concatenate([iv.k_upper.reshape(n, 8)[:, _REPORT_TO_BIJ], iv.c_upper.reshape(n, 8)[:, _REPORT_TO_BIJ]], 1)
            for j, nm in enumerate(REPORT_ORDER):
                data[f"{nm}_lo95"] = lo[:, j]
                data[f"{nm}_hi95"] = hi[:, j]
        data["std_source"] = self.std_source
        data["dof"] = self.dof if self.dof is not None else np.nan
        data["rel_std"] = self.rel_std if self.rel_std is not None else np.nan
        data["cond1"] = self.cond[:, 0]
        data["cond2"] = self.cond[:, 1]
        data["residual"] = self.residual
        data["rel_amplitude"] = self.rel_amplitude
        data["ok"] = self.ok
        data["flag"] = self.flag
        return pd.DataFrame(data)


def _run_label(i, run):
    return f"run {i} ({run.name!r})" if getattr(run, "name", None) else f"run {i}"


def _as_runs(runs):
    if isinstance(runs, dict):
        out = []
        for name, r in runs.items():
            if isinstance(r, SyncResponse) and r.name is None:
                r.name = str(name)
            out.append(r)
        return out
    if isinstance(runs, (list, tuple)):
        return list(runs)
    raise RotoridError(f"runs must be a list or dict of SyncResponse, got {type(runs).__name__}")


def _second_singular_ratio(rows):
    """s2 / s1 of the complex (R, 2) matrix ``rows`` (R >= 2, not all zero): the singular values
    from G = U^H U in closed form, s1^2 + s2^2 = tr G and s1^2 s2^2 = det G with det G the sum over
    i < j of |u_i1 u_j2 - u_j1 u_i2|^2 (Lagrange's identity, free of the cancellation of
    g11 g22 - |g12|^2). Python scalars: an SVD call on a few numbers costs ~25 µs."""
    top = max(max(abs(a), abs(b)) for a, b in rows)
    rows = [(a / top, b / top) for a, b in rows]  # no overflow of the squares below
    det = sum(abs(rows[i][0] * rows[j][1] - rows[j][0] * rows[i][1]) ** 2
              for i in range(len(rows)) for j in range(i + 1, len(rows)))
    tr = sum(abs(a) ** 2 + abs(b) ** 2 for a, b in rows)
    s1 = math.sqrt((tr + math.sqrt(max(tr * tr - 4.0 * det, 0.0))) / 2.0)
    return math.sqrt(det) / s1 / s1


def check_imbalance_independence(rotor: RigidRotor, imbalances, labels, *, identical=False):
    """Raise IdentifiabilityError when the imbalance sets cannot excite independent responses."""
    need = 1 if identical else 2
    if len(imbalances) < need:
        raise IdentifiabilityError(
            f"{len(imbalances)} run(s) given; identifying {'8' if identical else 'all 16'} coefficients needs at least "
            f"{need} imbalance run(s) with linearly independent imbalance sets (report eq. 11)")
    rows = [imb._forcing(rotor) for imb in imbalances]  # (f1, f2) per run, Python complex
    for i, (f1, f2) in enumerate(rows):
        if f1 == 0 and f2 == 0:
            raise IdentifiabilityError(f"{labels[i]} has no imbalance mass (zero excitation)")
    if identical:
        return
    d1, d2 = rotor.d
    if abs(d1 + d2) <= 1e-9 * max(abs(d1) + abs(d2), rotor.span):
        raise IdentifiabilityError(
            f"the rotor's two imbalance planes coincide (d1 = {d1:g} m from the CG toward bearing 1 is the same axial "
            f"position as d2 = {d2:g} m toward bearing 2): masses in one plane excite a force and a moment in a fixed "
            "ratio, so no set of runs is independent. Check d in the rotor definition")
    if _second_singular_ratio(rows) <= 1e-9:
        U = np.array(rows)  # (R, 2)
        scale = np.abs(U).max(axis=1)
        planes = np.abs(U) > 1e-12 * scale[:, None]
        if np.all(~planes[:, 1]) or np.all(~planes[:, 0]):
            p = 1 if np.all(~planes[:, 1]) else 2
            raise IdentifiabilityError(
                f"all runs ({', '.join(labels)}) place imbalance in plane {p} only; one imbalance plane cannot "
                "give linearly independent excitations (report section 4): use masses in both planes")
        ref = U[0]
        j = int(np.argmax(np.abs(ref)))
        pairs = []
        for i in range(1, len(U)):
            ratio = U[i, j] / ref[j]
            pairs.append(f"{labels[i]} = {abs(ratio):.4g}·exp(j{np.angle(ratio, deg=True):.1f}°) × {labels[0]}")
        raise IdentifiabilityError(
            "the imbalance sets are complex multiples of one another, so the responses are linearly dependent "
            f"(report eq. 11-13): {'; '.join(pairs)}")


def _diagnose_singular(qs, labels):
    """Explain why the response matrices are singular at every point."""
    dead = [lab for lab, q in zip(labels, qs) if not np.any(q)]
    if dead:
        return (f"{', '.join(dead)} show zero response at every point (a dead channel, an empty or unplugged "
                "recording, or a wrong channel map): nothing to identify from")
    x = qs[..., [0, 1]]
    y = qs[..., [2, 3]]
    circ = np.abs(y + 1j * x) / np.maximum(np.abs(x) + np.abs(y), 1e-300)  # 0 for forward circular orbits
    if np.nanmax(circ) < 1e-6:
        return ("every response is a forward circular orbit (y = -j·x): the bearings are isotropic, and x and y "
                "coefficients cannot be separated from imbalance responses (report section 4). Runs: "
                + ", ".join(labels))
    return ("the response matrices of runs " + ", ".join(labels) + " are singular at every point: the runs are "
            "linearly dependent (one is a complex multiple of another, or the data repeat a run)")


#: the values of ``method`` and ``estimator``
_METHODS = frozenset(("forces", "report"))
_ESTIMATORS = frozenset(("ls", "bias-corrected"))

#: flag bit "singular" (the core's identify::FLAG_SINGULAR); bit i is reason i of _BASE_REASONS
_SINGULAR = 1
_BASE_REASONS = ("singular", "ill-conditioned", "uncertain", "low amplitude", "negative direct damping")


def _flag_strings(code, reasons):
    """Flag codes (bit i = reasons[i]) as strings: reasons joined by "; ", "singular" alone."""
    out = np.full(code.shape, "", dtype=object)
    for c in np.unique(code[code != 0]):
        c = int(c)
        names = ["singular"] if c & _SINGULAR else [why for i, why in enumerate(reasons) if c >> i & 1]
        out[code == c] = "; ".join(names)
    return out


#: the flag of a point whose direct damping is significantly negative (the core's
#: identify::FLAG_NEGATIVE_DAMPING): a passive support dissipates, and a channel reversed in every
#: run leaves no residual but this (an independent lab's reversed x1 gave Cxx1 = -2560 and Cxx2 =
#: -12900 N·s/m, every point ok, K off by 136-440 %)
NEGATIVE_DAMPING = "negative direct damping"
IDENTICAL_REJECTED = "identical bearings rejected by the data"


def _finish(axis_name, axis, amp, k, c, cond, resid, ks, cs, cond_max, min_rel_amplitude, method, labels,
            std_source="none", dof=None, cov=None, max_rel_std=MAX_REL_STD, extra_flags=None, ks_res=None, cs_res=None,
            bias_k=None, bias_c=None, estimator="ls", rel_std=None, std_known=True, flags=None, flag_dof=None):
    """Result object with per-point flags. ``amp``: rms response amplitude over runs and coordinates;
    ``rel_std``: the relative standard error of ``ks``, ``cs`` when the core computed it;
    ``std_known=False``: there are no standard errors (no point can be "uncertain");
    ``flags``: (code, amp / max amp, code == 0) when the core computed them with the identification;
    ``flag_dof``: the dof of each damping's standard error (n, 2, 2, 2) for the negative-damping
    test when they differ from the point's ``dof``."""
    if rel_std is None:
        rel_std = _core.relative_std(*(np.ascontiguousarray(a, dtype=float).reshape(-1, 8) for a in (k, c, ks, cs)))
    if flags is not None:
        code, rel, ok = flags
    else:
        # bit i of the code is reason i of _BASE_REASONS, set in one pass by the core, with
        # ok = code == 0 (no (n,) pass and temporary here: 0.3-1.7 ms at a million points)
        code, rel, ok = _core.flag_codes(np.ascontiguousarray(cond), np.ascontiguousarray(amp),
                                         np.ascontiguousarray(rel_std, dtype=float) if std_known else None,
                                         float(cond_max), float(min_rel_amplitude), float(max_rel_std),
                                         np.ascontiguousarray(c, dtype=float),
                                         np.ascontiguousarray(cs, dtype=float) if std_known else None,
                                         _flag_dof(dof if flag_dof is None else flag_dof))
    reasons = list(_BASE_REASONS)
    if extra_flags is not None:
        try:
            extra = [(np.asarray(m, dtype=bool), str(why)) for m, why in extra_flags if isinstance(why, str)]
        except (TypeError, ValueError):
            raise RotoridError("extra_flags must be a list of (mask over the points, reason) pairs") from None
        if len(extra) != len(list(extra_flags)) or any(m.shape != (axis.size,) for m, _ in extra):
            raise RotoridError(f"extra_flags must be a list of (mask of {axis.size} points, reason) pairs")
        if len(reasons) + len(extra) > 16:
            raise RotoridError(f"extra_flags: at most {16 - len(_BASE_REASONS)} extra reasons")
        code = code.astype(np.uint16)
        for mask, why in extra:
            code |= mask.astype(np.uint16) << len(reasons)
            reasons.append(why)
        ok = code == 0
    return Identification(axis_name, axis, k, c, cond, resid, rel, ks, cs, ok, code, method, labels, std_source, dof,
                          cov, rel_std, ks_res, cs_res, bias_k, bias_c, estimator, tuple(reasons))


def _flag_dof(dof):
    """The degrees of freedom of the standard errors as the core's negative-damping test takes
    them: None (+inf), one value (a constant view: no (n,) copy), one per point, or one per
    coefficient (n, 2, 2, 2)."""
    if dof is None:
        return None
    dof = np.asarray(dof, dtype=float)
    if dof.ndim == 1 and dof.size and dof.strides == (0,):
        return np.array(dof[:1])
    return np.ascontiguousarray(dof)


#: the fewest points for which an API call wakes the core's threads before its own checks (the
#: core splits identifications into tasks of 1,024 points; below a few tasks the caller works alone)
WAKE_FROM = 4096


def _wake_core_threads(resp):
    """Wake the core's thread pool while the API checks its inputs (~50 µs), so that its threads
    are running when the core call begins rather than being woken by it: at 10,000 impact
    frequencies a woken-late helper added ~50 µs to the 0.2 ms call. A no-op when the helpers
    are still spinning after an earlier call (``ROTORID_SPIN_US``, README). ``resp``: the first
    run or test, for its number of points."""
    q = getattr(resp, "q", None)
    if getattr(q, "shape", (0,))[0] >= WAKE_FROM:
        _core.wake_pool()


def _check_bool(name, value):
    if not isinstance(value, (bool, np.bool_)):
        raise RotoridError(f"{name} must be True or False, got {value!r}")
    return bool(value)


def _check_threshold(name, value, lo, hi=np.inf):
    if type(value) is float and lo < value < hi:  # the common case (a default): no further checks
        return value
    from ._validate import number

    if hi == np.inf and isinstance(value, (float, np.floating)) and value == np.inf:  # no threshold
        return np.inf
    v = number(name, value)
    if not (lo < v < hi) and not (hi == np.inf and v == np.inf):
        raise RotoridError(f"{name} must be a number above {lo:g}{'' if hi == np.inf else f' and below {hi:g}'}, got "
                           f"{value!r}")
    return v


def _flag_list(extra_flags) -> list:
    """``extra_flags`` as a list of pairs (checked in full where the points are known, in
    ``_finish``); None is an empty list."""
    if extra_flags is None:
        return []
    if isinstance(extra_flags, (str, bytes, dict)) or not isinstance(extra_flags, (list, tuple)):
        raise RotoridError(f"extra_flags must be a list of (mask over the points, reason) pairs, got "
                           f"{type(extra_flags).__name__}")
    return list(extra_flags)


#: the farthest (relative) a run's speed may lie from the mean speed of the runs at a point
MAX_SPEED_OFFSET = 0.005
#: the largest max_speed_offset a user may set
MAX_SPEED_OFFSET_LIMIT = 0.05


def _same_speeds(runs):
    """Every run at the first run's speeds (:func:`_on_axis`)."""
    return all(_on_axis(r.speed_rpm, runs[0].speed_rpm) for r in runs[1:])


def _with_flag(ident: Identification, mask, reason: str) -> Identification:
    """``ident`` with the points of ``mask`` flagged for ``reason`` (one more bit of its codes)."""
    import dataclasses

    mask = np.asarray(mask, dtype=bool)
    if not mask.any():
        return ident
    reasons = tuple(ident.flag_reasons)
    if reason in reasons:
        bit = reasons.index(reason)
    else:
        if len(reasons) >= 16:
            raise RotoridError("at most 16 flag reasons")
        bit, reasons = len(reasons), reasons + (reason,)
    code = np.asarray(ident.flag_code).astype(np.uint16) | (mask.astype(np.uint16) << bit)
    return dataclasses.replace(ident, flag_code=code, ok=code == 0, flag_reasons=reasons)


def _identify_at_offsets(rotor, runs, labels, max_offset, shared_cov, accel_gain_std, accel_phase_std_deg, kw):
    """:func:`identify_synchronous` of runs whose speeds differ a little: at the mean speed of
    each point, every run carried there (:func:`rotorid.speed_offsets.carry_to_grid`)."""
    from ._validate import number
    from .speed_offsets import Dwells, carry_to_grid

    max_offset = number("max_speed_offset", max_offset, nonneg=True)
    if not max_offset <= MAX_SPEED_OFFSET_LIMIT:
        raise RotoridError(f"max_speed_offset must be at most {MAX_SPEED_OFFSET_LIMIT * 100:g} % (runs farther apart are "
                           f"at different dwells, not one), got {max_offset!r}")
    ref = runs[0].speed_rpm
    for lab, r in zip(labels, runs):
        if r.speed_rpm.shape != ref.shape:
            raise RotoridError(f"speed_rpm of {lab} has {r.speed_rpm.size} speeds, {labels[0]} {ref.size}: all runs "
                               "must be given at the same speeds (one vector per run at each point)")
    speeds = np.stack([r.speed_rpm for r in runs])
    grid = speeds.mean(axis=0)
    off = np.abs(speeds / grid - 1.0)
    if not (off.max() <= max_offset):
        i, j = np.unravel_index(np.argmax(off), off.shape)
        # named as a pair: the run farthest from the mean and the one farthest from it
        a, b = sorted((i, int(np.argmax(np.abs(speeds[:, j] - speeds[i, j])))))
        raise RotoridError(f"speed_rpm of {labels[b]} differs from that of {labels[a]}: {speeds[b, j]:.2f} against "
                           f"{speeds[a, j]:.2f} rpm, {off[i, j] * 100:.2f} % from the runs' mean speed there (beyond "
                           f"max_speed_offset = {max_offset * 100:g} %); give the runs at the same speeds")
    if any(r.pedestal is not None for r in runs):
        raise RotoridError("runs with pedestal motion must be given at the same speeds (the carry of runs taken at "
                           "slightly different speeds needs the rotor on rigid supports)")
    if shared_cov is not None:
        raise RotoridError("shared_cov is given but the runs' speeds differ: a baseline subtracted at other speeds "
                           "cannot be carried; give the runs at the same speeds (rotorid.pipeline.imbalance_chain "
                           "carries runs and baseline separately)")
    at = runs[0].at if all(r.at == runs[0].at for r in runs) else "bearings"
    moved = [r._moved(rotor, at) for r in runs]
    dwells = [Dwells(r.speed_rpm, r.q, r.cov, r.dof) for r in moved]

    def identify(qs, covs, shared):
        rs = [SyncResponse(grid, q, r.imbalance, at, r.name, None if covs is None else covs[i], r.dof)
              for i, (q, r) in enumerate(zip(qs, moved))]
        return identify_synchronous(rotor, rs, accel_gain_std=accel_gain_std,
                                    accel_phase_std_deg=accel_phase_std_deg, **kw)

    done = carry_to_grid(rotor, grid, dwells, identify, at=at)
    return _with_flag(done.identification, done.unresolved, SPEED_OFFSETS_UNRESOLVED)


def identify_synchronous(rotor: RigidRotor, runs, *, method: str = "forces", identical: bool = False,
                         cond_max: float = COND_MAX, min_rel_amplitude: float = MIN_REL_AMPLITUDE,
                         max_rel_std: float = MAX_REL_STD, estimator: str = "ls",
                         shared_cov=None, accel_gain_std: float = 0.0,
                         accel_phase_std_deg: float = 0.0, keyphasor_angle_std_deg=0.0,
                         keyphasor_delay_std_s: float = 0.0, max_speed_offset: float = MAX_SPEED_OFFSET) -> Identification:
    """Synchronous K and C of both bearings at every speed from two or more imbalance runs.

    ``runs``: list (or dict name -> run) of SyncResponse, each with its added ``imbalance`` and the
    same number of speeds; responses at the probes are moved to the bearings with eq. 19. Two runs
    solve eq. 11 exactly; more runs are solved in the least-squares sense.

    Runs whose speeds differ point by point (dwells that a speed control held at "3000 rpm" to
    within a few rpm) are identified at the mean of their speeds, each run's vectors carried there
    through the rotor on the bearings being identified (:mod:`rotorid.speed_offsets`; identified
    as if at one speed, runs ±0.1 % apart put the example rig's direct damping up to 8 % off).
    ``max_speed_offset`` (relative, default 0.5 %, at most 5 %) is the farthest a run's speed may
    lie from that mean; beyond it the call is refused as runs at different speeds. (The carry's
    own uncertainty, from the coefficients it uses, is not in the error bars: at ±0.25 % coverage
    is as at one speed, at ±1 % 0.92-0.94 against 0.95.) Far below the critical speeds, where the
    identification is ill-conditioned, the carry may not settle: those points are carried by
    (W / W_r)² alone and flagged. Points where the carry
    did not settle are flagged "speed offsets not resolved". Not with pedestal motion or
    ``shared_cov`` (the runs must then share their speeds).

    ``method``: "forces" (default; bearing reaction forces from the rotor equations, then a 2-unknown
    complex least-squares problem per bearing and direction) or "report" (the report's 16 real
    unknowns, eq. 8-18, solved by QR). Both give the same answer for two runs; for redundant runs
    "forces" weights every equation in newtons, "report" mixes force and moment rows.
    ``identical=True`` assumes the same coefficients at both bearings (8 unknowns; one run suffices).

    Uncertainty: when every run carries a measurement covariance (``SyncResponse.cov``, e.g. from
    order tracking), it is propagated through the estimator (``std_source`` "measurement
    covariance", also with two runs); otherwise redundant runs give residual-based standard errors
    ("residual"). A point whose largest standard error exceeds ``max_rel_std`` times its
    bearing's direct coefficients is flagged "uncertain"; a point over ``cond_max`` "ill-conditioned",
    below ``min_rel_amplitude`` "low amplitude".

    ``shared_cov`` (n, 8, 8), optional: a covariance shared by every pair of runs, where the runs
    (at the same place as ``q``) had the same baseline run subtracted: its error is common to all
    of them, which propagation must not treat as independent. With pedestal motion it is
    (n, 16, 16), over [Re q, Im q, Re p, Im p]. It adds to each run's own covariance (``cov``),
    which every run must then carry (a RotoridError says so otherwise).

    ``accel_gain_std`` (relative, e.g. 0.02) and ``accel_phase_std_deg``: the calibration
    uncertainty of each housing accelerometer's sensitivity and phase, independent between the
    four accelerometers and common to every run and speed (a systematic error that no averaging
    removes). With pedestal motion it is added to the coefficients' covariance: each gain or phase
    moves every run's pedestal channel (and, through eq. 19, the relative motion of runs measured
    at the probes) along one direction d, and Σ σ² (J d)(J d)ᵀ is added, with the Jacobian J of
    the measurement propagation (one core call; without measurement covariances J is formed for
    it alone). The pedestal-compensated coefficients depend strongly on it (docs/pedestals.md).

    ``keyphasor_angle_std_deg`` (a number, or one per speed) and ``keyphasor_delay_std_s``: the
    uncertainty of the phase reference, a phase error common to every run and channel at a speed,
    alpha(Omega) = theta + Omega tau (the keyphasor's mark angle known to within theta, its trigger
    timing or the probe channels' delays to within tau). It leaves no residual, so nothing else in
    the data reveals it, and damping is very sensitive to it: on the NSF rig a delay of 2.3 µs
    moves Cxx1 by 7.7 % at 6,000 rpm. The identification is repeated with every run's vectors
    (and pedestal motion) turned by e^{±j epsilon}; the central difference g = d(K, C)/d alpha
    adds sigma_alpha² g gᵀ to the covariance and the standard errors (``std_source`` then ends in
    "+ phase reference"). The imbalance chain sets the delay from the keyphasor's timing when
    the pulse shape makes it ambiguous (``Keyphasor.timing_std_s``).

    ``estimator``: "ls" (least squares, as the report) or "bias-corrected": least squares less its
    second-order errors-in-variables bias, estimated from the measurement covariance (sigma points
    through the estimator; see :mod:`rotorid.uncertainty`). It removes the attenuation bias that
    noisy responses cause at poorly conditioned speeds, at a small cost in variance.
    """
    if not isinstance(rotor, RigidRotor):
        raise RotoridError(f"rotor must be a rotorid.RigidRotor, got {type(rotor).__name__}")
    choice("method", method, _METHODS)
    _check_bool("identical", identical)
    runs = _as_runs(runs)
    labels = []
    for i, r in enumerate(runs):
        if not isinstance(r, SyncResponse):
            raise RotoridError(f"run {i} must be a rotorid.SyncResponse, got {type(r).__name__}")
        if r.imbalance is None:
            raise RotoridError(f"{_run_label(i, r)} has no imbalance: the identification needs the added imbalance of "
                               "every run (SyncResponse(imbalance=rotorid.Imbalance(...)))")
        labels.append(_run_label(i, r))
    if runs:
        _wake_core_threads(runs[0])
    check_imbalance_independence(rotor, [r.imbalance for r in runs], labels, identical=identical)
    rpm = runs[0].speed_rpm
    if not _same_speeds(runs):
        kw = dict(method=method, identical=identical, cond_max=cond_max, min_rel_amplitude=min_rel_amplitude,
                  max_rel_std=max_rel_std, estimator=estimator, keyphasor_angle_std_deg=keyphasor_angle_std_deg,
                  keyphasor_delay_std_s=keyphasor_delay_std_s)
        return _identify_at_offsets(rotor, runs, labels, max_speed_offset, shared_cov, accel_gain_std,
                                    accel_phase_std_deg, kw)
    phase_std = _phase_reference_std(rpm, keyphasor_angle_std_deg, keyphasor_delay_std_s)
    e = np.array([r.imbalance._generalized(rotor) for r in runs])  # (R, 4), scaled by Omega^2 below
    if _has_pedestal(runs, labels):
        qs, qps, covs, dofs, flags = _pedestal_inputs(rotor, runs, labels, "speed_rpm", rpm)
        cal = _calibration_inputs(rotor, runs, accel_gain_std, accel_phase_std_deg)
        om = rpm * RPM
        return _solve(rotor, "speed_rpm", rpm, om, om, qs, e, None, None, identical=identical, method=method,
                      labels=labels, cond_max=cond_max, min_rel_amplitude=min_rel_amplitude, what="responses",
                      covs=covs, dofs=dofs, max_rel_std=max_rel_std, estimator=estimator, extra_flags=flags,
                      q_ped=qps, shared_cov=_shared(rotor, runs, shared_cov, size=16), calibration=cal,
                      phase_std=phase_std, noise_planes=_noise_planes(rotor, runs) if identical else None)
    _no_calibration(accel_gain_std, accel_phase_std_deg)
    at_b, planes = _for_the_core(rotor, runs, may_use_planes=shared_cov is None)
    qs = [np.ascontiguousarray(r.q, dtype=complex) for r in at_b]  # the runs as they are: no copy, no stack
    covs = _run_covs(at_b, labels)
    # the core forms Omega = RPM * rpm (w_scale), takes it as the spin speed too (spin None) and
    # forms Omega^2 (gain None): no (n,) temporaries (two of them freed together made glibc return
    # and fault in megabytes on every call; Omega alone takes 18-23 µs at 100,000 speeds, and up to
    # 185 µs inside real calls, right after the core's threads have used the caches)
    return _solve(rotor, "speed_rpm", rpm, rpm, None, qs, e, None, None, identical=identical, method=method,
                  labels=labels, cond_max=cond_max, min_rel_amplitude=min_rel_amplitude, what="responses",
                  covs=covs, dofs=None if covs is None else _run_dofs(at_b), max_rel_std=max_rel_std,
                  estimator=estimator, shared_cov=_shared(rotor, runs, shared_cov), planes=planes, w_scale=RPM,
                  phase_std=phase_std, noise_planes=_noise_planes(rotor, runs) if identical else None)


def _phase_std_deg_per_speed(name, value, n):
    """``value`` checked as a phase uncertainty in degrees: a number or one per speed (``n``), not
    negative, below 45 degrees (a phase that uncertain identifies nothing)."""
    theta = real_array(name, value, nonneg=True)
    if theta.ndim > 1 or theta.size not in (1, n):
        raise RotoridError(f"{name} must be a number or one per speed ({n}), got shape {theta.shape}")
    if np.any(theta >= 45.0):
        raise RotoridError(f"{name} must be below 45 degrees, got {float(np.max(theta)):g}")
    return theta


def _phase_reference_std(rpm, angle_std_deg, delay_std_s):
    """(n,) standard uncertainty of the phase reference at each speed (rad), sqrt(theta² + (Omega
    tau)²), or None when both are zero (the defaults: no pass over the speeds)."""
    if type(delay_std_s) is float and delay_std_s == 0.0 and type(angle_std_deg) is float and angle_std_deg == 0.0:
        return None
    from ._validate import number

    tau = number("keyphasor_delay_std_s", delay_std_s, nonneg=True)
    theta = _phase_std_deg_per_speed("keyphasor_angle_std_deg", angle_std_deg, rpm.size)
    if tau * float(np.max(rpm)) * RPM >= np.pi / 4:
        raise RotoridError(f"keyphasor_delay_std_s = {tau:g} s is 45 degrees or more of a revolution at "
                           f"{float(np.max(rpm)):g} rpm: a phase reference that uncertain identifies nothing (a unit "
                           "error? the delay is in seconds)")
    std = np.hypot(np.deg2rad(theta), tau * rpm * RPM)
    return std if np.any(std > 0) else None


def _phase_sigma_points(rotor, w, spin, qs, e_core, gain, sigma, phase_std, *, identical, method, q_ped, planes,
                        w_scale):
    """The identification with every run's vectors (and pedestal motion, which shares the
    keyphasor) turned by e^{+j s} and e^{-j s}, s the phase reference's standard uncertainty at
    each point (sigma points: exact for the linear part, and the second difference captures the
    curvature where a coefficient hardly moves to first order). Returns ((k+, c+), (k-, c-)),
    (n, 2, 2, 2) each."""
    out = []
    for sign in (1.0, -1.0):
        turn = np.exp(1j * sign * phase_std)[:, None]
        k, c, *_ = _core.identify(rotor.core_params(), np.ascontiguousarray(w), spin, [q * turn for q in qs], e_core,
                                  gain, identical=identical, method=method, with_std=False, sigma=sigma,
                                  q_ped=None if q_ped is None else [p * turn for p in q_ped], planes=planes,
                                  w_scale=w_scale, flag_limits=None)
        out.append((k[0], c[0]))
    return out


#: pedestal motion above this multiple of the relative motion: a point is flagged (and warned about)
PEDESTAL_RATIO_MAX = 1.0


def _has_pedestal(runs, labels):
    """True when every run carries pedestal motion, False when none does; a mix is an error."""
    for r in runs:
        if r.pedestal is not None:
            break
    else:
        return False  # the common case, without the lists below
    have = [r.pedestal is not None for r in runs]
    if not all(have):
        without = [lab for lab, h in zip(labels, have) if not h]
        raise RotoridError(f"{', '.join(without)} carry no pedestal motion while the other runs do: identify with "
                           "pedestal motion on every run (accelerometer channels px1, py1, px2, py2) or on none")
    return all(have)


def _pedestal_frame(rotor, run, label="", *, finite=True, blocks=False):
    """(q_rel, p, joint_cov) of a run at the bearings: relative motion, pedestal motion, and the
    (n, 16, 16) covariance of [Re q_rel, Im q_rel, Re p, Im p] (None without covariances), or with
    ``blocks`` its blocks (cov, pedestal_cov, pedestal_cross or None), (n, 8, 8) each, as the core's
    pedestal fit takes them. ``finite=False`` leaves NaN and inf in the pedestal motion of a run at
    the bearings to the caller (a run at the probes is moved with its pedestal motion, which is
    checked first)."""
    from .simulate import joint_cov

    from .simulate import _check_pedestal

    if run.pedestal is None:
        raise RotoridError(f"{label or 'the run'} carries no pedestal motion")
    try:
        # checked again: fields set after construction skip __post_init__ (the eq. 19 move of a
        # run at the probes checks them, and q, itself)
        if run.at == "bearings":
            _check_pedestal(run, run.q.shape[0], finite=finite)
        rb = run.at_bearings(rotor)
    except RotoridError as exc:
        raise RotoridError(f"{label or 'the run'}: {exc}") from None
    q = rb.frf() if hasattr(rb, "frf") else rb.q
    if not blocks:
        jc = joint_cov(rb)
    elif rb.pedestal is None or rb.cov is None or rb.pedestal_cov is None:
        jc = None
    else:
        jc = tuple(None if c is None else np.ascontiguousarray(c, dtype=float)
                   for c in (rb.cov, rb.pedestal_cov, rb.pedestal_cross))
    if (run.cov is None) != (run.pedestal_cov is None):
        import warnings

        warnings.warn(f"{label}: only one of cov (probes) and pedestal_cov (accelerometers) is given; the "
                      "uncertainty needs both and falls back to the residual of redundant runs (or is unknown)")
    return np.ascontiguousarray(q, dtype=complex), np.ascontiguousarray(rb.pedestal, dtype=complex), jc


def _pedestal_inputs(rotor, runs, labels, axis_name, axis):
    """Relative and pedestal motion at the bearings, the runs' covariances (a list of (cov,
    pedestal_cov, cross or None) blocks, or None) and dofs, and the flag of points where the
    pedestal moves more than the journal in its housing (with a warning)."""
    import warnings

    # the covariances as each run's (cov, pedestal_cov, cross) blocks, as the core's propagation
    # takes them (stacking (n, 16, 16) joint matrices took a third of a 10,000-speed call)
    frames = [_pedestal_frame(rotor, r, lab, blocks=True) for r, lab in zip(runs, labels)]
    qs = [f[0] for f in frames]
    qps = [f[1] for f in frames]
    jcs = [f[2] for f in frames]
    covs = jcs if all(c is not None for c in jcs) else None
    if covs is None and any(c is not None for c in jcs):
        warnings.warn(f"only {sum(c is not None for c in jcs)} of {len(jcs)} runs carry measurement covariances (cov "
                      "and pedestal_cov): the uncertainty falls back to the residual of redundant runs")
    dofs = _run_dofs(runs) if covs is not None else None
    from .simulate import pedestal_ratio

    ratio = np.stack([pedestal_ratio(p, q) for q, p in zip(qs, qps)])
    worst = np.nanmax(np.where(np.isfinite(ratio), ratio, np.nan), axis=0) if np.isfinite(ratio).any() else \
        np.zeros(axis.size)
    big = worst > PEDESTAL_RATIO_MAX
    flags = []
    if big.any():
        j = int(np.nanargmax(worst))
        r = int(np.nanargmax(ratio[:, j]))
        unit = "rpm" if axis_name == "speed_rpm" else "Hz"
        warnings.warn(f"pedestal motion is up to {worst[j]:.3g} times the motion relative to the pedestals ({labels[r]} "
                      f"at {axis[j]:g} {unit}; {int(big.sum())} of {axis.size} points above 1): there the bearing "
                      "forces hang on small differences and the identification is poorly conditioned; those points "
                      "are flagged 'pedestal motion dominates'")
        flags.append((big, "pedestal motion dominates"))
    return qs, qps, covs, dofs, flags


#: relative step of the calibration derivatives (the estimate is smooth in the gains and phases)
_CAL_STEP = 1e-4


def _calibration_std(accel_gain_std, accel_phase_std_deg):
    from ._validate import number

    g = number("accel_gain_std", accel_gain_std, nonneg=True)
    ph = number("accel_phase_std_deg", accel_phase_std_deg, nonneg=True)
    if g >= 0.5:
        raise RotoridError(f"accel_gain_std is relative (0.02 = 2 %), got {g:g}: an accelerometer known to within "
                           "50 % or worse cannot compensate pedestal motion")
    if ph >= 45.0:
        raise RotoridError(f"accel_phase_std_deg must be below 45 degrees, got {ph:g}")
    return g, np.deg2rad(ph)


def _no_calibration(accel_gain_std, accel_phase_std_deg):
    """Accelerometer calibration without pedestal motion is an error (it would be silently unused)."""
    if type(accel_gain_std) is float and type(accel_phase_std_deg) is float and \
            accel_gain_std == 0.0 and accel_phase_std_deg == 0.0:
        return  # the defaults: nothing to check
    g, ph = _calibration_std(accel_gain_std, accel_phase_std_deg)
    if g or ph:
        raise RotoridError("accel_gain_std / accel_phase_std_deg are the accelerometers' calibration uncertainty, but "
                           "the runs carry no pedestal motion (no accelerometer data)")


def _calibration_inputs(rotor, runs, accel_gain_std, accel_phase_std_deg):
    """The accelerometers' calibration uncertainty as the core's propagation takes it: (gain std,
    phase std in radians, probe maps (R, 4, 4)), or None when both are zero. A run's map B moves
    its measured pedestal motion into the relative motion at the bearings (q = A q_probes + B p
    for a run at the probes, the probes riding on the pedestals; zeros for a run at the bearings):
    a calibration error of accelerometer j moves both p_j and, through B[:, j], q."""
    g, ph = _calibration_std(accel_gain_std, accel_phase_std_deg)
    if not (g or ph):
        return None
    return g, ph, _probe_maps(rotor, runs)


def _probe_maps(rotor, runs):
    """(R, 4, 4): each run's map B from its measured pedestal motion to its relative motion at
    the bearings (q = A q_probes + B p for a run at the probes; zeros for a run at the bearings)."""
    from .simulate import _pedestal_transform, _plane_matrix4

    maps = np.zeros((len(runs), 4, 4))
    for i, r in enumerate(runs):
        if r.at == "probes":
            maps[i] = _plane_matrix4(_pedestal_transform(_plane_matrix(rotor, "bearings"))[1])
    return maps


def _calibration_factors(gain_std, phase_std_rad):
    """For each of gain and phase with a nonzero uncertainty and each accelerometer j (xp1, xp2,
    yp1, yp2): (std, j, (f+, f-)), the factors 1 ± _CAL_STEP or e^{± i _CAL_STEP} its channel is
    stepped by for central differences."""
    for std, kind in ((gain_std, "gain"), (phase_std_rad, "phase")):
        if not std:
            continue
        for j in range(4):
            yield std, j, tuple(1.0 + sign * _CAL_STEP if kind == "gain" else np.exp(1j * sign * _CAL_STEP)
                                for sign in (1.0, -1.0))


def calibration_steps(qs, ps, maps, gain_std, phase_std_rad):
    """:func:`calibration_perturbations` of the runs' motions at the bearings: for each
    accelerometer j and each of gain and phase with a nonzero uncertainty, (std, (qs, ps) with
    accelerometer j's gain or phase stepped by +_CAL_STEP, the same by -_CAL_STEP). ``qs``,
    ``ps``: the runs' relative and pedestal motion at the bearings (n, 4) each; ``maps``:
    :func:`_probe_maps`. The pedestal channel j scales by the factor f, and a run's relative
    motion moves by (f - 1) p_j B[:, j], as moving the stepped run from the probes would move it
    (nothing is constructed, moved or checked again)."""
    def stepped(j, f):
        q2, p2 = [], []
        for q, p, b in zip(qs, ps, maps):
            pj = p.copy()
            pj[:, j] = f * p[:, j]
            p2.append(pj)
            q2.append(q + ((f - 1.0) * p[:, j])[:, None] * b[:, j][None, :] if b[:, j].any() else q)
        return q2, p2

    for std, j, (fp, fm) in _calibration_factors(gain_std, phase_std_rad):
        yield std, stepped(j, fp), stepped(j, fm)


def calibration_perturbations(runs, gain_std, phase_std_rad):
    """For each accelerometer j (xp1, xp2, yp1, yp2) and each of gain and phase with a nonzero
    uncertainty: (std, runs with accelerometer j's gain or phase stepped by +_CAL_STEP, the same
    by -_CAL_STEP) — the central differences of any estimate with respect to the calibration."""
    import dataclasses

    def stepped(j, f):
        fac = np.ones(4, complex)
        fac[j] = f
        return [dataclasses.replace(r, pedestal=r.pedestal * fac[None, :]) for r in runs]

    for std, j, (fp, fm) in _calibration_factors(gain_std, phase_std_rad):
        yield std, stepped(j, fp), stepped(j, fm)


def _on_axis(a, ref):
    """``a`` is the axis ``ref``: equal arrays pass at once (the common case, a pass over the
    data), otherwise within 1e-9 relative (rounding of a stored axis)."""
    return a is ref or np.array_equal(a, ref) or (a.shape == ref.shape and np.allclose(a, ref, rtol=1e-9, atol=0))


def _check_same_axis(name, axes, labels, what, unit, advice):
    """Every run on the first run's axis (:func:`_on_axis`)."""
    ref = axes[0]
    for i, a in enumerate(axes[1:], 1):
        if not _on_axis(a, ref):
            raise RotoridError(f"{name} of {labels[i]} differs from that of {labels[0]}: all {what} must be given at "
                               f"the same {unit} ({advice})")


#: a shared covariance is the part of the runs' errors they have in common: without each run's own
#: covariance it would be ignored (the standard errors come from the residual then)
_SHARED_WITHOUT_COV = ("shared_cov is given but not every run carries its own measurement covariance (cov=, and "
                       "pedestal_cov= with pedestal motion): the shared part alone does not give the runs' errors. "
                       "Give each run its cov (zeros where its own errors are nil) or drop shared_cov")


def _shared(rotor, runs, shared_cov, size: int = 8):
    """The shared covariance at the bearings (checked), or None. With pedestal motion (``size``
    16) it is the joint covariance of [Re q, Im q, Re p, Im p] common to the runs."""
    from .simulate import _cov_transform, _joint_moved, check_cov

    if shared_cov is None:
        return None
    c = check_cov("shared_cov", shared_cov, runs[0].q.shape[0], size)
    if any(r.at != runs[0].at for r in runs):
        raise RotoridError("shared_cov needs all runs measured at the same place (probes or bearings)")
    if runs[0].at != "probes":
        return c
    return _joint_moved(rotor, c, "bearings") if size == 16 else _cov_transform(_plane_matrix(rotor, "bearings"), c)


def _run_covs(runs, labels=None):
    """The runs' covariances, checked again (``run.cov = ...`` after construction skips the check);
    None unless every run has one (a warning says so when only some do)."""
    for r in runs:
        if r.cov is not None:
            break
    else:
        return None  # no run carries one: the common case, without the lists below
    n = runs[0].q.shape[0]
    have = [r.cov is not None for r in runs]
    if not all(have):
        if any(have):
            import warnings

            warnings.warn(f"only {sum(have)} of {len(runs)} runs/tests carry a measurement covariance: the standard "
                          "errors fall back to the residual of redundant runs (or are unknown)")
        return None
    from .simulate import check_covs

    labels = labels or [f"run {i}" for i in range(len(runs))]
    return check_covs([f"cov of {lab}" for lab in labels], [r.cov for r in runs], n)


def _run_dofs(runs):
    from .simulate import check_dof

    n = runs[0].q.shape[0]
    return np.stack([check_dof("dof", r.dof, n, copy=False) if r.dof is not None else np.full(n, np.inf)
                     for r in runs])


def _bij_from_report(x):
    """(n, 8) in eq. 9 order (Kxx1, Kxx2, Kxy1, Kxy2, ...: column 2 a + bearing) -> (n, 2, 2, 2) =
    [point, bearing, i, j] (flat index 4 bearing + a): the inverse of ``_REPORT_TO_BIJ`` as a
    transpose, copied by NumPy's strided loop (a fancy-indexed gather is 3-4x slower)."""
    n = x.shape[0]
    return np.ascontiguousarray(x.reshape(n, 4, 2).transpose(0, 2, 1)).reshape(n, 2, 2, 2)


#: the impacts' excitation gain, 1 at every frequency (broadcast by the core; read-only, shared)
_UNIT_GAIN = np.ones(1)
_UNIT_GAIN.flags.writeable = False


def _constant_view(value, shape):
    """A read-only float array of ``value`` of any shape on 8 bytes: ``np.broadcast_to(value,
    shape)`` without its argument handling (3 µs warm, ~30 µs inside real calls, right after the
    core's threads had used the caches)."""
    return np.ndarray(shape, float, buffer=np.float64(value).tobytes(), strides=(0,) * len(shape))


@functools.lru_cache(maxsize=32)
def _unknown_std_bases(n):
    return _constant_view(np.nan, (n, 2, 2, 2)), _constant_view(np.nan, (n,))


def _unknown_std(n):
    """(k_std = c_std (n, 2, 2, 2), rel_std (n,)) of n points whose standard errors are unknown:
    :func:`_constant_view` of NaN, fresh views (their own shape attributes) of read-only arrays
    made once per n, in one cached call (two lookups and batch-axis views took ~1 µs of a call);
    ``c_std`` is another view of the first."""
    coef, rel = _unknown_std_bases(n)
    return coef.view(), rel.view()


#: redundant runs disagree when their residual-based standard errors exceed those propagated from
#: the measurement covariance by this factor (median over a point's coefficients): with the 2 (R - 2)
#: residual degrees of freedom of R runs per bearing system, a chance exceedance has probability
#: P(chi2_2 > 18) = 1.2e-4 at 3 runs and below 3e-7 at 4 or more (the same factor tests the
#: identical-bearing hypothesis)
RUNS_DISAGREE = 3.0


def _misfit_ratio(ks_res, cs_res, ks_meas, cs_meas, n):
    """(n,) median over each point's coefficients of the residual-based over the propagated standard
    errors (NaN where no ratio is known; an infinite ratio, a misfit where the covariance gives no
    error, counts as one)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.concatenate([(ks_res / ks_meas).reshape(n, -1), (cs_res / cs_meas).reshape(n, -1)], 1)
    out = np.full(n, np.nan)
    some = ~np.isnan(ratio).all(axis=1)
    out[some] = np.nanmedian(ratio[some], axis=1)
    return out


def _solve(rotor, axis_name, axis, w, spin, qs, e, gain, sigma, *, identical, method, labels, cond_max,
           min_rel_amplitude, what, covs=None, dofs=None, max_rel_std=MAX_REL_STD, extra_flags=None,
           estimator="ls", shared_cov=None, q_ped=None, calibration=None, planes=None, w_scale=None, e_core=None,
           phase_std=None, noise_planes=None):
    """One core call for the whole axis, uncertainty, then flags; shared by both methods.
    ``e``: the (R, 4) excitations; ``e_core``: the same as the core takes them
    (:func:`_core_excitations`) when the caller has them at hand, else None.
    ``gain`` None: spin^2 (an imbalance), formed by the core. ``planes``: the (2, 2) eq. 19
    transform when ``qs`` are at the probe planes (no covariances then), else None.
    ``w_scale``: ``w`` is given in the axis' unit and is w_scale times that in rad/s (formed by
    the core: no (n,) temporary). ``spin`` None: the spin speed is w (synchronous runs).
    ``calibration``: the accelerometers' calibration uncertainty (:func:`_calibration_inputs`),
    added by the core's propagation. ``phase_std``: (n,) uncertainty of the phase reference (rad,
    :func:`_phase_reference_std`) or None. ``noise_planes``: with identical bearings, the eq. 19
    transform from the probe planes when the runs were measured there (:func:`_noise_planes`)."""
    assert planes is None or (covs is None and calibration is None and q_ped is None)
    cond_max = _check_threshold("cond_max", cond_max, 1.0)
    min_rel_amplitude = _check_threshold("min_rel_amplitude", min_rel_amplitude, -1e-300, 1.0)
    max_rel_std = _check_threshold("max_rel_std", max_rel_std, 0.0)
    choice("estimator", estimator, _ESTIMATORS)
    if estimator == "bias-corrected" and covs is None:
        raise RotoridError("estimator='bias-corrected' needs the measurement covariance of every run or test (cov=)")
    if shared_cov is not None and covs is None:
        raise RotoridError(_SHARED_WITHOUT_COV)
    # standard errors need redundant equations: more rows than the 2 unknowns of each system
    nruns = len(qs)
    redundant = nruns * (2 if identical else 1) > 2
    # the flags come from the same call unless the standard errors change below (propagated
    # covariance, accelerometer calibration)
    e_core = _core_excitations(e) if e_core is None else e_core
    # residual dof per bearing system: R complex equations (2R real) for 2 complex unknowns
    residual_dof = 2.0 * (nruns * (2 if identical else 1) - 2)
    # identical bearings pool both bearings' equations, whose errors differ: their residual-based
    # errors come from identical_std below, and the flags with them (in _finish)
    structured = identical and redundant and method == "forces"
    w = np.ascontiguousarray(w)
    k, c, cond, resid, amp, ks, cs, rel_std, code, rel_amp, ok, nbad = _core.identify(
        rotor.core_params(), w, spin, list(qs), e_core,
        gain, identical=identical, method=method, with_std=redundant and not structured, sigma=sigma, q_ped=q_ped,
        planes=planes, w_scale=w_scale,
        flag_limits=None if covs is not None or calibration is not None or phase_std is not None or structured
        else (cond_max, min_rel_amplitude, max_rel_std, residual_dof if redundant else np.inf))
    k_ls, c_ls = k[0], c[0]  # the least-squares estimate (before any bias correction)
    if nbad:
        qs = np.stack(qs)
        if q_ped is not None and not np.isfinite(np.stack(q_ped)).all():
            raise RotoridError(f"the pedestal motion (accelerometers) of the {what} contains NaN or inf")
        big = float(np.nanmax(np.abs(qs))) if np.isfinite(qs).all() else None
        if big is not None:
            raise RotoridError(f"{what} reach {big:.3g} (m or m/N): the computation overflows; no rotor responds that "
                               "much (a unit error?)")
        raise RotoridError(f"{what} contain NaN or inf")
    row_dof = None
    if structured:
        # (n, 2): the x and the y row's dof (identify::identical)
        # the noise white where the runs were measured: at the probes also when they reach the core
        # moved to the bearings (a covariance, pedestal motion, or q not a complex128 array; a list
        # instead of an array gave standard errors 0.82-1.05 times as large)
        ks, cs, row_dof = _core.identical_std(rotor.core_params(), w, spin, list(qs), e_core, gain, k, c, sigma=sigma,
                                              q_ped=q_ped, planes=planes, w_scale=w_scale,
                                              noise_planes=noise_planes if planes is None else None)
        row_dof = row_dof[0]
    std_known = ks is not None or covs is not None  # residual-based, or propagated below
    # residual-based errors only where the core computed them (not for method="report", whose
    # standard errors stay unknown without a covariance)
    residual_std = redundant and ks is not None
    # no finite condition number: the first point nearly always has one (then no pass over cond)
    if not (math.isfinite(cond.item(0)) or np.fmin.reduce(cond, axis=None) < np.inf):
        raise IdentifiabilityError(_diagnose_singular(np.stack(qs), labels))
    if ks is None:
        # unknown: read-only NaN views (no memory, no pass over it)
        ks, rel_std = _unknown_std(k.shape[1])
        cs = ks.view()
    else:
        ks, cs = ks[0], cs[0]
        rel_std = None if rel_std is None else rel_std[0]
    ks_res, cs_res = ks, cs
    bias_k = bias_c = None
    source, dof, cov = ("residual" if residual_std else "none"), None, None
    coef_dof = None  # the dof of each coefficient's error where they differ, (n, 2, 2, 2)
    if residual_std and row_dof is not None:
        coef_dof = np.broadcast_to(row_dof[:, None, :, None], (axis.size, 2, 2, 2))
        # the intervals take each point's smaller dof (NaN only where both are)
        dof = np.fmin(row_dof[:, 0], row_dof[:, 1])
    elif residual_std:
        # one value for every point: a read-only view, not an (n,) array (freed with om, two such
        # arrays made glibc return and fault in the memory on every call)
        dof = _constant_view(residual_dof, (axis.size,))
    if covs is not None:
        # the accelerometers' calibration (a systematic error common to all runs) is added to the
        # covariance by the same core call, through the same Jacobian
        from .uncertainty import _propagate

        cov, b, unknown, ks, cs, meas = _propagate(
            rotor, w, spin, list(qs), e, gain, sigma, covs, identical=identical, method=method,
            bias=True, shared=shared_cov, q_ped=None if q_ped is None else list(q_ped), w_scale=w_scale,
            calibration=calibration, meas_std=identical and redundant)
        # the measurement's standard errors alone (without the calibration's)
        ks_meas, cs_meas = meas if meas is not None else (ks, cs)
        rel_std = None  # the standard errors change: recomputed in _finish
        # the bias in [point, bearing, i, j] order, unknown (NaN) as 0: one finiteness pass of the
        # core, NaN handled only when there is one, and one strided copy per half (nan_to_num on
        # the strided halves took 27 ms of a 100,000-speed call)
        if not all_finite(b):
            b = np.nan_to_num(b)
        bias_k, bias_c = (_bij_from_report(b[:, h:h + 8]) for h in (0, 8))
        if estimator == "bias-corrected":
            k = k - bias_k[None]
            c = c - bias_c[None]
        if unknown.any():
            extra_flags = _flag_list(extra_flags) + [(unknown, "uncertainty unknown")]
        source = "measurement covariance"
        coef_dof = None
        dof = np.min(dofs, axis=0) if dofs is not None else np.full(axis.size, np.inf)
        dof = np.where(unknown, np.nan, dof)
    if covs is not None and not identical and residual_std and ks is not None:
        # redundant runs checked against their measurement covariance: where the runs' misfit is far
        # beyond what their errors explain (a unit mix-up on one channel of one run, a run taken at
        # another condition) the standard errors from the covariance do not cover the truth
        disagree = _misfit_ratio(ks_res, cs_res, ks_meas, cs_meas, axis.size) > RUNS_DISAGREE
        if disagree.any():
            extra_flags = _flag_list(extra_flags) + [(disagree, "runs disagree beyond their measurement errors")]
    if identical and redundant:
        # (before the calibration is added: it is common to both bearings' equations)
        # the identical-bearing hypothesis is testable: the two bearings' equations must agree within
        # the measurement errors (residual-based errors no larger than the propagated ones), or, without
        # a covariance, within 1 % of the forces
        if cov is not None:
            rejected = _misfit_ratio(ks_res, cs_res, ks_meas, cs_meas, axis.size) > RUNS_DISAGREE
        else:
            rejected = resid[0] > 0.01
        if rejected.any():
            extra_flags = _flag_list(extra_flags) + [(rejected, IDENTICAL_REJECTED)]
    # the estimated part of the variances (the residual's, or the measurement covariance's, with
    # the dof of the runs) before any stated uncertainty (accelerometer calibration, phase
    # reference; infinite dof) is added below
    estimated = None
    if dof is not None and source != "none" and (calibration is not None or phase_std is not None):
        estimated = (ks ** 2, cs ** 2) if covs is None else (ks_meas ** 2, cs_meas ** 2)
    if calibration is not None and covs is None and source != "none":
        # residual-based errors (redundant runs) plus the calibration's (without any estimate of
        # the random errors the standard errors stay unknown)
        from .uncertainty import _propagate

        _, _, _, kc, cc, _ = _propagate(rotor, w, spin, list(qs), e, gain, sigma, None, identical=identical,
                                        method=method, bias=False, q_ped=list(q_ped), w_scale=w_scale,
                                        calibration=calibration)
        ks, cs = np.sqrt(ks ** 2 + kc ** 2), np.sqrt(cs ** 2 + cc ** 2)
    if calibration is not None and source != "none":
        rel_std = None
        source = f"{source} + accelerometer calibration"
    if phase_std is not None and source != "none":
        # the phase reference: one direction common to every run and channel. With the sigma points
        # p± at ±sigma_alpha: g = (p+ - p-)/2, h = p+ + p- - 2 p, and for a normal alpha the
        # variance g gᵀ + h hᵀ/2 (first order alone missed K by 2x at 2 degrees near 6,500 rpm on
        # the NSF rig, where dK/dalpha nearly vanishes). Of the least-squares estimate, also with
        # estimator="bias-corrected" (its derivative measured 1.00-1.11 times that at usable points)
        (kp, cp), (km, cm) = _phase_sigma_points(rotor, w, spin, qs, e_core, gain, sigma, phase_std,
                                                 identical=identical, method=method, q_ped=q_ped, planes=planes,
                                                 w_scale=w_scale)
        gk, gc = 0.5 * (kp - km), 0.5 * (cp - cm)
        hk, hc = kp + km - 2.0 * k_ls, cp + cm - 2.0 * c_ls
        ks, cs = np.sqrt(ks ** 2 + gk ** 2 + 0.5 * hk ** 2), np.sqrt(cs ** 2 + gc ** 2 + 0.5 * hc ** 2)
        if cov is not None:
            from .uncertainty import _report_order

            g, h = _report_order(gk, gc), _report_order(hk, hc)
            cov = cov + g[:, :, None] * g[:, None, :] + 0.5 * h[:, :, None] * h[:, None, :]
        rel_std = None
        source = f"{source} + phase reference"
    flag_dof = coef_dof
    if estimated is not None:
        dof, flag_dof = _welch_satterthwaite(dof if coef_dof is None else coef_dof, estimated, (ks ** 2, cs ** 2),
                                             axis.size)
    return _finish(axis_name, axis, amp[0], k[0], c[0], cond[0], resid[0], ks, cs, cond_max, min_rel_amplitude,
                   method, labels, source, dof, cov, max_rel_std, extra_flags, ks_res, cs_res, bias_k, bias_c,
                   estimator, rel_std, std_known, flags=None if code is None else (code[0], rel_amp[0], ok[0]),
                   flag_dof=flag_dof)


def _welch_satterthwaite(dof, estimated, total, n):
    """Degrees of freedom once stated uncertainties (infinite dof: the accelerometers' calibration,
    the phase reference) are added to estimated ones: each coefficient's grow by (total /
    estimated variance)², Welch-Satterthwaite. ``dof``: the estimated errors' dof, per point (n,)
    or per coefficient (n, 2, 2, 2) (alike for K and C). Returns (per point, the smallest over its
    16 coefficients: the intervals'; per damping coefficient (n, 2, 2, 2): the negative-damping
    flag's). Residual-based errors of 3 runs (2 dof) made the intervals 2.2 times too wide where the
    phase term dominates; the point's smallest dof flagged 0.5 % of zero dampings (its damping's
    own gives the intended 2.3 %), and without any growth the calibration's case flagged none."""
    with np.errstate(divide="ignore", invalid="ignore"):
        grow_k, grow_c = ((t / e) ** 2 for t, e in zip(total, estimated))
    grow_k, grow_c = (np.where(np.isfinite(g), g, np.nan) for g in (grow_k, grow_c))
    base = np.asarray(dof, dtype=float)
    base = base.reshape(n, 1, 1, 1) if base.ndim == 1 else base
    # a point without any finite growth keeps its (smallest) dof
    grown = np.nanmin(np.concatenate([(base * grow_k).reshape(n, -1), (base * grow_c).reshape(n, -1)], axis=1),
                      axis=1, initial=np.inf)
    per_point = np.where(np.isfinite(grown), grown, np.broadcast_to(base, (n, 2, 2, 2)).reshape(n, -1).min(axis=1))
    per_damping = base * np.where(np.isnan(grow_c), 1.0, grow_c)
    return per_point, per_damping


def identify_synchronous_batch(rotor: RigidRotor, speed_rpm, q, imbalances, *, method: str = "forces",
                               identical: bool = False, with_std: bool = False, at: str = "bearings"):
    """Many identifications in one core call (Monte Carlo): q of shape (trials, runs, n, 4).

    ``imbalances``: list of Imbalance (one per run, shared by all trials) or a complex array
    (trials, runs, 4) of generalized imbalance vectors F_o/Ω² (eq. 4) when the imbalance itself is
    perturbed per trial. Returns a dict of arrays k, c (trials, n, 2, 2, 2), cond (trials, n, 2),
    residual and amplitude (rms response, m) (trials, n) and, with ``with_std``, k_std and c_std
    (residual-based; with ``identical=True`` also ``dof`` (trials, n, 2), the x and y rows' degrees
    of freedom, as :func:`identify_synchronous` computes them).
    No per-point flags: use cond (inf where singular, NaN where the input was not finite).
    ``q`` is used as it is when it is a C-contiguous complex128 array (no copy, no extra pass).
    """
    if not isinstance(rotor, RigidRotor):
        raise RotoridError(f"rotor must be a rotorid.RigidRotor, got {type(rotor).__name__}")
    choice("method", method, _METHODS)
    choice("at", at, {"bearings", "probes"})
    _check_bool("identical", identical)
    _check_bool("with_std", with_std)
    rpm = real_array("speed_rpm", speed_rpm, ndim=1, positive=True)
    q = complex_array("q", q, ndim=4, finite=False)  # NaN/inf trials come back as NaN with cond NaN
    if q.shape[2:] != (rpm.size, 4):
        raise RotoridError(f"q has shape {q.shape}, expected (trials, runs, {rpm.size}, 4)")
    if at == "probes":
        q = probes_to_bearings(rotor, q)
    if isinstance(imbalances, (list, tuple)) and all(isinstance(i, Imbalance) for i in imbalances):
        labels = [f"run {i}" for i in range(len(imbalances))]
        check_imbalance_independence(rotor, list(imbalances), labels, identical=identical)
        e = np.stack([imb.generalized(rotor) for imb in imbalances])[None]
    else:
        e = complex_array("imbalances", imbalances, ndim=3)
    if e.shape[1:] != (q.shape[1], 4) or e.shape[0] not in (1, q.shape[0]):
        raise RotoridError(f"imbalances give excitation shape {e.shape}, expected (1 or {q.shape[0]}, {q.shape[1]}, 4)")
    if e.shape[1] < (1 if identical else 2):
        raise IdentifiabilityError(f"{e.shape[1]} run(s) given: identifying all 16 coefficients needs at least two "
                                   "imbalance runs (one with identical=True)")
    if not identical and e.shape[1] >= 2:
        # the runs' force and moment excitations must be independent in every trial
        sv = np.linalg.svd(e[:, :, [0, 2]], compute_uv=False)          # (trials, 2): F and moment columns
        dep = sv[:, -1] <= 1e-9 * np.maximum(sv[:, 0], 1e-300)
        if dep.any():
            raise IdentifiabilityError(f"imbalances of trial {int(np.argmax(dep))} (and {int(dep.sum()) - 1} more) are "
                                       "linearly dependent across the runs (complex multiples of one another): those "
                                       "trials cannot identify the coefficients")
    om = rpm * RPM
    q, e = np.ascontiguousarray(q), np.ascontiguousarray(e)
    structured = identical and with_std and method == "forces"
    k, c, cond, resid, amp, ks, cs, *_ = _core.identify(rotor.core_params(), om, om, q, e, om ** 2, identical=identical,
                                                      method=method, with_std=with_std and not structured)
    out = dict(k=k, c=c, cond=cond, residual=resid, amplitude=amp)
    if structured:
        # identical bearings: errors with the structure of the pooled equations (identify_synchronous)
        ks, cs, dof = _core.identical_std(rotor.core_params(), om, om, q, e, om ** 2, k, c,
                                          noise_planes=_plane_matrix(rotor, "bearings") if at == "probes" else None)
        out.update(k_std=ks, c_std=cs, dof=dof)
    elif with_std and ks is not None:
        out.update(k_std=ks, c_std=cs)
    return out


def _noise_planes(rotor, runs):
    """The eq. 19 transform from the probe planes when every run (or test) was measured there, else
    None: the identical-bearing errors take the noise as white where it was measured."""
    return _plane_matrix(rotor, "bearings") if all(r.at == "probes" for r in runs) else None


def _for_the_core(rotor, runs, may_use_planes=True):
    """(runs at the bearings, planes) for the core call: runs (or tests) recorded at the probe
    planes as they are, with the eq. 19 transform for the core to apply as it loads each point
    (no moved copy of every run), when none carries a covariance (moved with its run in Python);
    else the runs moved to the bearings and None."""
    for r in runs:
        if r.at != "bearings":
            break
    else:
        return runs, None  # all at the bearings already (at_bearings would return each as it is)
    if may_use_planes and all(r.at == "probes" and r.cov is None and _q_as_checked(r) for r in runs):
        return runs, _plane_matrix(rotor, "bearings")
    return [r.at_bearings(rotor) for r in runs], None


def _rank_up_to_2(E, tol):
    """min(rank, 2) of a real (R, 4) matrix: singular values above ``tol`` counted as
    ``np.linalg.matrix_rank`` counts them, in closed form for R <= 2 (an SVD call costs ~25 µs,
    a tenth of a 10,000-frequency identification). For two rows a, b: s1 s2 = sqrt(det G) with
    det G = sum over i < j of (a_i b_j - a_j b_i)^2 (Lagrange's identity, free of the cancellation
    of |a|^2 |b|^2 - (a.b)^2) and s1^2 = (tr G + sqrt(tr G^2 - 4 det G)) / 2. Python floats
    throughout (NumPy calls on a 2 x 4 array cost more than the arithmetic)."""
    if E.shape[0] > 2:
        return min(2, int(np.linalg.matrix_rank(E, tol=tol)))
    rows = E.tolist()
    top = max((abs(x) for r in rows for x in r), default=0.0)
    if not top > 0.0:
        return 0
    # scaled by the largest entry: no overflow of the squares below for any finite input
    rows = [[x / top for x in r] for r in rows]
    tol = tol / top
    if len(rows) < 2:
        return int(math.sqrt(sum(x * x for x in rows[0])) > tol)
    a, b = rows
    det = sum((a[i] * b[j] - a[j] * b[i]) ** 2 for i in range(4) for j in range(i + 1, 4))
    tr = sum(x * x for x in a) + sum(x * x for x in b)
    s1 = math.sqrt((tr + math.sqrt(max(tr * tr - 4.0 * det, 0.0))) / 2.0)
    s2 = math.sqrt(det) / s1 if s1 > 0 else 0.0
    return int(s1 > tol) + int(s2 > tol)


def _excitation_rank(E):
    """min(rank, 2) of the tests' (R, 4) generalized forces, singular values below 1e-9 of the
    largest entry (at least 1) counted as zero."""
    top = max((abs(x) for x in E.ravel().tolist()), default=0.0)
    return _rank_up_to_2(E, 1e-9 * max(1.0, top))


def _core_excitations(e):
    """The runs' or tests' excitations (R, 4) as the core takes them, (1, R, 4) complex and
    contiguous."""
    return np.ascontiguousarray(e[None], dtype=complex)


def _excitations(E):
    """(E, rank, E in the core's form) of the tests' (R, 4) generalized forces, both
    :func:`~rotorid._validate.frozen`."""
    return frozen(E), _excitation_rank(E), frozen(_core_excitations(E))


@functools.lru_cache(maxsize=64)
def _layout_excitations(layout):
    """:func:`_excitations` of the impacts ``layout`` = ((plane, direction), ...). A rig is tested
    in a few layouts, identified many times: read once per layout, the excitations and their
    independence test cost 2 µs of a call instead of ~25 (measured inside real calls, the core
    having just evicted the interpreter's data from L2)."""
    from .simulate import impact_vector

    return _excitations(np.array([impact_vector(z, d) for z, d in layout]))


def _test_excitations(tests):
    """(E (R, 4), rank, E as the core takes it) of the tests' impacts (:func:`_excitations`),
    through the per-layout cache when the tests' planes are floats and directions strings (as the
    constructor leaves them), else computed afresh (each checked by ``impact_vector`` either
    way)."""
    layout = []
    for t in tests:
        plane, direction = t.plane, t.direction
        if type(plane) is not float or type(direction) is not str:
            return _excitations(np.array([t.excitation() for t in tests]))
        layout.append((plane, direction))
    return _layout_excitations(tuple(layout))


def check_impact_independence(tests, labels, *, identical=False):
    """Raise IdentifiabilityError when the impacts cannot excite independent responses; else
    return the tests' (R, 4) generalized forces, per unit force (:func:`_test_excitations`;
    read-only: the array may be shared with later calls)."""
    return _independent_excitations(tests, labels, identical)[0]


def _independent_excitations(tests, labels, identical):
    """:func:`check_impact_independence`, returning the excitations in both forms: (E, E as the
    core takes it)."""
    E, rank, core_form = _test_excitations(tests)
    need = 1 if identical else 2
    if rank < need:
        if len(tests) < need:
            raise IdentifiabilityError(
                f"{len(tests)} impact test(s) given; identifying all 16 coefficients needs at least two independent "
                "impacts at the same speed: two directions at one plane, or one direction at two planes (report section 5). "
                "With identical bearings one impact suffices (identical=True)")
        desc = ", ".join(f"{lab}: {t.direction} at plane {t.plane:g} m" for lab, t in zip(labels, tests))
        raise IdentifiabilityError(
            "the impact tests are not independent (all in the same direction at the same plane, so every test repeats the "
            f"same excitation): {desc}. Add an impact in the orthogonal direction or at another plane (report section 5)")
    return E, core_form


def identify_impact(rotor: RigidRotor, tests, *, method: str = "forces", identical: bool = False,
                    cond_max: float = COND_MAX, min_rel_amplitude: float = MIN_REL_AMPLITUDE_IMPACT,
                    max_rel_std: float = MAX_REL_STD, extra_flags=None, estimator: str = "ls",
                    accel_gain_std: float = 0.0, accel_phase_std_deg: float = 0.0) -> Identification:
    """Frequency-dependent K(w) and C(w) of both bearings from impacts at one running speed (eq. 23-28).

    ``tests``: list (or dict) of ImpactResponse at the same ``speed_rpm`` and ``freq_hz``: FRFs, or
    response and force spectra. Two independent tests (two directions at one plane, or one
    direction at two planes) solve the 16 coefficients at every frequency; repeated impacts add
    redundant equations solved in the least-squares sense. ``identical=True`` assumes the same
    coefficients at both bearings (8 unknowns) and works from a single impact. C is Im(Z)/w with w
    the vibration frequency; for exponentially windowed spectra (``ImpactResponse.sigma``) the
    equations are solved at s = sigma + j w and K = Re(Z) - sigma C. The whole frequency batch is
    one core call. ``accel_gain_std``, ``accel_phase_std_deg``: accelerometer calibration
    uncertainty with pedestal motion (see :func:`identify_synchronous`).
    """
    if not isinstance(rotor, RigidRotor):
        raise RotoridError(f"rotor must be a rotorid.RigidRotor, got {type(rotor).__name__}")
    choice("method", method, _METHODS)
    _check_bool("identical", identical)
    extra_flags = None if extra_flags is None else _flag_list(extra_flags)
    tests = list(tests.values()) if isinstance(tests, dict) else tests
    if not isinstance(tests, (list, tuple)):
        raise RotoridError(f"tests must be a list or dict of ImpactResponse, got {type(tests).__name__}")
    if not tests:
        raise IdentifiabilityError("no impact tests given")
    first = tests[0]
    if not isinstance(first, ImpactResponse):
        raise RotoridError(f"test 0 must be a rotorid.ImpactResponse, got {type(first).__name__}")
    _wake_core_threads(first)
    f, speed, sigma = first.freq_hz, first.speed_rpm, first.sigma
    labels = []
    same_f = True
    for i, t in enumerate(tests):
        if not isinstance(t, ImpactResponse):
            raise RotoridError(f"test {i} must be a rotorid.ImpactResponse, got {type(t).__name__}")
        labels.append(f"test {i} ({t.name!r})" if t.name else f"test {i}")
        same_f = same_f and t.freq_hz is f
    if not same_f:  # not the same array: compared by value
        _check_same_axis("freq_hz", [t.freq_hz for t in tests], labels, "tests", "frequencies",
                         "same record length and sample rate")
    for i, t in enumerate(tests[1:], 1):
        # scalars: equal, else math.isclose (np.isclose costs 16 µs)
        if t.speed_rpm != speed and not math.isclose(t.speed_rpm, speed, rel_tol=1e-6, abs_tol=1e-9):
            raise RotoridError(f"speed_rpm of {labels[i]} ({t.speed_rpm:g}) differs from {labels[0]} ({speed:g}): "
                               "impact identification needs all tests at the same running speed")
        if t.sigma != sigma and not math.isclose(t.sigma, sigma, rel_tol=1e-9, abs_tol=0.0):
            raise RotoridError(f"sigma (exponential window decay) of {labels[i]} ({t.sigma:g} 1/s) differs from "
                               f"{labels[0]} ({sigma:g} 1/s): window all tests alike")
    e, e_core = _independent_excitations(tests, labels, identical)  # (R, 4), per unit force
    q_ped = cal = planes = None
    if _has_pedestal(tests, labels):
        qs, q_ped, covs, dofs, pflags = _pedestal_inputs(rotor, tests, labels, "freq_hz", f)
        extra_flags = _flag_list(extra_flags) + pflags
        cal = _calibration_inputs(rotor, tests, accel_gain_std, accel_phase_std_deg)
    else:
        _no_calibration(accel_gain_std, accel_phase_std_deg)
        at_b, planes = _for_the_core(rotor, tests)
        qs = [np.ascontiguousarray(t.frf(), dtype=complex) for t in at_b]  # (n, 4) per unit force, per test
        covs = _run_covs(at_b, labels)
        dofs = None if covs is None else _run_dofs(at_b)
    # one running speed, a unit gain and one window decay, broadcast by the core; w = 2 pi f
    # formed by the core too
    spin = np.array([speed * RPM])
    return _solve(rotor, "freq_hz", f, f, spin, qs, e, _UNIT_GAIN, np.array([sigma]) if sigma else None,
                  w_scale=2 * np.pi, identical=identical, method=method, labels=labels, cond_max=cond_max,
                  min_rel_amplitude=min_rel_amplitude, what="impact responses", covs=covs, dofs=dofs,
                  max_rel_std=max_rel_std, extra_flags=extra_flags, estimator=estimator, q_ped=q_ped, calibration=cal,
                  planes=planes, e_core=e_core, noise_planes=_noise_planes(rotor, tests) if identical else None)
