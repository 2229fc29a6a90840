"""Forward imbalance-response throughput: rotorid core (batched assembly + 4x4 complex solves)
vs NumPy assembling H(Omega) for every speed and calling batched np.linalg.solve.

    python benches/bench_forward.py [--speeds 100000]
"""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from common import best_of, blas_info, quiet_blas  # noqa: E402

import rotorid  # noqa: E402
from rotorid.model import assemble  # noqa: E402


def numpy_forward(rotor, bearings, imb, rpm):
    om = rpm * np.pi / 30
    M, G = rotor.matrices()
    K = assemble(bearings.k, rotor.l1, rotor.l2)
    C = assemble(bearings.c, rotor.l1, rotor.l2)
    H = (K[None] - (om ** 2)[:, None, None] * M[None] + 1j * (om ** 2)[:, None, None] * G[None]
         + 1j * om[:, None, None] * C[None])
    F = imb.generalized(rotor)[None, :] * (om ** 2)[:, None]
    return np.linalg.solve(H, F[..., None])[..., 0]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--speeds", type=int, default=100_000)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    _blas = quiet_blas()  # noqa: F841  (kept alive for the whole run)
    rig = rotorid.nsf_rig()
    rpm = np.linspace(100, 10000, args.speeds)
    imb = rig.imbalances["B"]
    ours = rotorid.imbalance_response(rig.rotor, rig.bearings, imb, speed_rpm=rpm).q
    ref = numpy_forward(rig.rotor, rig.bearings, imb, rpm)
    print(f"speeds: {args.speeds}; BLAS: {blas_info()}")
    print(f"max relative difference: {np.abs(ours - ref).max() / np.abs(ref).max():.2e}")
    t_r = best_of(lambda: rotorid.imbalance_response(rig.rotor, rig.bearings, imb, speed_rpm=rpm), args.repeat)
    t_n = best_of(lambda: numpy_forward(rig.rotor, rig.bearings, imb, rpm), args.repeat)
    print(f"rotorid.imbalance_response   {1e3 * t_r:9.2f} ms  {args.speeds / t_r:.3e} speeds/s")
    print(f"numpy (assemble + solve)     {1e3 * t_n:9.2f} ms  {args.speeds / t_n:.3e} speeds/s")
    print(f"ratio numpy / rotorid: {t_n / t_r:.1f}x")


if __name__ == "__main__":
    main()
