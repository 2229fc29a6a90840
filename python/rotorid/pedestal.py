"""Flexible pedestals: the bearing housings as masses on springs and dampers (8-DOF model).

The report's first imbalance tests gave "bearing parameters varying with no defined trend"
because the pedestals moved; its remedy is to add the pedestal degrees of freedom and use the
accelerometers on the bearing housings. rotorid models each pedestal b as a point mass moving with
p_b = (xp_b, yp_b), on a stiffness K_p and damping C_p to ground (2 x 2, optionally
cross-coupled). The bearing force acts on the journal's motion relative to its housing, the
rotor's inertia on its absolute motion:

    Q(q_rel) P = F_o + Omega^2 (M - j G)(q_rel + q_ped)          (imbalance; impacts alike)
    (K_p - w^2 M_p + j w C_p) p_b = f_b                          (each pedestal)

The physics (series impedance, forced response, 16-state modal analysis, identification on
relative + pedestal motion, bearing forces) is in the Rust core (``rust/core/src/pedestal.rs``,
``identify/mod.rs``); this module holds the model object, the accelerometer conversion and the
pedestal identification.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ._validate import real_array
from .errors import IdentifiabilityError, RotoridError

#: largest angular frequency (rad/s) the pedestal functions accept: w² stays far from overflow
#: (1e12 rad/s is 160 GHz, beyond any vibration)
MAX_W = 1e12
#: smallest angular frequency they accept (1e-6 rad/s: one turn in 72 days)
MIN_W = 1e-6

#: pedestal degrees of freedom, the order of ``SyncResponse.pedestal`` (as q = [x1, x2, y1, y2])
PEDESTAL_DOFS = ("xp1", "xp2", "yp1", "yp2")
#: accelerometer channel of each pedestal degree of freedom (recordings, 1X tables)
ACCEL_CHANNELS = {"xp1": "px1", "xp2": "px2", "yp1": "py1", "yp2": "py2"}


def dof_matrix(a) -> np.ndarray:
    """A per-support array (2, 2, 2) [support b][i][j] as the 4 x 4 matrix over [x1, x2, y1, y2]
    (entry at row 2 i + b, column 2 j + b): bearing or pedestal coefficients acting on the motion
    at the supports."""
    a = np.asarray(a)
    out = np.zeros((4, 4), dtype=a.dtype)
    for b in range(2):
        for i in range(2):
            for j in range(2):
                out[2 * i + b, 2 * j + b] = a[b, i, j]
    return out


def _per_direction(name, value, *, nonneg=False):
    """(2, 2) [pedestal, direction] from a scalar, (2,) per pedestal or (2, 2)."""
    a = real_array(name, value, nonneg=nonneg)
    if a.ndim == 0:
        return np.full((2, 2), float(a))
    if a.shape == (2,):
        return np.repeat(a[:, None], 2, axis=1).astype(float)
    if a.shape == (2, 2):
        return a.astype(float)
    raise RotoridError(f"{name} must be a number, 2 values (one per pedestal) or (2, 2) [pedestal, x/y], "
                       f"got shape {a.shape}")


def _matrix(name, value):
    """(2, 2, 2) [pedestal, i, j] from (2, 2) [pedestal, direction] (uncoupled) or (2, 2, 2)."""
    a = real_array(name, value)
    if a.shape == (2, 2, 2):
        return a.astype(float)
    d = _per_direction(name, a)
    out = np.zeros((2, 2, 2))
    out[:, 0, 0] = d[:, 0]
    out[:, 1, 1] = d[:, 1]
    return out


@dataclass(frozen=True)
class Pedestals:
    """Mass, stiffness and damping of the two pedestals (bearing housings), SI units.

    ``mass_kg``: a number, one per pedestal (2,), or (2, 2) [pedestal, x/y] (the mass moving in
    each direction). ``k`` (N/m) and ``c`` (N·s/m): a number, (2,), (2, 2) [pedestal, x/y]
    (uncoupled), or (2, 2, 2) [pedestal, i, j] with cross-coupled terms. Pedestal 1 carries
    bearing 1 (drive end). Stored normalized: ``mass_kg`` (2, 2), ``k`` and ``c`` (2, 2, 2).

    Examples
    --------
    >>> import rotorid
    >>> ped = rotorid.Pedestals(mass_kg=20.0, k=[[1.2e7, 2.0e7], [1.4e7, 2.2e7]], c=3.0e3)
    >>> float(ped.k[0, 1, 1])
    20000000.0
    """

    mass_kg: object
    k: object
    c: object = 0.0

    def __post_init__(self):
        object.__setattr__(self, "mass_kg", _per_direction("mass_kg (pedestal mass)", self.mass_kg, nonneg=True))
        object.__setattr__(self, "k", _matrix("k (pedestal stiffness)", self.k))
        object.__setattr__(self, "c", _matrix("c (pedestal damping)", self.c))
        for b in range(2):
            for i in range(2):
                if not (self.k[b, i, i] > 0):
                    raise RotoridError(f"k (pedestal stiffness) of pedestal {b + 1} in {'xy'[i]} must be > 0, got "
                                       f"{self.k[b, i, i]:g} N/m (a pedestal without stiffness to ground floats)")

    def core_params(self) -> np.ndarray:
        """The 20 numbers the core takes: [m (4), k (8), c (8)]."""
        return np.concatenate([self.mass_kg.ravel(), self.k.ravel(), self.c.ravel()])

    def matrices(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(M_p, K_p, C_p), each 4 x 4 over [xp1, xp2, yp1, yp2] (the order of q)."""
        m = np.zeros((2, 2, 2))
        m[:, 0, 0], m[:, 1, 1] = self.mass_kg[:, 0], self.mass_kg[:, 1]
        return dof_matrix(m), dof_matrix(self.k), dof_matrix(self.c)

    def dynamic_stiffness(self, freq_hz) -> np.ndarray:
        """D(w) = K_p - w² M_p + j w C_p, complex (n, 2, 2, 2) [point, pedestal, i, j]."""
        w = 2 * np.pi * np.atleast_1d(real_array("freq_hz", freq_hz, nonneg=True))
        if np.any(w > MAX_W):
            raise RotoridError(f"freq_hz up to {w.max() / (2 * np.pi):.3g} Hz: above {MAX_W / (2 * np.pi):.3g} Hz the "
                               "dynamic stiffness overflows")
        m = np.zeros((2, 2, 2))
        m[:, 0, 0] = self.mass_kg[:, 0]
        m[:, 1, 1] = self.mass_kg[:, 1]
        return self.k[None] - (w ** 2)[:, None, None, None] * m[None] + 1j * w[:, None, None, None] * self.c[None]

    @property
    def natural_freq_hz(self) -> np.ndarray:
        """Undamped natural frequency of each pedestal on its own, (2, 2) [pedestal, x/y] (inf when
        massless)."""
        with np.errstate(divide="ignore"):
            return np.sqrt(np.diagonal(self.k, axis1=1, axis2=2) / self.mass_kg) / (2 * np.pi)

    def __repr__(self):
        return (f"Pedestals(mass_kg={self.mass_kg.tolist()}, k={self.k.tolist()}, c={self.c.tolist()})")


