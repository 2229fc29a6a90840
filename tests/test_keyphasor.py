"""Keyphasor timing over a family of pulse signals rotorid's own recordings never contain.

The signals come from rawsim.keyphasor, which defines each event as the mid-height crossing of the
leading edge of a continuous pulse train and samples it ideally; the detector knows none of it.
Timing bias is the mean error over a record in samples; records are long enough (>= 600 pulses)
that the statistical error of the mean is well below the tolerance.
"""

import dataclasses
import re
import warnings

import numpy as np
import pytest

from rotorid import RotoridError, signals
from rotorid.rawsim import PulseShape, event_times, pulse_train
from rotorid.recording import Recording

FS = 10000.0


def _record(shape, rpm, n_pulses=600, mark=0.01373917, wander=0.0, seed=1):
    """Pulse train at ``rpm`` (with a slow +-wander relative speed variation), its true events."""
    period = 60.0 / rpm
    dur = (n_pulses + 0.5) * period + mark
    t = np.arange(int(dur * FS)) / FS
    if wander:
        k = np.arange(n_pulses + 2)
        ev = mark + np.cumsum(np.r_[0.0, np.full(k.size - 1, period) * (1 + wander * np.sin(2 * np.pi * k[1:] / 97.0))])
        ev = ev[ev < dur]
    else:
        ev = event_times(rpm, dur, mark_time_s=mark)
    return pulse_train(t, ev, FS, shape, seed=seed), ev


def _corrected(kp):
    """The equivalent-time correction was taken (not left unmeasured with the edge family's bound):
    the timing carries only the correction's own uncertainty (its template's noise and roughness,
    0-0.006 sample on clean records)."""
    unmeasured = ("could not be measured", "creeps so slowly", "positions within a sample interval")
    return kp.refined and not any(u in kp.note for u in unmeasured) and kp.timing_std_s * FS < 0.01


def _covered(kp, e):
    """The mean error lies within twice the stated uncertainty (or 0.001 sample)."""
    return abs(e.mean()) <= max(2.0 * kp.timing_std_s * FS, 0.001)


def _errors(kp, ev):
    idx = np.clip(np.searchsorted(ev, kp.times), 1, ev.size - 1)
    near = np.where(np.abs(ev[idx] - kp.times) < np.abs(ev[idx - 1] - kp.times), ev[idx], ev[idx - 1])
    return (kp.times - near) * FS


FAMILY = [
    PulseShape("trapezoid", 1.0), PulseShape("trapezoid", 2.0), PulseShape("trapezoid", 3.0),
    PulseShape("rc", 1.0), PulseShape("rc", 2.0),
    PulseShape("smooth", 1.0), PulseShape("smooth", 3.0), PulseShape.notch(),
    PulseShape("trapezoid", 2.0, duty=0.001), PulseShape("trapezoid", 2.0, duty=0.5),
    PulseShape("trapezoid", 2.0, low_v=5.0, high_v=0.0),            # negative-going
    PulseShape("rc", 2.0, drift_v=0.4, low_v=1.0, high_v=6.0),      # offset drift of 8 % of the swing
    PulseShape("trapezoid", 2.0, duty=0.3, ringing=(0.15, 900.0, 1e-3)),  # 15 % ringing after each edge
]
# measured, not reached (README "Keyphasor timing"): RC edges of 4 samples bias -0.010 samples; at
# 9871 rpm (61 samples per revolution) smooth 3-sample edges +0.0065 and the ringing case -0.020
NOT_AT_HIGH_SPEED = {("smooth", 3.0), ("trapezoid-ring", 2.0)}


@pytest.mark.parametrize("shape", FAMILY, ids=lambda s: f"{s.kind}-{s.edge_samples}-d{s.duty}-{s.low_v}{s.high_v}"
                         f"{'-drift' if s.drift_v else ''}{'-ring' if s.ringing else ''}")
@pytest.mark.parametrize("rpm", [347.3, 3456.7, 9871.3])
def test_timing_bias_below_5_thousandths_of_a_sample(shape, rpm):
    key = (shape.kind + ("-ring" if shape.ringing else ""), shape.edge_samples)
    if rpm > 9000 and key in NOT_AT_HIGH_SPEED:
        pytest.skip("target not reached at 61 samples per revolution (README)")
    v, ev = _record(shape, rpm)
    edge = "rising" if shape.duty >= 0.5 else "auto"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no extra/missing pulses may be reported on clean signals
        kp = signals.keyphasor_times(v, FS, edge=edge)
    e = _errors(kp, ev)
    assert kp.times.size >= 0.99 * ev.size
    assert abs(e.mean()) < 0.005, (e.mean(), np.abs(e).max())
    # per pulse: a drifting offset is followed from the samples before each edge (noise-like error)
    assert np.abs(e).max() < (0.35 if shape.drift_v else 0.06)
    # flat tops (with ringing or drift too) are not taken for humps, nor timed with a shape
    # uncertainty; where the top is still settling at the trailing edge (RC edges of 2 samples at 61
    # samples per revolution) or rings, the level's dependence on where it is read is in it (0.002)
    assert "no flat top" not in kp.note
    assert kp.timing_std_s * FS < 0.005 or "too short to settle" in kp.note
    assert _covered(kp, e), (e.mean(), kp.timing_std_s * FS)


@pytest.mark.parametrize("shape", [PulseShape("trapezoid", 2.0, noise_v=0.02), PulseShape("rc", 1.0, noise_v=0.02),
                                   PulseShape("smooth", 1.0, noise_v=0.05), PulseShape.notch(noise_v=0.02)],
                         ids=lambda s: f"{s.kind}-noise{s.noise_v}")
def test_timing_bias_with_noise(shape):
    v, ev = _record(shape, 3456.7, n_pulses=2000)
    kp = signals.keyphasor_times(v, FS)
    e = _errors(kp, ev)
    # per-pulse scatter from the noise; the mean stays within the tolerance plus 3 standard errors
    assert abs(e.mean()) < 0.005 + 3 * e.std() / np.sqrt(e.size), (e.mean(), e.std())
    assert kp.jitter_s * FS < 3 * e.std() + 1e-3


def test_ideal_steps_are_unbiased_only_on_average_and_commensurate_speeds_are_reported():
    # an ideal step carries no sub-sample information: error uniform in +-0.5 sample, zero mean
    v, ev = _record(PulseShape("rectangular"), 3456.7, n_pulses=2000)
    e = _errors(signals.keyphasor_times(v, FS), ev)
    assert abs(e.mean()) < 0.01 and np.abs(e).max() <= 1.0
    # at exactly 6000 rpm and 10 kHz every pulse falls at the same sub-sample position: said so
    v, ev = _record(PulseShape("rc", 1.0), 6000.0)
    kp = signals.keyphasor_times(v, FS)
    assert not kp.refined and "commensurate" in kp.note


def _phase_bias_deg(shape, rpm, wander):
    """1X phase error (deg) of a pure 1X signal tracked with the detected keyphasor."""
    v, ev = _record(shape, rpm, n_pulses=1200, wander=wander)
    n = v.size
    t = np.arange(n) / FS
    theta = 2 * np.pi * np.interp(t, ev, np.arange(ev.size), left=np.nan, right=np.nan)
    good = np.isfinite(theta)
    x = np.where(good, np.cos(np.where(good, theta, 0.0) + 0.7), 0.0)  # X = e^{0.7j}
    rec = Recording(FS, {"x1": x, "x2": x, "y1": x, "y2": x, "kp": v})
    tr = signals.track(rec, orders=(1,), steady=False, revs_per_block=1000)
    return np.rad2deg(np.angle(tr.order(1)[:, 0] * np.exp(-0.7j)))


def test_1x_phase_bias_at_6000_rpm_and_10_khz():
    # the other simulator's case: a 0-5 V trapezoid with 2-sample edges at exactly 6000 rpm, and with
    # a slow speed wander of +-0.02 %. (Not reached for steeper or asymmetric edges at this
    # commensurate speed: 0.03-0.44 deg measured, README "Keyphasor timing".)
    assert np.abs(_phase_bias_deg(PulseShape("trapezoid", 2.0), 6000.0, 0.0)).max() < 0.01
    assert np.abs(_phase_bias_deg(PulseShape("trapezoid", 2.0), 6000.0, 2e-4)).max() < 0.01
    assert np.abs(_phase_bias_deg(PulseShape("trapezoid", 3.0), 6000.0, 2e-4)).max() < 0.01
    # at a speed that is not commensurate with the sample rate, the other shapes too
    for shape in (PulseShape("trapezoid", 1.0), PulseShape("rc", 1.0), PulseShape("smooth", 1.0), PulseShape.notch()):
        assert np.abs(_phase_bias_deg(shape, 6007.3, 0.0)).max() < 0.01, shape


