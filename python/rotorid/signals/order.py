"""Order tracking: synchronous (1X, nX) vectors from the keyphasor-referenced revolutions of a
recording; steady-speed segments, coast-down blocks and slow-roll run-out."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from .._corecall import core as _core
from ..errors import RotoridError
from ..recording import ACCELEROMETERS, DISPLACEMENTS, Recording
from .keyphasor import Keyphasor, keyphasor_times



@dataclass
class SyncTrack:
    """Synchronous vectors of a recording, one per block of whole revolutions.

    ``vectors``: complex (n_blocks, n_orders, 4) for [x1, x2, y1, y2] (m, 0-pk);
    ``speed_rpm`` (n_blocks,) mean speed of the block; ``scatter``: complex rms deviation of the
    per-revolution 1X vectors about the block mean (m), a measure of noise and speed drift;
    ``orders``: the orders tracked (1 = 1X); ``keyphasors``: the Keyphasor of each record (block)
    tracked, with its timing jitter and notes.

    ``cov`` (n_blocks, 8, 8): covariance of each block's 1X vector as the real 8-vector
    [Re x1, Re x2, Re y1, Re y2, Im x1, Im x2, Im y1, Im y2] (m²), estimated from the data
    themselves (batch means of the per-revolution vectors, so correlated noise between nearby
    revolutions is accounted for); ``dof`` (n_blocks,) its degrees of freedom. NaN where unknown.

    Flexible pedestals (tracked with ``pedestal=True``): ``pedestal`` complex (n_blocks,
    n_orders, 4), the housings' displacement [xp1, xp2, yp1, yp2] (m, 0-pk) from the
    accelerometers px1, px2, py1, py2 (each revolution's order-n acceleration divided by
    -(n Omega)^2); ``pedestal_cov`` (n_blocks, 8, 8) the covariance of its 1X as [Re, Im] and
    ``pedestal_cross`` (n_blocks, 8, 8) the covariance between the probes' 1X and it (both from
    the same batch means as ``cov``).
    """

    speed_rpm: np.ndarray
    vectors: np.ndarray
    orders: tuple
    n_revs: np.ndarray
    scatter: np.ndarray
    t_mid: np.ndarray
    keyphasors: list = field(default_factory=list)
    cov: np.ndarray | None = None
    dof: np.ndarray | None = None
    pedestal: np.ndarray | None = None
    pedestal_cov: np.ndarray | None = None
    pedestal_cross: np.ndarray | None = None

    def __post_init__(self):
        from .._validate import complex_array, real_array

        # checked, then kept as given (arrays; n_revs stays integer)
        sp = real_array("speed_rpm", self.speed_rpm, ndim=1)
        n = sp.size
        if n == 0:
            raise RotoridError("a SyncTrack needs at least one speed (speed_rpm is empty)")
        try:
            orders = tuple(self.orders)
        except TypeError:
            orders = ()
        if not orders or any(isinstance(o, (bool, np.bool_)) or not isinstance(o, (int, np.integer)) or o < 1
                             for o in orders):
            raise RotoridError(f"orders must be a tuple of whole numbers >= 1, got {self.orders!r}")
        self.orders = tuple(int(o) for o in orders)
        complex_array("vectors", self.vectors, shape=(n, len(self.orders), 4))
        for name, shape in (("n_revs", (n,)), ("scatter", (n, 4)), ("t_mid", (n,))):
            real_array(name, getattr(self, name), shape=shape, finite=False)
            setattr(self, name, np.asarray(getattr(self, name)))
        self.speed_rpm, self.vectors = sp, np.asarray(self.vectors)
        if self.cov is None:
            self.cov = np.full((n, 8, 8), np.nan)
        else:
            self.cov = real_array("cov", self.cov, shape=(n, 8, 8), finite=False)
        if self.dof is None:
            self.dof = np.full(n, np.nan)
        else:
            self.dof = real_array("dof", self.dof, shape=(n,), finite=False)
        if self.pedestal is None:
            if self.pedestal_cov is not None or self.pedestal_cross is not None:
                raise RotoridError("pedestal_cov / pedestal_cross given without pedestal (the pedestal motion)")
        else:
            self.pedestal = complex_array("pedestal", self.pedestal, shape=(n, len(self.orders), 4))
            for name in ("pedestal_cov", "pedestal_cross"):
                v = getattr(self, name)
                setattr(self, name, np.full((n, 8, 8), np.nan) if v is None else
                        real_array(name, v, shape=(n, 8, 8), finite=False))

    @property
    def has_pedestal(self) -> bool:
        """Whether the track carries pedestal (housing) motion from accelerometers."""
        return self.pedestal is not None

    def order(self, n: int = 1) -> np.ndarray:
        if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or n not in self.orders:
            raise RotoridError(f"order {n} was not tracked (orders {self.orders})")
        return self.vectors[:, self.orders.index(n), :]

    def minus(self, other: "SyncTrack | np.ndarray", other_cov=None) -> "SyncTrack":
        """Subtract vectors: another track interpolated to these speeds (baseline), or one fixed
        complex array (n_orders, 4) (slow-roll run-out) with its 1X covariance ``other_cov``
        (8, 8) if known. Covariances add (the two are independent measurements)."""
        ped = {}
        if isinstance(other, SyncTrack):
            if tuple(other.orders) != tuple(self.orders):
                raise RotoridError("tracks with different orders cannot be subtracted")
            if other.has_pedestal != self.has_pedestal:
                raise RotoridError("one track carries pedestal motion (accelerometers px1, px2, py1, py2) and the "
                                   "other does not: subtract tracks recorded with the same channels")
            sub = other.at_speeds(self.speed_rpm)
            ocov, odof = other.cov_at_speeds(self.speed_rpm)
            if self.has_pedestal:
                opc, ocr = other.pedestal_cov_at_speeds(self.speed_rpm)
                ped = dict(pedestal=self.pedestal - other.pedestal_at_speeds(self.speed_rpm),
                           pedestal_cov=self.pedestal_cov + opc, pedestal_cross=self.pedestal_cross + ocr)
        else:
            from .._validate import complex_array, real_array

            sub = complex_array("other", other)
            try:
                sub = np.broadcast_to(sub, self.vectors.shape[1:])[None]
            except ValueError:
                raise RotoridError(f"other must be a track or vectors (n_orders, 4) = {self.vectors.shape[1:]} to "
                                   f"subtract, got shape {sub.shape}") from None
            ocov = np.zeros((1, 8, 8)) if other_cov is None else real_array("other_cov", other_cov, shape=(8, 8),
                                                                            finite=False)[None]
            odof = np.full(1, np.inf)
            if self.has_pedestal:
                # run-out is the probes' (a shaft surface seen by a proximity probe): the housings'
                # motion keeps its value
                ped = dict(pedestal=self.pedestal, pedestal_cov=self.pedestal_cov,
                           pedestal_cross=self.pedestal_cross)
        return SyncTrack(self.speed_rpm, self.vectors - sub, self.orders, self.n_revs, self.scatter, self.t_mid,
                         self.keyphasors, self.cov + ocov, np.minimum(self.dof, odof), **ped)

    def _weights(self, speed_rpm):
        from .._validate import real_array

        s = real_array("speed_rpm", speed_rpm)
        if s.ndim > 1 or s.size == 0:
            raise RotoridError(f"speed_rpm must be a speed or a non-empty 1-D array of speeds, got shape {s.shape}")
        order = np.argsort(self.speed_rpm)
        sp = self.speed_rpm[order]
        lo, hi = sp[0], sp[-1]
        tol = 1e-3 * max(hi, 1.0)
        if np.any(s < lo - tol) or np.any(s > hi + tol):
            raise RotoridError(f"speeds {s.min():.0f}-{s.max():.0f} rpm outside the tracked range {lo:.0f}-{hi:.0f} rpm")
        if sp.size == 1:
            return order, np.zeros(s.size, int), np.zeros(s.size, int), np.ones(s.size)
        i = np.clip(np.searchsorted(sp, s) - 1, 0, sp.size - 2)
        w = np.clip((s - sp[i]) / (sp[i + 1] - sp[i]), 0.0, 1.0)
        return order, i, i + 1, 1.0 - w

    def at_speeds(self, speed_rpm) -> np.ndarray:
        """Vectors linearly interpolated (real and imaginary parts) to the given speeds; speeds
        outside the tracked range raise."""
        order, i, j, w = self._weights(speed_rpm)
        v = self.vectors[order]
        return v[i] * w[:, None, None] + v[j] * (1.0 - w)[:, None, None]

    def pedestal_at_speeds(self, speed_rpm) -> np.ndarray:
        """Pedestal motion (n, n_orders, 4) interpolated as :meth:`at_speeds`."""
        if not self.has_pedestal:
            raise RotoridError("this track carries no pedestal motion (no accelerometer channels were tracked)")
        order, i, j, w = self._weights(speed_rpm)
        v = self.pedestal[order]
        return v[i] * w[:, None, None] + v[j] * (1.0 - w)[:, None, None]

    def pedestal_cov_at_speeds(self, speed_rpm):
        """(pedestal_cov, pedestal_cross) interpolated as :meth:`cov_at_speeds`."""
        if not self.has_pedestal:
            raise RotoridError("this track carries no pedestal motion (no accelerometer channels were tracked)")
        order, i, j, w = self._weights(speed_rpm)
        a, b = (w ** 2)[:, None, None], ((1.0 - w) ** 2)[:, None, None]
        pc, cr = self.pedestal_cov[order], self.pedestal_cross[order]
        return pc[i] * a + pc[j] * b, cr[i] * a + cr[j] * b

    def cov_at_speeds(self, speed_rpm):
        """(cov, dof) of the 1X vectors interpolated to the given speeds (squared weights)."""
        order, i, j, w = self._weights(speed_rpm)
        c, d = self.cov[order], self.dof[order]
        return (c[i] * (w ** 2)[:, None, None] + c[j] * ((1.0 - w) ** 2)[:, None, None],
                np.where(w == 1.0, d[i], np.where(w == 0.0, d[j], np.minimum(d[i], d[j]))))


def mean_covariance(v, *, max_batches: int = 16):
    """Covariance of the mean of per-revolution complex vectors ``v`` (revs, 4) as the real
    8-vector [Re, Im] (``v`` (revs, 8), probes then accelerometers: the 16-vector [Re q, Im q,
    Re p, Im p]), from batch means: the revolutions are cut into up to ``max_batches``
    consecutive batches, so noise correlated over fewer revolutions than a batch is accounted
    for. Returns (cov (8, 8), dof)."""
    v = np.ascontiguousarray(v, dtype=complex)
    if v.ndim != 2 or v.shape[1] not in (4, 8) or v.shape[0] < 1:
        raise RotoridError(f"v must be per-revolution vectors of shape (revolutions, 4 or 8), got shape {v.shape}")
    revs = v.shape[0]
    _, cov, dof, *_ = _core.block_statistics(v[:, None, :], np.zeros(revs), np.zeros(revs), np.zeros(1, np.int64),
                                             np.full(1, revs, np.int64), 0, int(max_batches))
    return cov[0], float(dof[0])


def _block_statistics(per_rev, rpm, tmid, starts, lengths, i1):
    """Per block of revolutions starts[j] .. starts[j] + lengths[j]: the mean vectors (n_blocks,
    n_orders, C), the covariance of the 1X mean (n_blocks, 2C, 2C) and its dof
    (:func:`mean_covariance`; NaN without order 1 at index ``i1``), the mean speed and mid time,
    and the scatter of the first order's per-revolution vectors about their mean (n_blocks, 4).
    One core call for all blocks (``block_statistics``): a coast-down has thousands of blocks."""
    mean, cov, dof, sp, tm, scat = _core.block_statistics(
        np.ascontiguousarray(per_rev), np.ascontiguousarray(rpm, dtype=float), np.ascontiguousarray(tmid, dtype=float),
        np.ascontiguousarray(starts, dtype=np.int64), np.ascontiguousarray(lengths, dtype=np.int64), i1)
    return mean, cov, dof, sp, scat, tm


#: revolutions over which the speed is averaged before a dwell's 1X change along it is taken out
#: (odd: centred on its revolution; an even window lags half a revolution, which at 0.3 Hz left 3.6
#: times the steady covariance)
TREND_REVS = 15
#: ... where that averaged speed varies by more than this (rms, relative)
TREND_MIN_REL = 1e-6


def _without_speed_trend(per_rev, rpm, starts, lengths, i1):
    """The per-revolution vectors with each steady block's 1X change along its speed taken out, and
    per block whether one was. Within a dwell whose speed wanders (a speed control holding ±0.2 %),
    the 1X response follows the speed, q(Omega_i) ~ q(Omega_mean) + q' (Omega_i - Omega_mean): the
    block mean stands for the mean speed to first order, but batch means took that systematic
    change for noise, and the error bars came out several times too wide (an independent
    simulator, ±0.2 % at 0.3 Hz: median |z| 0.06-0.08). The change along the speed (averaged over
    TREND_REVS revolutions, so that a pulse's timing error, which moves two adjacent revolutions'
    speeds apart, does not correlate with its own 1X phase), to second order, is fitted by least
    squares per channel and taken out of the revolutions (their mean is unchanged); the
    covariance's dof lose two. Blocks shorter than 2 TREND_REVS, or whose averaged speed varies by
    less than TREND_MIN_REL, are left as they are."""
    out = per_rev
    done = np.zeros(len(starts), dtype=bool)
    for j, (a, n) in enumerate(zip(starts, lengths)):
        a, n = int(a), int(n)
        if n < 2 * TREND_REVS:
            continue
        r = rpm[a:a + n]
        w = np.ones(TREND_REVS) / TREND_REVS
        # centred moving average, its window shrinking at the block's ends
        x = np.convolve(r, w, mode="same") / np.convolve(np.ones(n), w, mode="same")
        x = x - x.mean()
        sxx = float(x @ x)
        if not sxx > (TREND_MIN_REL * float(np.mean(r))) ** 2 * n:
            continue   # a steady speed (to its rounding): nothing to take out
        v = per_rev[a:a + n, i1, :]
        # the change along the speed to second order (near a critical speed the response bends
        # within a ±0.2 % wander): regressors x and x² less its mean, both of zero mean
        X = np.stack([x, x * x - np.mean(x * x)], axis=1) / np.sqrt(sxx / n)
        coef = np.linalg.lstsq(X, v - v.mean(axis=0), rcond=None)[0]
        if out is per_rev:
            out = per_rev.copy()
        out[a:a + n, i1, :] = v - X @ coef
        done[j] = True
    return out, done


def steady_segments(kp: Keyphasor, *, tolerance: float = 0.005, min_revs: int = 8, settle_revs: int = 2):
    """Split the revolutions into runs of steady speed, skipping ``settle_revs`` revolutions after
    each change. Returns a list of (first_rev, last_rev_exclusive).

    A revolution belongs to the segment while its speed, or the speed over the
    ``SPAN_REVS`` revolutions centred on it, lies within ``tolerance`` of the segment's reference
    (the median of the span speeds of its first 16 revolutions but the first), and a segment's first
    and last revolutions (up to SPAN_REVS // 2 of each) whose own speed is off are left out. The
    span speed keeps a
    steady dwell whole where each revolution's speed is quantized by the sampling: pulses with step
    edges are timed to a sample, so at 4000 rpm and 10,240 Hz (153.6 samples per revolution) the
    periods alternate between 153 and 154 samples, ±0.33 % about their mean, and no 16 revolutions
    agreed within 0.5 % of one of them: the dwell was dropped without a word. A speed change (the
    ramp to the next dwell) moves both.
    """
    from .._validate import index, instance, number

    instance("kp", kp, Keyphasor, what="signals.Keyphasor")
    tolerance = number("tolerance", tolerance, positive=True)
    min_revs = index("min_revs", min_revs, 1)
    settle_revs = index("settle_revs", settle_revs, 0)
    rpm = kp.speed_rpm
    span = _span_speeds(kp.times)
    segs = []
    start = 0
    ref = rpm[0] if rpm.size else 0.0
    i = 1
    while i <= rpm.size:
        if i < rpm.size and i - start >= 16:
            # the reference is fixed from the 16th revolution of a segment on: jump to its end
            i = _first_off_speed(rpm, span, i, ref, tolerance)
        if i == rpm.size or (abs(rpm[i] - ref) > tolerance * ref and abs(span[i] - ref) > tolerance * ref):
            # the revolutions at the segment's ends that got in through their span alone (the
            # step or ramp revolution next to a change: review, a 0.7 % step made a dwell 0.99 %
            # wide) are left out, as many as the span reaches (a dwell timed to whole samples
            # whose every revolution is off by the sampling loses no more)
            lim = tolerance * ref
            b, lead = i, start
            while b > max(start, i - SPAN_REVS // 2) and abs(rpm[b - 1] - ref) > lim:
                b -= 1
            while lead < min(b, start + SPAN_REVS // 2) and abs(rpm[lead] - ref) > lim:
                lead += 1
            a = lead + settle_revs if start > 0 else lead
            if b - a >= min_revs:
                segs.append((a, b))
            start = i
            if i < rpm.size:
                ref = rpm[i]
        elif i - start < 16:
            # the segment's reference speed: median of its first 16 revolutions' span speeds (O(1)
            # per step), but the first's, whose span reaches back into the segment before
            ref = float(np.median(span[start + 1:i + 1]))
        i += 1
    return segs


#: revolutions over which :func:`steady_segments` also measures each revolution's speed
SPAN_REVS = 4


def _span_speeds(times):
    """The speed (rpm) over the SPAN_REVS revolutions centred on each revolution (fewer at the
    record's ends): a timing error of a sample is spread over them."""
    n = times.size - 1
    if n < 1:
        return np.zeros(0)
    i = np.arange(n)
    lo = np.maximum(i - (SPAN_REVS // 2 - 1), 0)
    hi = np.minimum(i + SPAN_REVS // 2 + 1, n)
    return 60.0 * (hi - lo) / (times[hi] - times[lo])


def _first_off_speed(rpm, span, i: int, ref, tolerance: float) -> int:
    """First revolution j >= i whose speed ``rpm[j]`` and span speed ``span[j]`` both lie farther
    than ``tolerance * ref`` from ``ref`` (rpm.size if none), scanning windows of growing length (a
    short segment costs a short scan)."""
    lim = tolerance * ref
    w = 256
    while i < rpm.size:
        hit = np.flatnonzero((np.abs(rpm[i:i + w] - ref) > lim) & (np.abs(span[i:i + w] - ref) > lim))
        if hit.size:
            return i + int(hit[0])
        i += w
        w = min(2 * w, 1 << 16)
    return rpm.size


#: largest resampling grid per revolution a user may ask for
MAX_POINTS_PER_REV = 1 << 16


def _order_vectors(x, fs_hz, t0_s, kpt, k0: int, k1: int, p: int, orders) -> np.ndarray:
    """Per-revolution order vectors (k1 - k0, n_orders, C), complex 0-pk, of the channels x (a
    (C, N) array, or a list of C contiguous (N,) arrays, used where they are) resampled at p
    angles per revolution (revolutions k0..k1 of the pulse times ``kpt``), each revolution's drift
    ramp removed: ``rfft(res[r] - step[r] * ramp)[orders] * 2 / p`` with ramp = j/p - 0.5 and step
    the change of the revolution means per revolution (``np.gradient``).

    One core call (``order_vectors``): the resampling and the order sums are fused, each
    revolution summed about its mean so a large offset keeps the FFT's accuracy; the resampled
    revolutions are never stored."""
    return _core.order_vectors(x, fs_hz, t0_s, kpt, k0, k1, int(p), [int(o) for o in orders])


def detect_keyphasor(rec: Recording, keyphasor=None) -> Keyphasor:
    """Keyphasor of a recording with the given options (a dict of ``keyphasor_times`` keywords);
    the keyphasor channel's delay from the file's channel map (``meta["channel_delays_s"]["kp"]``)
    is applied unless the options give ``delay_s``."""
    from .._validate import mapping

    opts = dict(rec.meta.get("keyphasor_options") or {})
    opts.update({k: v for k, v in mapping("keyphasor", keyphasor).items() if v is not None})
    times = opts.pop("times", None)
    delays = rec.meta.get("channel_delays_s", {}) or {}
    opts.setdefault("delay_s", float(delays.get("kp", 0.0)))
    lab = ((rec.meta.get("channel_sources") or {}).get("kp") or {}).get("file_channel")
    src = f"{rec.source or 'recording'}, channel {lab!r} (kp)" if lab and lab != "kp" else \
        f"{rec.source or 'recording'}, channel 'kp'"
    if times is not None:
        from .._validate import real_array

        t = real_array("keyphasor times", times, ndim=1)
        t = t[(t >= rec.t0_s) & (t <= rec.t0_s + rec.n_samples / rec.fs_hz)]
        return Keyphasor.from_times(t, mark_angle_deg=opts.get("mark_angle_deg", 0.0), delay_s=opts["delay_s"],
                                    source=src)
    rec.require("kp")
    try:
        return keyphasor_times(rec.channels["kp"], rec.fs_hz, t0_s=rec.t0_s, source=src, **opts)
    except TypeError as exc:
        raise RotoridError(f"keyphasor options: {exc}") from None
    except RotoridError:
        raise


def track(rec, *, orders=(1, 2, 3), revs_per_block: int | None = None, steady: bool = True,
          points_per_rev: int | None = None, kp=None, min_revs: int = 8, settle_revs: int = 2,
          speed_tolerance: float = 0.005, keyphasor=None, pedestal: bool = False) -> SyncTrack:
    """Synchronous vectors of the four displacement channels of a recording (and, with
    ``pedestal``, of the four housing accelerometers).

    Parameters
    ----------
    rec : Recording or SegmentedRecording
        A segmented recording is tracked block by block (no revolution bridges two blocks).
    orders : tuple of int
        Orders to extract (1 = 1X).
    steady : bool
        True (dwell recordings): one vector per steady-speed segment, averaged over all its
        revolutions (``settle_revs`` skipped after each change, at least ``min_revs``, speeds
        within ``speed_tolerance``). False (coast-downs and run-ups): one vector per block of
        ``revs_per_block`` revolutions (default 4), each at its own mean speed.
    points_per_rev : int, optional
        Resampling grid per revolution; orders up to points_per_rev/2 - 1 are resolved exactly.
        Default: the power of two at or above the samples per revolution at the lowest speed (at
        least 64, at most 4096).
    kp : Keyphasor or array_like, optional
        Keyphasor already detected, or pulse times (s) given directly.
    keyphasor : dict, optional
        Options of :func:`~rotorid.signals.keyphasor_times` (level, hysteresis, edge,
        mark_angle_deg, delay_s, tolerance, fill_missing), or ``{"times": array}``.

    pedestal : bool
        Also track the accelerometers on the bearing housings, channels px1, px2, py1, py2
        (m/s², required then), into ``SyncTrack.pedestal`` (housing displacement, m): each
        revolution's order-n vector divided by -(n Ω)² at that revolution's speed.

    Channels with a delay in ``rec.meta["channel_delays_s"]`` (from the channel map's
    ``delay_s``) have their order-n vectors advanced by n Ω delay.

    Examples
    --------
    >>> import rotorid
    >>> from rotorid import rawsim, signals
    >>> rotor, brg, remnant = rawsim.example_rig()
    >>> rec = rawsim.imbalance_recording(rotor, brg, speeds_rpm=[3000], added=None, remnant=remnant, dwell_s=1.0)
    >>> tr = signals.track(rec)
    >>> tr.vectors.shape   # (segments, orders, 4)
    (1, 3, 4)
    """
    from ..recording import SegmentedRecording

    if isinstance(rec, SegmentedRecording):
        import dataclasses

        # channel delays given for the whole recording reach the blocks that state none
        top = (rec.meta or {}).get("channel_delays_s")
        blocks = [dataclasses.replace(b, meta={**b.meta, "channel_delays_s": top})
                  if top and not b.meta.get("channel_delays_s") else b for b in rec.blocks]
        parts = [track(b, orders=orders, revs_per_block=revs_per_block, steady=steady, points_per_rev=points_per_rev,
                       kp=None, min_revs=min_revs, settle_revs=settle_revs, speed_tolerance=speed_tolerance,
                       keyphasor=keyphasor, pedestal=pedestal) for b in blocks]
        ped = {}
        if parts[0].has_pedestal:
            ped = {name: np.concatenate([getattr(p, name) for p in parts])
                   for name in ("pedestal", "pedestal_cov", "pedestal_cross")}
        return SyncTrack(np.concatenate([p.speed_rpm for p in parts]), np.concatenate([p.vectors for p in parts]),
                         parts[0].orders, np.concatenate([p.n_revs for p in parts]),
                         np.concatenate([p.scatter for p in parts]), np.concatenate([p.t_mid for p in parts]),
                         [k for p in parts for k in p.keyphasors], np.concatenate([p.cov for p in parts]),
                         np.concatenate([p.dof for p in parts]), **ped)
    if not isinstance(rec, Recording):
        raise RotoridError(f"rec must be a Recording or SegmentedRecording, got {type(rec).__name__}")
    from .._validate import flag

    pedestal = flag("pedestal", pedestal)
    channels = DISPLACEMENTS + (ACCELEROMETERS if pedestal else ())
    rec.require(*channels)
    try:
        raw = tuple(orders)
        orders = tuple(int(o) for o in raw)
    except (TypeError, ValueError):
        raise RotoridError(f"orders must be whole numbers >= 1, got {orders!r}") from None
    if any(isinstance(o, bool) or o != r for o, r in zip(orders, raw)):
        raise RotoridError(f"orders must be whole numbers >= 1 (an order is a multiple of the running speed), got "
                           f"{list(raw)!r}")
    if not orders or any(o < 1 for o in orders):
        raise RotoridError(f"orders must be whole numbers >= 1, got {orders!r}")
    from .._validate import index, number

    min_revs = index("min_revs", min_revs, 2)
    settle_revs = index("settle_revs", settle_revs, 0)
    steady = flag("steady", steady)
    speed_tolerance = number("speed_tolerance", speed_tolerance)
    if not (0 < speed_tolerance < 0.5):
        raise RotoridError(f"speed_tolerance must be between 0 and 0.5 (relative), got {speed_tolerance!r}")
    if revs_per_block is not None:
        revs_per_block = index("revs_per_block", revs_per_block, 1)
    if points_per_rev is not None:
        points_per_rev = index("points_per_rev", points_per_rev, 16, MAX_POINTS_PER_REV)
    if keyphasor is not None and not isinstance(keyphasor, dict):
        raise RotoridError(f"keyphasor options must be a dict of keyphasor_times keywords, got {keyphasor!r}")
    if kp is None:
        kp = detect_keyphasor(rec, keyphasor)
    elif not isinstance(kp, Keyphasor):
        kp = Keyphasor.from_times(kp, source=rec.source)
    if points_per_rev is None:
        spr = rec.fs_hz * np.max(kp.period_s)
        points_per_rev = int(max(64, 2 ** int(np.ceil(np.log2(max(spr, 2.0))))))
        points_per_rev = min(points_per_rev, 4096)
    elif isinstance(points_per_rev, bool) or int(points_per_rev) != points_per_rev or \
            not (16 <= points_per_rev <= MAX_POINTS_PER_REV):
        raise RotoridError(f"points_per_rev must be a whole number from 16 to {MAX_POINTS_PER_REV}, got {points_per_rev!r}")
    points_per_rev = int(points_per_rev)
    if max(orders) >= points_per_rev // 2:
        raise RotoridError(f"orders must be below points_per_rev/2 = {points_per_rev // 2} "
                           f"(got order {max(orders)} with points_per_rev = {points_per_rev})")
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
    # the channels as they are stored (the core takes them as a list: no (C, N) copy)
    x = [np.ascontiguousarray(rec.channels[c], dtype=float) for c in channels]
    # per-revolution order vectors (revs, orders, C): resampled and summed in the core, revolution by
    # revolution, so long records and fine grids need no more memory than the vectors
    per_rev = _order_vectors(x, rec.fs_hz, rec.t0_s, np.ascontiguousarray(kp.times), k0, k1, points_per_rev,
                             orders)
    rpm = kp.speed_rpm[k0:k1]
    tmid = kp.mid_times[k0:k1]
    delays = rec.meta.get("channel_delays_s", {}) or {}
    d = np.array([float(delays.get(c, 0.0)) for c in channels])
    om = (rpm * np.pi / 30.0)[:, None, None]
    nom = np.asarray(orders)[None, :, None] * om          # (revs, orders, 1): n Omega of each revolution
    if np.any(d):
        # x measured(t) = x(t - d): order n lags by n Omega d
        per_rev = per_rev * np.exp(1j * nom * d[None, None, :])
    if pedestal:
        # housing displacement from acceleration, revolution by revolution: a = -(n Omega)^2 x
        per_rev[:, :, 4:] = per_rev[:, :, 4:] / -(nom ** 2)
    if steady:
        sub = Keyphasor(kp.times[k0:k1 + 1])
        blocks = steady_segments(sub, tolerance=speed_tolerance, min_revs=int(min_revs), settle_revs=int(settle_revs))
        if not blocks:
            raise RotoridError(f"no steady-speed segment of at least {min_revs} revolutions in {rec.source!r} "
                               "(use steady=False for coast-downs)")
        blocks = (np.array([a for a, _ in blocks]), np.array([b - a for a, b in blocks]))
    else:
        rb = 4 if revs_per_block is None else revs_per_block
        if isinstance(rb, bool) or int(rb) != rb or rb < 1:
            raise RotoridError(f"revs_per_block must be a whole number >= 1, got {rb!r}")
        rb = int(rb)
        nb = rpm.size // rb
        if nb < 1:
            raise RotoridError(f"recording has {rpm.size} revolutions, fewer than revs_per_block = {rb}")
        blocks = (np.arange(nb) * rb, np.full(nb, rb))
    i1 = orders.index(1) if 1 in orders else None
    trend = None
    if steady and i1 is not None:
        per_rev, trend = _without_speed_trend(per_rev, rpm, *blocks, i1)
    mean, cov, dof, sp, scat, tm = _block_statistics(per_rev, rpm, tmid, *blocks, i1)
    if trend is not None:
        dof = np.where(trend, np.maximum(dof - 2.0, 1.0), dof)
    nrev = blocks[1]
    part = np.ascontiguousarray   # the probes' and the housings' parts as arrays of their own
    ped = dict(pedestal=part(mean[:, :, 4:]), pedestal_cov=part(cov[:, 8:, 8:]),
               pedestal_cross=part(cov[:, :8, 8:])) if pedestal else {}
    return SyncTrack(sp, part(mean[:, :, :4]), orders, nrev, scat, tm, [kp], part(cov[:, :8, :8]), dof, **ped)


def slow_roll_vector(rec: Recording, *, orders=(1, 2, 3), return_cov: bool = False, **kw):
    """Run-out vectors (n_orders, 4) from a slow-roll recording: the synchronous vectors at a speed
    low enough for the dynamic response to be negligible (mechanical and electrical run-out).
    With ``return_cov`` also the (8, 8) covariance of its 1X vector."""
    from .._validate import flag

    return_cov = flag("return_cov", return_cov)
    tr = track(rec, orders=orders, **kw)
    if tr.speed_rpm.size > 1:
        warnings.warn(f"slow-roll recording has {tr.speed_rpm.size} steady segments; using the slowest "
                      f"({tr.speed_rpm.min():.0f} rpm)")
    i = int(np.argmin(tr.speed_rpm))
    return (tr.vectors[i], tr.cov[i]) if return_cov else tr.vectors[i]
