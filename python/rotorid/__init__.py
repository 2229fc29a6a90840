"""rotorid: identification of bearing stiffness and damping coefficients of rigid rotors from
imbalance responses and impacts (after De Santiago & San Andrés, TRC-RD-1-01, 2001)."""

from . import io, pipeline, rawsim, signals  # noqa: F401  (submodules of the raw-data chain)
from .errors import IdentifiabilityError, RotoridError
from .identify import Identification, identify_impact, identify_synchronous, identify_synchronous_batch
from .kcm import KCMFit, fit_kcm
from .phasecal import PhaseCalibration, calibrate_phase
from .modal import ModalResult, critical_speeds, modal_analysis
from .io import load_recording, save_recording
from .model import REPORT_ORDER, BearingCoefficients, Imbalance, RigidRotor, Rig, nsf_rig
from .recording import Recording
from .simulate import (
    ImpactResponse,
    ProbeResolution,
    SyncResponse,
    TimeResponse,
    bearings_to_probes,
    half_sine_pulse,
    imbalance_response,
    impact_frf,
    impact_time_response,
    impact_vector,
    probes_to_bearings,
)

__all__ = [
    "BearingCoefficients", "IdentifiabilityError", "Identification", "ImpactResponse", "Imbalance", "ModalResult",
    "TimeResponse", "half_sine_pulse", "identify_impact", "impact_frf", "impact_time_response", "impact_vector",
    "ProbeResolution", "REPORT_ORDER", "RigidRotor", "Rig", "RotoridError", "SyncResponse",
    "bearings_to_probes", "critical_speeds", "identify_synchronous", "identify_synchronous_batch",
    "imbalance_response", "modal_analysis", "nsf_rig", "probes_to_bearings",
    "Recording", "load_recording", "save_recording", "io", "pipeline", "rawsim", "signals", "KCMFit", "fit_kcm", "PhaseCalibration", "calibrate_phase",
]
__version__ = "0.1.0"
