"""NumPy implementations of the benchmarked work: the baselines rotorid's core is measured against.

Each is the best NumPy we could write for the same inputs and outputs as the core call, in up to
three variants chosen by the benches (``common.numpy_variants``): all points at once
("unblocked"), cache-blocked on one thread, and cache-blocked on a few Python threads (NumPy's
ufuncs, BLAS and LAPACK calls release the GIL). The blocked kernels write into preallocated
outputs, so blocking costs no concatenation.

Block sizes. Every elementwise NumPy call streams its operands through the cache; all points at
once (10^5 points, megabytes per temporary) means every one of the ~100-200 calls of a kernel
goes to L3 or memory, and glibc maps and unmaps each temporary above its mmap threshold. In
blocks whose temporaries fit in L2 (512 KiB per core on the reference machine: one (4 runs x
2048 points) complex temporary is 128 KiB), the calls work from L2 and the temporaries recycle
through malloc's free lists; too small a block and the ~1 µs Python dispatch of each call
dominates, and with threads the GIL held during that dispatch limits the overlap. The benches
try a few sizes (``common.BLOCK_CANDIDATES``: 1024-16384 points; run-out 8192-65536 samples;
modal 256-4096 matrices) and keep the fastest, separately for one thread and for the threaded
variant, and print the tuning. On the reference machine (AMD EPYC, 2 cores, 512 KiB L2) the
winners were 2048-8192 points for the identification and the forward solve, 16384-65536
samples for the run-out filter (fewer, larger gathers), and ~1024 matrices for eig (indifferent:
LAPACK per matrix dominates). Block-size and thread-count winners vary from run to run on a
shared machine; the benches re-tune on every run.

Identification (synchronous and impact):
  numpy_report:  the report's formulation, eq. 8-12 and 16-18: real 8R x 16 matrix per point,
                 P = (B^T B)^-1 B^T F via batched np.linalg.solve (shown for reference only).
  numpy_fast:    bearing reaction forces from the rotor equations, then per bearing the 2x2 complex
                 normal equations solved in closed form; all points at once (the original baseline).
  numpy_ident:   the same normal equations from the Hermitian 4x4 Gram matrix of the responses over
                 the runs (10 products summed over runs instead of ~60 passes over runs x points),
                 the bearing forces entering as per-point linear combinations of Gram entries;
                 unblocked, blocked, threaded.
Forward imbalance response (batched 4x4 complex solves):
  numpy_forward(method="solve"):    assemble H (n, 4, 4) and batched np.linalg.solve (LAPACK zgesv per point);
  numpy_forward(method="explicit"): the 16 entries of H as rows from one real matmul, then Gaussian
                 elimination unrolled over the points with the rows ordered [Fx, Mx, Fy, My] so the
                 direct stiffness terms are the pivots (static pivoting; accuracy printed by the bench).
Modal analysis:
  numpy_modal:   8x8 state matrices, batched np.linalg.eig (LAPACK dgeev, balanced), modes with
                 Im(lambda) > 0 sorted by frequency, displacement part of the eigenvectors scaled
                 to unit largest component.
Run-out filter:
  numpy_signature:     revolution signature, 4-point Lagrange resampling (vectorized).
  numpy_runout_simple: per-sample searchsorted and 4-point stencils by fancy indexing, whole record
                       (the original baseline).
  numpy_runout:        the same interpolant as per-interval cubic polynomials of the template
                       (4 coefficient tables), the revolution of each sample from the pulse
                       positions (np.repeat), one gather per coefficient for all channels at once;
                       unblocked, blocked, threaded.
"""

import numpy as np


# ---------------------------------------------------------------------------------------------
# model matrices (pure NumPy, from the core's rotor parameter vector [m, I_T, I_p, l1, l2])

def rotor_matrices(p):
    m, it, ip, l1, l2 = (float(v) for v in p)
    L = l1 + l2
    M = np.array([[m * l2, m * l1, 0, 0], [0, 0, m * l2, m * l1], [-it, it, 0, 0], [0, 0, it, -it]]) / L
    G = np.array([[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, -ip, ip], [-ip, ip, 0, 0]]) / L
    return M, G


