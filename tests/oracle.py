"""A small, literal NumPy oracle of the report's equations, used only by the tests.

Everything here is written from the report directly (eq. 3, 4, 8-19) with dense matrices and
np.linalg, independent of the Rust core's algebra (sparsity, bearing-force solver, Givens QR).
"""

import numpy as np

RPM = np.pi / 30


def matrices(m, it, ip, l1, l2, kb, cb):
    L = l1 + l2
    M = (1 / L) * np.array([[m * l2, m * l1, 0, 0], [0, 0, m * l2, m * l1], [-it, it, 0, 0], [0, 0, it, -it]])
    G = (1 / L) * np.array([[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, -ip, ip], [-ip, ip, 0, 0]])

    def asm(b):
        xx1, xy1, yx1, yy1 = b[0, 0, 0], b[0, 0, 1], b[0, 1, 0], b[0, 1, 1]
        xx2, xy2, yx2, yy2 = b[1, 0, 0], b[1, 0, 1], b[1, 1, 0], b[1, 1, 1]
        return np.array([[xx1, xx2, xy1, xy2], [yx1, yx2, yy1, yy2],
                         [-xx1 * l1, xx2 * l2, -xy1 * l1, xy2 * l2], [yx1 * l1, -yx2 * l2, yy1 * l1, -yy2 * l2]])

    return M, G, asm(kb), asm(cb)


def imbalance_vector(m12, phi_deg, r12, d12):
    f1, f2 = np.asarray(m12) * np.asarray(r12) * np.exp(-1j * np.deg2rad(phi_deg))
    d1, d2 = d12
    return np.array([f1 + f2, -1j * (f1 + f2), -f1 * d1 + f2 * d2, -1j * (f1 * d1 - f2 * d2)])


def response(M, G, K, C, spin, w, F):
    """Eq. 13/27: q = H^-1 F with H = -w^2 M + j w spin G + j w C + K."""
    H = -w ** 2 * M + 1j * w * spin * G + 1j * w * C + K
    return np.linalg.solve(H, F)


def report_identify(qs, Fs, M, G, l1, l2, w, spin):
    """Eq. 8-18 at one point: qs, Fs lists of 4-vectors (runs). Returns P (16,) = [K..., wC...]."""
    lmat = np.diag([-l1, l2, -l1, l2])
    rows, rhs = [], []
    for q, F in zip(qs, Fs):
        z = np.zeros(4)
        qt = q
        ql = q @ lmat
        Q = np.array([
            np.concatenate([qt, z, 1j * qt, z]),
            np.concatenate([z, qt, z, 1j * qt]),
            np.concatenate([ql, z, 1j * ql, z]),
            np.concatenate([z, -ql, z, -1j * ql]),
        ])
        FT = F + (w ** 2 * M - 1j * w * spin * G) @ q
        rows += [Q.real, Q.imag]
        rhs += [FT.real, FT.imag]
    B = np.vstack(rows)
    Fv = np.concatenate(rhs)
    P, *_ = np.linalg.lstsq(B, Fv, rcond=None)
    return P


def eq19(l1, l2, s1, s2):
    return np.array([[l1 + s2, s1 - l1], [s2 - l2, l2 + s1]]) / (s1 + s2)


def eigen(M, G, K, C, spin):
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((4, 4)), np.eye(4)], [-Mi @ K, -Mi @ (C + spin * G)]])
    lam = np.linalg.eigvals(A)
    lam = lam[lam.imag > 0]
    return lam[np.argsort(lam.imag)]
