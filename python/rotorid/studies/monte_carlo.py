"""Monte Carlo studies of identification accuracy for imbalance and impact tests.

Each trial simulates the test with random measurement errors (:mod:`rotorid.studies.errors`,
docs/studies.md), identifies the coefficients as rotorid identifies measured data, and adds the
16 relative errors of every point to streaming histograms, all inside the core. Python only cuts
the work into tasks (blocks of ``TRIAL_BLOCK`` trials x at most ``POINT_BLOCK`` points), runs them
on local threads or a Dask cluster, and merges them in a fixed order, so the result is the same
for the same seed whichever way it ran.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field

import numpy as np

from .. import _core
from .._corecall import core
from .._validate import choice, index, instance, number, real_array, seed as check_seed
from ..errors import IdentifiabilityError, RotoridError
from ..model import REPORT_ORDER, BearingCoefficients, Imbalance, RigidRotor
from ..simulate import RPM, _check_model, _core_coeffs
from .errors import ImpactErrors, SyncErrors

#: trials per core call; a fixed size, so that the sums merge in the same order on any machine
TRIAL_BLOCK = 1024
#: points per core call (the histograms of one call: POINT_BLOCK x 16 x 1024 x 4 bytes = 32 MB per
#: worker); the points are processed one range after the other
POINT_BLOCK = 512
#: at most this many trials (a study of more is a mistake, not a plan)
MAX_TRIALS = 10 ** 9
#: at most this many points
MAX_POINTS = 100_000
DEFAULT_PERCENTILES = (5.0, 50.0, 95.0)


# --------------------------------------------------------------------------------------------
# specification of one study: what the core needs, picklable for Dask workers


@dataclass(frozen=True)
class _Spec:
    kind: str
    rotor_params: np.ndarray
    w: np.ndarray
    kb: np.ndarray
    cb: np.ndarray
    probes_z: np.ndarray
    planes_z: np.ndarray
    errors: np.ndarray
    u: np.ndarray | None
    dirs: np.ndarray | None
    spin: float
    method: str
    seed: int

    def _arrays(self):
        """The arrays as the core takes them: C-contiguous and aligned (a spec shipped to a Dask
        worker may arrive as views into a receive buffer that are neither)."""
        def c(a):
            return None if a is None else np.require(a, requirements=["C", "A"])

        return (c(self.rotor_params), c(self.w), c(self.kb), c(self.cb), c(self.probes_z), c(self.planes_z),
                c(self.errors), c(self.u), c(self.dirs))

    def accumulate(self, t0, t1, p0, p1, counts=None):
        rp, w, kb, cb, pz, plz, err, u, dirs = self._arrays()
        return core.study_accumulate(rp, w, kb, cb, pz, plz, err, t0, t1, p0, p1, u=u, dirs=dirs, spin=self.spin,
                                     method=self.method, seed=self.seed, counts=counts)

    def realize(self, t0, t1):
        rp, w, kb, cb, pz, plz, err, u, dirs = self._arrays()
        return core.study_realize(rp, w, kb, cb, pz, plz, err, t0, t1, u=u, dirs=dirs, spin=self.spin, seed=self.seed)


def _run_task(spec: _Spec, t0: int, t1: int, p0: int, p1: int):
    """One task (top level, so that Dask can ship it): trials t0..t1 at points p0..p1."""
    return spec.accumulate(t0, t1, p0, p1)


# --------------------------------------------------------------------------------------------
# the result


@dataclass
class StudyResult:
    """Summary of a Monte Carlo study: the distribution of each coefficient's relative error at
    each point (speed or frequency).

    Errors are signed and relative: (identified - true) / |true| (for a zero true coefficient:
    divided by the mean |direct coefficient| of the same kind and bearing). Arrays are (n, 16)
    with the coefficients in the report's order (``REPORT_ORDER``); ``pct`` is
    (len(percentiles), n, 16). ``singular``: fraction of trials without a finite estimate.
    ``coverage``: fraction of the identification's confidence intervals (``level``) that held the
    true value, over the first ``coverage_trials`` trials (NaN where no interval was finite).
    """

    kind: str
    axis_name: str
    axis: np.ndarray
    trials: int
    seed: int
    errors: object
    percentiles: tuple
    pct: np.ndarray
    mean: np.ndarray
    rms: np.ndarray
    singular: np.ndarray
    method: str = "forces"
    runs: tuple = ()
    coverage: np.ndarray | None = None
    coverage_trials: int = 0
    level: float = 0.95
    counts: np.ndarray | None = field(default=None, repr=False)

    names = REPORT_ORDER

    def percentile(self, q: float) -> np.ndarray:
        """The ``q``-th percentile of the errors, (n, 16), from the merged histograms (or the stored
        percentiles when the histograms were not kept)."""
        q = _check_percentiles([q])[0]
        if q in self.percentiles:
            return self.pct[self.percentiles.index(q)]
        if self.counts is None:
            raise RotoridError(f"percentile {q:g} was not computed and the histograms were not kept "
                               f"(computed: {self.percentiles})")
        return percentiles_from_counts(self.counts, [q])[0]

    def to_dataframe(self):
        """One row per point and coefficient: axis, coefficient, percentiles, mean, rms, singular
        fraction and coverage."""
        import pandas as pd

        n = self.axis.size
        d = {self.axis_name: np.repeat(self.axis, 16), "coefficient": np.tile(np.array(self.names), n)}
        for q, p in zip(self.percentiles, self.pct):
            d[f"p{q:g}"] = p.ravel()
        d["mean"] = self.mean.ravel()
        d["rms"] = self.rms.ravel()
        d["singular"] = self.singular.ravel()
        if self.coverage is not None:
            d[f"coverage_{self.level:g}"] = self.coverage.ravel()
        return pd.DataFrame(d)

    def band_summary(self, bands=None):
        """Median over the points of each band of the central spread (p95 - p5) / 2 of each coefficient
        group (direct / cross-coupled K and C), and the coverage: one row per band. ``bands``:
        list of (lo, hi) in the axis unit; default: four equal bands."""
        import pandas as pd

        if bands is None:
            edges = np.linspace(self.axis.min(), self.axis.max(), 5)
            bands = list(zip(edges[:-1], edges[1:]))
        lo_i = self.percentiles.index(min(self.percentiles))
        hi_i = self.percentiles.index(max(self.percentiles))
        spread = 0.5 * (self.pct[hi_i] - self.pct[lo_i])
        groups = dict(K_direct=[0, 1, 6, 7], K_cross=[2, 3, 4, 5], C_direct=[8, 9, 14, 15], C_cross=[10, 11, 12, 13])
        rows = []
        last = max(hi for _, hi in bands)
        for lo, hi in bands:
            # [lo, hi): a point on the edge between two bands counts once (the last band is closed)
            s = (self.axis >= lo) & ((self.axis < hi) | ((hi == last) & (self.axis <= hi)) | (self.axis == lo))
            if not s.any():
                continue
            row = {f"{self.axis_name}_from": lo, f"{self.axis_name}_to": hi, "points": int(s.sum())}
            for g, idx in groups.items():
                row[g] = float(np.nanmedian(spread[s][:, idx]))
            if self.coverage is not None:
                row["coverage"] = float(np.nanmean(self.coverage[s]))
            rows.append(row)
        return pd.DataFrame(rows)


# --------------------------------------------------------------------------------------------
# histograms -> percentiles

_EDGES = None


def bin_edges() -> np.ndarray:
    """Edges of the core's error histograms, (BINS + 1,), from -inf to +inf (docs/studies.md)."""
    global _EDGES
    if _EDGES is None:
        _EDGES = _core.study_bin_edges()
    return _EDGES