def example_pedestals() -> Pedestals:
    """Flexible pedestals for numerical experiments on the NSF rig (not from the report).

    20 kg housings on 2.0e7 (x) and 2.6e7 N/m (y) at bearing 1, 2.2e7 and 2.8e7 N/m at bearing 2,
    2500 N·s/m to ground. With the Table 4 bearings the pedestals move 14-18 % of the journal's
    motion in its housing around the critical speeds (3000-3700 rpm), 14 % at 500 rpm and 68 % at
    8000 rpm; their own modes lie at 159-189 Hz (9500-11300 rpm), above the speed range.

    Examples
    --------
    >>> import rotorid
    >>> rotorid.example_pedestals().natural_freq_hz.round()
    array([[159., 181.],
           [167., 188.]])
    """
    return Pedestals(mass_kg=20.0, k=[[2.0e7, 2.6e7], [2.2e7, 2.8e7]], c=2500.0)


def displacement_from_acceleration(accel, freq_hz, *, phase_deg=0.0, sensitivity=1.0):
    """Displacement phasors (m) from acceleration phasors (m/s²) at ``freq_hz``: -a / w².

    ``phase_deg``: the accelerometer's own phase lag at these frequencies (its calibration chart;
    the measured phasor is a·exp(-j phase)), removed first; ``sensitivity``: a correction factor of
    its calibration (measured / true). Both broadcast against ``accel``.

    Examples
    --------
    >>> import numpy as np
    >>> from rotorid.pedestal import displacement_from_acceleration
    >>> w = 2 * np.pi * 50.0
    >>> complex(np.round(displacement_from_acceleration(-w**2 * 1e-6, 50.0) * 1e6, 12))
    (1+0j)
    """
    from ._validate import complex_array

    a = complex_array("accel", accel)
    f = real_array("freq_hz", freq_hz, positive=True)
    ph = real_array("phase_deg", phase_deg)
    s = real_array("sensitivity", sensitivity, positive=True)
    w = 2 * np.pi * f
    if np.any(w < MIN_W) or np.any(w > MAX_W):
        raise RotoridError(f"freq_hz must lie between {MIN_W / (2 * np.pi):.3g} and {MAX_W / (2 * np.pi):.3g} Hz "
                           f"(the division by w² stays finite), got {f.min():.3g} to {f.max():.3g} Hz")
    if np.any(s < 1e-6) or np.any(s > 1e6):
        raise RotoridError(f"sensitivity is a correction factor near 1 (measured / true), got {s.min():.3g} to "
                           f"{s.max():.3g}")
    try:
        wb = np.broadcast_to(w[..., None] if (w.ndim == 1 and a.ndim == 2 and a.shape[0] == w.size) else w, a.shape)
    except ValueError:
        raise RotoridError(f"freq_hz has shape {f.shape}, which does not fit accel of shape {a.shape}") from None
    for name, v in (("phase_deg", ph), ("sensitivity", s)):
        try:
            np.broadcast_to(v, a.shape)
        except ValueError:
            raise RotoridError(f"{name} has shape {v.shape}, which does not fit accel of shape {a.shape} (a value, or "
                               "one per channel)") from None
    return -a * np.exp(1j * np.deg2rad(ph)) / s / wb ** 2


