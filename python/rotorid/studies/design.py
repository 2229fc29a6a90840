"""Test design: which trial masses (and which impacts) identify the bearings best on a given rig.

Trial masses. A run puts a mass in plane 1, in plane 2, or one in each at a relative angle that the
rig's holes allow. What a run contributes to the identification does not depend on its absolute
angle: turning every mass of a run by the same angle turns all its 1X vectors by that angle, which
multiplies the run's equations by a unit complex number and leaves the least-squares solution and
its noise unchanged. So a run is (m1, m2, θ2 - θ1), and candidates are the pairs and triples of such
runs. They are ranked in two stages:

1. a deterministic screen of every candidate: from the exact responses (the core's batched
   identification, no noise), the expected error of a noisy 1X vector through each bearing's
   response matrix, ``cond x (noise / amplitude)`` per speed, its median over the speeds;
2. a Monte Carlo study (:func:`synchronous_study`, common random numbers: one seed for all) of the
   best screened candidates, ranked by the expected coefficient error: the rms error of each
   coefficient as a fraction of its bearing's direct coefficient of the same kind, root mean
   square over the 16 coefficients, median over the speeds.

The 1X noise of a dwell follows from the probe noise: a sinusoid's complex amplitude estimated over
N = fs·T samples of white noise of rms σ has a complex error of rms modulus 2σ/√N.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field, replace

import numpy as np

from .._validate import choice, index, instance, mapping, number, real_array
from .._validate import seed as check_seed
from ..errors import RotoridError
from ..model import BearingCoefficients, Imbalance, RigidRotor
from ..simulate import RPM, _check_model
from .errors import ImpactErrors, SyncErrors, frf_random_error
from .monte_carlo import StudyResult, _check_range, impact_study, synchronous_study


def dwell_noise_m(probe_noise_m: float, dwell_s: float, fs_hz: float) -> float:
    """rms modulus (m) of the error of a 1X vector estimated over a dwell of ``dwell_s`` seconds
    sampled at ``fs_hz`` from a probe with white noise of rms ``probe_noise_m``: 2σ/sqrt(fs·T).

    Examples
    --------
    >>> from rotorid.studies import dwell_noise_m
    >>> round(dwell_noise_m(1e-6, 2.0, 5000.0) * 1e9, 2)   # 1 µm probe noise, 2 s at 5 kHz: nm
    20.0
    """
    s = number("probe_noise_m", probe_noise_m, nonneg=True)
    t = number("dwell_s", dwell_s, positive=True)
    fs = number("fs_hz", fs_hz, positive=True)
    if s > 1e-2:
        raise RotoridError(f"probe_noise_m = {s:g} m is not a probe's noise (at most 0.01 m)")
    if fs * t < 2:
        raise RotoridError(f"a dwell of {t:g} s at {fs:g} Hz has fewer than 2 samples")
    return float(2 * s / np.sqrt(fs * t))


@dataclass(frozen=True)
class TrialMassRig:
    """What a rig allows: ``holes`` equally spaced tapped holes per balance plane, the trial
    ``masses_kg`` at hand (at the rotor's balance radii), and optionally the largest 1X response
    any run may cause over the speed range (``max_response_m``, e.g. a fraction of the clearance:
    coefficients are linearized about small motions).

    Examples
    --------
    >>> from rotorid.studies import TrialMassRig
    >>> TrialMassRig(holes=8, masses_kg=(0.003, 0.005)).angles_deg()
    array([  0.,  45.,  90., 135., 180., 225., 270., 315.])
    """

    holes: int = 16
    masses_kg: tuple = (0.003, 0.005)
    max_response_m: float | None = None

    def __post_init__(self):
        object.__setattr__(self, "holes", index("holes", self.holes, 1, 360))
        m = real_array("masses_kg", np.atleast_1d(self.masses_kg), ndim=1, positive=True)
        if m.size == 0 or m.size > 10 or np.any(m > 10):
            raise RotoridError(f"masses_kg must list 1 to 10 trial masses, each at most 10 kg, got {self.masses_kg!r}")
        object.__setattr__(self, "masses_kg", tuple(float(v) for v in np.unique(m)))
        if self.max_response_m is not None:
            object.__setattr__(self, "max_response_m", number("max_response_m", self.max_response_m, positive=True))

    def angles_deg(self) -> np.ndarray:
        return np.arange(self.holes) * 360.0 / self.holes

    def runs(self) -> list:
        """Every distinct run: one mass in plane 1 or 2, or one in each at every relative angle."""
        out = []
        for m in self.masses_kg:
            out.append(Imbalance((m, 0.0), (0.0, 0.0)))
            out.append(Imbalance((0.0, m), (0.0, 0.0)))
        for m1, m2 in itertools.product(self.masses_kg, repeat=2):
            for a in self.angles_deg():
                out.append(Imbalance((m1, m2), (0.0, float(a))))
        return [replace(r, name=_describe(r)) for r in out]


def _sizes(name, value):
    """Set sizes to consider: 2 and/or 3."""
    if isinstance(value, (bool, np.bool_, str, bytes)) or value is None:
        raise RotoridError(f"{name} must be 2, 3 or a list of them, got {value!r}")
    try:
        vals = np.atleast_1d(np.asarray(value, dtype=object)).ravel().tolist()
    except Exception:
        raise RotoridError(f"{name} must be 2, 3 or a list of them, got {value!r}") from None
    if not vals:
        raise RotoridError(f"{name} must be 2, 3 or a list of them, got {value!r}")
    return tuple(sorted({index(name, v, 2, 3) for v in vals}))


def _describe(imb: Imbalance) -> str:
    (m1, m2), (a1, a2) = imb.mass_kg, imb.angle_deg
    if m2 == 0:
        return f"{m1 * 1e3:g} g in plane 1"
    if m1 == 0:
        return f"{m2 * 1e3:g} g in plane 2"
    return f"{m1 * 1e3:g} g / {m2 * 1e3:g} g at {(a2 - a1) % 360:g} deg"


@dataclass
class DesignResult:
    """Ranked candidate test designs.

    ``ranking``: DataFrame, one row per screened candidate (best first) with its ``screen`` value
    and, for those that went through the Monte Carlo, the ``expected_error`` (fraction of the
    direct coefficients) and the per-group errors. ``best``: {number of runs: list of runs (or
    tests)}. ``comparison``: the Monte Carlo expected error of the recommendations next to the
    designs given in ``compare``, same seed and trials. ``studies``: the StudyResult of every
    design in the comparison.
    """

    ranking: object
    best: dict
    comparison: object
    studies: dict = field(default_factory=dict, repr=False)
    noise_m: float = 0.0


def expected_error(study: StudyResult, bearings: BearingCoefficients) -> dict:
    """Expected coefficient error of a study: each coefficient's rms error as a fraction of its
    bearing's direct coefficient of the same kind, rms over the 16 coefficients (``all``) and over
    the groups, median over the points.

    Examples
    --------
    >>> import numpy as np, rotorid
    >>> from rotorid.studies import SyncErrors, expected_error, synchronous_study
    >>> rig = rotorid.nsf_rig()
    >>> st = synchronous_study(rig.rotor, rig.bearings, [rig.imbalances[s] for s in "AB"], [4000.0],
    ...                        SyncErrors(noise_m=1e-8), trials=100)
    >>> 0 < expected_error(st, rig.bearings)["all"] < 0.1
    True
    """
    from ..model import _REPORT_TO_BIJ
    from ..simulate import _core_coeffs

    n = study.axis.size
    kw = {"speed_rpm": study.axis} if study.axis_name == "speed_rpm" else {"freq_hz": study.axis}
    k, c = _core_coeffs(bearings, n, **kw)
    truth = np.concatenate([k[:, _REPORT_TO_BIJ], c[:, _REPORT_TO_BIJ]], 1)
    scale = np.empty((n, 16))
    for o in range(16):
        src = k if o < 8 else c
        b = _REPORT_TO_BIJ[o % 8] // 4
        scale[:, o] = 0.5 * (np.abs(src[:, 4 * b]) + np.abs(src[:, 4 * b + 3]))
    ref = np.where(truth != 0, np.abs(truth), scale)
    frac = study.rms * ref / scale  # rms error as a fraction of the direct coefficient
    groups = dict(all=range(16), K_direct=[0, 1, 6, 7], K_cross=[2, 3, 4, 5], C_direct=[8, 9, 14, 15],
                  C_cross=[10, 11, 12, 13])
    return {g: float(np.nanmedian(np.sqrt(np.nanmean(frac[:, list(i)] ** 2, axis=1)))) for g, i in groups.items()}


def _unit_responses(rotor, bearings, rpm, at):
    """Responses (2, n, 4) to 1 kg at the balance radius in plane 1 and in plane 2, at angle 0."""
    from ..simulate import imbalance_response

    return np.stack([imbalance_response(rotor, bearings, Imbalance(m, (0.0, 0.0)), speed_rpm=rpm, at=at).q
                     for m in ((1.0, 0.0), (0.0, 1.0))])


def _screen(rotor, runs, unit, rpm, noise, amp_rel, phase_rad, size, at):
    """Screen value of every candidate set of ``size`` runs: median over speeds of
    max_b cond_b x relative 1X error (noise / rms amplitude + amplitude and phase errors). The
    amplitude is that at the bearings, also when the probes measure (a proxy only: the Monte Carlo
    that follows measures where the test measures)."""
    from ..identify import identify_synchronous_batch

    w = np.array([[r.mass_kg[0], r.mass_kg[1] * np.exp(-1j * np.deg2rad(r.angle_deg[1]))] for r in runs])
    q_runs = np.einsum("rp,pnc->rnc", w, unit)  # (runs, n, 4)
    if at == "probes":  # the identification's view: moved to the bearings once, not per candidate
        from ..simulate import probes_to_bearings

        q_runs = probes_to_bearings(rotor, q_runs)
    idx = np.array(list(itertools.combinations(range(len(runs)), size)), dtype=np.intp).reshape(-1, size)
    # independent: some pair of runs of the set is not a complex multiple of the other
    scale = np.abs(w).max()
    indep = np.zeros(len(idx), bool)
    for a, b in itertools.combinations(range(size), 2):
        wa, wb = w[idx[:, a]], w[idx[:, b]]
        indep |= np.abs(wa[:, 0] * wb[:, 1] - wa[:, 1] * wb[:, 0]) > 1e-9 * scale ** 2
    idx = idx[indep]
    combos = [tuple(c) for c in idx]
    if not combos:
        return [], np.array([])
    scores = np.empty(len(combos))
    e_runs = np.stack([r.generalized(rotor) for r in runs])
    for s in range(0, len(combos), 2048):
        blk = idx[s:s + 2048]
        q = q_runs[blk]  # (B, size, n, 4)
        out = identify_synchronous_batch(rotor, rpm, q, e_runs[blk], at="bearings")
        amp = out["amplitude"]  # (B, n) rms response
        rel = np.sqrt((noise / np.maximum(amp, 1e-300)) ** 2 + amp_rel ** 2 + phase_rad ** 2)
        cond = np.nanmax(out["cond"], axis=2)
        scores[s:s + 2048] = np.median(cond * rel, axis=1)
    return combos, scores


def design_trial_masses(rotor: RigidRotor, bearings: BearingCoefficients, rig: TrialMassRig, speed_rpm, *,
                        dwell_s: float = 2.0, probe_noise_m: float = 0.5e-6, fs_hz: float = 5000.0,
                        errors: SyncErrors | None = None, runs=(2, 3), screen_keep: int = 20, trials: int = 200,
                        seed: int = 0, at: str = "probes", compare=None) -> DesignResult:
    """Rank trial-mass sets for an imbalance test on ``rig`` and recommend the best pair and triple.

    Parameters
    ----------
    rotor, bearings : RigidRotor, BearingCoefficients
        The system as it is expected to be (e.g. predicted bearing coefficients).
    rig : TrialMassRig
        Holes per plane, trial masses at hand, response limit.
    speed_rpm : array_like
        Speeds of the test, rpm.
    dwell_s, probe_noise_m, fs_hz : float
        Dwell per speed, probe noise rms and sampling rate: they set the 1X noise
        (:func:`dwell_noise_m`), added to ``errors.noise_m``.
    errors : SyncErrors, optional
        The test's other errors (DAQ amplitude and phase accuracy, keyphasor, ...).
    runs : sequence of int
        Set sizes to consider (2 and/or 3 runs).
    screen_keep : int
        Candidates per set size that go through the Monte Carlo.
    trials, seed : int
        Monte Carlo trials per candidate, and the seed shared by all (common random numbers).
    compare : dict of name -> list of Imbalance, optional
        Designs to compare the recommendations with in the same Monte Carlo (e.g. the report's
        sets A-D).

    Returns
    -------
    DesignResult

    Examples
    --------
    >>> import numpy as np, rotorid
    >>> from rotorid.studies import TrialMassRig, design_trial_masses
    >>> rig = rotorid.nsf_rig()
    >>> d = design_trial_masses(rig.rotor, rig.bearings, TrialMassRig(holes=4, masses_kg=(0.004,)),
    ...                         np.linspace(3000, 6000, 4), runs=(2,), screen_keep=3, trials=50)
    >>> len(d.best[2])
    2
    """
    import pandas as pd

    _check_model(rotor, bearings)
    instance("rig", rig, TrialMassRig, what="rotorid.studies.TrialMassRig")
    errors = SyncErrors() if errors is None else instance("errors", errors, SyncErrors,
                                                         what="rotorid.studies.SyncErrors")
    rpm = real_array("speed_rpm", np.atleast_1d(speed_rpm), ndim=1, positive=True)
    if not 0 < rpm.size <= 2000:
        raise RotoridError(f"speed_rpm has {rpm.size} speeds; a design needs a few dozen (1 to 2000)")
    _check_range("speed_rpm", rpm, 1e-3, 1e6, "rpm")
    sizes = _sizes("runs", runs)
    screen_keep = index("screen_keep", screen_keep, 1, 1000)
    trials = index("trials", trials, 1, 100_000)
    seed = check_seed("seed", seed)
    choice("at", at, {"bearings", "probes"})
    compare = mapping("compare", compare)
    for name, design in compare.items():
        if not isinstance(design, (list, tuple)) or not all(isinstance(r, Imbalance) for r in design):
            raise RotoridError(f"compare[{name!r}] must be a list of rotorid.Imbalance")
    noise = float(np.hypot(errors.noise_m, dwell_noise_m(probe_noise_m, dwell_s, fs_hz)))
    errs = replace(errors, noise_m=noise)
    cands = rig.runs()
    unit = _unit_responses(rotor, bearings, rpm, at)
    if rig.max_response_m is not None:
        w = np.array([[r.mass_kg[0], r.mass_kg[1] * np.exp(-1j * np.deg2rad(r.angle_deg[1]))] for r in cands])
        peak = np.abs(np.einsum("rp,pnc->rnc", w, unit)).max(axis=(1, 2))
        cands = [r for r, p in zip(cands, peak) if p <= rig.max_response_m]
        if len(cands) < 2:
            raise RotoridError(f"no two runs keep the response below max_response_m = {rig.max_response_m:g} m "
                               f"(the smallest trial mass gives {peak.min():.3g} m): use smaller masses")
    rows, best, studies, nruns = [], {}, {}, {}
    for size in sizes:
        combos, scores = _screen(rotor, cands, unit, rpm, noise, errs.amplitude_rel, np.deg2rad(errs.phase_deg),
                                 size, at)
        if not combos:
            raise RotoridError(f"no set of {size} independent runs can be made from these trial masses and holes")
        order = np.argsort(scores)[:screen_keep]
        best_err, best_set = np.inf, None
        for rank, i in enumerate(order):
            design = [cands[j] for j in combos[i]]
            st = synchronous_study(rotor, bearings, design, rpm, errs, trials=trials, seed=seed, at=at)
            ee = expected_error(st, bearings)
            rows.append(dict(runs=size, design=" + ".join(r.name for r in design), screen=float(scores[i]),
                             expected_error=ee["all"], **{g: v for g, v in ee.items() if g != "all"}))
            if ee["all"] < best_err:
                best_err, best_set, best_study = ee["all"], design, st
        best[size] = best_set
        studies[f"recommended ({size} runs)"] = best_study
        nruns[f"recommended ({size} runs)"] = size
    ranking = pd.DataFrame(rows).sort_values(["runs", "expected_error"]).reset_index(drop=True)
    for name, design in compare.items():
        studies[name] = synchronous_study(rotor, bearings, list(design), rpm, errs, trials=trials, seed=seed, at=at)
        nruns[name] = len(design)
    comp_rows = [dict(design=name, runs=nruns[name], **expected_error(st, bearings)) for name, st in studies.items()]
    comparison = pd.DataFrame(comp_rows).rename(columns={"all": "expected_error"})
    return DesignResult(ranking=ranking, best=best, comparison=comparison, studies=studies, noise_m=noise)


def design_impact_plan(rotor: RigidRotor, bearings: BearingCoefficients, planes_m, freq_hz, *, speed_rpm: float,
                       impacts_total: int = 10, coherence: float = 0.95, errors: ImpactErrors | None = None,
                       tests=(2, 3), trials: int = 200, seed: int = 0, at: str = "probes",
                       compare=None) -> DesignResult:
    """Rank impact plans: which planes and directions to hit, with a budget of ``impacts_total``
    impacts shared equally by the tests (more tests, fewer impacts each: a larger FRF error at the
    given ``coherence``). Every pair (and triple) of (plane, direction) among ``planes_m`` x {x, y} is
    run through :func:`impact_study`; ranked by :func:`expected_error`.

    Examples
    --------
    >>> import numpy as np, rotorid
    >>> from rotorid.studies import design_impact_plan
    >>> rig = rotorid.nsf_rig()
    >>> d = design_impact_plan(rig.rotor, rig.bearings, [0.0, 0.1], np.array([40.0, 80.0]), speed_rpm=1000,
    ...                        tests=(2,), trials=50)
    >>> len(d.best[2])
    2
    """
    import pandas as pd

    _check_model(rotor, bearings)
    planes = real_array("planes_m", np.atleast_1d(planes_m), ndim=1)
    if planes.size == 0 or planes.size > 20:
        raise RotoridError(f"planes_m must list 1 to 20 axial positions where impacts can land, got {planes_m!r}")
    impacts_total = index("impacts_total", impacts_total, 2, 100_000)
    base = ImpactErrors() if errors is None else instance("errors", errors, ImpactErrors,
                                                         what="rotorid.studies.ImpactErrors")
    sizes = _sizes("tests", tests)
    trials = index("trials", trials, 1, 100_000)
    seed = check_seed("seed", seed)
    choice("at", at, {"bearings", "probes"})
    number("speed_rpm", speed_rpm, nonneg=True)
    f = real_array("freq_hz", np.atleast_1d(freq_hz), ndim=1, positive=True)
    if f.size == 0 or f.size > 2000:
        raise RotoridError(f"freq_hz must hold 1 to 2000 frequencies, got {f.size}")
    _check_range("freq_hz", f, 1e-4, 1e6, "Hz")
    frf_random_error(coherence, 1)  # coherence checked before anything runs
    compare = mapping("compare", compare)
    for name, plan in compare.items():
        if not isinstance(plan, (list, tuple)) or not plan:
            raise RotoridError(f"compare[{name!r}] must be a list of (plane_m, direction) tests")
    options = [(float(p), d) for p in np.unique(planes) for d in ("x", "y")]
    rows, best, studies = [], {}, {}
    for size in sizes:
        per = impacts_total // size
        if per < 1:
            raise RotoridError(f"impacts_total = {impacts_total} cannot give {size} tests an impact each")
        errs = replace(base, coherence=coherence, impacts=per)
        best_err = np.inf
        for plan in itertools.combinations(options, size):
            if len({d for _, d in plan}) < 2 and len({p for p, _ in plan}) < 2:
                continue
            st = impact_study(rotor, bearings, list(plan), f, errs, speed_rpm=speed_rpm, trials=trials, seed=seed, at=at)
            ee = expected_error(st, bearings)
            name = " + ".join(f"{d} at {p * 1e3:g} mm" for p, d in plan)
            rows.append(dict(tests=size, impacts_per_test=per, design=name, expected_error=ee["all"],
                             **{g: v for g, v in ee.items() if g != "all"}))
            if ee["all"] < best_err:
                best_err, best[size], studies[f"recommended ({size} tests)"] = ee["all"], list(plan), st
    if not best:
        raise RotoridError("no impact plan from these planes identifies the coefficients")
    ranking = pd.DataFrame(rows).sort_values(["tests", "expected_error"]).reset_index(drop=True)
    comp_rows = [dict(design=k, **expected_error(v, bearings)) for k, v in studies.items()]
    for name, plan in compare.items():
        errs = replace(base, coherence=coherence, impacts=max(1, impacts_total // max(len(plan), 1)))
        st = impact_study(rotor, bearings, list(plan), f, errs, speed_rpm=speed_rpm, trials=trials, seed=seed, at=at)
        studies[name] = st
        comp_rows.append(dict(design=name, **expected_error(st, bearings)))
    comparison = pd.DataFrame(comp_rows).rename(columns={"all": "expected_error"})
    return DesignResult(ranking=ranking, best=best, comparison=comparison, studies=studies)
