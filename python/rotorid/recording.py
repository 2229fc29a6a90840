"""The data model of a raw recording: sampled channels, sample rate, units and metadata.

Canonical channel names (anything else is kept but ignored by the processing):

    x1, y1, x2, y2         shaft displacement at probe plane 1 (drive end) and 2 (free end), m
    kp                     keyphasor (once-per-revolution pulse), V (any consistent unit)
    force                  impact force, N
    px1, py1, px2, py2     pedestal accelerations at the two bearings, m/s^2 (optional)

All channels of one recording share one sample rate and start time. Data are float64 in SI
units once inside a Recording; readers convert on load (rotorid.units).

Metadata (``meta``, a plain dict, JSON-serializable) understood by the processing:

    kind            "imbalance" | "baseline" | "slow_roll" | "impact"
    speed_rpm       nominal running speed (informative; the keyphasor gives the real one)
    imbalance       {"mass_kg": [m1, m2], "angle_deg": [phi1, phi2]}: added imbalance of the run
    probes_at       "probes" (the rotor's s1, s2; default) or "bearings"
    plane, direction  impact plane (m from the CG, + toward bearing 2) and "x" | "y"
    rig             free text; any other keys are carried along
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import RotoridError

DISPLACEMENTS = ("x1", "x2", "y1", "y2")  # q order [x1, x2, y1, y2]
ACCELEROMETERS = ("px1", "px2", "py1", "py2")  # housing accelerometers, order [xp1, xp2, yp1, yp2] as q
KNOWN = DISPLACEMENTS + ("kp", "force", "px1", "py1", "px2", "py2")
SI_UNITS = {"x1": "m", "x2": "m", "y1": "m", "y2": "m", "kp": "V", "force": "N",
            "px1": "m/s^2", "py1": "m/s^2", "px2": "m/s^2", "py2": "m/s^2"}


@dataclass
class Recording:
    fs_hz: float
    channels: dict
    meta: dict = field(default_factory=dict)
    units: dict = field(default_factory=dict)
    t0_s: float = 0.0
    source: str = ""

    def __post_init__(self):
        from ._validate import number

        self.fs_hz = number("fs_hz", self.fs_hz, positive=True)
        self.t0_s = number("t0_s", self.t0_s)
        if not isinstance(self.channels, dict) or not self.channels:
            raise RotoridError("channels must be a non-empty dict {name: 1-D array of samples}, got "
                               f"{type(self.channels).__name__}")
        if not isinstance(self.meta, dict):
            raise RotoridError(f"meta must be a dict, got {type(self.meta).__name__}")
        self.units = _units(self.units)
        self.source = _source(self.source)
        n = None
        chans = {}
        for name, data in self.channels.items():
            if not isinstance(name, str) or not name:
                raise RotoridError(f"channel names must be non-empty strings, got {name!r}")
            from ._validate import real_array

            a = real_array(f"channel {name!r}", data)
            if a.ndim != 1:
                raise RotoridError(f"channel {name!r} must be 1-D, got shape {a.shape}")
            if a.size == 0:
                raise RotoridError(f"channel {name!r} is empty")
            if n is None:
                n = a.size
            elif a.size != n:
                raise RotoridError(f"channel {name!r} has {a.size} samples, others have {n}: all channels of a "
                                   "recording must share one time base")
            bad = ~np.isfinite(a)
            if bad.any():
                raise RotoridError(f"channel {name!r} contains {int(bad.sum())} NaN/inf samples "
                                   f"(first at sample {int(np.argmax(bad))})")
            chans[name] = a
        self.channels = chans
        for name in chans:
            self.units.setdefault(name, SI_UNITS.get(name, ""))

    @property
    def n_samples(self) -> int:
        return next(iter(self.channels.values())).size

    @property
    def duration_s(self) -> float:
        return self.n_samples / self.fs_hz

    @property
    def t(self) -> np.ndarray:
        return self.t0_s + np.arange(self.n_samples) / self.fs_hz

    def require(self, *names):
        missing = [n for n in names if n not in self.channels]
        if missing:
            raise RotoridError(f"recording {self.source or ''} lacks channel(s) {missing}; it has "
                               f"{sorted(self.channels)} (map lab channel names in the config's [channels])")

    def displacements(self) -> np.ndarray:
        """(4, N) array [x1, x2, y1, y2]."""
        self.require(*DISPLACEMENTS)
        return np.stack([self.channels[c] for c in DISPLACEMENTS])

    def segment(self, start_s: float, stop_s: float) -> "Recording":
        from ._validate import number

        start_s, stop_s = number("start_s", start_s), number("stop_s", stop_s)
        # clipped to the recording before rounding (times far outside it stay whole numbers)
        i0 = int(round(min(max((start_s - self.t0_s) * self.fs_hz, 0.0), self.n_samples)))
        i1 = int(round(min(max((stop_s - self.t0_s) * self.fs_hz, 0.0), self.n_samples)))
        return Recording(self.fs_hz, {k: v[i0:i1] for k, v in self.channels.items()}, dict(self.meta),
                         dict(self.units), self.t0_s + i0 / self.fs_hz, self.source)


@dataclass
class SegmentedRecording:
    """A recording saved as separate blocks (one per speed step, file, TDMS group or array row).

    Every block is a :class:`Recording` with its own start time ``t0_s``; all blocks share the
    sample rate and the channel names. Between blocks the DAQ was not recording, so processing
    (keyphasor, order tracking, compensation) runs per block and never bridges a gap: there is no
    "missing pulse" across a block boundary. ``meta`` describes the whole test (kind, imbalance,
    ...) and is what the chains read; each block keeps its own meta as well.
    """

    blocks: list
    meta: dict = field(default_factory=dict)
    source: str = ""

    def __post_init__(self):
        from ._validate import mapping

        if isinstance(self.blocks, (str, bytes, dict, np.ndarray)):
            raise RotoridError(f"blocks must be a list of Recording, got {type(self.blocks).__name__}")
        try:
            blocks = list(self.blocks)
        except TypeError:
            raise RotoridError(f"blocks must be a list of Recording, got {type(self.blocks).__name__}") from None
        self.meta = mapping("meta", self.meta)
        self.source = _source(self.source)
        if not blocks:
            raise RotoridError("a segmented recording needs at least one block")
        for i, b in enumerate(blocks):
            if not isinstance(b, Recording):
                raise RotoridError(f"block {i} of a segmented recording must be a Recording, got {type(b).__name__}")
        fs, names = blocks[0].fs_hz, set(blocks[0].channels)
        for i, b in enumerate(blocks[1:], 1):
            if abs(b.fs_hz - fs) > 1e-9 * fs:
                raise RotoridError(f"block {i} ({b.source or 'unnamed'}) is sampled at {b.fs_hz:g} Hz, block 0 at "
                                   f"{fs:g} Hz: all blocks of a segmented recording share one sample rate")
            if set(b.channels) != names:
                raise RotoridError(f"block {i} ({b.source or 'unnamed'}) has channels {sorted(b.channels)}, block 0 "
                                   f"has {sorted(names)}")
        self.blocks = blocks
        if not self.meta:
            self.meta = dict(blocks[0].meta)
        if not self.source:
            self.source = blocks[0].source

    @classmethod
    def from_arrays(cls, fs_hz: float, channels: dict, *, t0_s=None, meta=None, units=None,
                    source: str = "") -> "SegmentedRecording":
        """Blocks from 2-D arrays: ``channels[name]`` of shape (n_blocks, n_samples), one row per
        block; ``t0_s`` the start time of each block (default: back to back)."""
        from ._validate import mapping, number, real_array

        fs_hz = number("fs_hz", fs_hz, positive=True)
        meta, units = mapping("meta", meta), mapping("units", units)
        if not isinstance(channels, dict):
            raise RotoridError(f"channels must be a dict {{name: 2-D array (blocks, samples)}}, got "
                               f"{type(channels).__name__}")
        arrays = {}
        for k, v in channels.items():
            try:
                arrays[k] = real_array(f"channel {k!r}", v)
            except RotoridError:
                raise
            except Exception as exc:  # ragged nested lists
                raise RotoridError(f"channel {k!r} must be a 2-D array (blocks, samples): {exc}") from None
        if not arrays:
            raise RotoridError("from_arrays needs at least one channel")
        shapes = {k: a.shape for k, a in arrays.items()}
        first = next(iter(arrays.values()))
        if any(a.ndim != 2 for a in arrays.values()) or len(set(shapes.values())) != 1:
            raise RotoridError(f"from_arrays needs 2-D arrays (n_blocks, n_samples) of one shape, got {shapes}")
        nb, ns = first.shape
        if t0_s is None:
            t0 = np.arange(nb) * ns / fs_hz
        else:
            t0 = real_array("t0_s", t0_s, finite=False)
            if t0.shape != (nb,) or not np.all(np.isfinite(t0)):
                raise RotoridError(f"t0_s must hold {nb} finite start times (one per block), got shape {t0.shape}")
        source = _source(source)
        blocks = [Recording(fs_hz, {k: a[i] for k, a in arrays.items()}, dict(meta), dict(units),
                            float(t0[i]), f"{source} block {i}" if source else f"block {i}") for i in range(nb)]
        return cls(blocks, dict(meta), source)

    @property
    def fs_hz(self) -> float:
        return self.blocks[0].fs_hz

    @property
    def channels(self) -> dict:
        """Channel names (as keys) of the blocks; the data live in ``blocks[i].channels``."""
        return self.blocks[0].channels

    @property
    def units(self) -> dict:
        return self.blocks[0].units

    @property
    def n_samples(self) -> int:
        return sum(b.n_samples for b in self.blocks)

    def require(self, *names):
        for b in self.blocks:
            b.require(*names)


def _units(units):
    """The units of a recording's channels: a dict {name: unit string} (a copy; None: {})."""
    from ._validate import mapping

    units = mapping("units", units)
    for k, v in units.items():
        if not isinstance(k, str) or not isinstance(v, str):
            raise RotoridError(f"units must map channel names to unit strings, got {k!r}: {v!r}"[:300])
    return units


def _source(source):
    """Where a recording came from: a str (a path is turned into one)."""
    import os

    from ._validate import text

    return os.fsdecode(source) if isinstance(source, os.PathLike) else text("source", source)
