"""NI TDMS files (nptdms): groups of channels with waveform properties.

Every channel of every group is a channel, addressed in ``channel_map`` as ``"Group/Channel"``
or as ``"Channel"`` when no other group has a channel of that name. ``group=`` reads one group
only (a test day saved as one group per run); :func:`list_groups` lists them. Sample rate from
``wf_increment`` (``fs_hz`` is used only for channels without one), start time from
``wf_start_offset``, unit from ``unit_string``.

A channel that is a time axis is used as its group's time base, like a CSV time column, instead
of as a data channel: a channel named ``t``, ``time``, ``zeit``, ``time_s``, ``Time (s)``,
``Time [ms]``... (else one holding timestamps, else one whose ``unit_string`` is a time unit), or
the one ``time_column=`` names (``time_column=False``: none). Its steps must be uniform; it gives
the start time and, for channels without ``wf_increment``, the rate (with ``wf_increment`` both
must agree). A timestamp channel (TDMS time stamps, UTC) counts seconds from its first sample:
t0 = 0 and meta ``"start_time"`` holds the absolute start as an ISO string (with several groups,
from the earliest one). Timestamps may be quantized to 1 µs, as many writers store them.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import RotoridError
from ..recording import Recording, SegmentedRecording
from ._common import _TIME_UNITS, _TIMESTAMP_TICK, _atomic_write, _cannot, _describe, _lab_columns, _Raw, \
    _Read, _same_rate, _snap_rate, _split_unit, _time_base, _time_factor, _time_name_unit, _warn

__all__ = ["list_groups", "save_tdms", "save_tdms_segmented"]

# phrases of nptdms's warnings about truncated or inconsistent segments (reader/tdms_segment)
_TDMS_DAMAGE = ("incomplete", "less data", "chunk size", "cropping", "segment")


def _nptdms():
    try:
        import nptdms
    except ImportError:
        raise RotoridError("reading and writing TDMS files needs the nptdms package (pip install nptdms)") from None
    return nptdms


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


def list_groups(path) -> list[str]:
    """The names of the groups of a TDMS file, in file order (reads the metadata only).

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> from rotorid.recording import Recording
    >>> from rotorid.io import save_tdms, list_groups
    >>> path = os.path.join(tempfile.mkdtemp(), "day.tdms")
    >>> save_tdms(Recording(1000.0, {"x1": np.zeros(8)}), path, group="Run 1")
    >>> list_groups(path)
    ['Run 1']
    """
    from .._validate import path as _path

    _path("path", path)
    if not Path(path).is_file():
        raise RotoridError(f"cannot read {path}: " + ("it is a directory" if Path(path).is_dir() else "no such file"))
    nptdms = _nptdms()
    try:
        return [g.name for g in nptdms.TdmsFile.read_metadata(os.fspath(path)).groups()]
    except Exception as exc:  # nptdms raises ValueError, struct.error, KeyError ... on bad files
        raise _cannot(path, "tdms", _describe(exc)) from None


def _read_tdms_file(path: Path) -> list:
    """[(group name, [(channel name, properties, data)])] of the whole file."""
    nptdms = _nptdms()
    with _nptdms_log() as log:
        try:
            # raw timestamps: full TDMS precision (2^-64 s) rather than datetime64[us]
            tdms = nptdms.TdmsFile.read(os.fspath(path), raw_timestamps=True)
            groups = [(g.name, [(c.name, dict(c.properties), c[:]) for c in g.channels()]) for g in tdms.groups()]
        except Exception as exc:
            raise _cannot(path, "tdms", _describe(exc)) from None
    damage = [r.getMessage() for r in log if any(w in r.getMessage().lower() for w in _TDMS_DAMAGE)]
    if damage:
        raise _cannot(path, "tdms", f"the file is truncated or damaged (nptdms: {'; '.join(damage)})")
    for r in log:
        _warn(f"{path}: nptdms: {r.getMessage()}")
    return groups


def _is_timestamp(data) -> bool:
    dtype = getattr(data, "dtype", None)
    if dtype is None:
        return False
    return dtype.kind == "M" or {"seconds", "second_fractions"} <= set(dtype.names or ())


def _time_candidates(chans, gname, time_column) -> list[int]:
    if time_column is False:
        return []
    if isinstance(time_column, str):
        return [i for i, (c, _, _) in enumerate(chans) if time_column in (c, f"{gname}/{c}")]
    tiers = ([], [], [])
    for i, (cname, props, data) in enumerate(chans):
        unit = props.get("unit_string")
        if _time_name_unit(_split_unit(cname)[0])[0]:
            tiers[0].append(i)
        elif _is_timestamp(data):
            tiers[1].append(i)
        elif isinstance(unit, str) and unit.strip().lower() in _TIME_UNITS:
            tiers[2].append(i)
    return next((t for t in tiers if t), [])


def _time_axis(key, cname, props, data):
    """(seconds from the first sample or as stored, tick, absolute start as datetime64[ns] or None)."""
    where = f"time channel {key!r}"
    names = getattr(data.dtype, "names", None) or ()
    if "seconds" in names:
        s, f = data["seconds"].astype(np.int64), data["second_fractions"]
        if s.size == 0:
            raise RotoridError(f"{where}: it holds no samples")
        t = (s - s[0]).astype(np.float64) + (f.astype(np.float64) - float(f[0])) * 2.0 ** -64
        # TDMS counts seconds since 1904-01-01 UTC plus 2^-64 s fractions; to the nearest ns
        start = (np.datetime64("1904-01-01T00:00:00", "ns") + np.timedelta64(int(s[0]), "s")
                 + np.timedelta64(round(float(f[0]) * 2.0 ** -64 * 1e9), "ns"))
        return t, _TIMESTAMP_TICK, start
    if data.dtype.kind == "M":
        if data.size == 0:
            raise RotoridError(f"{where}: it holds no samples")
        unit = np.datetime_data(data.dtype)[0]
        tick = float(np.timedelta64(1, unit) / np.timedelta64(1, "ns")) * 1e-9
        return (data - data[0]) / np.timedelta64(1, "s"), max(tick, 0.0), data[0].astype("datetime64[ns]")
    if data.dtype.kind not in "iuf" or data.ndim != 1:
        raise RotoridError(f"{where}: its data are neither numbers nor timestamps (dtype {data.dtype})")
    name_unit = _split_unit(cname)[1] or _time_name_unit(_split_unit(cname)[0])[1]
    stated = props.get("unit_string")
    unit = (str(stated).strip() or None) if stated is not None else None
    return data.astype(np.float64) * _time_factor(unit or name_unit, where), 0.0, None


@dataclass
class _Axis:
    """A group's time channel and what it gives (or why it cannot be used)."""

    index: int                    # of the channel in its group
    key: str                      # "Group/Channel"
    fs: float | None = None
    t0: float | None = None
    rtol: float = 1e-6            # to compare its rate with wf_increment
    n: int = 0
    start: object = None          # absolute start (datetime64[ns]) of a timestamp channel
    problem: str | None = None


