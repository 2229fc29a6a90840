"""Report Figure 5: how well the cross-coupled stiffnesses are identified as a function of their size.

The report (section 4, eq. 20-22) scales the cross-coupled stiffnesses of the NSF rig so that the
cross-coupled-to-direct stiffness ratio ``a`` takes the values 1.3 % (Table 4), 2, 5, 10, 50 and
100 %, identifies the coefficients from the imbalance responses of sets A-D at every speed, and
plots the total relative error E of the identified K_xy and K_yx against ``a``.
:func:`cross_coupling_sensitivity` repeats that study through a stated measurement-error model
(:class:`rotorid.ProbeResolution`); :func:`speed_range_errors` gives the median errors of all
coefficients in speed bands scaled by the first critical speed (the report's conclusions about the
speed range). :func:`cross_coupling_ratio` and :func:`scale_cross_coupling` are eq. 20 and its
inverse.
"""

from __future__ import annotations

import numpy as np

from .. import _validate
from ..errors import RotoridError
from ..identify import identify_synchronous
from ..model import BearingCoefficients, Rig, nsf_rig
from ..simulate import ProbeResolution, imbalance_response

#: the report's ratios a of Figure 5 (1.3 % is Table 4)
REPORT_RATIOS = (0.013, 0.02, 0.05, 0.10, 0.50, 1.00)
#: ratios a accepted: from a millionth (smaller ones only underflow the relative errors) to ten
#: (cross-coupled stiffness ten times the direct one)
MIN_RATIO = 1e-6
MAX_RATIO = 10.0
#: at most this many ratios, trials, speeds, trials x ratios identifications (each over all the
#: speeds, ~1 ms) and trials x ratios x speeds identified points (~10 s at the limits)
MAX_RATIOS = 100
MAX_TRIALS = 1000
MAX_SPEEDS = 100_000
MAX_CALLS = 10_000
MAX_WORK = 10_000_000
#: report section 4: the identification is poor below this fraction of the first critical speed
LOW_SPEED_FRACTION = 0.6
#: (bearing, i, j) and report name of the four cross-coupled stiffnesses
_CROSS = ((0, 0, 1, "xy1"), (1, 0, 1, "xy2"), (0, 1, 0, "yx1"), (1, 1, 0, "yx2"))
_DEFINITIONS = {"rms", "printed"}


def _default_speeds():
    """The report's identification range, 100-10,000 rpm, every 100 rpm (100 speeds)."""
    return np.arange(100.0, 10000.0 + 50.0, 100.0)


def _constant_bearings(name, bearings):
    _validate.instance(name, bearings, BearingCoefficients, what="rotorid.BearingCoefficients")
    if not bearings.is_constant:
        raise RotoridError(f"{name} must be constant coefficients (eq. 20 averages one value per bearing), got a "
                           f"table over {bearings.axis_name}")
    return bearings


def _ratio_parts(k, definition):
    """(K_ij, K_ii) of eq. 20 from k[bearing, i, j]."""
    kb = k.mean(axis=0)  # the bars: averages over the two bearings
    sq = kb[0, 1] ** 2 + kb[1, 0] ** 2
    kij = np.sqrt(sq / 2.0) if definition == "rms" else np.sqrt(sq) / 2.0
    return float(kij), float((kb[0, 0] + kb[1, 1]) / 2.0)


def cross_coupling_ratio(bearings: BearingCoefficients, *, definition: str = "rms") -> float:
    """Cross-coupled-to-direct stiffness ratio a of report eq. 20.

    Parameters
    ----------
    bearings : rotorid.BearingCoefficients
        Constant coefficients of both bearings.
    definition : {"rms", "printed"}
        ``"rms"`` (default): K_ij = sqrt((K̄xy² + K̄yx²)/2), the "squared average" the report names,
        which gives its stated 1.3 % for Table 4 (1.27 %). ``"printed"``: K_ij = sqrt(K̄xy² + K̄yx²)/2
        exactly as eq. 20 is printed, which gives 0.90 % for Table 4 (sqrt(2) less). K_ii =
        (K̄xx + K̄yy)/2 in both; the bars are averages over the two bearings.

    Returns
    -------
    float
        a = K_ij / K_ii.

    Examples
    --------
    >>> import rotorid
    >>> from rotorid.studies.sensitivity import cross_coupling_ratio
    >>> round(100 * cross_coupling_ratio(rotorid.nsf_rig().bearings), 2)
    1.27
    >>> round(100 * cross_coupling_ratio(rotorid.nsf_rig().bearings, definition="printed"), 2)
    0.9
    """
    _constant_bearings("bearings", bearings)
    _validate.choice("definition", definition, _DEFINITIONS)
    kij, kii = _ratio_parts(bearings.k, definition)
    if not kii > 0:
        raise RotoridError(f"bearings: the mean direct stiffness (Kxx + Kyy)/2 is {kii:g} N/m; eq. 20 needs it > 0")
    return kij / kii