def test_the_old_percentile_level_failure_is_gone():
    # 0-5 V trapezoid, 2-sample edges: the percentile level landed at 2.40 V, 0.04 samples early
    v, ev = _record(PulseShape("trapezoid", 2.0, duty=0.03), 6000.0)
    kp = signals.keyphasor_times(v, FS)
    assert abs(kp.level - 2.5) < 1e-3 and np.abs(_errors(kp, ev)).max() < 1e-3


def test_narrow_pulses_at_low_speed_are_found():
    # 0.3 ms pulses at 300 rpm fill 0.15 % of the samples (once rejected as "flat")
    shape = PulseShape("trapezoid", 1.0, duty=0.0015, min_width_samples=2)
    v, ev = _record(shape, 300.0, n_pulses=20)
    kp = signals.keyphasor_times(v, FS)
    assert kp.times.size == ev.size and np.abs(_errors(kp, ev)).max() < 0.1


def test_mark_angle_and_delay_move_the_reference():
    v, ev = _record(PulseShape("trapezoid", 2.0), 3000.0, n_pulses=50)
    kp = signals.keyphasor_times(v, FS, mark_angle_deg=36.0, delay_s=20e-6)
    per = 60.0 / 3000.0
    np.testing.assert_allclose(kp.times, ev[: kp.times.size] - 0.1 * per - 20e-6, atol=2e-8)
    given = signals.Keyphasor.from_times(ev, mark_angle_deg=36.0)
    np.testing.assert_allclose(given.times, ev - 0.1 * per, atol=1e-12)


def test_options_reach_the_tracker_and_a_level_can_be_forced():
    v, ev = _record(PulseShape("trapezoid", 2.0), 3000.0, n_pulses=50)
    kp = signals.keyphasor_times(v, FS, level=2.0, hysteresis=0.5)
    assert kp.level == 2.0 and not kp.refined
    # a level below mid-height on a 2-sample edge times early by (2.5 - 2.0) / 2.5 = 0.2 samples
    np.testing.assert_allclose(np.mean(_errors(kp, ev)), -0.2, atol=1e-6)


# ---------------------------------------------------------------------------------------------
# bad input: one clear error that says what the channel looked like


def test_flat_and_noise_channels_are_refused_with_what_was_seen():
    with pytest.raises(signals.KeyphasorError, match="flat"):
        signals.keyphasor_times(np.zeros(1000), FS, source="run1.tdms, channel 'kp'")
    with pytest.raises(RotoridError, match="two distinct states"):
        signals.keyphasor_times(np.random.default_rng(0).standard_normal(20000), FS)


def test_pulses_on_both_polarities_are_refused():
    t = np.arange(40000) / FS
    up = pulse_train(t, event_times(3000.0, 4.0), FS, PulseShape("trapezoid", 2.0))
    dn = pulse_train(t, event_times(3000.0, 4.0, mark_time_s=0.009), FS, PulseShape("trapezoid", 2.0, high_v=-5.0))
    with pytest.raises(RotoridError, match="both polarities"):
        signals.keyphasor_times(up + dn, FS)


def test_a_speed_jump_beyond_the_tolerance_is_an_error_naming_it():
    t = np.arange(60000) / FS
    ev = np.r_[event_times(3000.0, 3.0), 3.0 + event_times(1900.0, 3.0, mark_time_s=0.031)]
    v = pulse_train(t, ev, FS, PulseShape("trapezoid", 2.0))
    with pytest.raises(RotoridError, match="the speed jumps .* from 3000.0 to"):
        signals.keyphasor_times(v, FS, source="step.csv, channel 'kp'")


@pytest.mark.parametrize("kw", [dict(edge="up"), dict(tolerance=0.0), dict(tolerance=1.5), dict(level=np.nan),
                                dict(hysteresis=-1.0), dict(mark_angle_deg=np.inf), dict(level=7.0)])
def test_bad_options_are_errors(kw):
    v, _ = _record(PulseShape("trapezoid", 2.0), 3000.0, n_pulses=20)
    with pytest.raises(RotoridError):
        signals.keyphasor_times(v, FS, **kw)


def test_bad_pulse_times_are_errors():
    with pytest.raises(RotoridError, match="increase"):
        signals.Keyphasor.from_times([0.0, 0.02, 0.01])
    with pytest.raises(RotoridError, match="NaN"):
        signals.Keyphasor.from_times([0.0, np.nan, 0.04])


def test_segmented_recording_has_no_false_missing_pulses_at_block_boundaries():
    from rotorid.recording import SegmentedRecording

    blocks = []
    for i, rpm in enumerate((3000.0, 3500.0, 4000.0)):
        v, ev = _record(PulseShape("trapezoid", 2.0), rpm, n_pulses=60, mark=0.0031 * (i + 1))
        n = v.size
        theta = 2 * np.pi * np.interp(np.arange(n) / FS, ev, np.arange(ev.size), left=0, right=0)
        x = np.cos(theta + 0.3) * 1e-5
        blocks.append(Recording(FS, {"x1": x, "x2": x, "y1": x, "y2": x, "kp": v}, t0_s=10.0 * i))
    seg = SegmentedRecording(blocks)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tr = signals.track(seg, orders=(1,))
    np.testing.assert_allclose(tr.speed_rpm, [3000.0, 3500.0, 4000.0], rtol=1e-6)
    np.testing.assert_allclose(tr.order(1)[:, 0], 1e-5 * np.exp(0.3j), rtol=2e-4)


def test_shape_family_generator_defines_events_at_mid_height():
    # the generator itself: the continuous pulse crosses mid-height exactly at the event
    fine = 1e6
    for shape in FAMILY[:9]:
        shape = dataclasses.replace(shape, noise_v=0.0)
        ev = np.array([0.01, 0.03])
        t = ev[0] + np.array([-1e-9, 1e-9])
        v = pulse_train(t, ev, FS, shape)
        mid = 0.5 * (shape.low_v + shape.high_v)
        assert (v[0] - mid) * (v[1] - mid) <= 0, shape
    assert fine


def test_pulses_on_both_polarities_can_be_chosen_with_edge_and_level():
    t = np.arange(40000) / FS
    ev_up = event_times(3000.0, 4.0)
    up = pulse_train(t, ev_up, FS, PulseShape("trapezoid", 2.0))
    dn = pulse_train(t, event_times(3000.0, 4.0, mark_time_s=0.009), FS, PulseShape("trapezoid", 2.0, high_v=-5.0))
    kp = signals.keyphasor_times(up + dn, FS, edge="rising", level=2.5)
    np.testing.assert_allclose(kp.times, ev_up[: kp.times.size], atol=1e-3 / FS)


def test_a_fifty_percent_speed_step_is_refused_by_default():
    t = np.arange(60000) / FS
    ev = np.r_[event_times(3000.0, 3.0), 3.0 + event_times(4500.0, 3.0, mark_time_s=0.011)]
    v = pulse_train(t, ev, FS, PulseShape("trapezoid", 2.0))
    with pytest.raises(RotoridError, match="3000.0 to 4500.0 rpm"):
        signals.keyphasor_times(v, FS)
    assert signals.keyphasor_times(v, FS, max_speed_step=0.6).times.size == ev.size


def test_a_pulse_level_carrying_float_round_off_is_one_state():
    """A clean pulse whose top alternates between 5.0 and the next float (a calibration's
    round-off) is one state, not a histogram numpy cannot bin (a bare ValueError before)."""
    n = np.arange(40000)
    kp = np.where((n / 100.37) % 1.0 < 0.1, 5.0, 0.0)
    top = np.flatnonzero(kp > 0)
    kp[top[::2]] = np.nextafter(5.0, 6.0)
    k = signals.keyphasor_times(kp, FS)
    assert k.states == pytest.approx((0.0, 5.0), abs=1e-12)
    assert k.times.size == 398
    # ideal steps: each time within a sample of its edge (the first sample above the rest)
    edges = np.flatnonzero((kp[1:] > 0) & (kp[:-1] == 0)) + 1
    assert edges.size == 398
    assert np.abs(k.times * FS - edges).max() <= 1.0


