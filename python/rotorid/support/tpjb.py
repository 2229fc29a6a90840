"""Tilting-pad journal bearing force coefficients from tables (issue 13, item 3).

rotorid does **not** model the physics of a tilting-pad bearing (pad tilt, pivot or web
flexibility, preload, thermal effects, pad deformation, ...). The flexure-pivot tilting-pad
bearing of the report (Table 1: 4 pads of 70 deg, 30.15 mm diameter, 22.9 mm long, preload 0.405,
pivot offset 0.5, pad rotational stiffness 40 N m/rad) is described to rotorid by the force
coefficients a bearing code predicts for it. A :class:`BearingTable` holds them and interpolates.

What a table is
---------------
A rectangular grid of *running speeds* (rpm) times *excitation frequencies*, and at every node
the 2 x 2 stiffness K (N/m), damping C (N s/m) and, optionally, added mass M (kg) over (x, y),
with rotorid's axes: x horizontal, y vertical (many bearing codes put x along the load, usually
vertical: swap their xx and yy, and xy and yx, before giving the table to rotorid):

    k[i, j], c[i, j], m[i, j]   at   speed_rpm[i], freq[j]        shape (ns, nf, 2, 2)

The frequency axis is either the excitation frequency in Hz (``freq_axis="hz"``) or the ratio
``r = excitation frequency / running frequency`` (``freq_axis="ratio"``), a common way bearing
codes tabulate non-synchronous (reduced, pad-assembly) coefficients. At a point (speed, f) the
ratio is ``r = f / (speed / 60)``; a ratio table cannot be asked at speed 0.

The impedance is Z = K + j w C - w^2 M (w = 2 pi f): the force on the journal is F = -Z X for a
motion X e^{j w t}. K, C and M are interpolated separately, bilinearly on the (speed, frequency or
ratio) grid; there is no extrapolation (a point outside the table raises, with a relative
tolerance of 1e-9 of the axis range at its ends). An axis with a single value (ns = 1 or nf = 1)
is taken as constant along that axis: a single-speed table serves every speed, a single-frequency
table every frequency.

Synchronous coefficients are the ones at f = speed / 60 (ratio 1): those are what the report's
imbalance-response identification estimates (:meth:`BearingTable.synchronous`). An impact
identification at the running speed sees the table at (speed, f) with f != speed / 60.

:class:`BearingTable`       the table, its impedance and coefficients at any points inside it
:func:`load_bearing_table`  a table from a CSV / text or Excel file, one row per grid node
"""

from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import units
from .._validate import path as _path_arg
from .._validate import real_array, text
from ..errors import RotoridError

__all__ = ["BearingTable", "load_bearing_table", "FREQ_AXES", "RANGE_TOLERANCE"]

#: the kinds of frequency axis: excitation frequency in Hz, or excitation / running frequency
FREQ_AXES = ("hz", "ratio")
#: relative tolerance (of an axis' largest magnitude) at the ends of the table's range: a point
#: this close outside is taken at the end node
RANGE_TOLERANCE = 1e-9

_IJ = ("xx", "xy", "yx", "yy")
_MAX_LIST = 6


def _g(v) -> str:
    return f"{float(v):g}"


def _list(items) -> str:
    items = list(items)
    more = f" and {len(items) - _MAX_LIST} more" if len(items) > _MAX_LIST else ""
    return ", ".join(str(i) for i in items[:_MAX_LIST]) + more


def _axis(name, value, unit):
    """A table axis: 1-D, non-empty, finite, >= 0, strictly ascending."""
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_)):
        value = [value]
    a = real_array(name, value, nonneg=True)
    if a.ndim != 1 or a.size == 0:
        raise RotoridError(f"{name} must be a non-empty 1-D array of {unit}, got shape {a.shape}")
    d = np.diff(a)
    if np.any(d == 0):
        i = int(np.nonzero(d == 0)[0][0])
        raise RotoridError(f"{name} has the value {_g(a[i])} twice (indices {i} and {i + 1}); every grid value "
                           "must appear once")
    if np.any(d < 0):
        i = int(np.nonzero(d < 0)[0][0])
        raise RotoridError(f"{name} must be ascending: {name}[{i}] = {_g(a[i])} > {name}[{i + 1}] = "
                           f"{_g(a[i + 1])}")
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