def assemble(b, l1, l2):
    """4x4 stiffness or damping matrix of eq. 3 from 8 bearing coefficients [bearing][i][j]."""
    xx1, xy1, yx1, yy1, xx2, xy2, yx2, yy2 = np.asarray(b, float).reshape(8)
    return np.array([[xx1, xx2, xy1, xy2], [yx1, yx2, yy1, yy2],
                     [-xx1 * l1, xx2 * l2, -xy1 * l1, xy2 * l2], [yx1 * l1, -yx2 * l2, yy1 * l1, -yy2 * l2]])


def _blocked(blocks, kernel, n, block, threads):
    if blocks is None:
        kernel(0, n)
    else:
        blocks.run(kernel, n, block, threads)


# ---------------------------------------------------------------------------------------------
# identification

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
    """Bearing-force formulation, closed-form 2x2 complex normal equations, all points at once.
    Returns k, c (n, 2, 2, 2). om: vibration frequency (rad/s); spin defaults to om, gain to om^2
    (synchronous imbalance)."""
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


class IdentPlan:
    """Constants of the Gram-matrix identification for one rotor and one set of excitations.

    The bearing forces are linear in the responses: for bearing force f (fx1, fy1, fx2, fy2),
    f = (w^2 / L) (a_f . q) + j (w spin I_p / L^2) (b_f . q) + gain eps_f with constant 4-vectors
    a_f, b_f and per-run excitations eps_f. So the normal-equation right-hand sides
    sum_runs conj(q_i) f are per-point combinations of the Gram entries G_ij = sum_runs conj(q_i) q_j
    and of H_if = sum_runs conj(q_i) eps_f, and only G (10 distinct entries) and H touch the runs."""

    def __init__(self, p, e):
        m, it, ip, l1, l2 = (float(v) for v in p)
        L = l1 + l2
        T, mL = it / L, m / L
        self.iL = 1.0 / L
        self.pg = ip / (L * L)
        e = np.asarray(e, complex)
        # eps: (4 forces, R) in the order fx1, fy1, fx2, fy2
        self.eps = np.ascontiguousarray(np.stack([(l2 * e[:, 0] - e[:, 2]) / L, (l2 * e[:, 1] + e[:, 3]) / L,
                                                  (e[:, 2] + l1 * e[:, 0]) / L, (l1 * e[:, 1] - e[:, 3]) / L]))
        c_in, c_out = l2 * l2 * mL + T, l1 * l2 * mL - T   # bearing 1: on (own, other) dof of the axis
        d_in, d_out = l1 * l1 * mL + T, l1 * l2 * mL - T   # bearing 2
        # per bearing b: dofs (x, y) and per force (force index, a coefficients on (dof1, dof2) of
        # its axis, axis 0 = x / 1 = y, sign of the gyroscopic term on the other axis' difference)
        self.bearings = (
            ((0, 2), ((0, (c_in, c_out), 0, +1.0), (1, (c_in, c_out), 1, -1.0))),
            ((1, 3), ((2, (d_out, d_in), 0, -1.0), (3, (d_out, d_in), 1, +1.0))),
        )


