"""Measurement-error models of Monte Carlo studies (docs/studies.md): standard deviations of every
error a lab's imbalance or impact test carries. Zero switches an error off."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from .._validate import number
from ..errors import RotoridError

#: a standard deviation above this is no measurement error but a wrong input (relative errors)
MAX_REL = 10.0


def _check_fields(obj, limits):
    for f in fields(obj):
        v = number(f.name, getattr(obj, f.name), nonneg=True)
        hi = limits.get(f.name)
        if hi is not None and v > hi[0]:
            raise RotoridError(f"{f.name} = {v:g} is not a plausible standard deviation (at most {hi[0]:g} {hi[1]})")
        object.__setattr__(obj, f.name, v)


@dataclass(frozen=True)
class SyncErrors:
    """Errors of an imbalance (synchronous) test, as standard deviations (0 = off).

    Parameters
    ----------
    amplitude_rel : float
        Relative error of each 1X amplitude (0.01 = 1 %), independent per speed, run and channel.
    phase_deg : float
        Error of each 1X phase (degrees), independent per speed, run and channel.
    noise_m : float
        Complex Gaussian noise added to each 1X vector (rms of the modulus, m).
    keyphasor_deg : float
        Offset of the keyphasor mark: one angle common to every vector of a test (degrees).
    channel_delay_s : float
        Delay of each probe channel (s): a phase lag Ω·τ that grows with speed.
    probe_position_m : float
        Axial position error of each probe (m): the probe-to-bearing transform uses the nominal one.
    trial_mass_rel : float
        Relative error of each trial mass (m·r) of each run.
    trial_angle_deg : float
        Angular error of each trial mass (degrees).
    speed_rel : float
        Relative error of the speed the identification is told, per speed.

    Examples
    --------
    >>> from rotorid.studies import SyncErrors
    >>> SyncErrors(amplitude_rel=0.01, phase_deg=0.5).phase_deg
    0.5
    """

    amplitude_rel: float = 0.0
    phase_deg: float = 0.0
    noise_m: float = 0.0
    keyphasor_deg: float = 0.0
    channel_delay_s: float = 0.0
    probe_position_m: float = 0.0
    trial_mass_rel: float = 0.0
    trial_angle_deg: float = 0.0
    speed_rel: float = 0.0

    def __post_init__(self):
        _check_fields(self, dict(amplitude_rel=(MAX_REL, ""), phase_deg=(180.0, "degrees"), noise_m=(0.01, "m"),
                                 keyphasor_deg=(180.0, "degrees"), channel_delay_s=(1.0, "s"),
                                 probe_position_m=(1.0, "m"), trial_mass_rel=(MAX_REL, ""),
                                 trial_angle_deg=(180.0, "degrees"), speed_rel=(0.5, "")))

    def core_array(self) -> np.ndarray:
        """The nine standard deviations in the core's order and units (radians)."""
        r = np.deg2rad
        return np.array([self.amplitude_rel, r(self.phase_deg), self.noise_m, r(self.keyphasor_deg),
                         self.channel_delay_s, self.probe_position_m, self.trial_mass_rel, r(self.trial_angle_deg),
                         self.speed_rel])

    def is_random_only(self) -> bool:
        """True when every error is independent per vector (amplitude, phase, noise): the errors a
        measurement covariance describes. The others are systematic within a test."""
        return not any((self.keyphasor_deg, self.channel_delay_s, self.probe_position_m, self.trial_mass_rel,
                        self.trial_angle_deg, self.speed_rel))


def frf_random_error(coherence: float, impacts: int) -> float:
    """Normalized random error ε = sqrt((1 - γ²) / (2 n γ²)) of an H1 FRF averaged over ``impacts``
    with ordinary coherence ``coherence`` = γ² (Bendat & Piersol, Random Data, eq. 9.73, 9.90): the
    standard deviation of the relative amplitude error and of the phase error (rad).

    Examples
    --------
    >>> from rotorid.studies import frf_random_error
    >>> round(frf_random_error(0.95, 5), 4)
    0.0725
    """
    g = number("coherence", coherence, positive=True)
    if g > 1:
        raise RotoridError(f"coherence is an ordinary coherence γ² in (0, 1], got {g:g}")
    n = number("impacts", impacts, positive=True)
    if n != int(n) or n > 1e6:
        raise RotoridError(f"impacts must be a whole number of impacts per test (1 to 1e6), got {impacts!r}")
    eps = float(np.sqrt((1 - g) / (2 * n * g)))
    if not eps <= MAX_REL:
        raise RotoridError(f"coherence {g:g} with {int(n)} impacts gives an FRF error of {eps:.3g} (relative): "
                           "such FRFs carry no information (coherence too low)")
    return eps


@dataclass(frozen=True)
class ImpactErrors:
    """Errors of an impact test, as standard deviations (0 = off) and the averaging that sets the
    FRFs' random error.

    Parameters
    ----------
    coherence : float
        Ordinary coherence γ² of every FRF (1 = no random error).
    impacts : int
        Impacts averaged per test (H1 estimator).
    force_calibration_rel : float
        Relative error of the force sensor gain, per test.
    impact_position_m : float
        Axial error of where a test's impacts land (m).
    channel_delay_s : float
        Delay of each probe channel (s).
    probe_position_m : float
        Axial position error of each probe (m).

    Examples
    --------
    >>> from rotorid.studies import ImpactErrors
    >>> ImpactErrors(coherence=0.95, impacts=5).frf_rel > 0
    True
    """

    coherence: float = 1.0
    impacts: int = 1
    force_calibration_rel: float = 0.0
    impact_position_m: float = 0.0
    channel_delay_s: float = 0.0
    probe_position_m: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "_eps", frf_random_error(self.coherence, self.impacts))
        object.__setattr__(self, "impacts", int(self.impacts))
        _check_fields(self, dict(coherence=(1.0, ""), force_calibration_rel=(MAX_REL, ""),
                                 impact_position_m=(1.0, "m"), channel_delay_s=(1.0, "s"), probe_position_m=(1.0, "m")))
        object.__setattr__(self, "impacts", int(self.impacts))

    @property
    def frf_rel(self) -> float:
        """Normalized random error ε of each FRF (see :func:`frf_random_error`)."""
        return self._eps

    def core_array(self) -> np.ndarray:
        return np.array([self.frf_rel, self.force_calibration_rel, self.impact_position_m, self.channel_delay_s,
                         self.probe_position_m])

    def is_random_only(self) -> bool:
        return not any((self.force_calibration_rel, self.impact_position_m, self.channel_delay_s,
                        self.probe_position_m))
