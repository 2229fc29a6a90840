"""Synchronous identification throughput: rotorid (Rust core) vs NumPy doing the same work.

    python benches/bench_identify.py [--speeds 100000] [--runs 4]

Work: identify the 16 bearing coefficients at every speed from 4 imbalance runs (NSF rig).
Baselines, both vectorized over speeds, run in the same process:
  numpy-report : the report's formulation, eq. 8-12 and 16-18: real 8R x 16 matrix per speed,
                 P = (B^T B)^-1 B^T F via batched np.linalg.solve.
  numpy-fast   : the fastest NumPy we could write: bearing reaction forces from the rotor
                 equations, then per bearing the 2x2 complex normal equations solved in closed form.
"""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from baselines import numpy_fast, numpy_report  # noqa: E402
from common import best_of, blas_info, quiet_blas, nsf_runs  # noqa: E402

import rotorid  # noqa: E402
from rotorid import _core  # noqa: E402

RPM = np.pi / 30


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--speeds", type=int, default=100_000)
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    _blas = quiet_blas()  # noqa: F841  (kept alive for the whole run)
    names = "ABCD"[: args.runs]
    rig, rpm, runs = nsf_runs(args.speeds, names)
    rotor = rig.rotor
    om = rpm * RPM
    qs = np.ascontiguousarray(np.stack([r.q for r in runs]))
    e = np.stack([rig.imbalances[n].generalized(rotor) for n in names])
    p = rotor.core_params()
    n = args.speeds

    def core(with_std=False):
        return _core.identify(p, om, om, qs[None], e[None], om ** 2, with_std=with_std)

    # same answer first
    k_core = core()[0][0]
    k_np, c_np = numpy_fast(rotor, om, qs, e)
    P = numpy_report(rotor, om, qs, e)
    ref = rig.bearings.k
    print(f"speeds: {n}, runs: {args.runs}, threads: {os.cpu_count()} cores; BLAS: {blas_info()}")
    well = slice(None)
    print("max |K - truth| / |Kxx|:  core %.2e   numpy-fast %.2e   numpy-report %.2e" % (
        np.abs(k_core[well] - ref).max() / 3e6, np.abs(k_np[well] - ref).max() / 3e6,
        np.abs(P[:, :8] - rig.bearings.to_report_vector()[:8]).max() / 3e6))

    t_core = best_of(core, args.repeat)
    t_core_std = best_of(lambda: core(True), args.repeat)
    t_api = best_of(lambda: rotorid.identify_synchronous(rotor, runs), args.repeat)
    t_fast = best_of(lambda: numpy_fast(rotor, om, qs, e), args.repeat)
    t_rep = best_of(lambda: numpy_report(rotor, om, qs, e), max(1, args.repeat // 2))
    rows = [("rotorid core (k, c, cond, residual)", t_core), ("rotorid core + standard errors", t_core_std),
            ("rotorid.identify_synchronous (public API)", t_api), ("numpy-fast (bearing forces, 2x2 closed form)", t_fast),
            ("numpy-report (16 unknowns, eq. 18)", t_rep)]
    print(f"{'implementation':48s} {'time (ms)':>10s} {'speeds/s':>12s}")
    for name, t in rows:
        print(f"{name:48s} {1e3 * t:10.2f} {n / t:12.3e}")
    print(f"ratio numpy-fast / rotorid core:   {t_fast / t_core:7.1f}x")
    print(f"ratio numpy-report / rotorid core: {t_rep / t_core:7.1f}x")
    print(f"ratio numpy-fast / rotorid API:    {t_fast / t_api:7.1f}x")


if __name__ == "__main__":
    main()
