"""Reading and writing recordings: rotorid's native file and the lab formats CSV, TDMS and UFF 58.

:func:`load_recording` reads any of them into a :class:`~rotorid.recording.Recording` (float64,
SI units, canonical channel names); :func:`save_recording` writes the native file;
:func:`save_csv`, :func:`save_tdms` and :func:`save_uff58` write lab files, for converting data
and for tests.

Native format (``.npz``, format_version 1)
------------------------------------------
A NumPy ``.npz`` archive written with ``np.savez_compressed`` and readable with
``np.load(path, allow_pickle=False)``. Entries (all 0-d arrays except the channels):

    format          str      "rotorid-recording"
    format_version  int      1
    fs_hz           float64  sample rate, Hz
    t0_s            float64  time of the first sample, s
    ch_<name>       float64  1-D, one per channel (``Recording.channels[name]``), SI units
    meta_json       str      JSON of ``Recording.meta`` (a JSON object)
    units_json      str      JSON object: channel name -> unit
    source          str      JSON string: ``Recording.source`` (where the data came from)

A reader refuses a file whose ``format`` or ``format_version`` differ. Loading a native file
without a channel_map gives back the saved Recording exactly, non-canonical channels included;
its ``source`` is the stored one (or the file's path if none was stored).

Lab files
---------
``.csv``    first row is the header; a cell may carry a unit as ``name [unit]``. A column ``t``,
            ``time`` or ``time_s`` (e.g. ``time [s]``) is the time axis; its steps must be uniform
            (deviation from the median step < 1e-6 relative) and give fs = (n-1)/(t[-1]-t[0]),
            the precise form of 1/median(diff) once the steps are known to be uniform. Without a
            time column ``fs_hz`` must be given. The separator is the one of ``,`` ``;`` and tab
            that is most frequent in the header.
``.tdms``   (nptdms) every channel of every group, addressed as ``"Group/Channel"`` or as
            ``"Channel"`` when no other group has a channel of that name. Sample rate from
            ``wf_increment`` (``fs_hz`` is used only for channels without one), start time from
            ``wf_start_offset``, unit from ``unit_string``.
``.uff``    (pyuff) every type-58 time series (function type 0 or 1, real data); the channel name
``.unv``    is ``id1``, the rate comes from the abscissa increment (or the abscissa values when
            the spacing is uneven), the unit from the ordinate axis units label.

How lab channels become Recording channels (``load_recording``'s ``channel_map``)::

    channel_map = {"Prox DE X": {"to": "x1", "unit": "mil"},
                   "Hammer":    {"to": "force", "unit": "lbf", "scale": 0.1}}  # file in mV, 10 mV/lbf

Each entry maps a lab channel to a canonical name (``recording.KNOWN``) and says how to get SI
values: ``value_SI = (raw * scale + offset) * units.factor(unit, quantity)``, the quantity
following from the canonical name (displacements: length, force: force, kp: voltage,
px*/py*: acceleration). ``scale`` (sensor sensitivity) defaults to 1, ``offset`` to 0; without
``unit`` the unit the file states is used, else SI is assumed. A unit of the wrong quantity
raises. Channels the file names canonically (``x1``, ...) are used without an entry, with the
file's unit or SI. Every other channel is dropped with one warning that lists them all; a mapped
channel missing from the file raises, naming it and what the file has. The Recording's meta then
records, under ``"channel_sources"``, which file channel, unit, scale and offset fed each channel.

Any file that cannot be parsed raises ``RotoridError("cannot read <path> as <format>: <reason>")``.
Displacement and force channels are checked for clipping on load (:func:`check_clipping`).
"""

from __future__ import annotations

import contextlib
import csv
import json
import logging
import math
import os
import re
import sys
import uuid
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import units as _units
from .errors import RotoridError
from .recording import DISPLACEMENTS, KNOWN, SI_UNITS, Recording

__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "FORMATS", "QUANTITY", "check_clipping", "load_recording",
           "save_csv", "save_recording", "save_tdms", "save_uff58"]

FORMAT_NAME = "rotorid-recording"
FORMAT_VERSION = 1
#: values of load_recording's ``fmt``
FORMATS = ("native", "csv", "tdms", "uff58")
_EXTENSIONS = {".npz": "native", ".csv": "csv", ".tdms": "tdms", ".uff": "uff58", ".unv": "uff58"}
_LABELS = {"native": "a rotorid recording (.npz)", "csv": "CSV", "tdms": "TDMS", "uff58": "UFF 58"}

#: physical quantity of each canonical channel (the units table's quantity names)
QUANTITY = {**{c: "length" for c in DISPLACEMENTS}, "force": "force", "kp": "voltage",
            **{c: "acceleration" for c in ("px1", "py1", "px2", "py2")}}
#: channels whose saturation would corrupt the identification
CLIP_CHECKED = DISPLACEMENTS + ("force",)
CLIP_MIN_RUN = 5

