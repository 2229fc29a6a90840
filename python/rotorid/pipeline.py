"""End to end: raw recordings -> compensated synchronous vectors or averaged FRFs -> coefficients.

Callable from Python (``imbalance_chain``, ``impact_chain``, ``run_config``) and from the CLI
(``rotorid identify imbalance CONFIG``, ``rotorid identify impact CONFIG``).
"""

from __future__ import annotations

import dataclasses
import functools
import os
import warnings
from dataclasses import dataclass, field

import numpy as np

from . import impact_noise, signals
from .errors import RotoridError
from .identify import Identification, _phase_reference_std, _with_flag, identify_impact, identify_synchronous
from .model import Imbalance, RigidRotor
from .recording import ACCELEROMETERS, DISPLACEMENTS, Recording, SegmentedRecording
from .simulate import RPM, ImpactResponse, SyncResponse


def _imbalance_of(rec, override=None, label="") -> Imbalance:
    """The added imbalance of run ``rec`` (a Recording, SegmentedRecording, SyncTrack or 1X
    table): ``override`` (an Imbalance or its config dict) or its metadata's; ``label`` names the
    run where it has no source file (a track or table made in Python)."""
    if isinstance(override, Imbalance):
        return override
    meta = getattr(rec, "meta", None) or {}
    spec = override if override is not None else meta.get("imbalance")
    if spec is None:
        what = f"recording {rec.source!r}" if getattr(rec, "source", "") else (label or "a run")
        raise RotoridError(f"{what} has no added imbalance: give it in the config (mass_g/mass_kg and angle_deg), in "
                           "the file's metadata, or as imbalances= (one rotorid.Imbalance per run)")
    if "mass_g" in spec:
        mass = [m * 1e-3 for m in spec["mass_g"]]
    else:
        mass = spec["mass_kg"]
    return Imbalance(tuple(mass), tuple(spec.get("angle_deg", (0.0, 0.0))), name=spec.get("name") or meta.get("name"))


#: a probe is dead when its 1X stays below this many of its own noise widths at (nearly) every speed
#: of every run
DEAD_PROBE_SNR = 3.0