def _block(name, value, ns, nf, unit):
    a = real_array(name, value)
    if a.shape != (ns, nf, 2, 2):
        raise RotoridError(f"{name} has shape {a.shape}, expected ({ns}, {nf}, 2, 2) = [speed, frequency, i, j] "
                           f"over x, y, in {unit}")
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


def _weights(grid, p):
    """Lower node index, upper node index and weight of the upper node of points p inside grid
    (p already clipped to the grid's range); one node: the axis is constant."""
    n = grid.size
    if n == 1:
        z = np.zeros(p.shape, dtype=int)
        return z, z, np.zeros(p.shape)
    i = np.clip(np.searchsorted(grid, p, side="right") - 1, 0, n - 2)
    t = np.clip((p - grid[i]) / (grid[i + 1] - grid[i]), 0.0, 1.0)
    return i, i + 1, t


@dataclass(frozen=True, eq=False, repr=False)
class BearingTable:
    """Bearing force coefficients tabulated over running speed and excitation frequency.

    Parameters
    ----------
    speed_rpm : array_like, shape (ns,)
        Running speeds (rpm), >= 0, strictly ascending. One speed: the coefficients do not depend
        on speed (any speed is accepted).
    freq : array_like, shape (nf,)
        The frequency axis, >= 0, strictly ascending: excitation frequencies in Hz
        (``freq_axis="hz"``) or ratios excitation / running frequency (``freq_axis="ratio"``).
        One value: the coefficients do not depend on frequency (any frequency is accepted).
    k : array_like, shape (ns, nf, 2, 2)
        Stiffness (N/m) over (x, y) at every node: ``k[i, j]`` at ``speed_rpm[i]``, ``freq[j]``.
    c : array_like, shape (ns, nf, 2, 2)
        Damping (N s/m).
    m : array_like, shape (ns, nf, 2, 2), optional
        Added mass (kg); None (default) is zero.
    freq_axis : {"hz", "ratio"}
        What ``freq`` holds (default "hz").
    name : str
        A label used in messages (default "").

    The arrays are stored as read-only float copies; use the properties :attr:`freq_hz` /
    :attr:`freq_ratio` to get the frequency axis by its kind.

    Raises
    ------
    RotoridError
        Wrong shapes or types, NaN or inf, negative, repeated or non-ascending axis values, an
        unknown ``freq_axis``.

    Examples
    --------
    Two speeds, two frequencies, a stiffness growing with speed, isotropic and without
    cross-coupling:

    >>> import numpy as np
    >>> from rotorid.support.tpjb import BearingTable
    >>> eye = np.eye(2)
    >>> k = np.array([[1e7 * eye, 1e7 * eye], [2e7 * eye, 2e7 * eye]])
    >>> c = np.full((2, 2, 2, 2), 0.0) + 3e3 * eye
    >>> t = BearingTable([1000.0, 3000.0], [0.0, 100.0], k, c, name="FPJB")
    >>> t
    BearingTable('FPJB': 2 speeds 1000..3000 rpm x 2 freq_hz 0..100 Hz)
    >>> K, C = t.coefficients(2000.0, 50.0)
    >>> float(K[0, 0, 0]), float(C[0, 1, 1])
    (15000000.0, 3000.0)
    """

    speed_rpm: np.ndarray
    freq: np.ndarray
    k: np.ndarray
    c: np.ndarray
    m: np.ndarray | None = None
    freq_axis: str = "hz"
    name: str = ""

    def __post_init__(self):
        name = text("name", self.name)
        axis = self.freq_axis
        if not isinstance(axis, str) or axis.strip().lower() not in FREQ_AXES:
            raise RotoridError(f"freq_axis must be one of {list(FREQ_AXES)}, got {axis!r}")
        axis = axis.strip().lower()
        s = _axis("speed_rpm", self.speed_rpm, "rpm")
        f = _axis("freq_hz" if axis == "hz" else "freq_ratio", self.freq, "Hz" if axis == "hz" else "ratios")
        ns, nf = s.size, f.size
        k = _block("k", self.k, ns, nf, "N/m")
        c = _block("c", self.c, ns, nf, "N s/m")
        if self.m is None:
            m = np.zeros((ns, nf, 2, 2))
            m.setflags(write=False)
        else:
            m = _block("m", self.m, ns, nf, "kg")
        for key, v in (("name", name), ("freq_axis", axis), ("speed_rpm", s), ("freq", f), ("k", k), ("c", c),
                       ("m", m)):
            object.__setattr__(self, key, v)

    # ---------------------------------------------------------------------------------------------

    def __repr__(self) -> str:
        s, f = self.speed_rpm, self.freq
        unit = " Hz" if self.freq_axis == "hz" else ""
        mass = ", with added mass" if np.any(self.m != 0) else ""
        return (f"BearingTable({self.name!r}: {s.size} speed{'s' if s.size > 1 else ''} "
                f"{_g(s[0])}..{_g(s[-1])} rpm x {f.size} freq_{self.freq_axis} {_g(f[0])}..{_g(f[-1])}{unit}"
                f"{mass})")

    @property
    def freq_hz(self) -> np.ndarray | None:
        """The frequency axis (Hz) of a ``freq_axis="hz"`` table; None for a ratio table."""
        return self.freq if self.freq_axis == "hz" else None

    @property
    def freq_ratio(self) -> np.ndarray | None:
        """The frequency axis (excitation / running frequency) of a ``freq_axis="ratio"`` table;
        None for a Hz table."""
        return self.freq if self.freq_axis == "ratio" else None

    # ---------------------------------------------------------------------------------------------

    def _points(self, speed_rpm, freq_hz):
        from .sfd import MAX_FREQ_HZ

        s = real_array("speed_rpm", speed_rpm, nonneg=True)
        f = real_array("freq_hz", freq_hz, nonneg=True)
        if np.any(f > MAX_FREQ_HZ) or np.any(s > 60.0 * MAX_FREQ_HZ):
            raise RotoridError(f"{self._where()}: freq_hz up to {np.max(f):.3g} Hz or speed_rpm up to {np.max(s):.3g} "
                               f"rpm is beyond {MAX_FREQ_HZ:g} Hz (a unit error?)")
        try:
            s, f = np.broadcast_arrays(np.atleast_1d(s), np.atleast_1d(f))
        except ValueError:
            raise RotoridError(f"speed_rpm (shape {np.shape(speed_rpm)}) and freq_hz (shape {np.shape(freq_hz)}) "
                               "do not broadcast to the same points") from None
        if s.ndim != 1 or s.size == 0:
            raise RotoridError(f"speed_rpm and freq_hz must be scalars or 1-D arrays of points, got shape {s.shape}")
        return np.array(s, dtype=float), np.array(f, dtype=float)

    def _where(self):
        return f"BearingTable {self.name!r}" if self.name else "BearingTable"

    def _ratio(self, s, f):
        zero = s == 0
        if np.any(zero):
            i = np.nonzero(zero)[0]
            raise RotoridError(f"{self._where()} tabulates freq_ratio (excitation / running frequency), which is "
                               f"undefined at speed 0 rpm: point(s) {_list(i.tolist())}")
        return f / (s / 60.0)

    def _inside(self, grid, p):
        """p clipped to grid's range, and the mask of points outside it (beyond the tolerance)."""
        if grid.size == 1:
            return p, np.zeros(p.shape, bool)
        lo, hi = grid[0], grid[-1]
        tol = RANGE_TOLERANCE * max(abs(lo), abs(hi))
        out = (p < lo - tol) | (p > hi + tol)
        return np.clip(p, lo, hi), out

    def _interp(self, s, x, f):
        """K, C, M (n, 2, 2) at speeds s and frequency-axis values x (Hz or ratio); f (Hz) for
        messages."""
        sc, out_s = self._inside(self.speed_rpm, s)
        xc, out_x = self._inside(self.freq, x)
        out = out_s | out_x
        if np.any(out):
            idx = np.nonzero(out)[0]
            unit = " Hz" if self.freq_axis == "hz" else ""

            def pt(i):
                r = "" if self.freq_axis == "hz" else f" = ratio {_g(x[i])}"
                return f"point {i} (speed {_g(s[i])} rpm, freq {_g(f[i])} Hz{r})"

            rng = []
            if self.speed_rpm.size > 1:
                rng.append(f"speed_rpm {_g(self.speed_rpm[0])}..{_g(self.speed_rpm[-1])} rpm")
            if self.freq.size > 1:
                rng.append(f"freq_{self.freq_axis} {_g(self.freq[0])}..{_g(self.freq[-1])}{unit}")
            raise RotoridError(f"{self._where()}: {idx.size} point(s) outside the table (no extrapolation): "
                               f"{_list(pt(int(i)) for i in idx)}; the table covers {' and '.join(rng)}")
        i0, i1, ts = _weights(self.speed_rpm, sc)
        j0, j1, tf = _weights(self.freq, xc)
        w00 = ((1 - ts) * (1 - tf))[:, None, None]
        w01 = ((1 - ts) * tf)[:, None, None]
        w10 = (ts * (1 - tf))[:, None, None]
        w11 = (ts * tf)[:, None, None]

        def at(a):
            return w00 * a[i0, j0] + w01 * a[i0, j1] + w10 * a[i1, j0] + w11 * a[i1, j1]

        return at(self.k), at(self.c), at(self.m)

    def _kcm(self, speed_rpm, freq_hz):
        s, f = self._points(speed_rpm, freq_hz)
        x = f if self.freq_axis == "hz" else self._ratio(s, f)
        return (f,) + self._interp(s, x, f)

    # ---------------------------------------------------------------------------------------------

    def impedance(self, speed_rpm, freq_hz) -> np.ndarray:
        """Impedance Z = K + j w C - w^2 M (w = 2 pi freq_hz) at points (speed, frequency).

        K, C and M are interpolated separately (bilinear on the table's grid); Z is then formed
        at each point's own frequency.

        Parameters
        ----------
        speed_rpm : float or array_like
            Running speed of each point (rpm, >= 0; > 0 for a ratio table).
        freq_hz : float or array_like
            Excitation frequency of each point (Hz, >= 0). ``speed_rpm`` and ``freq_hz`` broadcast
            to the same n points (1-D).

        Returns
        -------
        ndarray of complex, shape (n, 2, 2)
            N/m over (x, y): the force on the journal F = -Z X for a motion X e^{j w t}.

        Raises
        ------
        RotoridError
            Points outside the table (named, with the table's range), negative, NaN or
            non-numeric input, speed 0 on a ratio table.

        Examples
        --------
        >>> import numpy as np
        >>> from rotorid.support.tpjb import BearingTable
        >>> one = np.ones((1, 1, 2, 2)) * np.eye(2)
        >>> t = BearingTable([3000.0], [50.0], 1e7 * one, 1e3 * one, m=0.5 * one)
        >>> z = t.impedance(3000.0, [10.0, 20.0])     # single node: constant coefficients
        >>> w = 2 * np.pi * 10.0
        >>> bool(np.isclose(z[0, 0, 0], 1e7 + 1j * w * 1e3 - w**2 * 0.5))
        True
        >>> t2 = BearingTable([1000.0, 2000.0], [0.0, 50.0], 1e7 * np.ones((2, 2, 2, 2)),
        ...                   np.zeros((2, 2, 2, 2)), name="b")
        >>> t2.impedance(2500.0, 10.0)  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        rotorid.errors.RotoridError: BearingTable 'b': 1 point(s) outside the table (no extrapolation): ...
        >>> try:
        ...     t2.impedance(2500.0, 10.0)
        ... except ValueError as exc:
        ...     print(str(exc).split(": ", 2)[2])
        point 0 (speed 2500 rpm, freq 10 Hz); the table covers speed_rpm 1000..2000 rpm and freq_hz 0..50 Hz
        """
        f, k, c, m = self._kcm(speed_rpm, freq_hz)
        w = (2.0 * np.pi * f)[:, None, None]
        return k + 1j * w * c - w**2 * m

    def coefficients(self, speed_rpm, freq_hz) -> tuple:
        """Stiffness and damping (K, C) at points (speed, frequency), interpolated bilinearly.

        C is the table's damping only: an added mass M is not folded into K or C (use
        :meth:`impedance` for Z = K + j w C - w^2 M; an identification without a mass term
        estimates Re Z = K - w^2 M as its stiffness).

        Parameters
        ----------
        speed_rpm, freq_hz : float or array_like
            As in :meth:`impedance`.

        Returns
        -------
        K : ndarray, shape (n, 2, 2)
            Stiffness (N/m).
        C : ndarray, shape (n, 2, 2)
            Damping (N s/m).

        Raises
        ------
        RotoridError
            As :meth:`impedance`.

        Examples
        --------
        Midway between two speeds and two frequencies the stiffness is the mean of the four
        nodes:

        >>> import numpy as np
        >>> from rotorid.support.tpjb import BearingTable
        >>> k = np.zeros((2, 2, 2, 2))
        >>> k[:, :, 0, 0] = [[1e6, 2e6], [3e6, 6e6]]
        >>> t = BearingTable([0.0, 1000.0], [0.0, 40.0], k, np.zeros((2, 2, 2, 2)))
        >>> K, C = t.coefficients(500.0, 20.0)
        >>> float(K[0, 0, 0])
        3000000.0
        """
        _, k, c, _ = self._kcm(speed_rpm, freq_hz)
        return k, c

    def synchronous(self, speed_rpm) -> tuple:
        """Synchronous stiffness and damping (K, C): the table at freq_hz = speed_rpm / 60
        (ratio 1 on a ratio table).

        These are what an imbalance-response identification (the report's section 4) estimates,
        when the table has no added mass (with one, such an identification sees K - w^2 M).

        Parameters
        ----------
        speed_rpm : float or array_like (n,)
            Running speeds (rpm, >= 0; > 0 for a ratio table).

        Returns
        -------
        K, C : ndarray, shape (n, 2, 2)
            As :meth:`coefficients`.

        Examples
        --------
        >>> import numpy as np
        >>> from rotorid.support.tpjb import BearingTable
        >>> k = np.zeros((2, 3, 2, 2))
        >>> k[:, :, 0, 0] = [[1e6, 2e6, 3e6], [5e6, 6e6, 7e6]]     # ratios 0.5, 1, 2
        >>> t = BearingTable([1000.0, 3000.0], [0.5, 1.0, 2.0], k, np.zeros_like(k), freq_axis="ratio")
        >>> K, C = t.synchronous([1000.0, 2000.0])
        >>> K[:, 0, 0].tolist()
        [2000000.0, 4000000.0]
        """
        s = real_array("speed_rpm", speed_rpm, nonneg=True)
        s = np.array(np.atleast_1d(s), dtype=float)
        if s.ndim != 1:
            raise RotoridError(f"speed_rpm must be a scalar or a 1-D array of speeds, got shape {s.shape}")
        if s.size == 0:
            raise RotoridError("speed_rpm is empty")
        f = s / 60.0
        if self.freq_axis == "hz":
            _, k, c, _ = self._kcm(s, f)
        else:
            self._ratio(s, f)   # speed 0 refused
            k, c, _ = self._interp(s, np.ones_like(s), f)
        return k, c