def ident_kernel(plan, om, spin, gain, qs, k, c):
    """Identify k, c (B, 2, 2, 2) (written in place) at B points from qs (R, B, 4) (a view)."""
    R, B = qs.shape[0], qs.shape[1]
    Q = np.empty((4, R, B), complex)
    np.copyto(Q, qs.transpose(2, 0, 1))           # dof-major, contiguous per (dof, run)
    Qc = np.conj(Q)
    G = [[None] * 4 for _ in range(4)]
    for i in range(4):
        G[i][i] = np.multiply(Qc[i], Q[i]).sum(0).real
        for j in range(i + 1, 4):
            G[i][j] = np.multiply(Qc[i], Q[j]).sum(0)
    s = om * om * plan.iL                        # w^2 / L
    t = (om * spin) * plan.pg                    # w spin I_p / L^2
    Z = np.empty((2, 2, 2, B), complex)          # (bearing, force, response dof, point)
    for b, ((ix, iy), forces) in enumerate(plan.bearings):
        # H for this bearing's dofs and forces: (2 dofs, 2 forces, B) in one small matmul
        H = np.matmul(plan.eps[2 * b:2 * b + 2], Qc[ix::2])   # dofs (ix, iy) = (ix, ix + 2)
        a = G[ix][ix]
        d = G[iy][iy]
        g = G[ix][iy]
        idet = 1.0 / (a * d - (g.real * g.real + g.imag * g.imag))
        a = a * idet
        d = d * idet
        g = g * idet
        gc = np.conj(g)
        for i, (f, (c1, c2), axis, sgn) in enumerate(forces):
            hs = []
            for r, row in enumerate((ix, iy)):
                def Gr(j, row=row):
                    return G[row][j] if j >= row else np.conj(G[j][row])
                if axis == 0:   # x force: a on (x1, x2) = dofs 0, 1; gyroscopic term on y2 - y1
                    lin = c1 * Gr(0) + c2 * Gr(1)
                    dif = Gr(3) - Gr(2)
                else:           # y force: a on (y1, y2) = dofs 2, 3; gyroscopic term on x2 - x1
                    lin = c1 * Gr(2) + c2 * Gr(3)
                    dif = Gr(1) - Gr(0)
                h = s * lin
                h += (1j * sgn) * (t * dif)
                h += gain * H[r, i]
                hs.append(h)
            h1, h2 = hs
            np.subtract(d * h1, g * h2, out=Z[b, i, 0])
            np.subtract(a * h2, gc * h1, out=Z[b, i, 1])
    # k = Re Z, c = Im Z / w, each in one (transposing) pass
    Zt = Z.transpose(3, 0, 1, 2)
    np.copyto(k, Zt.real)
    np.multiply(Zt.imag, (1.0 / om)[:, None, None, None], out=c)


def numpy_ident(p, w, spin, gain, qs, e, blocks=None, block=None, threads=1):
    """Gram-matrix identification: qs (R, n, 4) complex, e (R, 4) -> k, c (n, 2, 2, 2).
    ``blocks`` (common.Blocks) and ``block``: cache-blocked, on ``threads`` threads; None: all at once."""
    plan = IdentPlan(p, e)
    n = w.size
    k = np.empty((n, 2, 2, 2))
    c = np.empty((n, 2, 2, 2))

    def kernel(s, t):
        ident_kernel(plan, w[s:t], spin[s:t], gain[s:t], qs[:, s:t], k[s:t], c[s:t])

    _blocked(blocks, kernel, n, block, threads)
    return k, c


# ---------------------------------------------------------------------------------------------
# forward imbalance response: H q = F, H = K - w^2 M + j w (C + spin G)

def _forward_solve_kernel(K, C, M, G, w, spin, F, out):
    H = (K - (w * w)[:, None, None] * M) + 1j * (w[:, None, None] * C + (w * spin)[:, None, None] * G)
    out[...] = np.linalg.solve(H, F[..., None])[..., 0]


ROW_ORDER = (0, 2, 1, 3)  # equations Fx, Mx, Fy, My: the direct terms of x1, x2, y1, y2 on the diagonal


def _forward_coef(K, C, M, G):
    """(4, 32) real matrix: [1, w^2, w, w spin] @ it = the 16 entries of H (rows in ROW_ORDER),
    interleaved real/imaginary, i.e. a complex (., 16) array."""
    cm = np.zeros((4, 32))
    for e, (r, col) in enumerate((r, col) for r in ROW_ORDER for col in range(4)):
        cm[0, 2 * e] = K[r, col]
        cm[1, 2 * e] = -M[r, col]
        cm[2, 2 * e + 1] = C[r, col]
        cm[3, 2 * e + 1] = G[r, col]
    return cm


def _forward_explicit_kernel(cm, w, spin, F, out):
    B = w.size
    basis = np.empty((B, 4))
    basis[:, 0] = 1.0
    np.multiply(w, w, out=basis[:, 1])
    basis[:, 2] = w
    np.multiply(w, spin, out=basis[:, 3])
    Hc = (basis @ cm).view(complex)              # (B, 16): row-major entries of the reordered H
    Ht = np.ascontiguousarray(Hc.T)              # (16, B): each entry contiguous over the points
    A = [[Ht[4 * r + col] for col in range(4)] for r in range(4)]
    b = [F[:, r] for r in ROW_ORDER]
    inv = [None] * 4
    for kk in range(4):
        inv[kk] = 1.0 / A[kk][kk]
        for i in range(kk + 1, 4):
            li = A[i][kk] * inv[kk]
            for j in range(kk + 1, 4):
                A[i][j] = A[i][j] - li * A[kk][j]
            b[i] = b[i] - li * b[kk]
    x = [None] * 4
    for i in range(3, -1, -1):
        acc = b[i]
        for j in range(i + 1, 4):
            acc = acc - A[i][j] * x[j]
        x[i] = acc * inv[i]
        out[:, i] = x[i]


