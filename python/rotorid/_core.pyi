"""Typed stubs of the compiled core (rust/src/lib.rs). Arrays must be C-contiguous.

Conventions: rotor = [m, I_T, I_p, l1, l2]; bearing coefficients per point as 8 values
[bearing][i][j]; responses q = [x1, x2, y1, y2]; w = vibration frequency and spin = running
speed in rad/s. Every function releases the GIL and raises ValueError on bad shapes.
"""

import numpy as np
import numpy.typing as npt

__version__: str
SIMD: str  # the SIMD level the kernels run at: avx512, avx2 or baseline (ROTORID_SIMD caps it)
SIMD_CPU: str  # the widest level this CPU supports
SPIN_US: float  # how long the pool's helpers spin after a parallel call, µs (ROTORID_SPIN_US sets it)
STEER: bool  # woken helpers kept off the caller's CPU (ROTORID_STEER=0 turns it off; Linux)

def forced_response(
    rotor: npt.NDArray[np.float64],
    k: npt.NDArray[np.float64],  # (n or 1, 8)
    c: npt.NDArray[np.float64],  # (n or 1, 8)
    spin: npt.NDArray[np.float64],  # (n,) or (1,)
    w: npt.NDArray[np.float64],  # (n,)
    force: npt.NDArray[np.complex128],  # (n or 1, nrhs, 4)
    gain: npt.NDArray[np.float64] | None = None,  # (n,): q_i scaled by gain[i]
    w_scale: float | None = None,  # w is given in another unit: w_scale * w rad/s (e.g. Hz and 2 pi)
    planes: npt.NDArray[np.float64] | None = None,  # (2, 2): every solution moved by it (as apply_planes)
) -> tuple[npt.NDArray[np.complex128], int]:
    """Solve H q = F with H = -w^2 M + j w spin G + j w C + K; returns (q (n, nrhs, 4), n_singular)."""

def apply_planes(
    t: npt.NDArray[np.float64],  # (2, 2) real plane transform (report eq. 19)
    q: npt.NDArray[np.complex128],  # (..., 4) [x1, x2, y1, y2], C-contiguous
) -> tuple[npt.NDArray[np.complex128], int | None]:
    """[x_a, x_b] = t [x1, x2] and [y_a, y_b] = t [y1, y2] at every point (same shape as q), and
    the flat index of q's first NaN or inf (None when all are finite)."""

def imbalance_response(
    rotor: npt.NDArray[np.float64],
    k: npt.NDArray[np.float64],  # (n or 1, 8)
    c: npt.NDArray[np.float64],  # (n or 1, 8)
    spin: npt.NDArray[np.float64],  # (n,) rad/s (or in another unit with spin_scale)
    force: npt.NDArray[np.complex128],  # (n or 1, nrhs, 4) generalized imbalance vectors
    spin_scale: float | None = None,  # spin_scale * spin rad/s (e.g. rpm with pi / 30)
    planes: npt.NDArray[np.float64] | None = None,  # (2, 2): every solution moved by it (as apply_planes)
) -> tuple[npt.NDArray[np.complex128], int]:
    """forced_response with w = spin and each point's solution scaled by spin^2; returns (q (n, nrhs, 4), n_singular)."""

def identify(
    rotor: npt.NDArray[np.float64],
    w: npt.NDArray[np.float64],  # (n,)
    spin: npt.NDArray[np.float64] | None,  # (n,) or (1,); None: spin = w (synchronous runs, after w_scale)
    q: npt.NDArray[np.complex128],  # (batch, runs, n, 4)
    e: npt.NDArray[np.complex128],  # (1 or batch, runs, 4)
    gain: npt.NDArray[np.float64] | None,  # (n,) or (1,): excitation at point i is e * gain[i]; None: spin^2
    identical: bool = False,
    method: str = "forces",  # or "report"
    with_std: bool = True,
    sigma: npt.NDArray[np.float64] | None = None,  # (n,) or (1,): solve at s = sigma + j w (exponential windows)
    q_ped: npt.NDArray[np.complex128] | None = None,  # as q: pedestal motion at the bearings (inertia sees q + q_ped)
    planes: npt.NDArray[np.float64] | None = None,  # (2, 2): q is at the probe planes, eq. 19 moves it to the bearings
    w_scale: float | None = None,  # w is given in another unit: w_scale * w rad/s (e.g. Hz and 2 pi)
    flag_limits: tuple[float, float, float, float] | None = None,  # (cond_max, min_rel_amplitude, max_rel_std, dof of the standard errors)
    refine_all: bool = False,  # the semi-normal equations' refinement step at every point, not only from cond 1e3 on
) -> tuple[
    npt.NDArray[np.float64],  # k (batch, n, 2, 2, 2)
    npt.NDArray[np.float64],  # c (batch, n, 2, 2, 2)
    npt.NDArray[np.float64],  # cond (batch, n, 2): inf where singular, NaN where input not finite
    npt.NDArray[np.float64],  # relative residual (batch, n)
    npt.NDArray[np.float64],  # rms response amplitude (batch, n)
    npt.NDArray[np.float64] | None,  # k standard error (batch, n, 2, 2, 2)
    npt.NDArray[np.float64] | None,  # c standard error
    npt.NDArray[np.float64] | None,  # largest relative standard error per point (batch, n)
    npt.NDArray[np.uint8] | None,  # flag codes (bit i: singular, ill-conditioned, uncertain, low amplitude), with flag_limits
    npt.NDArray[np.float64] | None,  # amplitude / its maximum over each batch row (batch, n), with flag_limits
    npt.NDArray[np.bool_] | None,  # ok = (flag code == 0) (batch, n), with flag_limits
    int,  # number of points with NaN/inf input
]: ...