def _tdms_read(path, groups, group=None, time_column=None) -> _Read:
    """The channels of the selected group (or all groups), each with its group's time base."""
    all_names = [g for g, _ in groups]
    if group is not None:
        groups = [(g, chans) for g, chans in groups if g == group]
        if not groups:
            raise RotoridError(f"{path} has no group {group!r}; its groups: {all_names}")
        if not groups[0][1]:
            raise RotoridError(f"group {group!r} of {path} holds no channels")
    axes, starts, ref = {}, [], None
    for gname, chans in groups:
        found = _time_candidates(chans, gname, time_column)
        if len(found) > 1:
            raise RotoridError(f"{path}: group {gname!r} has several time channels "
                               f"{[chans[i][0] for i in found]}; choose one with time_column= (False: none)")
        if found:
            axis = axes[gname] = _Axis(found[0], f"{gname}/{chans[found[0]][0]}")
            try:
                t, tick, axis.start = _time_axis(axis.key, *chans[axis.index])
                axis.fs, axis.t0 = _time_base(f"time channel {axis.key!r}", t, tick=tick, kind="channel")
                axis.rtol = 1e-6 + 2 * tick / (t[-1] - t[0])  # timestamps: their quantization over the span
                axis.fs = _snap_rate(axis.fs, axis.rtol) if tick else axis.fs
                axis.n = t.size
            except RotoridError as exc:  # raised only if a channel of this group is used
                axis.problem, axis.start = str(exc), None
            if axis.start is not None:
                starts.append(axis.start)
    if isinstance(time_column, str) and not axes:
        raise RotoridError(f"time_column={time_column!r} is not a channel of {path}; the file has "
                           f"{[f'{g}/{c}' for g, chans in groups for c, _, _ in chans]}")
    meta = {"group": group} if group is not None else {}
    if starts:
        ref = min(starts)
        meta["start_time"] = str(np.datetime_as_string(ref, unit="us", timezone="UTC"))

    raws, group_of = [], {}
    for gname, chans in groups:
        axis = axes.get(gname)
        for i, (cname, props, data) in enumerate(chans):
            if axis and i == axis.index:
                continue
            raws.append(_tdms_raw(gname, cname, props, data, axis, ref))
            group_of[raws[-1].key] = gname
    if not raws:
        raise _cannot(path, "tdms", "it holds no channels" if group is None else f"group {group!r} holds no channels")
    read = _Read(raws, meta)
    full = {g: sorted(c for c, _, _ in chans) for g, chans in groups if chans}
    if len(full) > 1:
        read.address = f"'Group/Channel', or choose one group with group= (one of {list(full)})"
        read.all_same = all(names == next(iter(full.values())) for names in full.values())

        def explain(keys):
            """Advice when the channels ``keys`` lie in groups that all hold the same channels."""
            channel_sets = {tuple(full[group_of[k]]) for k in keys}
            if len(channel_sets) != 1:
                return None
            names = list(channel_sets.pop())
            same = [g for g, n in full.items() if n == names]
            return (f"the file holds {len(same)} groups with the same channels ({names}); choose one with "
                    f"group= (one of {same}), or name each channel as 'Group/Channel' in channel_map")

        read.explain = explain
    return read