_RATE_RTOL = 1e-6   # two sample rates closer than this (relative) are the same rate
_TIME_RTOL = 1e-6   # allowed deviation of CSV time steps from their median (relative)
_MAP_KEYS = ("to", "unit", "scale", "offset")
_TIME_COLUMNS = ("t", "time", "time_s")
_TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6}
# UFF 58: id lines are 80 characters, axis unit labels 20 (fixed-width records)
_UFF_ID_LEN = 80
_UFF_LABEL_LEN = 20
# UFF 58 ordinate "specific data type" per quantity (displacement, excitation force, acceleration)
_UFF_DATA_TYPE = {"length": 8, "force": 13, "acceleration": 12}


# ---------------------------------------------------------------------------------------------
# small helpers


def _warn(message: str) -> None:
    """warnings.warn attributed to the first caller outside this module."""
    level, frame = 2, sys._getframe(1)  # stacklevel 2 is _warn's caller
    while frame is not None and frame.f_globals.get("__name__") == __name__:
        frame, level = frame.f_back, level + 1
    warnings.warn(message, UserWarning, stacklevel=level)


def _cannot(path, fmt: str, reason) -> RotoridError:
    return RotoridError(f"cannot read {path} as {_LABELS[fmt]}: {reason}")


def _describe(exc: BaseException) -> str:
    text = str(exc).strip()
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _positive_rate(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise RotoridError(f"{name} must be a number > 0, got {value!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise RotoridError(f"{name} must be a number > 0, got {value!r}")
    return v


def _same_rate(a: float, b: float) -> bool:
    return abs(a - b) <= _RATE_RTOL * max(abs(a), abs(b))


def _json_default(obj):
    # meta may hold NumPy scalars or arrays; anything else is not JSON and is refused
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"{type(obj).__name__} is not JSON-serializable")


def _split_unit(cell: str) -> tuple[str, str | None]:
    """'x1 [mil]' -> ('x1', 'mil'); 'x1' -> ('x1', None)."""
    m = re.fullmatch(r"\s*(.*?)\s*\[\s*([^\[\]]*?)\s*\]\s*", cell)
    if m:
        return m.group(1), (m.group(2) or None)
    return cell.strip(), None


@contextlib.contextmanager
def _atomic_write(path):
    """Yield a temporary path next to ``path``; it replaces ``path`` only if the block succeeds."""
    path = Path(path)
    # a fresh name rather than mkstemp, so the file gets the usual permissions when created
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        yield str(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.remove(tmp)
        raise


# ---------------------------------------------------------------------------------------------
# channel_map and the common assembly of a Recording from the channels a reader found


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


@dataclass
class _Use:
    """A file channel chosen to become Recording channel ``name``."""

    name: str
    raw: _Raw
    unit: str | None
    unit_from: str                # "channel_map" | "file" | "assumed SI" | "kept as is"
    scale: float = 1.0
    offset: float = 0.0


def _parse_channel_map(channel_map, path) -> dict:
    if channel_map is None:
        return {}
    if not isinstance(channel_map, Mapping):
        raise RotoridError(f"channel_map must be a dict lab channel -> {{'to': ..., 'unit': ...}}, "
                           f"got {type(channel_map).__name__}")
    out, target_of = {}, {}
    for lab, spec in channel_map.items():
        where = f"channel_map[{lab!r}] (for {path})"
        if not isinstance(lab, str) or not lab.strip():
            raise RotoridError(f"channel_map keys must be non-empty channel names, got {lab!r}")
        if not isinstance(spec, Mapping):
            raise RotoridError(f"{where} must be a dict like {{'to': 'x1', 'unit': 'mil'}}, got {spec!r}")
        unknown = sorted(set(spec) - set(_MAP_KEYS))
        if unknown:
            raise RotoridError(f"{where} has unknown key(s) {unknown}; allowed: {list(_MAP_KEYS)}")
        to = spec.get("to")
        if to not in KNOWN:
            raise RotoridError(f"{where}: 'to' must be one of {list(KNOWN)}, got {to!r}")
        if to in target_of:
            raise RotoridError(f"channel_map maps both {target_of[to]!r} and {lab!r} to {to!r} (for {path})")
        target_of[to] = lab
        unit = spec.get("unit")
        if unit is not None:
            if not isinstance(unit, str) or not unit.strip():
                raise RotoridError(f"{where}: 'unit' must be a unit name like 'mil', got {unit!r}")
            try:
                _units.factor(unit, QUANTITY[to])
            except RotoridError as exc:
                raise RotoridError(f"{where}: {exc} (channel {to!r})") from None
        nums = {}
        for k, default in (("scale", 1.0), ("offset", 0.0)):
            v = spec.get(k, default)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) \
                    or not math.isfinite(float(v)):
                raise RotoridError(f"{where}: {k!r} must be a finite number, got {v!r}")
            nums[k] = float(v)
        if nums["scale"] == 0:
            raise RotoridError(f"{where}: 'scale' must not be 0")
        out[lab] = _Use(to, None, unit, "channel_map", nums["scale"], nums["offset"])  # raw found later
    return out


def _find(raws: list[_Raw], name: str, path) -> _Raw:
    """The file channel ``name`` (full key, or bare name if unique)."""
    hits = [r for r in raws if r.key == name] or [r for r in raws if r.short == name]
    if len(hits) == 1:
        return hits[0]
    if hits:
        raise RotoridError(f"channel {name!r} named in channel_map is ambiguous in {path}: it matches "
                           f"{[r.key for r in hits]}; name it as 'Group/Channel'")
    raise RotoridError(f"channel {name!r} named in channel_map is not in {path}; the file has "
                       f"{[r.key for r in raws]}")


def _select(raws: list[_Raw], entries: dict, path, keep_other: bool) -> list[_Use]:
    """Decide which file channels are used (mapped or canonically named); warn about the rest."""
    uses, used = [], set()
    for lab, use in entries.items():
        raw = _find(raws, lab, path)
        if id(raw) in used:
            raise RotoridError(f"channel_map names file channel {raw.key!r} twice (for {path})")
        used.add(id(raw))
        use.raw = raw
        if use.unit is None:
            use.unit, use.unit_from = (raw.unit, "file") if raw.unit else (SI_UNITS[use.name], "assumed SI")
        uses.append(use)
    taken = {u.name for u in uses}
    shadowed, dropped, canonical = [], [], {}
    for raw in raws:
        if id(raw) in used:
            continue
        if raw.short in KNOWN:
            if raw.short in taken:
                shadowed.append(raw.key)
            else:
                canonical.setdefault(raw.short, []).append(raw)
        elif keep_other:
            uses.append(_Use(raw.key, raw, raw.unit, "kept as is"))
        else:
            dropped.append(raw.key)
    for name, rs in canonical.items():
        if len(rs) > 1:
            raise RotoridError(f"{path} has several channels named {name!r}: {[r.key for r in rs]}; "
                               "choose one with channel_map ('Group/Channel')")
        raw = rs[0]
        unit, how = (raw.unit, "file") if raw.unit else (SI_UNITS[name], "assumed SI")
        uses.append(_Use(name, raw, unit, how))
    if dropped or shadowed:
        parts = []
        if dropped:
            parts.append(f"dropped {len(dropped)} channel(s) that are neither in channel_map nor named "
                         f"canonically: {dropped}")
        if shadowed:
            parts.append(f"dropped {len(shadowed)} canonically named channel(s) because channel_map maps "
                         f"another channel onto that name: {shadowed}")
        _warn(f"{path}: " + "; ".join(parts) + f" (canonical names: {list(KNOWN)})")
    if not uses:
        raise RotoridError(f"{path} has no usable channel: none is named canonically ({list(KNOWN)}) or "
                           f"mapped by channel_map; the file has {[r.key for r in raws]}")
    return uses


def _convert(use: _Use, path) -> np.ndarray:
    raw = use.raw
    a = np.array(raw.data, dtype=np.float64)  # a copy: the readers' arrays stay untouched
    if use.name in QUANTITY:
        try:
            f = _units.factor(use.unit, QUANTITY[use.name])
        except RotoridError as exc:
            raise RotoridError(f"{path}: channel {raw.key!r} (-> {use.name}, unit from {use.unit_from}): "
                               f"{exc}") from None
        # value_SI = (raw * scale + offset) * factor, skipping identities so SI data stay bit-exact
        if use.scale != 1.0:
            a *= use.scale
        if use.offset != 0.0:
            a += use.offset
        if f != 1.0:
            a *= f
    bad = ~np.isfinite(a)
    if bad.any():
        raise RotoridError(f"{path}: channel {raw.key!r} has {int(bad.sum())} NaN/inf or empty value(s) "
                           f"(first at sample {int(np.argmax(bad))})")
    return a


def _assemble(path, raws, channel_map, fs_hz, file_meta, meta, *, source, keep_other=False,
              provenance=True) -> Recording:
    entries = _parse_channel_map(channel_map, path)
    uses = _select(raws, entries, path, keep_other)
    for u in uses:
        if u.raw.problem:
            raise RotoridError(f"{path}: channel {u.raw.key!r} (-> {u.name}) cannot be used: {u.raw.problem}")

    # one sample rate for all used channels: the file's, or fs_hz where the file states none
    rates = {}
    for u in uses:
        if u.raw.fs is not None:
            rates[u.raw.key] = u.raw.fs
        elif fs_hz is not None:
            rates[u.raw.key] = fs_hz
        else:
            raise RotoridError(f"{path} states no sample rate for channel {u.raw.key!r}: pass fs_hz")
    values = list(rates.values())
    if any(not _same_rate(values[0], v) for v in values[1:]):
        listing = ", ".join(f"{k} {v:.9g} Hz" for k, v in rates.items())
        raise RotoridError(f"{path}: sample rates disagree: {listing}")
    fs = values[0]
    file_rates = [u.raw.fs for u in uses if u.raw.fs is not None]
    if fs_hz is not None and file_rates and not _same_rate(fs_hz, file_rates[0]):
        _warn(f"{path}: fs_hz={fs_hz:g} ignored: the file states {file_rates[0]:.9g} Hz")

    lengths = {u.raw.key: u.raw.data.size for u in uses}
    if len(set(lengths.values())) > 1:
        raise RotoridError(f"{path}: channel lengths disagree: {lengths}")
    if next(iter(lengths.values())) == 0:
        raise RotoridError(f"{path}: the channels hold no samples")

    starts = {u.raw.key: u.raw.t0 for u in uses if u.raw.t0 is not None}
    t0 = next(iter(starts.values()), 0.0)
    if any(abs(v - t0) > 0.5 / fs for v in starts.values()):
        raise RotoridError(f"{path}: start times disagree: {starts}")

    channels, units, sources = {}, {}, {}
    # lab files: canonical order; native files: the order they were saved in
    if keep_other:
        position = {id(r): i for i, r in enumerate(raws)}
        uses = sorted(uses, key=lambda u: position[id(u.raw)])
    else:
        uses = sorted(uses, key=lambda u: (KNOWN.index(u.name) if u.name in KNOWN else len(KNOWN), u.name))
    for u in uses:
        channels[u.name] = _convert(u, path)
        units[u.name] = SI_UNITS[u.name] if u.name in QUANTITY else (u.unit or "")
        sources[u.name] = {"file_channel": u.raw.key, "unit": u.unit, "unit_from": u.unit_from,
                           "scale": u.scale, "offset": u.offset}
    merged = dict(file_meta)
    if provenance:
        merged["channel_sources"] = sources
    merged.update(meta or {})
    try:
        return Recording(fs, channels, merged, units, t0, source)
    except RotoridError as exc:
        raise RotoridError(f"{path}: {exc}") from None


# ---------------------------------------------------------------------------------------------
# load


def load_recording(path, *, channel_map=None, fs_hz=None, meta=None, fmt=None) -> Recording:
    """Read a recording from a native ``.npz``, CSV, TDMS or UFF 58 file (see the module doc).

    path         the file; its extension (.npz, .csv, .tdms, .uff, .unv) picks the format unless
                 ``fmt`` ("native", "csv", "tdms", "uff58") is given
    channel_map  {lab channel: {"to": canonical name, "unit": ..., "scale": ..., "offset": ...}}
    fs_hz        sample rate for files (or channels) that state none; ignored, with a warning if
                 it differs, where the file states one
    meta         merged into the recording's meta (these keys win)

    Returns a Recording in SI units; warns about dropped channels and possible clipping.
    """
    p = Path(path)
    if fmt is None:
        fmt = _EXTENSIONS.get(p.suffix.lower())
        if fmt is None:
            raise RotoridError(f"cannot tell the format of {path} from its extension {p.suffix!r}: use one of "
                               f"{sorted(_EXTENSIONS)} or pass fmt= one of {list(FORMATS)}")
    elif fmt not in FORMATS:
        raise RotoridError(f"fmt must be one of {list(FORMATS)}, got {fmt!r}")
    if fs_hz is not None:
        fs_hz = _positive_rate("fs_hz", fs_hz)
    if meta is not None and not isinstance(meta, Mapping):
        raise RotoridError(f"meta must be a dict, got {type(meta).__name__}")
    if not p.is_file():
        raise RotoridError(f"cannot read {path}: no such file")

    if fmt == "native":
        raws, file_meta, stored_source = _read_native(p)
        rec = _assemble(path, raws, channel_map, fs_hz, file_meta, meta, source=stored_source or str(path),
                        keep_other=True, provenance=channel_map is not None)
    else:
        reader = {"csv": _read_csv, "tdms": _read_tdms, "uff58": _read_uff58}[fmt]
        raws = reader(p)
        rec = _assemble(path, raws, channel_map, fs_hz, {"source_format": fmt}, meta, source=str(path))
    check_clipping(rec)
    return rec


def _read_native(path: Path):
    try:
        archive = np.load(path, allow_pickle=False)
    except Exception as exc:  # numpy raises OSError, ValueError, BadZipFile, EOFError ... on bad files
        raise _cannot(path, "native", _describe(exc)) from None
    if not hasattr(archive, "files"):  # a bare .npy array, not an archive
        raise _cannot(path, "native", "it is a single array, not an .npz archive")
    with archive:
        try:
            if "format" not in archive.files:
                raise _cannot(path, "native", "it has no 'format' entry (not written by save_recording)")
            fmt = str(archive["format"])
            if fmt != FORMAT_NAME:
                raise _cannot(path, "native", f"format is {fmt!r}, expected {FORMAT_NAME!r}")
            missing = [k for k in ("format_version", "fs_hz", "t0_s", "meta_json", "units_json", "source")
                       if k not in archive.files]
            if missing:
                raise _cannot(path, "native", f"entries {missing} are missing")
            version = archive["format_version"]
            if version.shape != () or version.dtype.kind not in "iu" or int(version) != FORMAT_VERSION:
                raise _cannot(path, "native", f"format_version {version!r} is not supported "
                                              f"(this rotorid reads version {FORMAT_VERSION})")
            fs = float(archive["fs_hz"])
            t0 = float(archive["t0_s"])
            file_meta = json.loads(str(archive["meta_json"]))
            units = json.loads(str(archive["units_json"]))
            source = json.loads(str(archive["source"]))
            if not isinstance(file_meta, dict) or not isinstance(units, dict) or not isinstance(source, str):
                raise _cannot(path, "native", "meta_json and units_json must hold JSON objects and source a "
                                              "JSON string")
            raws = []
            for key in archive.files:
                if key.startswith("ch_"):
                    name, data = key[3:], archive[key]
                    if data.ndim != 1 or data.dtype.kind != "f":
                        raise _cannot(path, "native", f"channel {name!r} is not a 1-D float array "
                                                      f"(shape {data.shape}, dtype {data.dtype})")
                    raws.append(_Raw(name, name, data.astype(np.float64, copy=False), units.get(name) or None,
                                     fs, t0))
        except RotoridError:
            raise
        except Exception as exc:  # corrupt members (CRC, truncation), bad JSON, bad scalars
            raise _cannot(path, "native", _describe(exc)) from None
    if not math.isfinite(fs) or fs <= 0:
        raise _cannot(path, "native", f"fs_hz is {fs!r}")
    if not raws:
        raise _cannot(path, "native", "it holds no channel (no 'ch_<name>' entry)")
    return raws, file_meta, source


def _read_csv(path: Path) -> list[_Raw]:
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            header_line = fh.readline()
            sep = max((",", ";", "\t"), key=header_line.count)
            fh.seek(0)
            rows = list(csv.reader(fh, delimiter=sep))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise _cannot(path, "csv", _describe(exc)) from None
    if not rows or not any(c.strip() for c in rows[0]):
        raise _cannot(path, "csv", "the file is empty (no header row)")
    header, body = rows[0], rows[1:]
    # (line number, cells) of the data rows; blank lines (e.g. a trailing one) are skipped
    body = [(i + 2, r) for i, r in enumerate(body) if any(c.strip() for c in r)]
    if not body:
        raise _cannot(path, "csv", "it has a header but no data rows")
    ncol = len(header)
    for line, r in body:
        if len(r) != ncol:
            raise _cannot(path, "csv", f"line {line} has {len(r)} fields, the header has {ncol}")
    names, col_units = zip(*(_split_unit(c) for c in header))
    if any(not n for n in names):
        raise _cannot(path, "csv", f"header has an empty column name: {header}")
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise _cannot(path, "csv", f"header names column(s) {dupes} more than once")

    raws = []
    for j, (name, unit) in enumerate(zip(names, col_units)):
        cells = [r[j] for _, r in body]
        try:
            data, problem = np.asarray(cells, dtype=np.float64), None
        except ValueError:
            k = next(k for k, c in enumerate(cells) if not _is_number(c))
            data, problem = None, f"cell {cells[k]!r} on line {body[k][0]} is not a number"
        raws.append(_Raw(name, name, data, unit, problem=problem))

    times = [r for r in raws if r.key.lower() in _TIME_COLUMNS]
    if len(times) > 1:
        raise RotoridError(f"{path}: several time columns {[r.key for r in times]}; keep one")
    if times:
        fs, t0 = _csv_time_base(path, times[0])
        raws = [r for r in raws if r is not times[0]]
        for r in raws:
            r.fs, r.t0 = fs, t0
    return raws


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True


def _csv_time_base(path, col: _Raw) -> tuple[float, float]:
    """Sample rate and start time from a CSV time column; the steps must be uniform."""
    where = f"{path}: time column {col.key!r}"
    if col.problem:
        raise RotoridError(f"{where}: {col.problem}")
    unit = col.unit or "s"
    if unit.lower() not in _TIME_UNITS:
        raise RotoridError(f"{where}: unknown time unit {unit!r}; known: {list(_TIME_UNITS)}")
    t = col.data * _TIME_UNITS[unit.lower()]
    if t.size < 2:
        raise RotoridError(f"{where}: at least 2 samples are needed to give a sample rate")
    if not np.all(np.isfinite(t)):
        raise RotoridError(f"{where}: has NaN/inf values (first at row {int(np.argmax(~np.isfinite(t)))})")
    dt = np.diff(t)
    step = float(np.median(dt))
    if not step > 0:
        raise RotoridError(f"{where}: time does not increase (median step {step:g} s)")
    dev = np.abs(dt - step) / step
    if dev.max() >= _TIME_RTOL:
        i = int(np.argmax(dev >= _TIME_RTOL))
        raise RotoridError(f"{where}: non-uniform time column: step {i} (between samples {i} and {i + 1}) is "
                           f"{dt[i]:.9g} s, the median step is {step:.9g} s (relative deviation {dev[i]:.2g}, "
                           f"allowed < {_TIME_RTOL:g})")
    # with uniform steps the span gives the same rate as 1/median(diff), with far less rounding error
    return (t.size - 1) / (t[-1] - t[0]), float(t[0])


@contextlib.contextmanager
def _nptdms_log():
    """Collect nptdms's log records: it reports damaged files as log warnings, not exceptions."""
    records = []

    class _Collect(logging.Handler):
        def emit(self, record):
            records.append(record)

    handler = _Collect(logging.WARNING)
    logger = logging.getLogger("nptdms")
    logger.addHandler(handler)
    try:
        yield records
    finally:
        logger.removeHandler(handler)


# phrases of nptdms's warnings about truncated or inconsistent segments (reader/tdms_segment)
_TDMS_DAMAGE = ("incomplete", "less data", "chunk size", "cropping", "segment")


def _read_tdms(path: Path) -> list[_Raw]:
    try:
        from nptdms import TdmsFile
    except ImportError:
        raise RotoridError(f"reading {path} needs the nptdms package (pip install nptdms)") from None
    with _nptdms_log() as log:
        try:
            tdms = TdmsFile.read(os.fspath(path))
            groups = [(g.name, [(c.name, c.properties, c[:]) for c in g.channels()]) for g in tdms.groups()]
        except Exception as exc:  # nptdms raises ValueError, struct.error, KeyError ... on bad files
            raise _cannot(path, "tdms", _describe(exc)) from None
    damage = [r.getMessage() for r in log if any(w in r.getMessage().lower() for w in _TDMS_DAMAGE)]
    if damage:
        raise _cannot(path, "tdms", f"the file is truncated or damaged (nptdms: {'; '.join(damage)})")
    for r in log:
        _warn(f"{path}: nptdms: {r.getMessage()}")

    raws = []
    for gname, channels in groups:
        for cname, props, data in channels:
            raw = _Raw(f"{gname}/{cname}", cname, None)
            unit = props.get("unit_string")
            raw.unit = (str(unit).strip() or None) if unit is not None else None
            data = np.asarray(data)
            if data.dtype.kind not in "iuf" or data.ndim != 1:
                raw.problem = f"its data are not real numbers (dtype {data.dtype})"
            elif data.size == 0:
                raw.problem = "it holds no samples"
            else:
                raw.data = data
            if "wf_increment" in props:
                inc = props["wf_increment"]
                try:
                    inc = float(inc)
                except (TypeError, ValueError):
                    inc = float("nan")
                if math.isfinite(inc) and inc > 0:
                    raw.fs = 1.0 / inc
                else:
                    raw.problem = raw.problem or f"wf_increment={props['wf_increment']!r} is not a sample interval"
            offset = props.get("wf_start_offset")
            if isinstance(offset, (int, float, np.integer, np.floating)) and math.isfinite(float(offset)):
                raw.t0 = float(offset)
            raws.append(raw)
    if not raws:
        raise _cannot(path, "tdms", "it holds no channels")
    return raws


def _snap_rate(fs: float, rel_uncertainty: float) -> float:
    """The nearest whole-hertz rate if ``fs`` is that rate within the precision it was stored with."""
    k = round(fs)
    if k > 0 and abs(fs - k) <= rel_uncertainty * fs * (1 + 1e-9):
        return float(k)
    return fs


def _read_uff58(path: Path) -> list[_Raw]:
    try:
        import pyuff
    except ImportError:
        raise RotoridError(f"reading {path} needs the pyuff package (pip install pyuff)") from None
    try:
        with open(path, "rb") as fh:
            content = fh.read()
    except OSError as exc:
        raise _cannot(path, "uff58", _describe(exc)) from None
    # pyuff pairs '    -1' delimiters and silently ignores an unpaired (truncated) last data set
    if not content.rstrip().endswith(b"    -1"):
        raise _cannot(path, "uff58", "it does not end with a '    -1' delimiter (truncated, or not a UFF file)")
    try:
        uff = pyuff.UFF(os.fspath(path))
        types = [int(t) for t in uff.get_set_types()]
        which = [i for i, t in enumerate(types) if t == 58]
        sets = uff.read_sets(which) if which else []
    except Exception as exc:  # pyuff raises bare Exception on any parse error
        raise _cannot(path, "uff58", _describe(exc)) from None
    if isinstance(sets, dict):  # pyuff returns a lone dict when there is one data set
        sets = [sets]
    if not sets:
        raise _cannot(path, "uff58", f"it holds no type-58 data set (data set types found: {types})")

    raws, skipped = [], []
    for i, ds in zip(which, sets):
        name = str(ds.get("id1", "")).strip()
        if name.upper() in ("", "NONE"):
            name = f"data set {i}"
        data = np.asarray(ds.get("data"))
        if ds.get("func_type") not in (0, 1) or data.dtype.kind not in "iuf":
            skipped.append(f"{name} (function type {ds.get('func_type')})")
            continue
        if data.ndim != 1 or data.size != ds.get("num_pts"):
            raise _cannot(path, "uff58", f"data set {i} ({name!r}) holds {data.size} values, its header says "
                                         f"{ds.get('num_pts')} (truncated?)")
        raw = _Raw(name, name, data)
        unit = str(ds.get("ordinate_axis_units_lab", "")).strip()
        raw.unit = unit if unit.upper() not in ("", "NONE") else None
        # the abscissa is stored as E13.5 (6 significant digits): snap to whole hertz when that fits
        inc = float(ds.get("abscissa_inc") or 0.0)
        if ds.get("abscissa_spacing") == 1 and inc > 0:
            raw.fs = _snap_rate(1.0 / inc, 0.5e-5 * 10.0 ** math.floor(math.log10(inc)) / inc)
            raw.t0 = float(ds.get("abscissa_min", 0.0))
        else:
            x = np.asarray(ds.get("x"), dtype=np.float64)
            span = x[-1] - x[0] if x.size >= 2 else 0.0
            if not span > 0:
                raw.problem = "its abscissa gives no sample interval"
            else:
                step = span / (x.size - 1)
                # each abscissa value carries up to 5e-6 relative rounding (E13.5)
                tol = _TIME_RTOL * step + 1e-5 * float(np.max(np.abs(x)))
                if np.max(np.abs(np.diff(x) - step)) > tol:
                    raw.problem = "its abscissa values are not uniformly spaced"
                else:
                    raw.fs = _snap_rate(1.0 / step, 1e-5 * float(np.max(np.abs(x))) / span + _TIME_RTOL)
                    raw.t0 = float(x[0])
        raws.append(raw)
    if skipped:
        _warn(f"{path}: ignored type-58 data set(s) that are not real time series: {skipped}")
    if not raws:
        raise _cannot(path, "uff58", "it holds no type-58 time series")
    return raws


# ---------------------------------------------------------------------------------------------
# clipping


def check_clipping(rec: Recording, *, min_run: int = CLIP_MIN_RUN) -> list[dict]:
    """Warn about displacement and force channels that look saturated.

    A channel is reported when it sits at its own maximum (or minimum) value for ``min_run`` or
    more consecutive samples. A level that is also the channel's median is its resting baseline
    (e.g. a hammer between impacts), not a rail, and is not reported; neither is a constant channel.
    Returns the findings as dicts (channel, side, level, unit, first_index, run_length, runs),
    one per warned channel and side.
    """
    findings = []
    for name in CLIP_CHECKED:
        a = rec.channels.get(name)
        if a is None or a.size < min_run:
            continue
        lo, hi = float(a.min()), float(a.max())
        if lo == hi:
            continue
        median = float(np.median(a))
        for side, level in (("maximum", hi), ("minimum", lo)):
            if level == median:
                continue
            at = np.concatenate(([False], a == level, [False])).astype(np.int8)
            edges = np.diff(at)
            starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
            long = (ends - starts) >= min_run
            if not long.any():
                continue
            first = int(starts[long][0])
            item = dict(channel=name, side=side, level=level, unit=rec.units.get(name, ""), first_index=first,
                        run_length=int((ends - starts)[long][0]), runs=int(long.sum()))
            findings.append(item)
            _warn(f"{rec.source or 'recording'}: channel {name!r} possibly clipped: it sits at its {side} "
                  f"{level:.6g} {item['unit']} for {item['run_length']} consecutive samples from sample {first} "
                  f"({item['runs']} such run(s) of >= {min_run} samples)")
    return findings


# ---------------------------------------------------------------------------------------------
# writers


def save_recording(rec: Recording, path) -> None:
    """Write ``rec`` in the native format (see the module doc); ``path`` is used as given."""
    if not isinstance(rec, Recording):
        raise RotoridError(f"rec must be a Recording, got {type(rec).__name__}")
    try:
        meta_json = json.dumps(rec.meta, default=_json_default, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise RotoridError(f"cannot write {path}: Recording.meta is not JSON-serializable ({exc})") from None
    arrays = {f"ch_{name}": np.asarray(data, dtype=np.float64) for name, data in rec.channels.items()}
    arrays.update(format=np.array(FORMAT_NAME), format_version=np.array(FORMAT_VERSION, dtype=np.int64),
                  fs_hz=np.array(rec.fs_hz, dtype=np.float64), t0_s=np.array(rec.t0_s, dtype=np.float64),
                  meta_json=np.array(meta_json), units_json=np.array(json.dumps(rec.units)),
                  source=np.array(json.dumps(rec.source)))
    # through an open file, so that numpy does not append ".npz" to a path that lacks it
    with _atomic_write(path) as tmp, open(tmp, "wb") as fh:
        np.savez_compressed(fh, **arrays)


def _lab_columns(rec: Recording, path, names, units, *, max_name=None, max_unit=None, forbid=""):
    """[(lab name, unit, data in that unit)] for the writers; ``names``/``units`` keyed by channel.

    The tables may cover canonical channels the recording lacks (one table for a lab's channel
    set); any other key that is not a channel of the recording is taken for a typo and raises.
    """
    if not isinstance(rec, Recording):
        raise RotoridError(f"rec must be a Recording, got {type(rec).__name__}")
    names, units = dict(names or {}), dict(units or {})
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


def save_csv(rec: Recording, path, units=None, names=None) -> None:
    """Write ``rec`` as CSV: a ``time [s]`` column, then ``name [unit]`` columns (17 significant digits).

    units  {channel: unit to write it in} (default: the recording's units, SI)
    names  {channel: column name to write it under} (default: the channel names)
    """
    cols = _lab_columns(rec, path, names, units, forbid=",;\t[]\"")
    header = ["time [s]"] + [f"{lab} [{unit}]" if unit else lab for lab, unit, _ in cols]
    table = np.column_stack([rec.t] + [d for _, _, d in cols])
    with _atomic_write(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        fh.write(",".join(header) + "\n")
        np.savetxt(fh, table, fmt="%.17g", delimiter=",")


def save_tdms(rec: Recording, path, group: str = "rotorid", names=None, units=None, dtype="float64") -> None:
    """Write ``rec`` as TDMS: one group, one channel per recording channel.

    Each channel carries ``wf_increment`` (1/fs), ``wf_start_offset`` (t0), ``wf_samples`` and
    ``unit_string``. ``names``/``units`` as for :func:`save_csv`; ``dtype`` "float64" (exact) or
    "float32" (half the size, ~7 significant digits, as many DAQs store).
    """
    try:
        dtype = np.dtype(dtype)
    except TypeError:
        raise RotoridError(f"dtype must be 'float64' or 'float32', got {dtype!r}") from None
    if dtype not in (np.float64, np.float32):
        raise RotoridError(f"dtype must be 'float64' or 'float32', got {dtype!r}")
    try:
        from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter
    except ImportError:
        raise RotoridError(f"writing {path} needs the nptdms package (pip install nptdms)") from None
    if not isinstance(group, str) or not group.strip() or "/" in group:
        raise RotoridError(f"group must be a non-empty name without '/', got {group!r}")
    cols = _lab_columns(rec, path, names, units, forbid="/")
    objects = [RootObject(properties={"name": Path(path).stem}), GroupObject(group)]
    for lab, unit, data in cols:
        props = {"wf_increment": 1.0 / rec.fs_hz, "wf_start_offset": float(rec.t0_s), "wf_samples": int(data.size)}
        if unit:
            props["unit_string"] = unit
        objects.append(ChannelObject(group, lab, data.astype(dtype), properties=props))
    with _atomic_write(path) as tmp, TdmsWriter(tmp) as writer:
        writer.write_segment(objects)


def save_uff58(rec: Recording, path, names=None, units=None) -> None:
    """Write ``rec`` as UFF (ASCII): one type-58 time response (double precision) per channel.

    ``id1`` is the channel name, the abscissa runs from t0 in steps of 1/fs (UFF stores both as
    E13.5, 6 significant digits; the reader snaps whole-hertz rates), the ordinate axis units label
    is the unit. ``names``/``units`` as for :func:`save_csv`.
    """
    try:
        import pyuff
    except ImportError:
        raise RotoridError(f"writing {path} needs the pyuff package (pip install pyuff)") from None
    cols = _lab_columns(rec, path, names, units, max_name=_UFF_ID_LEN, max_unit=_UFF_LABEL_LEN)
    x = rec.t
    sets = []
    for canonical, (lab, unit, data) in zip(rec.channels, cols):
        q = QUANTITY.get(canonical)
        plane = canonical[-1] if canonical in KNOWN and canonical[-1] in "12" else "0"
        direction = {"x": 1, "y": 2}.get(canonical.lstrip("p")[:1], 0) if plane != "0" else 0
        # every field pyuff's writer reads is given: some versions lack defaults for a few of them
        sets.append({
            "type": 58, "binary": 0, "id1": lab, "id2": "rotorid", "id3": "NONE", "id4": "NONE", "id5": "NONE",
            "func_type": 1, "func_id": 0, "ver_num": 0, "load_case_id": 0,
            "rsp_ent_name": "NONE", "rsp_node": int(plane), "rsp_dir": direction,
            "ref_ent_name": "NONE", "ref_node": 0, "ref_dir": 0,
            "ord_data_type": 4, "abscissa_spacing": 1, "abscissa_min": float(x[0]),
            "abscissa_inc": 1.0 / rec.fs_hz, "z_axis_value": 0.0,
            "abscissa_spec_data_type": 17, "abscissa_len_unit_exp": 0, "abscissa_force_unit_exp": 0,
            "abscissa_temp_unit_exp": 0, "abscissa_axis_lab": "Time", "abscissa_axis_units_lab": "s",
            "ordinate_spec_data_type": _UFF_DATA_TYPE.get(q, 0), "ordinate_len_unit_exp": 0,
            "ordinate_force_unit_exp": 0, "ordinate_temp_unit_exp": 0, "ordinate_axis_lab": "NONE",
            "ordinate_axis_units_lab": unit or "NONE",
            "orddenom_spec_data_type": 0, "orddenom_len_unit_exp": 0, "orddenom_force_unit_exp": 0,
            "orddenom_temp_unit_exp": 0, "orddenom_axis_lab": "NONE", "orddenom_axis_units_lab": "NONE",
            "z_axis_spec_data_type": 0, "z_axis_len_unit_exp": 0, "z_axis_force_unit_exp": 0,
            "z_axis_temp_unit_exp": 0, "z_axis_axis_lab": "NONE", "z_axis_axis_units_lab": "NONE",
            "data": data, "x": x,
        })
    with _atomic_write(path) as tmp:
        try:
            pyuff.UFF(tmp).write_sets(sets, mode="overwrite")
        except Exception as exc:  # pyuff wraps every failure in a bare Exception
            raise RotoridError(f"cannot write {path} as UFF 58: {_describe(exc)}") from None
