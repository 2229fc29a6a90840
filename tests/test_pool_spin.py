"""The core's helper threads keep spinning for ``ROTORID_SPIN_US`` after a parallel call (200 µs
by default, rust/core/src/par.rs), and a woken helper is kept off its caller's CPU unless
``ROTORID_STEER=0`` (rust/core/src/par/steer.rs): the values in use are reported, a misspelt one
is refused in one line, and the results are the same bits whatever they are (0 = helpers sleep at
once)."""

import os
import subprocess
import sys

import numpy as np
import pytest
import rotorid
from rotorid import _core

# an identification and a forward response large enough to run on the pool, both printed as bytes
_WORK = """
import sys, numpy as np, rotorid
from rotorid import _core
rig = rotorid.nsf_rig()
f = np.linspace(2, 300, 9000)
tests = [rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=1000.0, freq_hz=f, plane=0.0, direction=d) for d in "xy"]
out = []
for _ in range(3):  # back to back: helpers still spinning from the call before
    ident = rotorid.identify_impact(rig.rotor, tests)
    out.append(ident.k.tobytes() + ident.c.tobytes() + ident.flag_code.tobytes())
assert out[0] == out[1] == out[2]
resp = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["A"], speed_rpm=np.linspace(500, 9000, 20000))
sys.stdout.write(repr(_core.SPIN_US) + "\\n" + (out[0] + resp.q.tobytes()).hex())
"""


def _run(code, spin, timeout=120, steer=None):
    env = {**os.environ}
    env.pop("ROTORID_SPIN_US", None)
    env.pop("ROTORID_STEER", None)
    if spin is not None:
        env["ROTORID_SPIN_US"] = spin
    if steer is not None:
        env["ROTORID_STEER"] = steer
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=timeout,
                          check=False)


def test_the_spin_time_in_use_is_reported():
    want = float(os.environ.get("ROTORID_SPIN_US") or 200.0)
    assert _core.SPIN_US == want


def test_the_steering_in_use_is_reported():
    assert _core.STEER is (sys.platform.startswith("linux") and os.environ.get("ROTORID_STEER", "").strip() != "0")


@pytest.mark.parametrize(("spin", "steer"), [(None, None), ("0", None), ("1000", None), ("0", "0"), (None, "0")])
def test_results_are_the_same_bits_whatever_the_spin_time_and_steering(spin, steer):
    got = _run(_WORK.replace("repr(_core.SPIN_US)", "repr(_core.SPIN_US) + ' ' + repr(_core.STEER)"), spin,
               steer=steer)
    assert got.returncode == 0, got.stderr
    reported, data = got.stdout.split("\n")
    spin_us, steering = reported.split()
    assert float(spin_us) == (200.0 if spin is None else float(spin))
    assert steering == repr(steer != "0" and sys.platform.startswith("linux"))
    rig = rotorid.nsf_rig()
    f = np.linspace(2, 300, 9000)
    tests = [rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=1000.0, freq_hz=f, plane=0.0, direction=d)
             for d in "xy"]
    ident = rotorid.identify_impact(rig.rotor, tests)
    resp = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["A"],
                                      speed_rpm=np.linspace(500, 9000, 20000))
    assert bytes.fromhex(data) == ident.k.tobytes() + ident.c.tobytes() + ident.flag_code.tobytes() + resp.q.tobytes()


@pytest.mark.parametrize("value", ["fast", "-5", "50001", "nan", "200us"])
def test_a_bad_spin_time_is_refused_in_one_line(value, tmp_path):
    got = _run("import rotorid; rotorid.nsf_rig()", value)
    assert got.returncode != 0
    assert "RotoridError" in got.stderr
    assert (f"ROTORID_SPIN_US must be a number of microseconds within 0 and 50000 (or unset), got \"{value}\""
            in got.stderr)
    env = {**os.environ, "ROTORID_SPIN_US": value}
    cli = subprocess.run([sys.executable, "-m", "rotorid.cli", "demo", "--out", str(tmp_path / "d")],
                         capture_output=True, text=True, env=env, timeout=120, check=False)
    assert cli.returncode == 1
    assert cli.stderr.strip().splitlines() == [
        ("rotorid: error: cannot load rotorid's compiled core: ROTORID_SPIN_US must be a number of microseconds "
         f"within 0 and 50000 (or unset), got \"{value}\"")]
    assert not (tmp_path / "d").exists()


@pytest.mark.parametrize("value", ["yes", "2", "-1", "off"])
def test_a_bad_steering_value_is_refused_in_one_line(value, tmp_path):
    got = _run("import rotorid; rotorid.nsf_rig()", None, steer=value)
    assert got.returncode != 0
    assert "RotoridError" in got.stderr
    assert f"ROTORID_STEER must be 0 or 1 (or unset), got \"{value}\"" in got.stderr
    env = {**os.environ, "ROTORID_STEER": value}
    cli = subprocess.run([sys.executable, "-m", "rotorid.cli", "demo", "--out", str(tmp_path / "d")],
                         capture_output=True, text=True, env=env, timeout=120, check=False)
    assert cli.returncode == 1
    assert cli.stderr.strip().splitlines() == [
        f"rotorid: error: cannot load rotorid's compiled core: ROTORID_STEER must be 0 or 1 (or unset), got \"{value}\""]
    assert not (tmp_path / "d").exists()


@pytest.mark.parametrize("spin", ["50000", "0"])
def test_helpers_spinning_at_a_fork_leave_the_child_working(spin):
    # the parent's helpers are spinning when it forks (a call just ended), or asleep with their
    # CPU masks recorded and steered by every call (spin 0); the child, which has none of the
    # parent's threads, runs its calls on a pool of its own and steers none of the parent's
    code = """
import os, numpy as np, rotorid
rig = rotorid.nsf_rig()
f = np.linspace(2, 300, 9000)
tests = [rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=1000.0, freq_hz=f, plane=0.0, direction=d) for d in "xy"]
ref = rotorid.identify_impact(rig.rotor, tests)
pid = os.fork()
if pid == 0:
    ok = all(np.array_equal(rotorid.identify_impact(rig.rotor, tests).k, ref.k) for _ in range(3))
    os._exit(0 if ok else 3)
_, status = os.waitpid(pid, 0)
raise SystemExit(os.waitstatus_to_exitcode(status))
"""
    got = _run(code, spin, timeout=60)
    assert got.returncode == 0, got.stderr