@dataclass
class PedestalIdentification:
    """Pedestal mass, stiffness and damping identified from the bearing forces and the measured
    pedestal motion, per pedestal and direction.

    ``mass_kg`` (2, 2) [pedestal, x/y]; ``k``, ``c`` (2, 2, 2) [pedestal, i, j] (cross terms 0
    unless fitted); ``*_std`` their standard errors; ``dof`` residual degrees of freedom;
    ``residual`` (2, 2) relative rms misfit of each fit; ``std_source`` "measurement covariance"
    (weighted least squares with the propagated row covariances) or "residual" (ordinary least
    squares, heteroscedasticity-consistent errors); ``points`` the number of (run, point) equations used.
    """

    mass_kg: np.ndarray
    k: np.ndarray
    c: np.ndarray
    mass_std: np.ndarray
    k_std: np.ndarray
    c_std: np.ndarray
    dof: np.ndarray
    residual: np.ndarray
    std_source: str
    cross_coupled: bool
    points: int
    labels: list = field(default_factory=list)

    def pedestals(self) -> Pedestals:
        """The identified pedestals as a model (masses clipped at 0)."""
        return Pedestals(np.clip(self.mass_kg, 0.0, None), self.k, self.c)

    def interval(self, level: float = 0.95):
        """{"mass_kg": (lo, hi), "k": (lo, hi), "c": (lo, hi)} at a confidence level (Student t)."""
        from .uncertainty import t_quantile

        t = t_quantile(level, self.dof)  # (2, 2)
        out = {"mass_kg": (self.mass_kg - t * self.mass_std, self.mass_kg + t * self.mass_std)}
        for nm in ("k", "c"):
            v, s = getattr(self, nm), getattr(self, f"{nm}_std")
            out[nm] = (v - t[:, :, None] * s, v + t[:, :, None] * s)
        return out

    def summary(self, *, us: bool = False) -> str:
        """One line per pedestal and direction: mass, direct stiffness and damping with their
        standard errors (SI, or lb, lbf/in, lbf s/in with ``us``)."""
        from .units import from_si

        um, uk, uc = ("lb", "lbf/in", "lbf*s/in") if us else ("kg", "N/m", "N*s/m")
        parts = []
        for b in range(2):
            for i, d in enumerate("xy"):
                def f(v, s, unit):
                    return f"{from_si(v, unit):.4g} ± {from_si(s, unit):.2g}"
                parts.append(f"pedestal {b + 1} {d}: m {f(self.mass_kg[b, i], self.mass_std[b, i], um)} {um}, "
                             f"k {f(self.k[b, i, i], self.k_std[b, i, i], uk)} {uk}, "
                             f"c {f(self.c[b, i, i], self.c_std[b, i, i], uc)} {uc}")
        return "pedestals identified (" + self.std_source + "): " + "; ".join(parts)

    def to_dataframe(self, *, us: bool = False):
        """One row per pedestal and direction: mass, stiffness, damping (direct, and cross terms
        when fitted), each with its standard error and 95 % interval. SI columns (``mass_kg``,
        ``k_xx`` N/m, ``c_xx`` N s/m) or, with ``us``, lb, lbf/in and lbf s/in (the columns named
        with their unit)."""
        df = self._frame()
        if not us:
            return df
        from .units import from_si

        ren = {}
        for col in list(df.columns):
            if col.startswith("mass_"):
                df[col] = from_si(df[col], "lb")
                ren[col] = col.replace("mass_kg", "mass").replace("mass", "mass_lb", 1)
            elif col[:2] in ("k_", "c_"):
                unit, tag = ("lbf/in", "lbf_per_in") if col[0] == "k" else ("lbf*s/in", "lbf_s_per_in")
                df[col] = from_si(df[col], unit)
                ren[col] = f"{col}_{tag}"
        return df.rename(columns=ren)

    def _frame(self):
        import pandas as pd

        rows = []
        iv = self.interval(0.95)
        for b in range(2):
            for i, d in enumerate("xy"):
                row = dict(pedestal=b + 1, direction=d, mass_kg=self.mass_kg[b, i], mass_std=self.mass_std[b, i],
                           mass_lo95=iv["mass_kg"][0][b, i], mass_hi95=iv["mass_kg"][1][b, i])
                for nm in ("k", "c"):
                    for j, e in enumerate("xy"):
                        if i != j and not self.cross_coupled:
                            continue
                        key = f"{nm}_{d}{e}"
                        row[key] = getattr(self, nm)[b, i, j]
                        row[f"{key}_std"] = getattr(self, f"{nm}_std")[b, i, j]
                        row[f"{key}_lo95"] = iv[nm][0][b, i, j]
                        row[f"{key}_hi95"] = iv[nm][1][b, i, j]
                row.update(dof=self.dof[b, i], residual=self.residual[b, i], std_source=self.std_source)
                rows.append(row)
        return pd.DataFrame(rows)


