"""Runs measured at slightly different speeds, carried to common speeds through the rotor model.

Imbalance runs dwell at "the same" speeds only to within their speed control: a run's dwell at
"3000 rpm" is at 2997.4 rpm, the next run's at 3006.1. The identification's equations at a point
hold for one speed Omega (the imbalance force m e Omega², the rotor's inertia Omega² M q, the
damping force j Omega C x): runs taken a fraction of a percent apart and identified as if at one
speed give large errors where the response changes fast with speed, near the critical speeds
(the example rig, noise-free, runs ±0.1 % apart: direct damping up to 8 % off, ±0.25 %: 21 %).
Interpolating a run's vectors between its dwells does not help: the dwells are hundreds of rpm
apart, and the response between them is far from linear.

An imbalance response at speed Omega is q(Omega) = Omega² H(Omega) u (H the receptance of the rotor
on its bearings, u the generalized imbalance), so a vector measured at Omega_r is carried to
Omega exactly by

    q(Omega) = T q(Omega_r),   T = (Omega / Omega_r)² H(Omega) H(Omega_r)⁻¹,

whatever the imbalance (added or remnant). H needs the bearing coefficients being identified: the
carry is iterated with the identification (identify from the vectors as measured, carry them with
the coefficients found, identify again) to its fixed point, which for noise-free data is the exact
answer; T is within a few percent of the identity (its distance is about the speed offset over
the damping ratio), so the coefficients' own errors reach the carried vectors only scaled by it and
near and above the critical speeds the iteration contracts in a few steps. Far below them the
identification is so ill-conditioned that the carry's error can grow from pass to pass: points that
do not settle are carried by (Omega / Omega_r)² alone (no coefficients needed) and flagged.
Covariances are carried with the vectors (T Σ Tᴴ, in the real [Re, Im] form); the carry's own
uncertainty, from the coefficients it uses, is not added (at ±0.25 % coverage is as at one speed, at
±1 % 0.92-0.94), and the coefficients are taken as the same at Omega_r and Omega.

Run-out (the probes' 1X reading of the shaft's surface, the same at every speed) does not scale
with Omega² H: carried with the response it no longer cancels between a run and a baseline taken
at different speeds, (T_r - T_b) R stays. A slow roll takes it out first; without one the run-out
is estimated on every pass from the baseline's dwells, whose 1X is Omega² H(Omega) u + R at every
speed (u a remnant imbalance in the rotor's two planes: 6 complex unknowns by least squares over
the speeds), and taken out of the runs and the baseline before they are carried (its own error then
reaches the vectors only through T_r - T_b, a few percent of it).
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass

import numpy as np

from ._corecall import core as _core
from .errors import RotoridError
from .simulate import RPM, _planes_to

#: the flag of points where runs at slightly different speeds could not be carried to one
SPEED_OFFSETS_UNRESOLVED = "speed offsets not resolved"
#: the largest number of identify-and-carry passes
MAX_PASSES = 25
#: the carried vectors have converged when a pass moves none of them by more than this fraction of
#: its standard error (vectors with a covariance) ...
MOVE_PER_STD = 1e-3
#: ... or of its magnitude (without one)
MOVE_PER_SIZE = 1e-7


@dataclass
class Dwells:
    """One run's 1X vectors at the points of a common speed grid, each where it was measured.

    ``speed_rpm`` (n,): the speed of each vector (the run's dwell nearest the grid speed); ``q``
    (n, 4) complex [x1, x2, y1, y2]; ``cov`` (n, 8, 8) the covariance of [Re q, Im q] or None;
    ``dof`` (n,) its degrees of freedom or None.
    """

    speed_rpm: np.ndarray
    q: np.ndarray
    cov: np.ndarray | None = None
    dof: np.ndarray | None = None


@dataclass
class Carried:
    """The runs carried to the grid (:func:`carry_to_grid`).

    ``grid``: the speeds (rpm); ``q``: each run's (n, 4) vectors at them, the baseline's
    subtracted where there is one; ``cov``: each run's (n, 8, 8) covariance (its own and the
    baseline's; NaN where either is unknown), or None for a run without any; ``dof``: each run's
    (n,) degrees of freedom or None; ``shared``: the baseline's carried covariance, common to every
    run, or None; ``identification``: the last pass's; ``passes``: the identifications made;
    ``unresolved`` (n,): points where the passes had not settled (or where the coefficients found
    could not carry: singular or not finite), whose vectors are as the last pass left them;
    ``largest_offset``: the largest relative distance of a measured speed from its grid speed;
    ``runout``: the 1X run-out (4,) estimated from the baseline and taken out (m), or None.
    """

    grid: np.ndarray
    q: list
    cov: list
    dof: list
    shared: np.ndarray | None
    identification: object
    passes: int
    unresolved: np.ndarray
    largest_offset: float
    runout: np.ndarray | None = None


def _real_form(T):
    """The real (n, 8, 8) matrix acting on [Re q, Im q] as the complex (n, 4, 4) T acts on q."""
    n = T.shape[0]
    R = np.empty((n, 8, 8))
    R[:, :4, :4], R[:, :4, 4:] = T.real, -T.imag
    R[:, 4:, :4], R[:, 4:, 4:] = T.imag, T.real
    return R


def carry_matrix(rotor, k, c, from_rpm, to_rpm, *, at="bearings"):
    """The matrices T (n, 4, 4) that carry imbalance responses from ``from_rpm`` to ``to_rpm``.

    T = (Ω_to / Ω_from)² H(Ω_to) H(Ω_from)⁻¹ with H the synchronous receptance of ``rotor`` on
    bearings of stiffness ``k`` and damping ``c`` (n, 2, 2, 2), [point, bearing, i, j], taken as
    the same at both speeds; ``at`` "bearings" or "probes": where the vectors are. Points whose
    coefficients are not finite or whose receptance is singular get T = I; the mask of them is
    returned as well.

    Examples
    --------
    >>> import numpy as np, rotorid
    >>> from rotorid.speed_offsets import carry_matrix
    >>> rig = rotorid.nsf_rig()
    >>> k, c = rig.bearings.k[None], rig.bearings.c[None]
    >>> q = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["A"], speed_rpm=[4000.0, 4012.0]).q
    >>> T, bad = carry_matrix(rig.rotor, k, c, [4012.0], [4000.0])
    >>> bool(np.allclose(T[0] @ q[1], q[0], rtol=1e-12, atol=0)), bool(bad[0])
    (True, False)
    """
    f = np.ascontiguousarray(np.atleast_1d(np.asarray(from_rpm, dtype=float)))
    t = np.ascontiguousarray(np.atleast_1d(np.asarray(to_rpm, dtype=float)))
    n = max(f.size, t.size)
    f, t = np.broadcast_to(f, (n,)).copy(), np.broadcast_to(t, (n,)).copy()
    k = np.broadcast_to(np.asarray(k, dtype=float), (n, 2, 2, 2))
    c = np.broadcast_to(np.asarray(c, dtype=float), (n, 2, 2, 2))
    bad = ~(np.isfinite(k).all(axis=(1, 2, 3)) & np.isfinite(c).all(axis=(1, 2, 3)))
    k8 = np.ascontiguousarray(np.where(bad[:, None, None, None], 1.0, k).reshape(n, 8))
    c8 = np.ascontiguousarray(np.where(bad[:, None, None, None], 0.0, c).reshape(n, 8))
    unit = np.eye(4, dtype=complex)[None]
    planes = _planes_to(rotor, at)
    h = []
    for rpm in (f, t):
        om = rpm * RPM
        # the response to each unit generalized force: (n, force, coordinate)
        hq, _ = _core.forced_response(rotor.core_params(), k8, c8, om, om, unit, planes=planes)
        h.append(np.swapaxes(hq, 1, 2))   # columns: the responses
    hf, ht = h
    bad |= ~(np.isfinite(hf).all(axis=(1, 2)) & np.isfinite(ht).all(axis=(1, 2)))
    hf[bad], ht[bad] = np.eye(4), np.eye(4)
    try:
        # T = ht hf⁻¹, i.e. Tᵀ = hf⁻ᵀ htᵀ
        T = np.swapaxes(np.linalg.solve(np.swapaxes(hf, 1, 2), np.swapaxes(ht, 1, 2)), 1, 2)
    except np.linalg.LinAlgError:
        T = np.empty((n, 4, 4), complex)
        for i in range(n):
            try:
                T[i] = np.linalg.solve(hf[i].T, ht[i].T).T
            except np.linalg.LinAlgError:
                T[i], bad[i] = np.eye(4), True
    T *= ((t / f) ** 2)[:, None, None]
    T[bad] = np.eye(4)
    return T, bad


def _carry(d: Dwells, T):
    q = np.einsum("nij,nj->ni", T, d.q)
    if d.cov is None:
        return q, None
    R = _real_form(T)
    return q, R @ d.cov @ np.swapaxes(R, 1, 2)


def _compose(runs, baseline, Ts, Tb, runout=None):
    """(vectors, covariances, shared covariance) of the runs carried by ``Ts`` less the baseline
    carried by ``Tb``, ``runout`` (4,) taken out of both first: covariances a list with None for
    a run without one (NaN where the baseline has none), shared None without a baseline
    covariance."""
    if runout is not None:
        runs = [dataclasses.replace(d, q=d.q - runout) for d in runs]
        baseline = dataclasses.replace(baseline, q=baseline.q - runout)
    qs, covs = [], []
    qb = cb = None
    if baseline is not None:
        qb, cb = _carry(baseline, Tb)
    for d, T in zip(runs, Ts):
        q, cv = _carry(d, T)
        if qb is not None:
            q = q - qb
            if cv is not None:
                cv = cv + cb if cb is not None else np.full_like(cv, np.nan)
        qs.append(q)
        covs.append(cv)
    return qs, covs, cb


def _usable(covs, shared):
    """The covariances as the identification takes them: all runs' (finite) or None; the shared
    part with them only."""
    if any(cv is None or not np.isfinite(cv).all() for cv in covs):
        return None, None
    return covs, (shared if shared is not None and np.isfinite(shared).all() else None)


def _dofs(runs, baseline):
    out = []
    for d in runs:
        dof = d.dof
        if dof is not None and baseline is not None and baseline.dof is not None:
            dof = np.minimum(dof, baseline.dof)
        out.append(dof)
    return out


def _moved(old, new, d: Dwells):
    """(n,) how far each point's carried vector moved between passes, in its standard errors or
    (without a covariance) in its magnitude, scaled to the convergence limits."""
    dq = np.abs(np.einsum("nij,nj->ni", new - old, d.q))
    if d.cov is not None:
        sd = np.sqrt(np.maximum(d.cov[:, np.arange(4), np.arange(4)] + d.cov[:, np.arange(4, 8), np.arange(4, 8)],
                                0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where(sd > 0, dq / (MOVE_PER_STD * sd), np.nan)
        if np.isfinite(r).all():
            return r.max(axis=1)
    size = np.maximum(np.abs(d.q).max(axis=1), 1e-300)
    return dq.max(axis=1) / (MOVE_PER_SIZE * size)


#: the fewest speeds with usable coefficients from which the baseline's run-out is estimated
RUNOUT_MIN_SPEEDS = 3


def _runout_fit(rotor, k, c, baseline: Dwells, at, use=None):
    """The 1X run-out R (4,) of the baseline's dwells, as least squares of q_b = Omega² H(Omega) u +
    R over the speeds where the coefficients (k, c (n, 2, 2, 2)) are finite (and ``use``, a mask,
    if given), u a remnant imbalance in the rotor's two planes; each channel's equations weighted
    by the baseline's noise there where it states it. None with fewer than RUNOUT_MIN_SPEEDS such
    speeds."""
    from .model import Imbalance

    good = np.isfinite(k).all(axis=(1, 2, 3)) & np.isfinite(c).all(axis=(1, 2, 3))
    if use is not None:
        good &= use
    if good.sum() < RUNOUT_MIN_SPEEDS:
        return None
    g = int(good.sum())
    planes = np.array([Imbalance((1.0, 0.0), (0.0, 0.0))._generalized(rotor),
                       Imbalance((0.0, 1.0), (0.0, 0.0))._generalized(rotor)], dtype=complex)
    om = np.ascontiguousarray(baseline.speed_rpm[good] * RPM)
    k8 = np.ascontiguousarray(k[good].reshape(g, 8))
    c8 = np.ascontiguousarray(c[good].reshape(g, 8))
    # the response to a unit imbalance in each plane at each speed: (g, plane, channel)
    h, nsing = _core.forced_response(rotor.core_params(), k8, c8, om, om, planes[None], gain=om ** 2,
                                     planes=_planes_to(rotor, at))
    if nsing or not np.isfinite(h).all():
        return None
    A = np.zeros((g, 4, 6), dtype=complex)
    A[:, :, 0], A[:, :, 1] = h[:, 0, :], h[:, 1, :]
    A[:, np.arange(4), 2 + np.arange(4)] = 1.0
    b = np.asarray(baseline.q)[good]
    w = np.ones((g, 4))
    if baseline.cov is not None:
        cov = np.asarray(baseline.cov)[good]
        var = cov[:, np.arange(4), np.arange(4)] + cov[:, np.arange(4, 8), np.arange(4, 8)]
        if np.isfinite(var).all() and (var > 0).all():
            w = 1.0 / np.sqrt(var)
    x = np.linalg.lstsq((A * w[:, :, None]).reshape(4 * g, 6), (b * w).reshape(4 * g), rcond=None)[0]
    return x[2:]


def carry_to_grid(rotor, grid_rpm, runs, identify, *, baseline=None, at="probes", first=None, runout=False):
    """Each run's vectors carried from where they were measured to the grid speeds, with the
    bearing coefficients identified from them, iterated to its fixed point.

    ``runs``: list of :class:`Dwells`; ``baseline``: a :class:`Dwells` subtracted from every run
    after both are carried (its carried covariance is returned as the runs' shared part), or None;
    ``identify(qs, covs, shared)``: the identification at ``grid_rpm`` from the runs' (n, 4)
    vectors (a list), their covariances (a list, or None unless every run has a finite one) and
    the shared covariance (or None);
    ``first``: the identification from the vectors as measured, if the caller has it;
    ``runout``: estimate the run-out from the baseline on every pass and take it out of the runs
    and the baseline before carrying them (:func:`_runout_fit`; for vectors from which no slow roll
    was subtracted).

    Examples
    --------
    >>> import numpy as np, rotorid
    >>> from rotorid.speed_offsets import Dwells, carry_to_grid
    >>> rig = rotorid.nsf_rig()
    >>> grid = np.array([3500.0, 4000.0])
    >>> imbs = [rig.imbalances["A"], rig.imbalances["B"]]
    >>> own = [grid * 1.002, grid * 0.998]          # each run a little off the grid
    >>> runs = [Dwells(s, rotorid.imbalance_response(rig.rotor, rig.bearings, i, speed_rpm=s).q)
    ...         for s, i in zip(own, imbs)]
    >>> def identify(qs, covs, shared):
    ...     rs = [rotorid.SyncResponse(grid, q, i) for q, i in zip(qs, imbs)]
    ...     return rotorid.identify_synchronous(rig.rotor, rs)
    >>> done = carry_to_grid(rig.rotor, grid, runs, identify, at="bearings")
    >>> bool(np.allclose(done.identification.c, rig.bearings.c, rtol=1e-4)), bool(done.unresolved.any())
    (True, False)
    """
    grid = np.asarray(grid_rpm, dtype=float)
    n = grid.size
    eye = np.broadcast_to(np.eye(4, dtype=complex), (n, 4, 4))
    Ts = [eye.copy() for _ in runs]
    Tb = eye.copy()
    everyone = list(runs) + ([baseline] if baseline is not None else [])
    offset = max(float(np.max(np.abs(d.speed_rpm / grid - 1.0))) for d in everyone)
    dofs = _dofs(runs, baseline)
    if offset == 0.0:
        qs, covs, shared = _compose(runs, baseline, Ts, Tb)
        ident = first if first is not None else identify(qs, *_usable(covs, shared))
        return Carried(grid, qs, covs, dofs, shared, ident, 1, np.zeros(n, bool), 0.0)
    ident = first
    passes = 0 if first is not None else None
    unresolved = np.ones(n, bool)
    ro = None
    fit_runout = runout and baseline is not None
    with warnings.catch_warnings():
        # the passes' warnings are those of the last identification, made by the caller
        warnings.simplefilter("ignore")
        if ident is None:
            qs, covs, shared = _compose(runs, baseline, Ts, Tb)
            ident, passes = identify(qs, *_usable(covs, shared)), 1
        prev, growing = None, 0
        for _ in range(MAX_PASSES):
            k, c = np.asarray(ident.k), np.asarray(ident.c)
            if fit_runout:
                # from the points the identification trusts (where there are enough of them): a
                # point whose carry is running away must not set the run-out of all
                use = np.asarray(ident.ok, dtype=bool) & (~unresolved if passes > 1 else True)
                ro = _runout_fit(rotor, k, c, baseline, at, use if use.sum() >= RUNOUT_MIN_SPEEDS else None)
            new, bad = [], np.zeros(n, bool)
            for d in everyone:
                T, b = carry_matrix(rotor, k, c, d.speed_rpm, grid, at=at)
                new.append(T)
                bad |= b
            moved = np.zeros(n)
            for d, old, T in zip(everyone, Ts + ([Tb] if baseline is not None else []), new):
                moved = np.fmax(moved, _moved(old, T, d))
            Ts, Tb = new[:len(runs)], (new[-1] if baseline is not None else Tb)
            qs, covs, shared = _compose(runs, baseline, Ts, Tb, ro)
            ident, passes = identify(qs, *_usable(covs, shared)), passes + 1
            unresolved = bad | ~(moved <= 1.0)
            if not unresolved.any() or passes >= MAX_PASSES:
                break
            # every point still moving moves more than in the pass before, three passes running:
            # running away, not settling (the points that settle have settled)
            growing = growing + 1 if prev is not None and np.all(~(moved[unresolved] <= prev[unresolved])) else 0
            if growing >= 3:
                break
            prev = moved
        if unresolved.any():
            # where the passes did not settle (far below the critical speeds the identification is
            # so ill-conditioned that the carry's own error grows from pass to pass: an independent
            # review's 2000 rpm vector went from 16 µm to 9 cm, and every other point of the run
            # became "low amplitude" beside it) the vectors are carried by the imbalance force's
            # scaling alone, (W / W_r)², which needs no coefficients; those points stay flagged
            plain = [_force_scaling(d.speed_rpm, grid) for d in everyone]
            Ts = [np.where(unresolved[:, None, None], p, T) for p, T in zip(plain, Ts)]
            if baseline is not None:
                Tb = np.where(unresolved[:, None, None], plain[-1], Tb)
            qs, covs, shared = _compose(runs, baseline, Ts, Tb, ro)
            ident, passes = identify(qs, *_usable(covs, shared)), passes + 1
    if unresolved.any():
        bad = grid[unresolved]
        listed = ", ".join(f"{v:.0f}" for v in bad[:5]) + (", ..." if bad.size > 5 else "")
        warnings.warn(f"runs at slightly different speeds: the carry to common speeds did not settle at {listed} rpm "
                      f"(flagged \"{SPEED_OFFSETS_UNRESOLVED}\")")
    return Carried(grid, qs, covs, dofs, shared, ident, passes, unresolved, offset, ro)


def _force_scaling(from_rpm, to_rpm):
    """(W_to / W_from)² I (n, 4, 4): the carry of a response whose receptance does not change
    between the two speeds (far from resonance)."""
    f = ((np.asarray(to_rpm, dtype=float) / np.asarray(from_rpm, dtype=float)) ** 2)
    return f[:, None, None] * np.eye(4, dtype=complex)[None]


def _dwells_of(track, grid_rpm, tolerance_rpm, label, *, longest=False):
    """A track's (:class:`rotorid.signals.SyncTrack`) 1X vectors at each grid speed: its block
    (dwell, table row) nearest in speed, within ``tolerance_rpm`` (a RotoridError naming ``label``
    otherwise), as :class:`Dwells` (covariance None where the track states none).
    ``longest``: of several blocks within the tolerance (a dwell split by a speed change within it)
    the one of most revolutions, a UserWarning naming them."""
    i = _nearest_dwells(track.speed_rpm, grid_rpm, tolerance_rpm, label)
    if longest:
        i = _longest_within(track, grid_rpm, tolerance_rpm, label, i)
    i1 = tuple(track.orders).index(1)
    cov = None if track.cov is None else np.asarray(track.cov)[i]
    if cov is not None and np.isnan(cov).all():
        cov = None
    dof = None if track.dof is None or cov is None else np.asarray(track.dof, dtype=float)[i]
    return Dwells(np.asarray(track.speed_rpm, dtype=float)[i], np.asarray(track.vectors)[i, i1, :], cov, dof)


def _longest_within(track, grid_rpm, tolerance_rpm, label, nearest):
    """For each grid speed the block of most revolutions among those within the tolerance (the
    nearest where they tie), with a warning where there were several."""
    s = np.asarray(track.speed_rpm, dtype=float)
    revs = np.nan_to_num(np.asarray(track.n_revs, dtype=float), nan=0.0)
    g = np.asarray(grid_rpm, dtype=float)
    tol = np.broadcast_to(np.asarray(tolerance_rpm, dtype=float), g.shape)
    out = np.array(nearest)
    split = []
    for k in range(g.size):
        near = np.flatnonzero(np.abs(s - g[k]) <= tol[k])
        if near.size > 1:
            split.append(f"{g[k]:.0f} rpm ({near.size} blocks, {', '.join(f'{int(r)}' for r in revs[near])} revs)")
            best = near[revs[near] == revs[near].max()]
            out[k] = best[np.argmin(np.abs(s[best] - g[k]))]
    if split:
        warnings.warn(f"{label}: dwells split by a speed change within them, the longest block used: "
                      f"{'; '.join(split[:4])}{'; ...' if len(split) > 4 else ''} (a speed that wanders more than "
                      "speed_tolerance; raise it to keep such a dwell whole)")
    return out


def merged_dwell_speeds(speed_rpm, n_revs, tolerance_rpm=2.0, tolerance_rel=0.0):
    """A track's block speeds (rpm) with blocks that lie within the tolerance of each other (one
    dwell split by a speed change within it) given once, by the speed of their longest block;
    ascending. The tolerance at speed s is max(tolerance_rpm, tolerance_rel * s).

    Examples
    --------
    >>> from rotorid.speed_offsets import merged_dwell_speeds
    >>> merged_dwell_speeds([3000.0, 3010.0, 3500.0, 2995.0], [100, 300, 400, 50], tolerance_rel=0.01)
    array([3010., 3500.])
    """
    s = np.asarray(speed_rpm, dtype=float)
    revs = np.nan_to_num(np.asarray(n_revs, dtype=float), nan=0.0)
    order = np.argsort(s, kind="stable")
    s, revs = s[order], revs[order]
    out, a = [], 0
    for b in range(1, s.size + 1):
        if b == s.size or s[b] - s[a] > max(tolerance_rpm, tolerance_rel * s[a]):
            group = np.arange(a, b)
            out.append(s[group[np.argmax(revs[group])]])
            a = b
    return np.array(out)


def _nearest_dwells(speed_rpm, grid_rpm, tolerance_rpm, label):
    """For each grid speed, the index of the measured speed nearest it (within
    ``tolerance_rpm``, a number or one per grid speed; a RotoridError names ``label`` and the grid
    speed otherwise)."""
    s = np.asarray(speed_rpm, dtype=float)
    g = np.asarray(grid_rpm, dtype=float)
    tol = np.broadcast_to(np.asarray(tolerance_rpm, dtype=float), g.shape)
    i = np.argmin(np.abs(s[None, :] - g[:, None]), axis=1)
    far = np.abs(s[i] - g) > tol
    if far.any():
        raise RotoridError(f"{label}: no speed within {tol[far][0]:g} rpm of {g[far][0]:.1f} rpm (nearest "
                           f"{s[i][far][0]:.1f} rpm)")
    return i
