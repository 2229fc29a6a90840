"""Typed stubs of the compiled core (rust/src/lib.rs). Arrays must be C-contiguous.

Conventions: rotor = [m, I_T, I_p, l1, l2]; bearing coefficients per point as 8 values
[bearing][i][j]; responses q = [x1, x2, y1, y2]; w = vibration frequency and spin = running
speed in rad/s. Every function releases the GIL and raises ValueError on bad shapes.
"""

import numpy as np
import numpy.typing as npt

__version__: str

def forced_response(
    rotor: npt.NDArray[np.float64],
    k: npt.NDArray[np.float64],  # (n or 1, 8)
    c: npt.NDArray[np.float64],  # (n or 1, 8)
    spin: npt.NDArray[np.float64],  # (n,)
    w: npt.NDArray[np.float64],  # (n,)
    force: npt.NDArray[np.complex128],  # (n or 1, nrhs, 4)
) -> tuple[npt.NDArray[np.complex128], int]:
    """Solve H q = F with H = -w^2 M + j w spin G + j w C + K; returns (q (n, nrhs, 4), n_singular)."""

def identify(
    rotor: npt.NDArray[np.float64],
    w: npt.NDArray[np.float64],  # (n,)
    spin: npt.NDArray[np.float64],  # (n,)
    q: npt.NDArray[np.complex128],  # (batch, runs, n, 4)
    e: npt.NDArray[np.complex128],  # (1 or batch, runs, 4)
    gain: npt.NDArray[np.float64],  # (n,): excitation at point i is e * gain[i]
    identical: bool = False,
    method: str = "forces",  # or "report"
    with_std: bool = True,
    sigma: npt.NDArray[np.float64] | None = None,  # (n,): solve at s = sigma + j w (exponential windows)
) -> tuple[
    npt.NDArray[np.float64],  # k (batch, n, 2, 2, 2)
    npt.NDArray[np.float64],  # c (batch, n, 2, 2, 2)
    npt.NDArray[np.float64],  # cond (batch, n, 2): inf where singular, NaN where input not finite
    npt.NDArray[np.float64],  # relative residual (batch, n)
    npt.NDArray[np.float64],  # rms response amplitude (batch, n)
    npt.NDArray[np.float64] | None,  # k standard error (batch, n, 2, 2, 2)
    npt.NDArray[np.float64] | None,  # c standard error
    int,  # number of points with NaN/inf input
]: ...

def modal(
    rotor: npt.NDArray[np.float64],
    k: npt.NDArray[np.float64],  # (n, 8)
    c: npt.NDArray[np.float64],  # (n, 8)
    spin: npt.NDArray[np.float64],  # (n,)
) -> tuple[npt.NDArray[np.complex128], npt.NDArray[np.complex128], int]:
    """Eigenvalues with Im > 0 sorted by frequency (n, 4), mode shapes (n, 4, 4), n_failed."""