#: fewest degrees of freedom of the runs' covariances for a weighted pedestal fit (below it the fit
#: is unweighted with a sandwich covariance); measured by Monte Carlo, docs/pedestals.md
GLS_MIN_DOF = 10


def identify_pedestals(rotor, runs, *, cross_coupled: bool = False, freq_range_hz=None, accel_gain_std: float = 0.0,
                       accel_phase_std_deg: float = 0.0, shared_cov=None, keyphasor_angle_std_deg=0.0,
                       keyphasor_delay_std_s: float = 0.0, phase_line_cov=None,
                       phase_scatter_std_deg=0.0) -> PedestalIdentification:
    """Each pedestal's mass, stiffness and damping from imbalance runs (or impact tests) that carry
    pedestal motion.

    The bearing force on each housing follows from the rotor equations with the absolute motion
    (relative + pedestal), as in the bearing identification, and the pedestal obeys
    f_b = (K_p - w² M_p + j w C_p) p_b. Over every run and speed (or frequency) this is a real
    linear least-squares problem per pedestal and direction with the unknowns k, m, c (and the
    cross-coupled k, c with ``cross_coupled=True``).

    With measurement covariances on every run (``cov`` and ``pedestal_cov``) each equation is
    weighted by the inverse of its propagated covariance (including the accelerometer noise, which
    at low speed dominates: the displacement is a/w²) and the standard errors follow from that;
    otherwise the fit is unweighted with heteroscedasticity-consistent (HC3) standard errors. The
    unweighted fits run in the compiled core: the equations are formed point by point and folded
    into a Householder QR factor (as accurate as ``numpy.linalg.lstsq``, no design matrix in
    memory), the HC3 sums come from a second pass. ``freq_range_hz`` = (lo, hi) restricts the
    points used. With covariances from a few repeats
    (degrees of freedom below ``GLS_MIN_DOF``, e.g. H1 FRFs of five impacts) the fit is
    unweighted and takes the larger of the propagated (sandwich) and residual (HC3) variances.
    ``accel_gain_std`` (relative) and ``accel_phase_std_deg``: the accelerometers' calibration
    uncertainty, added to the standard errors (the pedestal stiffness scales with 1/gain).
    ``shared_cov`` (n, 16, 16): the covariance of [Re q, Im q, Re p, Im p] common to every pair of
    runs (all runs less the same baseline run; see :func:`rotorid.identify_synchronous`): the
    equations of one point are then correlated across runs, and weighted and propagated as such.
    The phase reference's uncertainty (imbalance runs only: impact FRFs are relative to the force,
    and these are ignored for them): a phase error common to every run's vectors (probes and
    accelerometers) at a speed. The pedestal fit pools the speeds, so how the error goes from speed
    to speed counts (the bearing identification, speed by speed, needs only its size at each):
    ``keyphasor_angle_std_deg`` (a number or one per speed): one error throughout the speeds of
    this size at each (a mark angle; wholly correlated between speeds); ``keyphasor_delay_std_s``:
    a delay's, Omega times it, independent of the angle's; ``phase_line_cov`` (2, 2): the
    covariance (or second moment) of an offset theta (deg) and a delay tau (s) whose error at each
    speed is theta - Omega tau (a phase calibration's: :meth:`rotorid.phasecal.PhaseCalibration.line_cov`),
    which changes sign where the two cancel; ``phase_scatter_std_deg`` (a number or one per speed):
    errors drawn anew at each speed (independent between speeds). Each is added to the standard
    errors by central differences of the whole fit: along the angle's profile and the delay's (two
    fits each), along theta and tau (four), and along each speed's phase for the scatter (two per
    speed; it also shows in the misfit, which widens the errors by itself, so it counts twice).
    Found by an independent simulator: a keyphasor timed 2-5 of its stated uncertainties late at
    high speed left the pedestal intervals covering 0.40-0.58 where the bearings' covered 0.98 (the
    imbalance chain passes what its identification took, with what a phase calibration found:
    ``ImbalanceChainResult.pedestal_phase_kw``).

    Examples
    --------
    >>> import numpy as np, rotorid
    >>> rig = rotorid.nsf_rig()
    >>> ped = rotorid.example_pedestals()
    >>> rpm = np.linspace(1000, 8000, 40)
    >>> runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm,
    ...                                    pedestals=ped) for s in "AB"]
    >>> fit = rotorid.identify_pedestals(rig.rotor, runs)
    >>> bool(np.allclose(fit.k, ped.k, rtol=1e-6, atol=1.0))
    True
    """
    from ._corecall import core as _core
    from ._validate import flag
    from .identify import _as_runs, _pedestal_frame, _run_label
    from .model import RigidRotor
    from .simulate import RPM, ImpactResponse, SyncResponse

    if not isinstance(rotor, RigidRotor):
        raise RotoridError(f"rotor must be a rotorid.RigidRotor, got {type(rotor).__name__}")
    cross = flag("cross_coupled", cross_coupled)
    from .identify import _calibration_std

    cal_g, cal_ph = _calibration_std(accel_gain_std, accel_phase_std_deg)
    runs = list(runs.values()) if isinstance(runs, dict) else _as_runs(runs)
    if not runs:
        raise IdentifiabilityError("no runs given")
    labels = [_run_label(i, r) for i, r in enumerate(runs)]
    kinds = {type(r) for r in runs}
    if len(kinds) != 1 or not kinds <= {SyncResponse, ImpactResponse}:
        raise RotoridError("runs must all be SyncResponse (imbalance) or all ImpactResponse (impacts)")
    missing = [lab for lab, r in zip(labels, runs) if r.pedestal is None]
    if missing:
        raise RotoridError(f"{', '.join(missing)} carry no pedestal motion (accelerometer channels px1, py1, px2, "
                           "py2): the pedestals cannot be identified without it")
    impact = isinstance(runs[0], ImpactResponse)
    # the core forms w = w_scale * axis (and spin = w for imbalance runs, gain = spin²): no (n,)
    # temporaries here for the fit without covariances
    if impact:
        axis = runs[0].freq_hz
        w_scale = 2 * np.pi
        spin = np.array([runs[0].speed_rpm * RPM])
        gain = np.ones(1)
        e = np.stack([r.excitation() for r in runs]).astype(complex)
        if any(r.force is not None for r in runs):
            raise RotoridError("identify_pedestals needs FRFs (force=None) for impact tests")
        speeds = {float(r.speed_rpm) for r in runs}
        if max(speeds) - min(speeds) > 1e-6 * max(max(speeds), 1.0):
            raise RotoridError(f"the impact tests were taken at different running speeds ({sorted(speeds)} rpm): the "
                               "pedestal fit needs one speed (identify each speed separately)")
        sig = {r.sigma for r in runs}
        if len(sig) != 1:
            raise RotoridError(f"the impact tests have different exponential windows (sigma {sorted(sig)} 1/s): "
                               "window all tests alike")
        sigma = sig.pop()
    else:
        for i, r in enumerate(runs):
            if r.imbalance is None:
                raise RotoridError(f"{labels[i]} has no imbalance: the bearing forces need it")
        axis = runs[0].speed_rpm
        w_scale = RPM
        spin = gain = None
        sigma = 0.0
        e = np.stack([r.imbalance.generalized(rotor) for r in runs])
    for lab, r in zip(labels[1:], runs[1:]):
        ax = r.freq_hz if impact else r.speed_rpm
        # equal axes (the usual case: runs simulated or resampled alike) pass without a tolerance check
        if ax is not axis and not (ax.shape == axis.shape and (np.array_equal(ax, axis)
                                                               or np.allclose(ax, axis, rtol=1e-9))):
            raise RotoridError(f"{lab} is not on the same {'frequencies' if impact else 'speeds'} as {labels[0]}")
    from .identify import _shared

    # NaN and inf are found by the core's fit and named then (_name_nonfinite): no scan here
    frames = [_pedestal_frame(rotor, r, lab, finite=False, blocks=True) for r, lab in zip(runs, labels)]
    shared = _shared(rotor, runs, shared_cov, size=16)
    qs = [fr[0] for fr in frames]
    ps = [fr[1] for fr in frames]
    covs = [fr[2] for fr in frames]
    have_cov = all(c is not None for c in covs)
    if shared is not None and not have_cov:
        from .identify import _SHARED_WITHOUT_COV

        raise RotoridError(_SHARED_WITHOUT_COV)
    # weighted least squares only with covariances known well enough to weigh with
    min_dof = np.inf
    if have_cov:
        dofs = [np.asarray(r.dof, float) if r.dof is not None else np.full(axis.size, np.inf) for r in runs]
        min_dof = float(np.nanmin(np.concatenate(dofs)))
    weighted = have_cov and min_dof >= GLS_MIN_DOF
    sel = None                                                     # every point
    if freq_range_hz is not None:
        lo, hi = real_array("freq_range_hz", freq_range_hz, shape=(2,), nonneg=True)
        f = axis if impact else axis / 60.0
        sel = (f >= lo) & (f <= hi)
        if sel.sum() < 3:
            raise RotoridError(f"freq_range_hz = ({lo:g}, {hi:g}) keeps {int(sel.sum())} points; at least 3 needed")

    sig_arr = np.array([sigma]) if sigma else None                 # the windowed spectra are at s = sigma + jw
    e = np.ascontiguousarray(e[None], dtype=complex)
    params = rotor.core_params()
    R, n = len(runs), axis.size
    nu = 5 if cross else 3
    if have_cov:
        # a point whose covariance some run lacks: NaN in one of its blocks
        unknown = _core.unknown_points([c for blocks in covs for c in blocks if c is not None], n)
        used = np.ones(n, bool) if sel is None else sel
        if unknown[used].all():
            import warnings

            warnings.warn("no point has a known measurement covariance (cov, pedestal_cov) in every run: the pedestal "
                          "fit is unweighted with residual (HC3) errors" + ("; shared_cov is not used" if shared is not None
                                                                           else ""))
            have_cov = False
        elif unknown[used].any():
            import warnings

            warnings.warn(f"{int(unknown[used].sum())} of {int(used.sum())} points have no measurement "
                          "covariance (NaN) in some run: the weighted pedestal fit leaves them out")
            sel = used & ~unknown
    ns = n if sel is None else int(sel.sum())
    if 2 * R * ns <= nu:
        raise IdentifiabilityError(f"{R} run(s) x {ns} point(s) give too few equations for {nu} unknowns")
    # the unweighted fits of all four (pedestal, direction) pairs with HC3 covariances, in the
    # core: equations formed point by point and folded into a QR factor, no design matrix; with
    # covariances, in the same call, the weighted fits or the sandwich covariances
    # (rotorid_core::pedestal_cov)
    def fit(qs, ps):
        """(mass, k, c, their standard errors, dof, residual, source) from the runs' relative and
        pedestal motion at the bearings (the covariances, points and weighting fixed above)."""
        try:
            th_all, c3_all, ranks, resid_all, m_rows, cov_fit = _core.pedestal_fit(
                params, np.ascontiguousarray(axis), spin, qs, e, gain, ps, sigma=sig_arr, select=sel, cross=cross,
                w_scale=w_scale, covs=covs if have_cov else None, shared=shared if have_cov else None,
                weighted=weighted)
        except RotoridError as exc:
            if "NaN or inf" not in str(exc):
                raise
            _name_nonfinite(labels, runs)
        for fi in range(4):
            if ranks[fi] < nu:
                raise IdentifiabilityError(f"pedestal {fi // 2 + 1} {'xy'[fi % 2]}: the equations are rank deficient "
                                           "(too few distinct frequencies, or no pedestal motion in that direction)")
        mass = np.zeros((2, 2))
        kk = np.zeros((2, 2, 2))
        cc = np.zeros((2, 2, 2))
        ms = np.zeros((2, 2))
        ks = np.zeros((2, 2, 2))
        cs = np.zeros((2, 2, 2))
        dof = np.full((2, 2), float(m_rows - nu))
        resid = resid_all.reshape(2, 2).copy()
        src = "residual"
        for b in range(2):
            for i in range(2):
                fi = 2 * b + i
                th, covt = th_all[fi], c3_all[fi]
                if have_cov and weighted:
                    # weighted least squares, the errors widened by a misfit beyond the measurement errors
                    th, covt, resid[b, i] = cov_fit[0][fi], cov_fit[1][fi], cov_fit[2][fi]
                    if not np.isfinite(th).all():
                        # the unweighted design has full rank (checked above): the weights made it
                        # numerically rank deficient
                        raise IdentifiabilityError(
                            f"pedestal {b + 1} {'xy'[i]}: the equations weighted by the measurement covariances are "
                            "numerically rank deficient (covariances spanning many orders of magnitude across the "
                            "points?); drop the runs' cov and pedestal_cov to fit unweighted with residual errors")
                    src = "measurement covariance"
                elif have_cov:
                    # covariances from a few repeats (impacts: dof = impacts - 1) are too noisy to weigh
                    # with (the inverse of a poorly estimated covariance overweights the rows whose
                    # variance happens to come out small): unweighted least squares with the sandwich of
                    # the propagated covariances, or the residual (HC3) covariance, which also sees errors
                    # the measurement covariance misses (run-out filter leftovers, low-coherence bins):
                    # the larger variance of the two counts
                    big = np.diag(covt) > np.diag(cov_fit[1][fi])
                    covt = np.where(big[:, None] & big[None, :], covt, cov_fit[1][fi])
                    src = "residual or measurement covariance, the larger (unweighted fit)"
                sd = np.sqrt(np.clip(np.diag(covt), 0, None))
                kk[b, i, i], mass[b, i], cc[b, i, i] = th[0], th[1], th[2]
                ks[b, i, i], ms[b, i], cs[b, i, i] = sd[0], sd[1], sd[2]
                if cross:
                    kk[b, i, 1 - i], cc[b, i, 1 - i] = th[3], th[4]
                    ks[b, i, 1 - i], cs[b, i, 1 - i] = sd[3], sd[4]
        return mass, kk, cc, ms, ks, cs, dof, resid, src

    from .identify import _phase_reference_std, _phase_std_deg_per_speed

    directions, line, scatter_std = [], None, None
    if not impact:
        om = axis * RPM
        angle = np.deg2rad(_phase_std_deg_per_speed("keyphasor_angle_std_deg", keyphasor_angle_std_deg, axis.size))
        if np.any(angle > 0):
            directions.append(angle * np.ones(axis.size))
        if _phase_reference_std(axis, 0.0, keyphasor_delay_std_s) is not None:
            directions.append(om * float(keyphasor_delay_std_s))
        if phase_line_cov is not None:
            from .phasecal import _line_scale

            line = real_array("phase_line_cov", phase_line_cov, shape=(2, 2))
            # in phase units (deg, deg at the top speed) the check of symmetry and semi-definiteness
            # is unit-free
            scale = _line_scale(float(np.max(om)))
            unit = line * scale[:, None] * scale[None, :]
            if not np.allclose(unit, unit.T, rtol=1e-9, atol=1e-300) or np.linalg.eigvalsh(unit).min() < \
                    -1e-9 * max(np.abs(unit).max(), 1e-300):
                raise RotoridError(f"phase_line_cov must be a symmetric positive semi-definite (2, 2) covariance of "
                                   f"the offset (deg) and the delay (s), got {line.tolist()}")
        scatter = _phase_std_deg_per_speed("phase_scatter_std_deg", phase_scatter_std_deg, axis.size)
        scatter_std = np.deg2rad(scatter) * np.ones(axis.size) if np.any(scatter > 0) else None
    mass, kk, cc, ms, ks, cs, dof, resid, src = fit(qs, ps)
    out = PedestalIdentification(mass, kk, cc, ms, ks, cs, dof, resid, src, cross, R * ns, labels)
    if cal_g or cal_ph:
        from .identify import _probe_maps

        _add_calibration(out, fit, qs, ps, _probe_maps(rotor, runs), cal_g, cal_ph)
    if directions or line is not None or scatter_std is not None:
        keep = (lambda v: v) if sel is None else (lambda v: np.where(sel, v, 0.0))
        _add_phase_reference(out, fit, qs, ps, [keep(d) for d in directions],
                             None if line is None else (line, keep(np.full(axis.size, np.pi / 180.0)), keep(-om)),
                             None if scatter_std is None else keep(scatter_std))
    return out


