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

SHAPES = ("rectangular", "trapezoid", "rc", "smooth", "notch")


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
        if self.kind not in SHAPES:
            raise ValueError(f"kind must be one of {SHAPES}, got {self.kind!r}")

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
    t = np.asarray(t, dtype=float)
    ev = np.asarray(event_times, dtype=float)
    if ev.ndim != 1 or ev.size < 1:
        raise ValueError("event_times must be a non-empty 1-D array")
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
    return v


def event_times(speed_rpm: float, duration_s: float, *, t0_s: float = 0.0, mark_time_s: float = 0.0137):
    """Event times of a steady speed: one every revolution from ``mark_time_s`` (s after t0)."""
    period = 60.0 / float(speed_rpm)
    n = int(np.floor((duration_s - mark_time_s) / period)) + 1
    return t0_s + mark_time_s + period * np.arange(max(n, 0))
