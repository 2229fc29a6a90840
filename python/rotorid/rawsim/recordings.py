"""Simulated raw recordings: what a DAQ would record on the rig, exact for the linear model.

Imbalance runs are sequences of steady-speed dwells; in each dwell the probes see the exact
steady-state response to (added + remnant) imbalance, plus shaft run-out (1X to 3X, locked to the
rotor angle), plus white sensor noise, and a keyphasor channel with a smooth rising edge at rotor
angle 0. Transients between dwells are not simulated (the tracker skips the first revolutions of
each dwell anyway). Impact runs are at one steady speed: remnant-imbalance response and run-out,
plus the exact response to sampled force pulses (rotorid.impact_time_response), plus noise.
Responses are at the probe planes s1, s2 of the rotor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import RotoridError
from ..model import BearingCoefficients, Imbalance, RigidRotor
from ..recording import Recording
from ..simulate import RPM, half_sine_pulse, imbalance_response, impact_time_response

#: most samples per channel a simulated recording holds (33 min at 10 kHz, 160 MB a channel)
MAX_SAMPLES = 20_000_000
#: most run-out orders
MAX_ORDERS = 64


@dataclass(frozen=True)
class Runout:
    """Shaft run-out at the four probes: complex amplitudes (m, 0-pk) of orders 1..3, in the rotor
    frame (the same at every speed). Default: about 8 µm 1X, 3 µm 2X, 1 µm 3X with a fixed
    pseudo-random phase per probe."""

    amplitudes_m: tuple = (8e-6, 3e-6, 1e-6)
    seed: int = 11

    def __post_init__(self):
        from .._validate import real_array, seed

        a = real_array("amplitudes_m", self.amplitudes_m, ndim=1, nonneg=True)
        if not 1 <= a.size <= MAX_ORDERS:
            raise RotoridError(f"amplitudes_m must hold the run-out of orders 1..n (1 <= n <= {MAX_ORDERS}), got "
                               f"{a.size} value(s)")
        object.__setattr__(self, "amplitudes_m", tuple(float(v) for v in a))
        object.__setattr__(self, "seed", seed("seed", self.seed))

    def vectors(self) -> np.ndarray:
        """(n, 4) complex run-out vectors, orders 1..n (n = len(amplitudes_m)) x [x1, x2, y1, y2]."""
        rng = np.random.default_rng(self.seed)
        ph = rng.uniform(-np.pi, np.pi, (len(self.amplitudes_m), 4))
        mag = np.asarray(self.amplitudes_m)[:, None] * rng.uniform(0.7, 1.3, (len(self.amplitudes_m), 4))
        return mag * np.exp(1j * ph)


def _keyphasor(theta, fs_hz, omega, volts=5.0, width_rev=0.05):
    """Pulse train with smooth edges: rises through volts/2 exactly at theta = 0 mod 2 pi.
    ``omega`` (rad/s) may be a scalar or, for varying speed, one value per sample."""
    frac = np.mod(theta, 2 * np.pi) / (2 * np.pi)
    frac = np.where(frac > 0.5, frac - 1.0, frac)  # in [-0.5, 0.5): 0 at the pulse
    dt = frac * 2 * np.pi / omega  # time since the pulse (s)
    tau = 2.0 / fs_hz  # edge time constant: a few samples
    # a notch of 5 % of a revolution, but never narrower than 32 samples so the pulse reaches its
    # full height and the rising edge is not shifted by the falling one
    period = 2 * np.pi / omega
    width = np.minimum(np.maximum(width_rev * period, 32.0 / fs_hz), 0.4 * period)
    rise = 0.5 * (1 + np.tanh(dt / tau))
    fall = 0.5 * (1 + np.tanh((width - dt) / tau))
    return volts * rise * fall


def _n_samples(name, seconds, fs_hz, count=1):
    """Samples of one record of ``seconds`` (the argument ``name``) at ``fs_hz``: at least 16, and
    at most MAX_SAMPLES per channel over all ``count`` records."""
    n = seconds * fs_hz
    if count * n > MAX_SAMPLES:
        raise RotoridError(f"{name} = {seconds:g} s at fs_hz = {fs_hz:g} Hz{f' ({count} records)' if count > 1 else ''}"
                           f" is {count * n:.3g} samples per channel, more than the simulator's limit of "
                           f"{MAX_SAMPLES:.0e}")
    if n < 16:
        raise RotoridError(f"{name} = {seconds:g} s at fs_hz = {fs_hz:g} Hz holds fewer than 16 samples")
    return int(round(n))


def _models(rotor, bearings, **imbalances):
    """Type checks of the rig model arguments (every simulator takes them)."""
    from .._validate import instance

    instance("rotor", rotor, RigidRotor, what="rotorid.RigidRotor")
    instance("bearings", bearings, BearingCoefficients, what="rotorid.BearingCoefficients")
    for name, imb in imbalances.items():
        instance(name, imb, Imbalance, allow_none=True, what="rotorid.Imbalance")


def _turning(name, rpm):
    """Speeds (rpm) whose angular speed is > 0 in floating point (5e-324 rpm is not)."""
    if not np.all(np.asarray(rpm) * RPM > 0):
        raise RotoridError(f"{name} = {rpm!r} rpm is too slow to turn the rotor (its angular speed is 0)")


def _runout(runout):
    """(orders, 4) run-out vectors (at least one order: zeros without run-out)."""
    from .._validate import instance

    instance("runout", runout, Runout, allow_none=True, what="rawsim.Runout")
    return runout.vectors() if runout is not None else np.zeros((1, 4), complex)


def _pedestals(pedestals):
    """The pedestals argument checked (None: rigid supports)."""
    from .._validate import instance
    from ..pedestal import Pedestals

    instance("pedestals", pedestals, Pedestals, allow_none=True, what="rotorid.Pedestals")
    return pedestals


def _accel_channels(a, noise, rng):
    """Accelerometer channels px1, px2, py1, py2 from housing accelerations (4, N) in the order
    [xp1, xp2, yp1, yp2], with white noise of ``noise`` m/s² rms."""
    from ..pedestal import ACCEL_CHANNELS, PEDESTAL_DOFS

    a = a + noise * rng.standard_normal(a.shape)
    return {ACCEL_CHANNELS[d]: a[j] for j, d in enumerate(PEDESTAL_DOFS)}


def _with_1x(q, ro):
    """Run-out vectors with the 1X response ``q`` (4,) added to order 1."""
    v = np.array(ro, dtype=complex)
    v[0] += q
    return v


def _synchronous(q_vectors, theta):
    """sum over orders n of Re(V_n e^{j n theta}) for V (orders, 4) -> (4, N)."""
    out = np.zeros((q_vectors.shape[1], theta.size))
    for n, v in enumerate(q_vectors, start=1):
        e = np.exp(1j * n * theta)
        out += (v[:, None] * e[None, :]).real
    return out


def imbalance_recording(rotor: RigidRotor, bearings: BearingCoefficients, *, speeds_rpm, added: Imbalance | None,
                        remnant: Imbalance | None = None, runout: Runout | None = Runout(), noise_m: float = 0.5e-6,
                        dwell_s: float = 6.0, fs_hz: float = 10000.0, seed: int = 0, kind: str = "imbalance",
                        theta0: float = 0.3, pedestals=None, accel_noise_ms2: float = 0.02) -> Recording:
    """A run of steady dwells of ``dwell_s`` seconds at ``speeds_rpm`` with the ``added`` imbalance
    (None for a baseline run) on top of the ``remnant`` imbalance. Channels x1, x2, y1, y2 (probes,
    m), kp (V).

    With ``pedestals`` (a :class:`rotorid.Pedestals`) the bearings sit on flexible housings: the
    probes, mounted on them, read the rotor's motion relative to the housings, and accelerometers
    on the housings add channels px1, px2, py1, py2 (m/s², white noise ``accel_noise_ms2`` rms).

    Examples
    --------
    >>> import rotorid
    >>> from rotorid import rawsim
    >>> rotor, brg, remnant = rawsim.example_rig()
    >>> rec = rawsim.imbalance_recording(rotor, brg, speeds_rpm=[3000], added=None, remnant=remnant, dwell_s=1.0,
    ...                                  pedestals=rotorid.example_pedestals())
    >>> sorted(rec.channels)
    ['kp', 'px1', 'px2', 'py1', 'py2', 'x1', 'x2', 'y1', 'y2']
    """
    from .._validate import number, seed as _seed, speeds_rpm as _speeds, text

    _models(rotor, bearings, added=added, remnant=remnant)
    rng = np.random.default_rng(_seed("seed", seed))
    speeds = _speeds("speeds_rpm", speeds_rpm)
    fs_hz = number("fs_hz", fs_hz, positive=True)
    dwell_s = number("dwell_s", dwell_s, positive=True)
    noise_m = number("noise_m", noise_m, nonneg=True)
    theta0 = number("theta0", theta0)
    kind = text("kind", kind)
    pedestals = _pedestals(pedestals)
    accel_noise_ms2 = number("accel_noise_ms2", accel_noise_ms2, nonneg=True)
    _turning("speeds_rpm", speeds)
    _n_samples("dwell_s", dwell_s, fs_hz, speeds.size)
    ro = _runout(runout)
    chunks, kps, accs = [], [], []
    theta_start = theta0
    for rpm in speeds:
        om = rpm * RPM
        n = int(round(dwell_s * fs_hz))
        theta = theta_start + om * np.arange(n) / fs_hz
        q, p = np.zeros(4, complex), np.zeros(4, complex)
        for imb in (added, remnant):
            if imb is not None:
                r = imbalance_response(rotor, bearings, imb, speed_rpm=[rpm], at="probes", pedestals=pedestals)
                q += r.q[0]
                if pedestals is not None:
                    p += r.pedestal[0]
        sig = _synchronous(_with_1x(q, ro), theta)
        chunks.append(sig)
        if pedestals is not None:
            accs.append(_synchronous((-om ** 2 * p)[None, :], theta))
        kps.append(_keyphasor(theta, fs_hz, om))
        theta_start = theta[-1] + om / fs_hz
    x = np.concatenate(chunks, axis=1)
    x = x + noise_m * rng.standard_normal(x.shape)
    kp = np.concatenate(kps) + 0.01 * rng.standard_normal(x.shape[1])
    meta = dict(kind=kind, speed_rpm=speeds.tolist(), probes_at="probes")
    if added is not None:
        meta["imbalance"] = {"mass_kg": list(added.mass_kg), "angle_deg": list(added.angle_deg)}
        if added.name:
            meta["name"] = added.name
    chans = {"x1": x[0], "x2": x[1], "y1": x[2], "y2": x[3], "kp": kp}
    if pedestals is not None:
        chans.update(_accel_channels(np.concatenate(accs, axis=1), accel_noise_ms2, rng))
    return Recording(fs_hz, chans, meta, source=f"simulated {kind}")


def impact_recording(rotor: RigidRotor, bearings: BearingCoefficients, *, speed_rpm: float, plane: float,
                     direction: str, impact_times_s=(0.5, 1.2, 1.9, 2.6, 3.3), peak_N: float = 4000.0,
                     duration_s: float = 2e-3, record_s: float = 4.0, remnant: Imbalance | None = None,
                     runout: Runout | None = Runout(), noise_m: float = 0.5e-6, force_noise_N: float = 2.0,
                     fs_hz: float = 10000.0, seed: int = 0, theta0: float = 0.3, double_hit_at=None,
                     pedestals=None, accel_noise_ms2: float = 0.02) -> Recording:
    """Impacts at ``plane`` in ``direction`` while the rotor spins at ``speed_rpm``: channels x1, x2,
    y1, y2 (probes, m), kp (V), force (N). ``double_hit_at``: index of an impact to follow by a
    rebound 8 ms later (to exercise the detector). With ``pedestals``, probes read the motion
    relative to the housings and channels px1, px2, py1, py2 (m/s²) hold the housings'
    acceleration (see :func:`imbalance_recording`)."""
    from .._validate import choice, index, number, real_array, seed as _seed

    _models(rotor, bearings, remnant=remnant)
    rng = np.random.default_rng(_seed("seed", seed))
    speed_rpm = number("speed_rpm", speed_rpm, positive=True)
    _turning("speed_rpm", speed_rpm)
    plane = number("plane", plane)
    choice("direction", direction, {"x", "y"})
    peak_N = number("peak_N", peak_N, positive=True)
    duration_s = number("duration_s", duration_s, positive=True)
    record_s = number("record_s", record_s, positive=True)
    noise_m = number("noise_m", noise_m, nonneg=True)
    force_noise_N = number("force_noise_N", force_noise_N, nonneg=True)
    fs_hz = number("fs_hz", fs_hz, positive=True)
    theta0 = number("theta0", theta0)
    times = real_array("impact_times_s", impact_times_s, ndim=1)
    if times.size and not (times.min() >= 0 and times.max() < record_s):
        raise RotoridError(f"impact_times_s must lie within the record, 0 to record_s = {record_s:g} s, got "
                           f"{times.min():g} to {times.max():g} s")
    if double_hit_at is not None:
        double_hit_at = index("double_hit_at", double_hit_at, 0, times.size - 1)
    pedestals = _pedestals(pedestals)
    accel_noise_ms2 = number("accel_noise_ms2", accel_noise_ms2, nonneg=True)
    n = _n_samples("record_s", record_s, fs_hz)
    om = speed_rpm * RPM
    theta = theta0 + om * np.arange(n) / fs_hz
    q, p = np.zeros(4, complex), np.zeros(4, complex)
    if remnant is not None:
        r = imbalance_response(rotor, bearings, remnant, speed_rpm=[speed_rpm], at="probes", pedestals=pedestals)
        q = r.q[0]
        if pedestals is not None:
            p = r.pedestal[0]
    ro = _runout(runout)
    x = _synchronous(_with_1x(q, ro), theta)
    u = np.zeros(n)
    for k, t in enumerate(times.tolist()):
        u += half_sine_pulse(peak_N * (1 + 0.05 * k), duration_s, fs_hz, n, t0_s=t)
        if double_hit_at is not None and k == double_hit_at:
            u += half_sine_pulse(0.4 * peak_N, duration_s, fs_hz, n, t0_s=t + 0.008)
    tr = impact_time_response(rotor, bearings, speed_rpm=speed_rpm, force_N=u, fs_hz=fs_hz, plane=plane,
                              direction=direction, at="probes", pedestals=pedestals)
    x = x + tr.q.T + noise_m * rng.standard_normal((4, n))
    chans = {"x1": x[0], "x2": x[1], "y1": x[2], "y2": x[3], "kp": _keyphasor(theta, fs_hz, om),
             "force": u + force_noise_N * rng.standard_normal(n)}
    if pedestals is not None:
        acc = _synchronous((-om ** 2 * p)[None, :], theta) + tr.pedestal_accel.T
        chans.update(_accel_channels(acc, accel_noise_ms2, rng))
    meta = dict(kind="impact", speed_rpm=float(speed_rpm), plane=float(plane), direction=direction, probes_at="probes")
    return Recording(fs_hz, chans, meta, source=f"simulated impact {direction} at {plane:g} m")


def example_rig():
    """The NSF rotor with two different, cross-coupled bearings (bearing 2 stiffer in x, softer in
    y, different damping; stiffness 80 % of Table 4 so that 3000-6000 rpm lies mostly between the
    critical speeds, 3190/3243 and 4569 rpm) and probes away from the bearings, plus a remnant
    imbalance of 1.0 g and 0.6 g: the example data set's truth."""
    from ..model import nsf_rig

    rig = nsf_rig()
    k = np.array([[[2.4e6, 4.0e4], [2.4e4, 2.8e6]], [[2.9e6, -6.4e4], [4.8e4, 2.6e6]]])
    c = np.array([[[2000.0, 250.0], [800.0, 2200.0]], [[2600.0, -300.0], [500.0, 1800.0]]])
    return rig.rotor, BearingCoefficients(k, c), Imbalance((1.0e-3, 0.6e-3), (35.0, 160.0), name="remnant")