def numpy_forward(p, kb, cb, spin, w, F, method="solve", blocks=None, block=None, threads=1):
    """Forced response q (n, 4) for constant bearing coefficients kb, cb (8,) and forces F (n, 4)."""
    M, G = rotor_matrices(p)
    l1, l2 = float(p[3]), float(p[4])
    K = assemble(kb, l1, l2)
    C = assemble(cb, l1, l2)
    n = w.size
    out = np.empty((n, 4), complex)
    if method == "solve":
        def kernel(s, t):
            _forward_solve_kernel(K, C, M, G, w[s:t], spin[s:t], F[s:t], out[s:t])
    elif method == "explicit":
        cm = _forward_coef(K, C, M, G)

        def kernel(s, t):
            _forward_explicit_kernel(cm, w[s:t], spin[s:t], F[s:t], out[s:t])
    else:
        raise ValueError(method)
    _blocked(blocks, kernel, n, block, threads)
    return out


# ---------------------------------------------------------------------------------------------
# modal analysis

def _modal_kernel(mk, mc, mg, spin, lam, shapes):
    B = spin.size
    A = np.zeros((B, 8, 8))
    A[:, 0:4, 4:8] = np.eye(4)
    A[:, 4:8, 0:4] = mk
    A[:, 4:8, 4:8] = mc + spin[:, None, None] * mg
    ev, vec = np.linalg.eig(A)
    ev = ev.astype(complex, copy=False)
    vec = vec.astype(complex, copy=False)
    pos = ev.imag > 1e-9 * np.abs(ev)
    order = np.argsort(np.where(pos, ev.imag, np.inf), axis=1, kind="stable")[:, :4]
    sel = np.take_along_axis(pos, order, 1)
    lm = np.take_along_axis(ev, order, 1)
    lm[~sel] = np.nan
    lam[...] = lm
    v = np.take_along_axis(vec[:, :4, :], order[:, None, :], 2).transpose(0, 2, 1)  # (B, modes, dofs)
    big = np.argmax(np.abs(v), axis=2)[..., None]
    sh = v / np.take_along_axis(v, big, 2)
    sh[~sel] = np.nan
    shapes[...] = sh


def numpy_modal(p, kb, cb, spin, blocks=None, block=None, threads=1):
    """Eigenvalues (n, 4) with Im > 0 sorted by frequency (NaN-padded) and mode shapes (n, 4, 4)
    for constant bearing coefficients kb, cb (8,) at running speeds spin (rad/s)."""
    M, G = rotor_matrices(p)
    l1, l2 = float(p[3]), float(p[4])
    Mi = np.linalg.inv(M)
    mk = -Mi @ assemble(kb, l1, l2)
    mc = -Mi @ assemble(cb, l1, l2)
    mg = -Mi @ G
    n = spin.size
    lam = np.empty((n, 4), complex)
    shapes = np.empty((n, 4, 4), complex)

    def kernel(s, t):
        _modal_kernel(mk, mc, mg, spin[s:t], lam[s:t], shapes[s:t])

    _blocked(blocks, kernel, n, block, threads)
    return lam, shapes


# ---------------------------------------------------------------------------------------------
# run-out filter

def lagrange4(f):
    return (-f * (f - 1) * (f - 2) / 6, (f + 1) * (f - 1) * (f - 2) / 2, -(f + 1) * f * (f - 2) / 2,
            (f + 1) * f * (f - 1) / 6)


def numpy_signature(x, fs, kp, k0, k1, p):
    """Average of revolutions k0..k1 resampled at p angles (4-point Lagrange): (C, p)."""
    t = (kp[k0:k1, None] + (kp[k0 + 1:k1 + 1] - kp[k0:k1])[:, None] * (np.arange(p) / p)[None, :]).ravel()
    u = t * fs
    m = np.floor(u).astype(np.int64)
    w = lagrange4(u - m)
    n = x.shape[1]
    out = sum(wi * x[:, np.clip(m + d, 0, n - 1)] for wi, d in zip(w, (-1, 0, 1, 2)))
    return out.reshape(x.shape[0], k1 - k0, p).mean(axis=1)