def _check_percentiles(percentiles):
    try:
        p = np.atleast_1d(np.asarray(percentiles))
    except (TypeError, ValueError):
        raise RotoridError(f"percentiles must be numbers between 0 and 100, got {percentiles!r}") from None
    if p.size and p.dtype.kind not in "iuf":  # not strings ("50" would pass as a float)
        raise RotoridError(f"percentiles must be numbers between 0 and 100, got {percentiles!r}")
    p = p.astype(float)
    if p.ndim != 1 or p.size == 0 or p.size > 99:
        raise RotoridError(f"percentiles must be a non-empty list of at most 99 numbers, got {percentiles!r}")
    if not np.all(np.isfinite(p)) or np.any(p < 0) or np.any(p > 100):
        raise RotoridError(f"percentiles must be between 0 and 100, got {percentiles!r}")
    return tuple(float(v) for v in p)


def percentiles_from_counts(counts, percentiles) -> np.ndarray:
    """Percentiles (len(percentiles), ...) of histograms ``counts`` (..., BINS): the bin holding the
    rank, then linear interpolation inside it (the end bins, open on one side, give their finite
    edge). NaN where a histogram is empty."""
    edges = bin_edges()
    counts = np.asarray(counts)
    if counts.ndim < 1 or counts.shape[-1] != edges.size - 1 or counts.dtype.kind not in "iu":
        raise RotoridError(f"counts must be integer histograms with {edges.size - 1} bins on the last axis "
                           f"(rotorid.studies.bin_edges()), got {counts.dtype} {counts.shape}")
    if counts.dtype.kind == "i" and counts.size and counts.min() < 0:
        raise RotoridError("counts must be >= 0")
    percentiles = _check_percentiles(percentiles)
    shape = counts.shape[:-1]
    # the core reads uint32 (the studies' own counts) or uint64 histograms in place; other
    # integer types (already checked >= 0) as uint64. One pass per histogram, without the GIL:
    # the NumPy version (cumsum, then a comparison per percentile) took 0.15 s for the 512 x 16
    # histograms of one point range, serial between the ranges' parallel work.
    flat = np.ascontiguousarray(counts if counts.dtype == np.uint32 else counts.astype(np.uint64, copy=False))
    out = _core.study_percentiles(flat, np.asarray(percentiles, dtype=float))
    return out.reshape((len(percentiles),) + shape)


