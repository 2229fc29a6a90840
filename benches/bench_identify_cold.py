"""Synchronous identification's core call with its data out of the caches.

    python benches/bench_identify_cold.py [--speeds 100000] [--calls 30] [--evict-mb 320]

Work: the core call of identify_synchronous (no standard errors) on ``--speeds`` speeds from 4
imbalance runs (41.6 MB of responses and outputs at 100,000 speeds), timed ``calls`` times, each
right after an array of ``--evict-mb`` MB has been updated in place, so the responses come from
memory rather than from a cache (this machine's L3 may hold them otherwise: see the header).
This is how the kernel's prefetching (rust/core/src/identify/registers.rs, PREFETCH) was
measured; ``ROTORID_SIMD=avx2`` gives the AVX2 instance. Prints best and median. No NumPy
comparison: bench_identify.py compares throughput with the best NumPy.
"""

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from common import nsf_runs, print_header  # noqa: E402

from rotorid import _core  # noqa: E402

RPM = np.pi / 30


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", type=int, default=100_000)
    ap.add_argument("--calls", type=int, default=30)
    ap.add_argument("--evict-mb", type=int, default=320)
    args = ap.parse_args()
    print_header("identification with its data out of the caches",
                 f"{args.speeds:,} speeds x 4 imbalance runs, {args.calls} calls after {args.evict_mb} MB of "
                 "other memory", 2)
    names = "ABCD"
    rig, rpm, runs = nsf_runs(args.speeds, names)
    rotor = rig.rotor
    om = rpm * RPM
    qs = np.ascontiguousarray(np.stack([r.q for r in runs]))[None]
    e = np.ascontiguousarray(np.stack([rig.imbalances[x].generalized(rotor) for x in names])[None], dtype=complex)
    p = rotor.core_params()
    gain = om ** 2
    junk = np.ones(args.evict_mb * 131_072)
    _core.identify(p, om, om, qs, e, gain, with_std=False)
    times = []
    for _ in range(args.calls):
        junk += 1.0
        t0 = time.perf_counter()
        _core.identify(p, om, om, qs, e, gain, with_std=False)
        times.append(time.perf_counter() - t0)
    print(f"core call after {args.evict_mb} MB: best {1e3 * min(times):.2f} ms, median {1e3 * np.median(times):.2f} ms "
          f"({1e9 * min(times) / args.speeds:.1f} ns of wall time per speed)")


if __name__ == "__main__":
    main()