def _check_live_probes(tracks, labels, runs=None):
    """Refuse a probe channel that shows no 1X above its noise anywhere: a dead or disconnected
    probe (a flat channel, or a gap voltage with noise only). Its vectors are then noise, which
    the identification would fit as a response (K and C off by 170-450 % with most points ok, an
    independent simulator's finding). Live probes read run-out and response together, far above
    their noise, before any compensation. Tracks without a covariance (1X tables) are not checked.
    Probes mounted at an angle (``runs``: the runs as loaded, whose meta says so) are checked on
    what they read, not on the x and y resolved from them: a dead probe's partner fills both."""
    from .probe_angles import moved_covariance, reading_map, recorded_angles

    names = ("x1", "x2", "y1", "y2")
    above, total = np.zeros(4), 0
    angles = {}
    for i, t in enumerate(tracks):
        if t.cov is None or 1 not in t.orders:
            continue
        v, cov = t.vectors[:, t.orders.index(1), :], t.cov
        run_angles = recorded_angles(runs[i]) if runs is not None else {}
        m = reading_map({c: a for c, a in run_angles.items() if c in names}, names)
        if m is not None:
            angles.update(run_angles)
            v, cov = v @ m.T, moved_covariance(cov, m)
        x = np.abs(v)
        var = np.stack([cov[:, c, c] + cov[:, c + 4, c + 4] for c in range(4)], axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            snr = np.where(x > 0, x / np.sqrt(var), 0.0)  # a flat channel: 0 / 0
        # an unknown noise (NaN) counts as live: nothing to say
        above += np.sum(~(snr < DEAD_PROBE_SNR), axis=0)
        total += x.shape[0]
    # noise alone reaches 3 of its widths at a point with probability e^-9; a live probe at most
    # points (run-out alone puts it far above its noise)
    live = above >= max(1.0, 0.05 * total)
    if total and not live.all():
        dead = [names[c] + (f" (the probe at {angles[names[c]]:g}°)" if names[c] in angles else "")
                for c in range(4) if not live[c]]
        raise RotoridError(f"probe channel(s) {', '.join(dead)} show no 1X response above their noise at any speed of "
                           f"{', '.join(labels) if len(labels) < 5 else 'any run'}: a dead or disconnected probe (flat, or "
                           "a gap voltage with noise only)? The identification needs all four probes")


@dataclass
class ImbalanceChainResult:
    responses: list          # SyncResponse per run (compensated, on the common speed grid)
    tracks: list             # raw SyncTrack per run
    identification: Identification
    notes: list = field(default_factory=list)
    shared_cov: np.ndarray | None = None   # the baseline's covariance common to every run (None without)
    slow_roll_1x: np.ndarray | None = None   # the slow-roll run-out 1X vector (4,) subtracted, m (None without)
    # the keyphasors' timing uncertainty as a phase at each grid speed (deg; None where every pulse
    # times exactly), and its part local to each dwell (where the pulses fall between samples,
    # noise, the equivalent-time correction's own), which a phase calibration does not absorb
    keyphasor_phase_std_deg: np.ndarray | None = None
    keyphasor_local_std_deg: np.ndarray | None = None
    # the phase-reference calibration (phase_calibration "report" or "apply"; None otherwise or
    # where it could not be made, with a note saying why)
    phase_calibration: object = None
    # the phase reference's uncertainty that the identification's error bars hold (stated, the
    # keyphasor pulse shape's, what a phase calibration found or its uncertainty, its scatter), as
    # keyword arguments of rotorid.identify_pedestals, which pools the speeds and so needs to know
    # how the error goes from speed to speed
    pedestal_phase_kw: dict = field(default_factory=dict)


#: speed_match_rpm's default where the runs are carried to common speeds: this fraction of each
#: grid speed, at least 2 rpm (2 rpm where they are interpolated: pedestal motion)
CARRY_MATCH = 0.005


def _probes_at(run):
    """Where a run's displacement probes are: "probes" (their planes) unless its file says
    "bearings"."""
    return (getattr(run, "meta", {}) or {}).get("probes_at", "probes")


def _carried_dwells(rotor, grid, tracks, baseline, tol, centre, imbs, at, method, ident_kw, notes, runout, longest):
    """The runs' (and baseline's) 1X vectors at the dwells nearest each grid speed, carried to it
    through the bearings identified from them (:func:`rotorid.speed_offsets.carry_to_grid`);
    ``centre``: the grid speed becomes the mean of the speeds measured there; ``runout``: the
    vectors still hold the run-out (no slow roll): estimated from the baseline and taken out;
    ``longest``: per run, then the baseline, whether it was recorded (not a table): of its blocks
    within the tolerance (a dwell split by a wandering speed) the longest is taken."""
    from .speed_offsets import carry_to_grid, _dwells_of

    ds = [_dwells_of(t, grid, tol, f"run {i}", longest=longest[i]) for i, t in enumerate(tracks)]
    db = None if baseline is None else _dwells_of(baseline, grid, tol, "baseline", longest=longest[-1])
    if centre:
        grid = np.mean([d.speed_rpm for d in ds + ([db] if db is not None else [])], axis=0)
    kw = {k: v for k, v in ident_kw.items() if k != "shared_cov"}

    def identify(qs, covs, shared):
        rs = [SyncResponse(grid, q, imb, at, cov=None if covs is None else covs[i],
                           dof=None if covs is None or d.dof is None else d.dof)
              for i, (q, imb, d) in enumerate(zip(qs, imbs, ds))]
        return identify_synchronous(rotor, rs, method=method, shared_cov=shared, **kw)

    done = carry_to_grid(rotor, grid, ds, identify, baseline=db, at=at, runout=runout)
    if done.runout is not None:
        notes.append("1X run-out estimated from the baseline's dwells (no slow roll) and taken out before carrying: "
                     + ", ".join(f"{ch} {abs(v) * 1e6:.2f} µm" for ch, v in zip(("x1", "x2", "y1", "y2"), done.runout)))
    elif runout and db is not None and done.largest_offset > 0:
        warnings.warn("no slow roll, and too few speeds (3 needed) to estimate the run-out from the baseline: the "
                      "run-out left in the vectors is carried as if it were response, and does not cancel exactly "
                      "between runs and a baseline measured at other speeds")
    far = max(float(np.max(np.abs(d.speed_rpm - done.grid))) for d in ds + ([db] if db is not None else []))
    if far >= 0.05:
        notes.append(f"dwell speeds up to {far:.1f} rpm ({done.largest_offset * 100:.2f} %) from the common speeds: "
                     f"each run's 1X vectors{' and the baseline' if db is not None else ''} carried to them through "
                     f"the rotor on the bearings identified ({done.passes} passes)")
    return done


def _near_only(track, speeds, tol, label, what):
    """The track without its blocks that lie farther than ``tol`` rpm from every one of ``speeds``
    (with a warning that says how many and why)."""
    d = np.min(np.abs(track.speed_rpm[:, None] - np.asarray(speeds)[None, :]), axis=1)
    far = d > tol
    if not far.any():
        return track
    if far.all():
        raise RotoridError(f"{label}: none of its speeds ({track.speed_rpm.min():.0f}-{track.speed_rpm.max():.0f} rpm) "
                           f"lies within {tol:g} rpm of a speed of {what}; raise speed_match_rpm if they are the same")
    listed = ", ".join(f"{v:.1f}" for v in track.speed_rpm[far][:5]) + (", ..." if far.sum() > 5 else "")
    warnings.warn(f"{label}: {int(far.sum())} of {far.size} speed(s) ({listed} rpm) dropped: farther than {tol:g} rpm "
                  f"(speed_match_rpm) from every speed of {what}")
    keep = ~far
    fields = ("speed_rpm", "vectors", "n_revs", "scatter", "t_mid", "cov", "dof")
    if track.has_pedestal:
        fields += ("pedestal", "pedestal_cov", "pedestal_cross")
    return dataclasses.replace(track, **{f: getattr(track, f)[keep] for f in fields})


def _accelerometers_of(run):
    """The accelerometer channels (px1, px2, py1, py2) a run carries: channels of a recording, all
    four for a 1X table with pedestal columns."""
    if isinstance(run, signals.SyncTrack):
        return list(ACCELEROMETERS) if run.has_pedestal else []
    chans = getattr(run, "channels", None) or {}
    return [c for c in ACCELEROMETERS if c in chans]


def _pedestal_choice(pedestal_motion, runs, labels):
    """Whether the chain uses the housings' accelerometers: ``pedestal_motion`` checked against the
    channels the runs carry (accelerometers without a choice, or a choice without accelerometers,
    is an error that names the run and channel)."""
    from ._validate import flag

    # runs of a wrong type are reported by the chain's own type check, not as missing channels
    kinds = (Recording, SegmentedRecording, signals.SyncTrack)
    found = [(lab, _accelerometers_of(r)) for lab, r in zip(labels, runs) if isinstance(r, kinds)]
    if pedestal_motion is None:
        having = [(lab, ch) for lab, ch in found if ch]
        if having:
            lab, ch = having[0]
            raise RotoridError(f"{lab} has accelerometer channel(s) {', '.join(ch)} (pedestal motion) but no pedestal "
                               "model was chosen: set pedestal_motion=True (config: [pedestals] measured = true) to "
                               "identify with the housings' motion, or False to ignore the accelerometers")
        return False
    pedestal_motion = flag("pedestal_motion", pedestal_motion)
    having = [lab for lab, ch in found if ch]
    if not pedestal_motion and having:
        # a choice, but one whose cost is not seen in the results: an independent simulator's
        # housings moving 0.3-0.65 of the journals' relative motion gave K off by 23 %, C by 34 %,
        # with a fifth of the points ok
        warnings.warn(f"{having[0]}" + (f" and {len(having) - 1} more carry" if len(having) > 1 else " carries") +
                      " housing accelerometers that are ignored (pedestal_motion=False; config: [pedestals] "
                      "measured = false): where the housings move, the coefficients identified are those of each "
                      "bearing in series with its pedestal, not the bearing's")
    if pedestal_motion:
        for lab, ch in found:
            missing = [c for c in ACCELEROMETERS if c not in ch]
            if missing:
                raise RotoridError(f"{lab} has no accelerometer channel {missing[0]}: identifying with pedestal motion "
                                   f"needs px1, px2, py1, py2 on every run (missing: {', '.join(missing)})")
    return pedestal_motion


def _labelled(fn, label, what):
    """Run fn; a RotoridError names the run it concerns."""
    try:
        return fn()
    except RotoridError as exc:
        raise RotoridError(f"{label} ({what}): {exc}") from None


#: imbalance runs and baselines whose fastest speed is below this (rpm) are refused: an added
#: imbalance's force m u Omega^2 is then negligible, and such speeds come from a unit error (a
#: sample rate in kHz, a speed column in Hz) that would otherwise give a similar rotor with
#: coefficients a million times too small and every point ok
MIN_RUN_RPM = 60.0


def _plausible_speeds(track, run, label):
    """A RotoridError when a run's speeds are too slow to be an imbalance run (a unit error)."""
    fastest = float(np.nanmax(track.speed_rpm)) if track.speed_rpm.size else float("nan")
    if not fastest >= MIN_RUN_RPM:
        fs = getattr(run.blocks[0] if isinstance(run, SegmentedRecording) else run, "fs_hz", None)
        src = getattr(run, "source", "")
        label = f"{label} ({src})" if src else label
        how = (f"at a sample rate of {fs:g} Hz: is the sample rate in Hz? (one in kHz gives speeds 1000 times too "
               "low)") if fs is not None else "in its speed column: are the speeds in rpm? (Hz gives 60 times too low)"
        raise RotoridError(f"{label}: its fastest speed is {fastest:.3g} rpm {how}; imbalance runs below "
                           f"{MIN_RUN_RPM:g} rpm give no usable imbalance force")
    return track


#: revolutions whose timing uncertainty a grid speed takes when no revolution is within the
#: speed tolerance of it: the nearest in speed (a coast-down's last revolutions are far apart)
NEAREST_REVOLUTIONS = 5


def _keyphasor_phase_std(keyphasors, grid_rpm, tol_rpm, part="timing_std_each_s"):
    """(n,) phase uncertainty (degrees) at the grid speeds from the keyphasors' per-pulse timing
    uncertainty (``Keyphasor.timing_std_each_s``), or None when every pulse's is 0. At each speed:
    Omega times the mean over the pulses of a keyphasor within max(tol_rpm, 0.5 %) of it (a pulse
    shape's timing in seconds changes with speed), the largest over the keyphasors that reach it;
    a speed no keyphasor reaches takes, from each keyphasor, the mean angle Omega times sigma_t of
    the ``NEAREST_REVOLUTIONS`` nearest to it in speed, the largest of these (the median over all
    pulses, in seconds, gave the end of a coast-down to 1000 rpm, where the revolutions are 10-40
    rpm apart, 0.23 of its uncertainty).

    The mean, not the median: the timing errors are systematic (common to the pulses of a stretch),
    so the error of the 1X, a mean over the revolutions, is at most the mean of their sizes. A dwell
    whose last third was left uncorrected (0.12 sample) and the rest corrected (0.0004) was off by
    0.027 sample, against a median of 0.0004.

    A keyphasor whose pulses all time exactly (``timing_std_each_s`` None) counts as 0 at the
    speeds it reaches: left out, its speeds took the nearest revolutions of another dwell's, and a
    segmented test whose 6000 rpm dwell had 0.12 sample stated 0.42 degrees at every clean speed
    (found in review).

    ``part`` = "local_std_each_s" gives the part of it local to each dwell (a keyphasor whose
    pulses have none counts as 0)."""
    each = [k for k in keyphasors if k.times.size > 1]
    if not any(getattr(k, part) is not None for k in each):
        return None
    grid_rpm = np.asarray(grid_rpm, dtype=float)
    out = np.full(grid_rpm.size, np.nan)
    nearest = np.full(grid_rpm.size, np.nan)
    for k in each:
        rpm = k.speed_rpm
        std = np.zeros(k.times.size) if getattr(k, part) is None else getattr(k, part)
        s = 0.5 * (std[1:] + std[:-1])
        for i, g in enumerate(grid_rpm):
            # (revolutions whose timing uncertainty is unknown, NaN, are left out)
            gap = np.where(np.isfinite(s), np.abs(rpm - g), np.nan)
            near = gap <= max(tol_rpm, 0.005 * g)
            if near.any():
                out[i] = np.fmax(out[i], float(np.mean(s[near])))
            elif np.isfinite(gap).any():
                # as an angle (a fixed-angle feature's timing in seconds scales with 1/speed), moved
                # to this speed: the nearest revolutions may be 100 rpm or more away
                closest = np.argsort(gap, kind="stable")[:min(NEAREST_REVOLUTIONS, int(np.isfinite(gap).sum()))]
                nearest[i] = np.fmax(nearest[i], float(np.mean(s[closest] * rpm[closest])) / g)
    out = np.where(np.isnan(out), nearest, out)
    return np.rad2deg(grid_rpm * np.pi / 30.0 * out)


def _track_of(run, label, *, orders, steady, track_kw, keyphasor, pedestal=False):
    """A run as a SyncTrack: tracked from a (segmented) recording, or a SyncTrack already (a DAQ
    1X table, see rotorid.tables)."""
    if isinstance(run, signals.SyncTrack):
        return _plausible_speeds(run, run, label)
    if isinstance(run, (Recording, SegmentedRecording)):
        return _plausible_speeds(_labelled(lambda: signals.track(run, orders=orders, steady=steady, keyphasor=keyphasor,
                                                                 pedestal=pedestal, **track_kw), label, "order tracking"),
                                 run, label)
    raise RotoridError(f"{label} must be a Recording, SegmentedRecording or SyncTrack (1X table), got "
                       f"{type(run).__name__}")


def imbalance_chain(rotor: RigidRotor, runs, *, baseline=None, slow_roll=None, speeds_rpm=None, steady: bool = True,
                    imbalances=None, orders=(1, 2, 3), method: str = "forces", keyphasor=None,
                    speed_match_rpm: float | None = None, slow_roll_max_rpm: float | None = None,
                    points_per_rev=None, min_revs: int = 8, settle_revs: int = 2, speed_tolerance: float = 0.005,
                    revs_per_block: int | None = None, pedestal_motion: bool | None = None,
                    phase_calibration: str = "off", **ident_kw) -> ImbalanceChainResult:
    """Imbalance runs -> 1X vectors -> slow-roll and baseline compensation -> identification.

    Parameters
    ----------
    rotor : RigidRotor
    runs : list
        Recordings, SegmentedRecordings (one block per speed step) or SyncTracks (DAQ 1X tables
        from :func:`rotorid.tables.load_1x_table`), one per imbalance run.
    baseline, slow_roll : same kinds, optional
        Baseline subtraction (run minus the baseline run without added mass, at the same speeds)
        isolates the response to the added imbalance and removes remnant imbalance and 1X run-out
        together; slow-roll subtraction removes the run-out alone (use it when there is no
        baseline run). A slow-roll table gives its slowest row (or the mean of the rows up to
        ``slow_roll_max_rpm``).
    speeds_rpm : array_like, optional
        Common speed grid. Default: the first run's speeds (steady dwells or table rows) inside
        the range all runs share, each moved to the mean of the runs' and the baseline's dwell
        speeds there (where they are carried, see ``speed_match_rpm``); for coast-downs every 50
        rpm over that range.
    speed_match_rpm : float, optional
        How far (rpm) a run's measured speed (a dwell, a table row) and the baseline's may be from
        a grid speed; farther grid speeds are dropped with a warning (interpolating 1X vectors
        across the gap between dwells would invent data that no uncertainty accounts for). The
        dwells matched are carried to the grid speed through the rotor on the bearings being
        identified (:mod:`rotorid.speed_offsets`), the grid speed being the mean of theirs unless
        ``speeds_rpm`` is given. Default 0.5 % of the grid speed, at least 2 rpm; with pedestal
        motion (not carried: interpolated) 2 rpm. Coast-downs (``steady=False``) are interpolated
        over their common range.
    keyphasor : dict, optional
        Keyphasor options for every recording (see :func:`rotorid.signals.keyphasor_times`).
    points_per_rev, min_revs, settle_revs, speed_tolerance, revs_per_block
        Order-tracking options (see :func:`rotorid.signals.track`).
    pedestal_motion : bool, optional
        True: the bearings sit on flexible housings whose accelerometers (channels px1, px2, py1,
        py2 on every run and the baseline; pedestal columns of 1X tables) measure their motion;
        the probes, mounted on the housings, read the motion relative to them, and the
        identification uses both (report sec. on pedestal motion). False: accelerometer channels
        are ignored. None (default): an error if any run carries accelerometer channels, so they
        are never silently ignored.
    phase_calibration : {"off", "report", "apply"}
        Estimate a keyphasor angle offset and a probe-channel delay across speeds
        (:func:`rotorid.calibrate_phase`, with the phase scatter between speeds that it estimates
        from its misfit): "report" puts it in ``phase_calibration`` and ``notes`` (a warning when
        significant), its speeds weighted by the keyphasor's timing uncertainty local to each
        dwell, and keeps the scatter in the error bars; "apply" also corrects the vectors and
        identifies again, with the calibration's own uncertainty and the scatter in the error bars
        (in place of ``keyphasor_angle_std_deg``, ``keyphasor_delay_std_s`` and the pulse shape's
        part, which it estimates); there the scatter stands in for the keyphasor's local part
        common to the runs at a speed where it rests on ``MIN_SCATTER_DOF`` degrees of freedom
        (the local part stays in each recording's covariance). Where it cannot be made (fewer
        than 3 trustworthy speeds) a note says why (with "apply" also a warning) and the
        identification is the uncalibrated one.
    **ident_kw
        Passed to :func:`rotorid.identify_synchronous` (identical, cond_max, min_rel_amplitude,
        keyphasor_angle_std_deg, keyphasor_delay_std_s, ...). Where a keyphasor's pulse shape
        leaves its timing uncertain (``Keyphasor.timing_std_each_s``), Omega times it, at each
        speed the largest over the runs and the baseline, is added to ``keyphasor_angle_std_deg``
        (root sum of squares) and noted; its part local to each dwell
        (``Keyphasor.local_std_each_s``) is also a phase error of each recording's own vectors, in
        their covariance (the dwells of different recordings at one speed may err alike or each its
        own way: both are counted, but see ``phase_calibration``).

    Examples
    --------
    >>> import numpy as np, rotorid
    >>> from rotorid import pipeline, rawsim
    >>> rotor, brg, remnant = rawsim.example_rig()
    >>> rpm = [3000.0, 4000.0, 5000.0, 6000.0]
    >>> masses = {"S0": (0, 0), "C0": (0, 180), "S90": (90, 90), "C90": (90, 270)}
    >>> runs = [rawsim.lab_imbalance_recording(rotor, brg, speeds_rpm=rpm, remnant=remnant, mark_angle_deg=0.5,
    ...         added=rotorid.Imbalance((5e-3, 5e-3), a, name=n), seed=i, dwell_s=1.0)
    ...         for i, (n, a) in enumerate(masses.items())]
    >>> base = rawsim.lab_imbalance_recording(rotor, brg, speeds_rpm=rpm, remnant=remnant, mark_angle_deg=0.5,
    ...                                       added=None, seed=9, dwell_s=1.0)
    >>> import warnings
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore")
    ...     res = pipeline.imbalance_chain(rotor, runs, baseline=base, phase_calibration="apply")
    >>> round(res.phase_calibration.offset_deg, 1)
    0.5
    """
    from ._validate import choice, flag, number, real_array

    if isinstance(runs, (str, bytes)) or not hasattr(runs, "__iter__"):
        raise RotoridError(f"runs must be a list of recordings or 1X tables, got {type(runs).__name__}")
    runs = list(runs)
    if len(runs) == 0:
        raise RotoridError("no imbalance runs given")
    steady = flag("steady", steady)
    phase_calibration = choice("phase_calibration", phase_calibration, ("off", "report", "apply"))
    if isinstance(orders, (str, bytes, dict)):
        raise RotoridError(f"orders must be a tuple of whole numbers >= 1 holding 1 (the 1X), got {orders!r}")
    speed_match_rpm = number("speed_match_rpm", speed_match_rpm, positive=True, allow_none=True)
    slow_roll_max_rpm = number("slow_roll_max_rpm", slow_roll_max_rpm, positive=True, allow_none=True)
    if speeds_rpm is not None:
        speeds_rpm = np.atleast_1d(real_array("speeds_rpm", speeds_rpm, positive=True))
        if speeds_rpm.ndim != 1 or speeds_rpm.size == 0:
            raise RotoridError(f"speeds_rpm must be a non-empty 1-D list of speeds, got shape {speeds_rpm.shape}")
    if imbalances is not None and len(imbalances) != len(runs):
        raise RotoridError(f"imbalances gives {len(imbalances)} entries for {len(runs)} runs")
    notes = []
    labels = [f"run {i}" for i in range(len(runs))] + (["baseline"] if baseline is not None else [])
    ped = _pedestal_choice(pedestal_motion, runs + ([baseline] if baseline is not None else []), labels)
    track_kw = dict(points_per_rev=points_per_rev, min_revs=min_revs, settle_revs=settle_revs,
                    speed_tolerance=speed_tolerance, revs_per_block=revs_per_block)
    kw = dict(orders=orders, steady=steady, track_kw=track_kw, keyphasor=keyphasor, pedestal=ped)
    if not ped:
        # pedestal_motion=False: 1X tables' accelerometer columns are ignored too
        def rigid(r):
            if isinstance(r, signals.SyncTrack) and r.has_pedestal:
                return dataclasses.replace(r, pedestal=None, pedestal_cov=None, pedestal_cross=None)
            return r
        runs = [rigid(r) for r in runs]
        baseline = rigid(baseline)
        slow_roll = rigid(slow_roll)
    sr, sr_cov = None, None
    if slow_roll is not None:
        if isinstance(slow_roll, signals.SyncTrack):
            from .tables import slow_roll_vector as table_slow_roll

            sr = table_slow_roll(slow_roll, max_rpm=slow_roll_max_rpm)
        else:
            sr, sr_cov = signals.slow_roll_vector(slow_roll, orders=orders, keyphasor=keyphasor, return_cov=True,
                                                  **track_kw)
        notes.append(f"slow-roll run-out 1X: {np.round(np.abs(sr[0]) * 1e6, 2)} µm")
    tracks = [_track_of(r, f"run {i}", **kw) for i, r in enumerate(runs)]
    for i, t in enumerate(tracks):
        for k in t.keyphasors:
            notes.append(f"run {i} keyphasor: {k.summary()}")
            if k.note:
                warnings.warn(f"run {i} keyphasor: {k.note}")
    _check_live_probes(tracks, [f"run {i}" for i in range(len(tracks))], runs)
    orders_of = tracks[0].orders
    if any(t.orders != orders_of for t in tracks):
        raise RotoridError("all runs must carry the same orders (waveforms and 1X tables cannot be mixed)")
    if 1 not in orders_of:
        raise RotoridError(f"orders must include 1: the 1X vectors identify the coefficients, got orders {orders_of}")
    # with a baseline the slow roll cancels (run - sr - (baseline - sr)): its covariance does not count
    sr_cov_used = None if baseline is not None else sr_cov
    comp = [t.minus(sr[: len(t.orders)], sr_cov_used) if sr is not None else t for t in tracks]
    is_table = all(isinstance(r, signals.SyncTrack) for r in runs)
    dwells = speed_match_rpm is not None or is_table or steady
    # dwells and table rows on rigid supports: each run's and the baseline's vectors where they were
    # measured, carried to the common speeds through the rotor on the bearings being identified
    # (rotorid.speed_offsets), not interpolated between dwells
    carry = dwells and not ped and len({_probes_at(r) for r in runs + ([baseline] if baseline is not None else [])}) == 1
    # the matching tolerance: the user's (rpm), else 2 rpm, and where the runs are carried also
    # CARRY_MATCH of each grid speed (tol_rel)
    tol = 2.0 if speed_match_rpm is None else float(speed_match_rpm)
    tol_rel = CARRY_MATCH if carry and speed_match_rpm is None else 0.0
    pre = comp
    if baseline is not None:
        bt = _track_of(baseline, "baseline", **kw)
        bt_raw = bt
        bt = bt.minus(sr[: len(bt.orders)]) if sr is not None else bt
    if baseline is not None:
        if not carry:
            if steady or isinstance(baseline, signals.SyncTrack):
                # the baseline is interpolated to each run's speeds: only where it was measured close by
                comp = [_near_only(t, bt.speed_rpm, tol, f"run {i}", "the baseline") for i, t in enumerate(comp)]
            comp = [_labelled(lambda t=t: t.minus(bt), f"run {i}", "baseline subtraction") for i, t in enumerate(comp)]
        # (carried: subtracted after the runs and the baseline are carried to the grid speeds)
        notes.append("baseline subtracted (remnant imbalance and run-out removed)")
    elif sr is None:
        notes.append("no baseline and no slow-roll: remnant imbalance and run-out stay in the vectors")
        warnings.warn("imbalance chain without baseline or slow-roll compensation: remnant imbalance and run-out "
                      "stay in the 1X vectors")
    imbs = [_imbalance_of(r, None if imbalances is None else imbalances[i], f"run {i} ({type(r).__name__})")
            for i, r in enumerate(runs)]
    carried = None
    if dwells:
        # dwells and table rows: a common grid only where every run was measured within the tolerance
        # (interpolating 1X vectors across the gap between two dwells would invent data)
        from .tables import match_speeds

        def one_x(t):
            i1 = t.orders.index(1)
            pk = dict(pedestal=t.pedestal[:, i1:i1 + 1]) if ped else {}
            return signals.SyncTrack(t.speed_rpm, t.vectors[:, i1:i1 + 1], (1,), t.n_revs, t.scatter, t.t_mid, **pk)

        if carry:
            both = pre + ([bt] if baseline is not None else [])
            # (the baseline's dwells too: a grid speed is kept where every run and the baseline were
            # measured within the tolerance)
            recorded = [not isinstance(r, signals.SyncTrack) for r in runs + ([baseline] if baseline is not None else [])]
            candidates = speeds_rpm
            if candidates is None and recorded[0]:
                # a dwell split by a speed change within it (blocks within the tolerance of each
                # other) is one grid speed, not several that would reuse the other runs' dwells
                from .speed_offsets import merged_dwell_speeds

                candidates = merged_dwell_speeds(pre[0].speed_rpm, pre[0].n_revs, tol, tol_rel)
            grid = match_speeds([one_x(t) for t in both], grid=candidates, tolerance_rpm=tol, tolerance_rel=tol_rel)[0]
            carried = _carried_dwells(rotor, grid, pre, bt if baseline is not None else None,
                                      np.maximum(tol, tol_rel * grid), speeds_rpm is None, imbs, _probes_at(runs[0]),
                                      method, ident_kw, notes, runout=sr is None, longest=recorded)
            grid, qs = carried.grid, carried.q
            ped_on_grid = None
        else:
            matched = match_speeds([one_x(t) for t in comp], grid=speeds_rpm, tolerance_rpm=tol, pedestal=ped)
            grid, qs = matched[:2]
            ped_on_grid = matched[2] if ped else None
    else:
        if speeds_rpm is None:
            if steady:
                grid = comp[0].speed_rpm
            else:
                lo = max(t.speed_rpm.min() for t in comp)
                hi = min(t.speed_rpm.max() for t in comp)
                grid = np.arange(np.ceil(lo / 50) * 50, hi + 1e-9, 50.0)
        else:
            grid = np.asarray(speeds_rpm, float)
        qs = [_labelled(lambda t=t: t.at_speeds(grid)[:, t.orders.index(1), :], f"run {i}", "the common speed grid")
              for i, t in enumerate(comp)]
        ped_on_grid = [t.pedestal_at_speeds(grid)[:, t.orders.index(1), :] for t in comp] if ped else None
    # the keyphasor timing uncertainty local to each recording's dwells: a phase error of that
    # recording's vectors alone (the baseline's reaches every run through the subtraction)
    # (the pulses of a grid speed: within max(kp_tol, 0.5 %) of it, the matching tolerance the user
    # gave, else 2 rpm, as before the dwells were carried)
    kp_tol = 2.0 if speed_match_rpm is None else tol
    turns = [_local_phase_cov(t, grid, kp_tol, ped) for t in tracks]
    base_turn = _local_phase_cov(bt_raw, grid, kp_tol, ped) if baseline is not None else None
    responses = []
    for i, (r, q, t) in enumerate(zip(runs, qs, comp)):
        if carried is not None:
            cov, dof = carried.cov[i], carried.dof[i]
        else:
            cov, dof = _labelled(lambda t=t: t.cov_at_speeds(grid), f"run {i}", "the common speed grid")
        imb = imbs[i]
        at = _probes_at(r)
        # a name from the file keeps no extension (sync_vectors_0_plain.csv, not ..._plain.csv.csv)
        name = imb.name or getattr(r, "name", None) or \
            os.path.splitext(os.path.basename(getattr(r, "source", "") or ""))[0] or f"run {i}"
        pk = {}
        if ped:
            pc, cr = t.pedestal_cov_at_speeds(grid)
            pk = dict(pedestal=ped_on_grid[i], pedestal_cov=pc, pedestal_cross=cr)
            # where either covariance is unknown (NaN) the joint one is too: those points are flagged
            # "uncertainty unknown", as without pedestal motion; elsewhere the cross terms stay
        if cov is not None and np.isnan(cov).all() and not pk:
            own = getattr(r, "cov", None)
            if own is None or np.isnan(own).all():
                # no accuracy stated for this run (a DAQ table without amplitude_std / phase_std_deg):
                # it carries no covariance, so redundant runs give residual-based standard errors
                # rather than every point being "uncertainty unknown"
                cov = dof = None
            else:
                warnings.warn(f"run {i} ({name}): its stated accuracy is lost in the compensation because the baseline "
                              "or slow roll has none (give them amplitude_std / phase_std_deg too): its standard "
                              "errors are unknown")
        for add in (turns[i], base_turn):
            if add is None or cov is None:
                continue   # (without a covariance to go into, the common phase below still holds it)
            cov = cov + add["cov"]
            if pk:
                pk["pedestal_cov"] = pk["pedestal_cov"] + add["pedestal_cov"]
                pk["pedestal_cross"] = pk["pedestal_cross"] + add["pedestal_cross"]
        responses.append(SyncResponse(grid, q, imb, at, name, cov,
                                      None if dof is None else np.where(np.isnan(dof), np.inf, dof), **pk))
    if ped:
        ratio = max(float(np.nanmax(r.pedestal_ratio)) for r in responses)
        notes.append(f"pedestal motion from accelerometers px1, px2, py1, py2: up to {ratio:.2f} x the motion "
                     "relative to the housings")
    if baseline is not None and "shared_cov" not in ident_kw:
        # every run had the same baseline subtracted: its error is common to all runs
        if carried is not None:
            # (NaN, unknown, where the baseline states no accuracy: not passed on, as interpolated)
            shared = carried.shared if carried.shared is not None else np.full((grid.size, 8, 8), np.nan)
        else:
            shared, _ = _labelled(lambda: bt.cov_at_speeds(grid), "baseline", "the common speed grid")
        if base_turn is not None:
            shared = shared + base_turn["cov"]
        if ped:
            pc, cr = bt.pedestal_cov_at_speeds(grid)
            if base_turn is not None:
                pc, cr = pc + base_turn["pedestal_cov"], cr + base_turn["pedestal_cross"]
            joint = np.zeros((grid.size, 16, 16))
            joint[:, :8, :8], joint[:, 8:, 8:] = shared, pc
            joint[:, :8, 8:], joint[:, 8:, :8] = cr, np.swapaxes(cr, 1, 2)
            shared = joint
        # (a shared part is used with every run's own covariance only: identify_synchronous refuses
        # it otherwise)
        own = all(r.cov is not None and (not ped or r.pedestal_cov is not None) for r in responses)
        if np.all(np.isfinite(shared)) and own:
            ident_kw = dict(ident_kw, shared_cov=shared)
    kps = [k for t in tracks + ([bt] if baseline is not None else []) for k in t.keyphasors]
    shape_deg = _keyphasor_phase_std(kps, grid, kp_tol)
    local_deg = _keyphasor_phase_std(kps, grid, kp_tol, part="local_std_each_s")
    fixed_kw = dict(ident_kw)   # the phase reference as the user stated it
    if shape_deg is not None:
        # pulses whose timing their shape leaves uncertain: a phase error common to every run (the
        # same sensor and convention), added to the phase reference's uncertainty at each speed. Its
        # part local to each dwell is also in each recording's covariance (above): where the pulses
        # fall between samples, the dwells of different recordings at one speed err alike (the mean
        # interpolation error over the positions, at 3000 rpm and 10,240 Hz 0.13 degree in every
        # run, 0.007 apart) or each its own way (4000 rpm: 0.09 degree apart), so both are counted
        stated = real_array("keyphasor_angle_std_deg", ident_kw.get("keyphasor_angle_std_deg", 0.0), nonneg=True)
        if stated.ndim > 1 or stated.size not in (1, grid.size):
            raise RotoridError(f"keyphasor_angle_std_deg must be a number or one per speed ({grid.size}), got shape "
                               f"{stated.shape}")
        ident_kw = dict(ident_kw, keyphasor_angle_std_deg=np.hypot(stated, shape_deg))
        local = "" if local_deg is None else (
            f"; up to {local_deg.max():.3g} degrees of it local to each recording's dwells (where the pulses fall "
            "between samples, noise: in that recording's 1X covariance, and not taken out by a phase calibration)")
        notes.append(f"keyphasor timing depends on the pulse shape by {shape_deg.min():.3g}-{shape_deg.max():.3g} "
                     "degrees of 1X phase at these speeds: counted in the uncertainty as a phase reference error "
                     f"(a phase calibration, or a trigger level of your own, takes out what is common to the dwells){local}")
    ident = identify_synchronous(rotor, responses, method=method, **ident_kw)
    cal = phase = None
    if phase_calibration != "off":
        responses, ident, cal, phase = _phase_calibrated(rotor, responses, ident, method, fixed_kw, local_deg,
                                                         phase_calibration == "apply", notes, ident_kw)
    if carried is not None and carried.unresolved.any():
        from .speed_offsets import SPEED_OFFSETS_UNRESOLVED

        ident = _with_flag(ident, carried.unresolved, SPEED_OFFSETS_UNRESOLVED)
    return ImbalanceChainResult(responses, tracks, ident, notes, ident_kw.get("shared_cov"),
                                None if sr is None else np.asarray(sr[0]), shape_deg, local_deg, cal,
                                _stated_phase_kw(ident_kw) if phase is None else phase)


def _phase_calibrated(rotor, responses, ident, method, ident_kw, local_deg, apply, notes, used_kw=None):
    """The chain's phase-reference calibration: (responses, identification, PhaseCalibration or
    None, the phase reference's uncertainty as :func:`rotorid.identify_pedestals` takes it where
    the calibration set the identification's, else None), the first two corrected when ``apply``.

    Reported only, what the calibration found is an uncertainty of the vectors as measured, not a
    correction (:func:`_reported_phase_std`): the size of the phase error theta - Omega tau it
    finds where larger than the phase uncertainty ``used_kw`` gave ``ident``, and the phase scatter between
    speeds it estimates from its misfit (``PhaseCalibration.scatter_deg``: phase errors of each
    speed alone beyond the stated uncertainty; 1X tables without a covariance, RC keyphasor edges
    of 0.5 sample at 10,240 Hz, no mark offset: coverage 0.81 without it); the runs are then
    identified again.

    What the user stated for the phase reference (``keyphasor_angle_std_deg``,
    ``keyphasor_delay_std_s``) and the part of the keyphasors' timing uncertainty common to their
    dwells (the pulse shape's) are what the calibration estimates: its own uncertainty replaces
    them. The part local to each dwell (``local_deg``, deg per grid speed) is a phase error of that
    speed alone, which theta - Omega tau cannot follow; as each recording's own it is in their
    covariances, which turn with the vectors. Where the dwells of different recordings at one
    speed err alike (3000 rpm at 10,240 Hz: every run 0.13 degree), it is also a phase common to
    the runs at that speed. The calibration's phase scatter between speeds stands in for that copy,
    applied or reported, where at least ``MIN_SCATTER_DOF`` degrees of freedom carry the scatter
    (applied, measured over 20 trials in 9 setups, RC keyphasor edges of 0.5 sample and others:
    coverage as with the copy, 0.978-0.997, and 91 % of the points ok instead of 61 %; reported,
    see the README's Uncertainty); with fewer, the copy weights the calibration and stays in the
    error bars beside its own uncertainty. Before 2026-11-29 (fourth part) the local
    part was dropped once applied and the calibration not weighted by it: RC keyphasor edges of
    0.5 sample at 10,240 Hz with a 0.3 degree mark offset gave the damping's 95 % intervals 48 %
    coverage (0.003-0.006 degree stated; the calibration 5-7 of its standard errors off in 2 of 6
    trials, pulled by 3000 rpm)."""
    from .phasecal import calibrate_phase

    own = {k: v for k, v in ident_kw.items() if k not in ("keyphasor_angle_std_deg", "keyphasor_delay_std_s")}
    local = {} if local_deg is None else dict(keyphasor_angle_std_deg=local_deg)
    stand_in = False    # the scatter stands in for the local part's common copy
    try:
        cal = None
        if local_deg is not None:
            try:
                trial = calibrate_phase(rotor, responses, method=method, **own)
            except RotoridError:
                trial = None     # (weighted by the local part below, it may still be made)
            if trial is not None and trial.scatter_dof >= MIN_SCATTER_DOF:
                cal, stand_in = trial, True
        if cal is None:
            cal = calibrate_phase(rotor, responses, method=method, **own, **local)
    except RotoridError as exc:
        notes.append(f"phase reference not calibrated: {exc}")
        if apply:
            # asked to correct, the user must not take the uncalibrated coefficients for corrected ones
            warnings.warn(f"phase_calibration = \"apply\": the phase reference could not be calibrated ({exc}); the "
                          "coefficients are identified from the vectors as measured")
        return responses, ident, None, None
    notes.append(cal.message)
    if not apply:
        if used_kw is not None:
            rpm = responses[0].speed_rpm
            # the stated phase uncertainty at each speed, the angle's and the delay's together as
            # identify_synchronous takes them: one common phase error per speed, which the
            # calibration's finding may take the place of
            ref = _phase_reference_std(rpm, used_kw.get("keyphasor_angle_std_deg", 0.0),
                                       used_kw.get("keyphasor_delay_std_s", 0.0))
            stated = np.zeros(rpm.shape) if ref is None else np.rad2deg(ref) * np.ones(rpm.shape)
            phase, why = _reported_phase_std(cal, rpm, stated, local_deg, stand_in=stand_in)
            if why:
                ident = identify_synchronous(rotor, responses, method=method, **{
                    **used_kw, "keyphasor_angle_std_deg": phase, "keyphasor_delay_std_s": 0.0})
                notes.append(f"{'; '.join(why)}: in the error bars; the calibration itself is reported, not applied")
                # the pedestal fit: the line found, as measured (its second moment, its uncertainty
                # taken out as the bearings' moment estimate does) beside what was stated
                v = np.array([cal.offset_deg, cal.delay_s])
                found = _psd_part(np.outer(v, v) - cal.line_cov(), float(np.max(rpm)) * RPM)
                return responses, ident, cal, dict(_stated_phase_kw(used_kw), phase_line_cov=found,
                                                   phase_scatter_std_deg=_drawn_anew(cal, rpm, local_deg, stand_in))
        return responses, ident, cal, None
    responses = cal.apply(responses)
    rpm = responses[0].speed_rpm
    std = cal.phase_std_deg(rpm)
    phase = std if stand_in or local_deg is None else np.hypot(std, local_deg)
    ident = identify_synchronous(rotor, responses, method=method, **own, keyphasor_angle_std_deg=phase)
    kept = (["its uncertainty"] + (["the phase scatter between speeds it estimated"] if cal.scatter_deg > 0 else [])
            + ([f"the own phase errors of the speeds off its line ({_rpm_list(cal.outlier_speeds_rpm)})"]
               if cal.outlier_speeds_rpm else []))
    local_note = ("" if local_deg is None else
                  ", with the keyphasor's local to each dwell in each recording's covariance" if stand_in else
                  ", with the keyphasor's local to each dwell, in each recording's covariance and common to the runs")
    notes.append(f"phase calibration applied to the 1X vectors ({' and '.join(kept)} in the error bars{local_note})")
    # the pedestal fit: the calibrated line's uncertainty replaces what was stated
    return responses, ident, cal, dict(phase_line_cov=cal.line_cov(),
                                       phase_scatter_std_deg=_drawn_anew(cal, rpm, local_deg, stand_in))


def _stated_phase_kw(ident_kw):
    """The phase reference's uncertainty the identification was given (``keyphasor_angle_std_deg``,
    with the keyphasor pulse shape's, and ``keyphasor_delay_std_s``), as the pedestal fit takes it."""
    return dict(keyphasor_angle_std_deg=ident_kw.get("keyphasor_angle_std_deg", 0.0),
                keyphasor_delay_std_s=ident_kw.get("keyphasor_delay_std_s", 0.0))


def _psd_part(m, om_max):
    """The positive semi-definite part of a symmetric (2, 2) matrix of (offset deg, delay s),
    taken in units where both are phases (deg, and deg at the top speed ``om_max``)."""
    from .phasecal import _line_scale

    scale = _line_scale(om_max)
    w, v = np.linalg.eigh(m * scale[:, None] * scale[None, :])
    return ((v * np.clip(w, 0.0, None)) @ v.T) / scale[:, None] / scale[None, :]


def _drawn_anew(cal, rpm, local_deg, stand_in):
    """The part of a calibration's phase uncertainty drawn anew at each speed (deg): the phase
    scatter between speeds and, where it does not stand in for it, the keyphasor's part local to
    each dwell."""
    loc2 = 0.0 if (stand_in or local_deg is None) else np.nan_to_num(np.asarray(local_deg, dtype=float)) ** 2
    return np.minimum(np.sqrt(cal.scatter_std_deg(rpm) ** 2 + loc2), MAX_REPORTED_PHASE_DEG)


def _reported_phase_std(cal, rpm, stated, local_deg, stand_in):
    """The phase uncertainty (deg per speed) of the vectors as measured with a phase calibration
    that is reported, not applied, and what it adds (a list of phrases for the note, empty where
    it adds nothing).

    ``stated``: the chain's (the user's angle and delay, the keyphasor pulse shape's, which holds the
    part local to each dwell ``local_deg`` as a phase common to the runs at a speed). Three things of the
    calibration's enter:

    - the phase error it found: left in the vectors, it is an error of the coefficients. Its size
      estimated from e = theta - Omega tau and e's uncertainty s_line, sqrt(max(e² - s_line², 0))
      (a moment estimate, as the scatter's, truncated at 0: a calibration that finds nothing adds
      nothing), takes the place of the stated common part where it is larger (a keyphasor mark
      0.3 degree off, found 17 standard errors away: 61 % of the points ok under "report" and none
      of them covered, 20 trials of the chain, before 2026-11-29, sixth part; the larger, not the
      sum, of two estimates of one error; sqrt(e² + s_line²), tried first, turned clean points
      "uncertain" where nothing was stated: at 10,000 Hz 39 -> 21 % ok, found in review);
    - the phase scatter between speeds and the outlying speeds' own (one speed 0.4 degree off among
      15, only the scatter added: its coefficients covered 5 %, found in review);
    - where the scatter rests on ``MIN_SCATTER_DOF`` or more (``stand_in``), it stands in for the
      local part's common copy, which leaves the stated part (it stays in each recording's
      covariance)."""
    loc2 = 0.0 if local_deg is None else np.nan_to_num(np.asarray(local_deg, dtype=float)) ** 2
    common = np.sqrt(np.clip(stated ** 2 - loc2, 0.0, None))
    found = np.sqrt(np.clip(cal.error_deg(rpm) ** 2 - cal.line_std_deg(rpm) ** 2, 0.0, None))
    scatter = cal.scatter_std_deg(rpm)
    phase = np.sqrt(np.fmax(common, found) ** 2 + (0.0 if stand_in else loc2) + scatter ** 2)
    why = []
    if np.any(found > common):
        why.append(f"the phase reference error the calibration found (up to {found.max():.3g} deg at these speeds, "
                   "where larger than stated" + (f"; counted as {MAX_REPORTED_PHASE_DEG:g} deg where beyond: such "
                                                 "coefficients mean little" if np.any(phase > MAX_REPORTED_PHASE_DEG)
                                                 else "") + ")")
    phase = np.minimum(phase, MAX_REPORTED_PHASE_DEG)
    if cal.scatter_deg > 0 or cal.outlier_speeds_rpm or stand_in:
        why.append(f"the phase scatter between speeds ({cal.scatter_deg:.3g} deg"
                   + (f"; the speeds off the line with their own: {_rpm_list(cal.outlier_speeds_rpm)}"
                      if cal.outlier_speeds_rpm else "")
                   + (", standing in for the keyphasor's local to each dwell as common to the runs; that part "
                      "stays in each recording's covariance" if stand_in else "")
                   + ")")
    return phase, why


#: the largest phase uncertainty a reported calibration puts in the error bars (deg; the
#: identification takes less than 45): a mark 60 degrees off would have refused the whole chain
MAX_REPORTED_PHASE_DEG = 44.0


def _rpm_list(speeds):
    """'4500, 6000 rpm' for a note."""
    return ", ".join(f"{s:g}" for s in speeds) + " rpm"


#: the degrees of freedom of an applied calibration's phase scatter from which it stands in for the
#: keyphasors' local timing uncertainty common to the runs at a speed (7 speeds give 4)
MIN_SCATTER_DOF = 3


def _local_phase_cov(track, grid, tol, pedestal):
    """What a recording's keyphasor timing uncertainty local to its dwells adds to the covariance of
    its 1X vectors at the grid speeds, or None where it has none.

    A phase error e of the recording turns its vector q (and the pedestal motion p) by e^{je}:
    d[Re q, Im q] / de = [-Im q, Re q] = v, so the covariance grows by s_e^2 v v^T (``cov``), with
    u from p likewise s_e^2 u u^T (``pedestal_cov``) and s_e^2 v u^T (``pedestal_cross``); s_e is the
    recording's own share at each speed (:func:`_keyphasor_phase_std`, "local_std_each_s"), q the
    1X of its block nearest in speed."""
    sd = _keyphasor_phase_std(track.keyphasors, grid, tol, part="local_std_each_s")
    if sd is None or not np.any(sd > 0):
        return None
    s2 = np.deg2rad(np.nan_to_num(sd)) ** 2
    near = np.argmin(np.abs(track.speed_rpm[:, None] - np.asarray(grid)[None, :]), axis=0)
    i1 = track.orders.index(1)

    def tangent(z):
        return np.concatenate([-z.imag, z.real], axis=1)

    v = tangent(track.vectors[near, i1, :])
    out = dict(cov=s2[:, None, None] * v[:, :, None] * v[:, None, :])
    if pedestal:
        u = tangent(track.pedestal[near, i1, :])
        out.update(pedestal_cov=s2[:, None, None] * u[:, :, None] * u[:, None, :],
                   pedestal_cross=s2[:, None, None] * v[:, :, None] * u[:, None, :])
    return out


@dataclass
class ImpactChainResult:
    tests: list              # ImpactResponse per (plane, direction) group
    frfs: list               # signals.FRF per group (with coherence)
    used: list               # per group: list of (source, impact time s)
    dropped: list            # (source, time s, reason)
    identification: Identification
    kcm: object = None       # KCMFit over kcm_band_hz (jackknife over impacts), when asked
    poolings: list = field(default_factory=list)  # impact_noise.Pooling per group of 2+ impacts, else None


def impact_segments(rec: Recording, *, record_s: float = 0.25, pre_s: float = 0.01, revs_before: int = 8,
                    runout: bool = True, kp: signals.Keyphasor | None = None, points_per_rev: int = 256,
                    exp_window_tau_s: float | None = None, detect=None, pedestal: bool = False):
    """Force and (run-out filtered) response segments of every clean impact of a recording.

    Returns (forces, responses, used_times, dropped): equally long records starting ``pre_s`` before
    each impact. The run-out filter subtracts the synchronous revolution signature of the
    ``revs_before`` revolutions preceding the impact (run-out and remnant-imbalance response).
    ``exp_window_tau_s``: multiply force and response by exp(-(t - t_impact)/tau) (the FRFs are then
    at s = 1/tau + j w, which ``impact_chain`` passes on to the identification).
    ``detect``: options of :func:`rotorid.signals.detect_impacts` (a dict, optional).
    ``pedestal``: the responses also hold the housing accelerometers px1, px2, py1, py2 (rows 4-7,
    m/s², run-out filtered alike: the filter removes their synchronous vibration)."""
    forces, responses, used, dropped, _ = _impact_segments(
        rec, record_s=record_s, pre_s=pre_s, revs_before=revs_before, runout=runout, kp=kp,
        points_per_rev=points_per_rev, exp_window_tau_s=exp_window_tau_s, detect=detect, pedestal=pedestal)
    return forces, responses, used, dropped


def _impact_noise_of(rec, channels, lo, hi, signature, n_seg, f, y, pre, fw):
    """The :class:`rotorid.impact_noise.ImpactNoise` (or None) of an impact's records ``f``, ``y``
    (``pre`` samples before the impact, force window ``fw``), measured on samples lo..hi of the
    recording ``rec`` (:func:`_quiet_stretch`): run-out filtered with ``signature`` = (keyphasor,
    revolution signature) when given, else less the mean of each segment's first ``pre`` samples
    as the record was."""
    return impact_noise.impact_noise(f, y, pre, fw, _quiet_stretch(rec, channels, lo, hi, n_seg, signature),
                                     demean=signature is None)


def _quiet_stretch(rec, channels, lo, hi, n_seg, signature):
    """(response (C, L), force (L,)) of samples lo..hi of the recording ``rec``'s ``channels`` and
    force: the last ``QUIET_SEGMENTS`` half-overlapping records of it and the samples their force's
    resting level is taken from, the response run-out filtered with ``signature`` = (keyphasor,
    revolution signature) when given; missing samples NaN (the filter's too, outside the
    keyphasor's pulses). None where no more than a record is left."""
    lo = max(lo, 0, hi - (impact_noise.QUIET_SEGMENTS + 1) * n_seg // 2 - impact_noise.FORCE_REST_SAMPLES - n_seg)
    if hi - lo <= n_seg:
        return None
    x = np.stack([rec.channels[c][lo:hi] for c in channels])
    force = np.array(rec.channels["force"][lo:hi], dtype=float)
    if signature is not None:
        kp, tmpl = signature
        missing = ~np.isfinite(x)
        # the filter refuses non-finite samples; it subtracts sample by sample, so zeros stand in for
        # them and they are missing again after it
        y = signals.runout_filter(np.where(missing, 0.0, x), rec.fs_hz, kp.times, tmpl, 0, hi - lo,
                                  t0_s=rec.t0_s + lo / rec.fs_hz)
        x = np.where(missing, np.nan, y)
    return x, force


def _impact_segments(rec, *, record_s, pre_s, revs_before, runout, kp, points_per_rev, exp_window_tau_s, detect,
                     pedestal):
    """:func:`impact_segments`, and per impact (a function of no arguments giving the noise of its
    records (:class:`rotorid.impact_noise.ImpactNoise` or None), measured on the recording's quiet
    stretch before it; whether that stretch follows an earlier impact of the recording)."""
    from ._validate import flag, index, instance, mapping, number

    instance("rec", rec, Recording, what="rotorid.Recording (one impact recording)")
    record_s = number("record_s", record_s, positive=True)
    pre_s = number("pre_s", pre_s, nonneg=True)
    revs_before = index("revs_before", revs_before, 0)
    runout = flag("runout", runout)
    instance("kp", kp, signals.Keyphasor, allow_none=True, what="rotorid.signals.Keyphasor")
    exp_window_tau_s = number("exp_window_tau_s", exp_window_tau_s, positive=True, allow_none=True)
    detect = mapping("detect", detect)
    unknown = sorted(str(k) for k in detect if k not in _DETECT_OPTIONS)
    if unknown:
        raise RotoridError(f"detect: unknown option(s) {unknown}; known: {list(_DETECT_OPTIONS)}")
    pedestal = flag("pedestal", pedestal)
    channels = DISPLACEMENTS + (ACCELEROMETERS if pedestal else ())
    rec.require("force", *channels)
    fs = rec.fs_hz
    if not pre_s < record_s:
        raise RotoridError(f"need record_s > 0 and 0 <= pre_s < record_s, got record_s={record_s!r}, pre_s={pre_s!r}")
    n_seg = int(round(record_s * fs))
    pre = int(round(pre_s * fs))
    imps = signals.detect_impacts(rec.channels["force"], fs, **detect)
    if runout:
        rec.require("kp")
        kp = kp if kp is not None else signals.order.detect_keyphasor(rec)
    x = np.stack([rec.channels[c] for c in channels])
    forces, responses, used, dropped, noises = [], [], [], [], []
    kept_before = False          # an earlier impact of this recording was kept
    for j, imp in enumerate(imps):
        t_imp = rec.t0_s + imp.start / fs
        if not imp.ok:
            dropped.append((rec.source, t_imp, ", ".join(imp.flags)))
            continue
        a = imp.start - pre
        b = a + n_seg
        nxt = imps[j + 1].start if j + 1 < len(imps) else rec.n_samples
        if a < 0 or b > rec.n_samples or b > nxt - pre:
            dropped.append((rec.source, t_imp, f"less than record_s = {record_s:g} s of clean record around it"))
            continue
        # the quiet stretch before the impact, whose noise stands for its record's: from a record's
        # length after the previous impact's last pulse (a merged group of hits rings from its last)
        # up to this record or, with the run-out filter, up to the revolutions its signature is
        # taken from (their noise is in the signature)
        quiet_from = imps[j - 1].stop - pre + n_seg if j > 0 else 0
        if runout:
            period = 60.0 / np.median(kp.speed_rpm)
            t_end = rec.t0_s + a / fs
            # the signature must hold no strong response to the previous hit: the first half of that
            # hit's record (record_s, in which its response is taken to die out) must end before the
            # window begins (the independent simulator's hits 0.3 s apart gave K off by 23 % and C
            # by 43 % at 2000 rpm, 153 % and 261 % at 1000 rpm, with points ok; 0.5 s apart at 2000
            # rpm, 2.8 and 3.1 %, only the tail of the record in the window: kept)
            win = a - int(np.ceil((revs_before + 1) * period * fs))
            if j > 0 and imps[j - 1].start + n_seg // 2 > win:
                gap = (revs_before + 1) * period + 0.5 * record_s + pre_s
                dropped.append((rec.source, t_imp, f"the response to the previous hit (t = "
                                f"{rec.t0_s + imps[j - 1].start / fs:.4f} s) reaches into the {revs_before} revolutions "
                                f"before this one, which the run-out filter takes as run-out: space the hits at least "
                                f"{gap:.2f} s apart (or lower revs_before or record_s)"))
                continue
            try:
                tmpl = signals.revolution_signature(x, fs, kp.times, t_end - (revs_before + 1) * period, t_end,
                                                    t0_s=rec.t0_s, points_per_rev=points_per_rev)
            except RotoridError as exc:
                dropped.append((rec.source, t_imp, str(exc)))
                continue
            y = signals.runout_filter(x, fs, kp.times, tmpl, a, b, t0_s=rec.t0_s)
            if not np.all(np.isfinite(y)):
                dropped.append((rec.source, t_imp, "keyphasor pulses do not cover the record"))
                continue
            quiet = (quiet_from, win, (kp, tmpl))
        else:
            y = x[:, a:b] - x[:, a:a + pre].mean(axis=1, keepdims=True) if pre > 0 else x[:, a:b]
            quiet = (quiet_from, a, None)
        if imp.peak_N < 0:
            raise RotoridError(f"impact recording {rec.source!r}: the force channel's impact at t = {t_imp:.4f} s peaks "
                               f"at {imp.peak_N:.4g} N; a hammer pushes, which a force transducer reads as positive: the "
                               "channel's polarity is inverted (give it scale = -1 in the channel map)")
        # the force transducer's resting level (a charge amplifier's offset or drift): the median of
        # the clean record before the impact, subtracted so that the window does not turn it into
        # spectral content (a 1 % offset cost 10-18 % in K and C)
        prev = imps[j - 1].stop if j > 0 else 0
        rest = rec.channels["force"][max(prev, imp.start - max(pre, impact_noise.FORCE_REST_SAMPLES)):imp.start]
        f0 = float(np.median(rest)) if rest.size >= 8 else 0.0
        fw = signals.force_window(n_seg, 0, imp.stop - a + pre, taper=0)
        f = (rec.channels["force"][a:b] - f0) * fw
        # measured when asked for (a test's single impact, or a recording's first kept hit in a test
        # of several): the quiet stretch's segments would hold 15 records per impact
        if j > 0 and not kept_before and imps[0].start - pre > quiet[1] - quiet[0]:
            # every earlier impact of the recording was dropped (a rebound, an overload): the quiet
            # record before the first of them, where longer, stands for this one's, with no hit's
            # tail in it (a dropped first hit left a test of two hits on the scatter's 1 dof beside
            # a second of quiet, review)
            quiet = (0, imps[0].start - pre, quiet[2])
        # with whether its quiet stretch follows an earlier hit, whose tail may still ring in it
        noises.append((functools.partial(_impact_noise_of, rec, channels, *quiet, n_seg, f, y, pre, fw),
                       j > 0 and quiet[0] > 0))
        kept_before = True
        if exp_window_tau_s is not None:
            ew = signals.exponential_window(n_seg, fs, exp_window_tau_s, start=pre)
            f = f * ew
            y = y * ew[None, :]
        forces.append(f)
        responses.append(y)
        used.append((rec.source, t_imp))
    return forces, responses, used, dropped, noises


#: the most impacts per test whose error bars, from their scatter alone for want of quiet record
#: before the first hit, draw a warning (Student's t of 12.7 and 4.3 for 95 % at 1 and 2 dof)
MAX_HITS_ADVISED = 3


#: a test's impact records end too soon when the rms of their last tenth, above the noise before the
#: impact, exceeds this fraction of their peak (median over the impacts, largest over the probes):
#: 0.1 s records of the NSF rig, 0.16 (K off by 16 %, C by 23 %, every point ok, an independent
#: simulator's finding); 0.25 s records or 0.1 s with a 30 ms exponential window, 0.014-0.02
DECAYED = 0.05


def _undecayed(responses, pre):
    """How much of a test's response is left at the end of its records: per impact and probe, the
    rms of the record's last tenth (less the noise of its ``pre`` samples before the impact, in
    quadrature) over the probe's peak (each FRF column leaks in proportion to its own response: an
    x hit's y response, ~1/8 of the x one on the rig, is the one that rings longest); the largest
    over the probes whose peak stands 20 noise widths clear (a probe that hardly responds would
    weigh the noise estimate's own scatter against a small peak), the median over the impacts."""
    y = np.asarray(responses)[:, :4, :]
    n = y.shape[2]
    tail = np.mean(y[:, :, int(0.9 * n):] ** 2, axis=2)
    noise = np.mean((y[:, :, :pre] - y[:, :, :pre].mean(axis=2, keepdims=True)) ** 2, axis=2) if pre >= 8 else 0.0
    peak = np.abs(y).max(axis=2)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.sqrt(np.maximum(tail - noise, 0.0)) / peak
    r = np.where(peak ** 2 >= 400.0 * noise, r, 0.0)
    return float(np.median(np.nanmax(r, axis=1)))


_DETECT_OPTIONS = ("threshold_N", "min_separation_s", "double_hit_window_s", "double_hit_fraction", "overload_N")

#: longest zero-padded impact record (samples) the impact chain transforms (8 MB per channel)
MAX_FFT_SAMPLES = 1 << 20


def _delay_rotation(phase):
    """Real (n, 2C, 2C) map of [Re, Im] (grouped per 4 channels) for multiplying channel j by
    e^{j phase[:, j]}."""
    n, C = phase.shape
    R = np.zeros((n, 2 * C, 2 * C))
    c, s = np.cos(phase), np.sin(phase)
    for j in range(C):
        g, k = divmod(j, 4)
        re, im = 8 * g + k, 8 * g + 4 + k
        R[:, re, re], R[:, re, im], R[:, im, re], R[:, im, im] = c[:, j], -s[:, j], s[:, j], c[:, j]
    return R


def _impact_response(frf, sel, speed, plane, direction, at, sigma, name, delays=None, extra_var=None) -> ImpactResponse:
    """The ImpactResponse of an averaged H1 over the band ``sel``; with 8 channels the last four
    are housing accelerometers, whose FRFs A become pedestal displacement FRFs A / s² with
    s = sigma + j w (their covariance mapped alike). ``delays`` (C,): each response channel's
    delay less the force channel's (s); the FRFs are advanced by e^{j w delay}. ``extra_var``
    (n_band, C): a variance of each FRF column's error of any phase (split evenly between its real
    and imaginary parts) added to the covariance (:func:`rotorid.impact_noise.truncation_var`)."""
    h = frf.h[sel]
    cov = None if frf.cov is None else frf.cov[sel]
    dof = None if cov is None else np.full(cov.shape[0], frf.dof)
    if cov is not None and extra_var is not None:
        cov = cov.copy()
        re = impact_noise.real_rows(h.shape[1])
        dof = impact_noise.with_truncation_dof(cov, extra_var, frf.dof)
        cov[:, re, re] += 0.5 * extra_var
        cov[:, re + 4, re + 4] += 0.5 * extra_var
    if delays is not None and np.any(delays):
        # measured x(t - d) has the spectrum X e^{-j w d}: undo it (the exponential window's decay
        # rate sigma does not change the phase of a pure delay's correction at s = sigma + j w
        # beyond the factor e^{sigma d}, a gain that is applied too)
        om = 2 * np.pi * frf.freq_hz[sel]
        h = h * np.exp((sigma + 1j * om)[:, None] * delays[None, :])
        if cov is not None:
            R = _delay_rotation(om[:, None] * delays[None, :])
            gain = np.exp(sigma * delays)
            G = np.concatenate([gain[g:g + 4] for g in range(0, delays.size, 4) for _ in (0, 1)])
            R = R * G[None, :, None]
            cov = R @ cov @ np.swapaxes(R, 1, 2)
    if h.shape[1] == 4:
        return ImpactResponse(speed_rpm=speed, freq_hz=frf.freq_hz[sel], q=h, plane=plane, direction=direction, at=at,
                              name=name, sigma=sigma, cov=cov, dof=dof)
    s = sigma + 2j * np.pi * frf.freq_hz[sel]
    g = 1.0 / s ** 2                                     # displacement per acceleration
    p = h[:, 4:] * g[:, None]
    pk = dict(pedestal=p)
    if cov is not None:
        # [Re p, Im p] = [[gr, -gi], [gi, gr]] [Re a, Im a] per channel
        L = np.zeros((g.size, 16, 16))
        L[:, np.arange(8), np.arange(8)] = 1.0
        for j in range(4):
            L[:, 8 + j, 8 + j], L[:, 8 + j, 12 + j] = g.real, -g.imag
            L[:, 12 + j, 8 + j], L[:, 12 + j, 12 + j] = g.imag, g.real
        joint = L @ cov @ np.swapaxes(L, 1, 2)
        joint = 0.5 * (joint + np.swapaxes(joint, 1, 2))
        cov = joint[:, :8, :8]
        pk.update(pedestal_cov=joint[:, 8:, 8:], pedestal_cross=joint[:, :8, 8:])
    return ImpactResponse(speed_rpm=speed, freq_hz=frf.freq_hz[sel], q=h[:, :4], plane=plane, direction=direction,
                          at=at, name=name, sigma=sigma, cov=cov, dof=dof, **pk)


@dataclass
class _ImpactGroup:
    """The clean impacts of one test (plane, direction) over its recordings: per impact its force
    and response records, (source, time) and noise (:func:`_impact_segments`); the test's channel
    delays relative to the force (s), one set for all its recordings."""

    delays: np.ndarray
    forces: list = field(default_factory=list)
    responses: list = field(default_factory=list)
    used: list = field(default_factory=list)
    noises: list = field(default_factory=list)


def impact_chain(rotor: RigidRotor, recordings, *, band_hz=(5.0, 150.0), record_s: float = 0.25, runout: bool = True,
                 identical: bool = False, method: str = "forces", tests_meta=None, exp_window_tau_s: float | None = None,
                 pre_s: float = 0.01, zero_pad_s: float | None = None, revs_before: int = 8, points_per_rev: int = 256,
                 keyphasor=None, speed_rpm: float | None = None, coherence_min: float = 0.9, threshold_N=None,
                 min_separation_s: float = 0.2, double_hit_window_s: float = 0.02, overload_N=None,
                 kcm_band_hz=None, pedestal_motion: bool | None = None, **ident_kw) -> ImpactChainResult:
    """Impact recordings -> impact detection -> run-out filter -> H1 FRFs per test (plane, direction),
    averaged over all clean impacts -> frequency-dependent identification over ``band_hz``.

    Parameters
    ----------
    record_s, pre_s : float
        Length of each impact record and how much of it precedes the impact (s). Long enough for
        the response to decay, no longer: past the decay a record adds only probe noise (0.25 s
        suits modes above ~15 Hz with 10 % damping; the frequency resolution is 1/record_s).
    zero_pad_s : float, optional
        FFT length (s, >= record_s): zero padding interpolates the FRFs on a finer grid.
    exp_window_tau_s : float, optional
        Exponential window on force and response (for records that end before the response has
        decayed); its decay 1/tau is accounted for in the identification (s = 1/tau + j w).
    runout, revs_before, points_per_rev
        The report's time-domain run-out filter and its signature (revolutions, resolution).
    keyphasor : dict, optional
        Keyphasor options (see :func:`rotorid.signals.keyphasor_times`).
    speed_rpm : float, optional
        Running speed when the recordings carry no keyphasor (needs ``runout=False``); with a
        keyphasor it is measured.
    coherence_min : float
        Coherence below which a warning names the channel and frequency.
    threshold_N, min_separation_s, double_hit_window_s, overload_N
        Impact detection (see :func:`rotorid.signals.detect_impacts`).
    kcm_band_hz : (float, float), optional
        Also fit K, C and an apparent mass over this band (:func:`rotorid.fit_kcm`), with standard
        errors from a delete-one jackknife over the impacts (``result.kcm``).
    pedestal_motion : bool, optional
        True: accelerometers on the bearing housings (channels px1, px2, py1, py2 on every
        recording) measure the pedestals' motion; their H1 FRFs, divided by s² (s = sigma + j w),
        are the pedestal FRFs the identification uses with the probes' (relative) FRFs. False:
        accelerometers are ignored. None: an error if any recording has accelerometer channels.
    """
    from ._validate import flag, index, mapping, number

    if isinstance(recordings, (str, bytes, dict)) or not hasattr(recordings, "__iter__"):
        raise RotoridError(f"recordings must be a list of impact recordings, got {type(recordings).__name__}")
    recordings = list(recordings)
    if not recordings:
        raise RotoridError("no impact recordings given")
    for i, rec in enumerate(recordings):
        if not isinstance(rec, Recording):
            raise RotoridError(f"recordings[{i}] must be a rotorid.Recording (one impact recording), got "
                               f"{type(rec).__name__}")
    if tests_meta is not None:
        if isinstance(tests_meta, (str, bytes, dict)) or not isinstance(tests_meta, (list, tuple)):
            raise RotoridError(f"tests_meta must be a list of dicts (one per recording) or None, got "
                               f"{type(tests_meta).__name__}")
        if len(tests_meta) != len(recordings):
            raise RotoridError(f"tests_meta gives {len(tests_meta)} entries for {len(recordings)} recordings")
        tests_meta = [mapping(f"tests_meta[{i}]", m) for i, m in enumerate(tests_meta)]
    revs_before = index("revs_before", revs_before, 0)
    try:
        lo, hi = (number("band_hz", v, nonneg=True) for v in band_hz)
    except (TypeError, ValueError):
        raise RotoridError(f"band_hz must be (low, high) in Hz, got {band_hz!r}") from None
    if not lo < hi:
        raise RotoridError(f"band_hz must be (low, high) with low < high, got {band_hz!r}")
    band_hz = (lo, hi)
    record_s = number("record_s", record_s, positive=True)
    pre_s = number("pre_s", pre_s, nonneg=True)
    runout = flag("runout", runout)
    coherence_min = number("coherence_min", coherence_min)
    exp_window_tau_s = number("exp_window_tau_s", exp_window_tau_s, positive=True, allow_none=True)
    zero_pad_s = number("zero_pad_s", zero_pad_s, positive=True, allow_none=True)
    speed_rpm = number("speed_rpm", speed_rpm, positive=True, allow_none=True)
    if zero_pad_s is not None and not zero_pad_s >= record_s:
        raise RotoridError(f"zero_pad_s must be >= record_s = {record_s:g} s, got {zero_pad_s!r}")
    if zero_pad_s is not None:
        fs_max = max(rec.fs_hz for rec in recordings)
        if zero_pad_s * fs_max > MAX_FFT_SAMPLES:
            raise RotoridError(f"zero_pad_s = {zero_pad_s:g} s makes records of {zero_pad_s * fs_max:.3g} samples at "
                               f"{fs_max:g} Hz; the maximum is {MAX_FFT_SAMPLES} samples (zero_pad_s <= "
                               f"{MAX_FFT_SAMPLES / fs_max:g} s)")
    if not (0.0 <= coherence_min <= 1.0):
        raise RotoridError(f"coherence_min must be between 0 and 1, got {coherence_min!r}")
    detect = dict(threshold_N=threshold_N, min_separation_s=min_separation_s, double_hit_window_s=double_hit_window_s,
                  overload_N=overload_N)
    ped = _pedestal_choice(pedestal_motion, recordings,
                           [f"impact recording {rec.source or i!r}" for i, rec in enumerate(recordings)])
    channels = DISPLACEMENTS + (ACCELEROMETERS if ped else ())
    groups = {}
    dropped, group_dropped = [], {}
    speeds = []
    for i, rec in enumerate(recordings):
        meta = dict(rec.meta)
        if tests_meta is not None:
            meta.update(tests_meta[i])
        for key in ("plane", "direction"):
            if key not in meta:
                raise RotoridError(f"impact recording {rec.source!r} needs '{key}' (config or file metadata)")
        kp = signals.order.detect_keyphasor(rec, keyphasor) if ("kp" in rec.channels or (keyphasor or {}).get("times")
                                                               is not None) else None
        if kp is not None:
            speeds.append(float(np.median(kp.speed_rpm)))
        elif runout:
            rec.require("kp")
        f, r, u, d, nz = _impact_segments(rec, record_s=record_s, pre_s=pre_s, runout=runout, kp=kp,
                                          exp_window_tau_s=exp_window_tau_s, revs_before=revs_before,
                                          points_per_rev=points_per_rev, detect=detect, pedestal=ped)
        dropped += d
        key = (float(meta["plane"]), str(meta["direction"]), meta.get("probes_at", "probes"), rec.fs_hz)
        group_dropped.setdefault(key, []).extend(d)
        # channel delays (the channel map's delay_s): each response channel relative to the force
        dl = rec.meta.get("channel_delays_s", {}) or {}
        rel = np.array([float(dl.get(c, 0.0)) for c in channels]) - float(dl.get("force", 0.0))
        g = groups.setdefault(key, _ImpactGroup(rel))
        if not np.allclose(g.delays, rel, rtol=0.0, atol=1e-12):
            raise RotoridError(f"impact recording {rec.source!r} has other channel delays than the other recordings "
                               f"of its test ({meta['direction']} at {float(meta['plane']):g} m): one FRF needs one "
                               "set of delays")
        g.forces.extend(f)
        g.responses.extend(r)
        g.used.extend(u)
        g.noises.extend(nz)
    for src, t, why in dropped:
        warnings.warn(f"impact at t = {t:.4f} s in {src!r} dropped: {why}")
    if speeds and (max(speeds) - min(speeds)) > 0.01 * np.mean(speeds):
        raise RotoridError(f"impact recordings were taken at different speeds {np.round(speeds)} rpm; "
                           "identify each speed separately")
    if speeds:
        speed = float(np.mean(speeds))
        if speed_rpm is not None and abs(speed - speed_rpm) > 0.01 * speed:
            raise RotoridError(f"speed_rpm = {speed_rpm:g} disagrees with the keyphasor's {speed:.1f} rpm")
    elif speed_rpm is not None:
        speed = float(speed_rpm)
    elif "speed_rpm" in recordings[0].meta:
        speed = float(recordings[0].meta["speed_rpm"])
    else:
        raise RotoridError("the running speed of the impact tests cannot be known: the recordings have no keyphasor "
                           "and no speed_rpm in their metadata; give speed_rpm")
    tests, frfs, used, truncated, poolings = [], [], [], [], []
    for (plane, direction, at, fs), grp in groups.items():
        fl, rl, ul, rel, nl = grp.forces, grp.responses, grp.used, grp.delays, grp.noises
        if not fl:
            # this test's reasons, without their per-impact details (times, counts)
            why = sorted({w.split(" (")[0] for _, _, w in group_dropped.get((plane, direction, at, fs), [])})
            raise RotoridError(f"no clean impact left for the test in {direction} at plane {plane:g} m" +
                               (f" (impacts dropped: {'; '.join(why)})" if why else ""))
        frf = impact_noise.h1(fl, rl, fs, zero_pad_s)
        pre = int(round(pre_s * fs))
        sel = (frf.freq_hz >= band_hz[0]) & (frf.freq_hz <= band_hz[1])
        noise = nl[0][0]() if len(fl) == 1 else None
        pooling = None
        # how much recording before an impact gives its noise: 1.5 records (two half-overlapping
        # segments) and their resting-level samples, after the run-out signature's revolutions
        # (and the record's pre_s, and a revolution before the first keyphasor pulse, which the
        # run-out filter needs, rounded up: 0.65 s was advised where 0.685 s is needed, review)
        need = 1.5 * record_s + pre_s + impact_noise.FORCE_REST_SAMPLES / fs + \
            ((revs_before + 2) * 60.0 / speed if runout else 0.0)
        need = float(np.ceil(need * 100.0) / 100.0)
        if len(fl) >= 2 and frf.cov is not None:
            # the scatter of few impacts pooled with the noise measured before them, where they agree
            # (only quiet record before a recording's first hit: after a hit, the tail of its response
            # rings on where a short record with an exponential window ends, and 0.1 s records with a
            # 30 ms window took five times the noise from between the hits)
            frf, pooling = impact_noise.pooled_frf(frf, fl, [None if after else nz() for nz, after in nl], fs,
                                                   zero_pad_s, exp_window_tau_s, sel)
            if not pooling.measured and len(fl) <= MAX_HITS_ADVISED:
                from scipy.stats import t as t_dist

                warnings.warn(f"test {direction} at {plane:g} m: the error bars of its {len(fl)} impacts rest on "
                              f"their scatter's {pooling.dof_scatter:g} degree(s) of freedom (95 % intervals "
                              f"{t_dist.ppf(0.975, pooling.dof_scatter):.3g} standard errors wide each way): too "
                              f"little quiet record before the first hit to measure the noise on; record at least "
                              f"{need:.2f} s before it to narrow them")
            elif pooling.measured and pooling.source == "scatter":
                warnings.warn(f"test {direction} at {plane:g} m: its {len(fl)} impacts scatter "
                              f"{pooling.excess:.3g} times as much (in power) as the noise measured before them "
                              "explains: they differ from hit to hit (where and how the hammer struck, a rebound, a "
                              "nonlinearity) or the noise changed over the recording (rising, a noisier recording "
                              "of the test), and the error bars come from their scatter alone "
                              f"({pooling.dof_scatter:g} degree(s) of freedom)")
            elif pooling.source == "noise changed":
                warnings.warn(f"test {direction} at {plane:g} m: its {len(fl)} impacts scatter "
                              f"{pooling.shortfall:.3g} times as much (in power) as the noise measured before them, "
                              "over the band: that noise is not theirs (a burst in the quiet record, noise that fell "
                              "over the recording), and the error bars come from their scatter alone "
                              f"({pooling.dof_scatter:g} degree(s) of freedom)")
            elif pooling.source == "noise in step":
                lo_hz, hi_hz = pooling.in_step_hz
                warnings.warn(f"test {direction} at {plane:g} m: its {len(fl)} impacts scatter "
                              f"{pooling.shortfall:.3g} times as much (in power) as the noise measured before them "
                              f"at {lo_hz:.4g}-{hi_hz:.4g} Hz: noise in step with the hits there (a hum whose period "
                              "divides their spacing) does not average out over them, and the error bars count it "
                              "as the same in every record")
        if len(fl) == 1 and frf.h.shape[1] in (4, 8):
            frf = impact_noise.single_impact_frf(frf, fl[0], noise, fs, zero_pad_s, exp_window_tau_s)
            advice = (f"record at least {need:.2f} s before the impact (after any earlier impact's record), "
                      "or hit two or more times")
            if noise is None:
                warnings.warn(f"test {direction} at {plane:g} m has one impact, no usable quiet record before it and "
                              f"{pre} sample(s) before it in its record (pre_s = {pre_s:g} s): too few to estimate its "
                              f"noise, so its FRF's uncertainty is unknown and every point is flagged; {advice}, or "
                              f"give pre_s of at least {impact_noise.MIN_NOISE_SAMPLES / fs:.2g} s")
            elif not noise.measured:
                warnings.warn(f"test {direction} at {plane:g} m has one impact and {noise.why_white}: its FRF's error "
                              f"bars come from the {pre} samples before the impact, taken as white noise (noise "
                              f"concentrated in the band is under-counted); {advice}")
            else:
                if noise.left_out:
                    warnings.warn(f"test {direction} at {plane:g} m: {noise.left_out} record-long segment(s) of the "
                                  f"quiet record before its impact left out of its noise estimate (an event in them: a "
                                  f"tap, a burst; {len(noise.segments)} used)")
                if noise.grown.max() >= impact_noise.GROWN_WARNING:
                    i = int(np.argmax(noise.grown))
                    name = "force" if i == noise.grown.size - 1 else channels[i]
                    warnings.warn(f"test {direction} at {plane:g} m: the noise just before its impact is "
                                  f"{noise.grown[i]:.3g} times ({name}, in power) that of the quiet record before it; "
                                  "its error bars are scaled up to it")
        coh = frf.coherence[sel]
        if np.any(coh < coherence_min):
            i, j = np.unravel_index(np.argmin(coh), coh.shape)
            warnings.warn(f"test {direction} at {plane:g} m: coherence drops to {coh[i, j]:.2f} "
                          f"({channels[j]} at {frf.freq_hz[sel][i]:.1f} Hz) in the band; "
                          f"{int((coh < coherence_min).sum())} of {coh.size} points below {coherence_min:g}")
        tail = _undecayed(rl, pre)
        if tail > DECAYED:
            truncated.append(f"{direction} at {plane:g} m: {100 * tail:.0f} %")
        sigma = 0.0 if exp_window_tau_s is None else 1.0 / exp_window_tau_s
        tests.append(_impact_response(frf, sel, speed, plane, direction, at, sigma,
                                      f"{direction}@{plane:g}m x{len(fl)}", rel,
                                      impact_noise.truncation_var(fl, rl, pre, fs, zero_pad_s, sel, exp_window_tau_s, noise)))
        frfs.append(frf)
        poolings.append(pooling)
        used.append(ul)
    # low coherence at a frequency (any test, any channel) flags the point: its FRFs are unreliable
    low_coh = np.zeros(tests[0].freq_hz.size, bool)
    for t, frf in zip(tests, frfs):
        sel = (frf.freq_hz >= band_hz[0]) & (frf.freq_hz <= band_hz[1])
        if sel.sum() == low_coh.size:
            low_coh |= frf.coherence[sel].min(axis=1) < coherence_min
    flags = [(low_coh, f"coherence < {coherence_min:g}")]
    if truncated:
        # leakage of a response cut off before it died out smears every frequency of the FRFs
        warnings.warn(f"the response has not died out by the end of the {record_s:g} s records (its last tenth, "
                      f"above the noise, against its peak: {'; '.join(truncated)}): the FRFs leak and every point is "
                      "flagged; " + ("a longer record_s or an exponential window (exp_window_tau_s) avoids it"
                                     if exp_window_tau_s is None else
                                     f"a longer record_s or a shorter exponential window than exp_window_tau_s = "
                                     f"{exp_window_tau_s:g} s avoids it"))
        flags.append((np.ones(low_coh.size, bool), "response not decayed in the record"))
    ident = identify_impact(rotor, tests, identical=identical, method=method, extra_flags=flags, **ident_kw)
    kcm = None
    if kcm_band_hz is not None:
        from .kcm import fit_kcm, with_jackknife

        kcm = fit_kcm(ident, band_hz=kcm_band_hz, rotor=rotor)
        group_data = [(g.forces, g.responses, fs, g.delays) for (_, _, _, fs), g in groups.items()]
        if all(len(g[0]) >= 2 for g in group_data):
            reps, labels = [], []
            for gi, (fl, rl, fs, rel) in enumerate(group_data):
                for i in range(len(fl)):
                    frf = impact_noise.h1(fl[:i] + fl[i + 1:], rl[:i] + rl[i + 1:], fs, zero_pad_s)
                    sel = (frf.freq_hz >= band_hz[0]) & (frf.freq_hz <= band_hz[1])
                    t0 = tests[gi]
                    rep_tests = list(tests)
                    rep_tests[gi] = _impact_response(frf, sel, t0.speed_rpm, t0.plane, t0.direction, t0.at,
                                                     t0.sigma, t0.name, rel)
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        rid = identify_impact(rotor, rep_tests, identical=identical, method=method, extra_flags=flags,
                                              **ident_kw)
                        rid.ok = ident.ok  # the same points as the full fit
                        reps.append(fit_kcm(rid, band_hz=kcm_band_hz, rotor=rotor))
                    labels.append(gi)
            kcm = with_jackknife(kcm, reps, labels, rotor)
        g_std, ph_std = ident_kw.get("accel_gain_std", 0.0), ident_kw.get("accel_phase_std_deg", 0.0)
        if ped and (g_std or ph_std):
            kcm = _kcm_with_calibration(kcm, rotor, tests, ident, kcm_band_hz, identical, method, flags, ident_kw)
    return ImpactChainResult(tests, frfs, used, dropped, ident, kcm, poolings)


def _kcm_with_calibration(kcm, rotor, tests, ident, band_hz, identical, method, flags, ident_kw):
    """The K-C-M fit's standard errors with the accelerometers' calibration added: one error common
    to every frequency, which neither the fit's weights nor the jackknife over impacts sees
    (central differences of the whole identification and fit)."""
    from .identify import _CAL_STEP, _calibration_std, calibration_perturbations
    from .kcm import fit_kcm

    g, ph = _calibration_std(ident_kw.get("accel_gain_std", 0.0), ident_kw.get("accel_phase_std_deg", 0.0))
    var = {name: np.zeros((2, 2, 2)) for name in ("K", "M", "C")}
    for std, plus, minus in calibration_perturbations(tests, g, ph):
        fits = []
        for moved in (plus, minus):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                rid = identify_impact(rotor, moved, identical=identical, method=method, extra_flags=flags, **ident_kw)
            rid.ok = ident.ok  # the same points as the nominal fit
            fits.append(fit_kcm(rid, band_hz=band_hz, rotor=rotor))
        for name in var:
            var[name] += (std * (getattr(fits[0], name) - getattr(fits[1], name)) / (2.0 * _CAL_STEP)) ** 2
    return dataclasses.replace(kcm, K_std=np.sqrt(kcm.K_std ** 2 + var["K"]), M_std=np.sqrt(kcm.M_std ** 2 + var["M"]),
                               C_std=np.sqrt(kcm.C_std ** 2 + var["C"]),
                               std_method=f"{kcm.std_method} + accelerometer calibration")


# ---------------------------------------------------------------------------------------------
# configuration files (TOML; the schema is declared once, in rotorid.config)

CONFIG_DOC = "The config format (every key, its type, default and unit) is documented in docs/config.md; " \
             "examples: docs/examples/*.toml. The schema itself is rotorid.config."


def load_config(path):
    """The validated config (see :mod:`rotorid.config`)."""
    from .config import load_config as _load

    return _load(path)


def _read_times(path) -> np.ndarray:
    """Pulse times (s) from a text/CSV file (one per line, first column; a header line is skipped)
    or a .npy array."""
    p = str(path)
    try:
        if p.endswith(".npy"):
            t = np.load(p, allow_pickle=False)
        else:
            import pandas as pd

            df = pd.read_csv(p, sep=None, engine="python", header=None, comment="#")
            col = pd.to_numeric(df.iloc[:, 0], errors="coerce")
            t = col.dropna().to_numpy(dtype=float)
            if col.isna().sum() > 1:
                raise RotoridError(f"{p}: {int(col.isna().sum())} rows of the pulse-time column are not numbers")
    except RotoridError:
        raise
    except Exception as exc:  # pandas / numpy parse errors
        raise RotoridError(f"cannot read keyphasor times from {p}: {exc}") from None
    return np.asarray(t, dtype=float).ravel()


def _load_entry(cfg, entry, needed):
    """One recording of a config entry: its files (one, several as blocks, or TDMS groups as
    blocks), its channel map, reading options and keyphasor options (carried in the recording's
    meta as ``keyphasor_options``, which the tracker applies)."""
    from . import io

    chans = cfg.channels_for(entry, only=needed) or None
    kw = cfg.files_for(entry)
    meta = dict(entry.meta())
    kpo = cfg.keyphasor_for(entry)
    times_file = kpo.pop("times_file", None)
    if times_file is not None:
        kpo["times"] = _read_times(times_file)
    meta["keyphasor_options"] = kpo
    paths = entry.paths(cfg)
    if len(paths) > 1 or entry.groups is not None:
        kw.pop("group", None)
        src = [str(q) for q in paths] if len(paths) > 1 else str(paths[0])
        return io.load_segmented(src, groups=entry.groups, channel_map=chans, meta=meta, **kw)
    return io.load_recording(paths[0], channel_map=chans, meta=meta, **kw)


def _load_table(cfg, entry, name=None):
    from .tables import load_1x_table

    paths = entry.paths(cfg)
    if len(paths) != 1:
        raise RotoridError(f"a DAQ 1X table is one file, got {len(paths)}: {[str(q) for q in paths]}")
    return load_1x_table(paths[0], name=name, meta=entry.meta(), **cfg.imbalance.table.reader_kwargs())


RESULT_PATTERNS = {"imbalance": ["sync_vectors_*.csv", "sync_vectors_*.png", "keyphasor.csv", "coefficients_imbalance.*",
                                 "pedestals_imbalance.csv", "result_imbalance.json"],
                   "impact": ["frf_*.csv", "frf_*.png", "dropped_impacts.csv", "kcm_fit.csv", "coefficients_impact.*",
                              "pedestals_impact.csv", "result_impact.json"]}


def run_config(path, kind: str, *, out_dir=None, log=print, overwrite: bool = False, plots: bool = True,
               report=None):
    """Run the imbalance or impact chain described by a TOML config; write CSV tables and plots.

    The config is validated completely (keys, types, units, files) before anything is read, and
    the output folder is checked: results of an earlier run are replaced only with
    ``overwrite=True`` (stale ones removed, see :mod:`rotorid.outputs`). ``plots=False`` writes the
    tables only. Returns (Identification, list of written files).

    The folder also gets ``result_<kind>.json``: the identification (SI) with the settings, the
    input files with their SHA-256, the warnings and the log of the run, which ``rotorid report``
    reads. ``report``: an HTML page of the run (:mod:`rotorid.report`): a path (``--report``),
    True (``report_<kind>.html`` in the output folder), False (none) or None (the config's
    ``[output] report``)."""
    from .report._run import warning_log

    if not callable(log):
        raise RotoridError(f"log must be a function taking a message (e.g. print), got {type(log).__name__}")
    lines = []

    def logged(message):
        lines.append(str(message))
        log(message)

    with warning_log() as seen:
        return _run_config(path, kind, out_dir=out_dir, log=logged, overwrite=overwrite, plots=plots, report=report,
                           seen=seen, lines=lines)


def _report_target(report, cfg, kind, folder_path):
    """(file name in the output folder, None) or (None, outside path) or (None, None)."""
    from ._validate import path as _path

    if report is None:
        report = cfg.output.report
        if isinstance(report, str):
            return report, None   # the config's file name: in the output folder
    if report is False:
        return None, None
    if report is True:
        return f"report_{kind}.html", None
    p = os.path.abspath(str(_path("report", report)))
    if not p.lower().endswith((".html", ".htm")):
        raise RotoridError(f"the report {p} must end in .html")
    if os.path.dirname(p) == folder_path:
        return os.path.basename(p), None
    return None, p


def _run_config(path, kind, *, out_dir, log, overwrite, plots, report, seen, lines):
    from ._validate import choice, flag
    from ._validate import path as _path
    from .outputs import ResultsFolder

    from . import plot

    choice("kind", kind, {"imbalance", "impact"})
    overwrite = flag("overwrite", overwrite)
    plots = flag("plots", plots)
    if out_dir is not None and not (isinstance(out_dir, str) and out_dir == ""):  # "": the config's folder
        _path("out_dir", out_dir)
    if not callable(log):
        raise RotoridError(f"log must be a function taking a message (e.g. print), got {type(log).__name__}")
    cfg = load_config(path)
    sec = cfg.section(kind)
    rotor = cfg.rotor()
    folder_path = os.path.abspath(str(out_dir) if out_dir else str(cfg.output_dir(kind)))
    if report is not None and not isinstance(report, bool):
        flag("overwrite", overwrite)
    report_name, report_path = _report_target(report, cfg, kind, folder_path)
    if report_path is not None:
        from .exports import _target

        _target(report_path, overwrite, (".html", ".htm"))   # refused before anything is computed
        if not os.access(os.path.dirname(report_path), os.W_OK):
            raise RotoridError(f"the folder of the report {report_path} is not writable")
    folder = ResultsFolder(folder_path, patterns=RESULT_PATTERNS[kind] + ([report_name] if report_name else []),
                           overwrite=overwrite, command=f"rotorid identify {kind} {path}")
    out = folder.path
    us = cfg.output.units.upper() == "US"
    conv = cfg.output.conventions()   # units, amplitude (0-pk, pk-pk) and phase (lag, arg) of what is written
    files = []
    ped_cfg = cfg.pedestals
    pedestal_motion = None if ped_cfg is None else ped_cfg.measured
    cal_kw = {}
    if pedestal_motion:
        cal_kw = dict(accel_gain_std=ped_cfg.accel_gain_std, accel_phase_std_deg=ped_cfg.accel_phase_std_deg)
        if not (ped_cfg.accel_gain_std or ped_cfg.accel_phase_std_deg):
            log("  note: the accelerometers' calibration uncertainty is not in the error bars ([pedestals] "
                "accel_gain_std, accel_phase_std_deg); the compensated coefficients are sensitive to it")

    def write_csv(df, name, **kw):
        with folder.atomic(name) as tmp:
            df.to_csv(tmp, index=False, **kw)
        files.append(os.path.join(out, name))

    def write_png(draw, name, **kw):
        """A figure of the measured data next to its table (skipped with plots=False)."""
        if plots:
            with folder.atomic(name) as tmp:
                draw(path=tmp, **kw)
            files.append(os.path.join(out, name))
    if kind == "imbalance":
        ident_kw = dict(identical=sec.identical, cond_max=sec.cond_max, min_rel_amplitude=sec.min_rel_amplitude,
                        max_rel_std=sec.max_rel_std, estimator=sec.estimator, **cal_kw)
        phase_ref = dict(keyphasor_angle_std_deg=float(sec.keyphasor_angle_std_deg),
                         keyphasor_delay_std_s=float(sec.keyphasor_delay_std_s))
        if sec.table is not None:
            runs = [_load_table(cfg, r, r.name) for r in sec.runs]
            base = _load_table(cfg, sec.baseline, "baseline") if sec.baseline is not None else None
            slow = _load_table(cfg, sec.slow_roll, "slow roll") if sec.slow_roll is not None else None
            chain_kw = dict(speed_match_rpm=sec.speed_match_rpm, slow_roll_max_rpm=sec.table.slow_roll_max_rpm)
        else:
            need = set(DISPLACEMENTS) | set(ACCELEROMETERS) | {"kp"}
            runs = [_load_entry(cfg, r, need) for r in sec.runs]
            base = _load_entry(cfg, sec.baseline, need) if sec.baseline is not None else None
            slow = _load_entry(cfg, sec.slow_roll, need) if sec.slow_roll is not None else None
            chain_kw = dict(points_per_rev=None if sec.points_per_rev == "auto" else sec.points_per_rev,
                            min_revs=sec.min_revs, settle_revs=sec.settle_revs, speed_tolerance=sec.speed_tolerance,
                            revs_per_block=sec.revs_per_block, speed_match_rpm=sec.speed_match_rpm)
        imbs = [r.imbalance_meta() for r in sec.runs]
        res = imbalance_chain(rotor, runs, baseline=base, slow_roll=slow,
                              speeds_rpm=None if sec.speeds_rpm is None else list(sec.speeds_rpm), steady=sec.steady,
                              imbalances=imbs, orders=tuple(sec.orders), method=sec.method,
                              pedestal_motion=pedestal_motion, phase_calibration=sec.phase_calibration,
                              **chain_kw, **ident_kw, **phase_ref)
        # (applied, the calibrated vectors serve everything downstream: the identification, the
        # pedestal fit and the written tables; its messages are among the chain's notes)
        ident = res.identification
        responses = res.responses
        for i, r in enumerate(responses):
            stem = f"sync_vectors_{i}_{_safe(r.name)}"
            write_csv(conv.sync_table(r), f"{stem}.csv", float_format="%.6g")
            write_png(plot.bode, f"{stem}_bode.png", response=r, title=f"Measured 1X vectors, run {r.name} (compensated)",
                      units=conv.units, amplitude=conv.amplitude, phase=conv.phase)
            write_png(plot.polar, f"{stem}_polar.png", response=r, title=f"Measured 1X vectors, run {r.name} (compensated)",
                      units=conv.units, amplitude=conv.amplitude, phase=conv.phase)
        kps = [(i, k) for i, t in enumerate(res.tracks) for k in t.keyphasors]
        if kps:
            import pandas as pd

            write_csv(pd.DataFrame([dict(run=i, pulses=k.times.size, speed_rpm=float(np.median(k.speed_rpm)),
                                         edge=k.edge, rest_state=k.states[0], pulse_state=k.states[1], level=k.level,
                                         jitter_us=1e6 * k.jitter_s, refined=k.refined, extra=k.extra.size,
                                         missing=sum(c for _, c in k.missing), note=k.note) for i, k in kps]),
                      "keyphasor.csv", float_format="%.6g")
        for n in res.notes:
            if n.startswith("slow-roll run-out 1X:") and res.slow_roll_1x is not None:
                n = _runout_note(res.slow_roll_1x, conv)   # in the output's units and conventions
            log("  " + n)
    else:
        need = set(DISPLACEMENTS) | set(ACCELEROMETERS) | {"kp", "force"}
        recs = [_load_entry(cfg, t, need) for t in sec.tests]
        for r in recs:
            if not isinstance(r, Recording):
                raise RotoridError("impact tests are single recordings (one file each); files/groups make a segmented "
                                   "recording, which only imbalance runs accept")
        meta = [t.meta() for t in sec.tests]
        res = impact_chain(rotor, recs, band_hz=tuple(sec.band_hz), record_s=sec.record_s, runout=sec.runout,
                           identical=sec.identical, method=sec.method, tests_meta=meta,
                           exp_window_tau_s=sec.exp_window_tau_s, pre_s=sec.pre_s, zero_pad_s=sec.zero_pad_s,
                           revs_before=sec.revs_before, points_per_rev=sec.points_per_rev,
                           keyphasor=None, speed_rpm=sec.speed_rpm, coherence_min=sec.coherence_min,
                           threshold_N=sec.threshold_N, min_separation_s=sec.min_separation_s,
                           double_hit_window_s=sec.double_hit_window_s, overload_N=sec.overload_N,
                           cond_max=sec.cond_max, min_rel_amplitude=sec.min_rel_amplitude, max_rel_std=sec.max_rel_std,
                           estimator=sec.estimator, kcm_band_hz=sec.kcm_band_hz, pedestal_motion=pedestal_motion,
                           **cal_kw)
        ident = res.identification
        responses = res.tests
        import pandas as pd

        for t, frf, stem in zip(res.tests, res.frfs, _distinct([f"frf_{_safe(t.name)}" for t in res.tests])):
            df = conv.frf_table(t)
            sel = (frf.freq_hz >= t.freq_hz[0] - 1e-9) & (frf.freq_hz <= t.freq_hz[-1] + 1e-9)
            for j, nm in enumerate(DISPLACEMENTS + (ACCELEROMETERS if t.pedestal is not None else ())):
                df[f"{nm}_coherence"] = frf.coherence[sel, j]
            write_csv(df, f"{stem}.csv", float_format="%.6g")
            write_png(plot.frf, f"{stem}.png", response=t, coherence=frf.coherence[sel, :4],
                      coherence_min=sec.coherence_min, title=f"H1 FRFs and coherence, test {t.name}",
                      units=conv.units, phase=conv.phase)
        if res.dropped:
            write_csv(pd.DataFrame(res.dropped, columns=["source", "time_s", "reason"]), "dropped_impacts.csv")
        log(f"  {sum(len(u) for u in res.used)} impacts used, {len(res.dropped)} dropped")
        for t, pooling in zip(res.tests, res.poolings):
            if pooling is not None:
                log(f"  test {t.name}: error bars from {pooling.summary()}")
        if res.kcm is not None:
            fit = res.kcm
            write_csv(_kcm_table(fit, conv), "kcm_fit.csv", float_format="%.6g")
            log(f"  K-C-M fit over {fit.band_hz[0]:g}-{fit.band_hz[1]:g} Hz ({fit.n_points} points)"
                + (f"; {fit.mass_check}" if fit.mass_check else ""))
    if ped_cfg is not None and ped_cfg.measured and ped_cfg.fit_pedestals:
        from .pedestal import identify_pedestals

        try:
            shared = res.shared_cov if kind == "imbalance" else None
            phase = res.pedestal_phase_kw if kind == "imbalance" else {}
            pfit = identify_pedestals(rotor, responses, cross_coupled=ped_cfg.cross_coupled,
                                      freq_range_hz=ped_cfg.freq_range_hz, shared_cov=shared, **cal_kw, **phase)
        except RotoridError as exc:
            log(f"  pedestals not identified: {exc}")
        else:
            write_csv(pfit.to_dataframe(us=us), f"pedestals_{kind}.csv", float_format="%.6g")
            log("  " + pfit.summary(us=us))
    df = ident.to_dataframe()
    if kind == "impact":
        # the running speed of the impacts (rotorid compare checks a prediction against it)
        df.insert(1, "speed_rpm", float(res.tests[0].speed_rpm))
    if us:
        from .units import from_si

        for col in df.columns:
            if col[:1] == "K" and col[1:3] in ("xx", "xy", "yx", "yy"):
                df[col] = from_si(df[col], "lbf/in")
            elif col[:1] == "C" and col[1:3] in ("xx", "xy", "yx", "yy"):
                df[col] = from_si(df[col], "lbf*s/in")
        df = df.rename(columns={c: c + ("_lbf_per_in" if c[0] == "K" else "_lbf_s_per_in") for c in df.columns
                                if c[:1] in "KC" and c[1:3] in ("xx", "xy", "yx", "yy")})
    write_csv(df, f"coefficients_{kind}.csv", float_format="%.6g")
    for ext in cfg.output.formats:
        # the same coefficients with their standard errors and intervals (rotorid.exports)
        name = f"coefficients_{kind}.{ext}"
        writer = {"xlsx": ident.to_excel, "json": ident.to_json, "nc": ident.to_netcdf}[ext]
        with folder.atomic(name) as tmp:
            writer(tmp, units="US" if us else "SI")
        files.append(os.path.join(out, name))
    if plots:
        with folder.atomic(f"coefficients_{kind}.png") as tmp:
            plot.coefficients(ident, None, path=tmp, units=conv.units,
                              title=f"Identified coefficients ({kind}), {os.path.basename(str(path))}")
        files.append(os.path.join(out, f"coefficients_{kind}.png"))
    # the machine-readable result (rotorid report RESULT) and the HTML page of the run
    from .report import write_report
    from .report._run import run_context

    context = run_context(cfg, path, kind, command=f"rotorid identify {kind} {path}", units="US" if us else "SI",
                          responses=responses if kind == "imbalance" else None, warnings=seen, log=lines)
    with folder.atomic(f"result_{kind}.json") as tmp:
        _to_json(ident, tmp, context)
    files.append(os.path.join(out, f"result_{kind}.json"))
    if report_name:
        with folder.atomic(report_name) as tmp:
            write_report(tmp, ident, overwrite=True, **context)
        files.append(os.path.join(out, report_name))
        log(f"  report: {files[-1]}")
    stale = folder.finish()
    if report_path:
        # outside the folder, after its manifest: a page that cannot be written leaves complete results
        files.append(write_report(report_path, ident, overwrite=overwrite, **context))
        log(f"  report: {report_path}")
    if stale:
        log(f"  removed {len(stale)} stale file(s) of the earlier run: {', '.join(stale[:5])}")
    ok = ident.ok
    log(f"identified {kind}: {ident.axis.size} points ({int(ok.sum())} ok) over {ident.axis_name} "
        f"{ident.axis.min():.4g}-{ident.axis.max():.4g}")
    if ok.any():
        med = np.median(ident.report_vector()[ok], axis=0)
        med = [float(conv.coefficient(v, n[0])) for n, v in zip(REPORT_NAMES, med)]
        log(f"  median over ok points ({conv.stiffness_unit}, {conv.damping_unit}): "
            + ", ".join(f"{n} {v:.4g}" for n, v in zip(REPORT_NAMES, med)))
    log(f"  wrote {len(files)} files to {out}/")
    return ident, files


def _runout_note(v, conv):
    """The slow-roll run-out note in the output's units and conventions."""
    amp, ph = conv.amplitude_of(v), conv.phase_of(v)
    parts = [f"{n} {a:.3g} {conv.length_label} @ {p:.0f}" for n, a, p in zip(DISPLACEMENTS, amp, ph)]
    return (f"slow-roll run-out 1X ({conv.amplitude}, phase {conv.phase} deg): " + ", ".join(parts))


def _kcm_table(fit, conv):
    """kcm_fit.csv: the K-C-M fit with its units in the headers (SI, or lbf/in, lbf*s/in, lb)."""
    df = fit.to_dataframe()
    if conv.units == "SI":
        return df
    from .units import from_si

    units = {"K": ("lbf/in", "lbf_per_in"), "C": ("lbf*s/in", "lbf_s_per_in"), "M": ("lb", "lb")}
    for col in ("K", "K_std", "C", "C_std", "M", "M_std"):
        df[col] = from_si(df[col], units[col[0]][0])
    return df.rename(columns={c: f"{c}_{units[c[0]][1]}" for c in ("K", "K_std", "C", "C_std", "M", "M_std")})


def _to_json(ident, path, context):
    from .exports import to_json

    return to_json(ident, path, overwrite=True, context=context)


def _safe(name, limit: int = 60):
    """A file-name-safe form of a run or test name, at most ``limit`` characters."""
    out = "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in str(name))
    return out[:limit] or "unnamed"


def _distinct(stems):
    """File stems made distinct (case-insensitively, as some file systems compare them): a stem
    met before gets _2, _3, ... (two impact tests whose planes agree to 6 significant figures, or
    names that differ only beyond 60 characters or in characters a file name cannot hold, had
    written one frf file over the other)."""
    seen, out = set(), []
    for stem in stems:
        cand, k = stem, 1
        while cand.lower() in seen:
            k += 1
            cand = f"{stem}_{k}"
        seen.add(cand.lower())
        out.append(cand)
    return out


from .model import REPORT_ORDER as REPORT_NAMES  # noqa: E402
