"""A second simulator: imbalance recordings as other DAQs make them.

Written apart from :mod:`rotorid.rawsim.recordings` so that tests do not only see what rotorid
itself would write. The rotor angle is explicit (theta(t) = theta0 + Omega t in each block), and:

- the keyphasor is any :class:`~rotorid.rawsim.keyphasor.PulseShape`, and its event happens when
  the rotor is at ``mark_angle_deg`` (not at rotorid's angle zero);
- every channel may lag the truth by its own delay (anti-alias filter group delay, cabling): the
  sample at time t holds the signal at t - delay;
- the ADC quantizes (``adc_bits`` over ``adc_range``, clipping at the rails);
- a step-speed test is one block per speed, each with its own start time and gaps between them
  (a :class:`~rotorid.recording.SegmentedRecording`), or one continuous record.
"""

from __future__ import annotations

import numpy as np

from ..model import BearingCoefficients, Imbalance, RigidRotor
from ..recording import Recording, SegmentedRecording
from ..simulate import RPM, imbalance_response
from .keyphasor import PulseShape, pulse_train


def _quantize(x, bits, full_range):
    if bits is None:
        return x
    lsb = full_range / 2.0 ** bits
    return np.clip(np.round(x / lsb) * lsb, -full_range / 2, full_range / 2 - lsb)


