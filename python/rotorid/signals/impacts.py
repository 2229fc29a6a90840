"""Impacts on the force channel, the report's time-domain run-out filter, windows and H1 FRFs."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from .._corecall import core as _core
from ..errors import RotoridError
from ..recording import DISPLACEMENTS, Recording

#: longest window (samples) the window functions build (512 MB of float64)
MAX_WINDOW = 1 << 26
#: most doubles revolution_signature resamples at once (1 GB)
MAX_RESAMPLED = 1 << 27


def _fs(fs_hz, name="fs_hz"):
    from .._validate import number

    return number(name, fs_hz, positive=True)


def _positive(name, value, allow_zero=False):
    from .._validate import number

    return number(name, value, nonneg=allow_zero, positive=not allow_zero)


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
    largest peak, at least 8 x the robust noise level); pulses less than ``min_separation_s`` apart
    are one impact. Flags: "double hit" when another pulse of at least ``double_hit_fraction`` of
    the peak follows within ``double_hit_window_s`` (a bounce); "hits closer than
    min_separation_s" when such a pulse follows later but within ``min_separation_s`` (a second
    hit before the response to the first died out); "overload" when
    the signal sits at its maximum (or at ``overload_N``) for 3 or more samples (a clipped
    transducer or DAQ range)."""
    from .._validate import real_array

    f = real_array("force", force, finite=False)
    if f.ndim != 1 or f.size == 0 or not np.all(np.isfinite(f)):
        raise RotoridError("force must be a finite, non-empty 1-D signal")
    fs_hz = _fs(fs_hz)
    for nm, v in (("min_separation_s", min_separation_s), ("double_hit_window_s", double_hit_window_s)):
        _positive(nm, v)
    if not (0 < _positive("double_hit_fraction", double_hit_fraction) <= 1):
        raise RotoridError(f"double_hit_fraction must be in (0, 1], got {double_hit_fraction!r}")
    for nm, v in (("threshold_N", threshold_N), ("overload_N", overload_N)):
        if v is not None:
            _positive(nm, v)
    if not np.any(f):
        raise RotoridError("the force channel is all zeros: no impact to detect (wrong channel, or the hammer's "
                           "cable unplugged?)")
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
            strong = abs(f[pulses[j][2]]) >= double_hit_fraction * abs(f[pk])
            if pulses[j][0] - b <= dh and strong:
                if "double hit" not in flags:
                    flags.append("double hit")
            elif strong and "hits closer than min_separation_s" not in flags:
                # another hit, not a bounce: the response to the first has not died out
                flags.append("hits closer than min_separation_s")
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
    from .._validate import index, number, real_array
    from .order import MAX_POINTS_PER_REV

    x = real_array("x", x, ndim=2, finite=False)  # only the samples of the signature are checked, below
    kpt = real_array("kp_times", kp_times, ndim=1)
    fs_hz = _fs(fs_hz)
    t_start = number("t_start", t_start)
    t_stop = number("t_stop", t_stop)
    t0_s = number("t0_s", t0_s)

    points_per_rev = index("points_per_rev", points_per_rev, 16, MAX_POINTS_PER_REV)
    inside = np.nonzero((kpt >= t_start) & (kpt <= t_stop))[0]
    if inside.size < 2:
        raise RotoridError(f"no whole revolution between t = {t_start:.4f} s and {t_stop:.4f} s to build the "
                           "run-out signature (record more revolutions before the impact)")
    size = x.shape[0] * (int(inside[-1]) - int(inside[0])) * points_per_rev
    if size > MAX_RESAMPLED:
        raise RotoridError(f"{int(inside[-1]) - int(inside[0])} revolutions between t_start and t_stop at "
                           f"points_per_rev = {points_per_rev} are {size:.3g} resampled values, more than "
                           f"{MAX_RESAMPLED:.3g}: shorten t_start..t_stop or lower points_per_rev")
    # the samples the signature reads (with the cubic stencil's reach), not the whole record
    i_a = max(0, int(np.floor((kpt[inside[0]] - t0_s) * fs_hz)) - 2)
    i_b = min(x.shape[1], int(np.ceil((kpt[inside[-1]] - t0_s) * fs_hz)) + 3)
    window = x[:, i_a:i_b]
    if not np.isfinite(window).all():
        bad = np.argwhere(~np.isfinite(window))[0]
        raise RotoridError(f"x contains NaN or inf in the revolutions of the run-out signature (channel {int(bad[0])}, "
                           f"sample {i_a + int(bad[1])})")
    res = _core.angle_resample(np.ascontiguousarray(x, dtype=float), fs_hz, t0_s, np.ascontiguousarray(kpt),
                               int(inside[0]), int(inside[-1]), int(points_per_rev))
    return res.mean(axis=1)


