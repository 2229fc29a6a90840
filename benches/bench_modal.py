"""Modal analysis throughput: eigenvalues and mode shapes at 10,000 running speeds.

    python benches/bench_modal.py [--speeds 10000] [--repeat 5] [--quick] [--threads 2]

Work: for each speed, the 8x8 state matrix of the NSF rig (constant bearings), its eigenvalues,
the (up to) 4 modes with Im(lambda) > 0 sorted by frequency and their displacement shapes scaled
to unit largest component. Timed in the same process, best of ``repeat`` interleaved rounds of
two back-to-back calls:
  rotorid._core.modal        the raw core call (bearing coefficients (n, 8) prepared; balancing,
                             Schur eigen-solver, two steps of inverse iteration per mode shape)
  rotorid.modal_analysis     the public API (checks, coefficients per speed, core call, result)
  NumPy (benches/baselines.py): state matrices and batched np.linalg.eig (LAPACK dgeev, balanced,
                             eigenvectors), selection and scaling vectorized; unblocked, blocked on
                             1 thread and on --threads threads. The fastest is "best NumPy".
The core runs on its rayon pool (all usable CPUs), so the target is per core: NumPy core-seconds /
rotorid core-seconds = (best NumPy / core) x NumPy threads / rotorid threads >= 3x, i.e.
ratio / rotorid threads when the single-thread NumPy variant wins.
"""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from baselines import numpy_modal  # noqa: E402
from common import (Blocks, best_of_each, check_api, numpy_variants, print_header, quick_args,  # noqa: E402
                    quiet_blas, rel_diff, report, rotorid_threads)

import rotorid  # noqa: E402
from rotorid import _core  # noqa: E402

TARGET_PER_CORE = 3.0
# eig dominates (LAPACK per 8x8 matrix); blocks only bound the (B, 8, 8) temporaries
MODAL_BLOCKS = (256, 1024, 4096)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", type=int, default=None, help="default 10,000 (2,000 with --quick)")
    ap.add_argument("--repeat", type=int, default=None, help="default 5 (3 with --quick)")
    quick_args(ap)
    args = ap.parse_args()
    n = args.speeds or (2_000 if args.quick else 10_000)
    repeat = args.repeat or (3 if args.quick else 5)
    _blas = quiet_blas()  # noqa: F841  (kept alive for the whole run)
    print_header("modal analysis", f"{n:,} speeds, 0-10,000 rpm (NSF rig): 8x8 state-matrix eigenvalues, "
                 "4 modes and shapes per speed", args.threads)

    rig = rotorid.nsf_rig()
    rotor, bearings = rig.rotor, rig.bearings
    rpm = np.linspace(0, 10000, n)
    spin = rpm * np.pi / 30
    p = rotor.core_params()
    kb = np.ascontiguousarray(bearings.k.reshape(8))
    cb = np.ascontiguousarray(bearings.c.reshape(8))
    kn = np.ascontiguousarray(np.broadcast_to(kb, (n, 8)))
    cn = np.ascontiguousarray(np.broadcast_to(cb, (n, 8)))
    blocks = Blocks(args.threads)

    def core():
        return _core.modal(p, kn, cn, spin)

    def api():
        return rotorid.modal_analysis(rotor, bearings, speed_rpm=rpm)

    variants, tuning = numpy_variants(
        blocks, "numpy eig",
        lambda: numpy_modal(p, kb, cb, spin),
        lambda b, t: numpy_modal(p, kb, cb, spin, blocks, b, t),
        MODAL_BLOCKS, 2, args.threads)

    lam_core, sh_core, nfail = core()
    print("agreement with rotorid's core (max |difference| / max |value|; eigenvalues, mode shapes):")
    res = check_api("public API", api)
    if res is not None:
        print(f"  {'public API':40s} {rel_diff(res.eigenvalues, lam_core):.1e}   {rel_diff(res.shapes, sh_core):.1e}")
    for label, fn in variants.items():
        lam, sh = fn()
        per = np.nanmax(np.abs(lam - lam_core) / np.abs(lam_core))
        print(f"  {label:40s} {rel_diff(lam, lam_core):.1e}   {rel_diff(sh, sh_core):.1e}   "
              f"(max per-mode relative eigenvalue difference {per:.1e})")
    print(f"failed points reported by the core: {nfail}")
    print(tuning)
    print()

    t = best_of_each({"core": core, **({"api": api} if res is not None else {}), **variants}, repeat)
    report(work=f"modal analysis at {n:,} speeds", n=n, unit="speeds",
           core=("rotorid._core.modal", t["core"]),
           api=("rotorid.modal_analysis (public API)", t["api"], None, None) if "api" in t else None,
           numpy={k: t[k] for k in variants}, target_ratio=TARGET_PER_CORE,
           per_core=rotorid_threads())
    blocks.close()


if __name__ == "__main__":
    main()