def _humps(rpm, sigma_samples, n_pulses=600, fs=FS):
    """Gaussian pulses of ``sigma_samples`` (no flat top) and their events: the crossing of half
    their peak on the leading flank."""
    period = 60.0 / rpm
    t = np.arange(int((n_pulses + 0.5) * period * fs)) / fs
    ev = 0.01373917 + np.arange(n_pulses) * period
    sig = sigma_samples / fs
    lead = sig * np.sqrt(2 * np.log(2))
    v = np.zeros_like(t)
    for e in ev:
        a, b = np.searchsorted(t, [e - 8 * sig, e + 10 * sig])
        v[a:b] += 5.0 * np.exp(-0.5 * ((t[a:b] - e - lead) / sig) ** 2)
    return v, ev


# measured, not reached (README "Keyphasor timing"): humps of under 3 samples at half their peak
# (sigma 1.2 samples) are still timed -0.042 samples early (-0.143 before): their sampled peak is
# too coarse for the parabola, which is then not trusted (it would overshoot a corner)
# exactly 6,000 and 5,000 rpm at 10 kHz: every pulse sampled at the same phases, whose samples
# pile into histogram modes; one such mode on the flank was taken for the pulse state (timed
# -0.27 samples, no note) until a state had to hold 3.5 samples per pulse
@pytest.mark.parametrize("rpm, sigma, bound", [(3457.3, 1.73, 0.01), (2213.9, 2.71, 0.01), (9871.3, 1.2, 0.05),
                                               (6000.0, 1.73, 0.025), (5000.0, 2.71, 0.01)])
def test_pulses_without_a_flat_top_are_timed_at_half_their_peak_and_noted(rpm, sigma, bound):
    """Gaussian keyphasor pulses (a narrow key under a wide probe spot) have no top to dwell at:
    the median of their middle half is 9-12 % below their peak, and mid-height taken there timed
    them 0.13-0.15 samples early (0.3-0.4 degrees of 1X at these speeds) with no note; found by an
    independent simulator. Half the peak is the level now, and the note says how much the timing
    depends on the pulse shape."""
    v, ev = _humps(rpm, sigma)
    kp = signals.keyphasor_times(v, FS)
    e = _errors(kp, ev)
    assert abs(e.mean()) < bound, e.mean()
    assert "no flat top" in kp.note and "samples earlier" in kp.note
    # the shape dependence the note gives is the timing uncertainty the chain propagates
    shift = float(re.search(r"time them ([0-9.]+) samples earlier", kp.note).group(1))
    # (at a speed commensurate with the sample rate the apex's sampling is unknowable: a third of a
    # sample at least, and said so)
    stuck = 1 / np.sqrt(12) if "fall at the same phases of the sampling" in kp.note else 0.0
    assert (stuck > 0) == (rpm in (5000.0, 6000.0))
    assert kp.timing_std_s * FS == pytest.approx(max(shift, stuck), abs=5e-4) and 0.05 < shift < 0.3
    # with a trigger level of the user's own, the level is their convention: no shape uncertainty
    assert signals.keyphasor_times(v, FS, level=2.5).timing_std_s == 0.0


@pytest.mark.parametrize("rpm", [347.3, 3456.7])
def test_ringing_on_a_drifting_offset_is_not_taken_for_a_hump(rpm):
    """15 % ringing after the edge on an offset drifting by 8 % of the swing: the overshoot lifts
    the peak and the drift widens the histogram, but the top is flat. An earlier form of the hump
    test (per-sample differences, noise from the spread of the drifting rest level) took it for a
    hump at 3456.7 rpm and timed it 0.23 samples late (found in review)."""
    shape = PulseShape("rc", 2.0, drift_v=0.4, low_v=1.0, high_v=6.0, duty=0.3, ringing=(0.15, 900.0, 1e-3))
    v, ev = _record(shape, rpm)
    kp = signals.keyphasor_times(v, FS)
    assert "no flat top" not in kp.note
    assert abs(_errors(kp, ev).mean()) < 0.005


def _pulses(kind, rpm, fs, frac, seconds=3.0, seed=0):
    """Pulses of ``kind`` ("triangle": rising linearly over frac of a revolution and falling as
    long; "narrow": a rectangle frac of a revolution wide) and their events (the triangle's half
    height on its rising flank, the rectangle's leading edge)."""
    t = np.arange(int(seconds * fs)) / fs
    per = 60.0 / rpm
    ev = 0.0123 + np.arange(int(seconds / per) - 1) * per
    v = np.zeros_like(t)
    width = frac * per
    for e in ev:
        a, b = np.searchsorted(t, [e - width, e + 2 * width])
        u = t[a:b] - (e - width / 2)  # the triangle starts half a rise before its event
        if kind == "triangle":
            v[a:b] += 5.0 * np.clip(1 - np.abs(u - width) / width, 0, None)
        else:
            v[a:b] += 5.0 * ((t[a:b] >= e) & (t[a:b] < e + width))
    return v + 0.01 * np.random.default_rng(seed).standard_normal(t.size), ev


@pytest.mark.parametrize("frac", [0.08, 0.02])
def test_triangular_pulses_are_timed_not_refused(frac):
    """Pulses that rise to a peak and fall at once have no upper state to dwell at: they were
    refused as "no two distinct states", even with a level given (found by an independent
    simulator). The median of their peaks is the pulse level now; they are timed at half of it,
    noted, and the shape's ambiguity is their timing uncertainty; with a level of the user's they
    are timed at it."""
    v, ev = _pulses("triangle", 3000.3, FS, frac)
    kp = signals.keyphasor_times(v, FS)
    assert kp.times.size == ev.size and abs(_errors(kp, ev).mean()) < 0.2
    assert "no flat top" in kp.note and kp.timing_std_s * FS > abs(_errors(kp, ev).mean())
    mine = signals.keyphasor_times(v, FS, level=2.5)
    assert abs(_errors(mine, ev).mean()) < 0.01 and mine.timing_std_s == 0.0


@pytest.mark.parametrize("make", [
    lambda rng, t: rng.standard_normal(t.size),                                  # noise
    lambda rng, t: 3 + 0.1 * rng.standard_normal(t.size),                        # noise on an offset
    lambda rng, t: np.sin(2 * np.pi * 50 * t) + 0.3 * rng.standard_normal(t.size),  # a noisy 1X signal
    lambda rng, t: rng.standard_normal(t.size) ** 3,                             # spiky noise
    lambda rng, t: _pulses("triangle", 3000.3, FS, 0.05)[0] - _pulses("triangle", 3000.3, FS, 0.05, seed=2)[0][
        np.arange(t.size) - 100],                                                # triangles both ways
    lambda rng, t: _pulses("triangle", 3000.3, FS, 0.3)[0],                      # a triangle wave, not pulses
], ids=["noise", "offset", "noisy-1X", "spiky", "bipolar", "triangle-wave"])
def test_noise_is_not_taken_for_a_train_of_peaked_pulses(make):
    t = np.arange(30000) / FS
    with pytest.raises(RotoridError, match="no two distinct states.*no train of like pulses"):
        signals.keyphasor_times(make(np.random.default_rng(1), t), FS)


@pytest.mark.parametrize("rise", [1.0, 1.5, 2.0, 2.5, 3.0])
@pytest.mark.parametrize("rpm", [2345.6, 3456.7, 6000.3, 3000.0])
def test_steep_triangles_are_timed_within_their_stated_uncertainty(rise, rpm):
    """Triangles rising over 1-3 samples: their sampled peaks vary with the sampling phase, and a
    first version refused them as a train (peaks within 10 %), then took a flank's histogram
    mode for the pulse state: 0.22-0.38 samples early with no note and no uncertainty (review).
    Now within max(2 timing_std_s, 0.05 samples) at every speed, never silently."""
    v, ev = _pulses("triangle", rpm, FS, rise * rpm / 60.0 / FS)
    kp = signals.keyphasor_times(v, FS)
    e = _errors(kp, ev)
    assert kp.times.size >= 0.95 * ev.size
    assert abs(e.mean()) <= max(2 * kp.timing_std_s * FS, 0.05), (e.mean(), kp.timing_std_s * FS, kp.note)


