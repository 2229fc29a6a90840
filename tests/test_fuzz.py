"""Short fuzz runs kept in CI: the file readers, the public API and the CLI answer bad input with a
RotoridError (CLI: one line, exit 2), never another exception, a crash or a hang."""

import os
import tempfile

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import rotorid
from rotorid import RotoridError, cli
from rotorid.io import load_recording, save_csv, save_recording

FUZZ = settings(max_examples=120, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow,
                                                                        HealthCheck.function_scoped_fixture])


def _valid_files(d):
    rec = rotorid.Recording(1000.0, {"x1": np.sin(np.arange(200) / 5.0) * 1e-5, "kp": (np.arange(200) % 20 < 2) * 5.0})
    save_recording(rec, os.path.join(d, "a.npz"))
    save_csv(rec, os.path.join(d, "a.csv"))
    return {ext: open(os.path.join(d, f"a.{ext}"), "rb").read() for ext in ("npz", "csv")}


_VALID = _valid_files(tempfile.mkdtemp())


@FUZZ
@given(ext=st.sampled_from(["npz", "csv", "txt", "tdms", "uff"]), data=st.binary(max_size=600),
       cut=st.integers(0, 4000), flip=st.integers(0, 4000))
def test_readers_fail_only_with_rotorid_errors(tmp_path, ext, data, cut, flip):
    base = _VALID.get(ext, b"")
    if base and len(data) % 2:  # mutate a valid file: truncate and flip a byte
        b = bytearray(base[: max(cut, 1)])
        if b:
            b[flip % len(b)] ^= 0xFF
        data = bytes(b)
    p = tmp_path / f"f.{ext}"
    p.write_bytes(data)
    try:
        load_recording(p, fs_hz=1000.0 if ext in ("csv", "txt") else None)
    except RotoridError:
        pass


@FUZZ
@given(argv=st.lists(st.sampled_from(["demo", "identify", "imbalance", "impact", "example", "check", "--out",
                                      "--overwrite", "--step-rpm", "-1", "0", "nan", "x.toml", "/proc/x",
                                      "--noise-um", "1e309", ""]), max_size=5))
def test_cli_never_tracebacks(tmp_path, capsys, monkeypatch, argv):
    monkeypatch.chdir(tmp_path)
    argv = [a for a in argv if a != "demo"]  # the demo itself is slow; its bad options are tested elsewhere
    try:
        code = cli.main(argv)
    except SystemExit as exc:  # argparse usage errors
        code = exc.code
    assert code in (0, 1, 2)
    err = capsys.readouterr().err
    assert "Traceback" not in err


numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-5, 10 ** 6), st.just("x"),
                    st.just(None), st.just(True), st.complex_numbers(max_magnitude=10.0))


@FUZZ
@given(m=numbers, l1=numbers, d=st.lists(numbers, max_size=3), rpm=st.lists(numbers, max_size=3), plane=numbers)
def test_model_and_simulation_fail_only_with_rotorid_errors(m, l1, d, rpm, plane):
    rig = rotorid.nsf_rig()
    for call in (lambda: rotorid.RigidRotor(mass_kg=m, it_kgm2=0.7, ip_kgm2=0.3, l1=l1, l2=0.2, d=d),
                 lambda: rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["A"], speed_rpm=rpm),
                 lambda: rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=1000, freq_hz=rpm, plane=plane),
                 lambda: rotorid.Imbalance(mass_kg=d, angle_deg=(0.0, plane))):
        try:
            call()
        except RotoridError:
            pass


@FUZZ
@given(rpm=st.lists(numbers, max_size=3), grid=numbers, max_rpm=numbers, level=numbers, method=st.sampled_from(
    ["forces", "report", "x", None]), identical=st.sampled_from([True, False, "yes", None, 1]))
def test_identification_and_modal_fail_only_with_rotorid_errors(rpm, grid, max_rpm, level, method, identical):
    rig = rotorid.nsf_rig()
    ok_rpm = np.array([4000.0, 5000.0])
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=ok_rpm) for s in "AB"]
    tests = [rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=1000, freq_hz=[20.0, 40.0], direction=d) for d in "xy"]
    calls = (lambda: rotorid.modal_analysis(rig.rotor, rig.bearings, speed_rpm=rpm),
             lambda: rotorid.critical_speeds(rig.rotor, rig.bearings, max_rpm=max_rpm, n_grid=grid),
             lambda: rotorid.identify_synchronous(rig.rotor, runs, method=method, identical=identical,
                                                  cond_max=max_rpm, min_rel_amplitude=level),
             lambda: rotorid.identify_impact(rig.rotor, tests, method=method, identical=identical, max_rel_std=level),
             lambda: rotorid.identify_synchronous(rig.rotor, runs).interval(level))
    for call in calls:
        try:
            call()
        except RotoridError:
            pass


_REC = None


def _rec():
    global _REC
    if _REC is None:
        rotor, brg, remnant = rotorid.rawsim.example_rig()
        _REC = rotorid.rawsim.imbalance_recording(rotor, brg, speeds_rpm=[3000.0], added=rotorid.Imbalance(
            (5e-3, 5e-3), (0.0, 0.0)), remnant=remnant, dwell_s=0.3)
    return _REC


@FUZZ
@given(a=numbers, b=numbers, orders=st.one_of(st.lists(numbers, max_size=3), numbers),
       steady=st.sampled_from([True, False, "no", None, 1]), kp=st.one_of(st.just(None), st.dictionaries(
           st.sampled_from(["level", "edge", "tolerance", "mark_angle_deg", "refine", "bogus"]), numbers, max_size=2)))
def test_tracking_and_chains_fail_only_with_rotorid_errors(a, b, orders, steady, kp):
    from rotorid import pipeline, signals

    rec = _rec()
    rotor = rotorid.rawsim.example_rig()[0]
    calls = (lambda: signals.track(rec, orders=orders, steady=steady, min_revs=a, speed_tolerance=b, keyphasor=kp),
             lambda: signals.track(rec, points_per_rev=a, revs_per_block=b, steady=False),
             lambda: signals.revolution_signature(np.zeros((4, 1000)), 1000.0, np.arange(0.0, 1.0, 0.1), a, b,
                                                  points_per_rev=64),
             lambda: pipeline.imbalance_chain(rotor, [rec, rec], speeds_rpm=orders, speed_match_rpm=a,
                                              steady=steady, keyphasor=kp),
             lambda: rotorid.rawsim.imbalance_recording(rotor, rotorid.rawsim.example_rig()[1], speeds_rpm=orders,
                                                        added=None, dwell_s=0.05, fs_hz=a if a else 1000.0))
    for call in calls:
        try:
            call()
        except RotoridError:
            pass