def _name_nonfinite(labels, runs):
    """Raise a RotoridError naming the first run and field (``q`` or ``pedestal``) with a NaN or
    inf; without one (finite data whose equations overflow) the runs as a whole."""
    for lab, run in zip(labels, runs):
        for name in ("q", "pedestal"):
            a = np.asarray(getattr(run, name))
            bad = ~np.isfinite(a)
            if bad.any():
                idx = tuple(int(v) for v in np.argwhere(bad)[0])
                raise RotoridError(f"{lab}: {name} contains NaN or inf (first at index {idx})")
    raise RotoridError("runs contain NaN or inf")


def _add_phase_reference(out, fit, qs, ps, profiles, line, scatter_rad):
    """Add the phase reference's uncertainty to a pedestal fit's standard errors. A phase error e_i
    at speed i turns every run's relative and pedestal motion there by e^{j e_i}; theta the fit's
    estimates. ``profiles``: errors e_i = s_i eps throughout the speeds (eps standard normal), each
    adding (d theta / d eps)²; ``line``: (M, d_0, d_tau), an error theta_0 d_0 + tau d_tau with
    (theta_0 in deg, tau in s) of covariance M, d_0 the radians per degree and d_tau = -Omega at
    each speed, adding g M g^T for g = d theta / d(theta_0, tau);
    ``scatter_rad`` (n,) or None: errors independent between speeds, adding sum_i s_i² (d theta /
    d e_i)². The derivatives by central differences of the whole fit (``fit(qs, ps)``: weights,
    points and covariances fixed). (The per-speed scatter taken as one error throughout the speeds
    made synthetic per-speed errors' intervals 4 times too wide; an error growing with speed taken
    as independent between speeds covered 0.66-0.72; a calibration's line passed as its size at
    each speed, which cannot change sign, covered 0.32-0.70 where the line crosses zero, review.)"""
    from .identify import _CAL_STEP

    def derivative(direction):
        """d(mass, k, c) / d eps for the phases eps * ``direction`` (rad per speed)."""
        est = []
        for step in (_CAL_STEP, -_CAL_STEP):
            turn = np.exp(1j * step * direction)[:, None]
            est.append(fit([q * turn for q in qs], [p * turn for p in ps])[:3])
        return [(a - b) / (2.0 * _CAL_STEP) for a, b in zip(est[0], est[1])]

    var = [np.zeros_like(out.mass_kg), np.zeros_like(out.k), np.zeros_like(out.c)]
    for profile in profiles:
        for v, d in zip(var, derivative(profile)):
            v += d ** 2
    if line is not None:
        M, d0, d_tau = line
        for v, a, b in zip(var, derivative(d0), derivative(d_tau)):
            v += a * a * M[0, 0] + 2.0 * a * b * M[0, 1] + b * b * M[1, 1]
    if scatter_rad is not None:
        for i in np.flatnonzero(scatter_rad > 0):
            unit = np.zeros(scatter_rad.size)
            unit[i] = scatter_rad[i]
            for v, d in zip(var, derivative(unit)):
                v += d ** 2
    _widen(out, var, "phase reference")