def _check_ratio(name, a):
    a = _validate.number(name, a, positive=True)
    if not MIN_RATIO <= a <= MAX_RATIO:
        raise RotoridError(f"{name} must be from {MIN_RATIO:g} to {MAX_RATIO:g} (a fraction: cross-coupled stiffness "
                           f"up to {MAX_RATIO:g} times the direct one), got {a:g}")
    return a


def scale_cross_coupling(bearings: BearingCoefficients, a: float, *, definition: str = "rms") -> BearingCoefficients:
    """The bearings with Kxy and Kyx of both bearings scaled by one factor so that eq. 20 gives ``a``.

    Signs and proportions of the four cross-coupled stiffnesses are kept; direct stiffnesses and all
    damping coefficients are unchanged.

    Parameters
    ----------
    bearings : rotorid.BearingCoefficients
        Constant coefficients with some cross-coupled stiffness (K_ij > 0).
    a : float
        The wanted ratio, 1e-6 <= a <= 10.
    definition : {"rms", "printed"}
        Which K_ij of eq. 20 (see :func:`cross_coupling_ratio`).

    Returns
    -------
    rotorid.BearingCoefficients

    Examples
    --------
    >>> import rotorid
    >>> from rotorid.studies.sensitivity import cross_coupling_ratio, scale_cross_coupling
    >>> b = scale_cross_coupling(rotorid.nsf_rig().bearings, 0.05)
    >>> round(cross_coupling_ratio(b), 12)
    0.05
    >>> [round(v) for v in b.k[0].ravel()]  # Table 4 (Kxy 5e4, Kyx 3e4 N/m) times 0.05 / 0.012686
    [3000000, 197060, 118236, 3500000]
    """
    a0 = cross_coupling_ratio(bearings, definition=definition)
    a = _check_ratio("a", a)
    if not a0 > 0:
        raise RotoridError("bearings have no cross-coupled stiffness (Kxy = Kyx = 0 on average): there is nothing to "
                           "scale to a given ratio a")
    k = bearings.k.copy()
    s = a / a0
    k[:, 0, 1] *= s
    k[:, 1, 0] *= s
    return BearingCoefficients(k, bearings.c.copy())


def _check_ratios(ratios):
    if isinstance(ratios, (str, bytes)) or ratios is None:
        raise RotoridError(f"ratios must be numbers a (cross-coupled / direct stiffness, {MIN_RATIO:g} <= a <= "
                           f"{MAX_RATIO:g}), "
                           f"got {ratios!r}")
    r = np.atleast_1d(_validate.real_array("ratios", ratios))
    if r.ndim != 1:
        raise RotoridError(f"ratios must be a number or a 1-D list of numbers, got shape {r.shape}")
    if r.size == 0:
        raise RotoridError("ratios is empty: give at least one ratio a")
    if r.size > MAX_RATIOS:
        raise RotoridError(f"ratios: at most {MAX_RATIOS} values, got {r.size}")
    out = (r < MIN_RATIO) | (r > MAX_RATIO)
    if out.any():
        raise RotoridError(f"ratios must be > 0, from {MIN_RATIO:g} to at most {MAX_RATIO:g} (fractions: 0.05 is 5 %), "
                           f"got {r[out][0]:g}")
    return r


def _check_names(names, rig):
    if isinstance(names, str):
        names = list(names)
    if not isinstance(names, (list, tuple)) or not all(isinstance(n, str) for n in names):
        raise RotoridError(f"imbalances must be the names of imbalance sets of the rig (a string like 'ABCD' or a "
                           f"list of names), got {names!r}"[:300])
    missing = [n for n in names if n not in rig.imbalances]
    if missing:
        raise RotoridError(f"imbalances: {missing[0]!r} is not an imbalance set of the rig (sets: "
                           f"{', '.join(map(repr, rig.imbalances))})")
    if len(set(names)) != len(names):
        raise RotoridError(f"imbalances: a set is named twice in {names!r}")
    if len(names) < 2:
        raise RotoridError(f"imbalances: identifying all 16 coefficients needs at least two imbalance sets, got "
                           f"{len(names)}")
    return list(names)


