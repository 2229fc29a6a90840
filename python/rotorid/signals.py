"""From raw waveforms to synchronous vectors and FRFs.

- keyphasor pulse detection with hysteresis, missing/extra pulses reported, speed per revolution;
- 1X (and nX) vectors by computed order tracking: every revolution is resampled at P uniform
  angles from its own keyphasor pulses (4-point cubic interpolation, Rust core) and the orders are
  read off the revolution DFTs, so run-out harmonics and a non-integer number of samples per
  revolution cannot leak into 1X;
- steady-speed segments and coast-downs; slow-roll and baseline-run compensation;
- impact detection (double hits, overloads), the report's time-domain run-out filter (Rust core),
  force and exponential windows, H1 FRFs averaged over repeated impacts, with coherence.

Phase convention: x(t) = Re(X e^{j theta(t)}) with theta = 0 at the keyphasor pulse.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from . import _core
from .errors import RotoridError
from .recording import DISPLACEMENTS, Recording


# ---------------------------------------------------------------------------------------------
# keyphasor


@dataclass
class Keyphasor:
    """Keyphasor pulse times (s, rotor angle 0) and what was corrected on the way."""

    times: np.ndarray
    extra: np.ndarray = field(default_factory=lambda: np.zeros(0))      # times of dropped extra pulses
    missing: list = field(default_factory=list)                         # (time, count) of gaps
    level: float = 0.0
    hysteresis: float = 0.0

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


def keyphasor_times(kp, fs_hz: float, *, t0_s: float = 0.0, level=None, hysteresis=None, fill_missing: bool = True,
                    tolerance: float = 0.35, polarity: str = "auto") -> Keyphasor:
    """Leading-edge times of a once-per-revolution pulse train.

    ``polarity``: "positive" pulses (leading edge rising), "negative" ones (leading edge falling,
    e.g. a proximity probe over a notch) or "auto" (from which side of the median the pulses lie).
    For a positive pulse train a pulse counts when the signal rises above ``level + hysteresis/2`` after having been below
    ``level - hysteresis/2`` (Schmitt trigger); its time is the linear-interpolated crossing of
    ``level``. Defaults: level halfway between the 1st and 99th percentiles, hysteresis 30 % of that
    range. Then the pulse intervals are checked against the local median period: an interval
    shorter than (1 - tolerance) x median marks an extra pulse (dropped), one longer than
    (1 + tolerance) x median marks missing pulses (filled by linear interpolation when
    ``fill_missing``). Every correction is reported in the result and by a warning.
    """
    kp = np.asarray(kp, dtype=float)
    if kp.ndim != 1 or kp.size < 3:
        raise RotoridError("kp (keyphasor channel) must be a 1-D signal with samples")
    if not np.all(np.isfinite(kp)):
        raise RotoridError("kp (keyphasor channel) contains NaN or inf")
    lo_p, hi_p = np.percentile(kp, [1, 99])
    span = hi_p - lo_p
    if not span > 0:
        raise RotoridError("no keyphasor pulses: the keyphasor channel is flat")
    if polarity == "auto":
        # a once-per-revolution pulse is short: the signal rests near its baseline most of the time,
        # so the pulses point away from the median (a proximity probe over a notch gives negative ones)
        med = np.median(kp)
        polarity = "positive" if (med - lo_p) < (hi_p - med) else "negative"
    elif polarity not in ("positive", "negative"):
        raise RotoridError(f"polarity must be 'auto', 'positive' or 'negative', got {polarity!r}")
    if polarity == "negative":
        kp = -kp
        lo_p, hi_p = -hi_p, -lo_p
        if level is not None:
            level = -float(level)
    lev = 0.5 * (lo_p + hi_p) if level is None else float(level)
    hys = 0.3 * span if hysteresis is None else float(hysteresis)
    hi, lo = lev + hys / 2, lev - hys / 2
    state = np.where(kp > hi, 1, np.where(kp < lo, -1, 0))
    idx = np.arange(kp.size)
    last = np.maximum.accumulate(np.where(state != 0, idx, 0))
    held = state[last]
    rise = np.nonzero((held[1:] == 1) & (held[:-1] == -1))[0] + 1
    if rise.size < 2:
        raise RotoridError(f"found {rise.size} keyphasor pulse(s); at least two are needed for one revolution "
                           "(check the keyphasor channel, level and hysteresis)")
    # crossing of `lev` before each trigger: last sample at or below the level, then interpolate
    below = np.maximum.accumulate(np.where(kp <= lev, idx, -1))
    k = below[rise]
    k = np.clip(k, 0, kp.size - 2)
    frac = _crossing(kp, k, lev)
    t = t0_s + (k + frac) / fs_hz
    # plausibility of the intervals
    extra = []
    missing = []
    for _ in range(3):
        d = np.diff(t)
        med = _running_median(d, 9)
        short = d < (1 - tolerance) * med
        if not short.any():
            break
        j = int(np.nonzero(short)[0][0]) + 1  # drop the pulse that ends the short interval
        extra.append(t[j])
        t = np.delete(t, j)
        if t.size < 2:
            raise RotoridError("keyphasor: fewer than two valid pulses after removing extra pulses")
    # remaining short intervals: drop them all in one go
    d = np.diff(t)
    med = _running_median(d, 9)
    short = np.nonzero(d < (1 - tolerance) * med)[0] + 1
    if short.size:
        extra.extend(t[short].tolist())
        t = np.delete(t, short)
    d = np.diff(t)
    med = _running_median(d, 9)
    long_ = np.nonzero(d > (1 + tolerance) * med)[0]
    if long_.size:
        pieces = [t[: long_[0] + 1]]
        for a, j in enumerate(long_):
            cnt = int(round(d[j] / med[j])) - 1
            missing.append((float(t[j]), max(cnt, 1)))
            if fill_missing and cnt >= 1:
                pieces.append(t[j] + d[j] * np.arange(1, cnt + 1) / (cnt + 1))
            end = long_[a + 1] + 1 if a + 1 < long_.size else t.size
            pieces.append(t[j + 1:end])
        t = np.concatenate(pieces)
    if extra:
        warnings.warn(f"keyphasor: dropped {len(extra)} extra pulse(s) at t = {np.round(extra[:5], 6)} s")
    if missing:
        what = "filled by interpolation" if fill_missing else "left as gaps"
        warnings.warn(f"keyphasor: {sum(c for _, c in missing)} missing pulse(s) after t = "
                      f"{[round(m[0], 6) for m in missing[:5]]} s ({what})")
    return Keyphasor(np.asarray(t), np.asarray(extra), missing, lev, hys)


def _crossing(x, k, level):
    """Fractional position in [0, 1] after sample k where x crosses ``level`` upward: root of the
    cubic through samples k-1..k+2 (linear where the stencil leaves the record), refined from the
    linear estimate by bisection. Cubic interpolation removes most of the timing bias a linear
    interpolation has on a smooth edge, bias that would otherwise repeat every revolution when the
    samples per revolution are nearly an integer."""
    x0, x1 = x[k], x[k + 1]
    lin = np.clip((level - x0) / np.where(x1 != x0, x1 - x0, 1.0), 0.0, 1.0)
    inner = (k >= 1) & (k + 2 < x.size)
    if not inner.any():
        return lin
    kk = k[inner]
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


def _running_median(d, w):
    if d.size <= w:
        return np.full_like(d, np.median(d))
    pad = w // 2
    dp = np.pad(d, pad, mode="edge")
    win = np.lib.stride_tricks.sliding_window_view(dp, w)
    return np.median(win, axis=1)


# ---------------------------------------------------------------------------------------------
# order tracking


@dataclass
class SyncTrack:
    """Synchronous vectors of a recording, one per block of whole revolutions.

    ``vectors``: complex (n_blocks, n_orders, 4) for [x1, x2, y1, y2] (m, 0-pk);
    ``speed_rpm`` (n_blocks,) mean speed of the block; ``scatter``: complex rms deviation of the
    per-revolution 1X vectors about the block mean (m), a measure of noise and speed drift;
    ``orders``: the orders tracked (1 = 1X).
    """

    speed_rpm: np.ndarray
    vectors: np.ndarray
    orders: tuple
    n_revs: np.ndarray
    scatter: np.ndarray
    t_mid: np.ndarray

    def order(self, n: int = 1) -> np.ndarray:
        if n not in self.orders:
            raise RotoridError(f"order {n} was not tracked (orders {self.orders})")
        return self.vectors[:, self.orders.index(n), :]

    def minus(self, other: "SyncTrack | np.ndarray") -> "SyncTrack":
        """Subtract vectors: another track interpolated to these speeds (baseline), or one fixed
        complex array (n_orders, 4) (slow-roll run-out)."""
        if isinstance(other, SyncTrack):
            if tuple(other.orders) != tuple(self.orders):
                raise RotoridError("tracks with different orders cannot be subtracted")
            sub = other.at_speeds(self.speed_rpm)
        else:
            sub = np.broadcast_to(np.asarray(other, complex), self.vectors.shape[1:])[None]
        return SyncTrack(self.speed_rpm, self.vectors - sub, self.orders, self.n_revs, self.scatter, self.t_mid)

    def at_speeds(self, speed_rpm) -> np.ndarray:
        """Vectors linearly interpolated (real and imaginary parts) to the given speeds; speeds
        outside the tracked range raise."""
        s = np.asarray(speed_rpm, float)
        order = np.argsort(self.speed_rpm)
        sp = self.speed_rpm[order]
        lo, hi = sp[0], sp[-1]
        tol = 1e-3 * max(hi, 1.0)
        if np.any(s < lo - tol) or np.any(s > hi + tol):
            raise RotoridError(f"speeds {s.min():.0f}-{s.max():.0f} rpm outside the tracked range {lo:.0f}-{hi:.0f} rpm")
        v = self.vectors[order]
        out = np.empty((s.size,) + v.shape[1:], complex)
        for i in range(v.shape[1]):
            for j in range(v.shape[2]):
                out[:, i, j] = np.interp(s, sp, v[:, i, j].real) + 1j * np.interp(s, sp, v[:, i, j].imag)
        return out


def steady_segments(kp: Keyphasor, *, tolerance: float = 0.005, min_revs: int = 8, settle_revs: int = 2):
    """Split the revolutions into runs of steady speed (each revolution within ``tolerance`` of the
    segment's median), skipping ``settle_revs`` revolutions after each change. Returns a list of
    (first_rev, last_rev_exclusive)."""
    rpm = kp.speed_rpm
    segs = []
    start = 0
    ref = rpm[0] if rpm.size else 0.0
    for i in range(1, rpm.size + 1):
        if i == rpm.size or abs(rpm[i] - ref) > tolerance * ref:
            a = start + settle_revs if start > 0 else start
            if i - a >= min_revs:
                segs.append((a, i))
            start = i
            if i < rpm.size:
                ref = rpm[i]
        elif i - start < 16:
            # the segment's reference speed: median of its first 16 revolutions (O(1) per step)
            ref = float(np.median(rpm[start:i + 1]))
    return segs


def track(rec: Recording, *, orders=(1, 2, 3), revs_per_block: int | None = None, steady: bool = True,
          points_per_rev: int | None = None, kp: Keyphasor | None = None, min_revs: int = 8,
          speed_tolerance: float = 0.005) -> SyncTrack:
    """Synchronous vectors of the four displacement channels of a recording.

    ``steady=True`` (dwell recordings): one vector per steady-speed segment, averaged over all its
    revolutions. ``steady=False`` (coast-downs and run-ups): one vector per block of
    ``revs_per_block`` revolutions (default 4), each at its own mean speed. Orders up to
    points_per_rev/2 - 1 are resolved exactly (no leakage between orders). ``points_per_rev``
    defaults to the power of two at or above the samples per revolution at the lowest speed
    (at least 64), so resampling keeps the noise averaging of every recorded sample.
    """
    rec.require("kp", *DISPLACEMENTS)
    orders = tuple(int(o) for o in orders)
    if kp is None:
        kp = keyphasor_times(rec.channels["kp"], rec.fs_hz, t0_s=rec.t0_s)
    if points_per_rev is None:
        spr = rec.fs_hz * np.max(kp.period_s)
        points_per_rev = int(max(64, 2 ** int(np.ceil(np.log2(max(spr, 2.0))))))
        points_per_rev = min(points_per_rev, 4096)
    if min(orders) < 1 or max(orders) >= points_per_rev // 2:
        raise RotoridError(f"orders must be between 1 and {points_per_rev // 2 - 1} for {points_per_rev} points per rev")
    # revolutions entirely inside the record (the cubic stencil needs one sample either side)
    t_first, t_last = rec.t0_s + 1 / rec.fs_hz, rec.t0_s + (rec.n_samples - 2) / rec.fs_hz
    ok = np.nonzero((kp.times >= t_first) & (kp.times <= t_last))[0]
    if ok.size < 2:
        raise RotoridError(f"recording {rec.source!r} is shorter than one revolution between keyphasor pulses")
    k0, k1 = int(ok[0]), int(ok[-1])
    sps = rec.fs_hz / (kp.speed_rpm[k0:k1].max() / 60.0)
    if sps < 8:
        raise RotoridError(f"only {sps:.1f} samples per revolution at the highest speed: sample faster "
                           "(at least 8, better 30+ samples per revolution)")
    x = np.ascontiguousarray(rec.displacements())
    kpt = np.ascontiguousarray(kp.times)
    # per-revolution order vectors (revs, orders, 4), resampled and transformed 1024 revolutions at
    # a time so long records do not need (4, revs, P) doubles at once
    parts = []
    for a in range(k0, k1, 1024):
        b = min(a + 1024, k1)
        res = _core.angle_resample(x, rec.fs_hz, rec.t0_s, kpt, a, b, int(points_per_rev))
        spec = np.fft.rfft(res, axis=2)[:, :, list(orders)] * (2.0 / points_per_rev)
        parts.append(spec.transpose(1, 2, 0))
    per_rev = np.concatenate(parts)
    rpm = kp.speed_rpm[k0:k1]
    tmid = kp.mid_times[k0:k1]
    if steady:
        sub = Keyphasor(kp.times[k0:k1 + 1])
        blocks = steady_segments(sub, tolerance=speed_tolerance, min_revs=min_revs)
        if not blocks:
            raise RotoridError(f"no steady-speed segment of at least {min_revs} revolutions in {rec.source!r} "
                               "(use steady=False for coast-downs)")
    else:
        rb = 4 if revs_per_block is None else int(revs_per_block)
        nb = rpm.size // rb
        if nb < 1:
            raise RotoridError(f"recording has {rpm.size} revolutions, fewer than revs_per_block = {rb}")
        blocks = [(i * rb, (i + 1) * rb) for i in range(nb)]
    vec, sp, nrev, scat, tm = [], [], [], [], []
    for a, b in blocks:
        v = per_rev[a:b]
        vec.append(v.mean(axis=0))
        sp.append(rpm[a:b].mean())
        nrev.append(b - a)
        scat.append(np.sqrt(np.mean(np.abs(v[:, 0, :] - v[:, 0, :].mean(axis=0)) ** 2, axis=0)))
        tm.append(tmid[a:b].mean())
    return SyncTrack(np.array(sp), np.array(vec), orders, np.array(nrev), np.array(scat), np.array(tm))


def slow_roll_vector(rec: Recording, *, orders=(1, 2, 3), **kw) -> np.ndarray:
    """Run-out vectors (n_orders, 4) from a slow-roll recording: the synchronous vectors at a speed
    low enough for the dynamic response to be negligible (mechanical and electrical run-out)."""
    tr = track(rec, orders=orders, **kw)
    if tr.speed_rpm.size > 1:
        warnings.warn(f"slow-roll recording has {tr.speed_rpm.size} steady segments; using the slowest "
                      f"({tr.speed_rpm.min():.0f} rpm)")
    return tr.vectors[int(np.argmin(tr.speed_rpm))]


# ---------------------------------------------------------------------------------------------
# impacts


@dataclass
class Impact:
    """One detected impact on the force channel."""

    start: int          # first sample above threshold
    stop: int           # first sample back below threshold
    peak_index: int
    peak_N: float
    flags: tuple = ()   # "double hit", "overload"

    @property
    def ok(self):
        return not self.flags


def detect_impacts(force, fs_hz: float, *, threshold_N=None, min_separation_s: float = 0.2,
                   double_hit_window_s: float = 0.02, double_hit_fraction: float = 0.1,
                   overload_N=None) -> list:
    """Impacts on a force channel: contiguous runs above ``threshold_N`` (default: 10 % of the
    largest peak, at least 8 x the robust noise level). Flags: "double hit" when another pulse of at
    least ``double_hit_fraction`` of the peak follows within ``double_hit_window_s``; "overload" when
    the signal sits at its maximum (or at ``overload_N``) for 3 or more samples (a clipped
    transducer or DAQ range)."""
    f = np.asarray(force, float)
    if f.ndim != 1 or not np.all(np.isfinite(f)):
        raise RotoridError("force must be a finite 1-D signal")
    noise = 1.4826 * np.median(np.abs(f - np.median(f)))
    thr = max(0.1 * np.abs(f).max(), 8 * noise) if threshold_N is None else float(threshold_N)
    above = np.abs(f) > thr
    edges = np.diff(above.astype(np.int8))
    starts = list(np.nonzero(edges == 1)[0] + 1)
    stops = list(np.nonzero(edges == -1)[0] + 1)
    if above[0]:
        starts.insert(0, 0)
    if above[-1]:
        stops.append(f.size)
    pulses = [(a, b, a + int(np.argmax(np.abs(f[a:b])))) for a, b in zip(starts, stops)]
    impacts = []
    dh = int(round(double_hit_window_s * fs_hz))
    sep = int(round(min_separation_s * fs_hz))
    i = 0
    fmax = np.abs(f).max()
    while i < len(pulses):
        a, b, pk = pulses[i]
        flags = []
        j = i + 1
        while j < len(pulses) and pulses[j][0] - b <= max(dh, sep):
            if pulses[j][0] - b <= dh and abs(f[pulses[j][2]]) >= double_hit_fraction * abs(f[pk]):
                if "double hit" not in flags:
                    flags.append("double hit")
            b = max(b, pulses[j][1])
            j += 1
        seg = np.abs(f[a:b])
        lim = fmax if overload_N is None else float(overload_N)
        at_lim = seg >= lim * (1 - 1e-9)
        if at_lim.size and _longest_run(at_lim) >= 3:
            flags.append("overload")
        impacts.append(Impact(int(a), int(b), int(pk), float(f[pk]), tuple(flags)))
        i = j
    return impacts


def _longest_run(mask):
    best = cur = 0
    for v in mask:
        cur = cur + 1 if v else 0
        best = max(best, cur)
    return best


def revolution_signature(x, fs_hz: float, kp_times, t_start: float, t_stop: float, *, t0_s: float = 0.0,
                         points_per_rev: int = 256) -> np.ndarray:
    """Average revolution signature (C, P) of channels x (C, N) over the whole revolutions that lie in
    [t_start, t_stop]: each revolution resampled at P uniform angles from its own pulses."""
    kpt = np.asarray(kp_times, float)
    inside = np.nonzero((kpt >= t_start) & (kpt <= t_stop))[0]
    if inside.size < 2:
        raise RotoridError(f"no whole revolution between t = {t_start:.4f} s and {t_stop:.4f} s to build the "
                           "run-out signature (record more revolutions before the impact)")
    res = _core.angle_resample(np.ascontiguousarray(x, dtype=float), fs_hz, t0_s, np.ascontiguousarray(kpt),
                               int(inside[0]), int(inside[-1]), int(points_per_rev))
    return res.mean(axis=1)


def runout_filter(x, fs_hz: float, kp_times, template, i0: int, i1: int, *, t0_s: float = 0.0) -> np.ndarray:
    """The report's time-domain run-out filter: samples i0..i1 of x (C, N) minus the revolution
    signature ``template`` (C, P) placed at each sample's rotor angle from the keyphasor pulses
    (each revolution stretched to its own pulse interval, so slow speed drift does not smear the
    subtraction). Runs in the Rust core."""
    return _core.runout_subtract(np.ascontiguousarray(x, dtype=float), float(fs_hz), float(t0_s),
                                 np.ascontiguousarray(kp_times, dtype=float),
                                 np.ascontiguousarray(template, dtype=float), int(i0), int(i1))


def exponential_window(n: int, fs_hz: float, tau_s: float, start: int = 0) -> np.ndarray:
    """w(t) = exp(-(t - t_start)/tau) after ``start`` (1 before). Applied to force and response alike,
    the FRF it produces is H(s) at s = 1/tau + j w. Identifying from it as if s were j w would bias
    the damping; give the decay to the identification (``ImpactResponse(sigma=1/tau)``, or
    ``impact_chain(exp_window_tau_s=tau)``) and it solves the equations at s instead."""
    t = (np.arange(n) - start) / fs_hz
    return np.where(t > 0, np.exp(-np.clip(t, 0, None) / tau_s), 1.0)


def force_window(n: int, start: int, stop: int, *, taper: int = 0) -> np.ndarray:
    """Rectangular window around the force pulse (zero elsewhere, removing force-channel noise),
    optionally with cosine tapers of ``taper`` samples on each side."""
    w = np.zeros(n)
    w[max(0, start):min(n, stop)] = 1.0
    if taper > 0:
        ramp = 0.5 * (1 - np.cos(np.pi * np.arange(1, taper + 1) / (taper + 1)))
        a0 = max(0, start - taper)
        w[a0:start] = ramp[taper - (start - a0):]
        b1 = min(n, stop + taper)
        w[stop:b1] = ramp[::-1][: b1 - stop]
    return w


@dataclass
class FRF:
    """H1 estimate over repeated impacts: ``h`` (n, C) = sum X F* / sum |F|^2, ``coherence`` (n, C),
    ``force`` (n,) mean force spectrum magnitude, ``sigma`` decay rate of any exponential window."""

    freq_hz: np.ndarray
    h: np.ndarray
    coherence: np.ndarray
    force: np.ndarray
    n_avg: int
    sigma: float = 0.0


def frf_h1(forces, responses, fs_hz: float) -> FRF:
    """H1 FRF and coherence from equally long force records (list of (N,)) and response records
    (list of (C, N)), one pair per impact."""
    if len(forces) != len(responses) or not forces:
        raise RotoridError("frf_h1 needs one response record per force record (and at least one)")
    n = len(forces[0])
    sff = 0.0
    sxf = 0.0
    sxx = 0.0
    for f, x in zip(forces, responses):
        if len(f) != n or np.shape(x)[-1] != n:
            raise RotoridError("all force and response records must have the same length")
        F = np.fft.rfft(f)
        X = np.fft.rfft(np.asarray(x), axis=-1).T  # (n_f, C)
        sff = sff + np.abs(F) ** 2
        sxf = sxf + X * np.conj(F)[:, None]
        sxx = sxx + np.abs(X) ** 2
    freq = np.fft.rfftfreq(n, 1 / fs_hz)
    with np.errstate(divide="ignore", invalid="ignore"):
        h = sxf / sff[:, None]
        coh = np.abs(sxf) ** 2 / (sff[:, None] * sxx)
    return FRF(freq, h, coh, np.sqrt(sff / len(forces)), len(forces))
