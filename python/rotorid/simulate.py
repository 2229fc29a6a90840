"""Forward simulation: synchronous imbalance response (report eq. 13-14), probe transforms (eq. 19)
and a measurement-error model for numerical experiments."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import _core
from ._validate import choice, complex_array, real_array, speeds_rpm
from .errors import RotoridError
from .model import BearingCoefficients, Imbalance, RigidRotor

RPM = np.pi / 30.0
DOFS = ("x1", "x2", "y1", "y2")


def bearings_to_probes_matrix(rotor: RigidRotor) -> np.ndarray:
    """2x2 matrix T with [x_p1, x_p2] = T [x_1, x_2] (rigid body; same for y)."""
    l1, l2, s1, s2 = rotor.l1, rotor.l2, rotor.s1, rotor.s2
    L = l1 + l2
    # x(z) = x_c + z a with a = (x2 - x1)/L, x_c = (l2 x1 + l1 x2)/L; probes at z = -s1, +s2
    return np.array([[l2 + s1, l1 - s1], [l2 - s2, l1 + s2]]) / L


def probes_to_bearings_matrix(rotor: RigidRotor) -> np.ndarray:
    """2x2 matrix of report eq. 19: [x_1, x_2] = T [x_p1, x_p2]."""
    l1, l2, s1, s2 = rotor.l1, rotor.l2, rotor.s1, rotor.s2
    return np.array([[l1 + s2, s1 - l1], [s2 - l2, l2 + s1]]) / (s1 + s2)


def _apply_planes(T, q):
    q = np.asarray(q)
    out = np.empty(np.broadcast_shapes(q.shape), dtype=np.result_type(q, complex))
    out[..., 0:2] = q[..., 0:2] @ T.T
    out[..., 2:4] = q[..., 2:4] @ T.T
    return out


def probes_to_bearings(rotor: RigidRotor, q_probes):
    """Report eq. 19 applied to [x_p1, x_p2, y_p1, y_p2] (last axis)."""
    return _apply_planes(probes_to_bearings_matrix(rotor), q_probes)


def bearings_to_probes(rotor: RigidRotor, q_bearings):
    """Inverse of eq. 19: responses at the probe planes from responses at the bearings."""
    return _apply_planes(bearings_to_probes_matrix(rotor), q_bearings)


@dataclass
class SyncResponse:
    """Synchronous (1X) response of one imbalance run.

    ``q``: complex (n, 4), order [x1, x2, y1, y2], 0-peak amplitude, x(t) = Re(q e^{jΩt}) in metres.
    ``imbalance``: the (added) imbalance that produced it. ``at``: where q was measured,
    "bearings" or "probes" (the rotor's s1, s2).
    """

    speed_rpm: np.ndarray
    q: np.ndarray
    imbalance: Imbalance | None = None
    at: str = "bearings"
    name: str | None = field(default=None)

    def __post_init__(self):
        self.speed_rpm = speeds_rpm("speed_rpm", self.speed_rpm)
        self.q = complex_array("q", self.q)
        if self.q.ndim == 1 and self.q.shape == (4,) and self.speed_rpm.size == 1:
            self.q = self.q[None, :]
        if self.q.shape != (self.speed_rpm.size, 4):
            raise RotoridError(f"q has shape {self.q.shape}, expected ({self.speed_rpm.size}, 4) "
                               "= (len(speed_rpm), [x1, x2, y1, y2])")
        choice("at", self.at, {"bearings", "probes"})
        if self.imbalance is not None and not isinstance(self.imbalance, Imbalance):
            raise RotoridError(f"imbalance must be a rotorid.Imbalance, got {type(self.imbalance).__name__}")
        if self.name is None and self.imbalance is not None:
            self.name = self.imbalance.name

    def at_bearings(self, rotor: RigidRotor) -> "SyncResponse":
        if self.at == "bearings":
            return self
        return SyncResponse(self.speed_rpm, probes_to_bearings(rotor, self.q), self.imbalance, "bearings", self.name)

    def at_probes(self, rotor: RigidRotor) -> "SyncResponse":
        if self.at == "probes":
            return self
        return SyncResponse(self.speed_rpm, bearings_to_probes(rotor, self.q), self.imbalance, "probes", self.name)

    @property
    def amplitude(self):
        """0-peak amplitude |q| (m), shape (n, 4)."""
        return np.abs(self.q)

    @property
    def phase_deg(self):
        """Phase angle arg(q) in degrees (instrument phase lag is its negative)."""
        return np.rad2deg(np.angle(self.q))

    def to_dataframe(self):
        import pandas as pd

        data = {"speed_rpm": self.speed_rpm}
        for j, nm in enumerate(DOFS):
            data[f"{nm}_amp_um"] = 1e6 * np.abs(self.q[:, j])
            data[f"{nm}_phase_deg"] = np.rad2deg(np.angle(self.q[:, j]))
        return pd.DataFrame(data)


def _core_coeffs(bearings: BearingCoefficients, n, speed_rpm=None, freq_hz=None, broadcast=False):
    """Bearing coefficients as the core wants them: (n, 8), or (1, 8) for constant coefficients when
    the core function broadcasts (``broadcast=True``)."""
    if broadcast and bearings.is_constant:
        return bearings.k.reshape(1, 8).copy(), bearings.c.reshape(1, 8).copy()
    k, c = bearings.at(speed_rpm=speed_rpm, freq_hz=freq_hz)
    k = np.ascontiguousarray(np.broadcast_to(k, (n, 2, 2, 2)).reshape(n, 8))
    c = np.ascontiguousarray(np.broadcast_to(c, (n, 2, 2, 2)).reshape(n, 8))
    return k, c


def imbalance_response(rotor: RigidRotor, bearings: BearingCoefficients, imbalance: Imbalance, *,
                       speed_rpm, at: str = "bearings") -> SyncResponse:
    """Synchronous response to an imbalance set over speeds (eq. 13-14), batched in the core."""
    if not isinstance(rotor, RigidRotor):
        raise RotoridError(f"rotor must be a rotorid.RigidRotor, got {type(rotor).__name__}")
    if not isinstance(bearings, BearingCoefficients):
        raise RotoridError(f"bearings must be a rotorid.BearingCoefficients, got {type(bearings).__name__}")
    if not isinstance(imbalance, Imbalance):
        raise RotoridError(f"imbalance must be a rotorid.Imbalance, got {type(imbalance).__name__}")
    choice("at", at, {"bearings", "probes"})
    rpm = speeds_rpm("speed_rpm", speed_rpm)
    n = rpm.size
    om = rpm * RPM
    k, c = _core_coeffs(bearings, n, speed_rpm=rpm, broadcast=True)
    force = (imbalance.generalized(rotor)[None, :] * (om ** 2)[:, None])[:, None, :]
    q, nsing = _core.forced_response(rotor.core_params(), k, c, om, om, force)
    if nsing:
        bad = rpm[~np.all(np.isfinite(q[:, 0, :]), axis=1)]
        raise RotoridError(f"the rotor-bearing system is singular (undamped resonance) at speed_rpm = {bad[:5]}")
    resp = SyncResponse(rpm, q[:, 0, :], imbalance, "bearings", imbalance.name)
    return resp.at_probes(rotor) if at == "probes" else resp


@dataclass(frozen=True)
class ProbeResolution:
    """Measurement-error model of 1X vectors: the amplitude is rounded to a fixed resolution and
    the phase to a fixed resolution, optionally after adding complex Gaussian noise (rms, metres).

    The defaults, 0.001 mil (0.0254 µm) 0-pk and 0.01 degree, are the precision to which the demo
    tabulates its simulated responses before identifying; with them the NSF experiment shows the
    report's Figure 4 pattern (poor below ~2000 rpm, good between the critical speeds, cross-coupled
    stiffness distorted above ~6000 rpm). A DAQ reporting 0.01 mil and 1 degree is far coarser and
    ruins the cross-coupled coefficients everywhere (README, "Figure 4").
    """

    amplitude_m: float = 0.0254e-6
    phase_deg: float = 0.01
    noise_m: float = 0.0

    def apply(self, q, rng=None):
        q = np.asarray(q, complex)
        if self.noise_m > 0:
            rng = np.random.default_rng(rng)
            q = q + self.noise_m / np.sqrt(2) * (rng.standard_normal(q.shape) + 1j * rng.standard_normal(q.shape))
        amp = np.abs(q)
        ph = np.angle(q, deg=True)
        if self.amplitude_m > 0:
            amp = np.round(amp / self.amplitude_m) * self.amplitude_m
        if self.phase_deg > 0:
            ph = np.round(ph / self.phase_deg) * self.phase_deg
        return amp * np.exp(1j * np.deg2rad(ph))

    def measure(self, response: SyncResponse, rng=None) -> SyncResponse:
        return SyncResponse(response.speed_rpm, self.apply(response.q, rng), response.imbalance, response.at, response.name)
