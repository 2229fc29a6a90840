"""load_recording and load_segmented: format dispatch, layout options, segmented recordings."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

from ..errors import RotoridError
from ..recording import Recording, SegmentedRecording
from ._channels import _assemble
from ._common import _EXTENSIONS, _LABELS, FORMATS, _positive_rate, _warn
from .clipping import check_clipping

#: the layout options of load_recording and the formats they apply to
_OPTIONS = {"group": ("tdms",), "skip_rows": ("csv",), "sep": ("csv",), "decimal": ("csv",),
            "time_column": ("csv", "tdms")}


def _format(path, fmt) -> str:
    if not isinstance(path, (str, os.PathLike)):
        raise RotoridError(f"path must be a file path, got {path!r}")
    if fmt is None:
        p = Path(path)
        fmt = _EXTENSIONS.get(p.suffix.lower())
        if fmt is None:
            raise RotoridError(f"cannot tell the format of {path} from its extension {p.suffix!r}: use one of "
                               f"{sorted(_EXTENSIONS)} or pass fmt= one of {list(FORMATS)}")
    elif not isinstance(fmt, str) or fmt not in FORMATS:
        raise RotoridError(f"fmt must be one of {list(FORMATS)}, got {fmt!r} (for {path})")
    return fmt


def _check_options(path, fmt, layout: dict) -> dict:
    """The layout options that are set, checked against the format and their types."""
    given = {k: v for k, v in layout.items() if v is not None}
    unknown = sorted(set(given) - set(_OPTIONS))
    if unknown:
        raise RotoridError(f"unknown option(s) {unknown} for {path}; layout options: {list(_OPTIONS)}")
    for name in given:
        if fmt not in _OPTIONS[name]:
            raise RotoridError(f"{name}= does not apply to {path}: it is read as {_LABELS[fmt]}; {name}= applies to "
                               f"{' and '.join(_LABELS[f] for f in _OPTIONS[name])} files")
    skip = given.get("skip_rows")
    if skip is not None and (isinstance(skip, bool) or not isinstance(skip, int) or skip < 0):
        raise RotoridError(f"skip_rows must be an integer >= 0 (lines before the header), got {skip!r} (for {path})")
    group = given.get("group")
    if group is not None and (not isinstance(group, str) or not group):
        raise RotoridError(f"group must be a group name (str), got {group!r} (for {path})")
    tc = given.get("time_column")
    if tc is not None and tc is not False and (not isinstance(tc, str) or not tc.strip()):
        raise RotoridError(f"time_column must be a column name or False, got {tc!r} (for {path})")
    return given


def _check_common(path, fs_hz, meta):
    if fs_hz is not None:
        fs_hz = _positive_rate("fs_hz", fs_hz)
    if meta is not None and not isinstance(meta, Mapping):
        raise RotoridError(f"meta must be a dict, got {type(meta).__name__} (for {path})")
    return fs_hz


def _read(path, fmt, opts):
    """(what the reader found, the stored source of a native file or None)."""
    from .delimited import _read_delimited
    from .native import _read_native
    from .tdms import _read_tdms
    from .uff import _read_uff58

    p = Path(path)
    if not p.is_file():
        raise RotoridError(f"cannot read {path}: " + ("it is a directory" if Path(path).is_dir() else "no such file"))
    if fmt == "native":
        return _read_native(p)
    if fmt == "csv":
        from ._sniff import _norm_decimal, _norm_sep

        sep = _norm_sep(opts.get("sep"))
        decimal = _norm_decimal(opts.get("decimal"), sep)
        read = _read_delimited(p, opts.get("skip_rows"), sep, decimal, opts.get("time_column"))
    elif fmt == "tdms":
        read = _read_tdms(p, opts.get("group"), opts.get("time_column"))
    else:
        read = _read_uff58(p)
    read.meta = {"source_format": fmt, **read.meta}
    return read, None


def _finish(path, fmt, read, stored_source, channel_map, fs_hz, meta, source=None, bare_names=False):
    if fmt == "native":
        rec, stated = _assemble(path, read, channel_map, fs_hz, meta, source=stored_source or str(path),
                                keep_other=True, provenance=channel_map is not None)
    else:
        rec, stated = _assemble(path, read, channel_map, fs_hz, meta, source=source or str(path),
                                bare_names=bare_names)
    check_clipping(rec)
    return rec, stated


def load_recording(path, *, channel_map=None, fs_hz=None, meta=None, fmt=None, group=None, skip_rows=None,
                   sep=None, decimal=None, time_column=None) -> Recording:
    """Read a recording from a native ``.npz``, delimited text, TDMS or UFF 58 file.

    See :mod:`rotorid.io` for the formats and the channel map.

    Parameters
    ----------
    path : str or path-like
        The file; its extension (.npz, .csv, .txt, .asc, .tdms, .uff, .unv) picks the format
        unless ``fmt`` is given.
    channel_map : dict, optional
        {lab channel: {"to": canonical name, "unit": ..., "scale": ..., "offset": ...,
        "delay_s": ..., "angle_deg": ...}}; ``angle_deg`` for a probe mounted at an angle (see
        ``rotorid.probe_angles``).
    fs_hz : float, optional
        Sample rate for files (or channels) that state none; ignored, with a warning if it
        differs, where the file states one.
    meta : dict, optional
        Merged into the recording's meta (these keys win).
    fmt : {"native", "csv", "tdms", "uff58"}, optional
        The format, whatever the extension ("csv" reads any delimited text, e.g. a ``.dat``).
    group : str, optional
        TDMS only: read this group alone.
    skip_rows : int, optional
        Delimited text only: the number of lines before the header (default: found).
    sep : str, optional
        Delimited text only: ``","``, ``";"``, ``"\\t"``, ``"whitespace"``... (default: found).
    decimal : {".", ","}, optional
        Delimited text only: the decimal mark (default: found).
    time_column : str or False, optional
        Delimited text and TDMS: the column/channel that is the time axis (default: found by
        name); False: none.

    Returns
    -------
    Recording
        In SI units; warns about dropped channels and possible clipping.

    Raises
    ------
    RotoridError
        For a file that cannot be read, an option that does not apply to its format, or a
        channel_map that does not fit it; the message names the file.

    Examples
    --------
    >>> import os, tempfile
    >>> from rotorid.io import load_recording
    >>> path = os.path.join(tempfile.mkdtemp(), "run.csv")
    >>> with open(path, "w") as fh:
    ...     _ = fh.write("DAQ 9000 export\\nSample rate: 1000 Hz\\n"
    ...                  "Prox DE X (mil);Prox DE Y (mil)\\n1,0;2,0\\n1,5;2,5\\n2,0;3,0\\n")
    >>> rec = load_recording(path, channel_map={"Prox DE X": {"to": "x1"}, "Prox DE Y": {"to": "y1"}})
    >>> rec.fs_hz, rec.units["x1"], round(float(rec.channels["x1"][1]) / 25.4e-6, 9)
    (1000.0, 'm', 1.5)
    >>> rec.meta["preamble"]
    ['DAQ 9000 export', 'Sample rate: 1000 Hz']
    """
    fmt = _format(path, fmt)
    opts = _check_options(path, fmt, dict(group=group, skip_rows=skip_rows, sep=sep, decimal=decimal,
                                          time_column=time_column))
    fs_hz = _check_common(path, fs_hz, meta)
    read, stored = _read(path, fmt, opts)
    return _finish(path, fmt, read, stored, channel_map, fs_hz, meta)[0]


def load_segmented(source, *, groups=None, channel_map=None, fs_hz=None, meta=None, fmt=None,
                   **layout) -> SegmentedRecording:
    """Read a recording saved as blocks: one file per block, or one TDMS group per block.

    Parameters
    ----------
    source : list of paths, or one TDMS path
        A list of files: one block per file, in list order. One TDMS file: one block per group
        named by ``groups``.
    groups : "*" or list of str, optional
        With a TDMS file: ``"*"`` for every group that holds channels (file order), or the
        group names in block order.
    channel_map, fs_hz, meta, fmt
        As for :func:`load_recording`, applied to every block (``meta`` also to the whole).
    **layout
        The layout options of :func:`load_recording` (``skip_rows``, ``sep``, ``decimal``,
        ``time_column``); not ``group``.

    Returns
    -------
    SegmentedRecording
        Each block's ``t0_s`` is the start time its file states (``wf_start_offset``, time
        column, abscissa); blocks whose file states none are laid back to back after the block
        before them, with a warning. Blocks timed by timestamps (TDMS timestamp channels) share
        one clock: t0 counts from the earliest block's start, meta ``"start_time"``. Start times are taken as stated: blocks may overlap when
        every file starts its time at 0. The meta holds what all blocks' metas share, the
        blocks' sources (``"block_sources"``) and ``meta``.

    Examples
    --------
    >>> import numpy as np, os, tempfile
    >>> from rotorid.recording import SegmentedRecording
    >>> from rotorid.io import save_tdms_segmented, load_segmented
    >>> seg = SegmentedRecording.from_arrays(1000.0, {"x1": np.ones((3, 100)) * 1e-6}, t0_s=[0.0, 5.0, 9.0])
    >>> path = os.path.join(tempfile.mkdtemp(), "steps.tdms")
    >>> save_tdms_segmented(seg, path, groups=["1000 rpm", "2000 rpm", "3000 rpm"])
    >>> [b.t0_s for b in load_segmented(path, groups="*").blocks]
    [0.0, 5.0, 9.0]
    """
    if "group" in layout:
        raise RotoridError("load_segmented takes groups= (one block per group), not group=")
    if isinstance(source, (str, os.PathLike)):
        if groups is None:
            raise RotoridError(f"load_segmented({source!r}): give a list of files (one block each), or a TDMS file "
                               "with groups='*' or a list of group names (one block per group)")
        return _segmented_groups(source, groups, channel_map, fs_hz, meta, fmt, layout)
    if groups is not None:
        raise RotoridError("groups= applies to one TDMS file; with a list of files each file is a block")
    try:
        paths = list(source)
    except TypeError:
        raise RotoridError(f"source must be a list of paths or one TDMS path, got {type(source).__name__}") from None
    if not paths or not all(isinstance(p, (str, os.PathLike)) for p in paths):
        raise RotoridError(f"source must be a non-empty list of paths, got {source!r}")
    loaded = []
    for p in paths:
        f = _format(p, fmt)
        opts = _check_options(p, f, dict(layout))
        rate = _check_common(p, fs_hz, meta)
        read, stored = _read(p, f, opts)
        loaded.append(_finish(p, f, read, stored, channel_map, rate, meta))
    return _segments(loaded, meta, ", ".join(str(p) for p in paths))


def _segmented_groups(path, groups, channel_map, fs_hz, meta, fmt, layout):
    from .tdms import _read_tdms_file, _tdms_read

    fmt = _format(path, fmt)
    if fmt != "tdms":
        raise RotoridError(f"groups= needs a TDMS file; {path} is read as {_LABELS[fmt]}")
    opts = _check_options(path, fmt, dict(layout))
    fs_hz = _check_common(path, fs_hz, meta)
    if not Path(path).is_file():
        raise RotoridError(f"cannot read {path}: " + ("it is a directory" if Path(path).is_dir() else "no such file"))
    content = _read_tdms_file(Path(path))
    names = [g for g, _ in content]
    if isinstance(groups, str) and groups == "*":
        groups = [g for g, chans in content if chans]
        if not groups:
            raise RotoridError(f"{path} holds no group with channels")
    elif not isinstance(groups, (list, tuple)) or not groups or not all(isinstance(g, str) for g in groups):
        raise RotoridError(f"groups must be '*' or a non-empty list of group names, got {groups!r} (for {path})")
    missing = [g for g in groups if g not in names]
    if missing:
        raise RotoridError(f"{path} has no group(s) {missing}; its groups: {names}")
    loaded = []
    for g in groups:
        read = _tdms_read(path, content, g, opts.get("time_column"))
        read.meta = {"source_format": "tdms", **read.meta}
        # (the groups' dropped channels named bare, so that one warning stands for all of them)
        loaded.append(_finish(path, "tdms", read, None, channel_map, fs_hz, meta, source=f"{path} (group {g!r})",
                              bare_names=len(groups) > 1))
    return _segments(loaded, meta, str(path))


def _common_clock(blocks) -> None:
    """Blocks timed by absolute timestamps (meta "start_time", t0 counted from it) are put on one
    clock: t0 counted from the earliest start, which becomes every block's "start_time"."""
    import numpy as np

    stamps = [b.meta.get("start_time") for b in blocks]
    if len(blocks) < 2 or not all(isinstance(s, str) for s in stamps):
        return
    try:
        starts = [np.datetime64(s.rstrip("Z"), "ns") for s in stamps]
    except ValueError:
        return
    ref = min(starts)
    for b, start, stamp in zip(blocks, starts, stamps):
        b.t0_s += float((start - ref) / np.timedelta64(1, "ns")) * 1e-9
        b.meta["start_time"] = stamps[starts.index(ref)]


def _segments(loaded, meta, source) -> SegmentedRecording:
    _common_clock([rec for rec, _ in loaded])
    blocks, laid = [], []
    for i, (rec, stated) in enumerate(loaded):
        if not stated and i > 0:
            prev = blocks[-1]
            rec.t0_s = prev.t0_s + prev.n_samples / prev.fs_hz
            laid.append(rec.source)
        elif not stated:
            laid.append(rec.source)
        blocks.append(rec)
    if laid and len(blocks) > 1:
        _warn(f"{source}: {len(laid)} block(s) state no start time ({laid}); laid back to back, each starting "
              "where the block before it ends")
    first = blocks[0].meta
    common = {k: v for k, v in first.items() if all(k in b.meta and b.meta[k] == v for b in blocks[1:])}
    common["block_sources"] = [b.source for b in blocks]
    common.update(meta or {})
    try:
        return SegmentedRecording(blocks, common, source)
    except RotoridError as exc:
        raise RotoridError(f"{source}: {exc}") from None
