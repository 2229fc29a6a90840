"""UFF (universal file format) data set 58: function at a node, here the time series of a DAQ.

Every type-58 data set with function type 0 or 1 (general / time response) and real data is a
channel. It is addressed in ``channel_map`` by its ``id1`` (the channel name most programs write
there) and also as ``"<node>:<dir>"`` from its response node and direction, with the direction
codes 1, 2, 3, -1, -2, -3 written ``+X``, ``+Y``, ``+Z``, ``-X``, ``-Y``, ``-Z``: e.g.
``{"3:+X": {"to": "x1", "unit": "mil"}}``. Files whose data sets all carry one ``id1`` (say
"Response") and differ only by node and direction are mapped that way; their channels are then
listed under their ``"<node>:<dir>"`` names. A ``-X``/``-Y`` data set mapped onto an x/y channel
is *not* negated: give ``"scale": -1`` in its channel_map entry if the sensor points the other way.

The sample rate comes from the abscissa increment (or the abscissa values when the spacing is
uneven), in the abscissa units label's time unit (s, ms, us; none is s; another label is refused),
snapped to whole hertz when that fits the E13.5 precision of the abscissa; the start time from the
abscissa minimum; the unit from the ordinate axis units label.
"""

from __future__ import annotations

import math
import os
import re
from collections import Counter
from pathlib import Path

import numpy as np

from ..errors import RotoridError
from ..recording import KNOWN, Recording
from ._common import QUANTITY, _TIME_RTOL, _TIME_UNITS, _atomic_write, _cannot, _describe, _lab_columns, _Raw, \
    _Read, _snap_rate, _warn

__all__ = ["save_uff58"]

# UFF 58: id lines are 80 characters, axis unit labels 20 (fixed-width records)
_UFF_ID_LEN = 80
_UFF_LABEL_LEN = 20
# UFF 58 ordinate "specific data type" per quantity (displacement, excitation force, acceleration)
_UFF_DATA_TYPE = {"length": 8, "force": 13, "acceleration": 12}
#: UFF direction codes -> the "<node>:<dir>" spelling
DIRECTIONS = {1: "+X", 2: "+Y", 3: "+Z", -1: "-X", -2: "-Y", -3: "-Z"}


def _node_dir(ds) -> str | None:
    try:
        node, code = int(ds.get("rsp_node")), int(ds.get("rsp_dir"))
    except (TypeError, ValueError):
        return None
    return f"{node}:{DIRECTIONS[code]}" if code in DIRECTIONS else None


def _read_uff58(path: Path) -> _Read:
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

    found, skipped = [], []
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
        found.append((i, ds, name, data, _node_dir(ds)))

    # the key names a data set in messages and listings: its id1, or "<node>:<dir>" where the id1 is shared
    names = Counter(name for _, _, name, _, _ in found)
    nodes = Counter(nd for _, _, _, _, nd in found)
    raws = []
    for i, ds, name, data, nd in found:
        key = name
        if names[name] > 1:
            key = nd if nd and nodes[nd] == 1 else f"{name} (data set {i})"
        raw = _Raw(key, name, data, aliases=(nd,) if nd else ())
        unit = str(ds.get("ordinate_axis_units_lab", "")).strip()
        raw.unit = unit if unit.upper() not in ("", "NONE") else None
        _uff_time_base(ds, raw)
        raws.append(raw)
    if skipped:
        _warn(f"{path}: ignored type-58 data set(s) that are not real time series: {skipped}")
    if not raws:
        raise _cannot(path, "uff58", "it holds no type-58 time series")
    return _Read(raws, address="'<node>:<dir>' (e.g. '3:+X')")


def _abscissa_seconds(ds, raw: _Raw) -> float | None:
    """Seconds per abscissa unit from the abscissa units label ('s', 'ms', 'us'; none or NONE
    is seconds), or None with ``raw.problem`` set when the label is no time unit (a file in ms
    read as seconds gave a sample rate 1000 times too low)."""
    label = str(ds.get("abscissa_axis_units_lab") or "").strip()
    if not label or label.upper() == "NONE":
        return 1.0
    # "Time (s)", "[s]", "sec.", "Seconds", "msec": the unit word, singular, without brackets
    word = re.sub(r"^.*[(\[]\s*|\s*[)\]].*$", "", label).strip().rstrip(".").lower()
    word = _TIME_WORDS.get(word, word)
    f = _TIME_UNITS.get(word)
    if f is None and ds.get("abscissa_spec_data_type") == 17:
        # the data set says its abscissa is time: seconds, as the format's default
        _warn(f"UFF data set {raw.key!r}: abscissa units label {label!r} is no time unit rotorid knows; its abscissa "
              "is time (specific data type 17): read as seconds")
        return 1.0
    if f is None:
        raw.problem = (f"its abscissa units label is {label!r}, not a time unit ({', '.join(_TIME_UNITS)}): it is "
                       "no time series")
    return f


#: spelled-out time units of UFF abscissa labels, as the keys of _TIME_UNITS
_TIME_WORDS = {"t": "s", "second": "s", "seconds": "s", "secs": "s", "msec": "ms", "msecs": "ms", "millisecond": "ms",
               "milliseconds": "ms", "usec": "us", "usecs": "us", "microsecond": "us", "microseconds": "us"}


def _uff_time_base(ds, raw: _Raw) -> None:
    per = _abscissa_seconds(ds, raw)
    if per is None:
        return
    # the abscissa is stored as E13.5 (6 significant digits): snap to whole hertz when that fits
    inc = float(ds.get("abscissa_inc") or 0.0)
    if ds.get("abscissa_spacing") == 1 and inc > 0:
        raw.fs = _snap_rate(1.0 / (inc * per), 0.5e-5 * 10.0 ** math.floor(math.log10(inc)) / inc)
        raw.t0 = float(ds.get("abscissa_min", 0.0)) * per
        return
    x = np.asarray(ds.get("x"), dtype=np.float64) * per
    span = x[-1] - x[0] if x.size >= 2 else 0.0
    if not span > 0:
        raw.problem = "its abscissa gives no sample interval"
        return
    step = span / (x.size - 1)
    # each abscissa value carries up to 5e-6 relative rounding (E13.5)
    tol = _TIME_RTOL * step + 1e-5 * float(np.max(np.abs(x)))
    if np.max(np.abs(np.diff(x) - step)) > tol:
        raw.problem = "its abscissa values are not uniformly spaced"
    else:
        raw.fs = _snap_rate(1.0 / step, 1e-5 * float(np.max(np.abs(x))) / span + _TIME_RTOL)
        raw.t0 = float(x[0])


def save_uff58(rec: Recording, path, names=None, units=None) -> None:
    """Write ``rec`` as UFF (ASCII): one type-58 time response (double precision) per channel.

    ``id1`` is the channel name, the abscissa runs from t0 in steps of 1/fs (UFF stores both as
    E13.5, 6 significant digits; the reader snaps whole-hertz rates), the ordinate axis units label
    is the unit; canonical channels get response node 1 or 2 (their plane) and direction +X/+Y.

    Parameters
    ----------
    rec : Recording
    path : str or path-like
    names : dict, optional
        {channel: id1 to write it under} (default: the channel names)
    units : dict, optional
        {channel: unit to write it in} (default: the recording's units, SI)
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