def lab_imbalance_recording(rotor: RigidRotor, bearings: BearingCoefficients, *, speeds_rpm, added: Imbalance | None,
                            remnant: Imbalance | None = None, runout_1x_m=(3e-6, 2e-6, 4e-6, 1e-6),
                            kp_shape: PulseShape = PulseShape("trapezoid", 2.0, duty=0.03),
                            mark_angle_deg: float = 0.0, kp_delay_s: float = 0.0, probe_delay_s=(0.0, 0.0, 0.0, 0.0),
                            adc_bits: int | None = 16, probe_range_m: float = 2e-3, kp_range_v: float = 20.0,
                            noise_m: float = 0.3e-6, dwell_s: float = 4.0, gap_s: float = 7.3, fs_hz: float = 10240.0,
                            segmented: bool = True, seed: int = 0, pedestals=None, accel_noise_ms2: float = 0.02,
                            accel_delay_s=(0.0, 0.0, 0.0, 0.0),
                            accel_range_ms2: float = 200.0) -> Recording | SegmentedRecording:
    """Dwells at ``speeds_rpm`` with the ``added`` imbalance (None: a baseline run) on top of the
    ``remnant`` imbalance; probes at the rotor's s1, s2 (channels x1, x2, y1, y2 in m, kp in V).

    ``runout_1x_m``: 1X run-out per probe (m, 0-pk; phase fixed per probe). ``probe_delay_s``: the
    delay of each of x1, x2, y1, y2. With ``segmented`` the result has one block per speed, the
    blocks ``gap_s`` apart; otherwise the dwells are concatenated (the speed changing within one
    sample, which a real drive cannot do; use it only with a single speed).

    ``pedestals``: flexible housings (:class:`rotorid.Pedestals`); the probes then read the motion
    relative to them and accelerometers add channels px1, px2, py1, py2 (m/s²), each with its
    delay in ``accel_delay_s`` (order px1, px2, py1, py2), noise ``accel_noise_ms2`` (m/s² rms) and the ADC's quantization over
    ``accel_range_ms2``."""
    from .._validate import flag, index, instance, number, real_array, seed as _seed, speeds_rpm as _speeds
    from ..errors import RotoridError
    from .recordings import _models, _n_samples, _turning

    _models(rotor, bearings, added=added, remnant=remnant)
    seed = _seed("seed", seed)
    rng = np.random.default_rng(seed)
    speeds = _speeds("speeds_rpm", speeds_rpm)
    _turning("speeds_rpm", speeds)
    instance("kp_shape", kp_shape, PulseShape, what="rawsim.PulseShape")
    mark_angle_deg = number("mark_angle_deg", mark_angle_deg)
    kp_delay_s = number("kp_delay_s", kp_delay_s)
    probe_delay_s = real_array("probe_delay_s", probe_delay_s, shape=(4,))
    if adc_bits is not None:
        adc_bits = index("adc_bits", adc_bits, 1, 64)
    probe_range_m = number("probe_range_m", probe_range_m, positive=True)
    kp_range_v = number("kp_range_v", kp_range_v, positive=True)
    noise_m = number("noise_m", noise_m, nonneg=True)
    dwell_s = number("dwell_s", dwell_s, positive=True)
    gap_s = number("gap_s", gap_s, nonneg=True)
    fs_hz = number("fs_hz", fs_hz, positive=True)
    segmented = flag("segmented", segmented)
    _n_samples("dwell_s", dwell_s, fs_hz, speeds.size)
    from .recordings import _pedestals
    pedestals = _pedestals(pedestals)
    accel_noise_ms2 = number("accel_noise_ms2", accel_noise_ms2, nonneg=True)
    accel_delay_s = real_array("accel_delay_s", accel_delay_s, shape=(4,))
    accel_range_ms2 = number("accel_range_ms2", accel_range_ms2, positive=True)
    if fs_hz * 60.0 / speeds.max() < 4:
        raise RotoridError(f"speeds_rpm up to {speeds.max():g} rpm at fs_hz = {fs_hz:g} Hz are fewer than 4 samples "
                           "per revolution: the keyphasor pulses cannot be sampled")
    if not segmented and speeds.size != 1:
        raise RotoridError("a continuous lab recording holds one speed; use segmented=True for several")
    ro = real_array("runout_1x_m", runout_1x_m, shape=(4,), nonneg=True) * np.exp(1j * np.array([0.4, 2.1, -1.3, 2.9]))
    mark = np.deg2rad(mark_angle_deg % 360.0)  # the same events (mark + 2 pi k), without cancellation
    blocks = []
    t_start = 0.0
    theta0 = 0.25
    for i, rpm in enumerate(speeds):
        om = rpm * RPM
        n = int(round(dwell_s * fs_hz))
        t = np.arange(n) / fs_hz
        q = ro.astype(complex)
        p = np.zeros(4, complex)
        for imb in (added, remnant):
            if imb is not None:
                r = imbalance_response(rotor, bearings, imb, speed_rpm=[rpm], at="probes", pedestals=pedestals)
                q = q + r.q[0]
                if pedestals is not None:
                    p = p + r.pedestal[0]
        chans = {}
        for j, name in enumerate(("x1", "x2", "y1", "y2")):
            theta = theta0 + om * (t - probe_delay_s[j])
            x = (q[j] * np.exp(1j * theta)).real + noise_m * rng.standard_normal(n)
            chans[name] = _quantize(x, adc_bits, probe_range_m)
        if pedestals is not None:
            for j, name in enumerate(("px1", "px2", "py1", "py2")):
                theta = theta0 + om * (t - accel_delay_s[j])
                a = (-om ** 2 * p[j] * np.exp(1j * theta)).real + accel_noise_ms2 * rng.standard_normal(n)
                chans[name] = _quantize(a, adc_bits, accel_range_ms2)
        # events: theta(t_k - kp_delay) = mark + 2 pi k, so the recorded pulse lags by kp_delay
        k0 = np.ceil((theta0 - mark) / (2 * np.pi) - 1)
        ks = k0 + np.arange(int(dwell_s * om / (2 * np.pi)) + 3)
        ev = (mark + 2 * np.pi * ks - theta0) / om + kp_delay_s
        ev = ev[(ev > -1.0) & (ev < dwell_s + 1.0)]
        if ev.size < 2:
            raise RotoridError(f"kp_delay_s = {kp_delay_s:g} s moves the keyphasor pulses out of the {dwell_s:g} s "
                               "dwell")
        chans["kp"] = _quantize(pulse_train(t, ev, fs_hz, kp_shape, seed=seed + 100 + i), adc_bits, kp_range_v)
        meta = dict(kind="imbalance" if added is not None else "baseline", probes_at="probes", speed_rpm=float(rpm))
        if added is not None:
            meta["imbalance"] = {"mass_kg": list(added.mass_kg), "angle_deg": list(added.angle_deg)}
        blocks.append(Recording(fs_hz, chans, dict(meta), t0_s=t_start,
                                source=f"lab simulator block {i} ({rpm:g} rpm)"))
        t_start += dwell_s + gap_s
        theta0 = float(rng.uniform(0, 2 * np.pi))
    meta = dict(blocks[0].meta)
    meta["speed_rpm"] = speeds.tolist()
    if segmented:
        return SegmentedRecording(blocks, meta, "lab simulator")
    b = blocks[0]
    return Recording(b.fs_hz, b.channels, meta, b.units, b.t0_s, "lab simulator")
