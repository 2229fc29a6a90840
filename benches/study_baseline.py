"""NumPy baseline of a Monte Carlo identification study: the fastest NumPy we could write for the
same work as the core's synchronous (and impact) study of docs/studies.md.

    python benches/study_baseline.py [--trials 1000] [--speeds 1000] [--runs 4] [--repeat 3] [--check]

Work of the synchronous study, for every trial and speed: the R imbalance responses of the true
system (the 4x4 inverse of H(Ω) per speed is computed once: without speed errors it does not
change between trials), 1X amplitude and phase errors on every vector (Gaussian, NumPy's ziggurat
on the SFC64 bit generator, seeded per block: the bench is about speed, not the spec's
counter-based stream; results do not depend on the thread count), probes -> bearings
(eq. 19), the 16 coefficients by the bearing-force method (rotor equations -> reaction forces; per
bearing the 2x2 complex normal equations over the runs in closed form, from the Gram matrix of
the responses as in ``baselines.numpy_ident``), relative errors and their streaming statistics
per speed and coefficient (the spec's log-linear histogram: 16 linear bins below E0 = 2^-20, 16
per octave above, 1024 in all; counts of finite and non-finite errors, sum and sum of squares;
percentiles from the histogram as in the spec).
``summary="exact"`` keeps every error of a block of speeds over all trials and takes
np.percentile instead (not streaming in the trials: memory grows with them).

Blocking: a block is (speeds x trials) with the trials on the fast axis, so every NumPy call runs
over contiguous trials and per-speed constants broadcast along the slow axis. The loop goes over
blocks of speeds (the tasks, on 1 or 2 threads; each task owns its speeds' statistics, so threads
never merge or lock) and inside a task over blocks of trials, so memory stays bounded by the block
whatever the trial count. ``block`` is the number of points (speeds x trials) per block, or an
explicit (speeds, trials). Every array of a block lives in a per-thread workspace (``_Workspace``):
fresh temporaries of this size come from mmap and their page faults cost more than the arithmetic.

Reference timings (AMD EPYC, 2 cores, AVX2, 512 KiB L2, NumPy 2.4, machine nearly idle), 1000 trials x
1000 speeds x 4 runs, histogram summary: synchronous 1 thread 0.86 s (block 8000 = 8 speeds x 1000
trials), 2 threads 0.54 s (block 16000); impact 0.77 s and 0.47 s. Of the 1-thread synchronous
time: about 30 % drawing the 32 normals per trial-speed (SFC64 ziggurat, ~8.5 ns each: NumPy's
fastest; Box-Muller costs more, np.sin/np.cos alone ~9.5 ns per value without AVX-512), 25 % the
identification, 15 % the statistics (the bin index ~7 %: read from the float bits, see
``_signed_magnitude``; the earlier np.frexp version was 8x slower, not for frexp itself but for
its masked ``where=`` ufuncs and int-to-float casts, and made the statistics 30 % of the time), 10 %
the percentiles, 8 % the phase factors (sin by its Taylor series for small angles, cos =
sqrt(1 - sin^2)), the rest the perturbation and probes -> bearings.

The impact study (``numpy_impact_study``) is the same work with FRFs: errors
(1 + ε (n_re + j n_im)) with ε = sqrt((1 - γ²) / (2 n_d γ²)), identification at each frequency
with R = E - s²Mq - sΩGq, gain 1, s = jw.
"""

import argparse
import os
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from baselines import IdentPlan, assemble, rotor_matrices  # noqa: E402

REPORT_TO_BIJ = np.array([0, 4, 1, 5, 2, 6, 3, 7])
BINS = 1024
E0 = 2.0 ** -20                   # errors below E0 binned linearly, above by octaves (16 bins each)
SUB = 16
PERCENTILES = (5.0, 50.0, 95.0)
COND_SINGULAR = 1e14              # rotorid's 'singular' flag: NaN coefficients


# ---------------------------------------------------------------------------------------------
# set-up shared by both studies

def _true_responses(p, kb, cb, w, spin, e, scale):
    """Bearing responses q (R, n, 4) = scale H(spin, w)^-1 e, from the per-point inverse."""
    M, G = rotor_matrices(p)
    l1, l2 = float(p[3]), float(p[4])
    K = np.array([assemble(k, l1, l2) for k in kb])
    C = np.array([assemble(c, l1, l2) for c in cb])
    H = K - (w * w)[:, None, None] * M + 1j * (w[:, None, None] * C + (w * spin)[:, None, None] * G)
    Hinv = np.linalg.inv(H)                                   # once per point
    return np.einsum("nij,rj->rni", Hinv, e) * scale[None, :, None]


def _channels(qb, l1, l2, z4):
    """Readings of the channels at axial positions z4 (4,): (4, R, n) complex."""
    L = l1 + l2
    out = np.empty((4,) + qb.shape[:2], complex)
    for c in range(4):
        a, b = (0, 1) if c < 2 else (2, 3)
        out[c] = ((l2 - z4[c]) * qb[..., a] + (l1 + z4[c]) * qb[..., b]) / L
    return out


