"""Impact identification throughput: 10,000 frequencies from 2 tests at one running speed.

    python benches/bench_impact.py [--freqs 10000] [--repeat 20] [--quick] [--threads 2]

Work: the 16 coefficients at every frequency from two impact FRFs (x and y at the CG plane), with
w = 2 pi f, spin = running speed and unit excitation (the core call identify_impact makes).
Timed in the same process, best of ``repeat`` interleaved rounds of two back-to-back calls:
  rotorid._core.identify      the raw core call (with_std=False: two tests are not redundant, so the
                              public API asks for no standard errors either); also a replay of exactly
                              the core calls identify_impact makes (recorded once, same arguments)
  rotorid.identify_impact     the public API
  NumPy (benches/baselines.py): numpy_fast (the original all-at-once baseline) and the Gram-matrix
                              formulation unblocked, cache-blocked on 1 thread and on --threads
                              threads (block size tuned here); the fastest is "best NumPy".
  numpy-report                eq. 8-18 literally (reference only, not with --quick).
Target: best NumPy / core >= 10x; public API throughput >= 90 % of the core's.
"""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from baselines import numpy_fast, numpy_ident, numpy_report  # noqa: E402
from common import (BLOCK_CANDIDATES, Blocks, best_of, best_of_each, check_api, numpy_variants,  # noqa: E402
                    print_header, quick_args, quiet_blas, record_core_calls, rel_diff, replay, report)

import rotorid  # noqa: E402
from rotorid import _core  # noqa: E402

TARGET = 10.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--freqs", type=int, default=10_000)
    ap.add_argument("--repeat", type=int, default=None, help="default 20 (5 with --quick)")
    quick_args(ap)
    args = ap.parse_args()
    n = args.freqs
    repeat = args.repeat or (5 if args.quick else 20)
    _blas = quiet_blas()  # noqa: F841  (kept alive for the whole run)
    print_header("impact identification", f"{n:,} frequencies x 2 impact tests at 1000 rpm (NSF rig), 16 "
                 "coefficients per frequency", args.threads)

    rig = rotorid.nsf_rig()
    f = np.linspace(2, 300, n)
    speed = 1000.0
    tests = [rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=speed, freq_hz=f, plane=0.0, direction=d)
             for d in "xy"]
    qs = np.ascontiguousarray(np.stack([t.q for t in tests]))
    e = np.stack([t.excitation() for t in tests]).astype(complex)
    w = 2 * np.pi * f
    spin = np.full_like(w, speed * np.pi / 30)
    gain = np.ones_like(w)
    p = rig.rotor.core_params()
    q4 = qs[None]
    e3 = np.ascontiguousarray(e[None])
    blocks = Blocks(args.threads)

    def core():
        return _core.identify(p, w, spin, q4, e3, gain, with_std=False)

    def api():
        return rotorid.identify_impact(rig.rotor, tests)

    variants, tuning = numpy_variants(
        blocks, "numpy Gram",
        lambda: numpy_ident(p, w, spin, gain, qs, e),
        lambda b, t: numpy_ident(p, w, spin, gain, qs, e, blocks, b, t),
        BLOCK_CANDIDATES, max(3, repeat // 4), args.threads)
    variants = {"numpy_fast (original), unblocked": lambda: numpy_fast(rig.rotor, w, qs, e, spin=spin, gain=gain),
                **variants}

    k_core, c_core = (a[0] for a in core()[:2])
    print("agreement with rotorid's core (max |difference| / max |value|):")
    ident = check_api("public API", api)
    if ident is not None:
        print(f"  {'public API':40s} k {rel_diff(ident.k, k_core):.1e}   c {rel_diff(ident.c, c_core):.1e}")
    for label, fn in variants.items():
        k, c = fn()
        print(f"  {label:40s} k {rel_diff(k, k_core):.1e}   c {rel_diff(c, c_core):.1e}")
    truth = rig.bearings.k
    print(f"accuracy (max |K - truth| / |Kxx| = 3e6 N/m): core {np.abs(k_core - truth).max() / 3e6:.1e}, "
          f"numpy Gram {np.abs(numpy_ident(p, w, spin, gain, qs, e)[0] - truth).max() / 3e6:.1e}")
    print(tuning)
    print()

    # the API's own core calls, replayed (recorded once)
    api_fns = {"core_api": replay(record_core_calls(api)), "api": api} if ident is not None else {}
    fns = {"core": core, **api_fns, **variants}
    t = best_of_each(fns, repeat)
    extra = []
    if not args.quick:
        extra.append(("numpy-report (16 unknowns, eq. 18; reference)",
                      best_of(lambda: numpy_report(rig.rotor, w, qs, e, spin=spin, gain=gain), 2, warmup=0)))
    report(work=f"identify {n:,} frequencies from 2 impacts", n=n, unit="freqs",
           core=("rotorid._core.identify (k, c, cond, residual, amplitude)", t["core"]),
           api=(("rotorid.identify_impact (public API)", t["api"], t.get("core_api"),
                 "rotorid._core.identify as the API calls it (replayed)") if "api" in t else None),
           numpy={k: t[k] for k in variants}, target_ratio=TARGET, extra_rows=extra)
    blocks.close()


if __name__ == "__main__":
    main()