def propagate(
    rotor: npt.NDArray[np.float64],
    w: npt.NDArray[np.float64],  # (n,), times w_scale if given
    spin: npt.NDArray[np.float64] | None,  # (n,) or (1,); None: spin = w (synchronous runs)
    q: list[npt.NDArray[np.complex128]],  # R arrays (n, 4) at the bearings (one problem)
    e: npt.NDArray[np.complex128],  # (1, R, 4)
    gain: npt.NDArray[np.float64] | None,  # (n,) or (1,); None: spin^2
    # (R, n, m, m): [Re q, Im q] (m = 8) or with q_ped [.., Re q_ped, Im q_ped] (16); with q_ped also
    # a list of one (cov, pedestal_cov, cross or None) of (n, 8, 8) per run; None only with calibration
    covs: npt.NDArray[np.float64] | list[tuple[npt.NDArray[np.float64], npt.NDArray[np.float64],
                                                npt.NDArray[np.float64] | None]] | None,
    identical: bool = False,
    method: str = "forces",  # or "report"
    sigma: npt.NDArray[np.float64] | None = None,
    q_ped: list[npt.NDArray[np.complex128]] | None = None,
    w_scale: float | None = None,
    shared: npt.NDArray[np.float64] | None = None,  # (n, m, m) common to every pair of runs
    bias: bool = True,
    # the accelerometers' calibration (with q_ped): (gain std, phase std rad, probe maps (R, 4, 4))
    calibration: tuple[float, float, npt.NDArray[np.float64]] | None = None,
    meas_std: bool = False,  # also the standard errors of the measurement covariance alone
) -> tuple[
    npt.NDArray[np.float64],  # Cov(p) (n, 16, 16), eq. 9 order, NaN where unknown
    npt.NDArray[np.float64] | None,  # second-order bias (n, 16), with bias
    npt.NDArray[np.uint8],  # unknown (n,): a run's covariance unknown or the estimator singular
    npt.NDArray[np.float64],  # k standard error (n, 2, 2, 2)
    npt.NDArray[np.float64],  # c standard error (n, 2, 2, 2)
    npt.NDArray[np.float64] | None,  # k standard error of the measurement alone, with meas_std and calibration
    npt.NDArray[np.float64] | None,  # c standard error of the measurement alone, likewise
]: ...

def move_covariances(
    a: npt.NDArray[np.float64],  # (8, 8) map of [Re q, Im q]
    b: npt.NDArray[np.float64] | None,  # (8, 8) map of the pedestal motion into q (q' = A q + B p)
    cov: npt.NDArray[np.float64],  # (n, 8, 8)
    pedestal_cov: npt.NDArray[np.float64] | None = None,  # (n, 8, 8), with b
    cross: npt.NDArray[np.float64] | None = None,  # (n, 8, 8) rows q, columns pedestal; None: uncorrelated
) -> tuple[
    npt.NDArray[np.float64],  # moved cov (n, 8, 8), exactly symmetric; points with a NaN all NaN
    npt.NDArray[np.float64] | None,  # moved cross (n, 8, 8), with b
]: ...

