"""Keyphasor detection: the time of every once-per-revolution event, whatever the pulse looks like.

A 1X phase is only as good as the keyphasor times it is referred to: a timing error δt is a phase
error Ω·δt on every 1X vector, common to all probes and runs at that speed, which the
identification cannot see in its residual (a common phase error is consistent with a different
impedance) but turns into damping errors of several per cent. The detector is therefore built so
that its timing does not depend on the pulse shape, the duty cycle or the trigger level:

1. **State levels** (IEEE Std 181 histogram method). The channel's histogram has two modes: the
   resting state (most samples) and the pulse state. Found from the modes, not from percentiles,
   so a pulse that fills 0.05 % of the samples is found as well as a 50 % square wave. The
   reference level is mid-height between the two states.
2. **Pulses** by a Schmitt trigger around the reference level (default hysteresis: 40 % of the
   swing) on the *leading* edge: the transition from the resting to the pulse state (``edge``
   "auto"), or the rising or falling edge as asked. A keyphasor over a notch gives
   negative-going pulses and works as is.
3. **Edge times**, in two steps. First the crossing of mid-height, linearly interpolated between
   the two samples that straddle it, measured against the local resting level before each edge
   (so a drifting offset does not move it; a base that drifts by more than 3 % of the swing has
   the pulses detected again, and the states read, on the signal less it). Then, when the pulses
   fall at diverse positions relative to the sample clock (8 of 16 bins of a sample interval, or
   for edges that are not steep no gap wider than a quarter sample), an *equivalent-time*
   refinement: all edges of a steady stretch are overlaid at their estimated times, which samples
   the edge shape ``g`` densely; each event time is then the shift that best fits its own samples
   to ``g`` (least squares), and ``g``'s mid-height crossing anchors them. This is unbiased for
   steep ramps (trapezoids of 1-3 samples), asymmetric edges (RC-rounded) and smooth ones alike,
   and it uses every sample of the edge, which lowers the jitter in noise. Steps (steep edges
   with few samples on them) are anchored by the boundary between the overlaid samples below and
   above mid-height, and carry its resolution (the widest gap between the pulses' positions within
   a sample, over √12) as their timing uncertainty; their linear estimate has an error uniform in
   ±0.5 sample that averages out over revolutions only when the pulse phases vary; the result
   says so when they do not (``Keyphasor.note``).
4. **Plausibility**: intervals far shorter than the running median period are extra pulses
   (dropped), intervals that are whole multiples of it are missing pulses (filled), both
   reported; an interval that is neither (a speed jump beyond ``tolerance``) is an error.
5. **Reference**: ``mark_angle_deg`` (the rotor angle at which the keyphasor event occurs,
   measured in the direction of rotation from rotorid's angle zero) and ``delay_s`` (the
   keyphasor channel's lag behind the probes) move the event times to the instants of rotor angle
   zero.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from ..errors import RotoridError
from .edge_shapes import interpolation_bound

#: bins of the equivalent-time edge template per sample interval
TEMPLATE_BINS = 16
#: steady stretches of at most this many pulses share one edge template
TEMPLATE_CHUNK = 256
#: half-width (pulses) of the local quadratic that gives the smooth time base of the refinement
LOCAL_FIT = 8


class KeyphasorError(RotoridError):
    """The keyphasor channel does not give usable once-per-revolution pulses."""


@dataclass
class Keyphasor:
    """Times of rotor angle zero (s), one per revolution, and how they were obtained.

    ``times``: event times after the mark-angle and delay corrections. ``extra``: times of dropped
    extra pulses; ``missing``: (time, count) of gaps filled or left. ``states``: (resting, pulse)
    levels of the channel (V); ``level``/``hysteresis``: the trigger used (V); ``edge``: "rising"
    or "falling" (the edge timed). ``jitter_s``: rms timing jitter per pulse (from the second
    differences of the times, so it includes genuine speed fluctuation); ``rise_samples``: the
    10-90 % edge duration; ``refined``: whether the equivalent-time refinement was used;
    ``note``: anything a user should know about the timing (empty when all is well).
    ``timing_std_s``: the standard uncertainty of the timing that the pulse shape and the sampling
    leave (s), the median over the pulses of ``timing_std_each_s`` (per pulse; None when 0 for
    all). Where the shape leaves mid-height ambiguous (pulses without a flat top, or too short to
    settle): the larger of the difference between the two mid-heights in the note and of how far
    the spread of the sampled peaks moves half of them along the edge; for flat tops the level's
    share where the top does not settle, the noise's, and the equivalent-time correction's own or,
    where it could not be made, the bound of the edge shapes the samples allow; 1/sqrt(3) sample for
    pulses too narrow to show their edges (also with a ``level``); otherwise 0 with a ``level``.
    ``local_std_each_s`` (per pulse, s; None when 0 for all): its part local to each stretch of
    the record, which changes from speed to speed (where the pulses fall between samples, noise,
    the correction's own); the rest is the pulse shape's, common to the record. The imbalance
    chain turns both into a phase uncertainty at each speed (``keyphasor_angle_std_deg``), the
    local part also into each recording's 1X covariance, which a phase calibration keeps.
    """

    times: np.ndarray
    extra: np.ndarray = field(default_factory=lambda: np.zeros(0))
    missing: list = field(default_factory=list)
    level: float = float("nan")
    hysteresis: float = float("nan")
    states: tuple = (float("nan"), float("nan"))
    edge: str = "rising"
    jitter_s: float = float("nan")
    rise_samples: float = float("nan")
    refined: bool = False
    note: str = ""
    mark_angle_deg: float = 0.0
    timing_std_s: float = 0.0
    timing_std_each_s: np.ndarray | None = None
    local_std_each_s: np.ndarray | None = None

    def __post_init__(self):
        # (per-pulse arrays of another length failed deep inside the chain)
        n = np.shape(self.times)[0] if np.ndim(self.times) == 1 else None
        for name in ("timing_std_each_s", "local_std_each_s"):
            v = getattr(self, name)
            if v is not None and (n is None or np.shape(v) != (n,)):
                raise KeyphasorError(f"Keyphasor.{name} must hold one value per pulse time ({n}), got shape "
                                     f"{np.shape(v)}")

    @classmethod
    def from_times(cls, times, *, mark_angle_deg: float = 0.0, delay_s: float = 0.0, source: str = "") -> "Keyphasor":
        """Pulse times given directly (s, one per revolution, increasing): from another system, a
        tachometer file, or a previous analysis. The same corrections apply as for detected
        pulses."""
        from .._validate import number, real_array, text

        try:
            source = text("source", source)
            t = real_array("keyphasor times", times, finite=False)
            mark_angle_deg = number("mark_angle_deg", mark_angle_deg)
            delay_s = number("delay_s", delay_s)
        except RotoridError as exc:
            raise KeyphasorError(str(exc)) from None
        where = f" ({source})" if source else ""
        if t.ndim != 1 or t.size < 2:
            raise KeyphasorError(f"keyphasor times{where} must be a 1-D array of at least 2 times, got shape {t.shape}")
        if not np.all(np.isfinite(t)):
            raise KeyphasorError(f"keyphasor times{where} contain NaN or inf")
        if np.any(np.diff(t) <= 0):
            i = int(np.argmax(np.diff(t) <= 0))
            raise KeyphasorError(f"keyphasor times{where} must increase: time {i + 1} ({t[i + 1]:.6g} s) is not after "
                                 f"time {i} ({t[i]:.6g} s)")
        out = cls(_to_angle_zero(t, mark_angle_deg, delay_s), mark_angle_deg=float(mark_angle_deg))
        out.jitter_s = _jitter(out.times)
        return out

    @property
    def period_s(self):
        return np.diff(self.times)

    @property
    def speed_rpm(self):
        """Speed of each revolution (between consecutive pulses), rpm."""
        return 60.0 / np.diff(self.times)

    @property
    def mid_times(self):
        return 0.5 * (self.times[1:] + self.times[:-1])

    def summary(self) -> str:
        """One line for logs and reports."""
        rpm = np.median(self.speed_rpm) if self.times.size > 1 else float("nan")
        s = (f"{self.times.size} pulses, {rpm:.1f} rpm median, {self.edge} edge, states {self.states[0]:.4g}/"
             f"{self.states[1]:.4g} V, jitter {self.jitter_s * 1e6:.2f} µs")
        if self.refined:
            s += ", equivalent-time refined"
        return s + (f"; {self.note}" if self.note else "")


def _to_angle_zero(t, mark_angle_deg, delay_s):
    """Event times -> times of rotor angle zero: subtract the channel delay, then go back by the
    mark angle's share of the local period (the event happens mark_angle_deg after angle zero)."""
    t = np.asarray(t, dtype=float) - float(delay_s)
    if mark_angle_deg:
        per = np.gradient(t) if t.size > 2 else np.full(t.size, t[-1] - t[0])
        t = t - float(mark_angle_deg) / 360.0 * per
    return t


def _jitter(t):
    if t.size < 5:
        return float("nan")
    d2 = np.diff(t, 2)
    mad = np.median(np.abs(d2 - np.median(d2)))
    return float(1.4826 * mad / np.sqrt(6.0))


# ---------------------------------------------------------------------------------------------
# state levels


def state_levels(v, *, where: str = "", pulse_side: str | None = None) -> tuple:
    """(resting, pulse) state levels of a two-state signal from its histogram modes.

    Raises KeyphasorError for a flat channel, a channel without two distinct states (noise, an
    analog signal) or pulses on both sides of the resting state, unless ``pulse_side`` ("up" or
    "down") says which pulses to use. A train of pulses that dwell at no level (triangles, narrow
    humps) gives the median of their peaks as the pulse level.

    Examples
    --------
    >>> import numpy as np
    >>> from rotorid import signals
    >>> v = np.zeros(1000)
    >>> v[5::100] = v[6::100] = v[7::100] = v[8::100] = 5.0   # 4-sample pulses every 100 samples
    >>> [round(x, 3) for x in signals.state_levels(v)]
    [0.0, 5.0]
    """
    return _state_levels(v, where=where, pulse_side=pulse_side)[:2]


def _state_levels(v, *, where: str = "", pulse_side: str | None = None) -> tuple:
    """:func:`state_levels` and whether the pulse level is the peaks' (no state the pulses dwell at)."""
    from .._validate import real_array, text

    try:
        where = text("where", where)
        v = real_array("v", v, ndim=1)
        if pulse_side is not None and (not isinstance(pulse_side, str) or pulse_side not in ("up", "down")):
            raise RotoridError(f"pulse_side must be 'up', 'down' or None, got {pulse_side!r}")
    except RotoridError as exc:
        raise KeyphasorError(str(exc)) from None
    if v.size == 0:
        raise KeyphasorError(f"no keyphasor pulses{where}: the channel holds no samples")
    vmin, vmax = float(v.min()), float(v.max())
    span = vmax - vmin
    if not span > 1e-12 * max(abs(vmin), abs(vmax), 1e-300):
        raise KeyphasorError(f"no keyphasor pulses{where}: the channel is flat (every sample is {vmin:.6g})")
    nb = 256
    h, e = np.histogram(v, bins=nb, range=(vmin, vmax))
    c = 0.5 * (e[1:] + e[:-1])
    r = int(np.argmax(h))
    rest = c[r]
    far = np.abs(c - rest) > 0.35 * span
    side = np.sign(c - rest)
    up = far & (side > 0)
    dn = far & (side < 0)
    n_up, n_dn = int(h[up].sum()), int(h[dn].sum())
    if n_up == 0 and n_dn == 0:
        raise KeyphasorError(f"no keyphasor pulses{where}: the channel rests at {rest:.4g} and never leaves it by more "
                             f"than a third of its range {vmin:.4g}..{vmax:.4g} (noise only?)")
    if pulse_side is not None:
        pside = up if pulse_side == "up" else dn
        if not pside.any() or h[pside].sum() == 0:
            raise KeyphasorError(f"no keyphasor pulses{where} {'above' if pulse_side == 'up' else 'below'} the resting "
                                 f"level {rest:.4g}")
    else:
        pside = up if n_up >= n_dn else dn
    p = int(np.flatnonzero(pside)[np.argmax(h[pside])])
    pulse = c[p]
    # two distinct states: the histogram must have a valley between them (an edge passes through
    # the middle levels quickly; noise or an analog signal lingers there)
    lo_i, hi_i = sorted((r, p))
    mid_band = h[lo_i + (hi_i - lo_i) * 2 // 5: lo_i + (hi_i - lo_i) * 3 // 5 + 1]
    near_pulse = h[max(p - 3, 0): p + 4]
    other = dn if pside is up else up
    sgn = 1.0 if pside is up else -1.0
    two_states = near_pulse.max() >= 2 and mid_band.mean() < 0.5 * near_pulse.max()
    peak = None
    if two_states:
        # a state is a level the pulses dwell at (counted within 3 noise widths of the mode). Pulses
        # without one, sampled at the same phases every revolution (a speed commensurate with the
        # sample rate), pile their samples into modes too, about one sample per pulse each: such a
        # mode was taken for the pulse state (a hump's flank at 37 % of its peak, timed 0.27 samples
        # early at exactly 6,000 rpm)
        reach = max(3, int(np.ceil(3.0 * _rest_noise(v, rest, abs(pulse - rest)) / (e[1] - e[0]))))
        dwelling = h[max(p - reach, 0): p + reach + 1].sum()
        inside = ((v > 0.5 * (rest + pulse)) == (pulse > rest)).astype(np.int8)
        crossings = np.count_nonzero(np.diff(inside) == 1)
        if dwelling < DWELL_SAMPLES * max(crossings, 1):
            peak = _peaked_pulses(v, rest, h[pside].sum(), h[other].sum(), sgn)
            if peak is None and pulse_side is None:
                # (with a level and an edge the caller times the pulses: the mode serves as it is)
                raise KeyphasorError(f"no keyphasor pulses{where}: the channel's level {pulse:.4g} holds "
                                     f"{dwelling / max(crossings, 1):.2g} sample(s) per pulse, no state the pulses "
                                     f"dwell at, and the samples away from its rest at {rest:.4g} form no train of "
                                     "like pulses (give a trigger level and edge)")
    else:
        peak = _peaked_pulses(v, rest, h[pside].sum(), h[other].sum(), sgn)
        if peak is None:
            raise KeyphasorError(f"no keyphasor pulses{where}: the channel shows no two distinct states (resting near "
                                 f"{rest:.4g}, no second level it dwells at, and no train of like pulses on one side "
                                 "of it; noise or an analog signal?)")
    if peak is not None:
        # pulses that rise to a peak and fall (triangles, narrow humps) have no state to dwell at:
        # the median of their peaks is the pulse level (the detection then times them at half of it)
        swing = abs(peak - rest)
        return _fine_mode(v, rest, swing, _rest_noise(v, rest, swing)), peak, True
    if pulse_side is None and other.any() and h[other].sum() >= 0.25 * h[pside].sum() and \
            h[other].max() >= 0.5 * near_pulse.max():
        o = int(np.flatnonzero(other)[np.argmax(h[other])])
        raise KeyphasorError(f"keyphasor pulses on both polarities{where}: the channel rests at {rest:.4g} and dwells "
                             f"at {pulse:.4g} and at {c[o]:.4g}; say which pulses to use with edge = \"rising\" "
                             f"(pulses above the rest) or \"falling\" (below) and a level between the rest and them")
    # refine each state: the mode of a finer histogram of the samples near it, then the mean of the
    # samples within a few noise widths of that mode (edge samples must not pull a state level)
    swing = abs(pulse - rest)
    noise = _rest_noise(v, rest, swing)
    rest = _fine_mode(v, rest, swing, noise)
    pulse = _fine_mode(v, pulse, swing, noise)
    return rest, pulse, False


#: samples per pulse below which a histogram mode is no state the pulses dwell at (a symmetric
#: pulse sampled at the same phases every revolution puts two samples per pulse at one level)
DWELL_SAMPLES = 3.5


def _rest_noise(v, rest, swing):
    """Robust noise of the resting state: the MAD (as a standard deviation) of the samples within
    6 % of ``swing`` of ``rest`` (0 when there are none)."""
    near = v[np.abs(v - rest) <= 0.06 * swing]
    return 1.4826 * float(np.median(np.abs(near - np.median(near)))) if near.size else 0.0


def _peaked_pulses(v, rest, n_side, n_other, sgn):
    """The median peak of a train of pulses without a flat top, or None when the samples away from
    ``rest`` are not such a train. ``n_side``, ``n_other``: samples beyond 35 % of the range on the
    pulses' side and on the other; ``sgn``: +1 for pulses above the rest. A train: excursions on one
    side only (noise leaves the rest both ways alike), filling under a quarter of the record (not an
    analog signal's half waves), resting in between, at least three of them, most at steady intervals (each within 15 %
    of the one before, or a whole multiple of it where a pulse was not sampled: random spikes come
    at any interval), their sampled peaks within a factor of about two (a pulse of one or two samples
    is sampled anywhere on its peak)."""
    if n_other > 0.05 * n_side:
        return None
    w = sgn * (v - rest)
    top = float(w.max())
    above = w > 0.5 * top
    if above.mean() >= 0.25:
        return None
    starts = np.flatnonzero(np.diff(above.astype(np.int8)) == 1) + 1
    if above[0]:
        starts = np.r_[0, starts]
    if starts.size < 3:
        return None
    gaps = np.diff(starts).astype(float)
    if gaps.size >= 2:
        ratio = gaps[1:] / gaps[:-1]
        ratio = np.where(ratio < 1.0, 1.0 / ratio, ratio)
        steady = np.abs(ratio - np.round(ratio)) <= 0.15 * np.round(ratio)
        if steady.mean() < 0.6:
            return None
    peaks = np.maximum.reduceat(w, starts)
    tall = float(np.median(peaks))
    if np.subtract(*np.percentile(peaks, [75, 25])) > 0.5 * tall:
        return None
    # between pulses the channel rests: most samples within 10 % of the pulses' height of the rest
    # (a noisy analog signal, resting nowhere, does not)
    if np.mean(np.abs(w) <= 0.1 * tall) < 0.5:
        return None
    return float(rest + sgn * tall)


def _fine_mode(v, centre, swing, noise):
    sel = v[np.abs(v - centre) <= 0.06 * swing]
    if sel.size < 3:
        return float(centre)
    if not sel.max() - sel.min() > max(1e-9 * swing, 64 * np.spacing(np.abs(sel).max())):
        # one level up to rounding (a clean synthetic or digital pulse whose level carries float
        # round-off, on any offset): 48 bins cannot divide a range of a few ulp of the level
        return float(np.median(sel))
    h, e = np.histogram(sel, bins=48)
    m = 0.5 * (e[np.argmax(h)] + e[np.argmax(h) + 1])
    tight = v[np.abs(v - m) <= max(3.0 * noise, 0.005 * swing)]
    return float(np.median(tight)) if tight.size else float(m)


# ---------------------------------------------------------------------------------------------
# detection


def _schmitt_rises(w, lo_thr, hi_thr):
    """Indices where w (oriented so the timed edge rises) goes above hi_thr after being below lo_thr."""
    st = np.where(w > hi_thr, 1, np.where(w < lo_thr, -1, 0)).astype(np.int8)
    idx = np.arange(w.size)
    last = np.maximum.accumulate(np.where(st != 0, idx, 0))
    held = st[last]
    return np.flatnonzero((held[1:] == 1) & (held[:-1] == -1)) + 1


def _last_below(w, level, at):
    """For each index in ``at``: the last sample index before it with w <= level."""
    idx = np.arange(w.size)
    below = np.maximum.accumulate(np.where(w <= level, idx, -1))
    return below[at]


def keyphasor_times(kp, fs_hz: float, *, t0_s: float = 0.0, level=None, hysteresis=None, edge: str = "auto",
                    mark_angle_deg: float = 0.0, delay_s: float = 0.0, tolerance: float = 0.35,
                    fill_missing: bool = True, refine: bool = True, polarity: str | None = None,
                    max_speed_step: float | None = None, source: str = "") -> Keyphasor:
    """Times of rotor angle zero from a keyphasor channel (see the module doc for the method).

    Parameters
    ----------
    kp : array_like
        The keyphasor channel (V, or any unit: levels are in the same unit).
    fs_hz : float
        Sample rate, Hz.
    t0_s : float
        Time of the first sample, s.
    level, hysteresis : float, optional
        Trigger level and hysteresis (channel units). Default: mid-height between the two states
        and 40 % of their difference. With ``level`` given, timing uses that level instead of the
        local mid-height.
    edge : {"auto", "rising", "falling"}
        The edge to time. "auto": the leading edge, from the resting state into the pulse.
    mark_angle_deg : float
        Rotor angle (degrees, in the direction of rotation) at which the keyphasor event occurs.
    delay_s : float
        How much the keyphasor channel lags the probe channels (s).
    tolerance : float
        Allowed relative deviation of a pulse interval from the running median period (beyond it:
        extra or missing pulses).
    max_speed_step : float, optional
        Largest relative change of the typical speed from the four revolutions before an interval
        to the four after it (default: ``tolerance``); a larger step is an error (a record joined
        from separate blocks, a wrong channel). Records of dwells joined without their run-up
        between them need it raised, or better, loading as blocks.
    fill_missing : bool
        Fill gaps of whole periods by interpolation (reported either way).
    refine : bool
        Use the equivalent-time edge refinement where the pulse phases allow it.
    polarity : {"auto", "positive", "negative"}, optional
        Older name of ``edge`` ("positive" = "rising", "negative" = "falling").
    source : str
        Name of the file and channel, for messages.

    Returns
    -------
    Keyphasor

    Examples
    --------
    >>> import numpy as np
    >>> from rotorid import signals
    >>> from rotorid.rawsim import PulseShape, event_times, pulse_train
    >>> fs = 10000.0
    >>> t = np.arange(20000) / fs
    >>> true = event_times(3000.7, 2.0)
    >>> kp = signals.keyphasor_times(pulse_train(t, true, fs, PulseShape("trapezoid", 2.0, duty=0.01)), fs)
    >>> err = (kp.times - true[:kp.times.size]) * fs   # samples
    >>> bool(np.abs(err).max() < 0.001), round(kp.level, 3)   # 2-sample edges; triggered at mid-height
    (True, 2.5)
    """
    if not isinstance(source, str):
        raise KeyphasorError(f"source must be a string (the file and channel, for messages), got {source!r}")
    where = f" in {source}" if source else ""
    if np.iscomplexobj(kp):
        raise KeyphasorError(f"the keyphasor channel{where} holds complex values; it is a real signal")
    try:
        x = np.asarray(kp, dtype=float)
    except (TypeError, ValueError):
        raise KeyphasorError(f"the keyphasor channel{where} must hold numbers") from None
    if x.ndim != 1 or x.size < 16:
        raise KeyphasorError(f"the keyphasor channel{where} must be a 1-D signal of at least 16 samples, got shape "
                             f"{x.shape}")
    if not np.all(np.isfinite(x)):
        raise KeyphasorError(f"the keyphasor channel{where} contains NaN or inf")
    from .._validate import number

    try:
        fs_hz = number("fs_hz", fs_hz, positive=True)
        t0_s = number("t0_s", t0_s)
        tolerance = number("tolerance", tolerance)
        mark_angle_deg = number("mark_angle_deg", mark_angle_deg)
        delay_s = number("delay_s", delay_s)
        level = number("level", level, allow_none=True)
        hysteresis = number("hysteresis", hysteresis, allow_none=True, nonneg=True)
        max_speed_step = number("max_speed_step", max_speed_step, allow_none=True, positive=True)
        from .._validate import flag

        fill_missing = flag("fill_missing", fill_missing)
        refine = flag("refine", refine)
    except RotoridError as exc:
        raise KeyphasorError(str(exc)) from None
    if polarity is not None:
        if not isinstance(polarity, str) or polarity not in ("auto", "positive", "negative", "rising", "falling"):
            raise KeyphasorError(f"polarity (older name of edge) must be 'auto', 'positive' or 'negative', got "
                                 f"{polarity!r}")
        edge = {"auto": "auto", "positive": "rising", "negative": "falling"}.get(polarity, polarity)
    if not isinstance(edge, str) or edge not in ("auto", "rising", "falling"):
        raise KeyphasorError(f"edge must be 'auto', 'rising' or 'falling', got {edge!r}")
    if not (0 < tolerance < 1):
        raise KeyphasorError(f"tolerance must be between 0 and 1, got {tolerance!r}")
    if max_speed_step is None:
        max_speed_step = tolerance
    side = None
    if level is not None and edge in ("rising", "falling"):
        # with a level and an edge the user has said which pulses count (e.g. a channel with pulses of
        # both polarities): the resting state lies on the far side of the level from the pulses
        med = float(np.median(x))
        side = "up" if float(level) > med else "down"
    rest, pulse, peaked = _state_levels(x, where=where, pulse_side=side)
    duty = float(np.mean(np.abs(x - pulse) < np.abs(x - rest)))
    ambiguous, unsettled, hump = "", "", ""
    shape_each = 0.0  # samples, per pulse: how much its timing depends on the pulse shape
    level_each, ringing = 0.0, ""  # samples: how much on the level of a top that does not settle
    # samples, per pulse: the part of its uncertainty local to its stretch of the record (where the
    # pulses fall between samples, noise, the correction's own), which changes from speed to speed
    local_each = 0.0
    if edge == "auto":
        if duty > 0.4:
            # a square-ish wave: which state is "resting" is a matter of noise; time the rising edge
            ambiguous = (f"the pulses fill {100 * duty:.0f} % of the record, so which edge leads is ambiguous: the "
                         "rising edge is timed (pass edge='rising' or 'falling' to choose)")
            rest, pulse = min(rest, pulse), max(rest, pulse)
        edge = "rising" if pulse > rest else "falling"
    sgn = 1.0 if edge == "rising" else -1.0
    w = sgn * x
    lo, hi = sorted((sgn * rest, sgn * pulse))  # states in the oriented signal: the timed edge rises lo -> hi
    swing = hi - lo
    lev = 0.5 * (lo + hi) if level is None else sgn * float(level)
    hys = 0.4 * swing if hysteresis is None else float(hysteresis)
    if not (lo < lev < hi):
        raise KeyphasorError(f"level {level!r} is not between the channel's states {rest:.4g} and {pulse:.4g}{where}")
    rises = _schmitt_rises(w, lev - hys / 2, lev + hys / 2)
    if rises.size < 2:
        n_cross = int(np.count_nonzero((w[1:] > lev) & (w[:-1] <= lev)))
        raise KeyphasorError(f"found {rises.size} keyphasor pulse(s){where}, at least two are needed: pulses fill "
                             f"{100 * duty:.2g} % of samples; states {rest:.4g} and {pulse:.4g}; {n_cross} crossing(s) "
                             f"of {sgn * lev:.4g} with hysteresis {hys:.3g}")
    k, rise, per_samples, width, full, half, post, base = _pulse_windows(w, rises, lo, swing, lev, duty, level)
    drifting = ""
    if level is None:
        # a resting level that drifts: detect and time the pulses above their own base. With an offset
        # drifting by 20 % of the swing the histogram's states sat at the drift's opposite extremes (a
        # swing 35 % too large: settled RC pulses judged too short to settle, timed 0.43-0.87 samples
        # late) and the Schmitt trigger missed pulses where the rest rose above its lower threshold
        # (77 of 300 "missing", filled by interpolation, and the equivalent-time correction left out)
        trend = np.zeros(w.size)
        for _ in range(DRIFT_PASSES):
            spread = float(np.percentile(base, 95) - np.percentile(base, 5)) if base.size >= 3 else 0.0
            if not spread > max(DRIFT_FRACTION * swing, 3.0 * _noise(w, lo, swing)):
                break
            step = np.interp(np.arange(w.size), k, base) - lo
            again = _without_drift(w - step, duty)
            # the drift must be slow against the pulses, so that the signal less the base
            # interpolated between them rests at a steadier level (an offset drifting at 10 Hz
            # under pulses at 5.8 Hz, timed 0.14-0.20 samples off through the states of such a
            # signal)
            if again is None or not _rest_spread(w - step, *again[:2]) < 0.75 * _rest_spread(w, lo, hi):
                break
            lo2, hi2, duty2 = again
            lev2, hys2 = 0.5 * (lo2 + hi2), 0.4 * (hi2 - lo2) if hysteresis is None else hys
            rises2 = _schmitt_rises(w - step, lev2 - hys2 / 2, lev2 + hys2 / 2)
            if rises2.size < max(2, rises.size // 2):
                break  # the signal less the base shows fewer pulses: keep the first detection
            w, trend, rises = w - step, trend + step, rises2
            lo, hi, duty, swing, lev, hys = lo2, hi2, duty2, hi2 - lo2, lev2, hys2
            k, rise, per_samples, width, full, half, post, base = _pulse_windows(w, rises, lo, swing, lev, duty, level)
        if np.any(trend):
            drifting = (f"the resting level drifts by {np.ptp(trend):.3g} ({100 * np.ptp(trend) / swing:.0f} % of the "
                        "swing): the pulses are detected and timed above their own base")
            # timed on the signal itself, above each pulse's own base (the trend, linear between the
            # pulses, has kinks at the edges: timing the signal less it moved the edges of pulses on
            # an offset drifting at 10 Hz by 0.24 samples)
            w = w + trend
            base = _local_base(w, k, half, lev + trend[k], lo + trend[k])

    def times_at(level):
        at = _last_below_each(w, rises, level, int(full) + 2, k)
        return at + _linear_crossing(w, at, level)

    def peak_sampling(heights):
        # where a peak is sampled moves it (a corner more than a smooth top, which the parabola
        # lifts): the tallest sampled peaks against the median, as time along the edge at mid-height
        spread = float(np.percentile(heights, 90) - np.median(heights))
        slope = float(np.median(w[k + 1] - w[k]))
        return spread / slope if slope > 0 else 0.0

    if level is None:
        # the swing from the pulses themselves (top after the edge less the base before it): with a
        # drifting offset the histogram modes sit at the drift's extremes and would misjudge it
        top = _local_top(w, k, base, swing, width)
        ok = np.isfinite(top)
        heights = _local_peak(w, k, base, width) - base
        if ok.sum() >= 3:
            flat_swing = float(np.median(top[ok] - base[ok]))
            peak_swing = float(np.median(heights[ok]))
            tol = max(HUMP_TOL, 3.0 * _noise(w, lo, swing) / swing)
            if flat_swing < (1 - tol) * peak_swing and flat_swing < (1 - tol) * swing and \
                    np.mean(_unimodal(w, k[ok], width, tol * swing)) >= 0.5:
                # no flat top (a Gaussian-like hump, or an edge still rising when the pulse ends): the
                # middle of the pulse is no state, its median sits below the top and moves mid-height
                # down the edge (timed 0.03-0.15 samples early); half the peak is the level then
                each = times_at(base + 0.5 * peak_swing) - times_at(base + 0.5 * flat_swing)
                shift = float(np.median(each))
                shape_each = np.maximum(np.abs(each), peak_sampling(heights[ok]))
                swing = peak_swing
                hump = (f"the pulses have no flat top (their middle stays {100 * (1 - flat_swing / peak_swing):.1f} % "
                        f"below their peak): mid-height is taken at half the peak; a level at half their middle "
                        f"would time them {abs(shift):.3f} samples {'earlier' if shift > 0 else 'later'}, which is how "
                        "much the timing depends on the pulse shape here (a phase calibration takes it out)")
            else:
                # a flat top: its level where the pulses have settled most (an RC edge still creeps
                # up through the middle of the pulse)
                settled, level_std = _settled_top(w, k, base, swing, width, _noise(w, lo, swing), trend, half)
                swing = float(np.median(np.where(np.isfinite(settled[ok]), settled[ok], top[ok]) - base[ok]))
                # a level error d moves mid-height by d / 2: time d / (2 s) along an edge of slope s
                slope = float(np.median(w[k + 1] - w[k]))
                if slope > 0 and level_std / (2.0 * slope) >= NEGLIGIBLE_STD:
                    level_each = level_std / (2.0 * slope)
                    ringing = (f"the pulses' tops do not settle (their level depends by {100 * level_std / swing:.2g} % of "
                               "the swing on where along the top it is read: ringing, or an edge still rising), "
                               f"a timing uncertainty of {level_each:.2g} sample")
        if ok.mean() < 0.5:
            # half of each pulse's own peak would time them otherwise: the shape dependence
            peak = float(np.median(heights))
            each = times_at(base + 0.5 * min(peak, swing)) - times_at(base + 0.5 * swing)
            alt = float(np.median(each))
            shape_each = np.maximum(shape_each, np.maximum(np.abs(each), peak_sampling(heights)))
            unsettled = ("most pulses are too short to settle at their upper state: mid-height is taken between the "
                         f"histogram states, and the timing depends on the pulse shape (by {abs(alt):.3f} samples "
                         "between half the states and half the pulses' peak)")
        # with the local base the mid-height moves with any offset drift: find the straddling pair again
        k = _last_below_each(w, rises, base + 0.5 * swing, int(full) + 2, k)
    mid = base + 0.5 * swing if level is None else np.full(k.size, lev)
    smooth = rise >= 2.5
    if level is not None:
        unsettled = ""
    frac = _cubic_crossing(w, k, mid) if smooth else _linear_crossing(w, k, mid)
    t_samples = k + frac
    refined, note = False, ""
    # samples in the pulse state per pulse found (not duty x period: a period counts the pulses the
    # sampling missed too)
    seen = duty * w.size / rises.size
    # (pulses this narrow show no edge to overlay: the equivalent-time correction moved pulses a
    # third of a sample wide by up to 2.9 samples)
    if refine and level is None and seen >= NARROW_SAMPLES:
        t_samples, refined, note, unresolved_std = _refine(w, t_samples, base, swing, half, post, rise)
        if unresolved_std.any():
            shape_each = np.maximum(shape_each, unresolved_std)
            local_each = unresolved_std
        elif smooth and not refined:
            note = ""  # a smooth edge timed by the cubic: the residual interpolation error is small
    narrow = ""
    if seen < NARROW_SAMPLES:
        # a pulse this narrow is seen in one or two samples: its edge lies anywhere within a sample
        # of where it is timed (measured: errors of -0.98 to -0.33 samples for pulses a third of a
        # sample wide), a standard uncertainty of 1/sqrt(3) sample (uniform over +-1 sample); some
        # pulses may not be sampled at all
        shape_each = np.maximum(shape_each, 1.0 / np.sqrt(3.0))
        # local to a dwell only where the pulses fall at the same few positions every revolution;
        # elsewhere they sample the edge at all positions and their mean error is the record's bias
        local_each = np.where(_commensurate(t_samples), np.maximum(local_each, 1.0 / np.sqrt(3.0)), local_each)
        narrow = (f"the pulses are only {seen:.2g} sample(s) wide: their edges fall between samples and are timed only to "
                  "within a sample (record the keyphasor at a higher rate, or widen the mark)")
    fixed = ""
    if level is None and (hump or unsettled or peaked) and not narrow:
        # pulses without a flat top are timed at half their peak; at a speed commensurate with the
        # sample rate every pulse is sampled at the same phases, so where between two samples the
        # apex lies, and how far the sampled peak falls short of it, cannot be seen: uniform over a
        # sample (a triangle rising over 3 samples was timed 0.23 samples early at exactly 3,000
        # rpm and 10 kHz, its peak sampled at 83 %, with no note)
        stuck = _commensurate(t_samples)
        if stuck.any():
            shape_each = np.where(stuck, np.maximum(shape_each, 1.0 / np.sqrt(12.0)), shape_each)
            local_each = np.where(stuck, np.maximum(local_each, 1.0 / np.sqrt(12.0)), local_each)
            fixed = ("the pulses have no flat top and fall at the same phases of the sampling every revolution "
                     f"(a speed commensurate with the sample rate, {100 * stuck.mean():.0f} % of them): their peak "
                     "is sampled short of its apex by an amount that cannot be seen, and their timing is uncertain "
                     "by a third of a sample")
    if not narrow:   # (a pulse a sample wide has no top to read a level on: its 1/sqrt(3) covers it)
        shape_each = np.hypot(shape_each, level_each)
    else:
        ringing = ""
    note = "; ".join(x for x in (ambiguous, drifting, unsettled, hump, ringing, narrow, fixed, note) if x)
    t = t0_s + t_samples / fs_hz
    found = t.copy()
    span_s = (t0_s, t0_s + (w.size - 1) / fs_hz)
    try:
        t, extra, missing = _plausible(t, tolerance, fill_missing, where, max_speed_step)
    except KeyphasorError as exc:
        if narrow:
            raise KeyphasorError(f"{exc}. The pulses are only {seen:.2g} sample(s) wide, so the sampling misses some "
                                 "of them: record the keyphasor at a higher rate, or widen the mark") from None
        # pulses of a fixed angle narrow as the speed rises: wide enough on average, they may be
        # missed at the fastest speeds (notches of 1.5-3 degrees at 12,800 Hz, 0.8-1.3 samples wide
        # at 6000 rpm, were refused as a speed jump that named only blocks and max_speed_step; an
        # independent simulator's finding)
        # (missed pulses leave periods that are 2 or 3 of their neighbours' along the record; a
        # genuine jump between two dwells only the few around it, found in review)
        d = np.diff(t)
        fast = duty * float(np.percentile(d, 5)) * fs_hz if t.size > 20 else np.inf
        uneven = t.size > 20 and int(np.sum(d / _running_median(d, 9) > 1.0 + tolerance)) >= UNEVEN_PERIODS
        if fast >= NARROW_AT_SPEED or not uneven:
            raise
        raise KeyphasorError(f"{exc}. At the fastest speeds the pulses are only {fast:.3g} sample(s) wide "
                             f"({100 * duty:.2g} % of a revolution), so the sampling may miss some of them: record the "
                             "keyphasor at a higher rate, widen the mark, or give a trigger level nearer the rest "
                             "state (level, hysteresis)") from None
    period = float(np.median(np.diff(t))) if t.size > 1 else np.inf
    if t.size > 1 and (t[0] - span_s[0] > UNUSED_PERIODS * period or span_s[1] - t[-1] > UNUSED_PERIODS * period):
        warnings.warn(f"keyphasor{where}: pulses only from t = {t[0]:.4g} to {t[-1]:.4g} s of the record's "
                      f"{span_s[0]:.4g} to {span_s[1]:.4g} s: the rest of the record has no revolutions to analyse "
                      f"(the keyphasor stopped, or pulses {seen:.2g} sample(s) wide fell between samples)")
    times = _to_angle_zero(t, mark_angle_deg, delay_s)
    # each pulse's shape uncertainty, carried to the pulses kept (and filled in) by time
    each_s = np.interp(t, found, np.broadcast_to(shape_each, found.shape)) / fs_hz if np.any(shape_each) else None
    local_s = np.interp(t, found, np.broadcast_to(local_each, found.shape)) / fs_hz if np.any(local_each) else None
    if extra.size:
        warnings.warn(f"keyphasor{where}: dropped {extra.size} extra pulse(s) at t = {np.round(extra[:5], 6)} s")
    if missing:
        what = "filled by interpolation" if fill_missing else "left as gaps"
        warnings.warn(f"keyphasor{where}: {sum(c for _, c in missing)} missing pulse(s) after t = "
                      f"{[round(m[0], 6) for m in missing[:5]]} s ({what})")
    return Keyphasor(times, extra, missing, sgn * lev, hys, (rest, pulse), edge, _jitter(t), rise, refined, note,
                     float(mark_angle_deg), 0.0 if each_s is None else float(np.median(each_s)), each_s, local_s)


def _commensurate(t):
    """Per pulse (edge times ``t`` in samples): whether it lies in a steady stretch of at least 16
    pulses whose edges fall at fewer than half of TEMPLATE_BINS positions within a sample interval
    (the stretches as :func:`_refine` forms them: the period steady to 1 %)."""
    out = np.zeros(t.size, dtype=bool)
    if t.size < 16:
        return out
    per = np.diff(t)
    cut = np.flatnonzero(np.abs(np.diff(per)) > 0.01 * per[1:]) + 2
    for a, b in zip(np.r_[0, cut], np.r_[cut, t.size]):
        if b - a >= 16:
            occupied = np.unique(np.floor(np.mod(t[a:b], 1.0) * TEMPLATE_BINS).astype(int)).size
            out[a:b] = occupied < TEMPLATE_BINS // 2
    return out


#: a speed jump where the pulses at the fastest speeds are narrower than this (samples) names them
#: as its likely cause (missed pulses)
NARROW_AT_SPEED = 2.0
#: ... where at least this many periods exceed their neighbours' by the tolerance (the gaps missed
#: pulses leave; extra pulses and glitches make short ones, which do not count)
UNEVEN_PERIODS = 8
#: pulses narrower than this (samples above mid-height) are timed only to within a sample
NARROW_SAMPLES = 1.5
#: a record whose first pulse comes later, or last pulse earlier, than this many periods from its
#: ends is warned about (the revolutions there are not analysed)
UNUSED_PERIODS = 2.5


def _last_below_each(w, rises, levels, reach, fallback):
    """For each trigger index: the last sample at or before it (looking back at most ``reach``)
    with w <= that pulse's own level; ``fallback`` where none is found."""
    offs = np.arange(reach + 1)
    idx = rises[:, None] - offs[None, :]
    valid = idx >= 0
    below = valid & (w[np.clip(idx, 0, w.size - 1)] <= levels[:, None])
    first = np.argmax(below, axis=1)
    found = below[np.arange(rises.size), first]
    return np.clip(np.where(found, rises - first, fallback), 0, w.size - 2)


def _rise_samples(w, rises, lo, swing):
    """Edge duration in samples, a scale for the edge window: twice the median time from the 25 %
    to the 75 % level (about the 10-90 % duration of common edges; the 25/75 % levels are robust to
    an offset drift), each crossing interpolated linearly."""
    times = []
    for frac in (0.25, 0.75):
        lvl = lo + frac * swing
        k = np.clip(_last_below(w, lvl, rises), 0, w.size - 2)
        times.append(k + _linear_crossing(w, k, np.full(k.size, lvl)))
    d = times[1] - times[0]
    d = d[np.isfinite(d) & (d >= 0)]
    return float(max(2.0 * np.median(d), 0.25)) if d.size else 1.0


#: a drift of the pulses' own base beyond this fraction of the swing (5th to 95th percentile over
#: the pulses, and beyond 3 noise widths) has the pulses detected again on the signal less it
DRIFT_FRACTION = 0.03
#: detection passes on the signal less its drifting base (the first base misses where the
#: first detection missed pulses)
DRIFT_PASSES = 2


def _pulse_windows(w, rises, lo, swing, lev, duty, level):
    """(k, rise, per_samples, width, full, half, post, base) of the pulses triggered at ``rises``:
    the sample before each mid-level crossing, the edge duration, the period and pulse width in
    samples, the edge windows before and after the edge, and each pulse's base just before it
    (the resting state ``lo`` for all with a user's ``level``)."""
    # rough times: the mid-level crossing, linear between the straddling samples, local base level
    k = np.clip(_last_below(w, lev, rises), 0, w.size - 2)
    rise = _rise_samples(w, rises, lo, swing)
    # the edge window: the whole edge, but clear of the pulse's other edge and of the previous pulse
    per_samples = np.median(np.diff(rises)) if rises.size > 1 else w.size
    width = duty * per_samples if duty <= 0.4 else 0.5 * per_samples
    full = max(np.ceil(1.5 * rise) + 2, 3)
    half = int(min(full, 256, max(0.4 * (per_samples - width) - 8, 3)))      # before the edge
    post = int(min(full, 256, max(0.4 * width, 2)))                          # after it
    base = _local_base(w, k, half, lev, lo) if level is None else np.full(k.size, lo)
    return k, rise, per_samples, width, full, half, post, base


def _rest_spread(w, lo, hi):
    """The 5th to 95th percentile range of the samples nearer the resting state ``lo`` than the
    pulse state ``hi``."""
    rest = w[np.abs(w - lo) < np.abs(w - hi)]
    return float(np.percentile(rest, 95) - np.percentile(rest, 5)) if rest.size else np.inf


def _without_drift(w, duty):
    """(lo, hi, duty) of the oriented signal ``w`` less its drifting base: its histogram states,
    which must still be two states with the pulses above the rest; None where they are not (the
    detection then keeps the signal as it is)."""
    try:
        rest, pulse, peaked = _state_levels(w)
    except KeyphasorError:
        return None
    if peaked:
        return None
    lo, hi = sorted((rest, pulse))
    new_duty = float(np.mean(np.abs(w - hi) < np.abs(w - lo)))
    # the same pulses: the pulse state above the rest, filling about as much of the record
    if not (hi - lo > 0 and abs(new_duty - duty) <= 0.5 * duty + 0.01):
        return None
    return lo, hi, new_duty


def _local_base(w, k, half, lev, lo):
    """Resting level just before each edge: median of up to 8 samples before the edge window that
    lie below the trigger level (the global resting state where there are too few). ``lev`` and
    ``lo``: one value, or one per pulse (a drifting rest)."""
    out = np.array(np.broadcast_to(lo, k.shape), dtype=float)
    levs = np.broadcast_to(lev, k.shape)
    for i, ki in enumerate(k):
        a = max(ki - half - 8, 0)
        seg = w[a:max(ki - half, 0)]
        seg = seg[seg < levs[i]]
        if seg.size >= 3:
            out[i] = np.median(seg)
    return out


def _local_top(w, k, base, swing, width):
    """Pulse level of each pulse: the median of the samples in the middle half of the pulse (farthest
    from both edges, so edge shape and ringing matter least); NaN where that is not above 80 % of
    the swing from the pulse's own base (a pulse too short to settle)."""
    a = int(np.floor(0.25 * width)) + 1
    b = max(int(np.ceil(0.75 * width)), a) + 1
    offs = np.arange(a, b)
    idx = np.clip(k[:, None] + offs[None, :], 0, w.size - 1)
    top = np.median(w[idx], axis=1)
    return np.where(top > base + 0.8 * swing, top, np.nan)


#: samples per pulse, just before its trailing edge departs from the top, whose median is the
#: pulse's settled level (:func:`_settled_top`)
SETTLED_SAMPLES = 3
#: a departure from a settled state, as a fraction of the swing (or 5 noise widths of a median
#: over the pulses, if larger)
SETTLED_FRACTION = 1e-4


def _settled_top(w, k, base, swing, width, noise, trend, half):
    """Settled level of each flat-topped pulse (leading edge after sample ``k``, resting at
    ``base``), from the samples before its trailing edge departs from the top: the median of the
    last SETTLED_SAMPLES of them where the pulses still approach their top there (the median
    profile rises toward the trailing edge), else the median of the later half of the top (an
    oscillation, e.g. ringing that has not died out, whose last samples sit at one phase of it);
    NaN where a pulse holds no such samples clear of both edges (the caller keeps the median of its
    middle half). Also the uncertainty of the level: for an approach the rise still to come (from
    its last steps, 0 where they are within the noise); for an oscillation how far
    the later half's level departs from its last half's or from the pulse's middle half's; without
    settled samples how far the middle half's highest per-offset median lies above its median
    (each 0 within twice the noise of such medians).

    The pulse level defines mid-height, and an error δ of it moves the timing by δ / (2 s) with s
    the edge's slope there. The middle of a pulse is not settled where its edge approaches the top
    slowly: an RC edge of time constant τ has the middle of a 24-sample pulse still 0.1 % short,
    which timed it 0.0017 samples early at τ = 2 samples, a damping error of twice its standard
    error at 5,000-6,000 rpm in a 4-run identification. Where the trailing edge departs from the
    top: for a rectangular pulse through any linear filter, both edges are the same step response,
    so the trailing edge leaves the top as long before its mid-height crossing as the leading edge
    leaves the rest before its own; that distance is read from the leading edges (per-offset
    medians over the pulses above SETTLED_FRACTION of the swing, or above 5 noise widths of such a
    median). ``trend``: the resting level's drift (zeros without), taken out between where the
    base was read (``half`` + 4 samples before the edge) and the samples read."""
    n = k.size
    eps = max(SETTLED_FRACTION * swing, 5.0 * noise / np.sqrt(max(n, 1)))
    mid = base + 0.5 * swing
    # the rest where the base was read (the 8 samples before the edge window) moves with the trend
    at_base = trend[np.clip(k - half - 4, 0, w.size - 1)][:, None]

    def above_rest(idx):
        return w[idx] - base[:, None] - (trend[idx] - at_base)

    # the leading edge's departure from the rest: offsets before the sample k (just below mid)
    # (the run of offsets from the edge back: further back lies the previous pulse where pulses fill
    # half the period or more, and its last offset above the rest read the level 11 samples into a
    # pulse at 60 % duty, 0.03 samples off)
    back = np.arange(0, max(int(np.ceil(width)), 4))
    idx = np.clip(k[:, None] - back[None, :], 0, w.size - 1)
    risen = np.median(above_rest(idx), axis=0) > eps
    depart = (int(np.argmin(risen)) if not risen.all() else risen.size) + 1
    # each pulse's trailing mid-height crossing: the first sample below mid after the top
    body = np.arange(2, int(np.ceil(1.5 * width)) + 5)
    idx = np.clip(k[:, None] + body[None, :], 0, w.size - 1)
    below = w[idx] < mid[:, None]
    has = below.any(axis=1)
    last = k + body[np.argmax(below, axis=1)] - 1 - depart
    # the later half of each top, counted back from its last settled sample
    span = int(np.median((last - k - 1)[has])) // 2 if has.any() else 0
    # the middle half of each pulse (as _local_top reads it), above the rest as it drifts
    offs = np.arange(int(np.floor(0.25 * width)) + 1, max(int(np.ceil(0.75 * width)), 2) + 1)
    idx = np.clip(k[:, None] + offs[None, :], 0, w.size - 1)
    middle = above_rest(idx)
    if span < SETTLED_SAMPLES:
        # no samples clear of both edges: the middle half's median, uncertain by as much as the
        # highest level the pulses reach there lies above it (a trapezoid's flat top: 0; the tail
        # of an RC edge or ringing: their departure from the level)
        y = np.median(middle, axis=0)
        above = float(y.max() - np.median(y))
        return np.full(n, np.nan), above if above > 2.0 * eps else 0.0   # (not noise)
    back = np.arange(span)
    idx = np.clip(last[:, None] - back[None, :], 0, w.size - 1)
    usable = has & (last - span + 1 >= k + 2) & (last < w.size)
    # (above the rest as it drifts from the edge to these samples: a drift of 2 % of the swing over
    # a long pulse moved the level read at its end by as much)
    y = above_rest(idx)
    profile = np.median(y[usable], axis=0) if usable.any() else np.zeros(span)
    # still approaching: the profile no lower toward the trailing edge, within its noise, and, where
    # it still rises at the end, by steps that shrink as an approach's do (a ratio r < 0.9: the
    # rest of the rise is then about d r / (1 - r) for a last step d; ringing sampled over a third
    # of its period also rises monotonically, by steps that do not shrink: 0.005 samples off with
    # no uncertainty as an approach)
    d = -np.diff(profile)        # the steps toward the trailing edge, last first
    approaching = np.all(d >= -eps)
    tail = 0.0
    if approaching and d[0] > eps:
        ratio = d[0] / d[1] if d.size > 1 and d[1] > 0 else np.inf
        approaching = ratio < 0.9
        tail = d[0] * ratio / (1.0 - ratio) if approaching else 0.0
    top = np.median(y[:, :SETTLED_SAMPLES] if approaching else y, axis=1) + base
    # an oscillation that has not died out: the level is uncertain by as much as it depends on
    # the window it is read from (the later half, its last half, the middle half of the pulse).
    # Ringing that decays within the pulse leaves them alike; ringing over 1.1 periods of a
    # 15-sample top does not (timed 0.027 samples off)
    spread = tail
    if not approaching and np.ptp(profile) > 2.0 * eps:   # (a flat top's noise is no oscillation)
        later = float(np.median(profile))
        last_half = float(np.median(profile[:max(span // 2, 1)]))
        in_middle = float(np.median(np.median(middle[usable], axis=1))) if usable.any() else later
        spread = max(abs(later - last_half), abs(later - in_middle))
    return np.where(usable, top, np.nan), spread


#: a pulse has no flat top when the median of its middle half is this fraction (or 3 noise widths)
#: below its peak and below the histogram's pulse state, and it rises to one peak and falls
#: (:func:`_unimodal`; ringing lifts the peak, not the middle, and rises and falls more than once)
HUMP_TOL = 0.015


def _noise(w, lo, swing):
    """Robust noise level of the resting state: the MAD of the sample-to-sample differences of the
    samples within 6 % of the swing of it, over sqrt(2) (a slow offset drift does not count)."""
    near = np.abs(w - lo) <= 0.06 * swing
    d = np.diff(w)[near[1:] & near[:-1]]
    return 1.4826 * float(np.median(np.abs(d - np.median(d)))) / np.sqrt(2.0) if d.size else 0.0


def _local_peak(w, k, base, width):
    """Peak of each pulse: its largest sample within the pulse body after the edge at ``k``,
    refined by the parabola through it and its neighbours where both lie above 60 % of
    the pulse (a smooth hump, whose sampled maximum lies below its top by up to an eighth of its
    curvature); not at a corner, where the parabola would overshoot (an RC edge cut off by the
    trailing edge)."""
    body = np.arange(1, int(np.ceil(width)) + 2)
    idx = np.clip(k[:, None] + body[None, :], 1, w.size - 2)
    m = idx[np.arange(k.size), np.argmax(w[idx], axis=1)]
    ym, y0, yp = w[m - 1], w[m], w[m + 1]
    curv = ym - 2.0 * y0 + yp
    smooth = (curv < 0) & (np.minimum(ym, yp) - base >= 0.6 * (y0 - base))
    with np.errstate(divide="ignore", invalid="ignore"):
        lift = np.where(smooth, -(yp - ym) ** 2 / (8.0 * curv), 0.0)
    return y0 + np.clip(lift, 0.0, None)


def _unimodal(w, k, width, tol):
    """Whether each pulse's body (the ``width`` samples after its edge at ``k``) rises to one peak
    and falls from it, within ``tol``: a hump. Ringing after a flat top's edge rises and falls
    more than once (its overshoot lifts the peak, not the top's level)."""
    n = max(int(np.ceil(width)), 2)
    idx = np.clip(k[:, None] + 1 + np.arange(n)[None, :], 0, w.size - 1)
    y = w[idx]
    p = np.argmax(y, axis=1)[:, None]
    col = np.arange(n)[None, :]
    # before the peak nothing falls more than tol below the highest sample so far, after it nothing
    # rises more than tol above the lowest so far (a rise spread over several samples counts whole)
    before = (col > p) | (y >= np.maximum.accumulate(y, axis=1) - tol)
    after = (col < p) | (y <= np.minimum.accumulate(np.where(col >= p, y, np.inf), axis=1) + tol)
    return np.all(before & after, axis=1)


def _cubic_crossing(x, k, level):
    """Fractional position in [0, 1] after sample k where x crosses ``level`` (scalar or per k)
    upward: root of the cubic through samples k-1..k+2 (linear where the stencil leaves the
    record), by bisection. On smooth edges (several samples long) it removes most of the bias of
    a linear interpolation, which would otherwise repeat every revolution at speeds commensurate
    with the sample rate; on steep edges the cubic overshoots and the linear estimate is better."""
    level = np.broadcast_to(np.asarray(level, dtype=float), k.shape)
    x0, x1 = x[k], x[k + 1]
    lin = np.clip((level - x0) / np.where(x1 != x0, x1 - x0, 1.0), 0.0, 1.0)
    full_level = level
    inner = (k >= 1) & (k + 2 < x.size)
    if not inner.any():
        return lin
    kk = k[inner]
    level = full_level[inner]
    xm, a, b, xp = x[kk - 1], x[kk], x[kk + 1], x[kk + 2]

    def cubic(f):
        return (-f * (f - 1) * (f - 2) / 6 * xm + (f + 1) * (f - 1) * (f - 2) / 2 * a
                - (f + 1) * f * (f - 2) / 2 * b + (f + 1) * f * (f - 1) / 6 * xp) - level

    lo = np.zeros(kk.size)
    hi = np.ones(kk.size)
    ok = (cubic(lo) <= 0) & (cubic(hi) >= 0)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        up = cubic(mid) >= 0
        hi = np.where(up, mid, hi)
        lo = np.where(up, lo, mid)
    out = lin.copy()
    out[np.nonzero(inner)[0][ok]] = (0.5 * (lo + hi))[ok]
    return out


def _linear_crossing(w, k, mid):
    x0, x1 = w[k], w[k + 1]
    d = np.where(x1 != x0, x1 - x0, 1.0)
    return np.clip((mid - x0) / d, 0.0, 1.0)


def _refine(w, t, base, swing, half, post, rise):
    """Equivalent-time correction of the edge times ``t`` (samples) of edges ``rise`` samples long.
    Returns (t, refined?, note, per pulse the timing uncertainty the correction leaves: of steps,
    whose edges no sample shows, and of stretches whose interpolation error it cannot reach
    (samples; 0 elsewhere)).

    Within each steady stretch the event times follow a smooth curve t_fit(i) (a quadratic in
    the revolution index). The linear-interpolation error of a pulse depends on where its edge
    falls between two samples; over pulses at diverse positions its mean is a bias b0 that a
    fit absorbs: t_fit = t_true + b0. Overlaying every edge at p = n - t_fit(i) therefore
    samples the true edge shape densely, shifted by b0; its mid-height crossing p* = -b0 is the
    correction, applied to every pulse of the stretch (the pulse-to-pulse variation, genuine
    speed fluctuation included, is kept)."""
    n = t.size
    steep = rise <= 1.5
    offs = np.arange(-half, post + 1)
    # each time's noise (samples): the rest's noise over the edge's slope at mid-height
    noise = _noise(w, float(np.median(base)), swing) / swing
    kt = np.clip(np.floor(t).astype(int), 0, w.size - 2)
    slope = float(np.median(w[kt + 1] - w[kt])) / swing if n else 0.0
    jitter = noise / slope if slope > 0 else 0.0
    if n < 16:
        left = _left_stds(w, t, base, swing, offs, rise, [(0, n)], noise) if n else np.zeros(0)
        note = (f"only {n} pulses: too few for the equivalent-time correction; their edge times are interpolated, "
                f"with {_allowed(left)}") if n else ""
        return t, False, note, np.maximum(left, _negligible(jitter / np.sqrt(max(n, 1))))
    out = t.copy()
    per = np.diff(t)
    starts = [0]
    for i in range(1, n - 1):
        ref = per[starts[-1]]
        if abs(per[i] - ref) > 0.01 * ref:
            starts.append(i + 1)
    starts.append(n)
    starts = _ramp_ends_split(t, starts)
    # steady stretches longer than TEMPLATE_CHUNK in equal parts (a short remainder could not see
    # the positions' whole cycle where they creep slowly)
    starts = sorted({int(a + round(j * (b - a) / -(-(b - a) // TEMPLATE_CHUNK)))
                     for a, b in zip(starts[:-1], starts[1:]) for j in range(-(-(b - a) // TEMPLATE_CHUNK))} | {n})
    notes, notes_rejected, notes_creep, notes_unmeasured, done = [], [], [], [], False
    step_std = np.zeros(n)
    gap_std = np.zeros(n)
    noise_std = np.zeros(n)
    unmeasured = []
    for a, b in zip(starts[:-1], starts[1:]):
        if b - a < 16:
            notes_unmeasured.append("short")
            unmeasured.append((a, b))
            continue
        tc = t[a:b]
        # the noise of the stretch's mean time (whether or not it is corrected)
        noise_std[a:b] = jitter / np.sqrt(b - a)
        # the smooth time base: a local quadratic in the revolution index, fitted to the times less
        # their phase-dependent interpolation error (estimated in turn from the fit; four rounds).
        # It spans +-LOCAL_FIT pulses, so that a real speed wobble is followed, or 1.5 cycles of
        # the positions within a sample where they creep slowly, so that it does not follow the
        # interpolation error as they creep
        fit = _local_quadratic(tc, LOCAL_FIT)
        i = np.arange(tc.size, dtype=float)
        quad = np.polyfit(i - i.mean(), tc, 2)
        on_quad = np.polyval(quad, i - i.mean())
        # one speed: a quadratic over the stretch whose period changes by less than
        # STEADY_PERIOD_CHANGE and from which the times depart by less than ONE_SPEED_RESIDUAL rms
        steady = abs(2.0 * quad[0] * tc.size) < STEADY_PERIOD_CHANGE and _rms(tc - on_quad) < ONE_SPEED_RESIDUAL
        # the positions' cycle from that quadratic at one speed (the +-8 pulse fit follows the
        # interpolation error, and at exactly 4 positions per sample spread them past the
        # quarter-sample gap: taken for a slow creep, left 0.04-0.08 sample off)
        cycle = _cycle_length(np.mod(on_quad if steady else fit, 1.0), MAX_POSITION_GAP)
        if steady and ((2 * cycle > tc.size) if cycle is not None else _occupied(fit) >= TEMPLATE_BINS // 2):
            # at one speed, the positions creep so slowly that the stretch holds less than two of
            # their cycles (or fills 8 bins without completing one): no time base can tell their
            # interpolation error from a change of speed, and it is left in the times with the
            # uncertainty the edge's samples allow (or the step's, if larger). (Where the speed
            # changes, a coast-down, the positions sweep ever faster and the narrow time base
            # separates them: RC edges at 3 %/s within 0.001 sample, 0.08 when left uncorrected)
            notes_creep.append(cycle or 0)
            unmeasured.append((a, b))
            if steep:
                gap_std[a:b] = _widest_gap(np.mod(fit, 1.0)) / np.sqrt(12.0)
            continue
        fit, e_phase = _time_base(tc, LOCAL_FIT, fit)
        wide = LOCAL_FIT if cycle is None else max(LOCAL_FIT, int(np.ceil(CREEP_WINDOW * cycle)))
        # the widest time base that explains the times as well (a speed that wanders over a
        # shorter time than the positions' cycle needs the narrow one): 1.5 cycles of the
        # positions, and at one speed the whole stretch (where the positions complete at least two
        # cycles in it: over part of one, a trend of the error with position is a change of speed).
        # The narrow base follows part of the interpolation error its phase curve misses,
        # differently at each position, which bends the template (RC edges of 0.5-1 sample at
        # 138.9-142.2 samples per revolution: 0.001-0.0017 samples late with the +-8-pulse base,
        # within 0.0003 with the stretch's)
        # The stretch's base is held to its residual within STRETCH_BASE_FACTOR of the narrow one's
        # (+ STRETCH_BASE_SLACK): a slow offset drift of 5 % of the swing moved the times by 0.0028
        # samples rms about it (0.0003 about the narrow base), and the position pattern drowned
        # in that was left in them (0.003 samples, found in review)
        narrow = _rms(tc - fit - e_phase)
        for m in sorted({wide} - {LOCAL_FIT} | ({tc.size} if steady and cycle is not None else set())):
            fit_w, e_w = _time_base(tc, m)
            limit = (STRETCH_BASE_FACTOR * narrow + STRETCH_BASE_SLACK) if m == tc.size else narrow + WIDE_BASE_SLACK
            if _rms(tc - fit_w - e_w) <= limit:
                fit, e_phase = fit_w, e_w
        occupied = _occupied(fit)
        kc = np.floor(fit).astype(int)
        idx = kc[:, None] + offs[None, :]
        valid = (idx >= 0) & (idx < w.size)
        y = (w[np.clip(idx, 0, w.size - 1)] - base[a:b, None]) / swing
        pv = (idx - fit[:, None])[valid]
        step = steep and np.mean(np.abs(y[valid][np.abs(pv) <= 1.0] - 0.5) < RAMP_BAND) < RAMP_FRACTION
        if step:
            # a step leaves no sample on its edge: it lies anywhere in the widest gap between the
            # positions its pulses fall at within a sample, uniformly (at 5 positions +-0.1 sample:
            # the records of an ideal step at 3000 and 6000 rpm and 10,240 Hz came out 0.07-0.10
            # samples off; the gap between the samples enclosing the boundary understated it, 0.003
            # against -0.048 at 4500 rpm)
            near = np.abs(pv) <= 2.0
            anchor = _boundary(pv[near], y[valid][near], 0.5)
            step_std[a:b] = _widest_gap(np.mod(fit, 1.0)) / np.sqrt(12.0)
        # the positions the correction needs: 8 of the 16 bins for steep edges (at 5 positions a
        # 1-sample trapezoid, timed exactly by the interpolation, came out up to 0.07 samples off);
        # 8 bins or evenly spread positions for the others (the gap rule alone turned away
        # coast-downs and short stretches filling 8 bins of part of a sample: 0.04-0.07 samples off)
        dense = occupied >= TEMPLATE_BINS // 2
        if not dense if steep else not (dense or _widest_gap(np.mod(fit, 1.0)) <= MAX_POSITION_GAP):
            notes.append(occupied)
            unmeasured.append((a, b))
            continue
        quiet = not _phase_dependent(np.mod(fit, 1.0), tc - fit, TEMPLATE_BINS)
        if quiet and _rms(tc - fit) > max(MAX_BASE_RESIDUAL, 2.0 * jitter):
            # no error that depends on the edge position shows, through a time base that missed the
            # speed by more than such an error: unmeasured (RC edges under a speed wobble of
            # 0.02-0.5 % at 0.7 Hz, 1500-4300 rpm: 0.04-0.08 sample late with no uncertainty)
            notes_unmeasured.append("wobble")
            unmeasured.append((a, b))
            continue
        if quiet and jitter < NOISY_JITTER:
            # the interpolated times show no error that depends on the edge position: keep them. Only
            # an edge interpolated exactly shows none (its error vanishes where a sample meets
            # mid-height)
            continue
        gx, gy, gn = _template(idx - fit[:, None], y, valid, max(half, post))
        if gx is None:
            notes_unmeasured.append("template")
            unmeasured.append((a, b))
            continue
        # the constant part: the template's mid-height crossing (a step's: the boundary between the
        # samples below and above, found above); the part that depends on where the edge falls
        # between samples (e_phase): the mean residual of the pulses at that position
        if not step:
            anchor, at, sens = _crossing_of(gx, gy, 0.5)
            # the scatter of the template points the crossing was read from (their noise, or their
            # roughness where the time base bent them: 7 clusters of positions left RC edges
            # 0.0016 samples late), and the noise of the mean time (the correction moves every
            # pulse of the stretch alike: a common timing error)
            point_std = np.maximum(noise / np.sqrt(gn[at]), _roughness(gx, gy, at))
            noise_std[a:b] = np.hypot(np.sqrt(np.sum((sens * point_std) ** 2)), noise_std[a])
        new = tc - e_phase + anchor
        if quiet and not step:
            # noisy times with no position pattern to see: an exact interpolation, or one whose
            # error the noise hides. Kept, with what the template says they may be off by, its shift
            # and its own uncertainty (corrected, a 2-sample trapezoid's exact times under 0.4 % noise
            # came out 3 times noisier, and a correction taken only where the shift exceeded 3 times
            # that uncertainty selected the records whose template was noise: RC edges under 2 %
            # noise 0.073 samples off against 0.009, found in review; RC edges of 2 samples, 0.009
            # off under 0.8 % noise, are covered)
            noise_std[a:b] = np.hypot(noise_std[a], float(np.mean(new - tc)))
            continue
        # the correction may not add scatter: if the refined times are rougher than the rough ones
        # (the time base could not follow the speed), keep the interpolated times
        if tc.size >= 8 and _jitter(new) > 1.5 * _jitter(tc) + 1e-3:
            notes_rejected.append(a)
            unmeasured.append((a, b))
            continue
        out[a:b] = new
        done = True
    left_std = np.maximum(_left_stds(w, t, base, swing, offs, rise, unmeasured, noise), gap_std)
    note = ""
    if notes_rejected:
        note = (f"the equivalent-time correction was rejected in {len(notes_rejected)} stretch(es) (it would have "
                "added scatter: the speed varies faster than the time base can follow); edge times are interpolated")
    if notes:
        note = (note + "; " if note else "") + (f"in {len(notes)} steady stretch(es) the pulses fall at only {min(notes)} of {TEMPLATE_BINS} positions "
                "within a sample interval (a speed commensurate with the sample rate): their edge times are "
                "interpolated, and any interpolation error repeats every revolution instead of averaging out: "
                f"{_allowed(left_std)} (a speed or sample rate a little different avoids it)")
    if notes_unmeasured:
        note = (note + "; " if note else "") + (
            f"in {len(notes_unmeasured)} stretch(es) the interpolation error could not be measured (fewer than 16 "
            "pulses, or a speed varying faster than the time base follows): their edge times are interpolated, "
            f"with {_allowed(left_std)}")
    if notes_creep:
        note = (note + "; " if note else "") + (
            f"in {len(notes_creep)} steady stretch(es) the pulses' position within a sample interval creeps so slowly "
            f"({'a cycle of ' + str(max(notes_creep)) + ' revolutions, more than half the stretch' if max(notes_creep) else 'not one cycle in the stretch'}: "
            "a speed nearly commensurate with the sample rate) that the interpolation error cannot be told from a change "
            f"of speed: their edge times are interpolated, with {_allowed(left_std)} (a longer record, or a "
            "speed or sample rate a little different, avoids it)")
    if step_std.max() > 0.02:
        note = (note + "; " if note else "") + (
            f"the edges are steps (few samples on them): timed to within {np.sqrt(12.0) * step_std.max():.2g} sample "
            "(the widest gap between the positions the pulses fall at within a sample), an uncertainty of "
            f"{step_std.max():.2g} sample")
    return out, done, note, np.maximum(np.maximum(step_std, left_std), _negligible(noise_std))


def _negligible(std):
    """``std`` (samples) where it reaches NEGLIGIBLE_STD, else 0."""
    return np.where(std >= NEGLIGIBLE_STD, std, 0.0)


#: timing uncertainties below this (samples) are not reported: 2e-4 sample is 20 ns at 10 kHz, a
#: phase of 0.007 degrees at 6,000 rpm (the template of a clean 16-bit keyphasor is rough by
#: 0.5-1e-4 sample from its quantization alone)
NEGLIGIBLE_STD = 2e-4


#: the standard deviation (samples) of the interpolated mid-height crossing of an edge over the
#: positions it can fall at within a sample, by its duration (twice the 25-75 % time, samples): an
#: envelope of the rms over 200 positions of first-order (RC), Bessel 2 and 4, Butterworth 2,
#: Gaussian, linear and circular-spot edges (linear interpolation below 2.5 samples, the cubic
#: above, as the timing uses them; tests/test_edge_shapes.py checks it against filter edges of
#: orders 2-4). For times no edge shape of edge_shapes fits
INTERPOLATION_STD = ((0.5, 0.24), (0.8, 0.145), (1.1, 0.125), (1.55, 0.11), (2.2, 0.09), (3.1, 0.05),
                     (4.4, 0.016), (6.6, 0.001))


#: times noisier than this (samples) may hide an interpolation error that depends on the edge's
#: position, and whose mean is not 0 (RC edges of 2 samples under 0.8 % noise: timed on the cubic
#: 0.009 samples late, the pattern unseen): their template is read whether one shows or not, and
#: its shift is stated as their uncertainty (they are kept as they are)
NOISY_JITTER = 0.005
#: a time base whose rms residual exceeds this (samples), or twice the times' noise, missed the
#: speed: an edge position pattern smaller than that cannot be seen through it (the times' own
#: noise alone, 0.025 samples for a noise of 1 % of the swing on a 1-sample erf edge, had such
#: records judged unmeasured and given the edge family's 0.08 samples)
MAX_BASE_RESIDUAL = 0.01

#: positions within a sample at which the interpolation error left in the times is bounded
BOUND_GROUPS = 8


def _allowed(left):
    """The notes' account of the uncertainty left in edge times (``left``, samples, per pulse)."""
    return f"an uncertainty of up to {left.max():.2g} sample for the edge shapes their samples allow"


def _left_stds(w, t, base, swing, offs, rise, stretches, noise):
    """Per pulse of the times ``t``, the standard uncertainty (samples) of the interpolation error
    left in those of the ``stretches`` (pulse ranges a:b, in order; 0 elsewhere). At each position
    within a sample, half the largest error of the edge shapes that fit the samples of the pulses
    there (edge_shapes.interpolation_bound, which no edge exceeded in 275 trials of 11 edge
    families), and at least their rms over each stretch's pulses (the mean time's error is the
    mean of theirs); where no shape fits, the family's INTERPOLATION_STD for edges ``rise``
    samples long. Stretches at nearly one speed (BOUND_SPEED_SPREAD) are bounded together.
    ``noise``: the samples' noise as a fraction of the swing (the fit's tolerance)."""
    out = np.zeros(t.size)
    if not stretches:
        return out
    def period(a, b):
        return (t[b - 1] - t[a]) / max(b - 1 - a, 1) if b - a > 1 else np.nan

    blocks = [[stretches[0]]]
    for a, b in stretches[1:]:
        first = period(*blocks[-1][0])
        if abs(period(a, b) / first - 1.0) <= BOUND_SPEED_SPREAD:
            blocks[-1].append((a, b))
        else:
            blocks.append([(a, b)])
    for block in blocks:
        sel = np.concatenate([np.arange(a, b) for a, b in block])
        each = np.empty(t.size)
        each[sel] = _position_std(w, t[sel], base[sel], swing, offs, rise, noise)
        for a, b in block:
            # not below the rms over the stretch: where the positions alternate (a half number of
            # samples per revolution), the mean time's error is the mean of theirs, which the
            # median over the pulses understated (0.0165 against a mean error of 0.037 sample for
            # Bessel edges whose two positions were bounded at 0.154 and 0.033)
            part = each[a:b]
            out[a:b] = np.maximum(part, float(np.sqrt(np.mean(part ** 2))))
    return out


#: stretches whose speeds lie within this fraction of the first one's are bounded together (an
#: edge that is a fixed angle of the rotor lasts fewer samples at a higher speed): one block for
#: a speed wobbling by +-3 %, where blocks of 64 pulses took 3.8 s for a 100 s record)
BOUND_SPEED_SPREAD = 0.05


def _position_std(w, tc, base, swing, offs, rise, noise):
    """Per pulse of the times ``tc``: half the bound on the interpolation error at its position
    within a sample (BOUND_GROUPS positions, each from its pulses within 1/128 sample of the
    median position there), or INTERPOLATION_STD where no edge shape fits."""
    kc = np.floor(tc).astype(int)
    idx = kc[:, None] + offs[None, :]
    valid = (idx >= 0) & (idx < w.size)
    y = (w[np.clip(idx, 0, w.size - 1)] - base[:, None]) / swing
    # (where the positions creep, a group's samples then lie at one position each, and the cost
    # stays that of 8 positions: a coast-down's 25 such stretches took 1.1 s at 16 bins)
    frac = np.mod(tc, 1.0)
    _, group = np.unique(np.floor(frac * BOUND_GROUPS).astype(int), return_inverse=True)
    centre = np.array([np.sort(frac[group == g])[(group == g).sum() // 2] for g in range(group.max() + 1)])
    use = valid & (np.abs(frac - centre[group]) <= 1.0 / 128.0)[:, None]
    groups = np.broadcast_to(group[:, None], idx.shape)
    bound = interpolation_bound((idx - tc[:, None])[use], y[use], groups[use], rise, noise)
    if bound is None:
        return np.full(tc.size, _interpolation_std(rise))
    return 0.5 * bound[group]


def _interpolation_std(rise):
    """The interpolation error to expect of edges ``rise`` samples long (INTERPOLATION_STD, log-linear
    between its rows, its end values beyond them)."""
    r, sd = np.array(INTERPOLATION_STD).T
    return float(np.exp(np.interp(rise, r, np.log(sd))))


#: a steep edge is a ramp, whose template is crossed at mid-height, rather than a step, placed by
#: the boundary between samples below and above it, when this fraction of the samples within a
#: sample of it lie on it (within RAMP_BAND of mid-height): the boundary scattered the runs of a
#: 1-sample trapezoid by +-0.01-0.03 samples from record to record (3500-5500 rpm at 10,240 Hz;
#: intervals of C through the imbalance chain covered the truth 71 % of the time)
RAMP_FRACTION = 0.25
RAMP_BAND = 0.45

#: the equivalent-time correction of edges that are not steep needs them at positions within a
#: sample interval no more than this far apart (a quarter sample: 4 evenly spread positions or
#: more). Requiring 8 of the 16 bins left RC edges of 1 sample at a speed with 5 positions per
#: sample (6,000 rpm at 10,240 Hz, 102.4 samples per revolution) 0.075 samples late with no
#: uncertainty: 0.26 deg there
MAX_POSITION_GAP = 0.26


def _widest_gap(frac):
    """The widest gap between the positions ``frac`` (in [0, 1)) around the unit circle."""
    f = np.sort(frac)
    return float(np.max(np.diff(np.r_[f, f[0] + 1.0]))) if f.size else 1.0


def _local_quadratic(t, m):
    """Savitzky-Golay smoothing of the sequence t: at each index the value of the least-squares
    quadratic through the 2m+1 neighbours (the first/last window's quadratic at the ends)."""
    n = t.size
    w = 2 * m + 1
    if n <= w:
        i = np.arange(n, dtype=float)
        return np.polyval(np.polyfit(i - i.mean(), t, 2), i - i.mean())
    j = np.arange(-m, m + 1, dtype=float)
    A = np.vander(j, 3, increasing=True)                 # 1, j, j^2
    coef = np.linalg.pinv(A)[0]                           # value at j = 0
    out = np.empty(n)
    # the linear trend is removed first, so the convolution works on small numbers (times are large)
    base = np.linspace(t[0], t[-1], n)
    d = t - base
    out[m:n - m] = np.convolve(d, coef[::-1], mode="valid") + base[m:n - m]
    for sl, jj in ((slice(0, m), np.arange(0, m)), (slice(n - m, n), np.arange(w - m, w))):
        seg = d[:w] if sl.start == 0 else d[n - w:]
        p = np.polyfit(np.arange(w, dtype=float), seg, 2)
        out[sl] = np.polyval(p, jj.astype(float)) + base[sl]
    return out


def _phase_dependent(phase, r, nbins, f_crit=4.0) -> bool:
    """Whether the residuals r depend on the sub-sample position (one-way analysis of variance over
    the phase bins: between-bin mean square over within-bin mean square above ``f_crit``). A
    linear edge of two samples or more is timed exactly by interpolation and shows none; a speed
    wobble the time base cannot follow shows up as scatter, not as a dependence on position."""
    b = np.minimum((phase * nbins).astype(int), nbins - 1)
    cnt = np.bincount(b, minlength=nbins)
    occ = cnt > 0
    k = int(occ.sum())
    n = r.size
    if k < 2 or n - k < 2:
        return False
    mean_b = np.bincount(b, weights=r, minlength=nbins)[occ] / cnt[occ]
    ss_between = float(np.sum(cnt[occ] * (mean_b - r.mean()) ** 2))
    ss_within = float(np.sum((r - (np.bincount(b, weights=r, minlength=nbins) / np.maximum(cnt, 1))[b]) ** 2))
    if ss_between < 1e-10 * n:  # (1e-5 samples)^2 per pulse: nothing to correct
        return False
    return ss_between / (k - 1) > f_crit * max(ss_within / (n - k), 1e-300)


#: a stretch whose period changes by less than this (samples, a quadratic over it) holds one speed:
#: pulses at positions that fill 8 of the 16 bins but leave a gap creep slowly there (at 10,240 Hz
#: and 85.3 rpm from a whole number of samples per revolution), where in a coast-down they sweep
STEADY_PERIOD_CHANGE = 0.1
#: ... and from which the times depart by less than this rms (samples; interpolation errors stay
#: below it, a speed wandering by 0.05 % over 97 revolutions departs by samples)
ONE_SPEED_RESIDUAL = 0.25


def _ramp_ends_split(t, starts):
    """The stretch boundaries ``starts`` with each stretch's ramp ends split off: the runs of pulses
    at either end that depart by more than ``ONE_SPEED_RESIDUAL`` from the quadratic through the
    stretch's middle half, where that middle holds one speed.

    A stretch begins where the period changes by 1 %: the last revolutions of a ramp into a dwell
    (and the first out of it) are within that and joined it, 0.3-5 samples off the dwell's speed.
    They made the dwell's quadratic miss by 0.26-0.41 samples rms, so it was not taken for one speed,
    and a time base that follows the speed then read a slowly creeping interpolation error as a
    change of speed (an independent simulator's dwells with 0.8 s ramps between them, 12,800 Hz,
    192.002 samples per revolution: 0.18 samples late beyond the pulse shape's share, stated 0.001;
    found 2026-11-29). Split off, the ends are stretches of their own (mostly too short to measure:
    the uncertainty their edges allow). A dwell whose speed drifts (1e-4 of it over the dwell) or
    wobbles by 0.005-0.01 % loses 7-43 of 199 pulses at its ends the same way (review): they then
    carry that uncertainty, a conservative result."""
    out = [starts[0]]
    for a, b in zip(starts[:-1], starts[1:]):
        m = b - a
        if m >= 32:
            i = np.arange(m, dtype=float) - 0.5 * (m - 1)
            m0, m1 = m // 4, m - m // 4
            quad = np.polyfit(i[m0:m1], t[a + m0:a + m1], 2)
            r = np.abs(t[a:b] - np.polyval(quad, i))
            if _rms(r[m0:m1]) < 0.5 * ONE_SPEED_RESIDUAL:
                off = r > ONE_SPEED_RESIDUAL
                lo = int(np.argmin(off[:m0])) if not off[:m0].all() else m0
                hi = m - (int(np.argmin(off[m1:][::-1])) if not off[m1:].all() else m - m1)
                out += [a + k for k in (lo, hi) if 0 < k < m]
        out.append(b)
    return sorted(set(out))


def _occupied(fit):
    """How many of the TEMPLATE_BINS bins of a sample interval the positions of ``fit`` fall in."""
    return np.unique(np.floor(np.mod(fit, 1.0) * TEMPLATE_BINS).astype(int)).size


def _time_base(tc, m, first=None):
    """The smooth time base of the times ``tc`` (a local quadratic over +-m pulses) and their
    interpolation error by position within a sample, each estimated from the other (four rounds;
    ``first``: the first round's quadratic, of ``tc`` itself, if the caller has it)."""
    e_phase = np.zeros(tc.size)
    for k in range(4):
        fit = first if k == 0 and first is not None else _local_quadratic(tc - e_phase, m)
        e_phase = _phase_curve(np.mod(fit, 1.0), tc - fit, TEMPLATE_BINS)
    return fit, e_phase


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


#: the wider time base is taken where its rms residual exceeds the +-LOCAL_FIT one's by no more
#: than this (samples)
WIDE_BASE_SLACK = 0.003
#: the stretch's own quadratic serves as time base where its rms residual is within this factor of
#: the +-8-pulse base's, plus STRETCH_BASE_SLACK samples (clean records: within 1.1 times)
STRETCH_BASE_FACTOR = 1.25
STRETCH_BASE_SLACK = 0.0002

#: the time base's half-width, in cycles of the pulses' positions within a sample (pulses until
#: they have spread over the interval): a quadratic over fewer follows an interpolation error that
#: creeps slowly with the position as if the speed varied
CREEP_WINDOW = 1.5


def _cycle_length(frac, max_gap):
    """How many consecutive pulses it takes for their positions ``frac`` (within a sample) to
    leave no gap wider than ``max_gap``, in CYCLE_SHARE of the windows of that many (a speed that
    wanders sweeps the positions quickly except where it turns); None if the whole sequence does
    not."""
    n = frac.size
    if _widest_gap(frac) > max_gap:
        return None
    length = 4
    while length < n:
        starts = range(0, n - length + 1, max(1, length // 2))
        if np.mean([_widest_gap(frac[a:a + length]) <= max_gap for a in starts]) >= CYCLE_SHARE:
            return length
        length = int(np.ceil(1.25 * length))
    return n


#: the share of windows in which the positions must spread for a cycle (a speed wandering by
#: +-0.05-0.5 % over 97 revolutions, 1500-3500 rpm: every window gave 50-90 pulses, a time base
#: too wide to follow the speed, RC edges 0.04-0.09 sample late; the +-8 pulses before had
#: followed it within 0.008)
CYCLE_SHARE = 0.75


def _phase_curve(phase, r, nbins):
    """Per pulse: the mean of r in the phase bins, interpolated linearly (and periodically) between
    the occupied bins' mean phases, less the mean of that over the pulses (so the mean of r minus it
    is zero: the correction cannot shift the mean time). Piecewise-constant bin means put steps into
    times whose position creeps slowly across the bins."""
    b = np.minimum((phase * nbins).astype(int), nbins - 1)
    cnt = np.bincount(b, minlength=nbins)
    occ = cnt > 0
    mean = np.bincount(b, weights=r, minlength=nbins)[occ] / cnt[occ]
    at = np.bincount(b, weights=phase, minlength=nbins)[occ] / cnt[occ]
    if at.size == 1:
        e = np.full(r.size, mean[0])
    else:
        e = np.interp(phase, np.r_[at[-1] - 1.0, at, at[0] + 1.0], np.r_[mean[-1], mean, mean[0]])
    return e - (e.mean() - r.mean())


def _boundary(p, y, level):
    """The position that best separates samples below ``level`` (before) from those above (after):
    the centre of the interval of positions with the fewest misclassified samples. For steps,
    which a binned template cannot resolve."""
    order = np.argsort(p)
    ps, above = p[order], y[order] >= level
    # misclassified if the boundary is placed after sample j: above ones up to j + below ones after j
    cum_above = np.cumsum(above)
    below_after = np.count_nonzero(~above) - np.cumsum(~above)
    mis = np.r_[np.count_nonzero(~above), cum_above + below_after]
    best = np.flatnonzero(mis == mis.min())
    cuts = np.r_[ps[0] - 1.0, 0.5 * (ps[:-1] + ps[1:]), ps[-1] + 1.0]
    return float(np.median(cuts[best]))


def _template(p, y, valid, half):
    """Edge shape from overlaid samples: mean of y in bins of 1/TEMPLATE_BINS sample along p
    (points, values and the samples behind each)."""
    pv, yv = p[valid], y[valid]
    edges = np.arange(-half, half + 1e-9, 1.0 / TEMPLATE_BINS)
    b = np.digitize(pv, edges) - 1
    ok = (b >= 0) & (b < edges.size - 1)
    cnt = np.bincount(b[ok], minlength=edges.size - 1)
    s = np.bincount(b[ok], weights=yv[ok], minlength=edges.size - 1)
    filled = cnt > 0
    if filled.sum() < 4:
        return None, None, None
    ps = np.bincount(b[ok], weights=pv[ok], minlength=edges.size - 1)
    cnt, s, ps = cnt[filled], s[filled], ps[filled]
    # one position split by a bin boundary is one point (two points 0.004 sample apart with one
    # value flatten a cubic through them: an RC edge at 5 positions was crossed 0.024 samples off
    # on the +-8-pulse time base)
    x = ps / cnt
    group = np.r_[0, np.cumsum(np.diff(x) > MERGE_SAMPLES)]
    cnt, s, ps = (np.bincount(group, weights=a) for a in (cnt, s, ps))
    return ps / cnt, s / cnt, cnt


#: template points closer than this (samples) are merged into one
MERGE_SAMPLES = 1.0 / 64.0


#: template points each side of the crossing's stencil whose roughness is measured
ROUGHNESS_REACH = 6


def _roughness(gx, gy, at):
    """Scatter of the template points about a smooth curve near the points ``at``: each point's
    departure from the cubics through four of its neighbours (two either side, or three on one side
    and one on the other), the smallest of the three, so that a kink beside a point does not count
    (a smooth edge departs by O(h⁴)); robustly over the points (the median), scaled to one point's
    standard deviation as for noisy points (their centred departure has 1 + Σw² = 1.94 times a
    point's variance). A linear edge at 5 positions within a sample, whose kinks lie 5 points
    either side of its crossing, came out 0.002-0.004 sample rough with the centred cubic alone."""
    if at.size == 0:
        return 0.0
    lo, hi = max(int(at.min()) - ROUGHNESS_REACH, 3), min(int(at.max()) + ROUGHNESS_REACH, gx.size - 4)
    res = []
    for j in range(lo, hi + 1):
        best = np.inf
        for near in ((j - 2, j - 1, j + 1, j + 2), (j - 3, j - 2, j - 1, j + 1), (j - 1, j + 1, j + 2, j + 3)):
            best = min(best, abs(gy[j] - float(np.dot(_lagrange(gx[j], gx[list(near)]), gy[list(near)]))))
        res.append(best)
    if not res:
        return 0.0
    return 1.4826 * float(np.median(res)) / np.sqrt(1.94)


def _crossing_of(gx, gy, level):
    """Position where the template crosses ``level`` going up, nearest to 0, and how it moves with
    the template's values: (x, indices j, dx/dy_j). On the cubic through the two template points
    straddling it and their outer neighbours, where it crosses once between the middle two;
    linearly otherwise.

    The points lie 1/TEMPLATE_BINS sample apart where the pulses fill the bins, but only 1/P apart
    where they fall at P positions within a sample (a speed commensurate with the sample rate);
    the linear crossing's error is about h² y''/(8 y') for spacing h: 0.007-0.010 samples for RC
    edges of τ = 0.5-0.7 samples at P = 5 (h = 0.2), which the cubic takes to 0.0001-0.001 (its
    largest error with the RC edge's kink among its points). A stencil chosen by divided
    differences (ENO) to keep to the smooth side of the kink, tried, erred more (it extrapolates
    further): 0.0066-0.032 against 0.0066-0.021 at P = 3-4 and τ = 0.5.

    The root x of P(x) = level of the interpolating polynomial P moves with each point's value by
    dx/dy_j = -L_j(x) / P'(x), L_j the Lagrange basis polynomial of point j."""
    above = gy >= level
    cand = np.flatnonzero(above[1:] & ~above[:-1])
    if cand.size == 0:
        return 0.0, np.zeros(0, dtype=int), np.zeros(0)
    i = cand[np.argmin(np.abs(gx[cand]))]
    x0, x1, y0, y1 = gx[i], gx[i + 1], gy[i], gy[i + 1]
    if y1 == y0:
        return float(x0), np.zeros(0, dtype=int), np.zeros(0)
    u_lin = (level - y0) / (y1 - y0)
    linear = (float(x0 + u_lin * (x1 - x0)), np.array([i, i + 1]),
              np.array([-(1.0 - u_lin), -u_lin]) * (x1 - x0) / (y1 - y0))
    if i < 1 or i + 2 >= gx.size:
        return linear
    u = (gx[i - 1:i + 3] - x0) / (x1 - x0)
    coef = np.polyfit(u, gy[i - 1:i + 3] - level, 3)
    roots = np.roots(coef)
    real = roots[(np.abs(roots.imag) < 1e-9) & (roots.real >= 0.0) & (roots.real <= 1.0)].real
    if real.size != 1:
        return linear
    r = real[0]
    slope = np.polyval(np.polyder(coef), r)
    return float(x0 + r * (x1 - x0)), np.arange(i - 1, i + 3), -_lagrange(r, u) / slope * (x1 - x0)


def _lagrange(x, nodes):
    """The Lagrange basis polynomials of ``nodes`` at ``x``: the weights of the interpolating
    polynomial's value there, L_j(x) = prod_{m != j} (x - x_m) / (x_j - x_m)."""
    return np.array([np.prod([(x - nodes[m]) / (nodes[j] - nodes[m]) for m in range(nodes.size) if m != j])
                     for j in range(nodes.size)])


def _running_median(d, w):
    if d.size <= w:
        return np.full_like(d, np.median(d))
    pad = w // 2
    dp = np.pad(d, pad, mode="edge")
    win = np.lib.stride_tricks.sliding_window_view(dp, w)
    return np.median(win, axis=1)


def _plausible(t, tolerance, fill_missing, where, max_speed_step=0.1):
    """Drop extra pulses, fill missing ones; an interval that is neither is a speed jump (error)."""
    extra = []
    for _ in range(3):
        d = np.diff(t)
        med = _running_median(d, 9)
        short = d < (1 - tolerance) * med
        if not short.any():
            break
        j = int(np.flatnonzero(short)[0]) + 1
        extra.append(t[j])
        t = np.delete(t, j)
        if t.size < 2:
            raise KeyphasorError(f"keyphasor{where}: fewer than two valid pulses after removing extra pulses")
    d = np.diff(t)
    med = _running_median(d, 9)
    short = np.flatnonzero(d < (1 - tolerance) * med) + 1
    if short.size:
        extra.extend(t[short].tolist())
        t = np.delete(t, short)
    d = np.diff(t)
    if d.size >= 9:
        # a speed that jumps: the typical period before and after an interval differ beyond the tolerance
        win = np.lib.stride_tricks.sliding_window_view(d, 4)
        med4 = np.median(win, axis=1)           # med4[j]: median of d[j:j+4]
        before, after = med4[:-5], med4[5:]     # around interval j + 4
        jump = np.abs(before / after - 1.0) > max_speed_step  # speed ratio (periods inverted)
        if jump.any():
            j = int(np.argmax(jump)) + 4
            raise KeyphasorError(
                f"keyphasor{where}: the speed jumps at t = {t[j]:.6g} s from {60 / before[j - 4]:.1f} to "
                f"{60 / after[j - 4]:.1f} rpm within a few revolutions (more than max_speed_step = {max_speed_step:g}). "
                "If the record is made of separate blocks, load it as a SegmentedRecording; for a genuinely fast "
                "speed change raise max_speed_step")
    med = _running_median(d, 9)
    missing = []
    long_ = np.flatnonzero(d > (1 + tolerance) * med)
    if long_.size:
        ratio = d[long_] / med[long_]
        off = np.abs(ratio - np.round(ratio))
        bad = off > tolerance / 2
        if bad.any():
            j = long_[np.argmax(bad)]
            raise KeyphasorError(
                f"keyphasor{where}: the interval after t = {t[j]:.6g} s is {d[j] / med[j]:.2f} times the running "
                f"median period ({60 / med[j]:.1f} rpm -> {60 / d[j]:.1f} rpm): neither a missing pulse nor a speed "
                f"change within the tolerance of {tolerance:g}. If the record is made of separate blocks, load it "
                "as a SegmentedRecording; for fast speed changes raise tolerance")
        pieces = [t[: long_[0] + 1]]
        for a, j in enumerate(long_):
            cnt = int(round(d[j] / med[j])) - 1
            missing.append((float(t[j]), max(cnt, 1)))
            if fill_missing and cnt >= 1:
                pieces.append(t[j] + d[j] * np.arange(1, cnt + 1) / (cnt + 1))
            end = long_[a + 1] + 1 if a + 1 < long_.size else t.size
            pieces.append(t[j + 1:end])
        t = np.concatenate(pieces)
    return t, np.asarray(extra), missing
