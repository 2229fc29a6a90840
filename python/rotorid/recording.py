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
        if not (np.isfinite(self.fs_hz) and self.fs_hz > 0):
            raise RotoridError(f"fs_hz must be > 0, got {self.fs_hz!r}")
        self.fs_hz = float(self.fs_hz)
        if not self.channels:
            raise RotoridError("a recording needs at least one channel")
        n = None
        chans = {}
        for name, data in self.channels.items():
            a = np.asarray(data, dtype=float)
            if a.ndim != 1:
                raise RotoridError(f"channel {name!r} must be 1-D, got shape {a.shape}")
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
        i0 = max(0, int(round((start_s - self.t0_s) * self.fs_hz)))
        i1 = min(self.n_samples, int(round((stop_s - self.t0_s) * self.fs_hz)))
        return Recording(self.fs_hz, {k: v[i0:i1] for k, v in self.channels.items()}, dict(self.meta),
                         dict(self.units), self.t0_s + i0 / self.fs_hz, self.source)