def _eq19(l1, l2, z4):
    """(4, 4) real matrix: bearing dofs [x1, x2, y1, y2] from channels at nominal positions z4."""
    L = l1 + l2
    A = np.zeros((4, 4))
    for ca, cb in ((0, 1), (2, 3)):
        fwd = np.array([[l2 - z4[ca], l1 + z4[ca]], [l2 - z4[cb], l1 + z4[cb]]]) / L
        A[ca:cb + 1, ca:cb + 1] = np.linalg.inv(fwd)
    return A


def _reference(kb, cb):
    """1 / ref (16, n) in report order (|p|, or the mean |direct| of the kind and bearing where p = 0)."""
    out = []
    for pm in (np.asarray(kb, float), np.asarray(cb, float)):
        ref = np.abs(pm)
        for b in range(2):
            direct = 0.5 * (np.abs(pm[:, 4 * b]) + np.abs(pm[:, 4 * b + 3]))
            blk = slice(4 * b, 4 * b + 4)
            ref[:, blk] = np.where(pm[:, blk] == 0, direct[:, None], ref[:, blk])
        out.append(ref[:, REPORT_TO_BIJ])
    return 1.0 / np.concatenate(out, axis=1).T


# ---------------------------------------------------------------------------------------------
# the per-block kernel: measured channels -> identification -> errors

class _Workspace:
    """Preallocated arrays of one (nb speeds x tb trials) block, reused block after block by one
    thread: the 16-values-per-point arrays (0.5-2 MB) would otherwise be fresh mmap'd memory at
    every call (glibc's mmap threshold), whose page faults cost more than the arithmetic."""

    def __init__(self, R, nb, tb):
        shp = (4, R, nb, tb)
        self.shape = shp
        self.nrm = np.empty((2,) + shp)
        self.r1 = np.empty(shp)
        self.r2 = np.empty(shp)
        self.r3 = np.empty(shp)
        self.r4 = np.empty(shp)
        self.f = np.empty(shp, complex)
        self.Q = np.empty(shp, complex)
        self.Qc = np.empty(shp, complex)
        self.prod = np.empty(shp[1:], complex)
        self.H = np.empty((2, 2, 2, nb * tb), complex)
        self.err = np.empty((16, nb, tb))
        self.e1 = np.empty((16, nb, tb))
        self.e2 = np.empty((16, nb, tb))
        self.idx = np.empty((16, nb, tb), np.int64)
        self.sing = np.empty((nb, tb), bool)
        # identification: the full Gram matrix (lower triangle = conjugates), the bearing's
        # normalized 2x2 system, the two right-hand sides, the two unknowns and two temporaries
        self.G = np.empty((4, 4, nb, tb), complex)
        self.sys = np.empty((4, nb, tb), complex)     # a/det, d/det, g/det, conj(g)/det
        self.h = np.empty((2, nb, tb), complex)
        self.Z = np.empty((2, nb, tb), complex)
        self.T = np.empty((2, nb, tb), complex)


_local = threading.local()


def _workspace(R, nb, tb):
    """This thread's workspace for blocks of that shape (a few shapes kept: full and tail blocks)."""
    cache = getattr(_local, "ws", None)
    if cache is None:
        cache = _local.ws = {}
    key = (R, nb, tb)
    if key not in cache:
        if len(cache) >= 4:
            cache.clear()
        cache[key] = _Workspace(R, nb, tb)
    return cache[key]