def runout_filter(x, fs_hz: float, kp_times, template, i0: int, i1: int, *, t0_s: float = 0.0) -> np.ndarray:
    """The report's time-domain run-out filter: samples i0..i1 of x (C, N) minus the revolution
    signature ``template`` (C, P) placed at each sample's rotor angle from the keyphasor pulses
    (each revolution stretched to its own pulse interval, so slow speed drift does not smear the
    subtraction). Runs in the Rust core. Samples before the first or after the last keyphasor pulse
    have no rotor angle: they come back NaN (check with ``np.isfinite``)."""
    from .._validate import index, number, real_array

    x = real_array("x", x, finite=False)  # NaN/inf are counted by the core on its way through
    template = real_array("template", template)
    kp_times = real_array("kp_times", kp_times, ndim=1)
    t0_s = number("t0_s", t0_s)
    if x.ndim != 2 or template.ndim != 2 or template.shape[0] != x.shape[0] or template.shape[1] < 4:
        raise RotoridError(f"runout_filter needs x (channels, samples) and a template (channels, points >= 4) with the "
                           f"same channels, got {x.shape} and {template.shape}")
    i0 = index("i0", i0, 0)
    i1 = index("i1", i1, 0)
    if not (0 <= i0 < i1 <= x.shape[1]):
        raise RotoridError(f"need 0 <= i0 < i1 <= {x.shape[1]} (the samples to filter), got i0 = {i0}, i1 = {i1}")
    fs_hz = _fs(fs_hz)
    out, nonfinite = _core.runout_subtract(np.ascontiguousarray(x, dtype=float), float(fs_hz), float(t0_s),
                                           np.ascontiguousarray(kp_times, dtype=float),
                                           np.ascontiguousarray(template, dtype=float), int(i0), int(i1))
    if nonfinite:
        bad = np.argwhere(~np.isfinite(x[:, i0:i1]))[0]
        raise RotoridError(f"x contains NaN or inf ({nonfinite} values in samples {i0}..{i1}, first at channel "
                           f"{int(bad[0])}, sample {i0 + int(bad[1])})")
    return out


def exponential_window(n: int, fs_hz: float, tau_s: float, start: int = 0) -> np.ndarray:
    """w(t) = exp(-(t - t_start)/tau) after ``start`` (1 before). Applied to force and response alike,
    the FRF it produces is H(s) at s = 1/tau + j w. Identifying from it as if s were j w would bias
    the damping; give the decay to the identification (``ImpactResponse(sigma=1/tau)``, or
    ``impact_chain(exp_window_tau_s=tau)``) and it solves the equations at s instead."""
    fs_hz = _fs(fs_hz)
    tau_s = _positive("tau_s (exponential window)", tau_s)
    from .._validate import index

    n = index("n", n, 1, MAX_WINDOW)
    start = index("start", start, 0, n)
    t = (np.arange(n) - start) / fs_hz
    return np.where(t > 0, np.exp(-np.clip(t, 0, None) / tau_s), 1.0)


def force_window(n: int, start: int, stop: int, *, taper: int = 0) -> np.ndarray:
    """Rectangular window around the force pulse (zero elsewhere, removing force-channel noise),
    optionally with cosine tapers of ``taper`` samples on each side."""
    from .._validate import index

    n = index("n", n, 1, MAX_WINDOW)
    start = index("start", start, 0, n - 1)
    stop = index("stop", stop, start + 1, n)
    taper = index("taper", taper, 0, n)
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
    cov: np.ndarray | None = None
    dof: float = float("nan")