# -------------------------------------------------------------------------------------------------
# loading from a file

_TEXT_EXT = {".csv", ".txt", ".tsv", ".dat"}
_EXCEL_EXT = {".xlsx", ".xlsm"}
_HEADER = re.compile(r"^\s*([A-Za-z_]+)\s*(?:[(\[]\s*([^)\]]*?)\s*[)\]])?\s*$")
_COEFS = [p + ij for p in "kcm" for ij in _IJ]
_KNOWN = {"speed_rpm", "freq_hz", "freq_ratio", *_COEFS}
_SPELL = {"speed_rpm": "speed_rpm", "freq_hz": "freq_hz", "freq_ratio": "freq_ratio",
          **{p + ij: p.upper() + ij for p in "kcm" for ij in _IJ}}
_ACCEPTED = ("speed_rpm, freq_hz (or freq_ratio with freq_axis='ratio'), Kxx Kxy Kyx Kyy, Cxx Cxy Cyx Cyy, "
             "optionally Mxx Mxy Myx Myy (any case, each optionally followed by its unit in () or [])")


def _decode(p: Path) -> str:
    from ..io._common import decode_text

    return decode_text(p.read_bytes())


def _blank(v) -> bool:
    if v is None:
        return True
    if isinstance(v, float) and math.isnan(v):
        return True
    return isinstance(v, str) and not v.strip()