def numpy_runout_simple(x, fs, kp, tmpl):
    """The straightforward vectorization: x (C, N) minus the template at each sample's angle."""
    n = x.shape[1]
    p = tmpl.shape[1]
    t = np.arange(n) / fs
    k = np.searchsorted(kp, t, side="right") - 1
    valid = (k >= 0) & (k < kp.size - 1)
    kc = np.clip(k, 0, kp.size - 2)
    phi = (t - kp[kc]) / (kp[kc + 1] - kp[kc])
    u = phi * p
    m = np.floor(u).astype(np.int64)
    w = lagrange4(u - m)
    out = np.empty_like(x)
    for c in range(x.shape[0]):
        s = sum(wi * tmpl[c, (m + d) % p] for wi, d in zip(w, (-1, 0, 1, 2)))
        out[c] = np.where(valid, x[c] - s, np.nan)
    return out


def _poly_tables(tmpl):
    """Per-interval cubic coefficients of the periodic 4-point Lagrange interpolant of tmpl (C, p):
    value at u = m + f is c0[m] + f (c1[m] + f (c2[m] + f c3[m])). Each table (C, p), flattened."""
    ym1 = np.roll(tmpl, 1, axis=1)
    y0 = tmpl
    y1 = np.roll(tmpl, -1, axis=1)
    y2 = np.roll(tmpl, -2, axis=1)
    c0 = y0
    c1 = -ym1 / 3 - y0 / 2 + y1 - y2 / 6
    c2 = (ym1 + y1) / 2 - y0
    c3 = (y2 - ym1) / 6 + (y0 - y1) / 2
    return [np.ascontiguousarray(c).ravel() for c in (c0, c1, c2, c3)]


def numpy_runout(x, fs, t0, kp, tmpl, i0, i1, blocks=None, block=None, threads=1):
    """Run-out filter as the core computes it: out (C, i1 - i0) = x[:, i0:i1] minus the template
    at each sample's angle (sample time t0 + i / fs; revolution k with kp[k] <= t < kp[k+1];
    u = (t - kp[k]) / (kp[k+1] - kp[k]) * p; cubic Lagrange on 4 template points); NaN outside
    [kp[0], kp[-1])."""
    C, N = x.shape
    p = tmpl.shape[1]
    tables = _poly_tables(tmpl)
    scale = p / np.diff(kp)                       # u per second, per revolution
    offs = (np.arange(C) * p)[:, None]
    m_all = i1 - i0
    out = np.empty((C, m_all))

    def kernel(s, e):
        a, b = i0 + s, i0 + e                     # absolute sample range
        t = t0 + np.arange(a, b) / fs
        # revolution of every sample: the pulses inside the block split it into runs of samples
        k_first = np.searchsorted(kp, t[0], side="right") - 1
        cut = np.searchsorted(t, kp[k_first + 1:np.searchsorted(kp, t[-1], side="right")], side="left")
        bounds = np.concatenate(([0], cut, [t.size]))
        counts = np.diff(bounds)
        ks = np.arange(k_first, k_first + counts.size)
        ok = (ks >= 0) & (ks < kp.size - 1)
        kc = np.clip(ks, 0, kp.size - 2)
        u = (t - np.repeat(kp[kc], counts)) * np.repeat(scale[kc], counts)
        mi = u.astype(np.intp)                    # u >= 0 where valid: truncation = floor
        f = u - mi
        np.minimum(mi, p - 1, out=mi)
        if not ok.all():                          # outside the pulses: any index, NaN below
            mi[~np.repeat(ok, counts)] = 0
        idx = mi + offs                           # (C, B) into the flattened tables
        c0, c1, c2, c3 = (tb.take(idx) for tb in tables)
        v = c3 * f
        v += c2
        v *= f
        v += c1
        v *= f
        v += c0
        np.subtract(x[:, a:b], v, out=out[:, s:e])
        if not ok.all():
            out[:, s:e][:, ~np.repeat(ok, counts)] = np.nan

    _blocked(blocks, kernel, m_all, block, threads)
    return out