def test_pulses_narrower_than_a_sample_are_noted_and_their_timing_uncertain():
    """Pulses a third of a sample wide at 5 kHz: only the pulses a sample happens to fall in are
    seen. Before, 50 of 149 were timed 0.25 samples early without a note and the rest of the
    record silently went unused, or the gaps were reported as a speed jump at half speed."""
    fs = 5000.0
    v, ev = _pulses("narrow", 3000.3, fs, 0.0033)
    with pytest.warns(UserWarning, match=r"pulses only from t = 1.0[0-9]* to 1.6[0-9]* s of the record's 0 to 3 s"):
        kp = signals.keyphasor_times(v, fs)
    assert "sample(s) wide: their edges fall between samples" in kp.note
    assert kp.timing_std_s == pytest.approx(1 / np.sqrt(3) / fs)
    e = _errors(kp, ev)  # measured -0.98 to -0.33 samples
    assert np.all(np.abs(e) < 1.0) and abs(e.mean()) < 1.5 * kp.timing_std_s * fs
    v, ev = _pulses("narrow", 2713.3, fs, 0.005)
    with pytest.raises(RotoridError, match=r"running median period.*sampling misses some of them: record the "
                                           r"keyphasor at a higher rate"):
        signals.keyphasor_times(v, fs)
    # Gaussian pulses of sigma 0.4 sample: the equivalent-time correction, which finds no edge to
    # overlay in them, moved them 1.55 samples late; it does not apply to pulses this narrow now
    v, ev = _humps(4800.37, 0.4, n_pulses=160)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        kp = signals.keyphasor_times(v, FS)
    assert np.all(np.abs(_errors(kp, ev)) < 1.0) and kp.timing_std_s == pytest.approx(1 / np.sqrt(3) / FS)
    # pulses 2 samples wide are not narrow: as steps, they are timed to within the gap between the
    # samples that enclose their edges in equivalent time (0.11 sample here)
    v, ev = _pulses("narrow", 3000.3, FS, 0.02)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        kp = signals.keyphasor_times(v, FS)
    assert "wide: their edges fall between samples" not in kp.note and "the edges are steps" in kp.note
    assert 0.0 < kp.timing_std_s * FS < 0.035


def test_a_pulse_that_never_settles_nor_forms_a_train_is_refused_not_timed_at_its_tail():
    """RC pulses of tau = 4 samples cut at 3 samples, at 61 samples per revolution: the pulse
    reaches half its step and decays over the revolution, so its samples spread over every level
    without dwelling anywhere (the histogram's far mode holds 3 samples per pulse). It was timed
    16.8 samples late (at its tail) with only a "no flat top" note; now a state must hold 3.5
    samples per pulse, and without one or a train of like peaks the channel is refused, naming
    the fix."""
    v, ev = _record(PulseShape("rc", 4.0), 9871.3)
    with pytest.raises(RotoridError, match=r"holds 3 sample\(s\) per pulse, no state the pulses dwell at.*give a "
                                           r"trigger level and edge"):
        signals.keyphasor_times(v, FS)
    # and with them it is timed at that level
    assert abs(_errors(signals.keyphasor_times(v, FS, level=2.5, edge="rising"), ev).mean()) < 0.1


@pytest.mark.parametrize("tau,rpm", [(1.0, 347.3), (1.0, 3456.7), (2.0, 347.3), (2.0, 1234.5), (2.0, 3456.7)])
@pytest.mark.parametrize("ringing", [None, (0.05, 900.0, 1e-3)])
def test_an_offset_drifting_by_a_fifth_of_the_swing(tau, rpm, ringing):
    """A resting level drifting by +-20 % of the swing (0.3 Hz): the histogram's states sat at the
    drift's opposite extremes (a swing 35 % too large), so settled RC pulses were judged too short
    to settle and timed 0.43-0.87 samples late, and the Schmitt trigger missed the pulses where the
    rest rose above its lower threshold (77 of 300 "missing", filled by interpolation, which left
    the equivalent-time correction out: 0.075 samples with no uncertainty). The pulses are now
    detected and timed above their own base, and the drift is noted."""
    shape = PulseShape("rc", tau, drift_v=1.0, low_v=1.0, high_v=6.0, duty=0.3, ringing=ringing)
    v, ev = _record(shape, rpm, n_pulses=300)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no pulse may be reported missing or extra
        kp = signals.keyphasor_times(v, FS)
    e = _errors(kp, ev)
    assert kp.times.size >= 0.99 * ev.size
    assert abs(e.mean()) < 0.005, (e.mean(), np.abs(e).max())
    assert np.abs(e).max() < 0.06
    # settled (the level read above the rest as it drifts), and not judged too short to settle
    assert "too short to settle" not in kp.note and kp.timing_std_s * FS < 0.002
    assert re.search(r"resting level drifts by 2 \(40 % of the swing\)", kp.note), kp.note


def test_a_steady_offset_is_not_detrended():
    """Without drift the detection is the single pass it always was (no note)."""
    shape = PulseShape("rc", 2.0, low_v=1.0, high_v=6.0, duty=0.3, noise_v=0.02)
    v, ev = _record(shape, 3456.7)
    kp = signals.keyphasor_times(v, FS)
    assert "drifts" not in kp.note
    assert abs(_errors(kp, ev).mean()) < 0.005


@pytest.mark.parametrize("rpm", [3000.0, 4000.0, 6000.0])
@pytest.mark.parametrize("edge_samples", [1.0, 2.0])
def test_rc_edges_at_five_positions_per_sample_are_corrected(rpm, edge_samples):
    """At 10,240 Hz these speeds put 204.8, 153.6 and 102.4 samples in a revolution: the edges fall
    at 5 positions within a sample interval. The equivalent-time correction required 8 of its 16
    bins and was left out: RC edges of 1 sample stayed 0.074-0.078 samples late with no
    uncertainty (0.26 deg at 6,000 rpm, where 2.3 µs of timing moves the NSF rig's Cxx1 by 7.7 %).
    Five evenly spread positions sample the edge finely enough."""
    fs = 10240.0
    t = np.arange(int(4.0 * fs)) / fs
    for offset in (0.0013, 0.0071):
        ev = event_times(rpm, 4.0, mark_time_s=offset)
        kp = signals.keyphasor_times(pulse_train(t, ev, fs, PulseShape("rc", edge_samples, duty=0.03)), fs)
        idx = np.clip(np.searchsorted(ev, kp.times), 1, ev.size - 1)
        near = np.where(np.abs(ev[idx] - kp.times) < np.abs(ev[idx - 1] - kp.times), ev[idx], ev[idx - 1])
        err = (kp.times - near) * fs
        assert abs(err.mean()) < 0.008, (err.mean(), kp.note)


@pytest.mark.parametrize("rpm", [3500.0, 4500.0, 5000.0])
def test_one_sample_ramps_are_crossed_not_bounded(rpm):
    """A 1-sample trapezoid edge is a ramp: placed by the boundary between the samples below and
    above mid-height (a method for steps), its records scattered by +-0.01-0.03 samples at these
    speeds (10,240 Hz); crossed on its equivalent-time template they stay within 0.003, with no
    step uncertainty. An ideal step keeps the boundary, and its resolution is its uncertainty."""
    fs = 10240.0
    t = np.arange(int(4.0 * fs)) / fs
    errs, step_errs, step_stds = [], [], []
    for offset in (0.0011, 0.0042, 0.0077, 0.0123):
        ev = event_times(rpm, 4.0, mark_time_s=offset)
        kp = signals.keyphasor_times(pulse_train(t, ev, fs, PulseShape("trapezoid", 1.0, duty=0.03)), fs)
        errs.append(_mean_error(kp, ev, fs))
        assert kp.timing_std_s == 0.0 and "steps" not in kp.note
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            kp = signals.keyphasor_times(pulse_train(t, ev, fs, PulseShape("rectangular", duty=0.03)), fs)
        step_errs.append(_mean_error(kp, ev, fs))
        step_stds.append(kp.timing_std_s * fs)
    assert np.max(np.abs(errs)) < 0.003, errs
    # the steps' stated uncertainty is of the size of their scatter (uniform within the gap)
    assert np.all(np.array(step_stds) > 0.0), step_stds
    assert np.std(step_errs) < 2.0 * np.mean(step_stds), (step_errs, step_stds)


def _mean_error(kp, ev, fs):
    idx = np.clip(np.searchsorted(ev, kp.times), 1, ev.size - 1)
    near = np.where(np.abs(ev[idx] - kp.times) < np.abs(ev[idx - 1] - kp.times), ev[idx], ev[idx - 1])
    return float(((kp.times - near) * fs).mean())


