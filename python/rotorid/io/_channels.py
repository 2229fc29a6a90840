"""channel_map parsing and the common assembly of a Recording from the channels a reader found."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .. import units as _units
from ..errors import RotoridError
from ..probe_angles import ANGLED, MAX_ANGLE_DEG, MIN_PROBE_SEPARATION_DEG, PLANE_PAIRS, default_angle, resolution
from ..recording import KNOWN, SI_UNITS, Recording
from ._common import QUANTITY, _Raw, _Read, _same_rate, _warn

_MAP_KEYS = ("to", "unit", "scale", "offset", "delay_s", "override_file_unit", "angle_deg")
_MAX_DELAY_S = 1.0  # |delay_s| must stay below this: a larger "delay" is a misread of the unit
#: a displacement channel spanning more than this (m, peak to peak) is refused: proximity probes
#: read 2-4 mm at most, and values in µm or mil read as metres (a file that states no unit) are
#: 1e6 or 4e4 times too large
MAX_PROBE_SPAN_M = 0.01


@dataclass
class _Use:
    """A file channel chosen to become Recording channel ``name``."""

    name: str
    raw: _Raw
    unit: str | None
    unit_from: str                # "channel_map" | "file" | "assumed SI" | "kept as is"
    scale: float = 1.0
    offset: float = 0.0
    delay: float = 0.0            # s by which the channel lags the true quantity
    override: bool = False        # the map's unit replaces a different one the file states
    angle: float | None = None    # deg from +x toward +y the probe measures along (None: x 0, y 90)


def _number(spec, key, default, where):
    v = spec.get(key, default)
    try:
        finite = math.isfinite(float(v))
    except (TypeError, ValueError, OverflowError):  # (an int beyond float's range)
        finite = False
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not finite:
        raise RotoridError(f"{where}: {key!r} must be a finite number, got {v!r}")
    return float(v)


def _parse_channel_map(channel_map, path) -> dict:
    if channel_map is None:
        return {}
    if not isinstance(channel_map, Mapping):
        raise RotoridError(f"channel_map must be a dict lab channel -> {{'to': ..., 'unit': ...}}, "
                           f"got {type(channel_map).__name__} (for {path})")
    out, target_of = {}, {}
    for lab, spec in channel_map.items():
        where = f"channel_map[{lab!r}] (for {path})"
        if not isinstance(lab, str) or not lab.strip():
            raise RotoridError(f"channel_map keys must be non-empty channel names, got {lab!r} (for {path})")
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
        scale = _number(spec, "scale", 1.0, where)
        offset = _number(spec, "offset", 0.0, where)
        if scale == 0:
            raise RotoridError(f"{where}: 'scale' must not be 0")
        v = spec.get("delay_s", 0.0)
        ok = not isinstance(v, bool) and isinstance(v, (int, float, np.integer, np.floating))
        if not (ok and math.isfinite(float(v)) and abs(float(v)) < _MAX_DELAY_S):
            raise RotoridError(f"{where}: 'delay_s' must be a finite number of seconds with |delay_s| < "
                               f"{_MAX_DELAY_S:g} (the lag of channel {to!r} behind the true quantity), got {v!r}")
        override = spec.get("override_file_unit", False)
        if not isinstance(override, (bool, np.bool_)):
            raise RotoridError(f"{where}: 'override_file_unit' must be true or false, got {override!r}")
        if override and unit is None:
            raise RotoridError(f"{where}: 'override_file_unit' needs the 'unit' that replaces the file's")
        angle = spec.get("angle_deg")
        if angle is not None:
            angle = _number(spec, "angle_deg", None, where)
            if abs(angle) > MAX_ANGLE_DEG:
                raise RotoridError(f"{where}: 'angle_deg' must be within ±{MAX_ANGLE_DEG:g} degrees (the direction the "
                                   f"probe measures along, from +x in the direction of rotation), got {angle:g}")
            if to not in ANGLED:
                raise RotoridError(f"{where}: 'angle_deg' is the measuring direction of a probe or housing "
                                   f"accelerometer (x1, y1, x2, y2, px1, py1, px2, py2), not of {to!r}")
        out[lab] = _Use(to, None, unit, "channel_map", scale, offset, float(v), bool(override),
                        angle)  # raw found later
    return out


def _ambiguous(read: _Read, path, what: str, keys: list) -> RotoridError:
    advice = read.explain(keys) if read.explain else None
    if advice and read.all_same:  # a file of runs: choosing the run is the answer
        return RotoridError(f"{path}: {advice} ({what}: {keys})")
    if what.startswith("channel "):
        return RotoridError(f"{what} named in channel_map is ambiguous in {path}: it matches {keys}; "
                            f"{advice or f'name it as {read.address}'}")
    return RotoridError(f"{path} has {what}: {keys}; "
                        f"{advice or f'choose one with channel_map (naming it as {read.address})'}")


def _find(read: _Read, name: str, path) -> _Raw:
    """The file channel ``name`` (full key, else bare name, else alias, if unique)."""
    raws = read.raws
    hits = ([r for r in raws if r.key == name] or [r for r in raws if r.short == name]
            or [r for r in raws if name in r.aliases])
    if len(hits) == 1:
        return hits[0]
    if hits:
        raise _ambiguous(read, path, f"channel {name!r}", [r.key for r in hits])
    raise RotoridError(f"channel {name!r} named in channel_map is not in {path}; the file has "
                       f"{[r.key for r in raws]}")


def _check_stated_unit(use: _Use, path):
    """A RotoridError when channel_map gives a channel a unit of the same quantity as the unit the
    file states for it, but another size (the map would silently win: a probe the file states in
    µm read as mil is 25.4 times too large, and the coefficients off by hundreds of percent with
    every point ok). A file unit rotorid does not know, of another quantity (volts from a probe's
    driver, converted with ``scale``), any ``scale`` other than +-1 (-1 reverses a sensor), or ``override_file_unit`` (the
    file's label is known to be wrong), is the map's to convert."""
    stated = use.raw.unit
    if not stated or use.name not in QUANTITY or abs(use.scale) != 1.0 or use.override:
        return
    try:
        from_file = _units.factor(stated, QUANTITY[use.name])
    except RotoridError:
        return
    mapped = _units.factor(use.unit, QUANTITY[use.name])
    if not math.isclose(from_file, mapped, rel_tol=1e-9):
        raise RotoridError(f"{path}: channel {use.raw.key!r} (-> {use.name}) is stated in the file as {stated!r}, "
                           f"but channel_map gives unit = {use.unit!r}: remove the unit from channel_map to use the "
                           "file's, or, if the file's label is wrong, add override_file_unit = true")


def _select(read: _Read, entries: dict, path, keep_other: bool, bare_names: bool = False) -> list[_Use]:
    """Decide which file channels are used (mapped or canonically named); warn about the rest (by
    their bare names with ``bare_names``: the groups of one TDMS file read one by one then warn
    once, not once per group)."""
    raws = read.raws
    uses, used = [], set()
    for lab, use in entries.items():
        raw = _find(read, lab, path)
        if id(raw) in used:
            raise RotoridError(f"channel_map names file channel {raw.key!r} twice (for {path})")
        used.add(id(raw))
        use.raw = raw
        if use.unit is None:
            use.unit, use.unit_from = (raw.unit, "file") if raw.unit else (SI_UNITS[use.name], "assumed SI")
        else:
            _check_stated_unit(use, path)
        uses.append(use)
    taken = {u.name for u in uses}
    shadowed, dropped, canonical = [], [], {}
    for raw in raws:
        if id(raw) in used:
            continue
        if raw.short in KNOWN:
            if raw.short in taken:
                shadowed.append(raw.short if bare_names else raw.key)
            else:
                canonical.setdefault(raw.short, []).append(raw)
        elif keep_other:
            uses.append(_Use(raw.key, raw, raw.unit, "kept as is"))
        else:
            dropped.append(raw.short if bare_names else raw.key)
    for name, rs in canonical.items():
        if len(rs) > 1:
            raise _ambiguous(read, path, f"several channels named {name!r}", [r.key for r in rs])
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
    if QUANTITY.get(use.name) == "length" and a.size:
        span = float(a.max() - a.min())
        if span > MAX_PROBE_SPAN_M:
            raise RotoridError(f"{path}: channel {raw.key!r} (-> {use.name}) spans {span:.3g} m peak to peak as read in "
                               f"{use.unit!r} (unit from {use.unit_from}): no displacement probe reads more than a few "
                               "mm; state its unit (e.g. unit = \"um\" in channel_map)")
    return a


def _resolve_angled_probes(channels: dict, uses: list, sources: dict, path, fs: float):
    """Probes mounted at angles (``angle_deg``; API 670's are at 45° either side of vertical)
    resolved into the plane's x and y motion, sample by sample (``rotorid.probe_angles``). Both
    channels of the plane must be there, at least ``MIN_PROBE_SEPARATION_DEG`` from parallel, with
    the same ``delay_s`` (the chain compensates a delay per channel; mixing two would leave
    neither). Clipping is looked for in what each probe reads (a probe at its rail leaves no flat
    top in the x and y resolved from it)."""
    from .clipping import check_clipping

    by_name = {u.name: u for u in uses}
    for xn, yn in PLANE_PAIRS:
        ux, uy = by_name.get(xn), by_name.get(yn)
        angled = [u for u in (ux, uy) if u is not None and u.angle is not None]
        if not angled:
            continue
        if ux is None or uy is None:
            u = angled[0]
            other = yn if u is ux else xn
            raise RotoridError(f"{path}: channel {u.raw.key!r} (-> {u.name}) has angle_deg = {u.angle:g}, but there "
                               f"is no {other} channel: a probe at an angle is resolved into x and y with the other "
                               f"probe of its plane; map that probe to {other!r}")
        a = default_angle(xn) if ux.angle is None else ux.angle
        b = default_angle(yn) if uy.angle is None else uy.angle
        r = resolution(a, b)
        if r is None:
            raise RotoridError(f"{path}: the probes of channels {ux.raw.key!r} (-> {xn}, angle_deg {a:g}) and "
                               f"{uy.raw.key!r} (-> {yn}, angle_deg {b:g}) are within {MIN_PROBE_SEPARATION_DEG:g}° "
                               "of parallel: the plane's motion cannot be resolved from them (check angle_deg)")
        if ux.delay != uy.delay:
            raise RotoridError(f"{path}: the angled probes {ux.raw.key!r} (-> {xn}) and {uy.raw.key!r} (-> {yn}) have "
                               f"different delay_s ({ux.delay:g}, {uy.delay:g} s): resolving them into x and y mixes "
                               "the two channels, so they must share one delay")
        ua, ub = channels[xn], channels[yn]
        check_clipping(Recording(fs, {xn: ua, yn: ub}, source=f"{path} (the probes {ux.raw.key!r} at {a:g}° -> {xn} "
                                                               f"and {uy.raw.key!r} at {b:g}° -> {yn}, as read)"))
        channels[xn] = r[0, 0] * ua + r[0, 1] * ub
        channels[yn] = r[1, 0] * ua + r[1, 1] * ub
        sources[xn]["angle_deg"], sources[yn]["angle_deg"] = a, b
        for name, ch in ((xn, channels[xn]), (yn, channels[yn])):
            if QUANTITY.get(name) == "length" and ch.size and float(ch.max() - ch.min()) > MAX_PROBE_SPAN_M:
                raise RotoridError(f"{path}: channel {name} resolved from the angled probes spans "
                                   f"{float(ch.max() - ch.min()):.3g} m peak to peak: no displacement probe reads "
                                   "more than a few mm (check the probes' units and angle_deg)")


def _assemble(path, read: _Read, channel_map, fs_hz, meta, *, source, keep_other=False,
              provenance=True, bare_names=False) -> tuple[Recording, bool]:
    """The Recording, and whether the file stated its start time (False: t0 = 0 by default);
    ``bare_names``: see :func:`_select`."""
    entries = _parse_channel_map(channel_map, path)
    uses = _select(read, entries, path, keep_other, bare_names)
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
        position = {id(r): i for i, r in enumerate(read.raws)}
        uses = sorted(uses, key=lambda u: position[id(u.raw)])
    else:
        uses = sorted(uses, key=lambda u: (KNOWN.index(u.name) if u.name in KNOWN else len(KNOWN), u.name))
    for u in uses:
        channels[u.name] = _convert(u, path)
        units[u.name] = SI_UNITS[u.name] if u.name in QUANTITY else (u.unit or "")
        sources[u.name] = {"file_channel": u.raw.key, "unit": u.unit, "unit_from": u.unit_from,
                           "scale": u.scale, "offset": u.offset}
    _resolve_angled_probes(channels, uses, sources, path, fs)
    merged = dict(read.meta)
    if provenance:
        merged["channel_sources"] = sources
    delays = {u.name: u.delay for u in uses if u.delay != 0.0}
    if delays:
        before = merged.get("channel_delays_s")
        merged["channel_delays_s"] = {**(before if isinstance(before, dict) else {}), **delays}
    merged.update(meta or {})
    try:
        return Recording(fs, channels, merged, units, t0, source), bool(starts)
    except RotoridError as exc:
        raise RotoridError(f"{path}: {exc}") from None