# --------------------------------------------------------------------------------------------
# running the tasks: local threads or a Dask cluster, merged in a fixed order


class _Progress:
    def __init__(self, total, enabled, what):
        self.total, self.done, self.enabled, self.what = total, 0, enabled, what

    def step(self, n):
        self.done += n
        if self.enabled:
            pct = 100.0 * self.done / max(self.total, 1)
            bar = "#" * int(pct / 5)
            sys.stderr.write(f"\r{self.what} [{bar:<20}] {pct:5.1f} %")
            if self.done >= self.total:
                sys.stderr.write("\n")
            sys.stderr.flush()


def _client(client):
    """A dask.distributed Client from a client or a scheduler address (within seconds)."""
    if client is None:
        return None
    if isinstance(client, str):
        try:
            from dask.distributed import Client
        except ImportError:
            raise RotoridError("a scheduler address needs dask.distributed (pip install 'rotorid[dask]')") from None
        if not client.strip():
            # never Client(""): depending on the dask version an empty address may start a local cluster
            raise RotoridError("the Dask scheduler address is empty (e.g. 'tcp://scheduler:8786')")
        try:
            return Client(client, timeout="10s")
        except Exception as exc:  # OSError, TimeoutError, ValueError (a malformed address), ...
            raise RotoridError(f"cannot reach the Dask scheduler at {client!r}: {type(exc).__name__}: {exc}") from None
    if type(client).__name__ != "Client" or not hasattr(client, "submit"):
        raise RotoridError(f"client must be a dask.distributed.Client or a scheduler address, got "
                           f"{type(client).__name__}")
    if getattr(client, "status", None) in ("closing", "closed"):
        raise RotoridError(f"the Dask client is {client.status}: pass an open client or a scheduler address")
    return client


def _tasks(trials, n):
    """The study's tasks, (t0, t1, p0, p1): point ranges of POINT_BLOCK, each cut into trial blocks
    of TRIAL_BLOCK (the merge order of the sums)."""
    return [(t0, min(t0 + TRIAL_BLOCK, trials), p0, min(p0 + POINT_BLOCK, n))
            for p0 in range(0, n, POINT_BLOCK) for t0 in range(0, trials, TRIAL_BLOCK)]


#: local worker threads (None: one per CPU); each adds its tasks' counts into its own array
LOCAL_WORKERS = None