def _tdms_raw(gname, cname, props, data, axis: _Axis | None, ref) -> _Raw:
    """One channel; with its group's time axis, which gives its start and (without wf_increment) rate."""
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
    if axis is None or raw.problem:
        return raw
    if axis.problem:
        raw.problem = axis.problem
    elif data.size != axis.n:
        raw.problem = f"it has {data.size} samples, its group's time channel {axis.key!r} has {axis.n}"
    elif raw.fs is not None and not _same_rate(raw.fs, axis.fs, axis.rtol):
        raw.problem = (f"its wf_increment gives {raw.fs:.9g} Hz, the time channel {axis.key!r} gives "
                       f"{axis.fs:.9g} Hz")
    else:
        raw.fs = raw.fs if raw.fs is not None else axis.fs
        # timestamp channels of several groups share one clock: seconds from the earliest start
        shift = float((axis.start - ref) / np.timedelta64(1, "ns")) * 1e-9 if axis.start is not None else 0.0
        raw.t0 = axis.t0 + shift
    return raw


def _read_tdms(path: Path, group=None, time_column=None) -> _Read:
    return _tdms_read(path, _read_tdms_file(path), group, time_column)


def _check_dtype(dtype):
    try:
        dtype = np.dtype(dtype)
    except (TypeError, ValueError):
        raise RotoridError(f"dtype must be 'float64' or 'float32', got {dtype!r}") from None
    if dtype not in (np.float64, np.float32):
        raise RotoridError(f"dtype must be 'float64' or 'float32', got {dtype!r}")
    return dtype