def frf_h1(forces, responses, fs_hz: float) -> FRF:
    """H1 FRF and coherence from equally long force records (list of (N,)) and response records
    (list of (C, N)), one pair per impact.

    With n >= 2 impacts and C = 4 channels (or 8: probes then accelerometers, the covariance then
    over [Re q, Im q, Re p, Im p]), also the covariance of H1's [Re, Im] per frequency
    from the scatter of the single impacts: with X_i = H F_i + N_i, H1 - H = Σ N_i F_i* / Σ|F_i|²,
    estimated from the residuals R_i = X_i - H1 F_i as Σ_i outer(R_i F_i* / Σ|F|²) / (1 - Σ_i w_i²)
    (real 8-vector form), w_i = |F_i|² / Σ|F|² (each impact's leverage: 1 - 1/n, the usual
    n / (n - 1), where the forces are equal), with n - 1 degrees of freedom. A frequency at which no impact has any force
    has no H1: h and coherence are NaN there, flagged by ``force`` = 0."""
    try:
        forces, responses = list(forces), list(responses)
    except TypeError:
        raise RotoridError(f"forces and responses must be lists of records (one per impact), got "
                           f"{type(forces).__name__} and {type(responses).__name__}") from None
    if len(forces) != len(responses) or not forces:
        raise RotoridError("frf_h1 needs one response record per force record (and at least one)")
    fs_hz = _fs(fs_hz)
    from .._validate import real_array

    forces = [real_array(f"forces[{i}]", f, ndim=1) for i, f in enumerate(forces)]
    responses = [real_array(f"responses[{i}]", x, ndim=2) for i, x in enumerate(responses)]
    n = forces[0].size
    if n < 16:
        raise RotoridError(f"force records must hold at least 16 samples, got {n}")
    for i, f in enumerate(forces):
        if not np.any(f):
            raise RotoridError(f"forces[{i}] is all zeros: no excitation, no FRF")
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
    m = len(forces)
    cov, dof = None, float("nan")
    if m >= 2 and h.shape[1] in (4, 8):
        c2 = 2 * h.shape[1]
        cov = np.zeros((freq.size, c2, c2))
        lev = np.zeros(freq.size)
        for f, x in zip(forces, responses):
            F = np.fft.rfft(f)
            with np.errstate(divide="ignore", invalid="ignore"):
                lev += (np.abs(F) ** 2 / sff) ** 2
            X = np.fft.rfft(np.asarray(x), axis=-1).T
            with np.errstate(divide="ignore", invalid="ignore"):
                e = (X - h * F[:, None]) * np.conj(F)[:, None] / sff[:, None]
            # [Re, Im] per group of 4 channels (probes, then accelerometers: [Re q, Im q, Re p, Im p])
            r = np.concatenate([part for g in range(0, e.shape[1], 4) for part in (e[:, g:g + 4].real,
                                                                                   e[:, g:g + 4].imag)], axis=1)
            cov += r[:, :, None] * r[:, None, :]
        # E|R_i|² = (1 - w_i) E|N|² with w_i = |F_i|² / Σ|F|² (each impact pulls H1 towards itself),
        # so E Σ |R_i F_i*|² / (Σ|F|²)² = (1 - Σ w_i²) E|H1 - H|²: 1 - 1/n for equal forces (the
        # usual n / (n - 1)); hits of unequal force, a hammer tip changed after the first (3 ms, then
        # 0.7 ms pulses), made it 0.2-0.4 and the intervals covered 0.89 (review)
        # (where one impact carries all the force, 1 - Σ w_i² is 0: no scatter to see, NaN, which
        # flags the point "uncertainty unknown"; inf made the chain fail, review)
        rest = 1.0 - lev
        with np.errstate(divide="ignore", invalid="ignore"):
            cov /= np.where(rest > 1e-12, rest, np.nan)[:, None, None]
        dof = float(m - 1)
    return FRF(freq, h, coh, np.sqrt(sff / m), m, cov=cov, dof=dof)