def _read_text(p: Path):
    """Header cells, data rows (lists of cells) and their line numbers; '#' lines and blank
    lines are skipped, the first other line is the header."""
    lines = [(n + 1, ln) for n, ln in enumerate(_decode(p).splitlines())
             if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise RotoridError(f"{p}: the file is empty (no header row)")
    head_no, head = lines[0]

    def split(ln, sep):
        try:
            row = next(csv.reader([ln], delimiter=sep, quotechar='"', skipinitialspace=True), [])
        except csv.Error:
            row = ln.split(sep)
        return [c.strip() for c in row]

    # the separator is the one that splits the header into the most recognised column names
    best = max(("\t", ";", ","), key=lambda sep: (sum(_name(c) in _KNOWN for c in split(head, sep)),
                                                  len(split(head, sep))))
    cells = split(head, best)
    rows, nos = [], []
    for no, ln in lines[1:]:
        row = split(ln, best)
        while len(row) > len(cells) and row[-1] == "":
            row.pop()
        if len(row) != len(cells):
            raise RotoridError(f"{p}: line {no} has {len(row)} fields, the header (line {head_no}) {len(cells)} "
                               f"(separator {best!r}); a missing or extra field would shift the columns")
        rows.append(row)
        nos.append(no)
    return cells, rows, nos, str(p), f"line {head_no}", "line"


def _read_excel(p: Path, sheet):
    from ..io._common import read_excel_sheet

    raw, sh, _ = read_excel_sheet(p, sheet)
    where = f"{p} (sheet {sh!r})"
    grid = [(n + 1, list(r)) for n, r in enumerate(raw.itertuples(index=False, name=None))
            if not all(_blank(v) for v in r)]
    if not grid:
        raise RotoridError(f"{where}: the sheet is empty (no header row)")
    head_no, head = grid[0]
    cells = ["" if _blank(v) else str(v).strip() for v in head]
    return cells, [r for _, r in grid[1:]], [n for n, _ in grid[1:]], where, f"row {head_no}", "row"


def _name(cell) -> str | None:
    m = _HEADER.match(str(cell))
    return m.group(1).lower() if m else None


def _number(v, col, where, what, no):
    if isinstance(v, (bool, np.bool_)):
        x = None
    elif isinstance(v, (int, float, np.integer, np.floating)):
        x = float(v)
    else:
        s = str(v).strip()
        try:
            x = float(s) if s else None
        except ValueError:
            x = None
    if x is None or not math.isfinite(x):
        shown = "a blank cell" if _blank(v) else repr(v)
        raise RotoridError(f"{where}: column {col!r}, {what} {no} has {shown}; every cell of the table's columns "
                           "must be a finite number")
    return x


def _unit_check(where, col, unit_in_header, quantity, unit_arg, argname=None):
    """A unit written in a column header must be the unit the argument (``argname``) says the
    column holds, or the column name's own unit (``argname`` None)."""
    if unit_in_header is None or unit_in_header == "":
        return
    try:
        fh = units.factor(unit_in_header, quantity)
    except RotoridError as exc:
        raise RotoridError(f"{where}: column {col!r}: {exc}") from None
    fa = units.factor(unit_arg, quantity)
    if math.isclose(fh, fa, rel_tol=1e-12):
        return
    if argname is None:
        raise RotoridError(f"{where}: column {col!r} must be in {unit_arg} (its name says so), not {unit_in_header}")
    raise RotoridError(f"{where}: column {col!r} is in {unit_in_header} but {argname}={unit_arg!r}; pass "
                       f"{argname}={unit_in_header!r} (the header unit is checked, not applied)")


def load_bearing_table(path, *, stiffness_unit="N/m", damping_unit="N*s/m", freq_axis="hz", sheet=None,
                       mass_unit="kg", name=None) -> BearingTable:
    """Read a bearing code's coefficient table: one row per (speed, frequency) grid node.

    Accepted files: delimited text (``.csv``, ``.txt``, ``.tsv``, ``.dat``; separator ``,``
    ``;`` or tab, decimal point; lines starting with ``#`` and blank lines are skipped and the
    first other line is the header) or Excel (``.xlsx``, ``.xlsm``, needs pandas and openpyxl;
    the first non-empty row of the sheet is the header).

    Columns (any order; names matched case-insensitively; other columns are ignored):

    - ``speed_rpm`` (rpm);
    - ``freq_hz`` (Hz) with ``freq_axis="hz"``, or ``freq_ratio`` (excitation / running
      frequency) with ``freq_axis="ratio"``;
    - ``Kxx``, ``Kxy``, ``Kyx``, ``Kyy`` in ``stiffness_unit``; ``Cxx``, ``Cxy``, ``Cyx``,
      ``Cyy`` in ``damping_unit``;
    - optionally all four of ``Mxx``, ``Mxy``, ``Myx``, ``Myy`` in ``mass_unit`` (else M = 0).

    A name may be followed by a unit in parentheses or brackets, ``Kxx (N/m)``,
    ``Cyy [lbf*s/in]``, ``speed_rpm (rpm)``, ``freq_hz [Hz]``, ``freq_ratio (-)``. Such a unit is
    checked against the argument (``stiffness_unit`` etc.) and a mismatch raises: the arguments
    decide the conversion, the header only guards it. Nothing else is recognised (no ``K_xx``,
    no ``Speed``), and a name may appear only once (``Kxx`` and ``Kxx (N/m)`` together raise).

    The rows must fill the full rectangular grid: every frequency (or ratio) value at every
    speed, each exactly once. Grid values are matched exactly as written.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    stiffness_unit, damping_unit : str
        Units of the K and C columns (:mod:`rotorid.units`, e.g. "N/m", "MN/m", "lbf/in";
        "N*s/m", "lbf*s/in").
    freq_axis : {"hz", "ratio"}
        Which frequency column the table has (see :class:`BearingTable`).
    sheet : str or int, optional
        Excel sheet (name or index; default the first). Not allowed for text files.
    mass_unit : str
        Unit of the optional M columns (default "kg").
    name : str, optional
        The table's name (default the file name without extension).

    Returns
    -------
    BearingTable
        In SI units.

    Raises
    ------
    RotoridError
        Missing, ambiguous or non-numeric columns, blank cells, NaN or inf, unknown units or a
        header unit other than the argument's, a grid node missing or given twice (named),
        negative speeds or frequencies, an unreadable file.

    Examples
    --------
    >>> import os, tempfile
    >>> from rotorid.support.tpjb import load_bearing_table
    >>> rows = ["speed_rpm,freq_hz,Kxx [lbf/in],Kxy,Kyx,Kyy,Cxx,Cxy,Cyx,Cyy"]
    >>> for s in (1000, 2000):
    ...     for f in (0, 50):
    ...         rows.append(f"{s},{f},{s * 10},0,0,{s * 10},5,0,0,5")
    >>> d = tempfile.mkdtemp()
    >>> p = os.path.join(d, "fpjb.csv")
    >>> with open(p, "w") as fh:
    ...     _ = fh.write("\\n".join(rows) + "\\n")
    >>> t = load_bearing_table(p, stiffness_unit="lbf/in", damping_unit="lbf*s/in")
    >>> t
    BearingTable('fpjb': 2 speeds 1000..2000 rpm x 2 freq_hz 0..50 Hz)
    >>> round(float(t.k[0, 0, 0, 0]))          # 10000 lbf/in in N/m
    1751268
    """
    p = _path_arg("path", path)
    stiffness_unit = text("stiffness_unit", stiffness_unit)
    damping_unit = text("damping_unit", damping_unit)
    mass_unit = text("mass_unit", mass_unit)
    for u, q in ((stiffness_unit, "stiffness"), (damping_unit, "damping"), (mass_unit, "mass")):
        units.factor(u, q)   # unknown units, or a unit of another quantity, fail before the file is read
    if not isinstance(freq_axis, str) or freq_axis.strip().lower() not in FREQ_AXES:
        raise RotoridError(f"freq_axis must be one of {list(FREQ_AXES)}, got {freq_axis!r}")
    axis = freq_axis.strip().lower()
    name = text("name", name, allow_none=True)
    ext = p.suffix.lower()
    if ext not in _TEXT_EXT | _EXCEL_EXT:
        raise RotoridError(f"{p}: unknown file type {p.suffix!r}; give a delimited text file "
                           f"({', '.join(sorted(_TEXT_EXT))}) or an Excel workbook ({', '.join(sorted(_EXCEL_EXT))})")
    if not p.is_file():
        raise RotoridError(f"no such file: {p}")
    if ext in _TEXT_EXT:
        if sheet is not None:
            raise RotoridError(f"sheet={sheet!r} applies to Excel workbooks only; {p} is a text file")
        cells, rows, nos, where, head_at, what = _read_text(p)
    else:
        cells, rows, nos, where, head_at, what = _read_excel(p, sheet)

    # which cell is which column
    found = {}
    for j, cell in enumerate(cells):
        m = _HEADER.match(str(cell))
        if not m or m.group(1).lower() not in _KNOWN:
            continue
        key = m.group(1).lower()
        if key in found:
            raise RotoridError(f"{where}: the header ({head_at}) has column {_SPELL[key]} twice, "
                               f"{cells[found[key][0]]!r} and {cell!r}; keep one")
        found[key] = (j, m.group(2))
    fcol = "freq_hz" if axis == "hz" else "freq_ratio"
    other = "freq_ratio" if axis == "hz" else "freq_hz"
    need = ["speed_rpm", fcol] + [p_ + ij for p_ in "kc" for ij in _IJ]
    missing = [_SPELL[c] for c in need if c not in found]
    if fcol in [c.lower() for c in missing] and other in found:
        raise RotoridError(f"{where}: the table has a {other} column, not {fcol}: pass freq_axis="
                           f"{'ratio' if axis == 'hz' else 'hz'!r}")
    if missing:
        raise RotoridError(f"{where}: no column(s) {missing}; the header ({head_at}) has "
                           f"{[c for c in cells if c]}; accepted: {_ACCEPTED}")
    masses = [c for c in ("m" + ij for ij in _IJ) if c in found]
    if masses and len(masses) != 4:
        raise RotoridError(f"{where}: added mass columns {[_SPELL[c] for c in masses]} without "
                           f"{[_SPELL['m' + ij] for ij in _IJ if 'm' + ij not in found]}: give all four or none")
    # header units guard the arguments
    for key, (j, unit) in found.items():
        col = cells[j]
        if key == "speed_rpm":
            _unit_check(where, col, unit, "speed", "rpm")
        elif key == "freq_hz":
            _unit_check(where, col, unit, "frequency", "Hz")
        elif key == "freq_ratio":
            if unit not in (None, "", "-"):
                raise RotoridError(f"{where}: column {col!r}: a frequency ratio has no unit (write freq_ratio "
                                   "or freq_ratio (-))")
        elif key[0] == "k":
            _unit_check(where, col, unit, "stiffness", stiffness_unit, "stiffness_unit")
        elif key[0] == "c":
            _unit_check(where, col, unit, "damping", damping_unit, "damping_unit")
        elif masses:
            _unit_check(where, col, unit, "mass", mass_unit, "mass_unit")
    if not rows:
        raise RotoridError(f"{where}: no data rows after the header ({head_at})")

    used = need + masses
    vals = {c: np.array([_number(r[found[c][0]] if found[c][0] < len(r) else None, cells[found[c][0]], where,
                                 what, no) for r, no in zip(rows, nos)]) for c in used}
    nos = np.asarray(nos)
    for c in ("speed_rpm", fcol):
        neg = vals[c] < 0
        if np.any(neg):
            raise RotoridError(f"{where}: column {cells[found[c][0]]!r} must be >= 0: {what}(s) "
                               f"{_list(nos[neg].tolist())} (e.g. {_g(vals[c][neg][0])})")

    # the grid
    s, f = vals["speed_rpm"], vals[fcol]
    speeds, freqs = np.unique(s), np.unique(f)
    i, j = np.searchsorted(speeds, s), np.searchsorted(freqs, f)
    lin = i * freqs.size + j
    count = np.bincount(lin, minlength=speeds.size * freqs.size)
    funit = " Hz" if axis == "hz" else ""
    if np.any(count > 1):
        dup = [int(q) for q in np.nonzero(count > 1)[0]]
        txt = "; ".join(f"speed {_g(speeds[q // freqs.size])} rpm, {fcol} {_g(freqs[q % freqs.size])}{funit} on "
                        f"{what}s {_list(nos[lin == q].tolist())}" for q in dup[:_MAX_LIST])
        raise RotoridError(f"{where}: grid node(s) given more than once: {txt}")
    if np.any(count == 0):
        gone = [int(q) for q in np.nonzero(count == 0)[0]]
        txt = _list(f"(speed {_g(speeds[q // freqs.size])} rpm, {fcol} {_g(freqs[q % freqs.size])}{funit})"
                    for q in gone)
        raise RotoridError(f"{where}: the rows do not fill the rectangular grid of {speeds.size} speeds x "
                           f"{freqs.size} {fcol} values; missing: {txt}")

    def block(prefix, unit, quantity):
        a = np.empty((speeds.size, freqs.size, 2, 2))
        for ij in _IJ:
            a[i, j, "xy".index(ij[0]), "xy".index(ij[1])] = units.to_si(vals[prefix + ij], unit, quantity)
        return a

    return BearingTable(speeds, freqs, block("k", stiffness_unit, "stiffness"), block("c", damping_unit, "damping"),
                        block("m", mass_unit, "mass") if masses else None,
                        freq_axis=axis, name=p.stem if name is None else name)
