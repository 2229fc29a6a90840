"""NumPy implementations of the identification work, used as baselines by the benchmarks.

numpy_report: the report's formulation, eq. 8-12 and 16-18: real 8R x 16 matrix per point,
              P = (B^T B)^-1 B^T F via batched np.linalg.solve.
numpy_fast:   the fastest NumPy we could write: bearing reaction forces from the rotor equations,
              then per bearing the 2x2 complex normal equations solved in closed form.
"""

import numpy as np


def numpy_report(rotor, om, qs, e, chunk=20000, spin=None, gain=None):
    """qs: (R, n, 4); e: (R, 4) -> P (n, 16) = [K, wC] in eq. 9 order. om: vibration frequency
    (rad/s); spin defaults to om (synchronous), gain (excitation scale per point) to om^2."""
    spin = om if spin is None else spin
    gain = om ** 2 if gain is None else gain
    M, G = rotor.matrices()
    l1, l2 = rotor.l1, rotor.l2
    lv = np.array([-l1, l2, -l1, l2])
    R, n, _ = qs.shape
    out = np.empty((n, 16))
    for s in range(0, n, chunk):
        q = qs[:, s:s + chunk]  # (R, m, 4)
        w = om[s:s + chunk]
        sp = spin[s:s + chunk]
        gn = gain[s:s + chunk]
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
        FT = e[:, None, :] * gn[None, :, None] + np.einsum("ij,rmj->rmi", M, q) * (w ** 2)[None, :, None] \
            - 1j * np.einsum("ij,rmj->rmi", G, q) * (w * sp)[None, :, None]
        B = np.concatenate([Q.real, Q.imag], axis=2).transpose(1, 0, 2, 3).reshape(m, 8 * R, 16)
        F = np.concatenate([FT.real, FT.imag], axis=2).transpose(1, 0, 2).reshape(m, 8 * R)
        BtB = np.einsum("mki,mkj->mij", B, B)
        BtF = np.einsum("mki,mk->mi", B, F)
        out[s:s + chunk] = np.linalg.solve(BtB, BtF[..., None])[..., 0]
    return out


def numpy_fast(rotor, om, qs, e, spin=None, gain=None):
    """Bearing-force formulation, closed-form 2x2 complex normal equations. Returns k, c (n, 2, 2, 2).
    om: vibration frequency (rad/s); spin defaults to om, gain to om^2 (synchronous imbalance)."""
    spin = om if spin is None else spin
    gain = om ** 2 if gain is None else gain
    m_, it, ip, l1, l2 = rotor.core_params()
    L = l1 + l2
    x1, x2, y1, y2 = qs[..., 0], qs[..., 1], qs[..., 2], qs[..., 3]  # (R, n)
    w2 = om ** 2
    wg = om * spin
    E = e[:, None, :] * gain[None, :, None]
    r1 = E[..., 0] + w2 * m_ * (l2 * x1 + l1 * x2) / L
    r2 = E[..., 1] + w2 * m_ * (l2 * y1 + l1 * y2) / L
    r3 = E[..., 2] + w2 * it * (x2 - x1) / L - 1j * wg * ip * (y2 - y1) / L
    r4 = E[..., 3] + w2 * it * (y1 - y2) / L - 1j * wg * ip * (x2 - x1) / L
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
