"""Phase-reference calibration: a keyphasor angle offset and a channel delay as nuisance parameters.

A phase error common to every 1X vector at a speed (keyphasor mark not at the angle assumed,
probe channels lagging the keyphasor through anti-alias filters or cabling) leaves a zero
least-squares residual: the data then agree exactly with a different impedance, so nothing in a
single speed can reveal it. Across speeds it can: the error phi(Omega) = theta - Omega tau (an angle
offset theta and a delay tau) would have to make the coefficients vary with speed in one particular
way. Assuming the coefficients constant over speed (or smooth: a polynomial in speed of degree
``degree``), the measured vectors are corrected by exp(-j phi(Omega)) and (theta, tau) chosen to make
the identified coefficients most consistent with that model, weighted by their covariance:

    min over (theta, tau) of  sum_speeds || L^-1 (p(Omega; theta, tau) - model(Omega)) ||^2

(p the 16 coefficients, L = diag of their standard errors at the speed, the model refitted for
every (theta, tau) with the same weights). The uncertainty of (theta, tau) is the sandwich
H^-1 (sum_speeds J_s^T L^-1 C_s L^-T J_s) H^-1 with J the Jacobian at the optimum, H = J^T J and C_s
the full 16 x 16 coefficient covariance of each speed, widened by the misfit's chi^2 where it
exceeds 1 (a chi^2 above ``MISFIT_CHI2`` makes the estimate a diagnostic); without covariances (L
then the bearings' scale) H^-1 times chi^2.

A phase error of each speed alone (a keyphasor whose timing errs from dwell to dwell, a filter
whose phase is not linear in frequency) is what theta - Omega tau cannot follow. Where it is known
(``keyphasor_angle_std_deg``) it weights the speeds; what nobody stated is estimated as a random
effect e_s ~ N(0, s_e^2) of each speed: at the optimum each speed's misfit along the direction a
phase of that speed alone moves its coefficients, g_s (whitened), gives delta_s = g_s^T r_s / g_s^T g_s
with variance v_s = g_s^T W C_s W g_s / (g_s^T g_s)^2 from the stated covariance, and s_e^2 solves
Paule and Mandel's moment equation sum_s delta_s^2 / (v_s + s_e^2) = n - p (n speeds, p = the
estimated parameters plus the model's degree + 1; 0 where the left side is already below). The fit
is then repeated with s_e in every speed's phase uncertainty (until s_e settles), and s_e stays in
the calibrated reference's uncertainty (:meth:`PhaseCalibration.phase_std_deg`). 1X tables from a
keyphasor whose timing errs at the speeds commensurate with the sample rate (RC edges of 0.5
sample, 10,240 Hz, a 0.3 degree mark offset, 20 trials), calibration applied: the damping's 95 %
intervals covered 63 % without it, 89 % with it (99 % of the points flagged ok). A speed whose
phase lies off the calibrated line beyond the scatter (Bonferroni's 5 % point, sought against a
robust s_e first so that two do not hide each other) keeps its own delta_s^2 - v_s where that is
larger. With constant coefficients
assumed, a real speed dependence of the coefficients is partly absorbed into theta and tau: use
``degree`` >= 1 for supports whose coefficients vary, and read the result as a diagnostic.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from .errors import RotoridError
from .simulate import RPM, SyncResponse


@dataclass
class PhaseCalibration:
    """Estimated phase-reference errors: the responses were measured as q e^{j(theta - Omega tau)}.

    ``chi2``: the coefficients' misfit of the model in speed per degree of freedom, with the stated
    uncertainty (above ``MISFIT_CHI2`` the estimate is a diagnostic). ``scatter_deg``: the phase
    error of each speed alone beyond the stated uncertainty, estimated from that misfit (0 where
    none shows or too few speeds); it is part of :meth:`phase_std_deg`. ``scatter_dof``: the
    degrees of freedom that estimate rests on (speeds less the fitted parameters; below 1 it is
    not estimated). ``outlier_speeds_rpm``, ``outlier_deg``: speeds whose
    phase lies off the calibrated line beyond the scatter (Bonferroni's 5 % point), each with its
    own phase error, which :meth:`phase_std_deg` takes there instead of ``scatter_deg``.
    """

    offset_deg: float
    offset_std_deg: float
    delay_s: float
    delay_std_s: float
    chi2: float
    n_speeds: int
    significant: bool
    message: str
    offset_delay_corr: float = 0.0
    scatter_deg: float = 0.0
    scatter_dof: int = 0
    outlier_speeds_rpm: tuple = ()
    outlier_deg: tuple = ()

    def phase_std_deg(self, speed_rpm):
        """Standard uncertainty of the calibrated phase reference at each speed (deg), from the
        estimate's covariance and the phase errors of each speed alone: sqrt(s_theta² + Omega²
        s_tau² - 2 Omega r s_theta s_tau + s_e²), with r the correlation of the two estimates and
        s_e :meth:`scatter_std_deg`. It stays in the coefficients' uncertainty once the
        calibration is applied (``keyphasor_angle_std_deg`` of
        :func:`rotorid.identify_synchronous`).

        Examples
        --------
        >>> from rotorid.phasecal import PhaseCalibration
        >>> cal = PhaseCalibration(0.5, 0.1, 10e-6, 0.0, 1.0, 8, True, "")
        >>> round(float(cal.phase_std_deg([3000.0])[0]), 3)
        0.1
        """
        rpm = _speeds(speed_rpm)
        return np.hypot(self.line_std_deg(rpm), self.scatter_std_deg(rpm))

    def line_cov(self):
        """(2, 2) covariance of the estimated offset (deg) and delay (s).

        Examples
        --------
        >>> from rotorid.phasecal import PhaseCalibration
        >>> PhaseCalibration(0.5, 0.1, 10e-6, 2e-6, 1.0, 8, True, "").line_cov()[0, 0].round(4)
        np.float64(0.01)
        """
        c = self.offset_delay_corr * self.offset_std_deg * self.delay_std_s
        return np.array([[self.offset_std_deg ** 2, c], [c, self.delay_std_s ** 2]])

    def line_std_deg(self, speed_rpm):
        """Standard uncertainty of the estimated line theta - Omega tau at each speed (deg), without
        the phase errors of each speed alone: sqrt(s_theta² + Omega² s_tau² - 2 Omega r s_theta
        s_tau).

        Examples
        --------
        >>> from rotorid.phasecal import PhaseCalibration
        >>> cal = PhaseCalibration(0.5, 0.1, 10e-6, 0.0, 1.0, 8, True, "", scatter_deg=0.2)
        >>> round(float(cal.line_std_deg([3000.0])[0]), 3)
        0.1
        """
        om = _speeds(speed_rpm) * RPM
        s_th, s_tau = np.deg2rad(self.offset_std_deg), self.delay_std_s
        # phase = theta - Omega tau: the covariance term enters with a minus sign
        var = s_th ** 2 + (om * s_tau) ** 2 - 2.0 * om * self.offset_delay_corr * s_th * s_tau
        return np.rad2deg(np.sqrt(np.clip(var, 0.0, None)))

    def error_deg(self, speed_rpm):
        """The phase error of the vectors as measured at each speed, as estimated (deg): theta -
        Omega tau, what :meth:`apply` takes out.

        Examples
        --------
        >>> from rotorid.phasecal import PhaseCalibration
        >>> cal = PhaseCalibration(0.5, 0.1, 10e-6, 0.0, 1.0, 8, True, "")
        >>> cal.error_deg([0.1, 3000.0]).round(3).tolist()   # 10 µs at 3000 rpm: 0.18 deg
        [0.5, 0.32]
        """
        om = _speeds(speed_rpm) * RPM
        return self.offset_deg - np.rad2deg(om * self.delay_s)

    def scatter_std_deg(self, speed_rpm):
        """The phase error of each speed alone beyond the stated uncertainty (deg): ``scatter_deg``,
        and at an outlying speed its own ``outlier_deg``. An uncertainty of the vectors as
        measured, whether the calibration is applied or not (the imbalance chain adds it to
        ``keyphasor_angle_std_deg`` also when the calibration is only reported).

        Examples
        --------
        >>> from rotorid.phasecal import PhaseCalibration
        >>> cal = PhaseCalibration(0.5, 0.1, 10e-6, 0.0, 1.0, 8, True, "", scatter_deg=0.02,
        ...                        outlier_speeds_rpm=(4000.0,), outlier_deg=(0.3,))
        >>> cal.scatter_std_deg([3000.0, 4000.0]).round(3).tolist()
        [0.02, 0.3]
        """
        rpm = _speeds(speed_rpm)
        sd = np.full(rpm.shape, float(self.scatter_deg))
        for at_rpm, own in zip(self.outlier_speeds_rpm, self.outlier_deg):
            sd = np.where(np.isclose(rpm, at_rpm, rtol=1e-9, atol=0.0), own, sd)
        return sd

    def apply(self, runs):
        """The runs corrected (each SyncResponse's q multiplied by e^{-j(theta - Omega tau)})."""
        runs = _runs(runs)
        return [_rotated(r, -np.deg2rad(self.offset_deg), -self.delay_s) for r in runs]


def _line_scale(om_max):
    """(2,) factors that turn a line's (offset deg, delay s) into phases (deg, and deg at the top
    speed ``om_max`` rad/s), where the two compare (symmetry, definiteness of a (2, 2) matrix)."""
    return np.array([1.0, np.rad2deg(om_max)])


def _speeds(speed_rpm):
    """Speeds in rpm as a 1-d float array, or a RotoridError."""
    from ._validate import real_array

    return np.atleast_1d(real_array("speed_rpm", speed_rpm, positive=True))


def _runs(runs) -> list:
    """A list of SyncResponse, or a RotoridError naming what is not."""
    if isinstance(runs, (SyncResponse, str, bytes)):
        raise RotoridError(f"runs must be a list of SyncResponse, got one {type(runs).__name__}")
    try:
        runs = list(runs)
    except TypeError:
        raise RotoridError(f"runs must be a list of SyncResponse, got {type(runs).__name__}") from None
    for i, r in enumerate(runs):
        if not isinstance(r, SyncResponse):
            raise RotoridError(f"runs[{i}] must be a SyncResponse, got {type(r).__name__}")
    return runs


def _rotated(run: SyncResponse, theta, tau) -> SyncResponse:
    """q e^{j(theta - Omega tau)}: the covariance rotates with it."""
    om = run.speed_rpm * RPM
    ph = theta - om * tau
    rot = np.exp(1j * ph)
    c, s = np.cos(ph), np.sin(ph)
    R = np.zeros((om.size, 8, 8))
    for j in range(4):
        R[:, j, j] = c
        R[:, j, j + 4] = -s
        R[:, j + 4, j] = s
        R[:, j + 4, j + 4] = c
    Rt = np.transpose(R, (0, 2, 1))

    def turned(m):
        return None if m is None else R @ m @ Rt

    if run.pedestal is None:
        return SyncResponse(run.speed_rpm, run.q * rot[:, None], run.imbalance, run.at, run.name, turned(run.cov),
                            run.dof)
    # the accelerometers share the keyphasor reference: their vectors turn with the probes'
    return SyncResponse(run.speed_rpm, run.q * rot[:, None], run.imbalance, run.at, run.name, turned(run.cov), run.dof,
                        run.pedestal * rot[:, None], turned(run.pedestal_cov), turned(run.pedestal_cross))


#: a misfit chi² (per degree of freedom, the coefficients each whitened by its standard error)
#: above which the message says the model does not fit (clean data: 0.4-1.5)
MISFIT_CHI2 = 3.0
#: the largest phase scatter between speeds (deg) taken into the error bars; beyond it the
#: calibration is refused
MAX_SCATTER_DEG = 10.0


def _flagged(ident, reason):
    """Per point: whether ``ident`` flags it for ``reason``."""
    if reason not in ident.flag_reasons:
        return np.zeros(ident.axis.size, dtype=bool)
    return (ident.flag_code.astype(np.int64) >> ident.flag_reasons.index(reason)) & 1 == 1


def calibrate_phase(rotor, runs, *, delay: bool = True, offset: bool = True, degree: int = 0,
                    significance: float = 3.0, **ident_kw) -> PhaseCalibration:
    """Estimate a keyphasor angle offset and a probe-channel delay from imbalance runs.

    Parameters
    ----------
    rotor : RigidRotor
    runs : list of SyncResponse
        The runs as for :func:`rotorid.identify_synchronous`, at three or more speeds, best with
        their measurement covariance (``cov``; from the imbalance chain). Points flagged only
        "uncertain", "negative direct damping" or "identical bearings rejected by the data" (the
        last two a phase error can cause; the last only where the calibrated phase reference
        removes the rejection) take part, weighted by their standard errors; points flagged for
        anything else (singular, ill-conditioned, low amplitude, unknown uncertainty, runs that
        disagree) are left out. Where the coefficients misfit the model beyond their covariance
        (chi² above ``MISFIT_CHI2``) the uncertainty is widened by the chi² and the message calls
        the estimate a diagnostic.
    delay, offset : bool
        Which of the two to estimate (the other is held at 0).
    degree : int
        Polynomial degree in speed of the coefficient model (0: constant coefficients).
    significance : float
        An estimate this many standard errors from zero is reported as significant (a warning).
    **ident_kw
        Passed to :func:`rotorid.identify_synchronous` (method, identical, thresholds,
        ``shared_cov``). ``keyphasor_angle_std_deg`` (per speed) is for phase errors of each speed
        alone, such as the keyphasor timing local to each dwell (``ImbalanceChainResult.
        keyphasor_local_std_deg``): theta - Omega tau cannot follow them, so they weight the speeds
        and enter the estimate's uncertainty. A phase error common to the speeds is what this
        estimates: do not pass it.

    Returns
    -------
    PhaseCalibration
        ``apply(runs)`` gives the corrected runs.

    Examples
    --------
    >>> import numpy as np, rotorid
    >>> rig = rotorid.nsf_rig()
    >>> rpm = np.arange(3200.0, 6001.0, 200.0)
    >>> runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm) for s in "ABCD"]
    >>> for r in runs:   # measured with a keyphasor 0.5 deg off and probes lagging by 10 us
    ...     r.q = r.q * np.exp(1j * (np.deg2rad(0.5) - r.speed_rpm * np.pi / 30 * 10e-6))[:, None]
    >>> cal = rotorid.calibrate_phase(rig.rotor, runs)
    >>> round(cal.offset_deg, 3), round(cal.delay_s * 1e6, 2)
    (0.5, 10.0)
    """
    from scipy.optimize import brentq, least_squares
    from scipy.stats import chi2 as chi2_dist
    from scipy.stats import norm as norm_dist

    from .identify import identify_synchronous
    from .uncertainty import report_vector

    from ._validate import index, number

    runs = _runs(runs)
    for nm, v in (("delay", delay), ("offset", offset)):
        if not isinstance(v, (bool, np.bool_)):
            raise RotoridError(f"{nm} must be True or False, got {v!r}")
    significance = number("significance", significance, positive=True)
    if not (offset or delay):
        raise RotoridError("calibrate_phase: estimate the offset, the delay or both")
    degree = index("degree", degree, 0)
    unknown = sorted(set(ident_kw) - {"method", "identical", "cond_max", "min_rel_amplitude", "max_rel_std",
                                      "estimator", "shared_cov", "accel_gain_std", "accel_phase_std_deg",
                                      "keyphasor_angle_std_deg"})
    if unknown:
        raise RotoridError(f"calibrate_phase got unknown argument(s) {unknown}")
    # the accelerometers' calibration is a systematic error common to all runs: it does not enter
    # the misfit between runs that the phase reference is estimated from
    ident_kw = {k: v for k, v in ident_kw.items() if k not in ("accel_gain_std", "accel_phase_std_deg")}
    base = identify_synchronous(rotor, runs, **ident_kw)
    # (the phase errors of each speed alone weight the speeds through base.cov; the refits need only
    # the coefficients)
    fit_kw = {k: v for k, v in ident_kw.items() if k != "keyphasor_angle_std_deg"}
    # points flagged only for negative direct damping count: a phase reference far off is one way
    # to get it, and is what this estimates; so is identical bearings rejected by the data (a phase
    # error turns the displacements but not the imbalance forces, and the two bearings' equations
    # then disagree: with a mark 0.3 degree off the calibration was made in 1 of 20 trials). So do
    # points flagged only "uncertain": their standard errors weight them down (left out, a keyphasor
    # whose timing is uncertain at most speeds, RC edges of 0.5 sample at 10 kHz, left fewer than 3
    # speeds: the calibration was not made and the mark's 0.3 degree stayed in the coefficients,
    # outside their intervals)
    from .identify import IDENTICAL_REJECTED, NEGATIVE_DAMPING

    code = base.flag_code.astype(np.int64)
    for reason in (NEGATIVE_DAMPING, IDENTICAL_REJECTED, "uncertain"):
        if reason in base.flag_reasons:
            code = code & ~(1 << base.flag_reasons.index(reason))
    rejected = _flagged(base, IDENTICAL_REJECTED)
    sel = (code == 0) & np.all(np.isfinite(base.k.reshape(base.axis.size, -1)), axis=1)
    n_par = int(offset) + int(delay)

    def params(x):
        it = iter(x)
        th = next(it) if offset else 0.0
        tau = next(it) * 1e-6 if delay else 0.0
        return th, tau

    def coefficients(th, tau, idx):
        """The 16 coefficients (report order) at the speeds ``idx`` of the runs corrected by
        e^{-j(th - Omega tau)}."""
        corrected = [_rotated(r, -th, -tau) for r in runs]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ident = identify_synchronous(rotor, corrected, **{**fit_kw, "max_rel_std": np.inf})
        return report_vector(ident.k, ident.c)[idx]

    def model_residual(p, V, weight):
        """Each coefficient's polynomial in speed fitted by least squares with the misfit's weights
        (an unweighted fit left the sandwich short by the mean's share: the estimates' spread was
        1.3-1.8 times the stated uncertainty), and what it leaves: (n, 16)."""
        out = []
        for j in range(16):
            y, sw = p[:, j], weight[:, j]
            coef, *_ = np.linalg.lstsq(V * sw[:, None], y * sw, rcond=None)
            out.append(y - V @ coef)
        return np.stack(out, axis=1)

    def whitening(sel, coef_cov):
        """(weight (n, 16), whether it is the coefficients' own): each coefficient by its own
        standard error (the full 16 x 16 covariance is nearly singular in some directions, where
        second-order effects would then dominate the misfit), else by the bearings' scale."""
        if coef_cov is not None and np.all(np.isfinite(coef_cov[sel])):
            sd = np.sqrt(np.clip(np.diagonal(coef_cov[sel], axis1=1, axis2=2), 1e-300, None))
            return 1.0 / sd, True
        rv = np.abs(base.report_vector()[sel])
        scale = np.concatenate([np.repeat(np.median(rv[:, [0, 1, 6, 7]]), 8), np.repeat(np.median(rv[:, 8:][:, [0, 1, 6, 7]]), 8)])
        return np.broadcast_to(1.0 / scale, (int(sel.sum()), 16)), False

    def speed_model(sel):
        """The polynomial model in speed at the speeds ``sel``: (n, degree + 1)."""
        om = base.axis[sel] * RPM
        return np.vander((om - om.mean()) / max(np.ptp(om), 1e-300), degree + 1)

    def _fit(sel, coef_cov, why=""):
        n = int(sel.sum())
        if n < degree + 3:
            raise RotoridError(f"calibrate_phase needs at least {degree + 3} trustworthy speeds (points neither singular, "
                               f"ill-conditioned, of too low amplitude, of unknown uncertainty nor of runs that disagree) to "
                               f"separate a phase offset and a delay from the coefficients, got {n}{why}")
        weight, weighted = whitening(sel, coef_cov)
        V = speed_model(sel)
        idx = np.nonzero(sel)[0]

        def resid(x):
            return (model_residual(coefficients(*params(x), idx), V, weight) * weight).ravel()

        x0 = np.zeros(n_par)
        sol = least_squares(resid, x0, method="lm", x_scale=np.r_[[np.deg2rad(0.1)] * int(offset), [1.0] * int(delay)])
        J = sol.jac
        dof = max(sol.fun.size - 16 * (degree + 1) - x0.size, 1)
        chi2 = float(np.sum(sol.fun ** 2) / dof)
        try:
            Hinv = np.linalg.inv(J.T @ J)
            if weighted:
                # sandwich: the 16 coefficients of a speed are strongly correlated, which the per-coefficient
                # weighting ignores; their full covariance gives the spread of the estimate
                Ms = np.zeros((x0.size, x0.size))
                for s_, (w, C) in enumerate(zip(weight, coef_cov[sel])):
                    Js = J[16 * s_:16 * s_ + 16]
                    Ms += Js.T @ (w[:, None] * C * w[None, :]) @ Js
                # widened by the Birge ratio where the coefficients misfit the model beyond their
                # covariance (identical=True on bearings 3 % apart at 1 % noise, not rejected there:
                # 6 standard errors off at chi² 4-7 unwidened; clean data give chi² 0.4-1.5)
                cov = Hinv @ Ms @ Hinv * max(1.0, chi2)
            else:
                cov = Hinv * chi2
        except np.linalg.LinAlgError:
            raise RotoridError("calibrate_phase: the offset and the delay cannot be separated over these speeds "
                               "(widen the speed range or estimate only one of them)") from None
        return sol, cov, chi2, n, weighted

    def misfit_phases(x, sel, weighted):
        """Each calibrated speed's phase error along its own direction, delta_s (rad), its variance
        v_s from the stated covariance (0 without one) and the whitened directions g_s, at the fit
        ``x``; None where they are not all finite."""
        idx = np.nonzero(sel)[0]
        th, tau = params(x)
        V = speed_model(sel)
        w = whitening(sel, base.cov if weighted else None)[0]
        r = model_residual(coefficients(th, tau, idx), V, w) * w
        eps = 1e-4
        g = (coefficients(th + eps, tau, idx) - coefficients(th - eps, tau, idx)) / (2 * eps) * w   # d p / d phase
        gg = np.sum(g * g, axis=1)
        delta = np.sum(g * r, axis=1) / gg                     # each speed's phase error along its own direction
        if weighted:
            C = base.cov[sel]
            var = np.einsum("si,sij,sj->s", g, w[:, :, None] * C * w[:, None, :], g) / gg ** 2
        else:
            var = np.zeros(idx.size)
        if not (np.all(np.isfinite(delta)) and np.all(np.isfinite(var)) and (not weighted or np.all(var > 0))):
            return None
        return delta, var, g

    def root_above_zero(excess, hi):
        """The s_e² in [0, hi] where the decreasing ``excess`` crosses zero; 0 where it is not
        positive at 0."""
        if excess(0.0) <= 0:
            return 0.0
        return float(brentq(excess, 0.0, hi, xtol=1e-12 * hi + 1e-30))

    def paule_mandel(delta, var, free):
        """s_e² solving sum delta² / (var + s_e²) = free (0 where the left side is below at 0);
        without variances the closed form sum delta² / free."""
        if not np.any(var > 0):
            return float(np.sum(delta ** 2)) / free

        return root_above_zero(lambda s2: float(np.sum(delta ** 2 / (var + s2))) - free,
                               float(np.sum(delta ** 2)) / free)

    def robust_scatter2(delta, var):
        """s_e² at which the median of delta² / (var + s_e²) is 0.4549, chi²(1)'s median (0 where it
        is below at 0); without variances the closed form median(delta²) / 0.4549 (the search
        divided by zero at 0, and a numpy warning reached the user's console)."""
        if not np.any(var > 0):
            return float(np.median(delta ** 2)) / 0.45494
        return root_above_zero(lambda s2: float(np.median(delta ** 2 / (var + s2))) - 0.45494,
                               float(np.max(delta ** 2)) / 0.45494)

    def scatter(x, sel, weighted):
        """(each calibrated speed's phase variance beyond the stated uncertainty (rad²), the common
        scatter s_e² in it, the outlying speeds' mask, its degrees of freedom, Q at s_e = 0 or None,
        the whitened directions g_s): the random effect of the module doc, and each speed beyond
        Bonferroni's 5 % two-sided point of |delta_s| / sqrt(v_s + s_e²), with s_e² there over the
        speeds not yet found, given its own share delta_s² - v_s where that is larger (one speed 1
        degree off among 15 had spread its error over all: its phase covered 0 %, its coefficients
        5 %, flagged ok in 20 % of trials; found in review)."""
        n_sel = int(sel.sum())
        free = n_sel - n_par - (degree + 1)
        got = misfit_phases(x, sel, weighted) if free >= 1 else None
        if got is None:
            return np.zeros(n_sel), 0.0, np.zeros(n_sel, dtype=bool), free, None, None
        delta, var, g = got
        q0 = float(np.sum(delta ** 2 / var)) if weighted else None
        out = np.zeros(n_sel, dtype=bool)
        s2_all = paule_mandel(delta, var, free)
        crit = norm_dist.isf(0.025 / n_sel)
        # the outliers are sought against a robust scatter first (the s_e² at which the median of
        # delta² / (v + s_e²) is chi²(1)'s median), so that two do not hide each other: two speeds 0.7
        # degree off either way among 15 lifted s_e to 0.29 and stayed inside it (their phases
        # covered 0 %). (The median of delta² - v over chi²(1)'s median, tried first, runs 1.2 v low
        # and named speeds under a uniform scatter in 20-36 % of draws; review.)
        robust = min(s2_all, robust_scatter2(delta, var))
        # (without the runs' covariance the speeds' own noise, which differs from speed to speed, is
        # not known: the median then took noisy speeds for outliers in 80 % of draws without any
        # scatter, so the test is against the whole misfit there)
        test = robust if weighted else s2_all
        while True:
            grown = out | (np.abs(delta) > crit * np.sqrt(var + test))
            if grown.sum() == out.sum() or free - int(grown.sum()) < 1:
                break
            out = grown
            test = paule_mandel(delta[~out], var[~out], free - int(out.sum()))
        # the outliers only add: every speed keeps the scatter of all of them (s_e² over the speeds
        # without the outliers left the others short where their errors are not all common to the
        # runs: 1X tables of RC keyphasor edges, 0.88 -> 0.81)
        own = np.full(n_sel, s2_all)
        own[out] = np.maximum(delta[out] ** 2 - var[out], s2_all)
        return own, s2_all, out, free, q0, g

    sol, cov, chi2, n, weighted = _fit(sel, base.cov)
    if (rejected & sel).any():
        # rejections of identical bearings count only where the phase reference was their cause: a
        # point still rejected once corrected is a pair of bearings that differ (counted, bearings
        # 3 % apart gave an offset 5.5 degrees off at 0.04 degree stated, and a warning to apply it;
        # found in review)
        th0, tau0 = params(sol.x)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            check = identify_synchronous(rotor, [_rotated(r, -th0, -tau0) for r in runs], **fit_kw)
        still = rejected & sel & _flagged(check, IDENTICAL_REJECTED)
        if still.any():
            sel = sel & ~still
            sol, cov, chi2, n, weighted = _fit(sel, base.cov, f" ({int(still.sum())} rejected identical bearings with "
                                                             "the phase reference calibrated: the bearings differ)")
    # phase errors of each speed alone that nobody stated (1X tables from a keyphasor whose timing
    # errs from dwell to dwell: the calibration applied, the damping's intervals covered 63 %)
    chi2_stated = chi2
    stated = np.broadcast_to(np.asarray(ident_kw.get("keyphasor_angle_std_deg", 0.0), float), base.axis.shape)
    state = scatter(sol.x, sel, weighted)   # (own, s2, out, free, Q, g)
    q0 = state[4]                           # the test against no scatter, at the fit with the stated uncertainty
    fitted = None                           # the state the fit was last made with
    for _ in range(3 if weighted else 1):
        own = state[0]
        if own.size and own.max() > np.deg2rad(MAX_SCATTER_DEG) ** 2:
            raise RotoridError(f"calibrate_phase: the coefficients scatter between speeds as a phase error of "
                               f"{np.rad2deg(np.sqrt(own.max())):.1f} deg of a speed alone would (beyond "
                               f"{MAX_SCATTER_DEG:g} deg, where their linear error propagation no longer holds): the "
                               "phase reference cannot be calibrated from these runs (check the keyphasor, the "
                               "imbalance masses and angles, the accelerometers' sensitivities where the pedestals "
                               "move, or whether the coefficients vary with speed beyond the calibration's model of "
                               f"degree {degree})")
        if not weighted or not own.size or (fitted is None and not own.max() > 0):
            break
        if fitted is not None and np.allclose(own, fitted[0], rtol=0.05, atol=1e-12):
            break
        # the fit made again with each speed's phase uncertainty grown by its share (its sandwich then
        # carries the scatter's share of theta and tau), and the shares estimated again at it: a
        # speed far off pulls the first fit, whose misfit then lifts the others' (one speed 1 degree
        # off among 15: s_e 0.106 degree from the first fit, 0 from the second)
        every = np.full(base.axis.size, state[1])
        every[sel] = own
        wide = identify_synchronous(rotor, runs, **{**ident_kw, "keyphasor_angle_std_deg":
                                                    np.hypot(stated, np.rad2deg(np.sqrt(every)))})
        sol, cov, chi2, n, weighted = _fit(sel, wide.cov)
        fitted = state
        state = scatter(sol.x, sel, weighted)
    own, s2, out, free, _, g = fitted if fitted is not None else state
    if own.size and own.max() > 0:
        if not weighted:
            # the weights (the bearings' scale) do not change with it: the fit stands, and the
            # scatter's share of the estimate's covariance is added, the sandwich with u_s² g_s g_s^T
            # for each speed's coefficient covariance (without it the offset's spread was 4.7 times
            # the stated, 20 draws of 0.15 degree per speed)
            J = sol.jac.reshape(n, 16, n_par)
            Jg = np.einsum("sip,si->sp", J, g)
            Hinv = np.linalg.inv(sol.jac.T @ sol.jac)
            cov = cov + Hinv @ (Jg.T @ (own[:, None] * Jg)) @ Hinv
    sd = np.sqrt(np.diag(cov))
    th, tau = params(sol.x)
    it = iter(sd)
    th_sd = float(next(it)) if offset else 0.0
    tau_sd = float(next(it)) * 1e-6 if delay else 0.0
    sig = (offset and abs(th) > significance * th_sd) or (delay and abs(tau) > significance * tau_sd)
    scatter_deg = float(np.rad2deg(np.sqrt(s2)))
    out_rpm = tuple(float(r) for r in base.axis[sel][out])
    out_deg = tuple(float(np.rad2deg(np.sqrt(u))) for u in own[out])
    msg = (f"phase reference: offset {np.rad2deg(th):.3f} ± {np.rad2deg(th_sd):.3f} deg, delay {tau * 1e6:.2f} ± "
           f"{tau_sd * 1e6:.2f} µs over {n} speeds (chi² {chi2_stated:.2f}")
    # no scatter rejected at 1 %: the error bars of uncalibrated coefficients miss it
    scatter_sig = q0 is not None and own.size > 0 and own.max() > 0 and chi2_dist.sf(q0, free) < 0.01
    shown = scatter_deg >= 5e-4   # (exact runs leave a scatter of rounding)
    if shown and weighted:
        msg += (f"; a phase scatter of {scatter_deg:.3f} deg between speeds beyond the stated uncertainty, in the "
                f"calibrated reference's uncertainty: chi² {chi2:.2f} with it")
        if scatter_sig:
            msg += (f"; the scatter is significant (Q = {q0:.1f} on {free} degrees of freedom): a phase reference "
                    "that errs from speed to speed (the coefficients' error bars miss it unless it is in their "
                    "keyphasor_angle_std_deg; the imbalance chain puts it there), or coefficients that vary with "
                    "speed (raise degree)")
            if any(getattr(r, "pedestal", None) is not None for r in runs):
                # an accelerometer's sensitivity off moves the pedestal motion's share of the bearing
                # forces from speed to speed, which the calibration reads as such a scatter (an
                # independent simulator's 3 % gain errors: Q up to 21,718 on 7 degrees of freedom)
                msg += (", or an accelerometer's sensitivity or phase off (the pedestal motion's share of the "
                        "bearing forces changes with speed; state it as accel_gain_std / accel_phase_std_deg)")
    elif shown:
        msg += (f"; a phase scatter of {scatter_deg:.3f} deg between speeds, in the calibrated reference's "
                "uncertainty (without the runs' covariance, all of the misfit along the speeds' phases, noise included)")
    elif free < 1:
        msg += f"; {n} speeds are too few to estimate a phase scatter between them"
    if out.any():
        off = ", ".join(f"{r:.0f} rpm by {d:.3f} deg" for r, d in zip(out_rpm, out_deg))
        msg += (f"; {int(out.sum())} speed(s) off the calibrated line beyond the scatter ({off}): their own phase "
                "error in their error bars")
    msg += ")"
    # the misfit with the stated uncertainties: a phase scatter between speeds is one reading of it,
    # coefficients that vary with speed or bearings that differ under identical=True are others,
    # which the scatter then stands in for (the estimate stays within its widened uncertainty: 1.2
    # standard errors for bearings 3 % apart at 1 % noise, but it is no calibration to apply)
    misfit = chi2_stated > MISFIT_CHI2
    if misfit and chi2 <= MISFIT_CHI2:
        msg += (f"; the coefficients misfit a degree-{degree} model in speed beyond their stated uncertainty, which "
                "the phase scatter explains; coefficients that vary with speed (raise degree) or bearings that differ "
                "under identical=True misfit alike, and the estimate is then a diagnostic only")
    elif misfit:
        msg += (f"; the coefficients misfit a degree-{degree} model in speed beyond their stated uncertainty: the "
                "estimate takes up that misfit and is a diagnostic only (a phase reference that errs from speed to "
                "speed; coefficients that vary with speed: raise degree; identical=True on bearings that differ)")
    if scatter_sig and not sig:
        warnings.warn(msg)
    if sig:
        msg += ("; significant" if misfit else
                "; significant: correct the keyphasor mark angle / channel delays, or apply this calibration")
        warnings.warn(msg)
    corr = float(cov[0, 1] / (sd[0] * sd[1])) if offset and delay and sd[0] > 0 and sd[1] > 0 else 0.0
    return PhaseCalibration(float(np.rad2deg(th)), float(np.rad2deg(th_sd)), float(tau), tau_sd, chi2_stated, n,
                            bool(sig), msg, corr, scatter_deg, max(int(free), 0), out_rpm, out_deg)