class _Totals:
    """Per-point totals of a study, added to in task order: finite and non-finite counts, sums of
    the errors and of their squares; and the progress bar."""

    def __init__(self, n, bar):
        self.finite = np.zeros((n, 16), np.int64)
        self.nonfinite = np.zeros((n, 16), np.int64)
        self.s1 = np.zeros((n, 16))
        self.s2 = np.zeros((n, 16))
        self.bar = bar

    def add(self, p0, p1, t0, t1, f, nf, a, b):
        self.finite[p0:p1] += f
        self.nonfinite[p0:p1] += nf
        self.s1[p0:p1] += a
        self.s2[p0:p1] += b
        self.bar.step((t1 - t0) * (p1 - p0))


def _execute(spec: _Spec, trials: int, progress: bool, client, what: str, percentiles, keep_histograms):
    """Run every task, one point range after the other, and merge: percentiles (P, n, 16) read
    from the merged histograms of each range, counts (n, 16, BINS) uint32 if kept (else None),
    finite, nonfinite, sum, sumsq (n, 16). The counts are integers (merged in any order); the
    sums are merged in task order, so the result is the same on any number of threads or workers.
    Memory: the histograms of one point range per worker, whatever the trial count."""
    n = spec.w.size
    pct = np.full((len(percentiles), n, 16), np.nan)
    counts_all = np.zeros((n, 16, _core.STUDY_BINS), np.uint32) if keep_histograms else None
    tot = _Totals(n, _Progress(trials * n, progress, what))
    cl = _client(client)
    try:
        _ranges(spec, trials, cl, counts_all, pct, percentiles, tot)
    finally:
        if cl is not None and isinstance(client, str):
            cl.close()  # a client rotorid opened from an address; a user's client stays open
    return pct, counts_all, tot.finite, tot.nonfinite, tot.s1, tot.s2


def _ranges(spec, trials, cl, counts_all, pct, percentiles, tot):
    """Every point range in turn: its trial blocks on local threads (counts added into one array
    per worker thread) or on the cluster ``cl``, then its percentiles."""
    import concurrent.futures as cf
    import os
    import threading

    n = spec.w.size
    bins = _core.STUDY_BINS
    spec_f = None if cl is None else cl.scatter(spec, broadcast=True, hash=False)  # once, kept to the end
    ranges = [(p0, min(p0 + POINT_BLOCK, n)) for p0 in range(0, n, POINT_BLOCK)]
    blocks = [(t0, min(t0 + TRIAL_BLOCK, trials)) for t0 in range(0, trials, TRIAL_BLOCK)]
    for p0, p1 in ranges:
        shape = (p1 - p0, 16, bins)
        if cl is None:
            accs, lock = {}, threading.Lock()

            def task(t0, t1, p0=p0, p1=p1, shape=shape):
                tid = threading.get_ident()
                with lock:
                    acc = accs.get(tid)
                    if acc is None:
                        acc = accs[tid] = np.zeros(shape, np.uint32)
                return spec.accumulate(t0, t1, p0, p1, counts=acc)[1:]

            workers = max(1, min(len(blocks), LOCAL_WORKERS or os.cpu_count() or 1))
            with cf.ThreadPoolExecutor(workers) as ex:
                pending = []
                for t0, t1 in blocks:
                    pending.append((t0, t1, ex.submit(task, t0, t1)))
                    if len(pending) >= 2 * workers:
                        a0, a1, f = pending.pop(0)
                        tot.add(p0, p1, a0, a1, *f.result())
                for a0, a1, f in pending:
                    tot.add(p0, p1, a0, a1, *f.result())
            counts = None
            for acc in accs.values():
                if counts is None:
                    counts = acc
                else:
                    counts += acc
        else:
            counts = np.zeros(shape, np.uint32)

            def merge(t0, t1, res, p0=p0, p1=p1, counts=counts):
                counts += res[0]
                tot.add(p0, p1, t0, t1, *res[1:])

            _run_on_cluster(cl, spec_f, blocks, p0, p1, merge)
        pct[:, p0:p1] = percentiles_from_counts(counts, percentiles)
        if counts_all is not None:
            counts_all[p0:p1] = counts


