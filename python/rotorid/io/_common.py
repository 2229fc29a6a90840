"""Shared pieces of the readers and writers: constants, messages, units in names, time axes,
atomic writes and the column table the lab writers share."""

from __future__ import annotations

import contextlib
import math
import os
import re
import sys
import uuid
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import units as _units
from ..errors import RotoridError
from ..recording import DISPLACEMENTS, KNOWN, Recording

def decode_text(raw: bytes) -> str:
    """Text of a lab file's bytes: UTF-8 (with or without a byte-order mark), else Windows-1252
    (what DAQ PCs write), else Latin-1 (which decodes anything)."""
    for encoding in ("utf-8-sig", "cp1252"):
        try:
            return raw.decode(encoding)
        except UnicodeDecodeError:
            continue
    return raw.decode("latin-1")


def read_excel_sheet(path, sheet):
    """(raw cells as an object DataFrame without header, sheet name, all sheet names) of one sheet
    of a workbook:
    ``sheet`` None (the first), an index or a name. Every cell is read as written: no NA guessing
    (a cell "n/a" stays text for the caller to report)."""
    import pandas as pd

    try:
        import openpyxl  # noqa: F401
    except ImportError:
        raise RotoridError(f"reading {path} needs openpyxl: pip install openpyxl (or export the table as CSV)") from None
    try:
        book = pd.ExcelFile(path, engine="openpyxl")
    except Exception as exc:  # openpyxl and zipfile raise many kinds for a damaged workbook
        raise RotoridError(f"cannot read {path} as an Excel workbook: {type(exc).__name__}: {exc}") from None
    with book:
        names = book.sheet_names
        if sheet is None:
            sh = names[0]
        elif isinstance(sheet, (int, np.integer)) and not isinstance(sheet, (bool, np.bool_)):
            if not 0 <= sheet < len(names):
                raise RotoridError(f"{path}: sheet index {sheet} out of range; the workbook has sheets {names}")
            sh = names[int(sheet)]
        elif str(sheet) in names:
            sh = str(sheet)
        else:
            raise RotoridError(f"{path}: no sheet {sheet!r}; the workbook has sheets {names}")
        return pd.read_excel(book, sheet_name=sh, header=None, dtype=object, na_filter=False), sh, names


FORMAT_NAME = "rotorid-recording"
FORMAT_VERSION = 1
#: values of load_recording's ``fmt``
FORMATS = ("native", "csv", "tdms", "uff58")
# ".dat" is deliberately absent: many DAQs (DIAdem, catman, LabVIEW) write binary .dat files;
# read a delimited-text .dat with fmt="csv"
_EXTENSIONS = {".npz": "native", ".csv": "csv", ".txt": "csv", ".asc": "csv", ".tdms": "tdms",
               ".uff": "uff58", ".unv": "uff58"}
_LABELS = {"native": "a rotorid recording (.npz)", "csv": "delimited text (CSV)", "tdms": "TDMS",
           "uff58": "UFF 58"}

#: physical quantity of each canonical channel (the units table's quantity names)
QUANTITY = {**{c: "length" for c in DISPLACEMENTS}, "force": "force", "kp": "voltage",
            **{c: "acceleration" for c in ("px1", "py1", "px2", "py2")}}

_RATE_RTOL = 1e-6   # two sample rates closer than this (relative) are the same rate
#: allowed deviation of a time-axis value from the uniform grid, as a fraction of the step: a DAQ
#: prints times rounded (9 significant digits, %.6f in ms, ...), and a timing error of 1 % of a
#: sample scatters 1X phases by far less than the noise; larger deviations are a non-uniform axis
_TIME_RTOL = 0.01
_TIMESTAMP_TICK = 1e-6  # absolute timestamps are commonly stored to the microsecond
#: time-axis units -> seconds
_TIME_UNITS = {"s": 1.0, "sec": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6, "μs": 1e-6}
#: names of a time axis (lower case, unit split off) -> the unit the name implies (None: from the file, else s)
_TIME_NAMES = {"t": None, "time": None, "zeit": None, "time_s": "s", "time_ms": "ms", "time_us": "us",
               "zeit_s": "s", "zeit_ms": "ms"}

_PACKAGE = __name__.rpartition(".")[0]


def _warn(message: str) -> None:
    """warnings.warn attributed to the first caller outside this package."""
    level, frame = 2, sys._getframe(1)  # stacklevel 2 is _warn's caller
    while frame is not None:
        name = frame.f_globals.get("__name__", "")
        if name != _PACKAGE and not name.startswith(_PACKAGE + "."):
            break
        frame, level = frame.f_back, level + 1
    warnings.warn(message, UserWarning, stacklevel=level)


def _cannot(path, fmt: str, reason) -> RotoridError:
    return RotoridError(f"cannot read {path} as {_LABELS[fmt]}: {reason}")


