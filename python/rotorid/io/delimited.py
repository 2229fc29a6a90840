"""Delimited text files (``.csv``, ``.txt``, ``.asc``; ``.dat`` with ``fmt="csv"``) as DAQ
software exports them, read with pandas' C parser.

Layout

* a preamble of any number of lines (DAQ name, date, comments) may precede the header. The
  header is found automatically as the last non-numeric line before the first block of 3 or
  more numeric lines with one field count, and must have that many fields; ``skip_rows=``
  (lines before the header) overrides. A preamble
  line like ``Sample rate: 10240 Hz`` (also ``Sampling rate``, ``fs``, ``Rate``, with ``Hz``,
  ``kHz``, ``S/s``) gives the sample rate when there is no time column and is checked against
  the time column when there is one. The preamble lines are kept in meta ``"preamble"``.
* the separator is one of ``,`` ``;`` tab and runs of whitespace, the decimal mark ``.`` or
  ``,``, both detected (every pair is tried on the first lines); ``sep=`` and ``decimal=``
  override, and must be given when the file reads two ways (e.g. ``0,5`` lines without a
  header: two integer columns, or one with decimal commas?).
* a file whose data lines are not all numeric (e.g. a text column) is read the simple way:
  header on the first line (after ``skip_rows``), separator the most frequent of ``,`` ``;``
  tab in it. A non-numeric cell matters only if its column is used; the error names its line.
* a line with fewer fields than the header raises (a truncated file), naming the line.
* a header cell may carry a unit as ``name [unit]`` or ``name (unit)`` (the latter only for a
  unit rotorid knows); ``name_unit`` is not split. A line of units under the names is read too.
  Without a header the columns are named ``column 1``, ``column 2``...
* a column named ``t``, ``time``, ``zeit``, ``time_s``, ``time_ms`` or ``time_us`` (any case,
  e.g. ``Time (s)``, ``Time [ms]``; units s, ms, us, µs) is the time axis, or the one
  ``time_column=`` names (``time_column=False``: none). Its times must lie on a uniform grid
  within 1 % of a step (printed rounding is fine); fs and t0 come from the least-squares grid.
"""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np

from ..errors import RotoridError
from ..recording import Recording
from ._common import _atomic_write, _cannot, _describe, _lab_columns, _Raw, _Read, _same_rate, _time_base, \
    _time_factor, _time_name_unit
from ._sniff import _NUMBER, _WS, _Layout, _layout, _stated_rate

__all__ = ["save_csv"]