def check_covariances(
    covs: list[npt.NDArray[np.float64]],  # R arrays (n, m, m)
    m: int,
) -> tuple[
    npt.NDArray[np.float64],  # (R, n, m, m) copy, unknown matrices all NaN
    tuple[str, int, int] | None,  # first fault: ("inf" | "asymmetric" | "indefinite", array, point)
]: ...

def unknown_points(
    blocks: list[npt.NDArray[np.float64]],  # arrays of n points each (first axis)
    n: int,
) -> npt.NDArray[np.bool_]: ...  # (n,): a NaN at that point in any of them

def sample_times(n: int, dt: float) -> npt.NDArray[np.float64]: ...  # i * dt for i in 0..n

def wake_pool(max_wait_us: float = 2000.0) -> None:
    """Wake the thread pool's helpers ahead of a parallel call; they spin for at most max_wait_us
    microseconds (0 to 50,000), or until SPIN_US after the parallel calls made meanwhile."""
    ...

def first_outside(a: npt.NDArray[np.float64], lo: float, hi: float) -> int | None:
    """Index of the first value of the 1-D array a outside (lo, hi), NaN included; None if none."""
    ...

def angle_resample(
    x: npt.NDArray[np.float64] | list[npt.NDArray[np.float64]],  # (C, N), or C arrays (N,) used where they are
    fs: float, t0: float, kp: npt.NDArray[np.float64], k0: int, k1: int, p: int,
) -> npt.NDArray[np.float64]: ...  # (C, k1 - k0, p): p uniform angles per revolution k0..k1