def _check_common(ratios, speed_rpm, resolution, trials, seed, imbalances, rig, at, definition):
    ratios = _check_ratios(ratios)
    rig = nsf_rig() if rig is None else _validate.instance("rig", rig, Rig, allow_none=True, what="rotorid.Rig")
    _constant_bearings("rig.bearings", rig.bearings)
    if speed_rpm is None:
        rpm = _default_speeds()
    else:
        rpm = _validate.speeds_rpm("speed_rpm", speed_rpm)
        if rpm.size > MAX_SPEEDS:
            raise RotoridError(f"speed_rpm: at most {MAX_SPEEDS} speeds, got {rpm.size}")
    res = _validate.instance("resolution", resolution, ProbeResolution, allow_none=True,
                             what="rotorid.ProbeResolution")
    res = ProbeResolution() if res is None else res
    trials = _validate.index("trials", trials, 1, MAX_TRIALS)
    seed = _validate.seed("seed", seed)
    names = _check_names(imbalances, rig)
    _validate.choice("at", at, {"bearings", "probes"})
    _validate.choice("definition", definition, _DEFINITIONS)
    a0 = cross_coupling_ratio(rig.bearings, definition=definition)
    if not a0 > 0:
        raise RotoridError("rig.bearings have no cross-coupled stiffness (Kxy = Kyx = 0 on average): there is nothing "
                           "to scale to a ratio a")
    if res.noise_m == 0:
        trials = 1  # rounding alone is deterministic: every trial would be the same
    if trials * ratios.size > MAX_CALLS:
        raise RotoridError(f"trials x ratios = {trials} x {ratios.size} identifications; at most {MAX_CALLS:,} "
                           "(use fewer trials or ratios)")
    if trials * ratios.size * rpm.size > MAX_WORK:
        raise RotoridError(f"trials x ratios x speeds = {trials} x {ratios.size} x {rpm.size} identifications; at most "
                           f"{MAX_WORK:,} points (use fewer trials or speeds)")
    return ratios, rpm, res, trials, seed, names, rig


def _simulate(rig, ratios, rpm, res, trials, seed, names, at, definition):
    """Per ratio: (scaled bearings, identified report vectors (trials, n, 16))."""
    out = []
    for a in ratios:
        brg = scale_cross_coupling(rig.bearings, a, definition=definition)
        runs = [imbalance_response(rig.rotor, brg, rig.imbalances[n], speed_rpm=rpm, at=at) for n in names]
        est = []
        for t in range(trials):
            # the same random numbers for every ratio (common random numbers): the ratios differ
            # only by the ratio
            rng = np.random.default_rng([seed, t])
            meas = [res.measure(r, rng) for r in runs]
            try:
                ident = identify_synchronous(rig.rotor, meas)
            except RotoridError as exc:
                raise type(exc)(f"a = {a:g}: after the measurement model ({_describe(res)}) {exc}") from None
            est.append(ident.report_vector())
        out.append((brg, np.stack(est)))
    return out


def _describe(res):
    s = f"amplitude rounded to {res.amplitude_m * 1e6:.4g} µm, phase to {res.phase_deg:g}°"
    return s + (f", noise {res.noise_m * 1e6:.4g} µm rms" if res.noise_m else "")


def _first_critical(rig_rotor, brg, top_rpm):
    """Critical speeds (rpm) below 3 x ``top_rpm``, ascending (empty when there are none)."""
    from ..modal import critical_speeds

    return critical_speeds(rig_rotor, brg, max_rpm=3.0 * top_rpm).speed_rpm.to_numpy()


