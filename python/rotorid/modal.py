"""Eigen-analysis vs running speed, Campbell data and critical speeds.

Damping definitions (both reported):
- ``damping_ratio`` = -Re(λ)/|λ| (the conventional modal damping ratio, DESIGN.md);
- ``damping_ratio_wd`` = -Re(λ)/Im(λ) = δ/(2π), with δ the logarithmic decrement. This is the
  definition the report's Table 5 uses: with it the NSF rig gives 0.114, 0.131, 0.201, 0.199 as
  printed, while -Re/|λ| gives 0.114, 0.130, 0.197, 0.195.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._corecall import core as _core
from ._validate import real_array
from .errors import RotoridError
from .model import BearingCoefficients, RigidRotor
from .simulate import RPM, _check_model, _core_coeffs


@dataclass
class ModalResult:
    """Modes with positive damped frequency at each speed, sorted by frequency (NaN when fewer)."""

    speed_rpm: np.ndarray      # (n,)
    eigenvalues: np.ndarray    # (n, modes) complex, rad/s: 4 modes, 8 with flexible pedestals
    shapes: np.ndarray         # (n, modes, dofs [x1, x2, y1, y2 (, xp1, xp2, yp1, yp2)]) complex

    @property
    def freq_hz(self):
        """Damped natural frequency Im(λ)/2π."""
        return self.eigenvalues.imag / (2 * np.pi)

    @property
    def damping_ratio(self):
        return -self.eigenvalues.real / np.abs(self.eigenvalues)

    @property
    def damping_ratio_wd(self):
        return -self.eigenvalues.real / self.eigenvalues.imag

    @property
    def log_decrement(self):
        return 2 * np.pi * self.damping_ratio_wd

    @property
    def forward_fraction(self):
        """Per mode, the share of the forward-whirl circle in the orbit at the bearing with the
        larger motion: 1 = pure forward, 0 = pure backward (rotation x -> y is forward)."""
        s = self.shapes[..., :4]  # the rotor's (absolute) motion
        x = s[..., [0, 1]]
        y = s[..., [2, 3]]
        fwd = np.abs(x + 1j * y)
        bwd = np.abs(x - 1j * y)
        big = np.argmax(fwd + bwd, axis=-1)[..., None]
        f = np.take_along_axis(fwd, big, -1)[..., 0]
        b = np.take_along_axis(bwd, big, -1)[..., 0]
        return f / (f + b)

    @property
    def whirl(self):
        ff = self.forward_fraction
        out = np.where(ff >= 0.5, "forward", "backward").astype(object)
        out[~np.isfinite(ff)] = ""
        return out

    def to_dataframe(self):
        import pandas as pd

        rows = []
        for i, rpm in enumerate(self.speed_rpm):
            for m in range(self.eigenvalues.shape[1]):
                if np.isfinite(self.eigenvalues[i, m]):
                    rows.append(dict(speed_rpm=rpm, mode=m + 1, freq_hz=self.freq_hz[i, m],
                                     freq_cpm=60 * self.freq_hz[i, m], damping_ratio=self.damping_ratio[i, m],
                                     damping_ratio_wd=self.damping_ratio_wd[i, m],
                                     log_decrement=self.log_decrement[i, m], whirl=self.whirl[i, m]))
        return pd.DataFrame(rows)


def _check(rotor, bearings):
    _check_model(rotor, bearings)
    if bearings.axis_name == "freq_hz":
        raise RotoridError("modal analysis needs coefficients constant or tabulated over speed_rpm; "
                           "frequency-dependent coefficients make it a nonlinear eigenproblem")


def modal_analysis(rotor: RigidRotor, bearings: BearingCoefficients, *, speed_rpm, pedestals=None) -> ModalResult:
    """Damped natural frequencies, damping and whirl direction at each running speed (batched).

    With ``pedestals`` (rotorid.Pedestals, masses > 0) the coupled 8-DOF system: up to 8 modes,
    shapes over [x1, x2, y1, y2, xp1, xp2, yp1, yp2] (absolute motions).

    Examples
    --------
    >>> import rotorid
    >>> rig = rotorid.nsf_rig()
    >>> m = rotorid.modal_analysis(rig.rotor, rig.bearings, speed_rpm=[3000.0], pedestals=rotorid.example_pedestals())
    >>> m.eigenvalues.shape
    (1, 8)
    """
    _check(rotor, bearings)
    pedestals = _check_pedestals(pedestals)
    rpm = np.atleast_1d(real_array("speed_rpm", speed_rpm, nonneg=True))
    if rpm.ndim != 1 or rpm.size == 0:
        raise RotoridError(f"speed_rpm must be a non-empty 1-D array, got shape {rpm.shape}")
    return _modal(rotor, bearings, rpm, pedestals)


def _check_pedestals(pedestals):
    from .simulate import _check_pedestals as check

    pedestals = check(pedestals)
    if pedestals is not None and np.any(pedestals.mass_kg <= 0):
        raise RotoridError("modal analysis with pedestals needs every pedestal mass > 0 (a massless pedestal adds "
                           f"no degree of freedom), got mass_kg = {pedestals.mass_kg.tolist()}")
    return pedestals


def _modal(rotor, bearings, rpm, pedestals=None):
    n = rpm.size
    k, c = _core_coeffs(bearings, n, speed_rpm=rpm)
    if pedestals is not None:
        lam, shapes, nfail = _core.modal_pedestal(rotor.core_params(), k, c, pedestals.core_params(),
                                                  np.ascontiguousarray(rpm * RPM))
    else:
        lam, shapes, nfail = _core.modal(rotor.core_params(), k, c, np.ascontiguousarray(rpm * RPM))
    if nfail:
        raise RotoridError(f"eigen-solver failed at {nfail} speed(s)")
    return ModalResult(rpm, lam, shapes)


def critical_speeds(rotor: RigidRotor, bearings: BearingCoefficients, *, max_rpm: float = 20000.0,
                    n_grid: int = 400, order: float = 1.0, pedestals=None):
    """Speeds where a damped natural frequency equals ``order`` x running speed (1X by default).

    Returns a pandas DataFrame with columns speed_rpm, freq_hz, damping_ratio, damping_ratio_wd,
    log_decrement, whirl, mode (index of the mode sorted by frequency).
    """
    import pandas as pd

    _check(rotor, bearings)
    pedestals = _check_pedestals(pedestals)
    from ._validate import number

    max_rpm = number("max_rpm", max_rpm, positive=True)
    order = number("order", order, positive=True)
    if isinstance(n_grid, bool) or not isinstance(n_grid, (int, np.integer)) or not (8 <= n_grid <= 1_000_000):
        raise RotoridError(f"n_grid must be a whole number from 8 to 1,000,000 (the speeds scanned for crossings), "
                           f"got {n_grid!r}")
    lo = 1e-3 * max_rpm
    if not bearings.is_constant:
        lo = max(lo, bearings.axis[0])
        max_rpm = min(max_rpm, bearings.axis[-1])
    grid = np.linspace(lo, max_rpm, int(n_grid))
    res = _modal(rotor, bearings, grid, pedestals)
    g = 60 * res.freq_hz - order * grid[:, None]
    rows = []
    for m in range(res.eigenvalues.shape[1]):
        gm = g[:, m]
        idx = np.nonzero(np.isfinite(gm[:-1]) & np.isfinite(gm[1:]) & (np.sign(gm[:-1]) != np.sign(gm[1:])))[0]
        for i in idx:
            a, b = grid[i], grid[i + 1]
            ga = gm[i]
            for _ in range(60):
                mid = 0.5 * (a + b)
                gmid = 60 * _modal(rotor, bearings, np.array([mid]), pedestals).freq_hz[0, m] - order * mid
                if np.sign(gmid) == np.sign(ga):
                    a, ga = mid, gmid
                else:
                    b = mid
                if b - a < 1e-9 * b:
                    break
            s = 0.5 * (a + b)
            r = _modal(rotor, bearings, np.array([s]), pedestals)
            rows.append(dict(speed_rpm=s, freq_hz=r.freq_hz[0, m], damping_ratio=r.damping_ratio[0, m],
                             damping_ratio_wd=r.damping_ratio_wd[0, m], log_decrement=r.log_decrement[0, m],
                             whirl=r.whirl[0, m], mode=m + 1))
    df = pd.DataFrame(rows, columns=["speed_rpm", "freq_hz", "damping_ratio", "damping_ratio_wd",
                                     "log_decrement", "whirl", "mode"])
    return df.sort_values("speed_rpm").reset_index(drop=True)
