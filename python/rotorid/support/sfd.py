"""Integral squeeze film damper (ISFD) with arc lands: linearized force coefficients about the
centered position (issue 13, item 2).

The damper journal (inner ring) is held centered in its housing by centering springs and squeezes
an oil film of radial clearance ``c`` over one or more arc lands (pads). For small motions (x, y)
of the journal about the center, the reaction force on the journal is

    F = -(K x + C dx/dt + M d2x/dt2),      Z_d(w) = K + j w C - w^2 M

with K the centering springs (the film gives no stiffness at the centered position), C the squeeze
film damping and M the fluid inertia (added mass). Z_d is what the series impedance of the
support takes.

Model (derivation in ``docs/sfd.md``): short-length (open ends, p = 0 at z = +-L/2), isothermal,
laminar, incompressible Reynolds equation for each land with temporal fluid inertia,

    d/dz (h^3 dp/dz) = 12 mu dh/dt + kappa rho h^2 d2h/dt2,   h = c - x cos(theta) - y sin(theta)

with kappa = 12/10 (:data:`TEMPORAL_INERTIA_FACTOR`), integrated over z and over each land's arc:

    C = (mu R L^3 / c^3) * S,    M = kappa rho R L^3 / (12 c) * S = rho R L^3 / (10 c) * S,
    S = sum over lands of  int [[cos^2, cos sin], [sin cos, sin^2]] d theta.

The angle theta runs from +x towards +y. With ``cavitation="pi"`` every land carries half these
coefficients (see :class:`SqueezeFilmDamper`).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from .._validate import choice, flag, index, number, real_array
from ..errors import RotoridError

__all__ = [
    "SqueezeFilmDamper",
    "SFDCoefficients",
    "SFDValidityWarning",
    "nsf_damper",
    "SHORT_LENGTH_MIN_ARC_RATIO",
    "SHORT_LENGTH_MAX_L_OVER_D",
    "INERTIA_RE_LIMIT",
    "INERTIA_NEGLIGIBLE_RE",
    "TEMPORAL_INERTIA_FACTOR",
]

#: smallest ratio (arc length of a land) / (axial length) R * extent / L for which the short-length
#: solution is taken as valid. Where the arc ends of a land sit at a constant (supply) pressure, the
#: exact squeeze film over the b x L rectangle carries 0.84 of the short-length force at ratio 4
#: (0.67 at ratio 1.9, the NSF damper), so the short-length model overpredicts by <~ 19 % above 4.
SHORT_LENGTH_MIN_ARC_RATIO = 4.0
#: largest L / D for the short-length model (the usual short-bearing criterion; D = 2 R).
SHORT_LENGTH_MAX_L_OVER_D = 0.5
#: largest squeeze Reynolds number Re_s = rho w c^2 / mu for the temporal fluid-inertia model
#: (laminar, small Re_s; literature range 10-50, the lower end taken).
INERTIA_RE_LIMIT = 10.0
#: with ``inertia=False``: the Re_s above which the neglected fluid inertia force exceeds 10 % of the
#: viscous damping force (w M / C = Re_s / 10 for the full or any land set).
INERTIA_NEGLIGIBLE_RE = 1.0
#: kappa in d/dz(h^3 dp/dz) = 12 mu h_t + kappa rho h^2 h_tt: 12/10 is the small-Re_s limit of the
#: laminar oscillating flow across the film (parabolic profile); a uniform-profile (bulk-flow
#: momentum) average gives 1.
TEMPORAL_INERTIA_FACTOR = 1.2

_TOL_DEG = 1e-9  # tolerance on land angles (overlap, full circle)


class SFDValidityWarning(UserWarning):
    """A squeeze film damper input outside the validity of the model (short-length approximation,
    fluid-inertia model): the numbers are still computed."""


@dataclass(frozen=True, eq=False)
class SFDCoefficients:
    """Linearized force coefficients of a squeeze film damper at a set of frequencies.

    Attributes
    ----------
    freq_hz : ndarray, shape (n,)
        Vibration frequencies (Hz).
    K : ndarray, shape (n, 2, 2)
        Stiffness (N/m) over (x, y): the centering springs (the centered film adds none).
    C : ndarray, shape (n, 2, 2)
        Squeeze film damping (N s/m).
    M : ndarray, shape (n, 2, 2)
        Fluid inertia, added mass (kg); zero when the damper has ``inertia=False``.
    Re_s : ndarray, shape (n,)
        Squeeze Reynolds number rho w c^2 / mu at each frequency (w = 2 pi f).

    Examples
    --------
    >>> d = SqueezeFilmDamper(radius_m=0.05, clearance_m=2e-4, length_m=0.02,
    ...                       land_arcs_deg=[(0.0, 360.0)], viscosity_pa_s=0.01,
    ...                       spring_stiffness_n_m=1e6)
    >>> co = d.coefficients([0.0, 100.0])
    >>> z = co.impedance()
    >>> z.shape
    (2, 2, 2)
    >>> w = 2 * np.pi * 100.0
    >>> bool(np.isclose(z[1, 0, 0], 1e6 + 1j * w * co.C[1, 0, 0] - w**2 * co.M[1, 0, 0]))
    True
    """

    freq_hz: np.ndarray
    K: np.ndarray
    C: np.ndarray
    M: np.ndarray
    Re_s: np.ndarray

    def impedance(self) -> np.ndarray:
        """Z_d = K + j w C - w^2 M, complex (n, 2, 2) (N/m), w = 2 pi f.

        Returns
        -------
        ndarray of complex, shape (n, 2, 2)
            The damper's dynamic stiffness: force on the journal F = -Z_d X for a motion
            X e^{j w t}.
        """
        w = (2.0 * np.pi * self.freq_hz)[:, None, None]
        return self.K + 1j * w * self.C - w**2 * self.M


def _lands(value):
    """The land arcs as a tuple of (start_deg, extent_deg) floats, checked."""
    if isinstance(value, (str, bytes, dict)) or value is None:
        raise RotoridError(f"land_arcs_deg must be a list of (start_deg, extent_deg) pairs, got {value!r}"[:300])
    if isinstance(value, np.ndarray):
        if value.ndim != 2 or value.shape[1] != 2:
            raise RotoridError(f"land_arcs_deg must have shape (n, 2) [(start_deg, extent_deg) per land], "
                               f"got shape {value.shape}")
        value = value.tolist()
    try:
        items = list(value)
    except TypeError:
        raise RotoridError(f"land_arcs_deg must be a list of (start_deg, extent_deg) pairs, got "
                           f"{type(value).__name__} {value!r}"[:300]) from None
    if not items:
        raise RotoridError("land_arcs_deg is empty: give at least one (start_deg, extent_deg) land")
    out = []
    for i, it in enumerate(items):
        if isinstance(it, (str, bytes, dict)) or not hasattr(it, "__len__") or len(it) != 2:
            raise RotoridError(f"land_arcs_deg[{i}] must be a (start_deg, extent_deg) pair, got {it!r}"[:300])
        s = number(f"land_arcs_deg[{i}] start_deg", it[0])
        e = number(f"land_arcs_deg[{i}] extent_deg", it[1])
        if not e > 0:
            raise RotoridError(f"land_arcs_deg[{i}] extent_deg must be > 0, got {e:g}")
        if e > 360.0 + _TOL_DEG:
            raise RotoridError(f"land_arcs_deg[{i}] extent_deg must be <= 360, got {e:g}")
        out.append((s, e))
    total = sum(e for _, e in out)
    if total > 360.0 + _TOL_DEG:
        raise RotoridError(f"land_arcs_deg: the lands' total extent is {total:g} deg, more than 360 deg")
    order = sorted(range(len(out)), key=lambda k: out[k][0] % 360.0)
    for i, a in enumerate(order):
        if len(order) == 1:
            break
        b = order[(i + 1) % len(order)]
        end_a = out[a][0] % 360.0 + out[a][1]
        start_b = out[b][0] % 360.0 + (360.0 if i == len(order) - 1 else 0.0)
        if end_a > start_b + _TOL_DEG:
            raise RotoridError(f"land_arcs_deg: lands {a} {out[a]} and {b} {out[b]} overlap (land {a} ends at "
                               f"{end_a % 360.0:g} deg, past the start of land {b} at {start_b % 360.0:g} deg)")
    return tuple(out)


def _segments(lands):
    """Arc lengths (deg) of the continuous film segments (touching lands merged); None for a
    full 360 deg ring without arc ends."""
    arcs = sorted(((s % 360.0, e) for s, e in lands))
    segs = []
    for s, e in arcs:
        if segs and abs(segs[-1][0] + segs[-1][1] - s) <= _TOL_DEG:
            segs[-1] = (segs[-1][0], segs[-1][1] + e)
        else:
            segs.append((s, e))
    if len(segs) > 1 and abs(segs[-1][0] + segs[-1][1] - (segs[0][0] + 360.0)) <= _TOL_DEG:
        segs[0] = (segs[-1][0], segs[-1][1] + segs[0][1])
        segs.pop()
    if len(segs) == 1 and segs[0][1] >= 360.0 - _TOL_DEG:
        return None
    return [e for _, e in segs]


def _spring(value):
    """The centering spring stiffness as a 2 x 2 tuple of floats."""
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_)):
        k = number("spring_stiffness_n_m", value, nonneg=True)
        return ((k, 0.0), (0.0, k))
    a = real_array("spring_stiffness_n_m", value)
    if a.ndim == 0:
        k = number("spring_stiffness_n_m", float(a), nonneg=True)
        return ((k, 0.0), (0.0, k))
    if a.shape != (2, 2):
        raise RotoridError(f"spring_stiffness_n_m must be a scalar (N/m) or a 2 x 2 matrix over (x, y), "
                           f"got shape {a.shape}")
    if a[0, 0] < 0 or a[1, 1] < 0:
        raise RotoridError(f"spring_stiffness_n_m: the direct stiffnesses must be >= 0, got "
                           f"kxx = {a[0, 0]:g}, kyy = {a[1, 1]:g}")
    return ((float(a[0, 0]), float(a[0, 1])), (float(a[1, 0]), float(a[1, 1])))


def _arc_matrix(start_deg, extent_deg):
    """int over [t1, t2] of [[cos^2, cos sin], [sin cos, sin^2]] d theta (closed form)."""
    t1 = math.radians(start_deg)
    b = math.radians(extent_deg)
    t2 = t1 + b
    d2 = math.sin(2 * t2) - math.sin(2 * t1)
    cs = 0.5 * (math.sin(t2) ** 2 - math.sin(t1) ** 2)
    return np.array([[0.5 * b + 0.25 * d2, cs], [cs, 0.5 * b - 0.25 * d2]])


@dataclass(frozen=True)
class SqueezeFilmDamper:
    """An integral squeeze film damper with arc lands, centered by springs; short-length
    (open-ends) linearized model about the centered position.

    Parameters
    ----------
    radius_m : float
        Land (journal) radius R (m), > 0.
    clearance_m : float
        Radial clearance c of the lands (m), > 0 (the clearance at the centered position).
    length_m : float
        Axial film length L (m), > 0. Both ends are open to ambient (p = 0 at z = +-L/2).
    land_arcs_deg : sequence of (start_deg, extent_deg)
        One pair per land: the arc from ``start_deg`` to ``start_deg + extent_deg``, angles from
        +x towards +y (deg). Extents > 0, total <= 360, no overlaps (touching lands are allowed and
        form one continuous film). ``[(0, 360)]`` is a conventional full-ring damper. See also
        :meth:`equal_lands`.
    viscosity_pa_s : float
        Dynamic viscosity mu (Pa s), > 0.
    spring_stiffness_n_m : float or array_like (2, 2)
        Centering spring stiffness (N/m): a scalar (isotropic) >= 0 or a 2 x 2 matrix over (x, y).
    density_kg_m3 : float, default 850.0
        Lubricant density rho (kg/m^3), >= 0, for the fluid inertia and Re_s.
    cavitation : {"none", "pi"}, default "none"
        ``"none"``: full film over every land (the pressure may go below ambient, e.g. an
        oil-fed damper whose supply pressure exceeds the dynamic pressure). ``"pi"``: the film is
        taken as wetted only where the linear film pressure (squeeze + inertia) is positive; the
        rest of the land holds ambient pressure (Guembel / half-Sommerfeld condition). In the
        short-length model the pressure at each angle depends on the local squeeze only, so for
        any small harmonic motion every point of a land is wetted during half of each period, and
        the first harmonic of the rectified force is exactly half the full-film force at every
        angle: the linearized C and M are half the full-film values over each land's whole arc.
        This is an approximation: it drops the mean force and the higher harmonics the rectified
        pressure produces (nonzero on arc lands), and ignores gas/vapor cavity dynamics and air
        ingestion.
    inertia : bool, default True
        Include temporal fluid inertia (added mass M); False gives M = 0.

    Warns
    -----
    SFDValidityWarning
        When a land's arc length R * extent is less than :data:`SHORT_LENGTH_MIN_ARC_RATIO` times
        L, or L / D > :data:`SHORT_LENGTH_MAX_L_OVER_D` (short-length approximation).

    Raises
    ------
    RotoridError
        Bad input: non-positive radius, clearance, length or viscosity, negative density,
        overlapping lands or more than 360 deg in total, extents <= 0, NaN, wrong types.

    Notes
    -----
    Film coefficients (derivation in ``docs/sfd.md``)::

        C = (mu R L^3 / c^3) S        M = rho R L^3 / (10 c) S   (kappa = 12/10)
        S = sum over lands of int [[cos^2, cos sin], [sin cos, sin^2]] d theta

    halved for ``cavitation="pi"``. A full 360 deg film gives C = pi mu R L^3 / c^3 and
    M = pi rho R L^3 / (10 c) per axis, with zero cross terms.

    Examples
    --------
    A conventional full-ring damper (R = 50 mm, c = 0.2 mm, L = 20 mm, 10 cP):

    >>> d = SqueezeFilmDamper(radius_m=0.05, clearance_m=2e-4, length_m=0.02,
    ...                       land_arcs_deg=[(0.0, 360.0)], viscosity_pa_s=0.01,
    ...                       spring_stiffness_n_m=1e6)
    >>> co = d.coefficients(100.0)
    >>> round(float(co.C[0, 0, 0]), 1), round(float(co.C[0, 0, 1]), 9)
    (1570.8, 0.0)
    >>> round(float(co.M[0, 0, 0]), 4), round(float(co.Re_s[0]), 3)
    (0.5341, 2.136)
    >>> z = d.impedance([50.0, 100.0])
    >>> z.shape, z.dtype
    ((2, 2, 2), dtype('complex128'))
    """

    radius_m: float
    clearance_m: float
    length_m: float
    land_arcs_deg: tuple
    viscosity_pa_s: float
    spring_stiffness_n_m: object
    density_kg_m3: float = 850.0
    cavitation: str = "none"
    inertia: bool = True

    def __post_init__(self):
        for name in ("radius_m", "clearance_m", "length_m", "viscosity_pa_s", "density_kg_m3"):
            v = number(name, getattr(self, name), positive=name != "density_kg_m3", nonneg=True)
            lo, hi, unit = _RANGES[name]
            if not (lo <= v <= hi) and not (name == "density_kg_m3" and v == 0.0):
                raise RotoridError(f"{name} = {v:g} {unit} is outside {lo:g} to {hi:g} {unit}: not a squeeze film "
                                   "damper (a unit error?)")
            object.__setattr__(self, name, v)
        object.__setattr__(self, "land_arcs_deg", _lands(self.land_arcs_deg))
        object.__setattr__(self, "spring_stiffness_n_m", _spring(self.spring_stiffness_n_m))
        choice("cavitation", self.cavitation, ("none", "pi"))
        object.__setattr__(self, "inertia", flag("inertia", self.inertia))
        if self.clearance_m >= self.radius_m:
            raise RotoridError(f"clearance_m ({self.clearance_m:g} m) must be much smaller than radius_m "
                               f"({self.radius_m:g} m): a thin film is assumed")
        self._check_short_length()

    # -- validity ----------------------------------------------------------------------------
    def _check_short_length(self):
        R, L = self.radius_m, self.length_m
        if L / (2.0 * R) > SHORT_LENGTH_MAX_L_OVER_D:
            warnings.warn(f"short-length approximation: L/D = {L / (2 * R):.3g} exceeds "
                          f"SHORT_LENGTH_MAX_L_OVER_D = {SHORT_LENGTH_MAX_L_OVER_D:g}; the open-ends "
                          "short-length coefficients overpredict the film forces", SFDValidityWarning,
                          stacklevel=4)
        segs = _segments(self.land_arcs_deg)
        if segs is None:
            return
        ratio = min(R * math.radians(e) / L for e in segs)
        if ratio < SHORT_LENGTH_MIN_ARC_RATIO:
            e = min(segs)
            warnings.warn(f"short-length approximation: land arc length R*extent = {R * math.radians(e) * 1e3:.3g} mm "
                          f"is only {ratio:.3g} times the axial length L = {L * 1e3:.3g} mm (below "
                          f"SHORT_LENGTH_MIN_ARC_RATIO = {SHORT_LENGTH_MIN_ARC_RATIO:g}); circumferential flow "
                          "out of the land's arc ends is neglected, so C and M are overpredicted if the arc "
                          "ends sit at a constant pressure", SFDValidityWarning, stacklevel=4)

    # -- constructors ------------------------------------------------------------------------
    @classmethod
    def equal_lands(cls, n, extent_deg, *, first_center_deg=0.0, **params) -> "SqueezeFilmDamper":
        """A damper with ``n`` equal lands of ``extent_deg`` each, equally spaced.

        Parameters
        ----------
        n : int
            Number of lands, >= 1.
        extent_deg : float
            Arc extent of each land (deg), > 0, with n * extent_deg <= 360.
        first_center_deg : float, default 0.0
            Angle of the first land's center (deg, from +x towards +y); land k is centered at
            ``first_center_deg + 360 k / n``.
        **params
            The other fields of :class:`SqueezeFilmDamper` (radius_m, clearance_m, length_m,
            viscosity_pa_s, spring_stiffness_n_m, density_kg_m3, cavitation, inertia).

        Returns
        -------
        SqueezeFilmDamper

        Examples
        --------
        >>> d = SqueezeFilmDamper.equal_lands(4, 60.0, radius_m=0.05, clearance_m=2e-4,
        ...                                   length_m=0.01, viscosity_pa_s=0.01,
        ...                                   spring_stiffness_n_m=2e6)
        >>> d.land_arcs_deg
        ((-30.0, 60.0), (60.0, 60.0), (150.0, 60.0), (240.0, 60.0))
        >>> c = d.damping_matrix()
        >>> bool(np.isclose(c[0, 0], c[1, 1])), bool(abs(c[0, 1]) < 1e-9 * c[0, 0])
        (True, True)
        """
        n = index("n", n, 1)
        extent = number("extent_deg", extent_deg, positive=True)
        c0 = number("first_center_deg", first_center_deg)
        if n * extent > 360.0 + _TOL_DEG:
            raise RotoridError(f"equal_lands: {n} lands of extent_deg = {extent:g} make {n * extent:g} deg, "
                               "more than 360 deg")
        if "land_arcs_deg" in params:
            raise RotoridError("equal_lands builds land_arcs_deg itself: do not pass it")
        lands = [(c0 + 360.0 * k / n - 0.5 * extent, extent) for k in range(n)]
        return cls(land_arcs_deg=lands, **params)

    # -- coefficients ------------------------------------------------------------------------
    def _shape_matrix(self) -> np.ndarray:
        """S = sum over lands of int n n^T d theta, times 1/2 for the pi film."""
        s = sum(_arc_matrix(a, e) for a, e in self.land_arcs_deg)
        s[np.abs(s) < 1e-13 * np.trace(s)] = 0.0  # rounding of cancelling arcs (symmetric land sets)
        return 0.5 * s if self.cavitation == "pi" else s

    def stiffness_matrix(self) -> np.ndarray:
        """K (2, 2) (N/m): the centering springs (the centered film adds no stiffness).

        Examples
        --------
        >>> d = SqueezeFilmDamper(0.05, 2e-4, 0.02, [(0, 360)], 0.01, [[1e6, 0.0], [0.0, 2e6]])
        >>> d.stiffness_matrix().tolist()
        [[1000000.0, 0.0], [0.0, 2000000.0]]
        """
        return np.array(self.spring_stiffness_n_m, dtype=float)

    def damping_matrix(self) -> np.ndarray:
        """C (2, 2) (N s/m): squeeze film damping, (mu R L^3 / c^3) S.

        Examples
        --------
        >>> d = SqueezeFilmDamper(0.05, 2e-4, 0.02, [(0, 360)], 0.01, 1e6, cavitation="pi")
        >>> round(float(d.damping_matrix()[1, 1]), 1)   # half of pi mu R L^3 / c^3
        785.4
        """
        k = self.viscosity_pa_s * self.radius_m * self.length_m**3 / self.clearance_m**3
        return k * self._shape_matrix()

    def added_mass_matrix(self) -> np.ndarray:
        """M (2, 2) (kg): fluid inertia, kappa rho R L^3 / (12 c) S with kappa = 12/10; zero
        without inertia.

        Examples
        --------
        >>> d = SqueezeFilmDamper(0.05, 2e-4, 0.02, [(0, 360)], 0.01, 1e6)
        >>> round(float(d.added_mass_matrix()[0, 0]), 4)   # pi rho R L^3 / (10 c)
        0.5341
        >>> SqueezeFilmDamper(0.05, 2e-4, 0.02, [(0, 360)], 0.01, 1e6,
        ...                   inertia=False).added_mass_matrix().tolist()
        [[0.0, 0.0], [0.0, 0.0]]
        """
        if not self.inertia:
            return np.zeros((2, 2))
        k = TEMPORAL_INERTIA_FACTOR * self.density_kg_m3 * self.radius_m * self.length_m**3 / (12.0 * self.clearance_m)
        return k * self._shape_matrix()

    def squeeze_reynolds(self, freq_hz) -> np.ndarray:
        """Squeeze Reynolds number Re_s = rho w c^2 / mu, w = 2 pi f, at each frequency.

        Parameters
        ----------
        freq_hz : float or array_like (n,)
            Frequencies (Hz), finite and >= 0.

        Returns
        -------
        ndarray, shape (n,)

        Examples
        --------
        >>> d = SqueezeFilmDamper(0.05, 2e-4, 0.02, [(0, 360)], 0.01, 1e6)
        >>> np.round(d.squeeze_reynolds([0.0, 100.0]), 3).tolist()
        [0.0, 2.136]
        """
        f = _freqs(freq_hz)
        return self.density_kg_m3 * 2.0 * np.pi * f * self.clearance_m**2 / self.viscosity_pa_s

    def coefficients(self, freq_hz) -> SFDCoefficients:
        """Linearized force coefficients at the centered position at each frequency.

        Parameters
        ----------
        freq_hz : float or array_like (n,)
            Vibration frequencies (Hz), finite and >= 0.

        Returns
        -------
        SFDCoefficients
            K, C, M (n, 2, 2) and Re_s (n,). The model's C and M do not depend on frequency;
            they are repeated so that they line up with frequency-dependent bearing tables.

        Warns
        -----
        SFDValidityWarning
            With ``inertia=True``, when Re_s exceeds :data:`INERTIA_RE_LIMIT` at some frequency;
            with ``inertia=False``, when Re_s exceeds :data:`INERTIA_NEGLIGIBLE_RE` (the
            neglected inertia force is then more than 10 % of the damping force).

        Examples
        --------
        >>> d = SqueezeFilmDamper(0.05, 2e-4, 0.02, [(0, 360)], 0.01, 1e6)
        >>> co = d.coefficients([10.0, 20.0, 30.0])
        >>> co.K.shape, co.C.shape, co.M.shape, co.Re_s.shape
        ((3, 2, 2), (3, 2, 2), (3, 2, 2), (3,))
        """
        f = _freqs(freq_hz)
        re = self.squeeze_reynolds(f)
        if f.size:
            k = int(np.argmax(re))
            if self.inertia and re[k] > INERTIA_RE_LIMIT:
                warnings.warn(f"fluid inertia model: squeeze Reynolds number Re_s = {re[k]:.3g} at {f[k]:g} Hz "
                              f"exceeds INERTIA_RE_LIMIT = {INERTIA_RE_LIMIT:g} (laminar, small-Re_s temporal "
                              "inertia model); the added mass and damping are uncertain there",
                              SFDValidityWarning, stacklevel=2)
            elif not self.inertia and re[k] > INERTIA_NEGLIGIBLE_RE:
                warnings.warn(f"fluid inertia neglected (inertia=False) but the squeeze Reynolds number "
                              f"Re_s = {re[k]:.3g} at {f[k]:g} Hz exceeds INERTIA_NEGLIGIBLE_RE = "
                              f"{INERTIA_NEGLIGIBLE_RE:g}: the inertia force is {re[k] / 10:.0%} of the damping "
                              "force; consider inertia=True", SFDValidityWarning, stacklevel=2)
        n = f.size
        rep = lambda m: np.repeat(m[None, :, :], n, axis=0)  # noqa: E731
        return SFDCoefficients(freq_hz=f, K=rep(self.stiffness_matrix()), C=rep(self.damping_matrix()),
                               M=rep(self.added_mass_matrix()), Re_s=re)

    def impedance(self, freq_hz) -> np.ndarray:
        """The damper's impedance Z_d = K + j w C - w^2 M (N/m), w = 2 pi f.

        Parameters
        ----------
        freq_hz : float or array_like (n,)
            Vibration frequencies (Hz), finite and >= 0.

        Returns
        -------
        ndarray of complex, shape (n, 2, 2)
            What the series impedance takes as the damper (Z_d).

        Examples
        --------
        >>> d = SqueezeFilmDamper(0.05, 2e-4, 0.02, [(0, 360)], 0.01, 1e6, inertia=False)
        >>> z = d.impedance(0.0)
        >>> z[0].real.tolist(), z[0].imag.tolist()
        ([[1000000.0, 0.0], [0.0, 1000000.0]], [[0.0, 0.0], [0.0, 0.0]])
        """
        return self.coefficients(freq_hz).impedance()


#: physical ranges of the damper's parameters (beyond them the numbers overflow or are a unit error)
_RANGES = {"radius_m": (1e-4, 10.0, "m"), "clearance_m": (1e-7, 0.1, "m"), "length_m": (1e-4, 10.0, "m"),
           "viscosity_pa_s": (1e-6, 1e3, "Pa s"), "density_kg_m3": (1.0, 1e5, "kg/m^3")}
#: highest frequency the models accept (Hz): far above any rotor vibration, far from overflow
MAX_FREQ_HZ = 1e6


def _freqs(freq_hz) -> np.ndarray:
    f = real_array("freq_hz", freq_hz, nonneg=True)
    if np.any(f > MAX_FREQ_HZ):
        raise RotoridError(f"freq_hz up to {np.max(f):.3g} Hz: above {MAX_FREQ_HZ:g} Hz (a unit error?)")
    if f.ndim > 1:
        raise RotoridError(f"freq_hz must be a scalar or a 1-D array, got shape {f.shape}")
    f = np.atleast_1d(f).astype(float)
    if f.size == 0:
        raise RotoridError("freq_hz is empty")
    return f


def nsf_damper(*, spring_stiffness_n_m, viscosity_pa_s=15.76e-3, density_kg_m3=850.0, cavitation="none",
               inertia=True, first_center_deg=0.0) -> SqueezeFilmDamper:
    """The integral squeeze film damper of the NSF-SFD rig (report TRC-RD-1-01, Table 1).

    Four arc lands of 52 deg, land radius R = 48.26 mm, radial clearance c = 0.229 mm (after
    the static deflection under the rotor weight, i.e. centered), axial length L = 23.0 mm, both
    ends open; ISO VG 10 at 15.76 cP (24.4 deg C).

    Parameters
    ----------
    spring_stiffness_n_m : float or array_like (2, 2)
        Required: the centering (S-spring) stiffness (N/m). The report gives no value (it only
        says the tilting-pad film is 3.5-4.5 times stiffer at ~3,000 rpm); measure it or take it
        from the manufacturer. No default on purpose.
    viscosity_pa_s : float, default 15.76e-3
        Table 1's average inlet viscosity.
    density_kg_m3 : float, default 850.0
        ISO VG 10 density (not given in the report; a typical value).
    cavitation : {"none", "pi"}, default "none"
    inertia : bool, default True
    first_center_deg : float, default 0.0
        Center angle of the first land: not stated in the report text, and immaterial for the
        coefficients (four equally spaced lands give isotropic C and M).

    Returns
    -------
    SqueezeFilmDamper

    Warns
    -----
    SFDValidityWarning
        Always: the lands' arc length R * 52 deg = 43.8 mm is only 1.9 times L = 23 mm, below
        :data:`SHORT_LENGTH_MIN_ARC_RATIO`; the short-length coefficients are marginal for this
        damper (see ``docs/sfd.md``).

    Examples
    --------
    >>> import warnings
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore", SFDValidityWarning)
    ...     d = nsf_damper(spring_stiffness_n_m=4.0e6)   # illustrative spring stiffness
    >>> co = d.coefficients([50.0, 150.0])
    >>> round(float(co.C[0, 0, 0]), 1), round(float(co.C[0, 1, 1]), 1)
    (1398.7, 1398.7)
    >>> round(float(co.M[0, 0, 0]), 4)
    0.3956
    >>> np.round(co.Re_s, 3).tolist()
    [0.889, 2.666]
    """
    return SqueezeFilmDamper.equal_lands(
        4, 52.0, first_center_deg=first_center_deg, radius_m=48.26e-3, clearance_m=0.229e-3, length_m=23.0e-3,
        viscosity_pa_s=viscosity_pa_s, spring_stiffness_n_m=spring_stiffness_n_m, density_kg_m3=density_kg_m3,
        cavitation=cavitation, inertia=inertia)