def _run_on_cluster(cl, spec_f, blocks, p0, p1, merge):
    """The trial blocks of one point range on a Dask cluster (``spec_f``: the scattered spec),
    merged in block order."""
    try:
        workers = max(1, len(cl.scheduler_info(n_workers=-1).get("workers", {})))
    except Exception:
        workers = 1
    window = 2 * workers
    pending = []
    try:
        for t0, t1 in blocks:
            pending.append((t0, t1, cl.submit(_run_task, spec_f, t0, t1, p0, p1, pure=False)))
            if len(pending) >= window:
                a0, a1, f = pending.pop(0)
                merge(a0, a1, f.result(timeout=3600))
                f.release()
        for a0, a1, f in pending:
            merge(a0, a1, f.result(timeout=3600))
            f.release()
    except RotoridError:
        raise
    except Exception as exc:
        raise RotoridError(f"the Dask cluster failed to run the study: {type(exc).__name__}: {exc}") from None


def _summarize(kind, axis_name, axis, trials, seed, errors, method, runs, percentiles, merged):
    pct, counts, finite, nonfinite, s1, s2 = merged
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(finite > 0, s1 / np.maximum(finite, 1), np.nan)
        rms = np.where(finite > 0, np.sqrt(s2 / np.maximum(finite, 1)), np.nan)
    singular = nonfinite / np.maximum(finite + nonfinite, 1)
    return StudyResult(kind=kind, axis_name=axis_name, axis=axis, trials=trials, seed=seed, errors=errors,
                       percentiles=percentiles, pct=pct, mean=mean, rms=rms, singular=singular, method=method,
                       runs=tuple(runs), counts=counts)


# --------------------------------------------------------------------------------------------
# argument checks shared by both studies


def _common(trials, seed, method, percentiles, coverage_trials, level, progress, keep_histograms):
    trials = index("trials", trials, 1, MAX_TRIALS)
    seed = check_seed("seed", seed)
    if seed >= 2 ** 64:
        raise RotoridError(f"seed must be below 2**64, got {seed}")
    choice("method", method, {"forces", "report"})
    percentiles = _check_percentiles(percentiles)
    coverage_trials = index("coverage_trials", coverage_trials, 0, 100_000)
    level = number("level", level)
    if not 0 < level < 1:
        raise RotoridError(f"level must be a confidence level between 0 and 1 (e.g. 0.95), got {level:g}")
    for name, v in (("progress", progress), ("keep_histograms", keep_histograms)):
        if not isinstance(v, (bool, np.bool_)):
            raise RotoridError(f"{name} must be True or False, got {v!r}")
    return trials, seed, percentiles, coverage_trials, level


def _check_range(name, a, lo, hi, unit):
    if a.min() < lo or a.max() > hi:
        raise RotoridError(f"{name} must be between {lo:g} and {hi:g} {unit}, got {a.min():g} to {a.max():g} "
                           "(a unit error?)")


def _probes_z(rotor, at):
    choice("at", at, {"bearings", "probes"})
    if at == "probes":
        return np.array([-rotor.s1, rotor.s2, -rotor.s1, rotor.s2])
    return np.array([-rotor.l1, rotor.l2, -rotor.l1, rotor.l2])


def _report_truth(k, c):
    """(n, 16) true coefficients in report order from (n, 8) [bearing][i][j] arrays."""
    from ..model import _REPORT_TO_BIJ

    return np.concatenate([k[:, _REPORT_TO_BIJ], c[:, _REPORT_TO_BIJ]], 1)


def _coverage(idents, truth, level):
    """Fraction of intervals holding the truth, (n, 16), over identifications (NaN: none finite)."""
    hit = np.zeros(truth.shape)
    seen = np.zeros(truth.shape)
    for ident in idents:
        iv = ident.interval(level)
        n = truth.shape[0]
        from ..model import _REPORT_TO_BIJ

        lo = np.concatenate([iv.k_lower.reshape(n, 8)[:, _REPORT_TO_BIJ], iv.c_lower.reshape(n, 8)[:, _REPORT_TO_BIJ]], 1)
        hi = np.concatenate([iv.k_upper.reshape(n, 8)[:, _REPORT_TO_BIJ], iv.c_upper.reshape(n, 8)[:, _REPORT_TO_BIJ]], 1)
        ok = np.isfinite(lo) & np.isfinite(hi)
        seen += ok
        hit += ok & (lo <= truth) & (truth <= hi)
    with np.errstate(invalid="ignore"):
        return np.where(seen > 0, hit / np.maximum(seen, 1), np.nan)