def cross_coupling_sensitivity(ratios=REPORT_RATIOS, *, speed_rpm=None, resolution: ProbeResolution | None = None,
                               trials: int = 1, seed: int = 2001, imbalances="ABCD", rig: Rig | None = None,
                               at: str = "bearings", definition: str = "rms"):
    """Report Figure 5: total relative error of the identified cross-coupled stiffnesses vs the ratio a.

    For each ratio a (eq. 20) the cross-coupled stiffnesses Kxy, Kyx of both bearings are scaled by
    one factor (signs and proportions of the rig's kept, see :func:`scale_cross_coupling`), the
    imbalance responses of the sets ``imbalances`` are simulated at ``speed_rpm``, passed through
    the measurement-error model ``resolution`` and identified with
    :func:`rotorid.identify_synchronous` (default options, every point used whatever its flag).
    For each of Kxy1, Kxy2, Kyx1, Kyx2 the errors over the n speeds give

    - ``E`` (eq. 21-22 exactly as printed): E = e/|K| with e = (1/n)·sqrt(Σ(K̂ - K)²);
    - ``Erms``: sqrt(mean((K̂ - K)²))/|K| = E·sqrt(n), the rms relative error. Eq. 21 puts 1/n
      outside the root, so E shrinks as 1/sqrt(n) for the same per-point errors: E depends on how
      many speeds there are, which is why the report compares the ratios at an equal n (done here:
      every ratio is identified at the same speeds), and only Erms compares across grids.

    Both also over the speeds at or above 0.6 of the first critical speed of the rig as given
    (Table 4 for the NSF rig; one cut-off for every ratio, so n is equal there too): the report
    finds the identification poor below it.

    Speeds where the measured responses leave the identification singular for any ratio or trial
    (amplitudes rounded to zero at the lowest speeds) are dropped for every ratio, so n stays
    equal; the frame's ``attrs["excluded_rpm"]`` lists them.

    Parameters
    ----------
    ratios : sequence of float
        The ratios a (fractions: 0.05 is 5 %), each from 1e-6 to 10 (at most 100 ratios).
        Default: the report's 1.3, 2, 5, 10, 50 and 100 %.
    speed_rpm : array_like, optional
        Identification speeds (rpm, > 0, at most 100,000). Default: the report's range, 100 to 10,000 rpm every
        100 rpm.
    resolution : rotorid.ProbeResolution, optional
        The measurement-error model of every 1X vector. Default ``ProbeResolution()``: amplitude
        rounded to 0.001 mil (0.0254 µm), phase to 0.01°, no noise (the demo's Figure 4 model).
        ``ProbeResolution(0, 0)`` gives the exact responses.
    trials : int
        Number of noise realizations (1 to 1000; trials x ratios at most 10,000 and trials x
        ratios x speeds at most 1e7) when ``resolution.noise_m > 0``; E and Erms then
        pool the squared errors of all trials (root of their mean). Without noise the model is
        deterministic and one trial is computed whatever ``trials`` says.
    seed : int
        Seed of the noise (>= 0). Trial t of every ratio uses the same random numbers.
    imbalances : str or list of str
        Names of the imbalance sets of the rig used (at least two), default "ABCD" (Table 3).
    rig : rotorid.Rig, optional
        A rig with constant bearing coefficients that have some cross-coupled stiffness; default
        :func:`rotorid.nsf_rig`.
    at : {"bearings", "probes"}
        Where the responses are measured (and rounded): at the bearings (default, as the demo's
        Figure 4) or at the rotor's probes (then moved to the bearings with eq. 19).
    definition : {"rms", "printed"}
        K_ij of eq. 20 (see :func:`cross_coupling_ratio`): "rms" gives the report's 1.3 % for
        Table 4, "printed" 0.90 %.

    Returns
    -------
    pandas.DataFrame
        One row per ratio: ``a``, ``n`` (speeds used), ``E_xy1``, ``E_xy2``, ``E_yx1``, ``E_yx2``,
        ``Erms_xy1``, ..., ``n_above``, ``E_xy1_above``, ..., ``Erms_yx2_above`` (speeds at or
        above 0.6 of the first critical speed), ``first_critical_rpm`` (of the scaled rig).
        Errors are fractions (0.1 = 10 %). ``attrs`` holds ``speed_rpm`` (used), ``excluded_rpm``,
        ``cutoff_rpm``, ``first_critical_rpm`` (of the rig as given), ``a_rig`` (its ratio),
        ``definition``, ``resolution`` and ``trials``. The ``_above`` columns are NaN when the rig
        has no critical speed below 3 times the top speed or no speed is above the cut-off.

    Raises
    ------
    rotorid.RotoridError
        Bad arguments, or measured responses that leave nothing to identify.

    Examples
    --------
    >>> import rotorid
    >>> from rotorid.studies.sensitivity import cross_coupling_sensitivity
    >>> exact = cross_coupling_sensitivity([0.013, 0.10], resolution=rotorid.ProbeResolution(0, 0))
    >>> bool((exact[["E_xy1", "E_yx2"]] < 1e-6).all().all())
    True
    >>> df = cross_coupling_sensitivity([0.013, 0.10])  # amplitude to 0.0254 µm, phase to 0.01°
    >>> int(df.n.iloc[0]), int(df.n_above.iloc[0]), round(df.attrs["cutoff_rpm"])
    (98, 80, 2080)
    >>> bool((df.Erms_xy1_above.iloc[1] < df.Erms_xy1_above.iloc[0] / 5))
    True
    """
    import pandas as pd

    ratios, rpm, res, trials, seed, names, rig = _check_common(ratios, speed_rpm, resolution, trials, seed,
                                                               imbalances, rig, at, definition)
    sims = _simulate(rig, ratios, rpm, res, trials, seed, names, at, definition)
    cross_idx = [2, 3, 4, 5]  # Kxy1, Kxy2, Kyx1, Kyx2 in report order
    ok = np.ones(rpm.size, bool)
    for _, est in sims:
        ok &= np.isfinite(est[:, :, cross_idx]).all(axis=(0, 2))
    if not ok.any():
        raise RotoridError(f"the identification is singular at every speed for some ratio after the measurement model "
                           f"({_describe(res)}): nothing to compare")
    crit = _first_critical(rig.rotor, rig.bearings, rpm.max())
    cutoff = LOW_SPEED_FRACTION * crit[0] if crit.size else np.nan
    above = ok & (rpm >= cutoff) if crit.size else np.zeros_like(ok)
    rows = []
    for a, (brg, est) in zip(ratios, sims):
        row = dict(a=float(a), n=int(ok.sum()))
        for sel, suffix in ((ok, ""), (above, "_above")):
            n = int(sel.sum())
            if suffix:
                row["n_above"] = n
            for (b, i, j, name), col in zip(_CROSS, cross_idx):
                true = brg.k[b, i, j]
                if n == 0:
                    e_sum = np.nan
                else:
                    d = est[:, sel, col] - true
                    e_sum = np.sqrt(np.mean(np.sum(d ** 2, axis=1)))  # pooled over trials
                row[f"E_{name}{suffix}"] = e_sum / n / abs(true) if n else np.nan
                row[f"Erms_{name}{suffix}"] = e_sum / np.sqrt(n) / abs(true) if n else np.nan
        c = _first_critical(rig.rotor, brg, rpm.max())
        row["first_critical_rpm"] = float(c[0]) if c.size else np.nan
        rows.append(row)
    order = (["a", "n"] + [f"E_{x[3]}" for x in _CROSS] + [f"Erms_{x[3]}" for x in _CROSS] + ["n_above"]
             + [f"E_{x[3]}_above" for x in _CROSS] + [f"Erms_{x[3]}_above" for x in _CROSS] + ["first_critical_rpm"])
    df = pd.DataFrame(rows, columns=order)
    df.attrs.update(speed_rpm=rpm[ok], excluded_rpm=rpm[~ok], cutoff_rpm=float(cutoff),
                    first_critical_rpm=float(crit[0]) if crit.size else np.nan,
                    a_rig=cross_coupling_ratio(rig.bearings, definition=definition), definition=definition,
                    resolution=res, trials=trials)
    return df


