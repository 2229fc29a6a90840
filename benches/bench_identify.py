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
from common import best_of, blas_info, nsf_runs  # noqa: E402

import rotorid  # noqa: E402
from rotorid import _core  # noqa: E402

RPM = np.pi / 30


def numpy_report(rotor, om, qs, e, chunk=20000):
    """qs: (R, n, 4); e: (R, 4) -> P (n, 16) = [K, wC] in eq. 9 order."""
    M, G = rotor.matrices()
    l1, l2 = rotor.l1, rotor.l2
    lv = np.array([-l1, l2, -l1, l2])
    R, n, _ = qs.shape
    out = np.empty((n, 16))
    for s in range(0, n, chunk):
        q = qs[:, s:s + chunk]  # (R, m, 4)
        w = om[s:s + chunk]
        m = q.shape[1]
        Q = np.zeros((R, m, 4, 16), complex)
        ql = q * lv
        Q[:, :, 0, 0:4] = q
        Q[:, :, 0, 8:12] = 1j * q
        Q[:, :, 1, 4:8] = q
        Q[:, :, 1, 12:16] = 1j * q
        Q[:, :, 2, 0:4] = ql
        Q[:, :, 2, 8:12] = 1j * ql
        Q[:, :, 3, 4:8] = -ql
        Q[:, :, 3, 12:16] = -1j * ql
        FT = e[:, None, :] * (w ** 2)[None, :, None] + np.einsum("ij,rmj->rmi", M, q) * (w ** 2)[None, :, None] \
            - 1j * np.einsum("ij,rmj->rmi", G, q) * (w ** 2)[None, :, None]
        B = np.concatenate([Q.real, Q.imag], axis=2).transpose(1, 0, 2, 3).reshape(m, 8 * R, 16)
        F = np.concatenate([FT.real, FT.imag], axis=2).transpose(1, 0, 2).reshape(m, 8 * R)
        BtB = np.einsum("mki,mkj->mij", B, B)
        BtF = np.einsum("mki,mk->mi", B, F)
        out[s:s + chunk] = np.linalg.solve(BtB, BtF[..., None])[..., 0]
    return out


def numpy_fast(rotor, om, qs, e):
    """Bearing-force formulation, closed-form 2x2 complex normal equations. Returns k, c (n, 2, 2, 2)."""
    m_, it, ip, l1, l2 = rotor.core_params()
    L = l1 + l2
    x1, x2, y1, y2 = qs[..., 0], qs[..., 1], qs[..., 2], qs[..., 3]  # (R, n)
    w2 = om ** 2
    E = e[:, None, :] * w2[None, :, None]
    r1 = E[..., 0] + w2 * m_ * (l2 * x1 + l1 * x2) / L
    r2 = E[..., 1] + w2 * m_ * (l2 * y1 + l1 * y2) / L
    r3 = E[..., 2] + w2 * it * (x2 - x1) / L - 1j * w2 * ip * (y2 - y1) / L
    r4 = E[..., 3] + w2 * it * (y1 - y2) / L - 1j * w2 * ip * (x2 - x1) / L
    f = [((l2 * r1 - r3) / L, (l2 * r2 + r4) / L), ((r3 + l1 * r1) / L, (l1 * r2 - r4) / L)]
    k = np.empty((om.size, 2, 2, 2))
    c = np.empty_like(k)
    for b, (x, y) in enumerate(((x1, y1), (x2, y2))):
        a = (x.real ** 2 + x.imag ** 2).sum(0)
        d = (y.real ** 2 + y.imag ** 2).sum(0)
        g = (x.conj() * y).sum(0)
        det = a * d - (g.real ** 2 + g.imag ** 2)
        for i in range(2):
            fb = f[b][i]
            h1 = (x.conj() * fb).sum(0)
            h2 = (y.conj() * fb).sum(0)
            z1 = (d * h1 - g * h2) / det
            z2 = (a * h2 - g.conj() * h1) / det
            k[:, b, i, 0] = z1.real
            k[:, b, i, 1] = z2.real
            c[:, b, i, 0] = z1.imag / om
            c[:, b, i, 1] = z2.imag / om
    return k, c


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--speeds", type=int, default=100_000)
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
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