class _Study:
    """Constants of one study; ``run_block`` does one (speeds x trials) block."""

    def __init__(self, p, kb, cb, w, spin, gain, e, X, probes_z, perturb):
        m, it, ip, l1, l2 = (float(v) for v in p)
        L = l1 + l2
        self.n = w.size
        self.R = e.shape[0]
        self.plan = IdentPlan(p, e)
        self.eps_t = np.ascontiguousarray(self.plan.eps)         # (4 forces, R) complex
        self.A = _eq19(l1, l2, probes_z)
        # per-point constants (n, 1): broadcast along the trials (fast axis)
        self.s = (w * w / L)[:, None]
        self.t = (w * spin * ip / (L * L))[:, None]
        self.gain = np.asarray(gain, float)[:, None]
        self.s_c = self.s.astype(complex)                          # complex copies: no mixed-type loops
        self.jt_c = 1j * self.t
        self.gain_c = self.gain.astype(complex)
        self.bij_to_report = np.argsort(REPORT_TO_BIJ)
        self.iw = (1.0 / w)[:, None]
        self.ktrue = np.asarray(kb, float)[:, REPORT_TO_BIJ].T[:, :, None]  # (8, n, 1) report order
        self.ctrue = np.asarray(cb, float)[:, REPORT_TO_BIJ].T[:, :, None]
        self.iref = _reference(kb, cb)[:, :, None]                 # (16, n, 1)
        self.X = X                                                 # (4, R, n) true channel readings
        self.perturb = perturb

    def measured_to_bearings(self, Xm, W):
        """W.Q (4 dofs, R, nb, tb) from the measured channels (eq. 19 at the nominal positions)."""
        A = self.A
        Q = W.Q
        for d in range(4):
            a, b = (0, 1) if d < 2 else (2, 3)
            np.multiply(Xm[a], A[d, a], out=Q[d])
            np.multiply(Xm[b], A[d, b], out=W.prod)
            Q[d] += W.prod
        return Q

    def identify_errors(self, Q, sl, W):
        """Relative errors (16, nb, tb) into ``W.err`` from bearing responses Q (4, R, nb, tb) at
        the speeds ``sl``. Gram matrix of the responses over the runs, bearing forces as its
        linear combinations (baselines.IdentPlan), 2x2 normal equations in closed form. Every
        temporary lives in the workspace."""
        plan = self.plan
        Qc = np.conjugate(Q, out=W.Qc)
        G = W.G
        R = self.R
        tmp = W.prod[0]
        for i in range(4):
            for j in range(i, 4):
                g = G[i, j]
                np.multiply(Qc[i, 0], Q[j, 0], out=g)
                for r in range(1, R):
                    np.multiply(Qc[i, r], Q[j, r], out=tmp)
                    g += tmp
            G[i, i].imag = 0.0                                    # exactly real (an FMA may leave ~1e-32)
            for j in range(i + 1, 4):
                np.conjugate(G[i, j], out=G[j, i])
        # H[b][r][i] = sum_runs conj(q_d) eps_f for the bearing's dofs d = (b, b + 2) and forces
        # f = (2b, 2b + 1) (fx_b, fy_b): (2, 2, 2, nb, tb)
        nb, tb = Q.shape[2:]
        for b in range(2):
            np.matmul(self.eps_t[2 * b:2 * b + 2], Qc[b::2].reshape(2, R, -1), out=W.H[b])
        H = W.H.reshape(2, 2, 2, nb, tb)
        sc, jt, gain = self.s_c[sl], self.jt_c[sl], self.gain_c[sl]
        iw, kt, ct, iref = self.iw[sl], self.ktrue[:, sl], self.ctrue[:, sl], self.iref[:, sl]
        T0, T1 = W.T
        an, dn, gn, gcn = W.sys
        err = W.err
        for b, ((ix, iy), forces) in enumerate(plan.bearings):
            np.multiply(G[ix, ix], G[iy, iy], out=T0)
            np.multiply(G[ix, iy], G[iy, ix], out=T1)             # |g|^2
            T0 -= T1                                              # det
            # singular as rotorid flags it, cond([x_b y_b]) > 1e14: lambda_max^2 > 1e28 det with
            # lambda_max = (a + d)/2 + sqrt(((a - d)/2)^2 + |g|^2) (the Gram matrix's eigenvalues are
            # the squared singular values). The normal equations themselves resolve cond up to ~1e8.
            lam, tmp = W.r1[0, 0], W.r1[0, 1]
            np.subtract(G[ix, ix].real, G[iy, iy].real, out=tmp)
            tmp *= 0.5
            tmp *= tmp
            tmp += T1.real
            np.sqrt(tmp, out=tmp)
            np.add(G[ix, ix].real, G[iy, iy].real, out=lam)
            lam *= 0.5
            lam += tmp
            lam *= lam
            lam *= 1.0 / COND_SINGULAR ** 2
            np.less_equal(T0.real, lam, out=W.sing)
            np.copyto(T0, complex(np.nan, np.nan), where=W.sing)
            np.divide(1.0, T0, out=T0)                            # 1 / det
            np.multiply(G[ix, ix], T0, out=an)
            np.multiply(G[iy, iy], T0, out=dn)
            np.multiply(G[ix, iy], T0, out=gn)
            np.multiply(G[iy, ix], T0, out=gcn)
            for i, (f, (c1, c2), axis, sgn) in enumerate(forces):
                k0, k1, k2, k3 = (0, 1, 2, 3) if axis == 0 else (2, 3, 0, 1)
                for r, (h, row) in enumerate(zip(W.h, (ix, iy))):
                    # h = s (c1 G[row,k0] + c2 G[row,k1]) + j sgn t (G[row,k3] - G[row,k2]) + gain H[row,f]
                    np.multiply(G[row, k0], c1, out=h)
                    np.multiply(G[row, k1], c2, out=T1)
                    h += T1
                    h *= sc
                    np.subtract(G[row, k3], G[row, k2], out=T1)
                    T1 *= jt
                    if sgn > 0:
                        h += T1
                    else:
                        h -= T1
                    np.multiply(H[b, r, i], gain, out=T1)
                    h += T1
                h1, h2 = W.h
                z0, z1 = W.Z
                np.multiply(dn, h1, out=z0)
                np.multiply(gn, h2, out=T1)
                z0 -= T1
                np.multiply(an, h2, out=z1)
                np.multiply(gcn, h1, out=T1)
                z1 -= T1
                for jj, z in enumerate((z0, z1)):
                    j = self.bij_to_report[4 * b + 2 * i + jj]
                    ek, ec = err[j], err[8 + j]
                    np.subtract(z.real, kt[j], out=ek)
                    ek *= iref[j]
                    np.multiply(z.imag, iw, out=ec)
                    ec -= ct[j]
                    ec *= iref[8 + j]
        return err

    def run_block(self, rng, sl, W):
        Xm = self.perturb(rng, self.X[:, :, sl, None], W)        # (4, R, nb, tb)
        Q = self.measured_to_bearings(Xm, W)
        return self.identify_errors(Q, sl, W)