def save_csv(rec: Recording, path, units=None, names=None) -> None:
    """Write ``rec`` as CSV: a ``time [s]`` column, then ``name [unit]`` columns (17 significant digits).

    Parameters
    ----------
    rec : Recording
    path : str or path-like
    units : dict, optional
        {channel: unit to write it in} (default: the recording's units, SI)
    names : dict, optional
        {channel: column name to write it under} (default: the channel names)
    """
    cols = _lab_columns(rec, path, names, units, forbid=",;\t[]\"")
    header = ["time [s]"] + [f"{lab} [{unit}]" if unit else lab for lab, unit, _ in cols]
    table = np.column_stack([rec.t] + [d for _, _, d in cols])
    with _atomic_write(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        fh.write(",".join(header) + "\n")
        np.savetxt(fh, table, fmt="%.17g", delimiter=",")


class _Lines:
    """File line numbers of data rows (blank lines are skipped by the parser), found on demand."""

    def __init__(self, path, lay: _Layout, encoding: str):
        self.path, self.lay, self.encoding = path, lay, encoding

    def scan(self, rows):
        """{row: (line number, field count)} for the given data rows."""
        want, out = set(rows), {}
        last = max(want)
        with open(self.path, encoding=self.encoding, newline="") as fh:
            row = -1
            for number, line in enumerate(fh, 1):
                if number <= self.lay.data or not line.strip():
                    continue
                row += 1
                if row in want:
                    line = line.rstrip("\r\n").replace("\r", " ").replace("\n", " ")
                    n = len(line.split()) if self.lay.sep == _WS else \
                        len(next(csv.reader([line], delimiter=self.lay.sep), []))
                    out[row] = (number, n)
                if row >= last:
                    break
        return out


def _read_table(path, lay: _Layout, encoding: str):
    import pandas as pd

    kw = dict(sep=lay.pandas_sep, decimal=lay.decimal, header=None, names=list(range(lay.k)), index_col=False,
              skiprows=lay.data, engine="c", encoding=encoding, skip_blank_lines=True)
    try:
        try:
            return pd.read_csv(path, dtype=np.float64, **kw), True
        except (ValueError, TypeError) as exc:
            if isinstance(exc, pd.errors.ParserError):
                raise
            return pd.read_csv(path, **kw), False  # some cell is not a number: find it per column
    except pd.errors.ParserError as exc:
        m = re.search(r"Expected (\d+) fields in line (\d+), saw (\d+)", str(exc))
        if m:
            raise _cannot(path, "csv", f"line {m.group(2)} has {m.group(3)} fields, the "
                                       f"{'header has' if lay.header is not None else 'data have'} {lay.k}") from None
        raise _cannot(path, "csv", _describe(exc)) from None
    except Exception as exc:  # UnicodeDecodeError, OSError, MemoryError ...
        raise _cannot(path, "csv", _describe(exc)) from None


def _columns(path, lay, encoding, df, numeric):
    """[(name, unit, float64 data or None, problem or None)], empty trailing columns dropped."""
    lines = _Lines(path, lay, encoding)
    out = []
    for j in range(lay.k):
        col, problem = df[j], None
        if numeric or col.dtype.kind in "iuf":
            data = col.to_numpy(dtype=np.float64)
        else:
            import pandas as pd

            coerced = pd.to_numeric(col, errors="coerce")
            bad = (coerced.isna() & col.notna()).to_numpy()
            if bad.any():
                row = int(np.argmax(bad))
                cell = str(col.iloc[row])
                number = lines.scan([row]).get(row, (None,))[0]
                where = f"line {number}" if number else f"data row {row + 1}"
                problem = f"cell {cell!r} on {where} is not a number"
                other = "," if lay.decimal == "." else "."
                if _NUMBER[other].fullmatch(cell.strip()):
                    problem += f" (decimal {other!r}? pass decimal={other!r})"
                data = None
            else:
                data = coerced.to_numpy(dtype=np.float64)
        out.append([lay.names[j], lay.units[j], data, problem])
    # a separator ending every line gives an unnamed, empty last column
    if out and out[-1][0] == "" and out[-1][2] is not None and np.isnan(out[-1][2]).all():
        out.pop()
    names = [c[0] for c in out]
    if any(not n for n in names):
        raise _cannot(path, "csv", f"header has an empty column name (column {names.index('') + 1}): {names}")
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise _cannot(path, "csv", f"header names column(s) {dupes} more than once")
    # a line with fewer fields than the header leaves NaN in its last cells: find such lines
    nan_rows = set()
    for _, _, data, _ in out:
        if data is None:
            continue
        nan = np.isnan(data)
        if nan.any() and not nan.all():  # an empty column tells nothing about short lines
            rows = np.flatnonzero(nan)
            nan_rows.update(rows[:20].tolist() + [int(rows[-1])])
    if nan_rows:
        need = len(out)
        for row, (number, n) in sorted(lines.scan(sorted(nan_rows)[:40] + [max(nan_rows)]).items()):
            if n < need:
                what = "header has" if lay.header is not None else "data have"
                raise _cannot(path, "csv", f"line {number} has {n} field(s), the {what} {need}"
                                           + (" (the file ends there: truncated?)" if row == len(df) - 1 else ""))
    return out


def _time_column(path, cols, time_column):
    if time_column is False:
        return None
    if isinstance(time_column, str):
        hits = [c for c in cols if c[0] == time_column or c[0].lower() == time_column.strip().lower()]
        if not hits:
            raise RotoridError(f"{path}: time_column={time_column!r} is not a column; the columns are "
                               f"{[c[0] for c in cols]}")
        return hits[0]
    hits = [c for c in cols if _time_name_unit(c[0])[0]]
    if len(hits) > 1:
        raise RotoridError(f"{path}: several time columns {[c[0] for c in hits]}; keep one or pass time_column=")
    return hits[0] if hits else None


def _read_delimited(path: Path, skip_rows=None, sep=None, decimal=None, time_column=None) -> _Read:
    lay, encoding = _layout(path, skip_rows, sep, decimal)
    df, numeric = _read_table(path, lay, encoding)
    if len(df) == 0:
        raise _cannot(path, "csv", "it has a header but no data rows")
    cols = _columns(path, lay, encoding, df, numeric)
    stated = _stated_rate(path, lay)
    meta = {"preamble": [text for _, text in lay.preamble]} if lay.preamble else {}

    fs = t0 = None
    tcol = _time_column(path, cols, time_column)
    if tcol is not None:
        name, unit, data, problem = tcol
        where = f"{path}: time column {name!r}"
        if problem:
            raise RotoridError(f"{where}: {problem}")
        implied = _time_name_unit(name)[1]
        if unit and implied and _time_factor(unit, where) != _time_factor(implied, where):
            raise RotoridError(f"{where}: its name says {implied!r}, its unit {unit!r}")
        fs, t0 = _time_base(where, data * _time_factor(unit or implied, where))
        if stated and not _same_rate(stated[0], fs):
            raise RotoridError(f"{path}: the preamble states a sample rate of {stated[0]:.9g} Hz (line {stated[1]}: "
                               f"{stated[2]!r}), the time column {name!r} gives {fs:.9g} Hz")
        cols = [c for c in cols if c is not tcol]
    elif stated:
        fs = stated[0]
    raws = [_Raw(name, name, data, unit, fs, t0, problem) for name, unit, data, problem in cols]
    if not raws:
        raise _cannot(path, "csv", "it has no data column besides the time column")
    return _Read(raws, meta, address="its column name")