def block_statistics(
    per_rev: npt.NDArray[np.complex128],  # (revolutions, orders, C), C >= 4
    rpm: npt.NDArray[np.float64], t_mid: npt.NDArray[np.float64],  # (revolutions,)
    starts: npt.NDArray[np.int64], lengths: npt.NDArray[np.int64],  # (blocks,): revolutions of each block
    cov_order: int | None = None, max_batches: int = 16,
) -> tuple[npt.NDArray[np.complex128], npt.NDArray[np.float64], npt.NDArray[np.float64],
           npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Per block: (mean vectors (blocks, orders, C), batch-means covariance of order ``cov_order``'s
    mean (blocks, 2C, 2C; NaN without it or for one revolution), its dof, mean rpm, mean t_mid,
    scatter of order 0 on channels 0-3 (blocks, 4)) (revolution_blocks.rs)."""
    ...


def order_vectors(
    x: npt.NDArray[np.float64] | list[npt.NDArray[np.float64]],  # as angle_resample
    fs: float, t0: float, kp: npt.NDArray[np.float64], k0: int, k1: int, p: int,
    orders: list[int],  # each from 1 to below p / 2
) -> npt.NDArray[np.complex128]:
    """Per-revolution order vectors (k1 - k0, len(orders), C), 0-pk, each revolution's drift ramp
    removed: resampling and order sums fused (order.rs::order_vectors)."""
    ...

def modal(
    rotor: npt.NDArray[np.float64],
    k: npt.NDArray[np.float64],  # (n, 8)
    c: npt.NDArray[np.float64],  # (n, 8)
    spin: npt.NDArray[np.float64],  # (n,)
) -> tuple[npt.NDArray[np.complex128], npt.NDArray[np.complex128], int]:
    """Eigenvalues with Im > 0 sorted by frequency (n, 4), mode shapes (n, 4, 4), n_failed."""

# Flexible pedestals: pedestals = [m [ped][x, y] (4); k [ped][i][j] (8); c [ped][i][j] (8)] (20,)

def forced_response_pedestal(
    rotor: npt.NDArray[np.float64],
    k: npt.NDArray[np.float64],  # (n or 1, 8) bearing coefficients
    c: npt.NDArray[np.float64],  # (n or 1, 8)
    pedestals: npt.NDArray[np.float64],  # (20,)
    spin: npt.NDArray[np.float64],  # (n,)
    w: npt.NDArray[np.float64],  # (n,)
    force: npt.NDArray[np.complex128],  # (n or 1, nrhs, 4)
    gain: npt.NDArray[np.float64] | None = None,  # (n,)
    imbalance: bool = False,  # scale by spin^2 (not with gain)
    relative: bool = False,  # journal motion relative to the pedestals instead of absolute
    w_scale: float | None = None,  # as in forced_response (spin may be (1,) too)
    planes: npt.NDArray[np.float64] | None = None,  # (2, 2) bearings -> probes, with relative=True: T q - p
) -> tuple[npt.NDArray[np.complex128], npt.NDArray[np.complex128], int]:
    """Journal (absolute, or relative: at the bearings, or at the probe planes with ``planes``) and
    pedestal motion at the bearings, each (n, nrhs, 4), n_singular."""

def effective_coefficients(
    k: npt.NDArray[np.float64],  # (n or 1, 8)
    c: npt.NDArray[np.float64],  # (n or 1, 8)
    pedestals: npt.NDArray[np.float64],  # (20,)
    w: npt.NDArray[np.float64],  # (n,)
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.complex128], int]:
    """Series bearing + pedestal: K_eff, C_eff (n, 8), transfer T = (Z + D)^-1 Z (n, 8), n_singular."""

def modal_pedestal(
    rotor: npt.NDArray[np.float64],
    k: npt.NDArray[np.float64],  # (n, 8)
    c: npt.NDArray[np.float64],  # (n, 8)
    pedestals: npt.NDArray[np.float64],  # (20,)
    spin: npt.NDArray[np.float64],  # (n,)
) -> tuple[npt.NDArray[np.complex128], npt.NDArray[np.complex128], int]:
    """8-DOF eigenvalues (n, 8), shapes (n, 8, 8) over [x1, x2, y1, y2, xp1, xp2, yp1, yp2], n_failed."""

def series_impedance(
    z_bearing: npt.NDArray[np.complex128],  # (n or 1, 2, 2)
    z_damper: npt.NDArray[np.complex128],  # (n or 1, 2, 2)
    journal_mass: npt.NDArray[np.float64],  # (n or 1,)
    w: npt.NDArray[np.float64],  # (n,) rad/s, or an axis times w_scale in rad/s
    w_scale: float = 1.0,
) -> tuple[npt.NDArray[np.complex128], int]:
    """Z_eq = Z_b - Z_b (Z_b + Z_d - w^2 m_j I)^-1 Z_b (n, 2, 2), n_singular (NaN there)."""

def identical_std(
    rotor: npt.NDArray[np.float64],
    w: npt.NDArray[np.float64],  # (n,), times w_scale if given
    spin: npt.NDArray[np.float64] | None,  # (n,) or (1,); None: spin = w (synchronous runs)
    q: npt.NDArray[np.complex128] | list[npt.NDArray[np.complex128]],  # as identify's
    e: npt.NDArray[np.complex128],  # (1 or batch, runs, 4)
    gain: npt.NDArray[np.float64] | None,  # (n,) or (1,); None: spin^2
    k: npt.NDArray[np.float64],  # (batch, n, 2, 2, 2): identify's estimate with identical=True
    c: npt.NDArray[np.float64],
    sigma: npt.NDArray[np.float64] | None = None,
    q_ped: npt.NDArray[np.complex128] | list[npt.NDArray[np.complex128]] | None = None,
    planes: npt.NDArray[np.float64] | None = None,  # (2, 2) eq. 19 transform when q is at the probe planes
    w_scale: float | None = None,
    # (2, 2) eq. 19 transform from the probe planes, where the noise is white, for q moved to the
    # bearings before the call (None: white where q is given)
    noise_planes: npt.NDArray[np.float64] | None = None,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Residual-based standard errors of identical bearings with the structure of their pooled
    equations (identify::identical): k_std, c_std (batch, n, 2, 2, 2) and each row's real dof
    (batch, n, 2) [x, y]; NaN where the estimate is not finite or no dof is left."""

def bearing_forces(
    rotor: npt.NDArray[np.float64],
    w: npt.NDArray[np.float64],
    spin: npt.NDArray[np.float64],
    q: npt.NDArray[np.complex128],  # (batch, runs, n, 4)
    e: npt.NDArray[np.complex128],  # (1 or batch, runs, 4)
    gain: npt.NDArray[np.float64] | None,  # (n,) or (1,); None: spin^2
    sigma: npt.NDArray[np.float64] | None = None,
    q_ped: npt.NDArray[np.complex128] | None = None,
    planes: npt.NDArray[np.float64] | None = None,  # (2, 2) eq. 19 transform when q is at the probe planes
) -> npt.NDArray[np.complex128]:
    """Bearing reactions from the rotor equations, (batch, runs, n, 4) as [f1x, f2x, f1y, f2y]."""

def pedestal_fit(
    rotor: npt.NDArray[np.float64],
    w: npt.NDArray[np.float64],  # times w_scale: rad/s
    spin: npt.NDArray[np.float64] | None,  # (n,) or (1,); None: spin = w (synchronous runs)
    q: list[npt.NDArray[np.complex128]] | npt.NDArray[np.complex128],  # runs of (n, 4) or (1, runs, n, 4)
    e: npt.NDArray[np.complex128],  # (1, runs, 4)
    gain: npt.NDArray[np.float64] | None,  # (n,) or (1,); None: spin^2
    q_ped: list[npt.NDArray[np.complex128]] | npt.NDArray[np.complex128],  # laid out as q
    sigma: npt.NDArray[np.float64] | None = None,
    select: npt.NDArray[np.bool_] | None = None,  # (n,) points used; None: all
    cross: bool = False,
    w_scale: float | None = None,
    covs: list[tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64] | None]] | None = None,
    shared: npt.NDArray[np.float64] | None = None,  # (n, 16, 16) common to every pair of runs
    weighted: bool = True,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.int64], npt.NDArray[np.float64], int,
           tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]] | None]:
    """Unweighted pedestal fits with HC3 covariances: (theta (4, u), cov (4, u, u), rank (4,),
    relative residual (4,), equations per fit, cov_fit), fits (pedestal, direction) = (1, x),
    (1, y), (2, x), (2, y); u = 3 [k, m, c] or 5 with the cross-coupled [k_ij, c_ij]. With
    ``covs`` (per run the (n, 8, 8) blocks cov, pedestal_cov, cross of [Re q, Im q, Re q_ped,
    Im q_ped]): cov_fit = (theta (4, u), cov (4, u, u), resid (4,)) of the weighted fits or (not
    ``weighted``) the sandwich covariances at the unweighted theta; None when a fit is rank
    deficient."""