def test_a_stretch_filling_eight_bins_of_part_of_a_sample_is_corrected():
    """At 120.505 samples per revolution the last 45 pulses of 301 (a stretch of their own) fall at
    positions filling 8 of the 16 bins but leaving a gap of 0.3 sample: the quarter-sample gap rule
    alone left them 0.07 samples off (found in review); with the 8-bin rule they are corrected."""
    fs = 10240.0
    rpm = 60.0 * fs / 120.505
    t = np.arange(int(302 * 120.505)) / fs
    ev = event_times(rpm, t[-1], mark_time_s=0.00371)
    ev = ev[ev < t[-1] - 0.3 * 120.505 / fs]
    kp = signals.keyphasor_times(pulse_train(t, ev, fs, PulseShape("rc", 1.0, duty=0.15)), fs)
    idx = np.clip(np.searchsorted(ev, kp.times), 1, ev.size - 1)
    near = np.where(np.abs(ev[idx] - kp.times) < np.abs(ev[idx - 1] - kp.times), ev[idx], ev[idx - 1])
    err = (kp.times - near) * fs
    assert abs(err[-44:].mean()) < 0.02, err[-44:].mean()
    # since steady stretches are split evenly (not cut at 256 pulses) these pulses share the
    # record's stretch, whose time base spans the positions' slow creep near half a sample per
    # revolution: the whole record reads 0.0005 (0.0125 before)
    assert abs(err.mean()) < 0.005, err.mean()


CREEP_SHAPES = [PulseShape("rc", 0.7), PulseShape("rc", 1.0), PulseShape("smooth", 0.6), PulseShape("trapezoid", 1.0)]


@pytest.mark.parametrize("shape", CREEP_SHAPES, ids=lambda s: f"{s.kind}-{s.edge_samples}")
@pytest.mark.parametrize("creep", [0.01, 0.02, 0.05, 0.98])
def test_edges_creeping_slowly_across_the_sample_positions_are_corrected(shape, creep):
    """120 + creep samples per revolution: each pulse's edge falls `creep` of a sample later within
    its sample interval than the last one's, so the interpolation error changes over 20-100
    revolutions. A time base over +-8 pulses followed it as if the speed varied, and RC edges of
    0.7-1 sample were timed 0.04-0.08 sample late with no uncertainty (a review's generator found
    them at 4-6 of 40 random speeds); the time base now spans 1.5 cycles of the positions."""
    v, ev = _record(shape, 60.0 * FS / (120.0 + creep))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        kp = signals.keyphasor_times(v, FS)
    e = _errors(kp, ev)
    assert _corrected(kp) and _covered(kp, e), (e.mean(), kp.timing_std_s * FS, kp.note)
    assert abs(e.mean()) < 0.005, e.mean()
    assert np.abs(e).max() < 0.02


@pytest.mark.parametrize("shape", CREEP_SHAPES + [PulseShape("trapezoid", 2.0), PulseShape("rc", 2.0)],
                         ids=lambda s: f"{s.kind}-{s.edge_samples}")
@pytest.mark.parametrize("creep", [0.0, 0.002, 0.5])
def test_positions_too_few_or_too_slow_to_correct_carry_the_uncertainty_their_samples_allow(shape, creep):
    """At a whole or half number of samples per revolution the pulses fall at one or two positions
    within a sample; creeping 0.002 sample per revolution they cover 1.2 samples in 600. Their
    interpolation error cannot be measured (it repeats, or cannot be told from a change of speed):
    RC edges of 0.7-1 sample were 0.07-0.17 sample late with no uncertainty. The times now carry
    half the largest error of the edge shapes their samples allow, and the note says why."""
    v, ev = _record(shape, 60.0 * FS / (120.0 + creep))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        kp = signals.keyphasor_times(v, FS)
    e = _errors(kp, ev)
    std = kp.timing_std_s * FS
    assert abs(e.mean()) <= 2.0 * std, (e.mean(), std)
    assert np.all(np.abs(e) <= 2.0 * kp.timing_std_each_s * FS + 0.01)
    assert ("positions within a sample interval" in kp.note or "creeps so slowly" in kp.note) and "sample for the edge shapes" in kp.note
    if shape.kind == "trapezoid" and shape.edge_samples == 2.0:
        # the ramp's samples exclude the long-tailed shapes: below the family-wide 0.09 sample
        assert std < 0.05


@pytest.mark.parametrize("shape", [PulseShape("rc", 0.7), PulseShape("rc", 1.0)], ids=lambda s: f"{s.kind}-{s.edge_samples}")
@pytest.mark.parametrize("rpm,wander", [(1500.0, 0.0005), (1500.0, 0.002), (2345.6, 0.002), (2345.6, 0.005),
                                        (3456.7, 0.0005), (3456.7, 0.005)])
def test_a_wandering_speed_keeps_the_narrow_time_base(shape, rpm, wander):
    """A speed wandering by +-0.05-0.5 % over 97 revolutions sweeps the positions within a sample
    quickly except where it turns. The first version of the creep-wide time base took its cycle
    from every window, the turns included: 50-90 pulses, a time base that could not follow the
    speed, and RC edges 0.03-0.09 sample late, some with no uncertainty. The wide time base is now
    taken only where it explains the times as well as the +-8-pulse one."""
    v, ev = _record(shape, rpm, wander=wander)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        kp = signals.keyphasor_times(v, FS)
    # (the correction's uncertainty follows the wander only roughly: 0.0001-0.0038 sample off against
    # 0.0003-0.0058, one case of 12 beyond twice it: 0.00105 against 0.0003)
    e = _errors(kp, ev)
    assert _corrected(kp), (e.mean(), kp.timing_std_s * FS, kp.note)
    assert abs(e.mean()) < 0.006


def test_a_coast_down_keeps_its_correction():
    """A coast-down of 3 %/s from 6000 rpm at 10,240 Hz: its steady stretches (1 % of speed each)
    are 40-50 pulses, and their positions within a sample sweep ever faster. The slow-creep rule,
    first applied to them too, left RC edges of one sample uncorrected (0.08 sample, within their
    new uncertainty); it now applies at one speed only, and they are corrected again."""
    fs, f0, a = 10240.0, 100.0, -3.0                  # rev/s, rev/s^2 (3 % of 100 rev/s per second)
    k = np.arange(int(8.0 * 85))
    ev = 0.00371 + (-f0 + np.sqrt(f0 * f0 + 2.0 * a * k)) / a   # f0 t + a t^2 / 2 = k
    ev = ev[ev < 7.9]
    t = np.arange(int(8.0 * fs)) / fs
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        kp = signals.keyphasor_times(pulse_train(t, ev, fs, PulseShape("rc", 1.0, duty=0.15)), fs)
    e = (kp.times - ev[np.argmin(np.abs(kp.times[:, None] - ev[None, :]), axis=1)]) * fs
    assert kp.refined
    blocks = np.array_split(e, 8)        # seconds of the coast-down: 0.0001-0.0077, as before the change
    assert max(abs(b.mean()) for b in blocks) < 0.01, [round(b.mean(), 4) for b in blocks]


@pytest.mark.parametrize("shape", [PulseShape("rc", 0.7), PulseShape("rc", 1.0)], ids=lambda s: f"{s.kind}-{s.edge_samples}")
def test_four_positions_per_sample_are_corrected_not_taken_for_a_creep(shape):
    """At exactly 100.25 samples per revolution the pulses fall at 4 evenly spread positions within
    a sample, which the correction uses. Read from the +-8-pulse fit, whose own interpolation error
    spreads them past the quarter-sample gap, they were taken for a slow creep (found in review:
    0.002-0.011 before, 0.04-0.08 then, with an uncertainty); the positions come from the
    quadratic over the stretch where it holds one speed."""
    v, ev = _record(shape, 60.0 * FS / 100.25)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        kp = signals.keyphasor_times(v, FS)
    e = _errors(kp, ev)
    assert _corrected(kp) and _covered(kp, e), (e.mean(), kp.timing_std_s * FS, kp.note)
    assert abs(e.mean()) < 0.015


# ---------------------------------------------------------------------------------------------
# the pulse level, the template's crossing and the correction's own uncertainty (2026-11-29, third
# part): a 4-run identification resolves the damping to 0.07-0.3 %, which a timing error of 0.002
# sample moves by twice that at 6,000 rpm and 10,240 Hz


def _second_order_record(tau, rpm, width, n_pulses=400, mark=0.0123457):
    """Rectangular pulses of ``width`` samples through a critically damped second-order low pass of
    time constant ``tau`` samples (step response 1 - (1 + u) e^-u, u = t / tau), 5 V, written here
    apart from rawsim: the edge approaches its top as slowly as u e^-u, and crosses mid-height
    1.6783 tau after the step."""
    def g(u):
        u = np.maximum(u, 0.0)
        return 1.0 - (1.0 + u) * np.exp(-u)
    period = 60.0 / rpm * FS
    steps = mark * FS + period * np.arange(n_pulses)
    n = np.arange(int(steps[-1] + period))
    v = np.zeros(n.size)
    for s in steps:
        near = slice(max(int(s) - 2, 0), min(int(s + width + 60 * tau), n.size))
        v[near] += 5.0 * (g((n[near] - s) / tau) - g((n[near] - s - width) / tau))
    return v, (steps + 1.678347 * tau) / FS


