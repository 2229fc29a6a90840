"""Impact identification throughput: 10,000 frequencies from 2 tests at one running speed.

    python benches/bench_impact.py [--freqs 10000]

rotorid (Rust core; and the public identify_impact) against the same two NumPy baselines as the
synchronous bench (benches/baselines.py), with w = 2 pi f, spin = running speed, unit excitation.
"""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from baselines import numpy_fast, numpy_report  # noqa: E402
from common import best_of, blas_info, quiet_blas  # noqa: E402

import rotorid  # noqa: E402
from rotorid import _core  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--freqs", type=int, default=10_000)
    ap.add_argument("--repeat", type=int, default=20)
    args = ap.parse_args()
    _blas = quiet_blas()  # noqa: F841  (kept alive for the whole run)
    rig = rotorid.nsf_rig()
    f = np.linspace(2, 300, args.freqs)
    speed = 1000.0
    tests = [rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=speed, freq_hz=f, plane=0.0, direction=d)
             for d in "xy"]
    qs = np.ascontiguousarray(np.stack([t.q for t in tests]))
    e = np.stack([t.excitation() for t in tests]).astype(complex)
    w = 2 * np.pi * f
    spin = np.full_like(w, speed * np.pi / 30)
    gain = np.ones_like(w)
    p = rig.rotor.core_params()

    def core():
        return _core.identify(p, w, spin, qs[None], e[None], gain, with_std=False)

    k = core()[0][0]
    kf, _ = numpy_fast(rig.rotor, w, qs, e, spin=spin, gain=gain)
    P = numpy_report(rig.rotor, w, qs, e, spin=spin, gain=gain)
    print(f"frequencies: {args.freqs}, tests: 2; BLAS: {blas_info()}")
    print("max |K - truth| / |Kxx|:  core %.2e   numpy-fast %.2e   numpy-report %.2e" % (
        np.abs(k - rig.bearings.k).max() / 3e6, np.abs(kf - rig.bearings.k).max() / 3e6,
        np.abs(P[:, :8] - rig.bearings.to_report_vector()[:8]).max() / 3e6))
    t_core = best_of(core, args.repeat)
    t_api = best_of(lambda: rotorid.identify_impact(rig.rotor, tests), args.repeat)
    t_fast = best_of(lambda: numpy_fast(rig.rotor, w, qs, e, spin=spin, gain=gain), args.repeat)
    t_rep = best_of(lambda: numpy_report(rig.rotor, w, qs, e, spin=spin, gain=gain), max(1, args.repeat // 4))
    for name, t in [("rotorid core", t_core), ("rotorid.identify_impact (public API)", t_api),
                    ("numpy-fast", t_fast), ("numpy-report", t_rep)]:
        print(f"{name:40s} {1e3 * t:9.3f} ms  {args.freqs / t:.3e} freqs/s")
    print(f"ratio numpy-fast / rotorid core:   {t_fast / t_core:7.1f}x")
    print(f"ratio numpy-report / rotorid core: {t_rep / t_core:7.1f}x")
    print(f"ratio numpy-fast / rotorid API:    {t_fast / t_api:7.1f}x")


if __name__ == "__main__":
    main()