def _vector_cov(x, amp_rel, phase_rad, noise_m):
    """(n, 8, 8) covariance of [Re, Im] of the four channels' vectors x (n, 4) under independent
    relative amplitude, phase and additive noise errors (the analyst's view: from measured values)."""
    n = x.shape[0]
    cov = np.zeros((n, 8, 8))
    a = np.abs(x)
    u = np.where(a > 0, x / np.where(a > 0, a, 1), 1.0)
    ur, ui = u.real, u.imag
    vr, vi = -ui, ur
    sr2 = (a * amp_rel) ** 2
    st2 = (a * phase_rad) ** 2
    sn2 = noise_m ** 2 / 2
    for j in range(4):
        cov[:, j, j] = sr2[:, j] * ur[:, j] ** 2 + st2[:, j] * vr[:, j] ** 2 + sn2
        cov[:, j + 4, j + 4] = sr2[:, j] * ui[:, j] ** 2 + st2[:, j] * vi[:, j] ** 2 + sn2
        cov[:, j, j + 4] = cov[:, j + 4, j] = sr2[:, j] * ur[:, j] * ui[:, j] + st2[:, j] * vr[:, j] * vi[:, j]
    return cov


# --------------------------------------------------------------------------------------------
# the studies


def synchronous_study(rotor: RigidRotor, bearings: BearingCoefficients, imbalances, speed_rpm,
                      errors: SyncErrors | None = None, *, trials: int = 1000, seed: int = 0, at: str = "probes",
                      method: str = "forces", percentiles=DEFAULT_PERCENTILES, coverage_trials: int = 0,
                      level: float = 0.95, client=None, progress: bool = False,
                      keep_histograms: bool = False) -> StudyResult:
    """Monte Carlo study of synchronous (imbalance) identification.

    Each trial runs the imbalance test on the true system (``rotor``, ``bearings``) with the
    ``imbalances`` (two or more runs), measures the 1X vectors ``at`` the probes or the bearings
    with the random ``errors``, identifies the 16 coefficients at every speed as
    :func:`rotorid.identify_synchronous` would, and accumulates the relative errors.

    Parameters
    ----------
    rotor, bearings : RigidRotor, BearingCoefficients
        The true system (bearing coefficients constant or tabulated over speed).
    imbalances : list of Imbalance
        The trial-mass sets of the runs (their nominal values; ``errors`` perturbs the true ones).
    speed_rpm : array_like
        The speeds of the test, rpm.
    errors : SyncErrors
        Standard deviations of every error (default: none, which gives rounding-level errors).
    trials : int
        Number of simulated tests. Memory does not grow with it.
    seed : int
        Seed of the counter-based random numbers: the same seed gives the same result on any
        number of threads or Dask workers.
    at : {"probes", "bearings"}
        Where the vectors are measured (probes: the rotor's s1, s2, moved with eq. 19).
    method : {"forces", "report"}
        Identification method.
    percentiles : sequence of float
        Percentiles of the errors to report (0-100).
    coverage_trials : int
        Also identify this many trials through :func:`rotorid.identify_synchronous` with the
        measurement covariance that the random errors imply, and report how often its ``level``
        confidence intervals held the truth. Systematic errors (keyphasor, delays, probe
        positions, trial masses, speed) are not in that covariance, so they lower the coverage.
    level : float
        Confidence level of the intervals whose coverage is measured.
    client : dask.distributed.Client or str, optional
        Run the tasks on this Dask cluster (or scheduler address); locally on threads otherwise.
    progress : bool
        Print a progress bar to stderr.
    keep_histograms : bool
        Keep the merged histograms (n x 16 x 1024 counts) for other percentiles later.

    Returns
    -------
    StudyResult

    Examples
    --------
    >>> import numpy as np, rotorid
    >>> from rotorid.studies import SyncErrors, synchronous_study
    >>> rig = rotorid.nsf_rig()
    >>> res = synchronous_study(rig.rotor, rig.bearings, [rig.imbalances[s] for s in "ABCD"],
    ...                         np.array([3500.0, 4500.0]), SyncErrors(phase_deg=0.1), trials=200, seed=1)
    >>> res.pct.shape
    (3, 2, 16)
    >>> bool(np.all(np.abs(res.percentile(50)[:, [0, 1, 6, 7]]) < 0.01))
    True
    """
    _check_model(rotor, bearings)
    errors = SyncErrors() if errors is None else instance("errors", errors, SyncErrors, what="rotorid.studies.SyncErrors")
    trials, seed, percentiles, coverage_trials, level = _common(trials, seed, method, percentiles, coverage_trials,
                                                                level, progress, keep_histograms)
    if not isinstance(imbalances, (list, tuple)) or len(imbalances) < 2 or not all(
            isinstance(i, Imbalance) for i in imbalances):
        raise RotoridError("imbalances must be a list of two or more rotorid.Imbalance (one per run)")
    rpm = real_array("speed_rpm", np.atleast_1d(speed_rpm), ndim=1, positive=True)
    if not 0 < rpm.size <= MAX_POINTS:
        raise RotoridError(f"speed_rpm has {rpm.size} speeds: 1 to {MAX_POINTS} per study")
    _check_range("speed_rpm", rpm, 1e-3, 1e6, "rpm")
    from ..identify import check_imbalance_independence

    labels = [i.name or f"run {n}" for n, i in enumerate(imbalances)]
    check_imbalance_independence(rotor, list(imbalances), labels)
    probes_z = _probes_z(rotor, at)
    n = rpm.size
    kb, cb = _core_coeffs(bearings, n, speed_rpm=rpm, broadcast=False)
    u = np.array([imb.forcing(rotor) for imb in imbalances], dtype=complex)
    spec = _Spec(kind="imbalance", rotor_params=rotor.core_params(), w=rpm * RPM, kb=kb, cb=cb, probes_z=probes_z,
                 planes_z=np.array([-rotor.d[0], rotor.d[1]]), errors=errors.core_array(), u=u, dirs=None, spin=0.0,
                 method=method, seed=seed)
    merged = _execute(spec, trials, progress, client, "synchronous study", percentiles, keep_histograms)
    res = _summarize("synchronous", "speed_rpm", rpm, trials, seed, errors, method, labels, percentiles, merged)
    if coverage_trials:
        res.coverage = _sync_coverage(spec, rotor, imbalances, rpm, errors, at, method, coverage_trials, level,
                                      _report_truth(kb, cb))
        res.coverage_trials, res.level = coverage_trials, level
    return res


