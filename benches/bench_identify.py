"""Synchronous identification throughput: rotorid (Rust core) vs the best NumPy for the same work.

    python benches/bench_identify.py [--speeds 100000] [--runs 4] [--repeat 7] [--quick] [--threads 2]

Work: identify the 16 bearing coefficients at every speed from 4 imbalance runs (NSF rig).
Timed in the same process, best of ``repeat`` interleaved rounds of two back-to-back calls:
  rotorid._core.identify           the raw core call (k, c, cond, residual, amplitude; no standard errors)
  ... as the API calls it          a replay of exactly the core calls identify_synchronous makes
                                   (recorded once, same argument objects: standard errors for
                                   redundant runs, flags in the core), at the bearings and at the
                                   probe planes; API / core compares each public call with its own
  rotorid.identify_synchronous     the public API (checks, core call, uncertainty, flags), on the runs
                                   at the bearings and on the same runs at the probe planes
  NumPy (benches/baselines.py):    numpy_fast (the original all-at-once baseline) and the Gram-matrix
                                   formulation unblocked, cache-blocked on 1 thread and on --threads
                                   threads (block size tuned here); the fastest is "best NumPy".
  numpy-report                     eq. 8-18 literally (reference only, not with --quick).
Every NumPy variant's k and c are compared with the core's first (max relative difference).
Target: best NumPy / core >= 10x; public API throughput >= 90 % of the core's.
"""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from baselines import numpy_fast, numpy_ident, numpy_report  # noqa: E402
from common import (BLOCK_CANDIDATES, Blocks, best_of, best_of_each, check_api, nsf_runs,  # noqa: E402
                    numpy_variants, print_header, quick_args, quiet_blas, record_core_calls, rel_diff,
                    replay, report)

import rotorid  # noqa: E402
from rotorid import _core  # noqa: E402

RPM = np.pi / 30
TARGET = 10.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", type=int, default=None, help="default 100,000 (20,000 with --quick)")
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--repeat", type=int, default=None, help="default 7 (3 with --quick)")
    quick_args(ap)
    args = ap.parse_args()
    n = args.speeds or (20_000 if args.quick else 100_000)
    repeat = args.repeat or (3 if args.quick else 7)
    _blas = quiet_blas()  # noqa: F841  (kept alive for the whole run)
    print_header("synchronous identification", f"{n:,} speeds x {args.runs} imbalance runs (NSF rig), 16 "
                 "coefficients per speed", args.threads)

    names = "ABCDEFGH"[: args.runs]
    rig, rpm, runs = nsf_runs(n, names)
    rotor = rig.rotor
    om = rpm * RPM
    gain = om ** 2
    qs = np.ascontiguousarray(np.stack([r.q for r in runs]))       # (R, n, 4)
    e = np.stack([rig.imbalances[x].generalized(rotor) for x in names])
    p = rotor.core_params()
    q4 = qs[None]
    e3 = np.ascontiguousarray(e[None], dtype=complex)
    blocks = Blocks(args.threads)

    def core():
        return _core.identify(p, om, om, q4, e3, gain, with_std=False)

    def api():
        return rotorid.identify_synchronous(rotor, runs)

    # the same runs as labs record them, at the probe planes: the API moves them to the bearings
    runs_at_probes = [r.at_probes(rotor) for r in runs]

    def api_probes():
        return rotorid.identify_synchronous(rotor, runs_at_probes)

    variants, tuning = numpy_variants(
        blocks, "numpy Gram",
        lambda: numpy_ident(p, om, om, gain, qs, e),
        lambda b, t: numpy_ident(p, om, om, gain, qs, e, blocks, b, t),
        BLOCK_CANDIDATES, max(2, repeat // 2), args.threads)
    variants = {"numpy_fast (original), unblocked": lambda: numpy_fast(rotor, om, qs, e), **variants}

    # same answer first
    k_core, c_core = core()[:2]
    k_core, c_core = k_core[0], c_core[0]
    print("agreement with rotorid's core (max |difference| / max |value|):")
    ident = check_api("public API", api)
    if ident is not None:
        print(f"  {'public API':40s} k {rel_diff(ident.k, k_core):.1e}   c {rel_diff(ident.c, c_core):.1e}")
        ip = api_probes()
        print(f"  {'public API, runs at the probes':40s} k {rel_diff(ip.k, k_core):.1e}   c {rel_diff(ip.c, c_core):.1e}")
    for label, fn in variants.items():
        k, c = fn()
        print(f"  {label:40s} k {rel_diff(k, k_core):.1e}   c {rel_diff(c, c_core):.1e}")
    truth = rig.bearings.k
    print(f"accuracy (max |K - truth| / |Kxx| = 3e6 N/m): core {np.abs(k_core - truth).max() / 3e6:.1e}, "
          f"numpy Gram {np.abs(numpy_ident(p, om, om, gain, qs, e)[0] - truth).max() / 3e6:.1e}, "
          f"numpy_fast {np.abs(numpy_fast(rotor, om, qs, e)[0] - truth).max() / 3e6:.1e}")
    print(tuning)
    print()

    # the API's own core calls, replayed (recorded once each)
    api_fns = {}
    if ident is not None:
        api_fns = {"core_api": replay(record_core_calls(api)), "api": api,
                   "core_api_probes": replay(record_core_calls(api_probes)), "api_probes": api_probes}
    fns = {"core": core, **api_fns, **variants}
    t = best_of_each(fns, repeat)
    extra = []
    if not args.quick:
        extra.append(("numpy-report (16 unknowns, eq. 18; reference)",
                      best_of(lambda: numpy_report(rotor, om, qs, e), 1, warmup=0)))
    if "api_probes" in t:
        extra[:0] = [("rotorid._core.identify as the API calls it, runs at the probe planes", t["core_api_probes"]),
                     ("rotorid.identify_synchronous, runs at the probe planes (eq. 19 in the core)", t["api_probes"])]
    api_label = "rotorid._core.identify as the API calls it (replayed: standard errors, flags)"
    report(work=f"identify {n:,} speeds from {args.runs} runs", n=n, unit="speeds",
           core=("rotorid._core.identify (k, c, cond, residual, amplitude)", t["core"]),
           api=(("rotorid.identify_synchronous (public API)", t["api"], t["core_api"], api_label)
                if "api" in t else None),
           extra_rows=extra, numpy={k: t[k] for k in variants}, target_ratio=TARGET)
    if "api_probes" in t:
        pct = 100.0 * t["core_api_probes"] / t["api_probes"]
        print(f"public API throughput / core throughput, runs at the probe planes: {pct:5.1f} %   target >= 90 %: "
              f"{'met' if pct >= 90 else 'NOT met'}")
    blocks.close()


if __name__ == "__main__":
    main()
