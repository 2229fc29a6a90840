"""Forward imbalance-response throughput: rotorid core (batched assembly + 4x4 complex solves) vs
the best NumPy for the same work.

    python benches/bench_forward.py [--speeds 100000] [--repeat 7] [--quick] [--threads 2]

Work: the synchronous response of the NSF rig to imbalance set B at every speed: assemble
H = K - w^2 M + j w (C + spin G) and solve H q = F (4x4 complex) per speed, constant bearings.
Timed in the same process, best of ``repeat`` interleaved rounds of two back-to-back calls:
  rotorid._core.forced_response   the raw core call (coefficients (1, 8), forces (n, 1, 4) prepared)
  rotorid._core.imbalance_response the core call the API makes (e Omega^2 formed in the core: no
                                  (n, 4) force array read; shown, not ranked)
  rotorid.imbalance_response      the public API (checks, forces from the imbalance, core call)
  NumPy (benches/baselines.py), from the same inputs as the core call:
    numpy solve:    H (n, 4, 4) and batched np.linalg.solve, unblocked / blocked / threaded;
    numpy explicit: the entries of H from one real matmul, Gaussian elimination unrolled over the
                    points (static pivoting on the direct terms), unblocked / blocked / threaded.
  The fastest is "best NumPy". Every variant's q is compared with the core's first.
Target: best NumPy / core >= 8x; public API throughput >= 90 % of the core's.
"""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from baselines import numpy_forward  # noqa: E402
from common import (BLOCK_CANDIDATES, Blocks, best_of_each, check_api, numpy_variants,  # noqa: E402
                    print_header, quick_args, quiet_blas, rel_diff, report)

import rotorid  # noqa: E402
from rotorid import _core  # noqa: E402

TARGET = 8.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", type=int, default=None, help="default 100,000 (20,000 with --quick)")
    ap.add_argument("--repeat", type=int, default=None, help="default 7 (3 with --quick)")
    quick_args(ap)
    args = ap.parse_args()
    n = args.speeds or (20_000 if args.quick else 100_000)
    repeat = args.repeat or (3 if args.quick else 7)
    _blas = quiet_blas()  # noqa: F841  (kept alive for the whole run)
    print_header("forward imbalance response", f"{n:,} speeds, 100-10,000 rpm (NSF rig, imbalance B): "
                 "assemble and solve a 4x4 complex system per speed", args.threads)

    rig = rotorid.nsf_rig()
    rotor, bearings = rig.rotor, rig.bearings
    rpm = np.linspace(100, 10000, n)
    om = rpm * np.pi / 30
    imb = rig.imbalances["B"]
    p = rotor.core_params()
    kb = np.ascontiguousarray(bearings.k.reshape(8))
    cb = np.ascontiguousarray(bearings.c.reshape(8))
    k1, c1 = kb.reshape(1, 8), cb.reshape(1, 8)
    F = np.ascontiguousarray(imb.generalized(rotor)[None, :] * (om ** 2)[:, None])   # (n, 4)
    F3 = F[:, None, :]
    blocks = Blocks(args.threads)

    def core():
        return _core.forced_response(p, k1, c1, om, om, F3)

    def api():
        return rotorid.imbalance_response(rotor, bearings, imb, speed_rpm=rpm)

    e3 = np.ascontiguousarray(imb.generalized(rotor), dtype=complex).reshape(1, 1, 4)

    def core_imbalance():
        return _core.imbalance_response(p, k1, c1, om, e3)

    variants, notes = {}, []
    for method in ("solve", "explicit"):
        v, note = numpy_variants(
            blocks, f"numpy {method}",
            lambda m=method: numpy_forward(p, kb, cb, om, om, F, m),
            lambda b, t, m=method: numpy_forward(p, kb, cb, om, om, F, m, blocks, b, t),
            BLOCK_CANDIDATES, max(2, repeat // 2), args.threads)
        variants.update(v)
        notes.append(note)

    q_core, nsing = core()
    q_core = q_core[:, 0]
    print("agreement with rotorid's core (max |difference| / max |q|; max per-speed relative difference):")
    resp = check_api("public API", api)
    rows = ([("public API", resp.q)] if resp is not None else []) + [(label, fn()) for label, fn in variants.items()]
    for label, q in rows:
        per = np.max(np.abs(q - q_core) / np.abs(q_core).max(axis=1, keepdims=True))
        print(f"  {label:40s} {rel_diff(q, q_core):.1e}   {per:.1e}")
    print(f"singular points reported by the core: {nsing}")
    print("\n".join(notes))
    print()

    print(f"  {'core imbalance entry (the API calls it)':40s} {rel_diff(core_imbalance()[0][:, 0], q_core):.1e}")
    t = best_of_each({"core": core, "core_imbalance": core_imbalance, **({"api": api} if resp is not None else {}),
                      **variants}, repeat)
    report(work=f"imbalance response at {n:,} speeds", n=n, unit="speeds",
           core=("rotorid._core.forced_response", t["core"]),
           api=("rotorid.imbalance_response (public API)", t["api"], None, None) if "api" in t else None,
           extra_rows=[("rotorid._core.imbalance_response (forces e Omega^2 formed in the core; the API's call)",
                        t["core_imbalance"])],
           numpy={k: t[k] for k in variants}, target_ratio=TARGET)
    blocks.close()


if __name__ == "__main__":
    main()