def _check_bands(bands):
    if bands is None:
        return None
    if isinstance(bands, (str, bytes)):
        raise RotoridError(f"bands must be increasing band edges (fractions of the first critical speed), got "
                           f"{bands!r}")
    b = np.atleast_1d(_validate.real_array("bands", bands, finite=False))
    if b.ndim != 1 or b.size < 2:
        raise RotoridError(f"bands must be at least two increasing edges (fractions of the first critical speed), got "
                           f"shape {b.shape}")
    if b.size > 101:
        raise RotoridError(f"bands: at most 101 edges, got {b.size}")
    if np.isnan(b).any() or np.isneginf(b).any() or b[0] < 0 or np.any(np.diff(b) <= 0):
        raise RotoridError(f"bands must be increasing edges >= 0 (the last may be inf), got {b.tolist()}")
    if np.isinf(b[:-1]).any():
        raise RotoridError("bands: only the last edge may be inf")
    return b


def speed_range_errors(ratios=(0.013, 0.02, 0.10), *, speed_rpm=None, resolution: ProbeResolution | None = None,
                       trials: int = 1, seed: int = 2001, imbalances="ABCD", rig: Rig | None = None,
                       at: str = "bearings", definition: str = "rms", bands=None):
    """Median relative errors of the identified coefficients in speed bands scaled by the first critical speed.

    The same study as :func:`cross_coupling_sensitivity` (scaled cross-coupling, simulated
    responses of the imbalance sets, measurement model, identification at every speed), summarized
    per band of speed ratio ω/ω_n1, where ω_n1 is the first critical speed of the rig at that ratio
    (:func:`rotorid.critical_speeds`). Default bands: below 0.6 (the report: poor there), 0.6 to 1
    (improving), from the first to the last critical speed below the top speed ("between the
    critical speeds": the report's best range), above the last critical speed.

    Parameters
    ----------
    ratios, speed_rpm, resolution, trials, seed, imbalances, rig, at, definition
        As in :func:`cross_coupling_sensitivity`; default ratios 1.3, 2 and 10 %.
    bands : sequence of float, optional
        Band edges as fractions of the first critical speed, increasing, >= 0, the last may be
        ``inf``.

    Returns
    -------
    pandas.DataFrame
        One row per ratio and band: ``a``, ``band`` (e.g. "0-0.6"), ``lo``, ``hi`` (fractions),
        ``lo_rpm``, ``hi_rpm``, ``points`` (speeds in the band), ``singular`` (of them, points the
        identification could not solve; left out of the medians), ``K_direct``, ``K_cross``,
        ``C_direct``, ``C_cross``: medians of |p̂ - p|/|p| over the band's points, the trials and
        the four coefficients of each kind (fractions). Bands without points are left out.

    Raises
    ------
    rotorid.RotoridError
        Bad arguments, a rig without critical speed below 3 times the top speed, or measured
        responses that leave nothing to identify.

    Examples
    --------
    >>> from rotorid.studies.sensitivity import speed_range_errors
    >>> df = speed_range_errors([0.013])
    >>> df.band.tolist()
    ['0-0.6', '0.6-1', '1-2.118', '2.118-inf']
    >>> k = df.set_index("band").K_cross
    >>> bool(k["1-2.118"] < k["0.6-1"] < k["0-0.6"])
    True
    """
    import pandas as pd

    ratios, rpm, res, trials, seed, names, rig = _check_common(ratios, speed_rpm, resolution, trials, seed,
                                                               imbalances, rig, at, definition)
    edges_in = _check_bands(bands)
    sims = _simulate(rig, ratios, rpm, res, trials, seed, names, at, definition)
    kinds = dict(K_direct=[0, 1, 6, 7], K_cross=[2, 3, 4, 5], C_direct=[8, 9, 14, 15], C_cross=[10, 11, 12, 13])
    rows = []
    for a, (brg, est) in zip(ratios, sims):
        crit = _first_critical(rig.rotor, brg, rpm.max())
        if not crit.size:
            raise RotoridError(f"a = {a:g}: the rig has no critical speed below {3 * rpm.max():g} rpm, so no speed "
                               "bands relative to the first critical speed")
        w1 = crit[0]
        if edges_in is None:
            last = crit[crit <= rpm.max()].max(initial=w1) / w1  # the last critical speed within the speeds
            edges = np.array([0.0, LOW_SPEED_FRACTION, 1.0] + ([last] if last > 1.0 + 1e-9 else []) + [np.inf])
        else:
            edges = edges_in
        p0 = brg.to_report_vector()
        with np.errstate(divide="ignore", invalid="ignore"):
            err = np.abs(est - p0) / np.abs(p0)  # (trials, n, 16); zero coefficients give inf/NaN
        solved = np.isfinite(est).all(axis=(0, 2))
        ratio = rpm / w1
        for lo, hi in zip(edges[:-1], edges[1:]):
            sel = (ratio >= lo) & (ratio < hi)
            if not sel.any():
                continue
            row = dict(a=float(a), band=f"{_fmt(lo)}-{_fmt(hi)}", lo=float(lo), hi=float(hi), lo_rpm=float(lo * w1),
                       hi_rpm=float(hi * w1), points=int(sel.sum()), singular=int((sel & ~solved).sum()))
            for kind, idx in kinds.items():
                e = err[:, sel & solved][:, :, idx]
                e = e[np.isfinite(e)]
                row[kind] = float(np.median(e)) if e.size else np.nan
            rows.append(row)
    return pd.DataFrame(rows, columns=["a", "band", "lo", "hi", "lo_rpm", "hi_rpm", "points", "singular",
                                       *kinds])


def _fmt(x):
    return "inf" if np.isinf(x) else f"{x:.4g}"
