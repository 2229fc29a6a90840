"""Bad input gets one clear RotoridError naming the argument, never a silent wrong number or a
traceback from deep inside (issue: never a silent wrong number)."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import rotorid
from rotorid import RotoridError, signals
from rotorid.recording import Recording

RIG = rotorid.nsf_rig()


def test_complex_values_are_not_cast_to_real():
    with pytest.raises(RotoridError, match="complex"):
        rotorid.RigidRotor(mass_kg=45.3 + 1j, it_kgm2=0.7, ip_kgm2=0.3, l1=0.2, l2=0.2)
    k = RIG.bearings.k + 1j * 2 * np.pi * 50 * RIG.bearings.c  # K + j w C, the damping would be dropped
    with pytest.raises(RotoridError, match="complex"):
        rotorid.BearingCoefficients(k, RIG.bearings.c)
    with pytest.raises(RotoridError, match="complex"):
        rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances["A"], speed_rpm=[3000 + 1j])
    with pytest.raises(RotoridError, match="complex"):
        Recording(1000.0, {"x1": np.ones(10) * (1 + 1j)})


def test_strings_and_booleans_are_not_numbers():
    with pytest.raises(RotoridError, match="string"):
        rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances["A"], speed_rpm="3000")
    with pytest.raises(RotoridError):
        Recording(True, {"x1": np.ones(10)})
    with pytest.raises(RotoridError):
        Recording("1e3", {"x1": np.ones(10)})


def test_probe_transform_needs_four_responses():
    with pytest.raises(RotoridError, match="four responses"):
        rotorid.probes_to_bearings(RIG.rotor, np.ones((3, 5)))


@pytest.mark.parametrize("t0", [np.nan, np.inf, "x"])
def test_recording_start_time_must_be_finite(t0):
    with pytest.raises(RotoridError, match="t0_s"):
        Recording(1000.0, {"x1": np.ones(10)}, t0_s=t0)


def test_empty_channels_and_bad_rates_are_refused():
    with pytest.raises(RotoridError, match="empty"):
        Recording(1000.0, {"x1": np.zeros(0)})
    for fs in (0.0, -1.0, np.nan, "fast"):
        with pytest.raises(RotoridError, match="fs_hz"):
            Recording(fs, {"x1": np.ones(10)})
        with pytest.raises(RotoridError, match="fs_hz"):
            signals.detect_impacts(np.r_[np.zeros(50), 100.0, np.zeros(50)], fs)
        with pytest.raises(RotoridError, match="fs_hz"):
            signals.exponential_window(100, fs, 0.1)


def test_signal_processing_arguments_are_checked():
    with pytest.raises(RotoridError, match="tau_s"):
        signals.exponential_window(100, 1000.0, 0.0)
    with pytest.raises(RotoridError, match="all zeros"):
        signals.detect_impacts(np.zeros(100), 1000.0)
    with pytest.raises(RotoridError, match="threshold_N"):
        signals.detect_impacts(np.r_[np.zeros(50), 100.0, np.zeros(50)], 1000.0, threshold_N=-1.0)
    rotor, brg, remnant = rotorid.rawsim.example_rig()
    rec = rotorid.rawsim.imbalance_recording(rotor, brg, speeds_rpm=[3000.0], added=None, remnant=remnant, dwell_s=0.5)
    with pytest.raises(RotoridError, match="whole numbers"):
        signals.track(rec, orders=(1, 1.5))
    for kw in (dict(peak_N=100.0, duration_s=0.0, fs_hz=1000.0, n_samples=10),
               dict(peak_N=100.0, duration_s=1e-3, fs_hz=np.nan, n_samples=10),
               dict(peak_N=100.0, duration_s=1e-3, fs_hz=1000.0, n_samples=-3)):
        with pytest.raises(RotoridError):
            rotorid.half_sine_pulse(**kw)


def test_batch_with_dependent_imbalances_in_a_trial_is_refused():
    rpm = np.array([4000.0, 5000.0])
    q = np.stack([rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances[s], speed_rpm=rpm).q
                  for s in "AB"])[None].repeat(3, axis=0)
    e = np.stack([RIG.imbalances[s].generalized(RIG.rotor) for s in "AB"])[None].repeat(3, axis=0)
    e[1, 1] = 2j * e[1, 0]  # trial 1: run B's imbalance a complex multiple of run A's
    with pytest.raises(rotorid.IdentifiabilityError, match="trial 1"):
        rotorid.identify_synchronous_batch(RIG.rotor, rpm, q, e)


# ---------------------------------------------------------------------------------------------
# property: whatever the arguments, a RotoridError or a result, never another exception

bad_numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10, 10 ** 9), st.just("x"),
                        st.just(None), st.just(True), st.complex_numbers(max_magnitude=1e6), st.just([1.0, 2.0]))


@settings(max_examples=300, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(fs=bad_numbers, t0=bad_numbers, tau=bad_numbers, level=bad_numbers, tol=bad_numbers)
def test_public_signal_functions_fail_only_with_rotorid_errors(fs, t0, tau, level, tol):
    kp = np.r_[np.zeros(40), 5.0 * np.ones(5)] .repeat(1)
    kp = np.tile(kp, 20)
    calls = [lambda: Recording(fs, {"x1": np.ones(16)}, t0_s=t0),
             lambda: signals.exponential_window(64, fs, tau),
             lambda: signals.keyphasor_times(kp, fs, t0_s=t0, level=level, tolerance=tol),
             lambda: signals.detect_impacts(np.r_[np.zeros(50), 100.0, np.zeros(50)], fs, threshold_N=level)]
    for call in calls:
        try:
            call()
        except RotoridError:
            pass


def test_an_undamped_rotor_at_its_natural_frequency_is_singular_not_a_huge_number():
    undamped = rotorid.BearingCoefficients(RIG.bearings.k, np.zeros((2, 2, 2)))
    m = rotorid.modal_analysis(RIG.rotor, undamped, speed_rpm=[1e-9])
    for fn in np.sort(np.abs(m.freq_hz.ravel()))[:4]:
        with pytest.raises(RotoridError, match="singular"):
            rotorid.impact_frf(RIG.rotor, undamped, speed_rpm=0, freq_hz=[fn])
    # a lightly damped resonance is a large, finite, trustworthy response
    light = rotorid.BearingCoefficients(RIG.bearings.k, RIG.bearings.c * 1e-4)
    r = rotorid.impact_frf(RIG.rotor, light, speed_rpm=0, freq_hz=np.sort(np.abs(m.freq_hz.ravel()))[:1])
    assert np.all(np.isfinite(r.q))


def test_identical_bearings_assumed_on_different_bearings_is_flagged():
    rotor, brg, _ = rotorid.rawsim.example_rig()
    rpm = np.arange(3000, 6001, 500.0)
    for bearings, expect in ((brg, True), (RIG.bearings, False)):
        runs = [rotorid.imbalance_response(rotor, bearings, RIG.imbalances[s], speed_rpm=rpm, at="probes")
                for s in "AB"]
        i = rotorid.identify_synchronous(rotor, runs, identical=True)
        # without a covariance: residuals above 1 % of the forces (here 6 of 7 speeds; all are "uncertain")
        assert sum("identical bearings rejected" in f for f in i.flag) >= (6 if expect else 0)
        assert not expect or not i.ok.any()
        # with a measurement covariance, the test is against the measurement errors
        for r in runs:
            r.cov = np.broadcast_to(np.eye(8) * (1e-8) ** 2, (rpm.size, 8, 8))
        i = rotorid.identify_synchronous(rotor, runs, identical=True)
        assert all(("identical bearings rejected" in f) == expect for f in i.flag), i.flag


def test_messages_name_the_real_cause():
    import dataclasses

    flat = dataclasses.replace(RIG.rotor, d=(0.05, -0.05))  # both planes at z = -0.05 m
    runs = [rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances[s], speed_rpm=[4000.0, 5000.0])
            for s in "AB"]
    with pytest.raises(rotorid.IdentifiabilityError, match="imbalance planes coincide"):
        rotorid.identify_synchronous(flat, runs)
    runs[1] = rotorid.SyncResponse(runs[1].speed_rpm, np.zeros((2, 4)), runs[1].imbalance)
    with pytest.raises(rotorid.IdentifiabilityError, match="zero response"):
        rotorid.identify_synchronous(RIG.rotor, runs)


def test_core_argument_errors_are_rotorid_errors():
    x = np.zeros((4, 100))
    for kw in (dict(i0=-5, i1=10), dict(i0=50, i1=10), dict(i0=0, i1=1000)):
        with pytest.raises(RotoridError, match="i0"):
            signals.runout_filter(x, 1000.0, np.arange(0, 0.1, 0.01), np.zeros((4, 16)), **kw)
    with pytest.raises(RotoridError, match="same channels"):
        signals.runout_filter(x, 1000.0, np.arange(0, 0.1, 0.01), np.zeros((3, 16)), 0, 10)


def test_more_messages_that_name_the_cause(tmp_path):
    rpm = np.array([4000.0, 5000.0])
    runs = [rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances[s], speed_rpm=rpm) for s in "AB"]
    with pytest.raises(RotoridError, match="True or False"):
        rotorid.identify_synchronous(RIG.rotor, runs, identical="yes")
    huge = [rotorid.SyncResponse(rpm, r.q * 1e300, r.imbalance) for r in runs]
    with pytest.raises(RotoridError, match="overflows"):
        rotorid.identify_synchronous(RIG.rotor, huge)
    with pytest.raises(RotoridError, match="directory"):
        rotorid.load_recording(tmp_path, fmt="csv")
    from rotorid.pipeline import _safe

    assert len(_safe("x" * 300)) == 60 and _safe("") == "unnamed"


def test_an_output_too_large_for_memory_is_a_memory_error_not_an_abort():
    from rotorid import _core

    x = np.zeros((4, 1000))
    kp = np.arange(0.0, 1.0, 0.01)
    with pytest.raises(MemoryError, match="angle_resample"):
        _core.angle_resample(x, 1000.0, 0.0, kp, 0, 90, 2 ** 28)   # 773 GB
    with pytest.raises(MemoryError):
        _core.angle_resample(x, 1000.0, 0.0, kp, 0, 90, 2 ** 62)   # the size overflows


def test_sweep_findings_are_rotorid_errors(tmp_path):
    from rotorid import io as rio
    from rotorid import tables
    from rotorid.recording import SegmentedRecording

    bad = [
        lambda: signals.frf_h1(np.ones((3, 2048)) * 0, np.ones((3, 4, 2048)), 1e4),
        lambda: signals.frf_h1([np.ones(64) + 1j], [np.ones((4, 64))], 1e4),
        lambda: signals.frf_h1([np.zeros(0)], [np.zeros((4, 0))], 1e4),
        lambda: signals.frf_h1(["ab"], ["cd"], 1e4),
        lambda: signals.frf_h1([np.zeros(2048)], [np.ones((4, 2048))], 1e4),
        lambda: signals.frf_h1([np.ones(2048)], [np.ones(2048)], 1e4),
        lambda: signals.force_window(100, 10.5, 50),
        lambda: signals.force_window(100, 50, 10),
        lambda: signals.force_window(100, 10, 50, taper=-1),
        lambda: signals.exponential_window("100", 1e4, 0.1),
        lambda: signals.exponential_window(True, 1e4, 0.1),
        lambda: signals.exponential_window(100, 1e4, 0.1, start=200),
        lambda: signals.keyphasor_times(np.tile(np.r_[np.zeros(40), 5 * np.ones(5)], 20), 1e4, fill_missing="no"),
        lambda: Recording(1e4, [1, 2]),
        lambda: Recording(1e4, {"x1": "abc"}),
        lambda: Recording(1e4, {"x1": np.ones(10, bool)}),
        lambda: Recording(1e4, {1: np.ones(10)}),
        lambda: Recording(1e4, {"x1": np.ones(10)}, meta=[1]),
        lambda: SegmentedRecording.from_arrays(1e4, {"x1": [np.ones(10), np.ones(5)]}),
        lambda: SegmentedRecording.from_arrays(1e4, [1]),
        lambda: rio.save_recording(Recording(1e4, {"x1": np.ones(10)}), tmp_path),
        lambda: rio.save_recording(Recording(1e4, {"x1": np.ones(10)}), tmp_path / "out.csv"),
        lambda: rio.save_csv(Recording(1e4, {"x1": np.ones(10)}), tmp_path / "no" / "a.csv"),
        lambda: rio.load_recording(None),
        lambda: rotorid.ProbeResolution(noise_m="0"),
        lambda: rotorid.ProbeResolution(amplitude_m=-1.0),
        lambda: rotorid.RigidRotor(True, 0.704, 0.299, 0.189, 0.217),
        lambda: rotorid.Imbalance(mass_kg=(True, False)),
        lambda: rotorid.BearingCoefficients(RIG.bearings.k.astype(bool), RIG.bearings.c),
        lambda: rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances["A"], speed_rpm=True),
        lambda: tables.match_speeds([], tolerance_rpm="2"),
    ]
    for i, call in enumerate(bad):
        with pytest.raises(RotoridError):
            call()


# ---------------------------------------------------------------------------------------------
# found by the sweep over every public function (tests/test_fuzz.py): each refusal names the argument

def _bad_argument_cases():
    from rotorid import kcm, outputs, phasecal, rawsim, tables, uncertainty
    from rotorid import io as rio
    from rotorid.recording import SegmentedRecording

    rotor, brg, remnant = rawsim.example_rig()
    imb = rotorid.Imbalance((5e-3, 5e-3), (0.0, 0.0))
    sim = dict(rotor=rotor, bearings=brg, added=imb, remnant=remnant, fs_hz=2000.0)
    rec = Recording(1000.0, {"x1": np.zeros(32)})
    seg = SegmentedRecording.from_arrays(1000.0, {"x1": np.zeros((2, 8))})
    track = tables.load_1x_table(tables.EXAMPLE_DIR + "/run_S0.csv", columns=tables.EXAMPLE_COLUMNS)
    kp = np.tile(np.r_[np.zeros(40), 5.0 * np.ones(5)], 20)
    x = np.zeros((4, 1000))
    return [
        # simulators: no argument was checked beyond speeds_rpm, fs_hz, dwell_s, noise_m
        ("runout", lambda: rawsim.imbalance_recording(speeds_rpm=[3000.0], dwell_s=0.1, runout=1.0, **sim)),
        ("seed", lambda: rawsim.imbalance_recording(speeds_rpm=[3000.0], dwell_s=0.1, seed=-1.0, **sim)),
        ("theta0", lambda: rawsim.imbalance_recording(speeds_rpm=[3000.0], dwell_s=0.1, theta0="x", **sim)),
        ("duration_s", lambda: rawsim.coastdown_recording(start_rpm=4000.0, stop_rpm=3000.0, duration_s=np.nan, **sim)),
        ("fs_hz", lambda: rawsim.coastdown_recording(start_rpm=4000.0, stop_rpm=3000.0, duration_s=0.2,
                                                     **{**sim, "fs_hz": 1e12})),  # 2e11 samples, never allocated
        ("stop_rpm", lambda: rawsim.coastdown_recording(start_rpm=4000.0, stop_rpm="x", duration_s=0.2, **sim)),
        ("speed_rpm", lambda: rawsim.impact_recording(rotor, brg, speed_rpm=5e-324, plane=0.0, direction="x",
                                                      record_s=0.3, impact_times_s=(0.1,), fs_hz=2000.0)),
        ("direction", lambda: rawsim.impact_recording(rotor, brg, speed_rpm=1000.0, plane=0.0, direction=["x"],
                                                      record_s=0.3, impact_times_s=(0.1,), fs_hz=2000.0)),
        ("impact_times_s", lambda: rawsim.impact_recording(rotor, brg, speed_rpm=1000.0, plane=0.0, direction="x",
                                                           record_s=0.3, impact_times_s=0.1, fs_hz=2000.0)),
        ("record_s", lambda: rawsim.impact_recording(rotor, brg, speed_rpm=1000.0, plane=0.0, direction="x",
                                                     record_s=-1.0, impact_times_s=(0.1,), fs_hz=2000.0)),
        ("double_hit_at", lambda: rawsim.impact_recording(rotor, brg, speed_rpm=1000.0, plane=0.0, direction="x",
                                                          record_s=0.3, impact_times_s=(0.1,), double_hit_at=[1])),
        ("speeds_rpm", lambda: rawsim.lab_imbalance_recording(speeds_rpm=1e12, dwell_s=0.1, **sim)),  # was 12 GB
        ("probe_delay_s", lambda: rawsim.lab_imbalance_recording(speeds_rpm=[3000.0], dwell_s=0.1, probe_delay_s=0.0,
                                                                 **sim)),
        ("adc_bits", lambda: rawsim.lab_imbalance_recording(speeds_rpm=[3000.0], dwell_s=0.1, adc_bits=1e12, **sim)),
        ("kp_shape", lambda: rawsim.lab_imbalance_recording(speeds_rpm=[3000.0], dwell_s=0.1, kp_shape=None, **sim)),
        ("segmented", lambda: rawsim.lab_imbalance_recording(speeds_rpm=[3000.0], dwell_s=0.1, segmented="no", **sim)),
        ("kp_delay_s", lambda: rawsim.lab_imbalance_recording(speeds_rpm=[3000.0], dwell_s=0.1, kp_delay_s=1e12,
                                                              **sim)),
        ("edge_samples", lambda: rawsim.PulseShape("trapezoid", 0.0)),  # 0/0 in the edge: a NaN pulse train
        ("kind", lambda: rawsim.PulseShape(np.array(["rc"]))),
        ("duty", lambda: rawsim.PulseShape(duty=1.5)),
        ("ringing", lambda: rawsim.PulseShape(ringing=(0.1, 900.0))),
        ("event_times", lambda: rawsim.pulse_train(np.arange(10.0), [2.0, 1.0], 1.0)),
        ("shape", lambda: rawsim.pulse_train(np.arange(10.0), [2.0], 1.0, shape="rc")),
        ("speed_rpm", lambda: rawsim.event_times(1e12, 10.0)),  # was 10 GB of event times
        ("t0_s", lambda: rawsim.event_times(3000.0, 1.0, t0_s=np.nan)),  # was a silent NaN
        ("amplitudes_m", lambda: rawsim.Runout(amplitudes_m=(1e-6, -1e-6))),
        # writers and readers
        ("names", lambda: rio.save_csv(rec, "unused.csv", names=1.0)),
        ("units", lambda: rio.save_uff58(rec, "unused.uff", units=["mil"])),
        ("path", lambda: rio.save_tdms(rec, None)),
        ("dtype", lambda: rio.save_tdms(rec, "unused.tdms", dtype={"x1": "mil"})),
        ("groups", lambda: rio.save_tdms_segmented(seg, "unused.tdms", groups=3)),
        ("path", lambda: rio.list_groups(3.0)),
        ("min_run", lambda: rio.check_clipping(rec, min_run="5")),
        ("rec", lambda: rio.check_clipping(None)),
        ("fmt", lambda: rio.load_recording("unused.npz", fmt=np.array(["csv"]))),
        # tables
        ("path", lambda: tables.load_1x_table(None, columns=tables.EXAMPLE_COLUMNS)),
        ("meta", lambda: tables.load_1x_table(tables.EXAMPLE_DIR + "/run_S0.csv", columns=tables.EXAMPLE_COLUMNS,
                                              meta=[1])),
        ("amplitude_std", lambda: tables.load_1x_table(tables.EXAMPLE_DIR + "/run_S0.csv",
                                                       columns=tables.EXAMPLE_COLUMNS, amplitude_std=[1.0, 2.0])),
        ("preamble", lambda: tables.save_1x_table(track, "unused.csv", preamble="Machine: m")),
        ("preamble", lambda: tables.save_1x_table(track, "unused.csv", preamble={"Note": "two\nlines"})),
        ("tracks", lambda: tables.match_speeds(3.0)),
        ("max_rpm", lambda: tables.slow_roll_vector(track, max_rpm="400")),
        ("out_dir", lambda: tables.example_tables(None)),
        ("amplitude_std_m", lambda: tables.polar_covariance(np.ones((2, 4)), 1e300, 0.0)),  # overflowed
        ("other", lambda: track.minus(np.ones(3))),
        ("speed_rpm", lambda: track.at_speeds(np.nan)),
        ("orders", lambda: signals.SyncTrack([3000.0], np.ones((1, 1, 4)), "1", [1], np.zeros((1, 4)), [0.0])),
        # kcm, phasecal, uncertainty, outputs
        ("fit", lambda: kcm.with_jackknife(None, 3.0, [0])),
        ("runs", lambda: rotorid.calibrate_phase(rotor, 3.0)),
        ("degree", lambda: rotorid.calibrate_phase(rotor, [], degree=np.nan)),
        ("runs", lambda: phasecal.PhaseCalibration(0.0, 0.0, 0.0, 0.0, 1.0, 3, False, "").apply([1.0])),
        ("level", lambda: uncertainty.t_quantile("0.95", 5)),
        ("dof", lambda: uncertainty.t_quantile(0.95, None)),
        ("cov", lambda: uncertainty.std_from_cov(np.eye(16))),
        ("k", lambda: uncertainty.report_vector(np.ones(2), np.ones((1, 2, 2, 2)))),
        ("path", lambda: outputs.ResultsFolder(None, patterns=["*.csv"])),
        ("patterns", lambda: outputs.ResultsFolder("unused", patterns=3)),
        # signals
        ("pulse_side", lambda: signals.state_levels(kp, pulse_side=["up"])),
        ("keyphasor times", lambda: signals.Keyphasor.from_times("x")),
        ("kp", lambda: signals.steady_segments(None)),
        ("return_cov", lambda: signals.slow_roll_vector(rec, return_cov=np.zeros(2))),
        ("points_per_rev", lambda: signals.revolution_signature(x, 1000.0, np.arange(0.0, 1.0, 0.1), 0.0, 0.5,
                                                                points_per_rev=np.nan)),
        ("t0_s", lambda: signals.runout_filter(x, 1000.0, np.arange(0.0, 1.0, 0.1), np.zeros((4, 16)), 0, 10,
                                               t0_s=np.nan)),  # was all NaN
        ("i0", lambda: signals.runout_filter(x, 1000.0, np.arange(0.0, 1.0, 0.1), np.zeros((4, 16)), np.nan, 10)),
        ("n", lambda: signals.force_window(10 ** 12, 0, 10)),  # was 8 TB
        ("forces", lambda: signals.frf_h1(3.0, 3.0, 1000.0)),
        ("polarity", lambda: signals.keyphasor_times(kp, 1000.0, polarity=["positive"])),
        ("source", lambda: signals.keyphasor_times(kp, 1000.0, source=np.zeros(2))),
        # the rest of the public surface (the second sweep of tests/test_fuzz.py)
        *_rest_of_the_surface_cases(rotor, rec),
    ]


def _rest_of_the_surface_cases(rotor, rec):
    from rotorid import config, demo, example, pipeline, plot, units
    from rotorid.recording import SegmentedRecording

    rpm = np.array([4000.0, 5000.0])
    runs = [rotorid.imbalance_response(RIG.rotor, RIG.bearings, RIG.imbalances[s], speed_rpm=rpm) for s in "AB"]
    arrays = {"x1": np.zeros((2, 8))}
    return [
        ("plane", lambda: rotorid.impact_vector(np.nan, "x")),  # was a NaN excitation vector
        ("plane", lambda: rotorid.impact_time_response(RIG.rotor, RIG.bearings, speed_rpm=1000.0,
                                                       force_N=np.ones(8), fs_hz=1e4, plane="x")),
        ("n_samples", lambda: rotorid.half_sine_pulse(100.0, 1e-3, 1e4, np.nan)),
        ("rotor", lambda: rotorid.probes_to_bearings(None, runs[0].q)),
        ("rotor", lambda: rotorid.bearings_to_probes(3.0, runs[0].q)),
        ("cond_max", lambda: rotorid.identify_synchronous(RIG.rotor, runs, cond_max=np.ones(2))),
        ("max_rel_std", lambda: rotorid.identify_synchronous(RIG.rotor, runs, max_rel_std=np.zeros(0))),
        ("units", lambda: Recording(1e3, {"x1": np.zeros(8)}, units=3.0)),
        ("source", lambda: Recording(1e3, {"x1": np.zeros(8)}, source=np.zeros(2))),
        ("start_s", lambda: rec.segment(np.nan, 0.01)),
        ("stop_s", lambda: rec.segment(0.0, "x")),
        ("blocks", lambda: SegmentedRecording(3.0)),
        ("meta", lambda: SegmentedRecording([rec], meta=np.zeros(2))),
        ("fs_hz", lambda: SegmentedRecording.from_arrays("x", arrays)),
        ("meta", lambda: SegmentedRecording.from_arrays(1e3, arrays, meta=3)),
        ("units", lambda: SegmentedRecording.from_arrays(1e3, arrays, units="mil")),
        ("quantity", lambda: units.factor("mil", np.ones(2))),
        ("value", lambda: units.to_si("x", "mil")),
        ("value", lambda: units.from_si(None, "mil")),
        ("response", lambda: plot.bode(3.0)),
        ("path", lambda: plot.bode(runs[0], path=3.0)),
        ("ident", lambda: plot.coefficients(None)),
        ("show_flagged", lambda: plot.coefficients(rotorid.identify_synchronous(RIG.rotor, runs),
                                                   show_flagged=np.ones(2))),
        ("modal_result", lambda: plot.campbell(None)),
        ("crit", lambda: plot.campbell(rotorid.modal_analysis(RIG.rotor, RIG.bearings, speed_rpm=[1000.0]), crit=3)),
        ("orders", lambda: pipeline.imbalance_chain(rotor, [rec], orders=b"x")),
        ("rec", lambda: pipeline.impact_segments(None)),
        ("record_s", lambda: pipeline.impact_segments(rec, record_s=np.nan)),
        ("revs_before", lambda: pipeline.impact_segments(rec, revs_before="x")),
        ("runout", lambda: pipeline.impact_segments(rec, runout=np.ones(2))),
        ("detect", lambda: pipeline.impact_segments(rec, detect=3)),
        ("detect", lambda: pipeline.impact_segments(rec, detect={"bogus": 1})),
        ("recordings[0]", lambda: pipeline.impact_chain(rotor, [1.0])),
        ("tests_meta", lambda: pipeline.impact_chain(rotor, [rec], tests_meta=3)),
        ("zero_pad_s", lambda: pipeline.impact_chain(rotor, [rec], zero_pad_s=1e12)),  # was a MemoryError
        ("path", lambda: pipeline.run_config(3.0, "imbalance")),
        ("kind", lambda: pipeline.run_config("unused.toml", np.zeros(2))),
        ("path", lambda: config.load_config(None)),
        ("check_files", lambda: config.load_config("unused.toml", check_files="no")),
        ("out", lambda: example.copy_example(None)),
        ("overwrite", lambda: example.copy_example("unused", overwrite=np.ones(2))),
        ("step_rpm", lambda: demo.synchronous("unused", step_rpm=0.001)),  # was 6e6 speeds, gigabytes
        ("step_rpm", lambda: demo.synchronous("unused", step_rpm=np.nan)),
        ("resolution", lambda: demo.synchronous("unused", resolution=3.0)),
        ("out", lambda: demo.impact(None)),
    ]


def test_every_refusal_found_by_the_sweep_names_its_argument(tmp_path, monkeypatch):
    import re

    monkeypatch.chdir(tmp_path)
    wrong = []
    for i, (arg, call) in enumerate(_bad_argument_cases()):
        try:
            call()
            wrong.append(f"case {i} ({arg}): no error")
        except RotoridError as exc:
            if not re.search(re.escape(arg), str(exc)):
                wrong.append(f"case {i} ({arg}): {exc}")
    assert not wrong, "\n".join(wrong)


def test_cli_demo_refuses_a_speed_step_of_millions_of_speeds_at_once(tmp_path, capsys):
    import time

    from rotorid import cli

    out = tmp_path / "demo"
    t = time.perf_counter()
    code = cli.main(["demo", "--out", str(out), "--step-rpm", "0.001"])  # was 1e7 speeds, gigabytes
    took = time.perf_counter() - t
    err = capsys.readouterr().err
    assert code == 1
    assert err.count("\n") == 1 and err.startswith("rotorid: error:") and "--step-rpm" in err, err
    assert "10000" in err  # the stated maximum number of speeds
    assert took < 10.0, f"took {took:.1f} s"
    assert not out.exists()  # refused before anything was written


def test_a_mark_angle_whole_turns_away_is_the_same_mark():
    # the lab simulator reduces the mark angle to one turn (a huge angle lost the events to rounding)
    rotor, brg, remnant = rotorid.rawsim.example_rig()
    kw = dict(speeds_rpm=[3000.0], added=None, remnant=remnant, dwell_s=0.1, fs_hz=2048.0, segmented=False)
    a = rotorid.rawsim.lab_imbalance_recording(rotor, brg, mark_angle_deg=23.0, **kw)
    for turns in (1, -3, 10 ** 6):
        b = rotorid.rawsim.lab_imbalance_recording(rotor, brg, mark_angle_deg=23.0 + 360.0 * turns, **kw)
        np.testing.assert_allclose(b.channels["kp"], a.channels["kp"], atol=1e-3)


def test_measured_data_plots_refuse_bad_input():
    import numpy as np

    import rotorid
    from rotorid import plot

    with pytest.raises(RotoridError, match="axis"):
        plot.polar(np.ones((5, 4), complex))
    with pytest.raises(RotoridError, match=r"\(n, 4\)"):
        plot.polar(np.ones((5, 3), complex), axis=np.arange(5.0))
    rig = rotorid.nsf_rig()
    t = rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=1000, freq_hz=np.arange(2, 50, 1.0), plane=0.0,
                           direction="x")
    with pytest.raises(RotoridError, match="coherence must be"):
        plot.frf(t, np.ones((3, 4)))
    with pytest.raises(RotoridError, match="coherence_min"):
        plot.frf(t, np.ones((t.freq_hz.size, 4)), coherence_min=-1)


@pytest.mark.parametrize("value,kw,ok", [
    (1.5, {}, True), (0.0, {}, True), (-0.0, {}, True), (-2.0, {}, True), (0.0, {"nonneg": True}, True),
    (0.0, {"positive": True}, False), (-0.0, {"positive": True}, False), (-1e-300, {"nonneg": True}, False),
    (float("nan"), {}, False), (float("inf"), {}, False), (-float("inf"), {"nonneg": True}, False),
    (np.float64(np.nan), {}, False), (True, {}, False), ("1", {}, False), (1 + 0j, {}, False)])
def test_scalar_check_fast_path_refuses_what_the_full_check_refuses(value, kw, ok):
    """``_validate.number`` returns plain finite floats at once; everything else goes through the
    full checks, which must still refuse NaN, infinities, signs and non-numbers."""
    from rotorid._validate import number

    if ok:
        assert number("x", value, **kw) == value
    else:
        with pytest.raises(RotoridError, match="x"):
            number("x", value, **kw)


@pytest.mark.parametrize("layout", ["C", "F", "strided", "complex64"])
@pytest.mark.parametrize("bad", [complex(np.nan, 0.0), complex(0.0, np.nan), complex(np.inf, 1.0),
                                 complex(1.0, -np.inf), None])
def test_complex_finiteness_check_finds_every_nan_and_inf(layout, bad):
    """``complex_array``'s finiteness check (one core pass over the float64 pairs of a C-contiguous
    complex128 array, NumPy otherwise) refuses NaN or inf in either part at any position, names the
    first, and accepts the largest finite values."""
    from rotorid._validate import complex_array

    rng = np.random.default_rng(3)
    a = rng.normal(size=(7, 6)) + 1j * rng.normal(size=(7, 6))
    big = np.finfo(np.complex64 if layout == "complex64" else float).max
    a[0, 0] = complex(big, -big)
    if bad is not None:
        a[5, 2] = bad  # (5, 1) of the strided view
    view = {"C": a, "F": np.asfortranarray(a), "strided": a[:, ::2],
            "complex64": a.astype(np.complex64)}[layout]
    if bad is None:
        np.testing.assert_array_equal(complex_array("q", view), view)
        return
    first = r"\(5, 1\)" if layout == "strided" else r"\(5, 2\)"
    with pytest.raises(RotoridError, match="q contains NaN or inf \\(first at index " + first):
        complex_array("q", view)


def test_core_plane_transform_refuses_bad_shapes():
    from rotorid import _core

    q = np.zeros((5, 4), complex)
    with pytest.raises(ValueError, match="t has shape"):
        _core.apply_planes(np.eye(3), q)
    with pytest.raises(ValueError, match=r"q has shape \[5, 3\]"):
        _core.apply_planes(np.eye(2), np.zeros((5, 3), complex))
    with pytest.raises(ValueError, match="C-contiguous"):
        _core.apply_planes(np.eye(2), np.zeros((5, 8), complex)[:, ::2])
    with pytest.raises(TypeError):
        _core.apply_planes(np.eye(2), np.zeros((5, 4)))  # real, not complex128


def test_review_findings_of_the_speed_round():
    """Inputs found by review of the 2026-11-26 speed changes: each gives a clear error or the
    right answer, never a raw exception or a core panic."""
    from rotorid import IdentifiabilityError, ImpactResponse, _core

    rig = rotorid.nsf_rig()
    rpm = np.linspace(2000, 5000, 6)
    # a probe run whose q was replaced by a list after construction: validated again, identified
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm, at="probes")
            for s in "ABC"]
    ref = rotorid.identify_synchronous(rig.rotor, runs)
    runs[0].q = runs[0].q.tolist()
    np.testing.assert_array_equal(rotorid.identify_synchronous(rig.rotor, runs).k, ref.k)
    # ... or cut short: the error names that run's shape
    runs[0].q = np.asarray(runs[0].q)[:4]
    with pytest.raises(RotoridError, match=r"q has shape \(4, 4\)"):
        rotorid.identify_synchronous(rig.rotor, runs)
    # an impact plane far beyond any rotor: an error or a result, not an OverflowError
    f = np.linspace(5, 100, 4)
    tests = [ImpactResponse(speed_rpm=1000, freq_hz=f, q=np.ones((4, 4)) * 1e-6, plane=z, direction="x")
             for z in (0.0, 1e160)]
    try:
        rotorid.identify_impact(rig.rotor, tests)
    except RotoridError:
        pass
    # one run without identical bearings: refused before the core, and by the core itself
    e = np.ones((1, 1, 4), complex)
    q = np.ones((1, 1, 6, 4), complex) * 1e-6
    for method in ("forces", "report"):
        with pytest.raises(IdentifiabilityError, match="at least two"):
            rotorid.identify_synchronous_batch(rig.rotor, rpm, q, e, method=method)
    w = rpm * np.pi / 30
    with pytest.raises(ValueError, match="runs"):
        _core.identify(rig.rotor.core_params(), w, w, q, e, None, method="report")
    # Fortran-ordered arrays are refused by the core (they would be read in memory order)
    qf = np.asfortranarray(np.ones((6, 4), complex))
    with pytest.raises(ValueError, match="C-contiguous"):
        _core.apply_planes(np.eye(2), qf)


def test_exported_datasets_own_their_data():
    """to_xarray copies: the dataset is writable even where the Identification holds read-only
    views (constant degrees of freedom, unknown standard errors)."""
    rig = rotorid.nsf_rig()
    rpm = np.linspace(2000, 5000, 4)
    for names in ("AB", "ABC"):
        runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm) for s in names]
        ident = rotorid.identify_synchronous(rig.rotor, runs)
        ds = ident.to_xarray()
        for var in ("dof", "K_std", "K", "cond"):
            ds[var].values[...] = 0.0
        assert np.all(ident.k != 0.0)


def test_shared_covariance_without_the_runs_own_is_refused():
    """A shared covariance is the common part of the runs' errors: given without each run's own
    covariance it used to be ignored in silence (the standard errors came from the residual, the
    same with or without it). Now it is refused, naming what is missing, in all three fits."""
    rig = rotorid.nsf_rig()
    rpm = np.linspace(3000.0, 6000.0, 5)
    shared = np.eye(8)[None].repeat(5, 0) * 1e-14
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm) for s in "ABC"]
    with pytest.raises(RotoridError, match="shared_cov is given but not every run carries its own"):
        rotorid.identify_synchronous(rig.rotor, runs, shared_cov=shared)
    # with every run's covariance it is used
    cov = np.eye(8)[None].repeat(5, 0) * 1e-14
    with_cov = [rotorid.SyncResponse(r.speed_rpm, r.q, r.imbalance, cov=cov) for r in runs]
    rotorid.identify_synchronous(rig.rotor, with_cov, shared_cov=shared)
    # only some runs with a covariance: refused as well
    some = with_cov[:2] + runs[2:]
    with pytest.warns(UserWarning, match="carry a measurement covariance"):
        with pytest.raises(RotoridError, match="shared_cov is given but not every run"):
            rotorid.identify_synchronous(rig.rotor, some, shared_cov=shared)
    ped = rotorid.example_pedestals()
    pruns = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm, pedestals=ped)
             for s in "AB"]
    shared16 = np.eye(16)[None].repeat(5, 0) * 1e-14
    with pytest.raises(RotoridError, match="shared_cov is given but not every run carries its own"):
        rotorid.identify_pedestals(rig.rotor, pruns, shared_cov=shared16)
    with pytest.raises(RotoridError, match="shared_cov is given but not every run carries its own"):
        rotorid.identify_synchronous(rig.rotor, pruns, shared_cov=shared16)