def _sync_coverage(spec, rotor, imbalances, rpm, errors, at, method, trials, level, truth):
    from ..identify import identify_synchronous
    from ..simulate import SyncResponse

    e = errors.core_array()
    idents = []
    for t in range(trials):
        q, w_told = spec.realize(t, t + 1)
        told = w_told[0] / RPM
        runs = [SyncResponse(told, q[0, r], imbalance=imb, at=at, cov=_vector_cov(q[0, r], e[0], e[1], e[2]))
                for r, imb in enumerate(imbalances)]
        try:
            idents.append(identify_synchronous(rotor, runs, method=method))
        except IdentifiabilityError:
            continue
    return _coverage(idents, truth, level)


def impact_study(rotor: RigidRotor, bearings: BearingCoefficients, tests, freq_hz, errors: ImpactErrors | None = None,
                 *, speed_rpm: float, trials: int = 1000, seed: int = 0, at: str = "probes", method: str = "forces",
                 percentiles=DEFAULT_PERCENTILES, coverage_trials: int = 0, level: float = 0.95, client=None,
                 progress: bool = False, keep_histograms: bool = False) -> StudyResult:
    """Monte Carlo study of impact (frequency-domain) identification.

    Each trial measures the FRFs of the ``tests`` (two or more, each ``(plane_m, "x" | "y")``: where
    the impacts land and in which direction) at ``freq_hz`` while the rotor runs at ``speed_rpm``,
    with the random error of H1 estimates of the given coherence and impact count plus the
    systematic ``errors``, identifies as :func:`rotorid.identify_impact` would, and accumulates the
    relative errors. Other parameters as :func:`synchronous_study`.

    Examples
    --------
    >>> import numpy as np, rotorid
    >>> from rotorid.studies import ImpactErrors, impact_study
    >>> rig = rotorid.nsf_rig()
    >>> res = impact_study(rig.rotor, rig.bearings, [(0.0, "x"), (0.0, "y")], np.array([40.0, 80.0]),
    ...                    ImpactErrors(coherence=0.98, impacts=5), speed_rpm=1000, trials=200, seed=1)
    >>> res.axis_name, res.pct.shape
    ('freq_hz', (3, 2, 16))
    """
    _check_model(rotor, bearings)
    errors = ImpactErrors() if errors is None else instance("errors", errors, ImpactErrors,
                                                           what="rotorid.studies.ImpactErrors")
    trials, seed, percentiles, coverage_trials, level = _common(trials, seed, method, percentiles, coverage_trials,
                                                                level, progress, keep_histograms)
    spin_rpm = number("speed_rpm", speed_rpm, nonneg=True)
    if spin_rpm > 1e6:
        raise RotoridError(f"speed_rpm = {spin_rpm:g} is beyond 1e6 rpm (a unit error?)")
    if not isinstance(tests, (list, tuple)) or len(tests) < 2:
        raise RotoridError("tests must be a list of two or more (plane_m, direction) pairs, e.g. [(0.0, 'x'), (0.0, 'y')]")
    planes, dirs = [], []
    for i, t in enumerate(tests):
        if not isinstance(t, (list, tuple)) or len(t) != 2:
            raise RotoridError(f"tests[{i}] must be a (plane_m, direction) pair, got {t!r}")
        planes.append(number(f"tests[{i}] plane", t[0]))
        dirs.append(0 if choice(f"tests[{i}] direction", t[1], {"x", "y"}) == "x" else 1)
    if len(set(dirs)) < 2 and len(set(planes)) < 2:
        raise IdentifiabilityError("the impact tests are all in one direction at one plane: they are not independent "
                                   "(impact in x and in y, or at two planes)")
    f = real_array("freq_hz", np.atleast_1d(freq_hz), ndim=1, positive=True)
    if not 0 < f.size <= MAX_POINTS:
        raise RotoridError(f"freq_hz has {f.size} frequencies: 1 to {MAX_POINTS} per study")
    _check_range("freq_hz", f, 1e-4, 1e6, "Hz")
    probes_z = _probes_z(rotor, at)
    n = f.size
    kb, cb = _core_coeffs(bearings, n, freq_hz=f, broadcast=False)
    spec = _Spec(kind="impact", rotor_params=rotor.core_params(), w=2 * np.pi * f, kb=kb, cb=cb, probes_z=probes_z,
                 planes_z=np.array(planes, float), errors=errors.core_array(), u=None,
                 dirs=np.array(dirs, np.uint8), spin=spin_rpm * RPM, method=method, seed=seed)
    merged = _execute(spec, trials, progress, client, "impact study", percentiles, keep_histograms)
    labels = [f"{'xy'[d]} at {p:g} m" for p, d in zip(planes, dirs)]
    res = _summarize("impact", "freq_hz", f, trials, seed, errors, method, labels, percentiles, merged)
    if coverage_trials:
        res.coverage = _impact_coverage(spec, rotor, f, spin_rpm, planes, dirs, errors, at, method, coverage_trials,
                                        level, _report_truth(kb, cb))
        res.coverage_trials, res.level = coverage_trials, level
    return res


def _impact_coverage(spec, rotor, f, spin_rpm, planes, dirs, errors, at, method, trials, level, truth):
    from ..identify import identify_impact
    from ..simulate import ImpactResponse

    eps = errors.frf_rel
    idents = []
    for t in range(trials):
        h, _ = spec.realize(t, t + 1)
        tests = [ImpactResponse(speed_rpm=spin_rpm, freq_hz=f, q=h[0, r], plane=planes[r], direction="xy"[dirs[r]],
                                at=at, cov=_vector_cov(h[0, r], eps, eps, 0.0))
                 for r in range(len(planes))]
        try:
            idents.append(identify_impact(rotor, tests, method=method))
        except IdentifiabilityError:
            continue
    return _coverage(idents, truth, level)