STUDY_BINS: int  # bins of each study histogram
STUDY_E0: float  # errors below E0 are binned linearly
STUDY_SUB: int  # bins per octave above E0

def study_accumulate(
    rotor: npt.NDArray[np.float64],
    w: npt.NDArray[np.float64],  # (n,) speeds (imbalance) or frequencies (impacts), rad/s
    kb: npt.NDArray[np.float64],  # (n, 8) or (1, 8) true coefficients [bearing][i][j]
    cb: npt.NDArray[np.float64],
    probes_z: npt.NDArray[np.float64],  # (4,) nominal axial positions of x1, x2, y1, y2
    planes_z: npt.NDArray[np.float64],  # (2,) imbalance planes, or (runs,) impact planes
    errors: npt.NDArray[np.float64],  # (9,) imbalance or (5,) impact standard deviations
    t0: int,
    t1: int,
    p0: int,
    p1: int,
    *,
    u: npt.NDArray[np.complex128] | None = None,  # (runs, 2) m r e^{-j phi} per plane
    dirs: npt.NDArray[np.uint8] | None = None,  # (runs,) 0 = x, 1 = y
    spin: float = 0.0,  # running speed of impact tests, rad/s
    method: str = "forces",
    seed: int = 0,
) -> tuple[
    npt.NDArray[np.uint32],  # counts (p1 - p0, 16, STUDY_BINS)
    npt.NDArray[np.uint32],  # finite errors (p1 - p0, 16)
    npt.NDArray[np.uint32],  # non-finite errors
    npt.NDArray[np.float64],  # sum of errors
    npt.NDArray[np.float64],  # sum of squared errors
]:
    """Trials t0..t1 of a Monte Carlo study at points p0..p1, accumulated (docs/studies.md)."""

def study_realize(
    rotor: npt.NDArray[np.float64],
    w: npt.NDArray[np.float64],
    kb: npt.NDArray[np.float64],
    cb: npt.NDArray[np.float64],
    probes_z: npt.NDArray[np.float64],
    planes_z: npt.NDArray[np.float64],
    errors: npt.NDArray[np.float64],
    t0: int,
    t1: int,
    *,
    u: npt.NDArray[np.complex128] | None = None,
    dirs: npt.NDArray[np.uint8] | None = None,
    spin: float = 0.0,
    seed: int = 0,
) -> tuple[npt.NDArray[np.complex128], npt.NDArray[np.float64]]:
    """Measured values (trials, runs, n, 4) at the channels and the told point frequencies (trials, n)."""

def study_bin_edges() -> npt.NDArray[np.float64]:
    """Bin edges of the study histograms, (STUDY_BINS + 1,), from -inf to +inf."""

def study_percentiles(
    counts: npt.NDArray[np.uint32] | npt.NDArray[np.uint64],
    percentiles: npt.NDArray[np.float64],
) -> npt.NDArray[np.float64]:
    """Percentiles (P, rows) of C-contiguous histograms (..., STUDY_BINS) (docs/studies.md rule)."""
