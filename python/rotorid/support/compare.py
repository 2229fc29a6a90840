"""Predicted support coefficients side by side with identified ones (issue 13, item 4).

A :class:`SeriesSupport` is one bearing support of the report: the bearing film (a table from a
bearing code, :class:`rotorid.support.tpjb.BearingTable`, or any object with
``impedance(speed_rpm, freq_hz)``) in series with the damper (``impedance(freq_hz)``, e.g.
:class:`rotorid.support.sfd.SqueezeFilmDamper`, or a constant 2 x 2 impedance) through the damper
journal's mass. :func:`predict_coefficients` evaluates both supports where an identification
measured: at w = Ω for imbalance runs (synchronous), at the test's running speed over the
frequencies of impacts. :func:`compare` puts the prediction next to the identified coefficients
with their intervals, in units of the identified uncertainty.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._validate import real_array
from ..errors import RotoridError
from .series import coefficients_of, series_impedance


def _const_impedance(name, z):
    try:
        a = np.asarray(z, dtype=complex)
    except (TypeError, ValueError):
        return None
    if a.shape != (2, 2):
        raise RotoridError(f"{name} must be an object with an impedance method or a 2 x 2 impedance, got shape "
                           f"{a.shape}")
    if not np.all(np.isfinite(a)):
        raise RotoridError(f"{name} contains NaN or inf")
    return a


@dataclass(frozen=True)
class SeriesSupport:
    """One bearing support: ``bearing`` film in series with ``damper`` through the damper journal
    (``journal_mass_kg``: ring + bearing shell).

    ``bearing``: an object with ``impedance(speed_rpm, freq_hz) -> (n, 2, 2)`` (a
    :class:`~rotorid.support.tpjb.BearingTable`) or a constant 2 x 2 complex impedance;
    ``damper``: an object with ``impedance(freq_hz) -> (n, 2, 2)`` (a
    :class:`~rotorid.support.sfd.SqueezeFilmDamper`) or a constant 2 x 2 complex impedance. A
    constant complex impedance K + jH is hysteretic (its imaginary part is the same at every
    frequency, so its damping H / w falls with frequency); a viscous damper needs an object whose
    impedance is K + j w C at each frequency.

    Examples
    --------
    >>> import numpy as np
    >>> from rotorid.support.compare import SeriesSupport
    >>> s = SeriesSupport(bearing=np.diag([1.2e7, 1.2e7]), damper=np.diag([3e6, 3e6]) + 2e3j * np.eye(2),
    ...                   journal_mass_kg=0.0)
    >>> z = s.impedance(speed_rpm=[3000.0], freq_hz=[50.0])
    >>> round(float(z[0, 0, 0].real) / 1e6, 3)          # about the springs in series, 2.4e6
    2.4
    """

    bearing: object
    damper: object
    journal_mass_kg: float = 0.0
    name: str = ""

    def __post_init__(self):
        from .._validate import number

        for nm, obj, method in (("bearing", self.bearing, "impedance"), ("damper", self.damper, "impedance")):
            if not callable(getattr(obj, method, None)) and _const_impedance(nm, obj) is None:
                raise RotoridError(f"{nm} must have an impedance method or be a 2 x 2 complex impedance, got "
                                   f"{type(obj).__name__}")
        object.__setattr__(self, "journal_mass_kg", number("journal_mass_kg", self.journal_mass_kg, nonneg=True))
        if not isinstance(self.name, str):
            raise RotoridError(f"name must be a string, got {type(self.name).__name__}")

    def _part(self, name, obj, n, *args):
        if callable(getattr(obj, "impedance", None)):
            try:
                z = np.asarray(obj.impedance(*args), dtype=complex)
            except RotoridError:
                raise
            except (TypeError, ValueError) as exc:
                raise RotoridError(f"{name}.impedance{'(speed_rpm, freq_hz)' if name == 'bearing' else '(freq_hz)'} "
                                   f"failed ({type(exc).__name__}: {exc}); is the {name} the right object (a bearing "
                                   "table for bearing, a damper for damper)?") from None
            if z.shape != (n, 2, 2):
                raise RotoridError(f"{name}.impedance returned shape {z.shape}, expected ({n}, 2, 2)")
            if not np.all(np.isfinite(z)):
                raise RotoridError(f"{name}.impedance returned NaN or inf")
            return z
        return np.broadcast_to(_const_impedance(name, obj), (n, 2, 2))

    def impedance(self, speed_rpm, freq_hz) -> np.ndarray:
        """Z_eq (n, 2, 2) at running speeds ``speed_rpm`` and vibration frequencies ``freq_hz``
        (broadcast to n points)."""
        s = np.atleast_1d(real_array("speed_rpm", speed_rpm, nonneg=True))
        f = np.atleast_1d(real_array("freq_hz", freq_hz, nonneg=True))
        try:
            s, f = np.broadcast_arrays(s, f)
        except ValueError:
            raise RotoridError(f"speed_rpm {s.shape} and freq_hz {f.shape} do not broadcast") from None
        if s.ndim != 1:
            raise RotoridError(f"speed_rpm and freq_hz must be 1-D, got shape {s.shape}")
        n = s.size
        zb = self._part("bearing", self.bearing, n, s, f)
        zd = self._part("damper", self.damper, n, f)
        return series_impedance(zb, zd, self.journal_mass_kg, f)


def predict_coefficients(supports, *, speed_rpm, freq_hz=None):
    """K and C (n, 2, 2, 2) [point, bearing, i, j] of two series supports where an identification
    measured: synchronous (``freq_hz`` None: w = Ω at each ``speed_rpm``) or at one running speed
    over ``freq_hz`` (impacts).

    Examples
    --------
    >>> import numpy as np
    >>> from rotorid.support.compare import SeriesSupport, predict_coefficients
    >>> s = SeriesSupport(np.diag([1.2e7, 1.2e7]), np.diag([3e6, 3e6]) + 2e3j * np.eye(2), 2.0)
    >>> k, c = predict_coefficients([s, s], speed_rpm=[3000.0, 4000.0])
    >>> k.shape
    (2, 2, 2, 2)
    """
    if isinstance(supports, SeriesSupport) or not isinstance(supports, (list, tuple)):
        raise RotoridError(f"supports must be a list of two SeriesSupport (bearing 1, bearing 2), got "
                           f"{type(supports).__name__}")
    supports = list(supports)
    if len(supports) != 2 or not all(isinstance(s, SeriesSupport) for s in supports):
        raise RotoridError("supports must be two SeriesSupport, bearing 1 then bearing 2")
    rpm = np.atleast_1d(real_array("speed_rpm", speed_rpm, nonneg=True))
    if freq_hz is None:
        if rpm.ndim != 1:
            raise RotoridError(f"speed_rpm must be 1-D, got shape {rpm.shape}")
        if np.any(rpm <= 0):
            raise RotoridError("synchronous coefficients (w = Omega) need speeds > 0 rpm")
        f = rpm / 60.0
    else:
        if rpm.size != 1:
            raise RotoridError("with freq_hz (impacts) give the one running speed of the tests as speed_rpm")
        f = np.atleast_1d(real_array("freq_hz", freq_hz, positive=True))
        if f.ndim != 1:
            raise RotoridError(f"freq_hz must be 1-D, got shape {f.shape}")
        rpm = np.full(f.size, rpm.ravel()[0])
    k = np.empty((f.size, 2, 2, 2))
    c = np.empty((f.size, 2, 2, 2))
    for b, s in enumerate(supports):
        k[:, b], c[:, b] = coefficients_of(s.impedance(rpm, f), f)
    return k, c


@dataclass
class Comparison:
    """Predicted and identified coefficients at the identification's points.

    ``axis_name``/``axis``: speed_rpm (synchronous) or freq_hz (impacts); ``names``: the 16
    coefficients (report order); ``identified``, ``std``, ``lower``, ``upper``, ``predicted``:
    (n, 16); ``z``: (predicted - identified) / std, the disagreement in units of the identified
    standard error; ``inside``: the prediction within the identified interval (``level``);
    ``ok``: the identification's flags (only ok points count in :meth:`summary`).
    """

    axis_name: str
    axis: np.ndarray
    names: tuple
    identified: np.ndarray
    std: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    predicted: np.ndarray
    ok: np.ndarray
    level: float = 0.95

    @property
    def z(self):
        """(predicted - identified) / std; NaN where the std is unknown or not positive."""
        std = np.where(self.std > 0, self.std, np.nan)
        with np.errstate(divide="ignore", invalid="ignore"):
            return (self.predicted - self.identified) / std

    @property
    def inside(self):
        return (self.lower <= self.predicted) & (self.predicted <= self.upper)

    def to_dataframe(self):
        """One row per point and coefficient (long format)."""
        import pandas as pd

        n, m = self.identified.shape
        return pd.DataFrame({self.axis_name: np.repeat(self.axis, m), "coefficient": np.tile(self.names, n),
                             "identified": self.identified.ravel(), "std": self.std.ravel(),
                             f"lo{int(100 * self.level)}": self.lower.ravel(),
                             f"hi{int(100 * self.level)}": self.upper.ravel(), "predicted": self.predicted.ravel(),
                             "z": self.z.ravel(), "inside": self.inside.ravel(), "ok": np.repeat(self.ok, m)})

    def summary(self):
        """Per coefficient over the ok points with a known uncertainty: median and largest |z|,
        the fraction of points whose interval holds the prediction, and the median relative
        difference (predicted / identified - 1; little meaning for a coefficient near zero, such as
        a cross-coupled one: read its z)."""
        import pandas as pd

        rows = []
        for j, name in enumerate(self.names):
            sel = self.ok & (self.std[:, j] > 0)
            z = np.abs(self.z[sel, j])
            with np.errstate(divide="ignore", invalid="ignore"):
                rel = self.predicted[sel, j] / self.identified[sel, j] - 1
            rows.append(dict(coefficient=name, points=int(sel.sum()),
                             median_abs_z=float(np.median(z)) if z.size else np.nan,
                             max_abs_z=float(z.max()) if z.size else np.nan,
                             inside_fraction=float(self.inside[sel, j].mean()) if z.size else np.nan,
                             median_rel_difference=float(np.median(rel)) if z.size else np.nan))
        return pd.DataFrame(rows)


def compare(identification, predicted_k, predicted_c, *, level: float = 0.95) -> Comparison:
    """Put predicted coefficients (n, 2, 2, 2) next to an :class:`rotorid.Identification` at the
    same points: the disagreement in units of the identified standard error.

    Examples
    --------
    >>> import numpy as np, rotorid
    >>> from rotorid.support.compare import compare
    >>> rig = rotorid.nsf_rig()
    >>> rpm = np.array([3500.0, 4000.0, 4500.0])
    >>> runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm) for s in "AB"]
    >>> for r in runs:
    ...     r.cov = np.broadcast_to(np.eye(8) * (0.1e-6) ** 2, (3, 8, 8))
    >>> ident = rotorid.identify_synchronous(rig.rotor, runs)
    >>> k, c = rig.bearings.at()
    >>> cmp = compare(ident, np.repeat(k, 3, 0), np.repeat(c, 3, 0))
    >>> bool(np.all(np.abs(cmp.z) < 1e-6))              # the truth itself: no disagreement
    True
    """
    from .._validate import number
    from ..identify import Identification
    from ..model import REPORT_ORDER, _REPORT_TO_BIJ

    if not isinstance(identification, Identification):
        raise RotoridError(f"identification must be a rotorid Identification, got {type(identification).__name__}")
    level = number("level", level)
    if not 0.0 < level < 1.0:
        raise RotoridError(f"level must be between 0 and 1, got {level:g}")
    n = identification.axis.size
    pk = real_array("predicted_k", predicted_k, shape=(n, 2, 2, 2))
    pc = real_array("predicted_c", predicted_c, shape=(n, 2, 2, 2))

    def report(k, c):
        out = np.empty((n, 16))
        out[:, :8] = k.reshape(n, 8)[:, _REPORT_TO_BIJ]
        out[:, 8:] = c.reshape(n, 8)[:, _REPORT_TO_BIJ]
        return out

    iv = identification.interval(level)
    return Comparison(identification.axis_name, identification.axis.copy(), tuple(REPORT_ORDER),
                      report(identification.k, identification.c), report(identification.k_std, identification.c_std),
                      report(iv.k_lower, iv.c_lower), report(iv.k_upper, iv.c_upper), report(pk, pc),
                      np.asarray(identification.ok, bool).copy(), level)


#: coefficient columns of rotorid's tables in US units: suffix -> unit
_US_SUFFIX = {"K": ("_lbf_per_in", "lbf/in"), "C": ("_lbf_s_per_in", "lbf*s/in")}


def _read_table(path, what):
    import pandas as pd

    from .._validate import path as _path

    p = _path(what, path)
    if not p.is_file():
        raise RotoridError(f"{what}: no such file {str(p)!r}")
    try:
        return pd.read_csv(p)
    except Exception as exc:  # pandas raises many kinds for a damaged file
        raise RotoridError(f"{what}: {str(p)!r} is not a readable CSV table ({exc})") from None


def _numbers(df, col, path, what):
    """A column as floats (empty cells NaN); a non-numeric cell is an error naming it."""
    import pandas as pd

    v = pd.to_numeric(df[col], errors="coerce")
    bad = v.isna() & df[col].notna() & (df[col].astype(str).str.strip() != "")
    if bad.any():
        i = int(np.argmax(bad.to_numpy()))
        raise RotoridError(f"{what} {str(path)!r}: column {col!r} row {i + 1} holds {df[col].iloc[i]!r}, not a number")
    return v.to_numpy(float)


def _column(df, name, suffix_kind, path, what, required=True):
    """A coefficient column in SI: ``name`` (SI) or ``name`` + US suffix (converted); None when
    not ``required`` and absent."""
    from ..units import to_si

    if name in df.columns:
        return _numbers(df, name, path, what)
    suffix, unit = _US_SUFFIX[suffix_kind]
    stem, _, tail = name.partition("_")
    us = f"{stem}{('_' + tail) if tail else ''}{suffix}"
    if us in df.columns:
        return np.asarray(to_si(_numbers(df, us, path, what), unit), float)
    if not required:
        return None
    raise RotoridError(f"{what} {str(path)!r} has no column {name!r} (nor {us!r}); it has {list(df.columns)[:12]}")


def compare_tables(identified_csv, predicted_csv, *, level: float = 0.95) -> Comparison:
    """A :class:`Comparison` from files: an identification's coefficient table as rotorid writes it
    (``coefficients_imbalance.csv`` / ``coefficients_impact.csv``: the axis, Kxx1 ... Cyy2, their
    ``_std``, ``_lo95`` and ``_hi95`` columns and ``ok``; SI or US units) and a predicted table (the
    same axis column, ``speed_rpm`` or ``freq_hz``, and Kxx1 ... Cyy2 in SI or with the US
    suffixes), interpolated linearly onto the identified points (no extrapolation).

    Examples
    --------
    >>> import os, tempfile, numpy as np, pandas as pd
    >>> from rotorid.support.compare import compare_tables
    >>> from rotorid.model import REPORT_ORDER
    >>> d = tempfile.mkdtemp()
    >>> ident = {"speed_rpm": [3000.0, 4000.0], "ok": [True, True]}
    >>> for n in REPORT_ORDER:
    ...     ident.update({n: [1e6, 1e6], f"{n}_std": [1e4, 1e4], f"{n}_lo95": [0.98e6, 0.98e6],
    ...                   f"{n}_hi95": [1.02e6, 1.02e6]})
    >>> pd.DataFrame(ident).to_csv(os.path.join(d, "id.csv"), index=False)
    >>> pd.DataFrame({"speed_rpm": [2000.0, 5000.0], **{n: [1.01e6, 1.01e6] for n in REPORT_ORDER}}).to_csv(
    ...     os.path.join(d, "pred.csv"), index=False)
    >>> cmp = compare_tables(os.path.join(d, "id.csv"), os.path.join(d, "pred.csv"))
    >>> float(cmp.z[0, 0])
    1.0
    """
    from .._validate import number
    from ..model import REPORT_ORDER

    level = number("level", level)
    ident, pred = _read_table(identified_csv, "identified"), _read_table(predicted_csv, "predicted")
    for df, path, what in ((ident, identified_csv, "identified"), (pred, predicted_csv, "predicted")):
        if len(df) == 0:
            raise RotoridError(f"{what} {str(path)!r} has no rows")
    # impacts: freq_hz is the axis (a speed_rpm column is then the running speed); imbalance: speed_rpm
    axis_name = "freq_hz" if "freq_hz" in ident.columns else "speed_rpm" if "speed_rpm" in ident.columns else None
    if axis_name is None:
        raise RotoridError(f"identified {str(identified_csv)!r} has no axis column, speed_rpm or freq_hz; it has "
                           f"{list(ident.columns)[:8]}")
    if axis_name not in pred.columns:
        raise RotoridError(f"predicted {str(predicted_csv)!r} has no {axis_name} column: it must be given on the same "
                           f"axis as the identification ({axis_name})")
    if axis_name == "freq_hz":
        # the running speed of impacts: the prediction must be for the same one
        speeds = [(_numbers(df, "speed_rpm", path, what), what) for df, path, what in
                  ((ident, identified_csv, "identified"), (pred, predicted_csv, "predicted")) if "speed_rpm" in df.columns]
        if len(speeds) == 2:
            a, b = np.nanmedian(speeds[0][0]), np.nanmedian(speeds[1][0])
            if not abs(a - b) <= 0.01 * max(abs(a), abs(b), 1.0):
                raise RotoridError(f"the impacts ran at {a:g} rpm but the prediction is for {b:g} rpm: predict at the "
                                   "tests' speed")
        elif len(speeds) == 1:
            import warnings

            warnings.warn(f"only the {speeds[0][1]} table states its running speed (speed_rpm): check that the "
                          "prediction is for the impacts' speed")
    x = _numbers(ident, axis_name, identified_csv, "identified")
    xp = _numbers(pred, axis_name, predicted_csv, "predicted")
    if not np.all(np.isfinite(x)):
        raise RotoridError(f"identified {str(identified_csv)!r}: {axis_name} has empty or NaN cells")
    if not (np.all(np.isfinite(xp)) and np.all(np.diff(xp) > 0)):
        raise RotoridError(f"predicted {str(predicted_csv)!r}: {axis_name} must be finite and strictly increasing")
    tol = 1e-9 * max(abs(xp).max(), 1.0)
    if x.min() < xp[0] - tol or x.max() > xp[-1] + tol:
        raise RotoridError(f"the identification spans {x.min():g}-{x.max():g} ({axis_name}) but the prediction only "
                           f"{xp[0]:g}-{xp[-1]:g}: extend the predicted table")
    cols = {}
    for key in ("", "_std", "_lo95", "_hi95"):
        # an identification without any uncertainty has no _std, _lo95, _hi95 columns: unknown (NaN)
        got = [_column(ident, n + key, n[0], identified_csv, "identified", required=key == "") for n in REPORT_ORDER]
        cols[key] = np.stack([g if g is not None else np.full(x.size, np.nan) for g in got], 1)
    predicted = np.stack([np.interp(x, xp, _column(pred, n, n[0], predicted_csv, "predicted")) for n in REPORT_ORDER],
                         1)
    if not np.all(np.isfinite(predicted)):
        raise RotoridError(f"predicted {str(predicted_csv)!r} contains NaN or empty cells")
    if "ok" in ident.columns:
        raw = ident["ok"].astype(str).str.strip().str.lower()
        if not raw.isin(["true", "false", "1", "0"]).all():
            raise RotoridError(f"identified {str(identified_csv)!r}: column 'ok' must hold True/False, got "
                               f"{sorted(set(raw) - {'true', 'false', '1', '0'})[:3]}")
        ok = raw.isin(["true", "1"]).to_numpy()
    else:
        ok = np.ones(x.size, bool)
    if abs(level - 0.95) > 1e-12:
        raise RotoridError("tables carry 95 % intervals: level must be 0.95 here")
    return Comparison(axis_name, x, tuple(REPORT_ORDER), cols[""], cols["_std"], cols["_lo95"], cols["_hi95"],
                      predicted, ok, 0.95)
