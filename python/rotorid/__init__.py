"""rotorid: identification of bearing stiffness and damping coefficients of rigid rotors from
imbalance responses and impacts (after De Santiago & San Andrés, TRC-RD-1-01, 2001)."""

# The public names are imported on first access (PEP 562 ``__getattr__`` below), so that
# ``import rotorid`` and ``rotorid --help`` load neither numpy nor the core extension; the heavy
# optional dependencies (pandas, matplotlib, scipy, pydantic, nptdms, pyuff, openpyxl) are in
# turn imported only inside the functions that use them. tests/test_startup.py guards this.
TYPE_CHECKING = False  # (not typing.TYPE_CHECKING: importing typing alone costs ~10 ms)
if TYPE_CHECKING:
    from . import io, pipeline, rawsim, signals, studies  # noqa: F401  (submodules)
    from .errors import IdentifiabilityError, RotoridError
    from .identify import Identification, identify_impact, identify_synchronous, identify_synchronous_batch
    from .kcm import KCMFit, fit_kcm
    from .phasecal import PhaseCalibration, calibrate_phase
    from .modal import ModalResult, critical_speeds, modal_analysis
    from .io import load_recording, save_recording
    from .model import REPORT_ORDER, BearingCoefficients, Imbalance, RigidRotor, Rig, nsf_rig
    from .pedestal import PedestalIdentification, Pedestals, example_pedestals, identify_pedestals
    from .recording import Recording
    from .support import series_impedance
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

# public name -> submodule defining it (the imports above, done lazily)
_LAZY_NAMES = {
    **dict.fromkeys(("IdentifiabilityError", "RotoridError"), "errors"),
    **dict.fromkeys(("Identification", "identify_impact", "identify_synchronous", "identify_synchronous_batch"),
                    "identify"),
    **dict.fromkeys(("KCMFit", "fit_kcm"), "kcm"),
    **dict.fromkeys(("PhaseCalibration", "calibrate_phase"), "phasecal"),
    **dict.fromkeys(("ModalResult", "critical_speeds", "modal_analysis"), "modal"),
    **dict.fromkeys(("load_recording", "save_recording"), "io"),
    **dict.fromkeys(("REPORT_ORDER", "BearingCoefficients", "Imbalance", "RigidRotor", "Rig", "nsf_rig"), "model"),
    "Recording": "recording",
    **dict.fromkeys(("PedestalIdentification", "Pedestals", "example_pedestals", "identify_pedestals"), "pedestal"),
    "series_impedance": "support",
    **dict.fromkeys(("ImpactResponse", "ProbeResolution", "SyncResponse", "TimeResponse", "bearings_to_probes",
                     "half_sine_pulse", "imbalance_response", "impact_frf", "impact_time_response", "impact_vector",
                     "probes_to_bearings"), "simulate"),
}
# submodules that an eager ``import rotorid`` used to leave as attributes of the package
_LAZY_SUBMODULES = frozenset(("io", "pipeline", "rawsim", "signals", "errors", "identify", "kcm", "phasecal", "modal",
                              "model", "pedestal", "recording", "simulate", "support", "units", "studies", "_core",
                              "_corecall", "_validate"))


def __getattr__(name):
    from importlib import import_module

    if name in _LAZY_NAMES:
        value = getattr(import_module(f"{__name__}.{_LAZY_NAMES[name]}"), name)
    elif name in _LAZY_SUBMODULES:
        value = import_module(f"{__name__}.{name}")
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value  # later lookups bypass __getattr__
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY_NAMES) | _LAZY_SUBMODULES)


__all__ = [
    "BearingCoefficients", "IdentifiabilityError", "Identification", "ImpactResponse", "Imbalance", "ModalResult",
    "TimeResponse", "half_sine_pulse", "identify_impact", "impact_frf", "impact_time_response", "impact_vector",
    "ProbeResolution", "REPORT_ORDER", "RigidRotor", "Rig", "RotoridError", "SyncResponse",
    "bearings_to_probes", "critical_speeds", "identify_synchronous", "identify_synchronous_batch",
    "imbalance_response", "modal_analysis", "nsf_rig", "probes_to_bearings",
    "Recording", "load_recording", "save_recording", "io", "pipeline", "rawsim", "signals", "studies", "KCMFit", "fit_kcm", "PhaseCalibration", "calibrate_phase",
    "Pedestals", "PedestalIdentification", "example_pedestals", "identify_pedestals", "series_impedance", "support",
]
__version__ = "0.1.0"