def _group_objects(nptdms, rec, path, group, names, units, dtype) -> list:
    if not isinstance(group, str) or not group.strip() or "/" in group:
        raise RotoridError(f"cannot write {path}: a group must be a non-empty name without '/', got {group!r}")
    cols = _lab_columns(rec, path, names, units, forbid="/")
    objects = [nptdms.GroupObject(group)]
    for lab, unit, data in cols:
        props = {"wf_increment": 1.0 / rec.fs_hz, "wf_start_offset": float(rec.t0_s), "wf_samples": int(data.size)}
        if unit:
            props["unit_string"] = unit
        objects.append(nptdms.ChannelObject(group, lab, data.astype(dtype), properties=props))
    return objects


def save_tdms(rec: Recording, path, group: str = "rotorid", names=None, units=None, dtype="float64") -> None:
    """Write ``rec`` as TDMS: one group, one channel per recording channel.

    Each channel carries ``wf_increment`` (1/fs), ``wf_start_offset`` (t0), ``wf_samples`` and
    ``unit_string``.

    Parameters
    ----------
    rec : Recording
    path : str or path-like
    group : str
        Name of the group (no '/').
    names, units : dict, optional
        As for :func:`rotorid.io.save_csv`.
    dtype : {"float64", "float32"}
        float64 is exact; float32 is half the size, ~7 significant digits, as many DAQs store.
    """
    from .._validate import path as _path

    _path("path", path)
    dtype = _check_dtype(dtype)
    nptdms = _nptdms()
    objects = [nptdms.RootObject(properties={"name": Path(path).stem})]
    objects += _group_objects(nptdms, rec, path, group, names, units, dtype)
    with _atomic_write(path) as tmp, nptdms.TdmsWriter(tmp) as writer:
        writer.write_segment(objects)


def save_tdms_segmented(seg: SegmentedRecording, path, groups=None, names=None, units=None,
                        dtype="float64") -> None:
    """Write a segmented recording as TDMS: one group per block, in block order.

    Each block's channels carry its own ``wf_start_offset``, so :func:`rotorid.io.load_segmented`
    with ``groups="*"`` gives the blocks back with their start times.

    Parameters
    ----------
    seg : SegmentedRecording
    path : str or path-like
    groups : list of str, optional
        One group name per block (default ``"block 0"``, ``"block 1"``, ...).
    names, units, dtype
        As for :func:`save_tdms`.

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> from rotorid.recording import SegmentedRecording
    >>> from rotorid.io import save_tdms_segmented, list_groups
    >>> seg = SegmentedRecording.from_arrays(1000.0, {"x1": np.zeros((2, 8))})
    >>> path = os.path.join(tempfile.mkdtemp(), "steps.tdms")
    >>> save_tdms_segmented(seg, path, groups=["500 rpm", "600 rpm"])
    >>> list_groups(path)
    ['500 rpm', '600 rpm']
    """
    from .._validate import path as _path

    if not isinstance(seg, SegmentedRecording):
        raise RotoridError(f"seg must be a SegmentedRecording, got {type(seg).__name__}")
    _path("path", path)
    if groups is None:
        groups = [f"block {i}" for i in range(len(seg.blocks))]
    elif isinstance(groups, str):
        groups = [groups]
    elif isinstance(groups, (list, tuple)):
        groups = list(groups)
    else:
        raise RotoridError(f"groups must be a list of group names (one per block), got {groups!r}")
    bad = [g for g in groups if not isinstance(g, str)]
    if bad:
        raise RotoridError(f"cannot write {path}: group names must be strings, got {bad!r}")
    if len(groups) != len(seg.blocks):
        raise RotoridError(f"cannot write {path}: {len(groups)} group name(s) for {len(seg.blocks)} blocks")
    if len(set(groups)) != len(groups):
        raise RotoridError(f"cannot write {path}: group names repeat: {groups}")
    dtype = _check_dtype(dtype)
    nptdms = _nptdms()
    objects = [nptdms.RootObject(properties={"name": Path(path).stem})]
    for block, group in zip(seg.blocks, groups):
        objects += _group_objects(nptdms, block, path, group, names, units, dtype)
    with _atomic_write(path) as tmp, nptdms.TdmsWriter(tmp) as writer:
        writer.write_segment(objects)
