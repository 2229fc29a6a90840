"""Core calls after the caller has done something else: back to back, after Python work, after a sleep.

    python benches/bench_cold_calls.py [--freqs 10000] [--calls 300] [--quick]

Work: the core call of identify_impact on 10,000 frequencies from 2 impacts (about 0.3-0.7 ms),
timed alone ``calls`` times after each of: nothing (back to back), 100 µs of Python, 100 µs of
NumPy reading 3 MB, a 100 µs sleep, a 1 ms sleep, a 30 ms sleep; and the public
``identify_impact`` after a 30 ms sleep (at most 100 calls each). A public API call always comes after some
Python, and a script's calls come after whatever the script does; a pool thread that has gone
to sleep in between has to be woken. The kernels share their tasks with the calling thread
(rust/core/src/par.rs), so a late pool thread costs at most the second thread's share, not a
wake-up round trip, and a woken thread is kept off the caller's CPU (rust/core/src/par/steer.rs;
``ROTORID_STEER=0`` to compare). Prints min and median per case; run with RAYON_NUM_THREADS=1 for
one thread.
No NumPy comparison: this bench measures latency, not throughput.
"""

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from common import print_header  # noqa: E402

import rotorid  # noqa: E402
from rotorid import _core  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--freqs", type=int, default=10_000)
    ap.add_argument("--calls", type=int, default=None, help="calls per case (default 300, 40 with --quick)")
    ap.add_argument("--quick", action="store_true", help="few calls (a second)")
    args = ap.parse_args()
    calls = args.calls or (40 if args.quick else 300)
    print_header("core calls after other work", f"identify_impact's core call, {args.freqs:,} frequencies x 2 "
                 f"impacts, {calls} calls per case", 1)

    rig = rotorid.nsf_rig()
    f = np.linspace(2, 300, args.freqs)
    speed = 1000.0
    tests = [rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=speed, freq_hz=f, direction=d) for d in "xy"]
    q4 = np.ascontiguousarray(np.stack([t.q for t in tests]))[None]
    e3 = np.ascontiguousarray(np.stack([t.excitation() for t in tests]).astype(complex)[None])
    w = 2 * np.pi * f
    spin = np.full_like(w, speed * np.pi / 30)
    gain = np.ones_like(w)
    p = rig.rotor.core_params()
    big = np.ones(400_000)

    def core():
        return _core.identify(p, w, spin, q4, e3, gain, with_std=False)

    def python_for(us):
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < us * 1e-6:
            pass

    def numpy_for(us):
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < us * 1e-6:
            big.sum()

    def api():
        return rotorid.identify_impact(rig.rotor, tests)

    cases = [("back to back", None, core), ("after 100 µs of Python", lambda: python_for(100), core),
             ("after 100 µs of NumPy (3 MB)", lambda: numpy_for(100), core),
             ("after a 100 µs sleep", lambda: time.sleep(1e-4), core), ("after a 1 ms sleep", lambda: time.sleep(1e-3), core),
             ("after a 30 ms sleep", lambda: time.sleep(0.03), core),
             ("public API after a 30 ms sleep", lambda: time.sleep(0.03), api)]
    core()
    api()
    print(f"pool helpers spin {_core.SPIN_US:g} µs after a call; woken helpers kept off the caller's CPU: "
          f"{'yes' if _core.STEER else 'no (ROTORID_STEER=0)'}")
    print(f"{'case':32s} {'min µs':>8s} {'median µs':>10s}")
    for label, before, fn in cases:
        times = []
        for _ in range(calls if before is None or "30 ms" not in label else min(calls, 100)):
            if before is not None:
                before()
            t = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t)
        print(f"{label:32s} {min(times) * 1e6:8.0f} {np.median(times) * 1e6:10.0f}")


if __name__ == "__main__":
    main()
