"""Keyphasor signals of many shapes, written independently of rotorid's detector.

A test of a keyphasor detector is only as good as the signals it sees. These generators evaluate a
continuous-time pulse train at the sample instants (ideal sampling), with the *event time* of each
pulse defined as the instant its leading edge crosses mid-height between the two states (the
50 % reference level of IEEE Std 181). Shapes:

``"rectangular"``  an ideal step (the 50 % crossing is the step itself)
``"trapezoid"``    linear edges lasting ``edge_samples`` samples, centred on the event
``"rc"``           a rectangular pulse through a first-order low pass of time constant
                   ``edge_samples`` samples (a conditioned optical or magnetic pickup): the
                   exponential edge reaches 50 % at t_step + tau ln 2
``"smooth"``       Gaussian-smoothed edges (erf) of rms width ``edge_samples`` samples
``"notch"``        a proximity probe over a keyway: a gap voltage (default -8 V) that dips to
                   -10 V while the notch passes, with erf edges whose width is a fixed *angle*
                   (the probe's spot size), so it spans fewer samples the faster the rotor turns

Options: duty cycle (pulse width as a fraction of the revolution), polarity by the order of the
two levels, white noise, ringing after each edge, and a slow offset drift of the whole signal.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import RotoridError

SHAPES = ("rectangular", "trapezoid", "rc", "smooth", "notch")
#: most keyphasor events one call generates (each is a pulse evaluated in Python)
MAX_EVENTS = 2_000_000


def _erf(x):
    """Error function, elementwise."""
    return np.vectorize(math.erf, otypes=[float])(x)


@dataclass(frozen=True)
class PulseShape:
    """One shape of keyphasor pulse (see the module doc).

    ``edge_samples``: duration of a trapezoid edge, RC time constant or erf rms width, in samples;
    for ``"notch"`` the erf rms width is ``edge_deg`` degrees of rotation instead. ``duty``:
    pulse width as a fraction of the revolution (never narrower than ``min_width_samples``).
    ``low_v``/``high_v``: the resting and the pulse state (high < low gives negative-going
    pulses). ``ringing``: (amplitude as a fraction of the swing, frequency Hz, decay s) of a
    damped oscillation after each edge; ``drift_v``: amplitude of a slow (``drift_hz``)
    sinusoidal offset of the whole signal.
    """

    kind: str = "trapezoid"
    edge_samples: float = 2.0
    edge_deg: float = 1.5
    duty: float = 0.05
    min_width_samples: float = 4.0
    low_v: float = 0.0
    high_v: float = 5.0
    noise_v: float = 0.0
    ringing: tuple | None = None
    drift_v: float = 0.0
    drift_hz: float = 0.3

    def __post_init__(self):
        from .._validate import choice, number, real_array

        choice("kind", self.kind, set(SHAPES))
        # edge_samples shapes the trapezoid, rc and smooth edges, where zero would give 0/0 (NaN)
        edge_ok = dict(positive=self.kind not in ("rectangular", "notch"), nonneg=True)
        checked = dict(edge_samples=number("edge_samples", self.edge_samples, **edge_ok),
                       edge_deg=number("edge_deg", self.edge_deg, positive=True),
                       duty=number("duty", self.duty, positive=True),
                       min_width_samples=number("min_width_samples", self.min_width_samples, nonneg=True),
                       low_v=number("low_v", self.low_v), high_v=number("high_v", self.high_v),
                       noise_v=number("noise_v", self.noise_v, nonneg=True), drift_v=number("drift_v", self.drift_v),
                       drift_hz=number("drift_hz", self.drift_hz, nonneg=True))
        if not checked["duty"] < 1:
            raise RotoridError(f"duty must be a fraction of the revolution between 0 and 1, got {self.duty!r}")
        if self.ringing is not None:
            r = real_array("ringing", self.ringing, shape=(3,))
            if not (r[1] >= 0 and r[2] > 0):
                raise RotoridError(f"ringing must be (amplitude, frequency >= 0 Hz, decay > 0 s), got {self.ringing!r}")
            checked["ringing"] = tuple(float(v) for v in r)
        for k, v in checked.items():
            object.__setattr__(self, k, v)

    @classmethod
    def notch(cls, **kw):
        kw.setdefault("low_v", -8.0)
        kw.setdefault("high_v", -10.0)
        kw.setdefault("duty", 0.02)
        return cls(kind="notch", **kw)


def _edge(shape: PulseShape, tau, fs_hz: float, period_s):
    """Leading-edge step response e(tau) in [0, 1], e(0) = 0.5; tau in seconds after the event."""
    dt = 1.0 / fs_hz
    if shape.kind == "rectangular":
        return np.where(tau > 0, 1.0, np.where(tau < 0, 0.0, 0.5))
    if shape.kind == "trapezoid":
        e = shape.edge_samples * dt
        return np.clip(tau / e + 0.5, 0.0, 1.0)
    if shape.kind == "rc":
        rc = shape.edge_samples * dt
        u = tau + rc * math.log(2.0)
        return np.where(u > 0, -np.expm1(-np.maximum(u, 0.0) / rc), 0.0)
    if shape.kind == "smooth":
        sig = shape.edge_samples * dt
    else:  # notch: a fixed angle, so a fixed fraction of the period
        sig = shape.edge_deg / 360.0 * period_s
    return 0.5 * (1.0 + _erf(tau / (np.sqrt(2.0) * sig)))


def _settle_samples(shape, per, fs_hz):
    """Samples an edge needs to reach its state (so every pulse reaches full height)."""
    if shape.kind == "rc":
        return 10.0 * shape.edge_samples
    if shape.kind == "smooth":
        return 9.0 * shape.edge_samples
    if shape.kind == "notch":
        return 9.0 * shape.edge_deg / 360.0 * per * fs_hz
    return shape.edge_samples if shape.kind == "trapezoid" else 0.0


def pulse_train(t, event_times, fs_hz: float, shape: PulseShape = PulseShape(), *, seed=0):
    """The keyphasor channel at sample times ``t`` (s) for pulses whose leading edges cross
    mid-height at ``event_times`` (s, increasing).

    Each pulse lasts ``max(duty * period, min_width_samples / fs + settling)`` from its event to the
    mid-height of its trailing edge (period: the interval to the next event, or the previous one
    for the last). Returns volts (float array like ``t``).
    """
    from .._validate import instance, number, real_array
    from .._validate import seed as _seed

    t = real_array("t", t, ndim=1)
    ev = real_array("event_times", event_times, ndim=1)
    fs_hz = number("fs_hz", fs_hz, positive=True)
    instance("shape", shape, PulseShape)
    seed = _seed("seed", seed)
    if ev.size < 1:
        raise RotoridError("event_times must be a non-empty 1-D array")
    if ev.size > MAX_EVENTS:
        raise RotoridError(f"event_times holds {ev.size} events, more than {MAX_EVENTS}")
    if np.any(np.diff(ev) <= 0):
        raise RotoridError("event_times must increase")
    if np.any(np.diff(t) <= 0):
        raise RotoridError("t (the sample times) must increase")
    per = np.diff(ev)
    per = np.r_[per, per[-1] if per.size else 1.0]
    width = np.maximum(shape.duty * per, (shape.min_width_samples + _settle_samples(shape, per, fs_hz)) / fs_hz)
    swing = shape.high_v - shape.low_v
    v = np.full(t.shape, shape.low_v, dtype=float)
    dt = 1.0 / fs_hz
    # the reach of an edge: where it is settled to 1e-12 (RC: 28 tau; erf: 7.5 sigma)
    if shape.kind == "notch":
        reach = 8 * shape.edge_deg / 360.0 * per.max() + 2 * dt
    else:
        reach = (30 * shape.edge_samples + 2) * dt
    for k, (tk, wk, pk) in enumerate(zip(ev, width, per)):
        a = np.searchsorted(t, tk - reach)
        b = np.searchsorted(t, tk + wk + reach + (5 * shape.ringing[2] if shape.ringing else 0.0))
        if b <= a:
            continue
        tau = t[a:b] - tk
        p = _edge(shape, tau, fs_hz, pk) - _edge(shape, tau - wk, fs_hz, pk)
        if shape.ringing:
            amp, f, dec = shape.ringing
            settle = {"trapezoid": 0.5 * shape.edge_samples * dt, "rc": 3 * shape.edge_samples * dt,
                      "smooth": 3 * shape.edge_samples * dt}.get(shape.kind, 0.0)
            if shape.kind == "notch":
                settle = 3 * shape.edge_deg / 360.0 * pk
            r = tau - settle
            p = p + np.where(r > 0, amp * np.exp(-np.maximum(r, 0) / dec) * np.sin(2 * np.pi * f * r), 0.0)
        v[a:b] += swing * p
    if shape.drift_v:
        v += shape.drift_v * np.sin(2 * np.pi * shape.drift_hz * t + 0.7)
    if shape.noise_v:
        v += shape.noise_v * np.random.default_rng(seed).standard_normal(t.shape)
    if not np.all(np.isfinite(v)):
        raise RotoridError(f"shape: the pulse train overflows (low_v {shape.low_v:g} V, high_v {shape.high_v:g} V, "
                           f"noise_v {shape.noise_v:g} V, drift_v {shape.drift_v:g} V)")
    return v


def event_times(speed_rpm: float, duration_s: float, *, t0_s: float = 0.0, mark_time_s: float = 0.0137):
    """Event times of a steady speed: one every revolution from ``mark_time_s`` (s after t0)."""
    from .._validate import number

    period = 60.0 / number("speed_rpm", speed_rpm, positive=True)
    duration_s = number("duration_s", duration_s, nonneg=True)
    t0_s = number("t0_s", t0_s)
    mark_time_s = number("mark_time_s", mark_time_s)
    revs = (duration_s - mark_time_s) / period
    if revs > MAX_EVENTS:
        raise RotoridError(f"duration_s = {duration_s:g} s at speed_rpm = {speed_rpm:g} rpm are {revs:.3g} "
                           f"revolutions, more than {MAX_EVENTS}")
    n = int(np.floor(revs)) + 1
    out = t0_s + mark_time_s + period * np.arange(max(n, 0))
    if not np.all(np.isfinite(out)):
        raise RotoridError(f"event times of speed_rpm = {speed_rpm!r} rpm from t0_s = {t0_s!r} + mark_time_s = "
                           f"{mark_time_s!r} overflow")
    return out
