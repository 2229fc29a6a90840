"""The core works in child processes, whatever multiprocessing's start method, also after the
parent used its thread pool (a forked child inherits no pool threads)."""

import multiprocessing as mp

import numpy as np
import pytest

import rotorid
from rotorid import rawsim, signals


def _work(_):
    rig = rotorid.nsf_rig()
    modal = rotorid.modal_analysis(rig.rotor, rig.bearings, speed_rpm=[1000.0, 2000.0, 3000.0])
    rotor, brg, remnant = rawsim.example_rig()
    rec = rawsim.imbalance_recording(rotor, brg, speeds_rpm=[3000.0], added=None, remnant=remnant, dwell_s=0.5)
    tr = signals.track(rec)
    # large enough for the API to wake the core's threads before its checks (WAKE_FROM)
    f = np.linspace(2.0, 300.0, 6000)
    tests = [rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=1000.0, freq_hz=f, direction=d) for d in "xy"]
    k = rotorid.identify_impact(rig.rotor, tests).k
    return float(modal.freq_hz.max()), complex(tr.order(1)[0, 0]), float(k[100, 0, 0, 0])


@pytest.mark.parametrize("method", ["fork", "forkserver", "spawn"])
def test_core_calls_in_child_processes_do_not_hang(method):
    expected = _work(0)  # the parent uses the core (and its thread pool) first
    ctx = mp.get_context(method)
    with ctx.Pool(2) as pool:
        got = pool.map_async(_work, range(3)).get(timeout=120)
    for g in got:
        assert g[0] == pytest.approx(expected[0], rel=1e-12)
        assert abs(g[1] - expected[1]) < 1e-12 * abs(expected[1])
        assert g[2] == expected[2]