def coastdown_recording(rotor: RigidRotor, bearings: BearingCoefficients, *, start_rpm: float, stop_rpm: float,
                        duration_s: float, added: Imbalance | None, remnant: Imbalance | None = None,
                        runout: Runout | None = Runout(), noise_m: float = 0.5e-6, fs_hz: float = 10000.0,
                        seed: int = 0, theta0: float = 0.3) -> Recording:
    """A coast-down with the speed falling linearly from ``start_rpm`` to ``stop_rpm``.

    The response is quasi-steady, x(t) = Re(q(Omega(t)) e^{j theta(t)}): not exact (the transient
    terms scale with the deceleration), so use slow coast-downs, as on a rig with a free-wheeling
    clutch. Run-out, noise and keyphasor as in ``imbalance_recording``."""
    from .._validate import number, seed as _seed

    _models(rotor, bearings, added=added, remnant=remnant)
    rng = np.random.default_rng(_seed("seed", seed))
    start_rpm = number("start_rpm", start_rpm, positive=True)
    stop_rpm = number("stop_rpm", stop_rpm, positive=True)
    _turning("start_rpm", start_rpm)
    _turning("stop_rpm", stop_rpm)
    duration_s = number("duration_s", duration_s, positive=True)
    noise_m = number("noise_m", noise_m, nonneg=True)
    fs_hz = number("fs_hz", fs_hz, positive=True)
    theta0 = number("theta0", theta0)
    ro = _runout(runout)
    n = _n_samples("duration_s", duration_s, fs_hz)
    t = np.arange(n) / fs_hz
    rpm = start_rpm + (stop_rpm - start_rpm) * t / duration_s
    om = rpm * RPM
    theta = theta0 + np.cumsum(om) / fs_hz
    grid = np.linspace(min(start_rpm, stop_rpm), max(start_rpm, stop_rpm), 400)
    qg = np.zeros((grid.size, 4), complex)
    for imb in (added, remnant):
        if imb is not None:
            qg += imbalance_response(rotor, bearings, imb, speed_rpm=grid, at="probes").q
    q = np.stack([np.interp(rpm, grid, qg[:, j].real) + 1j * np.interp(rpm, grid, qg[:, j].imag) for j in range(4)])
    x = (q * np.exp(1j * theta)[None, :]).real
    x += _synchronous(ro, theta) + noise_m * rng.standard_normal(x.shape)
    kp = _keyphasor(theta, fs_hz, om)
    meta = dict(kind="imbalance", probes_at="probes", speed_rpm=[float(start_rpm), float(stop_rpm)])
    if added is not None:
        meta["imbalance"] = {"mass_kg": list(added.mass_kg), "angle_deg": list(added.angle_deg)}
    return Recording(fs_hz, {"x1": x[0], "x2": x[1], "y1": x[2], "y2": x[3], "kp": kp}, meta,
                     source="simulated coast-down")