_ABS = np.int64(0x7FFFFFFFFFFFFFFF)
_ONE = np.uint32(1)
_LOG0 = (1023 - 20) * SUB        # (bits of |e|) >> 48 - _LOG0 = 16 E + t for x = |e| / E0 = 2^E (1 + t/16 + ...)


def _signed_magnitude(e, f1=None, f2=None, sg=None):
    """m for e >= 0 and -1 - m for e < 0 (int64, the bin minus 512), m the spec's magnitude index
    of x = |e| / E0, read from the bits of e as the core reads them: E0 = 2^-20 only shifts the
    exponent, so (bits of |e|) >> 48 holds the octave and the top four mantissa bits; below E0
    the linear floor(16 x). Twelve unmasked passes, each of one dtype, no branch: about 8x faster
    than np.frexp followed by masked (``where=``) and mixed int/float ufuncs. ``f1``, ``f2``
    (float64) and ``sg`` (int64): work arrays like e; the result is ``f1`` viewed as int64."""
    f1 = np.add(e, 0.0, out=f1)                   # -0.0 -> +0.0 (the spec: e >= 0 is the upper half)
    b = f1.view(np.int64)
    sg = np.right_shift(b, 63, out=sg)            # -1 where e < 0, else 0
    np.bitwise_and(b, _ABS, out=b)                # f1 = |e|
    f2 = np.multiply(f1, SUB / E0, out=f2)        # 16 x
    np.minimum(f2, SUB, out=f2)
    lin = f2.view(np.int64)
    np.copyto(lin, f2, casting="unsafe")          # floor(16 x) below 1, 16 above
    np.right_shift(b, 48, out=b)
    b -= _LOG0
    np.maximum(b, 0, out=b)                       # 16 E + t above 1, 0 below
    b += lin                                      # the magnitude index
    np.minimum(b, BINS // 2 - 1, out=b)
    np.bitwise_xor(b, sg, out=b)                  # m, or -1 - m below zero
    return b


def _bin_index(e):
    """The spec's bin (int64) of each finite error: 512 + m for e >= 0, 511 - m below."""
    return _signed_magnitude(np.asarray(e, float)) + BINS // 2


def bin_edges():
    """(1025,) edges of the bins, -inf and +inf at the ends."""
    m = np.arange(BINS // 2 + 1, dtype=float)
    lo = np.where(m < SUB, m / SUB, 2.0 ** ((m - SUB) // SUB) * (1 + ((m - SUB) % SUB) / SUB)) * E0
    pos = lo[:-1]
    return np.concatenate([[-np.inf], -pos[:0:-1], [0.0], pos[1:], [np.inf]])


class _Accumulator:
    """Streaming statistics of the spec: counts (n, 16, 1024) uint32 as in the core (a block's
    speeds are one contiguous slice, counted in place by np.add.at: its fast path needs the count
    and the increment of one dtype, np.uint32(1) here, else it is 40x slower), finite / non-finite
    counts, sums (16, n)."""

    def __init__(self, n):
        self.counts = np.zeros((n, 16, BINS), np.uint32)
        self.finite = np.zeros((16, n), np.int64)
        self.nonfinite = np.zeros((16, n), np.int64)
        self.sum = np.zeros((16, n))
        self.sumsq = np.zeros((16, n))

    def add(self, sl, err, base, W=None):
        """err (16, nb, tb) at speeds sl; base (16, nb, 1) int64 flat offsets of (speed, coefficient)
        plus the centre bin 512; W: the block's workspace (or None)."""
        s = err.sum(-1)
        if np.isfinite(s).all():                                 # then every error is finite
            ok = None
            self.sum[:, sl] += s
            self.sumsq[:, sl] += np.einsum("ijk,ijk->ij", err, err)
            self.finite[:, sl] += err.shape[-1]
            e = err
        else:                                                    # singular trials: the slow path
            ok = np.isfinite(err)
            e = np.where(ok, err, 0.0)
            self.sum[:, sl] += e.sum(-1)
            self.sumsq[:, sl] += np.einsum("ijk,ijk->ij", e, e)
            nf = ok.sum(-1)
            self.finite[:, sl] += nf
            self.nonfinite[:, sl] += err.shape[-1] - nf
        same = W is not None and W.err.shape == err.shape
        idx = _signed_magnitude(e, *((W.e1, W.e2, W.idx) if same else ()))
        idx += base                                              # flat (speed, coefficient, bin)
        if ok is not None:
            idx = idx[ok]
        np.add.at(self.counts[sl].reshape(-1), idx.reshape(-1), _ONE)


def percentiles_from_histogram(counts, q=PERCENTILES, rows_per_chunk=512):
    """Percentiles (len(q), ...) of histograms counts (..., 1024), linear inside the bin:
    target rank q/100 N, the first bin whose cumulative count reaches it (and holds values),
    bin start + (target - count below) / count of the bin x width; NaN where empty.

    ``rows_per_chunk`` histograms at a time (their cumulative counts stay in cache). In a chunk the
    cumulative counts of row r are offset by r (N_max + 1), which makes one increasing array, and
    a single searchsorted finds every row's bin."""
    c_all = np.asarray(counts)
    shp = c_all.shape[:-1]
    c_all = c_all.reshape(-1, c_all.shape[-1])
    nbins = c_all.shape[1]
    out = np.full((len(q), c_all.shape[0]), np.nan)
    edges = bin_edges()
    lo_e, hi_e = edges[:-1].copy(), edges[1:].copy()
    lo_e[0], hi_e[-1] = hi_e[0], lo_e[-1]
    for r0 in range(0, c_all.shape[0], rows_per_chunk):
        c = c_all[r0:r0 + rows_per_chunk]
        rows = c.shape[0]
        ar = np.arange(rows)
        cum = np.cumsum(c, axis=1, dtype=np.int64)
        N = cum[:, -1].copy()
        off = ar * (int(N.max()) + 1)
        cum += off[:, None]
        flat = cum.reshape(-1)
        for i, qq in enumerate(q):
            target = qq / 100.0 * N
            k = np.maximum(np.ceil(target), 1).astype(np.int64)     # cum >= target <=> cum >= ceil(target)
            b = np.searchsorted(flat, k + off, side="left") - ar * nbins
            ok = (N > 0) & (b < nbins)
            b = np.where(ok, b, 0)
            cb = c[ar, b].astype(float)
            below = cum[ar, b] - off - cb
            with np.errstate(invalid="ignore", divide="ignore"):
                frac = np.clip((target - below) / cb, 0.0, 1.0)
            out[i, r0:r0 + rows] = np.where(ok, lo_e[b] + frac * (hi_e[b] - lo_e[b]), np.nan)
    return out.reshape((len(q),) + shp)


def _block_shape(block, T, n):
    """(speeds per block, trials per block) for ``block`` points (or an explicit (nb, tb))."""
    if isinstance(block, tuple):
        nb, tb = block
    else:
        tb = min(T, int(block))
        nb = max(1, int(block) // tb)
    return min(nb, n), min(tb, T)


def _run(study, T, block, threads, seed, summary, q=PERCENTILES, pool=None):
    n = study.n
    nb, tb = _block_shape(block, T, n)
    acc = _Accumulator(n)
    exact = np.full((len(q), 16, n), np.nan) if summary == "exact" else None
    chunks = [slice(s, min(s + nb, n)) for s in range(0, n, nb)]

    def task(ci):
        sl = chunks[ci]
        m = sl.stop - sl.start
        base = ((np.arange(16)[:, None] + 16 * np.arange(m)[None, :]) * BINS + BINS // 2)[:, :, None]
        keep = np.empty((16, m, T)) if exact is not None else None
        for t0 in range(0, T, tb):
            t1 = min(t0 + tb, T)
            W = _workspace(study.R, m, t1 - t0)
            rng = np.random.Generator(np.random.SFC64([seed, ci, t0]))
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):   # singular points: NaN
                err = study.run_block(rng, sl, W)
            if exact is None:
                acc.add(sl, err, base, W)
            else:
                keep[:, :, t0:t1] = err
        if exact is not None:
            ok = np.isfinite(keep)
            fn = np.percentile if ok.all() else np.nanpercentile
            exact[:, :, sl] = fn(keep, q, axis=-1, method="inverted_cdf")
            acc.finite[:, sl] = ok.sum(-1)
            acc.nonfinite[:, sl] = T - ok.sum(-1)
            kz = np.where(ok, keep, 0.0)
            acc.sum[:, sl] = kz.sum(-1)
            acc.sumsq[:, sl] = (kz * kz).sum(-1)

    if threads <= 1:
        for ci in range(len(chunks)):
            task(ci)
    else:
        own = pool is None
        ex = pool or ThreadPoolExecutor(threads)
        try:
            for _ in ex.map(task, range(len(chunks))):
                pass
        finally:
            if own:
                ex.shutdown()
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = acc.sum / acc.finite
        rms = np.sqrt(acc.sumsq / acc.finite)
    pct = np.swapaxes(exact, 1, 2) if exact is not None else percentiles_from_histogram(acc.counts, q)
    # report layout: (len(q), n, 16), (n, 16), (n, 16, 1024)
    return {"percentiles": pct, "mean": mean.T, "rms": rms.T, "finite": acc.finite.T, "nonfinite": acc.nonfinite.T,
            "counts": None if exact is not None else acc.counts}


# ---------------------------------------------------------------------------------------------
# the two studies

# sin of a small angle: x P(x^2), the Taylor series with as many terms as the largest |x| of the
# block needs for double precision (the first omitted term below 2^-53 |x|: 5 terms for the 0.5 deg
# phase errors, whose |x| stays under 0.06 rad; 7 at SMALL_ANGLE); cos = sqrt(1 - sin^2) (|x| < pi/2).
# Larger angles fall back to np.sin/np.cos.
SMALL_ANGLE = 0.2
_SIN_COEF = tuple((-1.0) ** k / float(np.prod(np.arange(1, 2 * k + 2))) for k in range(8))


def _sin_terms(amax):
    """Terms of the sine series for |x| <= amax: the first omitted term |x|^(2K+1)/(2K+1)! < 2^-53 |x|."""
    k = 1
    while k < len(_SIN_COEF) - 1 and amax ** (2 * k) * abs(_SIN_COEF[k]) >= 2.0 ** -53:
        k += 1
    return k


def _sincos_into(phi, sin_out, cos_out, tmp1, tmp2):
    """sin and cos of phi (real array) into sin_out, cos_out; tmp1, tmp2: work arrays like phi."""
    amax = max(float(phi.max(initial=0.0)), -float(phi.min(initial=0.0)))
    if not amax <= SMALL_ANGLE:                   # (NaN too)
        np.sin(phi, out=sin_out)
        np.cos(phi, out=cos_out)
        return
    coef = _SIN_COEF[:_sin_terms(amax)]
    x2 = np.multiply(phi, phi, out=tmp1)
    if len(coef) == 1:
        np.copyto(sin_out, phi)
    else:
        acc = np.multiply(x2, coef[-1], out=tmp2)
        for c in coef[-2:0:-1]:
            acc += c
            acc *= x2
        acc += coef[0]
        np.multiply(acc, phi, out=sin_out)
    np.multiply(sin_out, sin_out, out=x2)
    np.subtract(1.0, x2, out=x2)
    np.sqrt(x2, out=cos_out)


def _amp_phase_perturb(amplitude_rel, phase_deg):
    a = float(amplitude_rel)
    ph = float(np.deg2rad(phase_deg))

    def perturb(rng, X, W):
        """X (4, R, nb, 1) -> W.f = X (1 + a n1) e^{j ph n2}, (4, R, nb, tb)."""
        rng.standard_normal(out=W.nrm)
        amp, phi = W.nrm[0], W.nrm[1]
        amp *= a
        amp += 1.0
        phi *= ph
        _sincos_into(phi, W.r1, W.r2, W.r3, W.r4)
        f = W.f
        np.multiply(W.r2, amp, out=f.real)                       # real ops into the strided halves
        np.multiply(W.r1, amp, out=f.imag)
        f *= X
        return f

    return perturb


def _frf_perturb(eps):
    def perturb(rng, X, W):
        """X (4, R, nb, 1) -> W.f = X (1 + eps (n_re + j n_im))."""
        f = W.f
        rng.standard_normal(out=f.view(float).reshape(W.shape + (2,)))   # n_re + j n_im
        f *= eps
        f += 1.0
        f *= X
        return f

    return perturb


def numpy_sync_study(rotor_params, kb, cb, speed_rad, u, planes_z, probes_z, amplitude_rel, phase_deg, trials,
                     block=4096, threads=1, seed=0, summary="histogram", q=PERCENTILES, pool=None):
    """Synchronous study with 1X amplitude and phase errors only. kb, cb (n, 8) [bearing][i][j];
    speed_rad (n,); u (R, 2) nominal m r e^{-j phi}; planes_z (2,); probes_z (4,) channel positions
    (x1, x2, y1, y2); trials: count. Returns a dict: percentiles (len(q), n, 16) in report order,
    mean, rms, finite, nonfinite (n, 16), counts (n, 16, 1024) (histogram summary)."""
    p = np.asarray(rotor_params, float)
    l1, l2 = float(p[3]), float(p[4])
    om = np.asarray(speed_rad, float)
    kb = np.broadcast_to(np.asarray(kb, float), (om.size, 8))
    cb = np.broadcast_to(np.asarray(cb, float), (om.size, 8))
    u = np.asarray(u, complex)
    S = u[:, 0] + u[:, 1]
    Mo = planes_z[0] * u[:, 0] + planes_z[1] * u[:, 1]
    e = np.stack([S, -1j * S, Mo, 1j * Mo], axis=-1)            # (R, 4), eq. 4
    qb = _true_responses(p, kb, cb, om, om, e, om ** 2)
    X = _channels(qb, l1, l2, np.asarray(probes_z, float))
    study = _Study(p, kb, cb, om, om, om ** 2, e, X, np.asarray(probes_z, float),
                   _amp_phase_perturb(amplitude_rel, phase_deg))
    return _run(study, int(trials), block, threads, seed, summary, q, pool)


def impact_vector(plane, direction):
    return np.array([1.0, 0.0, plane, 0.0]) if direction == "x" else np.array([0.0, 1.0, 0.0, -plane])


def numpy_impact_study(rotor_params, kb, cb, spin_rad, w_rad, tests, probes_z, coherence, impacts, trials,
                       block=4096, threads=1, seed=0, summary="histogram", q=PERCENTILES, pool=None):
    """Impact study with the FRF random error of coherence and impacts only (ε of the spec).
    kb, cb (n, 8) at each frequency w_rad (n,); spin_rad the running speed; tests [(plane_z, "x"|"y")]."""
    p = np.asarray(rotor_params, float)
    l1, l2 = float(p[3]), float(p[4])
    w = np.asarray(w_rad, float)
    kb = np.broadcast_to(np.asarray(kb, float), (w.size, 8))
    cb = np.broadcast_to(np.asarray(cb, float), (w.size, 8))
    spin = np.full(w.size, float(spin_rad))
    e = np.array([impact_vector(z, d) for z, d in tests], complex)
    qb = _true_responses(p, kb, cb, w, spin, e, np.ones(w.size))
    X = _channels(qb, l1, l2, np.asarray(probes_z, float))
    eps = np.sqrt((1.0 - coherence) / (2.0 * impacts * coherence))
    study = _Study(p, kb, cb, w, spin, np.ones(w.size), e, X, np.asarray(probes_z, float), _frf_perturb(eps))
    return _run(study, int(trials), block, threads, seed, summary, q, pool)


# ---------------------------------------------------------------------------------------------
# script: checks against the oracle and timings

def _nsf(n_speeds, runs, lo_rpm=1000.0, hi_rpm=7000.0):
    import rotorid

    rig = rotorid.nsf_rig()
    rot = rig.rotor
    om = np.linspace(lo_rpm, hi_rpm, n_speeds) * np.pi / 30
    names = "ABCD"[:runs]
    u = np.array([rig.imbalances[x].forcing(rot) for x in names])
    kb = np.tile(rig.bearings.k.reshape(8), (n_speeds, 1))
    cb = np.tile(rig.bearings.c.reshape(8), (n_speeds, 1))
    planes = np.array([-rot.d1, rot.d2])
    probes = np.array([-rot.s1, rot.s2, -rot.s1, rot.s2])
    return rot.core_params(), kb, cb, om, u, planes, probes, rig


def _z_summary(a, b, se):
    z = (a - b) / (np.sqrt(2.0) * se)
    return (f"mean z {z.mean():+.3f}, rms z {np.sqrt((z ** 2).mean()):.3f}, max |z| {np.abs(z).max():.2f}, "
            f"|z| > 3: {100 * (np.abs(z) > 3).mean():.2f} %")


def check_against_oracle(trials=1000, points=20, seed=11):
    """Percentiles, means and rms of this baseline vs the spec's oracle (tests/study_oracle.py) and
    vs rotorid's study: the same statistics with different random numbers, so they agree within
    Monte Carlo error. z = difference / (sqrt(2) x the oracle's bootstrap standard error); the
    control line compares the oracle with itself under another seed. rotorid with the oracle's
    seed draws the oracle's random numbers (counter-based, docs/studies.md), so those two agree
    to rounding (a percentile may move by one bin where a rounding difference crosses an edge)."""
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))
    import study_oracle as so
    from rotorid.studies import ImpactErrors, SyncErrors, impact_study, synchronous_study

    p, kb, cb, om, u, planes, probes, rig = _nsf(points, 4)
    f_hz = np.linspace(20.0, 200.0, points)
    w = 2 * np.pi * f_hz
    tests = [(0.0, "x"), (0.0, "y"), (0.05, "x"), (-0.08, "y")]
    spin = 3000 * np.pi / 30
    imbs = [rig.imbalances[x] for x in "ABCD"]
    cases = [
        (f"synchronous, NSF rig, {points} speeds 1000-7000 rpm, 4 runs, amplitude 1 %, phase 0.5 deg",
         lambda sd: so.sync_errors(p, kb, cb, om, u, planes, probes, {"amplitude_rel": 0.01, "phase_deg": 0.5}, sd,
                                   range(trials)),
         lambda: numpy_sync_study(p, kb, cb, om, u, planes, probes, 0.01, 0.5, trials, 4096, 1, 3),
         lambda sd: synchronous_study(rig.rotor, rig.bearings, imbs, om * 30 / np.pi,
                                      SyncErrors(amplitude_rel=0.01, phase_deg=0.5), trials=trials, seed=sd)),
        (f"impact, NSF rig at 3000 rpm, {points} frequencies 20-200 Hz, 4 tests, coherence 0.95, 5 impacts",
         lambda sd: so.impact_errors(p, kb, cb, spin, w, tests, probes, {"coherence": 0.95, "impacts": 5}, sd,
                                     range(trials)),
         lambda: numpy_impact_study(p, kb, cb, spin, w, tests, probes, 0.95, 5, trials, 4096, 1, 3),
         lambda sd: impact_study(rig.rotor, rig.bearings, tests, f_hz, ImpactErrors(coherence=0.95, impacts=5),
                                 speed_rpm=3000, trials=trials, seed=sd)),
    ]
    rng = np.random.default_rng(0)
    for name, oracle, base, ours in cases:
        err, err2 = oracle(seed), oracle(seed + 1)
        po, mo, ro, _ = so.summary(err)
        po2, mo2, ro2, _ = so.summary(err2)
        boots = np.array([np.percentile(err[rng.integers(0, trials, trials)], PERCENTILES, axis=0,
                                        method="inverted_cdf") for _ in range(200)])
        se = boots.std(0)
        sm = err.std(0) / np.sqrt(trials)
        rb = base()
        rr, rr_same = ours(seed + 2), ours(seed)
        print(name)
        print(f"  5/50/95 percentiles, baseline vs oracle:      {_z_summary(rb['percentiles'], po, se)}")
        print(f"  5/50/95 percentiles, baseline vs rotorid:     {_z_summary(rb['percentiles'], rr.pct, se)}")
        print(f"  5/50/95 percentiles, oracle vs oracle seed+1: {_z_summary(po2, po, se)}  (control)")
        print(f"  means, baseline vs oracle:                    {_z_summary(rb['mean'], mo, sm)}")
        print(f"  means, baseline vs rotorid:                   {_z_summary(rb['mean'], rr.mean, sm)}")
        print(f"  means, oracle vs oracle seed+1:               {_z_summary(mo2, mo, sm)}  (control)")
        for lab, r in (("baseline / oracle", rb["rms"]), ("baseline / rotorid", rr.rms), ("oracle+1 / oracle", ro2)):
            d = np.abs(r / ro - 1) if lab != "baseline / rotorid" else np.abs(rb["rms"] / rr.rms - 1)
            print(f"  rms, {lab} - 1: median {np.median(d):.4f}, max {d.max():.4f}"
                  + ("  (control)" if lab.startswith("oracle") else ""))
        dp = np.abs(rr_same.pct - po) / np.maximum(np.abs(po), 1e-300)
        print(f"  rotorid vs oracle, same seed (same random numbers): percentiles max rel. diff {dp.max():.1e}, "
              f"means {np.abs(rr_same.mean - mo).max() / np.abs(mo).max():.1e}, "
              f"rms {np.abs(rr_same.rms / ro - 1).max():.1e}")
        print(f"  non-finite errors: baseline {int(rb['nonfinite'].sum())}, oracle {int((~np.isfinite(err)).sum())}, "
              f"rotorid {int(np.round(rr.singular * trials).sum())}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=1000)
    ap.add_argument("--speeds", type=int, default=1000)
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--blocks", default="4000,8000,16000", help="points (speeds x trials) per block to try")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--amplitude-rel", type=float, default=0.01)
    ap.add_argument("--phase-deg", type=float, default=0.5)
    ap.add_argument("--impact", action="store_true", help="also time the impact study (same sizes)")
    ap.add_argument("--check", action="store_true", help="compare with the oracle (1000 trials, 20 points)")
    args = ap.parse_args()
    try:
        from threadpoolctl import threadpool_limits
        _lim = threadpool_limits(1)  # noqa: F841  (BLAS only sees tiny matrices; idle BLAS threads steal a core)
    except ImportError:
        pass
    if args.check:
        check_against_oracle()
        print()
    p, kb, cb, om, u, planes, probes, _ = _nsf(args.speeds, args.runs)
    work = f"{args.trials} trials x {args.speeds} speeds x {args.runs} runs"
    print(f"NumPy {np.__version__}, {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}")
    threads = [int(t) for t in args.threads.split(",")]
    pool = ThreadPoolExecutor(max(threads)) if max(threads) > 1 else None
    studies = [("synchronous", lambda blk, thr: numpy_sync_study(
        p, kb, cb, om, u, planes, probes, args.amplitude_rel, args.phase_deg, args.trials, blk, thr, 1, pool=pool))]
    if args.impact:
        w = 2 * np.pi * np.linspace(10.0, 300.0, args.speeds)
        tests = [(0.0, "x"), (0.0, "y"), (0.05, "x"), (-0.08, "y")][:args.runs]
        studies.append(("impact", lambda blk, thr: numpy_impact_study(
            p, kb, cb, 3000 * np.pi / 30, w, tests, probes, 0.95, 5, args.trials, blk, thr, 1, pool=pool)))
    best = {}
    for name, fn in studies:
        print(f"{name} study, {work}, streaming histogram summary; best of {args.repeat}")
        for thr in threads:
            times = {}
            for blk in (int(b) for b in args.blocks.split(",")):
                ts = []
                for _ in range(args.repeat):
                    t0 = time.perf_counter()
                    fn(blk, thr)
                    ts.append(time.perf_counter() - t0)
                times[blk] = min(ts)
            b = min(times, key=times.get)
            best[(name, thr)] = (b, times[b])
            tune = ", ".join(f"{k}: {v:.3f} s" for k, v in times.items())
            print(f"  {thr} thread(s): best block {b} ({_block_shape(b, args.trials, args.speeds)} speeds x trials) "
                  f"{times[b]:.3f} s = {1e9 * times[b] / (args.trials * args.speeds):.0f} ns per trial-speed   "
                  f"[{tune}]", flush=True)
    if pool is not None:
        pool.shutdown()
    return best


if __name__ == "__main__":
    main()