@pytest.mark.parametrize("rpm", [2345.6, 3456.7])
@pytest.mark.parametrize("source", ["rc-2", "rc-3", "second-order-1.5"])
def test_a_top_still_creeping_up_at_mid_pulse_is_read_where_it_has_settled(source, rpm):
    """An edge that approaches its top slowly (first-order tau = 2-3 samples, critically damped
    second order) is 0.05-0.3 % short of it in the middle of a 24-30 sample pulse. The level was
    read there, which put mid-height that much low: RC edges 0.0017-0.005 samples early with no
    uncertainty (damping errors of twice their standard errors in a 4-run identification on the
    second simulator, 83 % coverage at 5,000 rpm). The level is now read just before the trailing
    edge departs from the top."""
    if source.startswith("rc"):
        v, ev = _record(PulseShape("rc", float(source[3:]), duty=0.01), rpm, n_pulses=400)
    else:
        v, ev = _second_order_record(1.5, rpm, width=26.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        kp = signals.keyphasor_times(v, FS)
    e = _errors(kp, ev)
    assert abs(e.mean()) < 0.0005, e.mean()
    assert kp.timing_std_s * FS < 0.001 and "do not settle" not in kp.note, kp.note


@pytest.mark.parametrize("tau", [0.5, 0.7, 1.0])
@pytest.mark.parametrize("per_rev", [100.4, 100.0 + 3.0 / 7.0, 142.19])
def test_edges_at_few_positions_are_crossed_on_a_cubic(tau, per_rev):
    """At 5 or 7 positions within a sample (100.4 and 100 3/7 samples per revolution) the
    template's points lie 0.2 and 0.14 sample apart, and its linear crossing was 0.004-0.007
    samples late on RC edges (the error of a chord on a curved edge); it is read on a cubic now. At
    142.19 samples per
    revolution the +-8-pulse time base followed part of the interpolation error and bent the
    template (0.001-0.0017 late); the stretch's own quadratic serves now where it explains the times
    as well. Now within 0.0007 sample, and within the correction's stated uncertainty."""
    v, ev = _record(PulseShape("rc", tau), 60.0 * FS / per_rev)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        kp = signals.keyphasor_times(v, FS)
    e = _errors(kp, ev)
    if tau == 0.5 and per_rev == 100.0 + 3.0 / 7.0:
        # a steep edge (1.1 samples) needs 8 of the 16 bins: at 7 it is left uncorrected, with the
        # bound of the edge shapes its samples allow
        assert not _corrected(kp) and "positions within a sample interval" in kp.note
        assert _covered(kp, e), (e.mean(), kp.timing_std_s * FS)
        return
    assert _corrected(kp), kp.note
    assert abs(e.mean()) < 0.0007 and _covered(kp, e), (e.mean(), kp.timing_std_s * FS)


@pytest.mark.parametrize("shape,rpm,calibrated", [
    (PulseShape("rc", 2.0, duty=0.03, noise_v=0.01), 3456.7, True),
    (PulseShape("rc", 0.7, duty=0.03, noise_v=0.02), 60.0 * FS / 100.4, True),
    (PulseShape("rc", 2.0, duty=0.03, noise_v=0.04), 3456.7, False),
    (PulseShape("trapezoid", 2.0, duty=0.03, noise_v=0.02), 3456.7, False),
    (PulseShape("smooth", 1.0, duty=0.03, noise_v=0.05), 2345.6, False)],
    ids=["rc-2", "rc-0.7-5-positions", "rc-2-noise-0.8%", "trapezoid-2", "erf-1"])
def test_a_noisy_keyphasor_states_the_uncertainty_its_noise_leaves(shape, rpm, calibrated):
    """White noise of 0.2-1 % of the swing: the mean time of 150 pulses and the template's
    crossing carry its error, common to every pulse of the stretch. They were given no uncertainty
    (40 records each: mean errors up to 0.009 sample, nearly every one beyond twice its stated 0),
    and a 1-sample erf edge's noisy times were taken for a speed the time base missed (0.08 sample
    of edge-family bound for 0.002 of error). The timing now states the noise's share. Where the
    correction is taken (RC edges, whose position pattern shows) its uncertainty matches the
    spread of the mean errors over 30 records; where no pattern shows under the noise, the times
    are kept unless their template moves them by more than 3 times its uncertainty, and carry what
    the template says they may be off by: 5-7 times the error for an exact interpolation
    (trapezoid, erf), 1.3-1.5 times for RC edges whose cubic crossing is 0.009 sample off under
    0.8 % noise, the pattern unseen."""
    errs, stds = [], []
    for seed in range(30):
        v, ev = _record(shape, rpm, n_pulses=150, seed=seed)
        kp = signals.keyphasor_times(v, FS)
        errs.append(_errors(kp, ev).mean())
        stds.append(kp.timing_std_s * FS)
        assert "do not settle" not in kp.note, kp.note   # (a flat top's noise is no oscillation)
    errs, stds = np.array(errs), np.array(stds)
    rms = float(np.sqrt(np.mean(errs ** 2)))
    assert np.mean(np.abs(errs) > 2.0 * stds) <= 0.1, np.abs(errs / stds).max()
    if calibrated:
        assert 0.6 < rms / np.median(stds) < 1.6, (rms, np.median(stds))
    else:
        assert 0.1 < rms / np.median(stds) < 1.0, (rms, np.median(stds))
    if shape.kind != "rc":
        # an exact interpolation keeps its precision (0.0006 / 0.0018 sample; corrected, the
        # template's noise made them 0.0017 / 0.0064)
        assert rms < (0.001 if shape.kind == "trapezoid" else 0.003), rms


@pytest.mark.parametrize("shape", [PulseShape("rc", 1.0, duty=0.05, ringing=(0.05, FS / 4.0, 0.002)),
                                   PulseShape("smooth", 1.0, duty=0.03, ringing=(0.08, 3000.0, 0.001))],
                         ids=["rc-1", "erf-1"])
def test_a_ringing_top_that_does_not_settle_states_its_level_uncertainty(shape):
    """Ringing of 5-8 % of the swing at a quarter or a third of the sample rate that decays over
    10-20 samples, after RC or erf edges, on pulses of 13-20 samples: the top never settles, and
    the level read from it depends on where it is read by up to 5 % of the swing. Timed 0.005-0.027
    samples off with no uncertainty before; now within twice the level's uncertainty, with a note.
    (Three samples of ringing rising monotonically were first taken for an RC top's approach: the
    steps of an approach shrink.)"""
    fs = 10240.0
    for rpm in (1234.5, 2345.6, 3456.7, 5555.5):
        ev = event_times(rpm, 3.0, mark_time_s=0.3 * 60.0 / rpm + 0.37 / fs)
        kp = signals.keyphasor_times(pulse_train(np.arange(int(3.0 * fs)) / fs, ev, fs, shape, seed=3), fs)
        e = _errors(kp, ev) * fs / FS
        assert "tops do not settle" in kp.note, (rpm, kp.note)
        assert abs(e.mean()) <= max(2.0 * kp.timing_std_s * fs, 0.001), (rpm, e.mean(), kp.timing_std_s * fs)


def _rc_edge(x, tau):
    """Unit RC edge crossing 1/2 at x = 0 (its start, a kink, at -tau ln 2)."""
    u = np.maximum(x / tau + np.log(2.0), 0.0)
    return 1.0 - np.exp(-u)


@pytest.mark.parametrize("start", np.linspace(-0.19, -0.01, 9))   # (a point exactly at the crossing: one-sided)
def test_the_template_crossing_is_read_on_a_cubic(start):
    """Template points 0.2 sample apart (5 positions) on an RC edge of tau = 0.7: the chord between
    the two points straddling mid-height is 0.0071 sample off at worst, the cubic through them and
    their neighbours 0.0002 (0.001 for tau = 0.5, whose kink lies among the points). Its
    sensitivities dx/dy_j are those of the cubic it solved (central differences)."""
    from rotorid.signals import keyphasor as kpm

    gx = start + 0.2 * np.arange(-8, 9)
    for tau, tol in ((0.7, 3e-4), (0.5, 1.2e-3)):
        x, at, sens = kpm._crossing_of(gx, _rc_edge(gx, tau), 0.5)
        assert abs(x) < tol, (tau, x)
    gy = _rc_edge(gx, 0.7)
    x, at, sens = kpm._crossing_of(gx, gy, 0.5)
    assert at.size == 4
    for j, s in zip(at, sens):
        d = np.zeros(gy.size)
        d[j] = 1e-7
        fd = (kpm._crossing_of(gx, gy + d, 0.5)[0] - kpm._crossing_of(gx, gy - d, 0.5)[0]) / 2e-7
        assert fd == pytest.approx(s, rel=1e-4, abs=1e-9)


def test_one_position_split_by_a_bin_boundary_is_one_template_point():
    """Pulses at one position whose samples straddle a template bin boundary (-0.0005 and +0.0034
    sample) gave two points 0.004 apart with one value, which bent the crossing's cubic (0.024
    sample off): they are one point."""
    from rotorid.signals import keyphasor as kpm

    p = np.r_[np.arange(-3, 4) - 0.0005, np.arange(-3, 4) + 0.0034, np.arange(-3, 4) + 0.2][None, :]
    y = _rc_edge(p, 0.7)
    gx, gy, gn = kpm._template(p, y, np.ones(p.shape, dtype=bool), 4)
    assert np.min(np.diff(gx)) > 0.1 and gn.sum() == p.size
    assert np.isclose(gx, 0.00145).any()


def test_the_template_roughness_is_its_points_scatter_not_its_kinks():
    """Roughness of template points: about 0 on a smooth edge, the points' noise on a noisy one,
    and not raised by a linear edge's kinks five points from the crossing."""
    from rotorid.signals import keyphasor as kpm

    gx = 0.2 * np.arange(-10, 11) + 0.05
    at = np.array([9, 10])
    assert kpm._roughness(gx, _rc_edge(gx, 2.0), at) < 1e-4
    assert kpm._roughness(gx, np.clip(gx / 2.0 + 0.5, 0.0, 1.0), at) < 1e-12
    rng = np.random.default_rng(5)
    noisy = [kpm._roughness(gx, _rc_edge(gx, 2.0) + 1e-3 * rng.standard_normal(gx.size), at) for _ in range(200)]
    assert 0.5e-3 < np.median(noisy) < 1.5e-3, np.median(noisy)


def _filtered_pulses(b, a, per, width, n=20480, phase=37.3, drift=0.0, drift_per=3000.0, lead=None, noise=0.0,
                     seed=0):
    """Rectangular pulses of ``width`` samples every ``per`` samples (or from the samples ``lead``)
    through the analog filter b/a (time in samples, unit DC gain), sampled ideally, 5 V, on a 0.3 V
    offset with a sinusoidal drift of ``drift`` and white noise of ``noise`` of the swing; written
    here apart from rawsim (exact step response by partial fractions). Returns the samples and the
    true events (samples)."""
    from scipy import signal as sps
    from scipy.optimize import brentq

    b = np.asarray(b, float) / (np.asarray(b, float)[-1] / np.asarray(a, float)[-1])
    r, p, _ = sps.residue(b, np.polymul(a, [1.0, 0.0]))

    def step(t):
        t = np.asarray(t, float)
        return np.where(t >= 0, sum(ri * np.exp(pi * np.maximum(t, 0.0)) for ri, pi in zip(r, p)).real, 0.0)

    fine = np.linspace(0.0, 100.0, 100001)
    j = np.flatnonzero(step(fine) >= 0.5)[0]
    t50 = brentq(lambda t: float(step(np.array([t]))[0]) - 0.5, fine[j - 1], fine[j], xtol=1e-13)
    if lead is None:
        lead = phase + per * np.arange(int((n - 60 - phase) // per))
    k = np.arange(n)
    x = np.zeros(n)
    for e in lead:
        x += step(k - e) - step(k - e - width)
    x = x + drift * np.sin(2 * np.pi * k / drift_per + 0.7) + noise * np.random.default_rng(seed).standard_normal(n)
    return 5.0 * x + 0.3, lead + t50


def _butterworth3():
    from scipy import signal as sps
    return sps.butter(3, 0.8, analog=True)


def test_a_slow_offset_drift_keeps_the_narrow_time_base():
    """A resting level drifting by 5 % of the swing over 3000 samples moves the edge times slowly
    (0.0028 samples rms about a quadratic over the whole stretch, 0.0003 about the +-8-pulse one).
    The stretch's base was accepted within 0.003 samples of the narrow one's residual, the position
    pattern drowned in the drift, and the times were left uncorrected and silent (Butterworth-3 and
    second-order edges 0.0027-0.0033 off; found in review). The stretch's base must now explain the
    times within 1.25 times the narrow base's residual."""
    for b, a in (_butterworth3(), ([0.36], [1.0, 0.6, 0.36])):
        x, ev = _filtered_pulses(b, a, 133.37, 30.0, drift=0.05)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            kp = signals.keyphasor_times(x, FS)
        e = kp.times * FS - ev[np.abs(ev[:, None] - kp.times[None, :] * FS).argmin(axis=0)]
        assert kp.refined and abs(e.mean()) <= max(2 * kp.timing_std_s * FS, 0.001), (e.mean(), kp.timing_std_s * FS)
        assert abs(e.mean()) < 0.0008


@pytest.mark.parametrize("duty", [0.45, 0.6])
def test_pulses_filling_half_the_period_read_their_own_top(duty):
    """Where the pulses fill half the period or more, the scan back from the edge for where it
    leaves the rest reached into the previous pulse, and the level was read 11 samples into the
    pulse (second-order edges of damping 0.5: 0.03 samples off, with a "do not settle" note on a
    settled top; found in review). The scan takes the run of offsets from the edge only."""
    per = 133.37
    x, ev = _filtered_pulses([0.36], [1.0, 0.6, 0.36], per, duty * per)
    kp = signals.keyphasor_times(x, FS, edge="rising")
    e = kp.times * FS - ev[np.abs(ev[:, None] - kp.times[None, :] * FS).argmin(axis=0)]
    assert abs(e.mean()) < 0.001 and "do not settle" not in kp.note, (e.mean(), kp.note)


@pytest.mark.parametrize("filt", ["rc-2", "butterworth-3"])
def test_a_wandering_speed_under_noise_is_not_corrected_on_a_base_that_missed_it(filt):
    """The period wandering by +-0.5 % over 3000 samples, with noise of 0.2 % of the swing: no
    edge-position pattern shows through the noise, and the check that the time base had followed
    the speed was made only for quiet records, so a template read on a base that had missed it
    corrected the times 0.05-0.11 samples off (found in review). Now such times are unmeasured, and
    carry the edge shapes' bound."""
    b, a = ([1.0], [2.0, 1.0]) if filt == "rc-2" else _butterworth3()
    t = np.arange(20480.0)
    rev = np.cumsum(1.0 / (131.7 * (1 + 0.005 * np.sin(2 * np.pi * t / 3000.0))))
    lead = np.interp(np.arange(0.0, rev[-1] - rev[0]), rev - rev[0], t) + 37.3
    lead = lead[(lead > 30) & (lead < 20480 - 200)]
    for seed in (7, 8, 9, 10):
        x, ev = _filtered_pulses(b, a, None, 30.0, lead=lead, noise=0.002, seed=seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            kp = signals.keyphasor_times(x, FS)
        e = kp.times * FS - ev[np.abs(ev[:, None] - kp.times[None, :] * FS).argmin(axis=0)]
        assert abs(e.mean()) <= max(2 * kp.timing_std_s * FS, 0.001), (seed, e.mean(), kp.timing_std_s * FS)


@pytest.mark.parametrize("noise", [0.01, 0.02])
def test_noisy_times_are_not_corrected_by_a_template_of_noise(noise):
    """RC edges of 2 samples at 5 positions per sample (102.4 samples per revolution) under 1-2 %
    noise: no edge-position pattern shows in most records. They were corrected where the template
    moved them by more than 3 times its uncertainty, which selected the records whose template was
    noise (0.073 samples off against a stated 0.009; found in review). They are kept now, with the
    template's shift as their uncertainty; over 40 records none lies beyond twice it."""
    z = []
    for seed in range(40):
        x, ev = _filtered_pulses([1.0], [2.0, 1.0], 102.4, 30.0, phase=37.3137, noise=noise, seed=seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            kp = signals.keyphasor_times(x, FS)
        e = kp.times * FS - ev[np.abs(ev[:, None] - kp.times[None, :] * FS).argmin(axis=0)]
        z.append(abs(e.mean()) / max(kp.timing_std_s * FS, 1e-12))
    assert np.mean(np.array(z) > 2.0) <= 0.05, np.sort(z)[-5:]


def test_the_timing_uncertainty_local_to_a_dwell_is_told_apart_from_the_shapes():
    """``local_std_each_s``: the part of each pulse's timing uncertainty that changes from dwell to
    dwell (where the pulses fall between samples, noise, the correction's own), which a phase
    calibration's theta - Omega tau cannot follow; the rest is the pulse shape's, common to the
    record. RC edges of 0.5 sample at exactly 6000 rpm (5 positions): all local; Gaussian humps:
    the shape's alone; pulses a sample wide: local where they fall at the same few positions every
    revolution, the record's bias otherwise; pulses without a flat top sampled alike every
    revolution: a third of a sample local (where their apex lies between samples)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        v, _ = _record(PulseShape("rc", 0.5), 6000.0, n_pulses=300)
        rc = signals.keyphasor_times(v, FS)
        hump = signals.keyphasor_times(_humps(4321.0, 1.33, n_pulses=300)[0], FS)
        narrow = {rpm: signals.keyphasor_times(_record(PulseShape("trapezoid", 0.3, duty=0.0001, min_width_samples=1.0),
                                                       rpm, n_pulses=300)[0], FS) for rpm in (6000.0, 4321.0)}
        # no flat top, at a speed commensurate with the sample rate (every pulse sampled alike)
        peaked = signals.keyphasor_times(_record(PulseShape("trapezoid", 1.0, duty=0.0005, min_width_samples=1.0),
                                                 6000.0, n_pulses=300)[0], FS)
    assert rc.timing_std_each_s is not None and rc.local_std_each_s is not None
    np.testing.assert_allclose(rc.local_std_each_s, rc.timing_std_each_s)
    assert hump.timing_std_each_s is not None and np.all(hump.timing_std_each_s > 0)
    assert hump.local_std_each_s is None or np.all(hump.local_std_each_s <= 0.01 * hump.timing_std_each_s)
    for kp in narrow.values():
        np.testing.assert_allclose(kp.timing_std_each_s * FS, 1 / np.sqrt(3), rtol=1e-9)
    np.testing.assert_allclose(narrow[6000.0].local_std_each_s * FS, 1 / np.sqrt(3), rtol=1e-9)
    assert narrow[4321.0].local_std_each_s is None
    np.testing.assert_allclose(peaked.local_std_each_s * FS, 1 / np.sqrt(12), rtol=1e-9)
    assert "no flat top" in peaked.note and np.all(peaked.timing_std_each_s >= peaked.local_std_each_s)


def test_a_keyphasor_of_per_pulse_arrays_of_another_length_is_refused():
    """A hand-built Keyphasor whose per-pulse uncertainties do not match its times failed deep in
    the chain (a raw ValueError in the phase-uncertainty lookup; found in review)."""
    from rotorid.signals.keyphasor import Keyphasor, KeyphasorError

    t = np.arange(10) * 0.01
    Keyphasor(t, timing_std_each_s=np.full(10, 1e-6), local_std_each_s=np.zeros(10))
    for name in ("timing_std_each_s", "local_std_each_s"):
        with pytest.raises(KeyphasorError, match=f"{name} must hold one value per pulse time \\(10\\)"):
            Keyphasor(t, **{name: np.full(9, 1e-6)})


def _dwell_between_ramps(spr, shape, fs=12800.0, ramp_rpm_s=625.0, dwell_s=3.0):
    """(channel, event times s, dwell's events mask): 0.5 s at 500 rpm below a dwell of ``spr``
    samples per revolution, a ramp of ``ramp_rpm_s`` into it, the dwell, a ramp 500 rpm up and
    0.5 s there (a lab's test: the speed does not jump between dwells)."""
    rpm_d = fs * 60.0 / spr
    t_up = 500.0 / ramp_rpm_s
    marks = np.cumsum([0.5, t_up, dwell_s, t_up, 0.5])
    dt = 1e-5
    tt = np.arange(0.0, marks[-1], dt)
    rpm = np.interp(tt, [0.0, marks[0], marks[1], marks[2], marks[3], marks[4]],
                    [rpm_d - 500, rpm_d - 500, rpm_d, rpm_d, rpm_d + 500, rpm_d + 500])
    turns = 0.123 + np.cumsum(rpm / 60.0 * dt)
    ev = np.interp(np.arange(np.ceil(turns[0]), np.floor(turns[-1])), turns, tt)
    v = pulse_train(np.arange(0.0, marks[-1], 1.0 / fs), ev, fs, shape, seed=1)
    return v, ev, (ev > marks[1] + 0.3) & (ev < marks[2] - 0.3)


@pytest.mark.parametrize("spr", [255.999, 170.695, 192.002])
@pytest.mark.parametrize("shape", [PulseShape("smooth", 0.6, duty=0.03), PulseShape("trapezoid", 1.0, duty=0.03)],
                         ids=["erf-0.6", "trapezoid-1"])
def test_a_dwell_between_ramps_is_timed_as_one_speed(spr, shape):
    """The last revolutions of a ramp into a dwell are within 1 % of its period and joined its
    stretch, 0.3-5 samples off its speed: the dwell was then not taken for one speed, and a time
    base that follows the speed read a slowly creeping interpolation error as a change of it
    (255.999 samples per revolution: erf edges 0.048 samples early, a 1-sample trapezoid 0.068,
    against 0.006 stated; 170.695: 0.023 against 0.005). The ends are now split off: the dwell's
    mean error is within twice the timing uncertainty stated for it (+ 0.01 sample). An
    independent simulator's dwell at 192.002 was 0.18 samples late; these pulse trains at 192.002
    passed before too (kept as cases)."""
    fs = 12800.0
    v, ev, dwell = _dwell_between_ramps(spr, shape, fs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        kp = signals.keyphasor_times(v, fs)
    tk = np.asarray(kp.times)
    near = np.searchsorted(tk, ev[dwell] - 0.5 / fs)
    err = float(np.mean(tk[near] - ev[dwell])) * fs
    stated = 0.0 if kp.timing_std_each_s is None else float(np.mean(kp.timing_std_each_s[near])) * fs
    assert abs(err) <= 2.0 * stated + 0.01, (err, stated)


def test_pulses_that_narrow_with_speed_are_named_when_they_are_missed():
    """A mark of a fixed angle (2.5 degrees, 1-sample edges) is 2-3 samples wide on average over a
    run-up from 1500 to 6000 rpm at 12,800 Hz, but under a sample at the top: pulses are missed
    there, the periods jump, and the refusal named only blocks and max_speed_step (an independent
    simulator's notches of 1.5-3 degrees); it now names the narrow pulses and what to do."""
    fs, dt, span = 12800.0, 1e-5, 12.0
    tt = np.arange(0.0, span, dt)
    turns = 0.1 + np.cumsum(np.interp(tt, [0, 1, 11, span], [1500, 1500, 6000, 6000]) / 60.0 * dt)
    ev = np.interp(np.arange(np.ceil(turns[0]), np.floor(turns[-1])), turns, tt)
    v = pulse_train(np.arange(0.0, span, 1.0 / fs), ev, fs,
                    PulseShape("trapezoid", edge_samples=1.0, duty=2.5 / 360, min_width_samples=0.0), seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(RotoridError, match=r"speed jumps .* At the fastest speeds the pulses are only 0\.\d+ "
                                               r"sample\(s\) wide .* widen the mark"):
            signals.keyphasor_times(v, fs)


def test_a_genuine_speed_jump_is_not_blamed_on_narrow_pulses():
    """Two dwells joined without a ramp (3000 then 6000 rpm at 10 kHz, pulses 1.8 samples wide at
    the top): the periods are even on both sides, no pulse is missed, and the refusal does not
    name narrow pulses (it did, review)."""
    fs, dt, span = 10000.0, 1e-5, 4.0
    tt = np.arange(0.0, span, dt)
    turns = 0.1 + np.cumsum(np.where(tt < 2.0, 3000.0, 6000.0) / 60.0 * dt)
    ev = np.interp(np.arange(np.ceil(turns[0]), np.floor(turns[-1])), turns, tt)
    v = pulse_train(np.arange(0.0, span, 1.0 / fs), ev, fs,
                    PulseShape("trapezoid", edge_samples=0.5, duty=0.018, min_width_samples=0.0), seed=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(RotoridError, match="speed jumps") as err:
            signals.keyphasor_times(v, fs)
    assert "narrow" not in str(err.value) and "sample(s) wide" not in str(err.value), str(err.value)