def _describe(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _positive_rate(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise RotoridError(f"{name} must be a number > 0, got {value!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise RotoridError(f"{name} must be a number > 0, got {value!r}")
    return v


def _same_rate(a: float, b: float, rtol: float = _RATE_RTOL) -> bool:
    return abs(a - b) <= rtol * max(abs(a), abs(b))


def _snap_rate(fs: float, rel_uncertainty: float) -> float:
    """The nearest whole-hertz rate if ``fs`` is that rate within the precision it was stored with."""
    k = round(fs)
    # (a margin of 1e-5 of the uncertainty: 51.2 kHz stored as 1.95313e-05 s lies exactly half a
    # last digit from 1/51200, 1.0000026 times the bound as computed from the stored value)
    if k > 0 and abs(fs - k) <= rel_uncertainty * fs * (1 + 1e-5):
        return float(k)
    return fs


def _json_default(obj):
    # meta may hold NumPy scalars or arrays; anything else is not JSON and is refused
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"{type(obj).__name__} is not JSON-serializable")


def _is_unit(text: str) -> bool:
    """Whether ``text`` is a unit rotorid knows (the units table or a time unit)."""
    if text.strip().lower() in _TIME_UNITS:
        return True
    try:
        _units.factor(text)
    except RotoridError:
        return False
    return True


_BRACKETS = re.compile(r"\s*(.*?)\s*\[\s*([^\[\]]*?)\s*\]\s*")
_PARENS = re.compile(r"\s*(.*?)\s*\(\s*([^()]*?)\s*\)\s*")


def _split_unit(cell: str) -> tuple[str, str | None]:
    """'x1 [mil]' -> ('x1', 'mil'); 'DE X (mil)' -> ('DE X', 'mil'); 'x1' -> ('x1', None).

    A unit in square brackets is always taken as one; a parenthesised suffix only when it is a
    unit rotorid knows, so that names like 'Prox (DE)' stay whole. 'name_unit' is never split.
    """
    m = _BRACKETS.fullmatch(cell)
    if m and m.group(1):
        return m.group(1), (m.group(2) or None)
    m = _PARENS.fullmatch(cell)
    if m and m.group(1) and m.group(2) and _is_unit(m.group(2)):
        return m.group(1), m.group(2)
    return cell.strip(), None


def _time_name_unit(name: str) -> tuple[bool, str | None]:
    """(is the bare name of a time axis, the unit its name implies)."""
    key = name.strip().lower()
    return key in _TIME_NAMES, _TIME_NAMES.get(key)


def _time_factor(unit: str | None, where: str) -> float:
    unit = unit or "s"
    f = _TIME_UNITS.get(unit.strip().lower())
    if f is None:
        raise RotoridError(f"{where}: unknown time unit {unit!r}; known: {list(_TIME_UNITS)}")
    return f


def _time_base(where: str, t: np.ndarray, *, tick: float = 0.0, kind: str = "column") -> tuple[float, float]:
    """Sample rate and start time of a time axis in seconds; its steps must be uniform.

    ``where`` names the axis for messages. Every time may lie off the least-squares uniform grid by
    at most 1 % of a step (the rounding of printed times; more is a missing sample, a restart or a
    clock jump), and rate and start come from that grid; ``tick`` (> 0 for absolute timestamps
    stored to a resolution) checks the steps against the mean step instead.
    """
    if t.size < 2:
        raise RotoridError(f"{where}: at least 2 samples are needed to give a sample rate")
    if not np.all(np.isfinite(t)):
        raise RotoridError(f"{where}: has NaN/inf or empty values (first at row {int(np.argmax(~np.isfinite(t)))})")
    dt = np.diff(t)
    step = float(np.median(dt))
    if not step > 0:
        raise RotoridError(f"{where}: time does not increase (median step {step:g} s)")
    if tick > 0:
        ref = (t[-1] - t[0]) / (t.size - 1)
        dev = np.abs(dt - ref)
        allowed = _TIME_RTOL * ref + tick * (1 + 1e-6)
        if dev.max() > allowed:
            i = int(np.argmax(dev > allowed))
            raise RotoridError(f"{where}: non-uniform time {kind}: step {i} (between samples {i} and {i + 1}) is "
                               f"{dt[i]:.9g} s, the mean step is {ref:.9g} s (allowed deviation {allowed:.3g} s)")
        return (t.size - 1) / (t[-1] - t[0]), float(t[0])
    # the uniform grid that best fits the printed times (least squares), and how far each time is from it
    i = np.arange(t.size, dtype=float)
    ic = i - i.mean()
    slope = float(np.dot(ic, t - t.mean()) / np.dot(ic, ic))
    resid = t - (t.mean() + slope * ic)
    dev = np.abs(resid) / slope
    if dev.max() > _TIME_RTOL:
        j = int(np.argmax(dev))
        raise RotoridError(f"{where}: non-uniform time {kind}: sample {j} is {resid[j]:.3g} s ({dev[j]:.2g} of a step) "
                           f"off the uniform grid of step {slope:.9g} s (allowed {_TIME_RTOL:g} of a step: a missing "
                           "sample, a restart or a clock jump?)")
    return 1.0 / slope, float(t.mean() - slope * i.mean())


@dataclass
class _Raw:
    """One channel as a reader found it, before mapping and unit conversion."""

    key: str                      # its full name in the file (TDMS "Group/Channel")
    short: str                    # its bare name (the TDMS channel name; = key elsewhere)
    data: np.ndarray | None       # None when it cannot be used (see problem)
    unit: str | None = None       # unit the file states for it
    fs: float | None = None       # sample rate the file states for it
    t0: float | None = None       # time of its first sample, if the file states one
    problem: str | None = None    # why it cannot be used; raised only if it is used
    aliases: tuple = ()           # further names channel_map may use (UFF "<node>:<dir>")


@dataclass
class _Read:
    """What a reader found in a file."""

    raws: list
    meta: dict = field(default_factory=dict)   # file-level meta (source_format, group, preamble, ...)
    address: str = "'Group/Channel'"            # how to name one channel unambiguously (for messages)
    explain: object = None                      # keys -> advice when identical groups share a name, or None
    all_same: bool = False                      # every group holds the same channels (a file of runs)


@contextlib.contextmanager
def _atomic_write(path):
    """Yield a temporary path next to ``path``; it replaces ``path`` only if the block succeeds.
    A path that cannot be written (a folder, a missing folder, no permission) is a RotoridError."""
    if not isinstance(path, (str, os.PathLike)):
        raise RotoridError(f"path must be a file path, got {path!r}")
    path = Path(path)
    if path.is_dir():
        raise RotoridError(f"cannot write {path}: it is a directory")
    if not path.parent.is_dir():
        raise RotoridError(f"cannot write {path}: the folder {path.parent} does not exist")
    # a fresh name rather than mkstemp, so the file gets the usual permissions when created
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        yield str(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        with contextlib.suppress(OSError):
            os.remove(tmp)
        raise RotoridError(f"cannot write {path}: {exc.strerror or exc}") from None
    except BaseException:
        with contextlib.suppress(OSError):
            os.remove(tmp)
        raise


def _lab_columns(rec: Recording, path, names, units, *, max_name=None, max_unit=None, forbid=""):
    """[(lab name, unit, data in that unit)] for the writers; ``names``/``units`` keyed by channel.

    The tables may cover canonical channels the recording lacks (one table for a lab's channel
    set); any other key that is not a channel of the recording is taken for a typo and raises.
    """
    from .._validate import mapping

    if not isinstance(rec, Recording):
        raise RotoridError(f"rec must be a Recording, got {type(rec).__name__}")
    names, units = mapping("names", names), mapping("units", units)
    for arg, d in (("names", names), ("units", units)):
        extra = sorted(k for k in d if k not in rec.channels and k not in KNOWN)
        if extra:
            raise RotoridError(f"cannot write {path}: {arg} names channel(s) {extra} that the recording lacks "
                               f"(it has {sorted(rec.channels)})")
    cols, seen = [], set()
    for name, data in rec.channels.items():
        lab = names.get(name, name)
        if not isinstance(lab, str) or not lab.strip() or any(ch in lab for ch in forbid + "\n\r"):
            raise RotoridError(f"cannot write {path}: channel name {lab!r} (for {name!r}) is empty or holds one "
                               f"of {list(forbid)}")
        if max_name and len(lab) > max_name:
            raise RotoridError(f"cannot write {path}: channel name {lab!r} is longer than {max_name} characters")
        if lab in seen:
            raise RotoridError(f"cannot write {path}: two channels would be written as {lab!r}")
        seen.add(lab)
        have = rec.units.get(name, "")
        unit = units.get(name, have)
        if not isinstance(unit, str):
            raise RotoridError(f"cannot write {path}: the unit of channel {name!r} must be a string, got {unit!r}")
        if unit != have:
            try:
                f_have = _units.factor(have)
                f_want = _units.factor(unit, _units.quantity_of(have))
            except RotoridError as exc:
                raise RotoridError(f"cannot write {path}: channel {name!r} from {have!r} to {unit!r}: {exc}") from None
            data = (data * f_have if f_have != 1.0 else data) / f_want
        if unit and any(ch in unit for ch in forbid + "\n\r"):
            raise RotoridError(f"cannot write {path}: unit {unit!r} of channel {name!r} holds one of {list(forbid)}")
        if max_unit and len(unit) > max_unit:
            raise RotoridError(f"cannot write {path}: unit {unit!r} is longer than {max_unit} characters")
        cols.append((lab, unit, np.asarray(data, dtype=np.float64)))
    return cols