def _widen(out, var, source):
    """Add the variances ``var`` (of mass, k, c; the negative rounding of a sum of cross terms as 0)
    to a pedestal fit's standard errors, and ``source`` to its ``std_source``."""
    out.mass_std = np.sqrt(out.mass_std ** 2 + np.clip(var[0], 0.0, None))
    out.k_std = np.sqrt(out.k_std ** 2 + np.clip(var[1], 0.0, None))
    out.c_std = np.sqrt(out.c_std ** 2 + np.clip(var[2], 0.0, None))
    out.std_source += f" + {source}"


def _add_calibration(out, fit, qs, ps, maps, gain_std, phase_std_rad):
    """Add the accelerometers' calibration uncertainty to a pedestal fit's standard errors: central
    differences of the whole fit (``fit(qs, ps)``: its weights, points and covariances fixed) with
    respect to each accelerometer's gain and phase, on the runs' motions at the bearings stepped
    as moving the stepped runs would step them (``identify.calibration_steps``)."""
    from .identify import _CAL_STEP, calibration_steps

    var = [np.zeros_like(out.mass_kg), np.zeros_like(out.k), np.zeros_like(out.c)]
    for std, plus, minus in calibration_steps(qs, ps, maps, gain_std, phase_std_rad):
        est = [fit(*side)[:3] for side in (plus, minus)]
        for v, a, b in zip(var, est[0], est[1]):
            v += (std * (a - b) / (2.0 * _CAL_STEP)) ** 2
    _widen(out, var, "accelerometer calibration")
