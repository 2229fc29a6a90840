"""The series support's equivalent impedance (the physics is in the core, rust/core/src/series.rs)."""

from __future__ import annotations

import numpy as np

from .._corecall import core as _core
from .._validate import complex_array, real_array
from ..errors import RotoridError


#: the open interval (_BELOW_ZERO, _ABOVE_MAX_HZ) of first_outside is the closed [0, 1e6] Hz
_BELOW_ZERO = -np.finfo(float).smallest_subnormal
_ABOVE_MAX_HZ = float(np.nextafter(1e6, np.inf))


def _stack(name, z, n):
    """(n or 1, 2, 2) complex, C-contiguous: one matrix for every point, or one per point. NaN and
    inf pass here: the core finds them itself (such a point comes out singular), and
    :func:`series_impedance` then names the argument, without a scan of every call's input."""
    a = complex_array(name, z, finite=False)
    if a.shape == (2, 2):
        a = a[None]
    if a.ndim != 3 or a.shape[1:] != (2, 2) or a.shape[0] not in (1, n):
        raise RotoridError(f"{name} has shape {a.shape}, expected (2, 2) or ({n}, 2, 2) = [point, i, j] over x, y")
    return np.ascontiguousarray(a, dtype=complex)


def series_impedance(z_bearing, z_damper, journal_mass_kg, freq_hz) -> np.ndarray:
    """Equivalent impedance of a bearing film in series with a damper, the damper journal's mass
    between them.

    The journal (rotor) moves x, the damper journal (ring + bearing shell, mass m_j) y; the film
    Z_b acts on x - y, the damper Z_d on y. At w = 2 pi freq_hz

        Z_eq = Z_b - Z_b (Z_b + Z_d - w² m_j I)⁻¹ Z_b,    K = Re Z_eq,  C = Im Z_eq / w

    (:func:`coefficients_of`). Z_eq depends on frequency even where Z_b and Z_d do not: a
    synchronous identification (w = Ω) and an impact one (w ≠ Ω) measure different things.

    Parameters
    ----------
    z_bearing, z_damper : array_like, complex, (n, 2, 2) or (2, 2)
        Impedances K + j w C (- w² M) over (x, y), SI (N/m), per point or one for all.
    journal_mass_kg : float or array_like (n,)
        The damper journal's mass, >= 0.
    freq_hz : array_like (n,)
        Vibration frequency of each point, Hz (>= 0).

    Returns
    -------
    ndarray, complex (n, 2, 2)

    Raises
    ------
    RotoridError
        Shapes, NaN, negative mass or frequency; a point where Z_b + Z_d - w² m_j I is singular
        (an undamped resonance of the damper journal): the frequencies are named.

    Examples
    --------
    >>> import numpy as np, rotorid
    >>> zb = np.diag([3e6, 3e6]).astype(complex)          # a stiff film
    >>> zd = np.diag([1e6, 1e6]).astype(complex)          # a softer damper spring
    >>> z = rotorid.series_impedance(zb, zd, 0.0, [50.0])
    >>> float(z[0, 0, 0].real)                            # springs in series: 3e6 * 1e6 / 4e6
    750000.0
    """
    f = np.atleast_1d(real_array("freq_hz", freq_hz, finite=False))
    if f.ndim != 1 or f.size == 0:
        raise RotoridError(f"freq_hz must be a non-empty 1-D array of frequencies, got shape {f.shape}")
    # 0 <= f <= 1e6 in one pass of the core (NaN is outside); only when that fails the full checks,
    # for the error naming what is wrong
    if _core.first_outside(np.ascontiguousarray(f), _BELOW_ZERO, _ABOVE_MAX_HZ) is not None:
        real_array("freq_hz", freq_hz, nonneg=True)               # NaN, inf or a negative frequency
        raise RotoridError(f"freq_hz up to {f.max():.3g} Hz: beyond 1e6 Hz (a unit error?)")
    n = f.size
    zb, zd = _stack("z_bearing", z_bearing, n), _stack("z_damper", z_damper, n)
    m = np.atleast_1d(real_array("journal_mass_kg", journal_mass_kg, nonneg=True))
    if m.ndim != 1 or m.size not in (1, n):
        raise RotoridError(f"journal_mass_kg must be one mass or one per point ({n}), got shape {m.shape}")
    # w = 2 pi f formed by the core, point by point (no (n,) array)
    z, nbad = _core.series_impedance(zb, zd, np.ascontiguousarray(m), np.ascontiguousarray(f), 2 * np.pi)
    if nbad:
        # a NaN or inf in an impedance makes its points singular in the core: named first, in the
        # words of the finite check (which before the call would scan both inputs every time)
        complex_array("z_bearing", z_bearing)
        complex_array("z_damper", z_damper)
        bad = ~np.isfinite(z).all(axis=(1, 2))
        raise RotoridError(f"Z_b + Z_d - w² m_j I is singular at freq_hz = {f[bad][:5].tolist()}: an undamped "
                           "resonance of the damper journal between film and damper (give the damper some damping)")
    return z


def coefficients_of(z, freq_hz):
    """(K, C) = (Re Z, Im Z / w), each real (n, 2, 2), of impedances Z (n, 2, 2) at freq_hz (> 0).

    Examples
    --------
    >>> import numpy as np
    >>> from rotorid.support.series import coefficients_of
    >>> k, c = coefficients_of(np.array([[[1e6 + 2j * np.pi * 10 * 500, 0], [0, 1e6]]]), [10.0])
    >>> float(k[0, 0, 0]), round(float(c[0, 0, 0]), 9)
    (1000000.0, 500.0)
    """
    f = np.atleast_1d(real_array("freq_hz", freq_hz, positive=True))
    if f.ndim != 1:
        raise RotoridError(f"freq_hz must be a 1-D array of frequencies, got shape {f.shape}")
    if np.any(f < 1e-6):
        raise RotoridError(f"freq_hz down to {f.min():.3g} Hz: C = Im Z / w needs w well above 0 (>= 1e-6 Hz)")
    z = complex_array("z", z)
    if z.ndim != 3 or z.shape[1:] != (2, 2) or z.shape[0] != f.size:
        raise RotoridError(f"z has shape {z.shape}, expected ({f.size}, 2, 2) to match freq_hz")
    return z.real.copy(), z.imag / (2 * np.pi * f)[:, None, None]
