"""Rotor, bearing coefficients and imbalance sets (report section 4, Tables 2-4)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ._validate import finite_scalar, frozen, positive_scalar, real_array
from .errors import RotoridError

#: names of the 16 coefficients in report eq. 9 order
REPORT_ORDER = (
    "Kxx1", "Kxx2", "Kxy1", "Kxy2", "Kyx1", "Kyx2", "Kyy1", "Kyy2",
    "Cxx1", "Cxx2", "Cxy1", "Cxy2", "Cyx1", "Cyx2", "Cyy1", "Cyy2",
)
# eq. 9 order index -> flat index of [bearing, i, j]
_REPORT_TO_BIJ = np.array([0, 4, 1, 5, 2, 6, 3, 7])


@dataclass(frozen=True)
class RigidRotor:
    """Rigid rotor on two bearings (report Fig. 2). SI units: kg, kg·m², m.

    Axial positions are measured from the rotor CG, positive toward bearing 2 (free end):
    bearing 1 at -l1, bearing 2 at +l2; imbalance planes at -d1, +d2 with radii r1, r2; probes at
    -s1, +s2.
    """

    mass_kg: float
    it_kgm2: float
    ip_kgm2: float
    l1: float
    l2: float
    d: tuple = (0.0, 0.0)
    r: tuple = (1.0, 1.0)
    s: tuple = None  # probes; default: at the bearings

    def __post_init__(self):
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731
        set_("mass_kg", positive_scalar("mass_kg", self.mass_kg))
        set_("it_kgm2", positive_scalar("it_kgm2 (transverse inertia)", self.it_kgm2))
        set_("ip_kgm2", positive_scalar("ip_kgm2 (polar inertia)", self.ip_kgm2))
        set_("l1", finite_scalar("l1", self.l1))
        set_("l2", finite_scalar("l2", self.l2))
        if not self.l1 + self.l2 > 0:
            raise RotoridError(f"bearing span l1 + l2 must be > 0, got {self.l1 + self.l2:g} m")
        d = real_array("d (imbalance planes)", self.d, shape=(2,))
        r = real_array("r (imbalance radii)", self.r, shape=(2,), positive=True)
        s = real_array("s (probe positions)", (self.l1, self.l2) if self.s is None else self.s, shape=(2,))
        if abs(s[0] + s[1]) <= 1e-9 * (abs(s[0]) + abs(s[1]) + self.l1 + self.l2):
            raise RotoridError(f"s (probe positions): the two probe planes coincide (s1 = {s[0]:g}, s2 = {s[1]:g} "
                               "give the same axial position -s1 = s2); the tilt cannot be measured")
        set_("d", tuple(map(float, d)))
        set_("r", tuple(map(float, r)))
        set_("s", tuple(map(float, s)))

    d1 = property(lambda self: self.d[0])
    d2 = property(lambda self: self.d[1])
    r1 = property(lambda self: self.r[0])
    r2 = property(lambda self: self.r[1])
    s1 = property(lambda self: self.s[0])
    s2 = property(lambda self: self.s[1])

    @property
    def span(self) -> float:
        return self.l1 + self.l2

    def _plane_matrix(self, to: str) -> np.ndarray:
        """The (2, 2) plane transform of (x1, x2) and of (y1, y2): to ``"bearings"`` from the probe
        planes (report eq. 19) or to ``"probes"`` from the bearings (its inverse). Computed once per
        rotor (a frozen dataclass: its geometry cannot change) and read-only, since the batch
        transforms use it on every call; the public ``*_matrix`` functions hand out copies."""
        cache = self.__dict__.get("_planes")
        if cache is None:
            l1, l2, s1, s2 = self.l1, self.l2, self.s1, self.s2
            # x(z) = x_c + z a with a = (x2 - x1)/L, x_c = (l2 x1 + l1 x2)/L; probes at z = -s1, +s2
            to_probes = np.array([[l2 + s1, l1 - s1], [l2 - s2, l1 + s2]]) / (l1 + l2)
            to_bearings = np.array([[l1 + s2, s1 - l1], [s2 - l2, l2 + s1]]) / (s1 + s2)
            for m in (to_probes, to_bearings):
                m.setflags(write=False)
            cache = {"probes": to_probes, "bearings": to_bearings}
            object.__setattr__(self, "_planes", cache)
        return cache[to]

    def __getstate__(self):
        # the cached arrays are recomputed where the rotor is unpickled (read-only there too)
        return {k: v for k, v in self.__dict__.items() if k not in ("_planes", "_params")}

    def core_params(self) -> np.ndarray:
        """[mass, It, Ip, l1, l2] as the core takes them: made once per rotor (frozen), since every
        identification passes it (0.3 µs per call to build afresh), on an immutable buffer, so
        that it cannot be made writeable and change the rotor behind its fields (copy it to
        change a value)."""
        params = self.__dict__.get("_params")
        if params is None:
            params = frozen(np.array([self.mass_kg, self.it_kgm2, self.ip_kgm2, self.l1, self.l2]))
            object.__setattr__(self, "_params", params)
        return params

    @classmethod
    def from_quantities(cls, *, mass, it, ip, l1, l2, d=(0.0, 0.0), r=(1.0, 1.0), s=None) -> "RigidRotor":
        """A rigid rotor from values with their units (strings such as ``"99.9 lb"``, or numbers in SI).

        Parameters
        ----------
        mass, it, ip : float or str
            Mass, transverse and polar moments of inertia about the CG (``"2405 lb*in**2"``).
        l1, l2 : float or str
            CG to bearing 1 and to bearing 2 (``"7.44 in"``).
        d, r, s : pair of float or str
            Imbalance planes, imbalance radii, probe planes (``s`` None: at the bearings).

        Returns
        -------
        RigidRotor
            In SI, as the constructor makes it (every value parsed by :func:`rotorid.units.quantity`).

        Examples
        --------
        >>> from rotorid import RigidRotor
        >>> rotor = RigidRotor.from_quantities(mass="99.87 lb", it="2405 lb*in**2", ip="1022 lb*in**2",
        ...                                    l1="7.44 in", l2="8.54 in", d=("2.64 in", "4.02 in"),
        ...                                    r=("4.49 in", "3.74 in"), s=(0.119, 0.146))
        >>> round(rotor.mass_kg, 2), round(rotor.it_kgm2, 3), rotor.l1, rotor.s
        (45.3, 0.704, 0.188976, (0.119, 0.146))
        >>> RigidRotor.from_quantities(mass="3 in", it=0.7, ip=0.3, l1=0.19, l2=0.22)
        Traceback (most recent call last):
        ...
        rotorid.errors.RotoridError: mass: '3 in' is a length, expected a mass (kg)
        """
        from .units import quantity

        def pair(name, v):
            if v is None:
                return None
            # a sequence of two (bytes, sets and mappings are not: b"ab" would be 97 m and 98 m)
            if (isinstance(v, (str, bytes, bytearray, set, frozenset, dict)) or not hasattr(v, "__len__")
                    or len(v) != 2):
                raise RotoridError(f"{name} must be a pair of lengths ({name}1, {name}2), got {v!r}"[:300])
            return tuple(quantity(x, "length", f"{name}[{i}]") for i, x in enumerate(v))

        return cls(mass_kg=quantity(mass, "mass", "mass"), it_kgm2=quantity(it, "inertia", "it"),
                   ip_kgm2=quantity(ip, "inertia", "ip"), l1=quantity(l1, "length", "l1"),
                   l2=quantity(l2, "length", "l2"), d=pair("d", d), r=pair("r", r), s=pair("s", s))

    @classmethod
    def from_ross(cls, rotor, bearing_nodes, probe_positions=None, **kwargs) -> "RigidRotor":
        """The rigid rotor of a ROSS rotor (see :func:`rotorid.ross.rigid_rotor_from_ross`; needs ``rotorid[ross]``)."""
        from .ross import rigid_rotor_from_ross

        return rigid_rotor_from_ross(rotor, bearing_nodes, probe_positions, **kwargs)

    def matrices(self, k=None, c=None):
        """M, G (and K, C of eq. 3 when 2x2x2 bearing arrays k, c are given) as NumPy arrays."""
        m, it, ip, l1, l2, L = self.mass_kg, self.it_kgm2, self.ip_kgm2, self.l1, self.l2, self.span
        M = np.array([[m * l2, m * l1, 0, 0], [0, 0, m * l2, m * l1], [-it, it, 0, 0], [0, 0, it, -it]]) / L
        G = np.array([[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, -ip, ip], [-ip, ip, 0, 0]]) / L
        out = [M, G]
        for b in (k, c):
            if b is not None:
                out.append(assemble(np.asarray(b, float), l1, l2))
        return tuple(out)


def assemble(b, l1, l2):
    """4x4 stiffness/damping matrix of eq. 3 from bearing coefficients b[bearing, i, j]."""
    (xx1, xy1), (yx1, yy1) = b[0]
    (xx2, xy2), (yx2, yy2) = b[1]
    return np.array([
        [xx1, xx2, xy1, xy2],
        [yx1, yx2, yy1, yy2],
        [-xx1 * l1, xx2 * l2, -xy1 * l1, xy2 * l2],
        [yx1 * l1, -yx2 * l2, yy1 * l1, -yy2 * l2],
    ])


class BearingCoefficients:
    """Stiffness K (N/m) and damping C (N·s/m) of both bearings, indexed [bearing, i, j], i, j in (x, y).

    Constant: ``k`` and ``c`` of shape (2, 2, 2). Tables: shape (m, 2, 2, 2) together with
    ``speed_rpm`` (synchronous coefficients vs running speed) or ``freq_hz`` (coefficients vs
    vibration frequency); values in between are interpolated linearly, values outside the table
    raise an error.
    """

    def __init__(self, k, c, *, speed_rpm=None, freq_hz=None):
        if speed_rpm is not None and freq_hz is not None:
            raise RotoridError("give a table axis as speed_rpm or as freq_hz, not both")
        axis = speed_rpm if speed_rpm is not None else freq_hz
        self.axis_name = None if axis is None else ("speed_rpm" if speed_rpm is not None else "freq_hz")
        if axis is None:
            self.k = real_array("k", k, shape=(2, 2, 2))
            self.c = real_array("c", c, shape=(2, 2, 2))
            self.axis = None
        else:
            ax = real_array(self.axis_name, axis, ndim=1, positive=True)
            if ax.size < 2 or np.any(np.diff(ax) <= 0):
                raise RotoridError(f"{self.axis_name} of a coefficient table must be strictly increasing with >= 2 points")
            self.k = real_array("k", k, shape=(ax.size, 2, 2, 2))
            self.c = real_array("c", c, shape=(ax.size, 2, 2, 2))
            self.axis = ax

    # -- constructors -----------------------------------------------------------------------
    @classmethod
    def identical(cls, k, c):
        """Both bearings with the same 2x2 K and C."""
        k = real_array("k", k, shape=(2, 2))
        c = real_array("c", c, shape=(2, 2))
        return cls(np.stack([k, k]), np.stack([c, c]))

    @classmethod
    def from_report_vector(cls, p):
        """From the 16 values of report eq. 9 order (K then C: xx1, xx2, xy1, xy2, yx1, yx2, yy1, yy2)."""
        p = real_array("p", p, shape=(16,))
        k = np.empty(8)
        c = np.empty(8)
        k[_REPORT_TO_BIJ] = p[:8]
        c[_REPORT_TO_BIJ] = p[8:]
        return cls(k.reshape(2, 2, 2), c.reshape(2, 2, 2))

    def to_report_vector(self):
        """16 values in report eq. 9 order (constant coefficients only)."""
        if self.axis is not None:
            raise RotoridError("to_report_vector needs constant coefficients")
        return np.concatenate([self.k.reshape(8)[_REPORT_TO_BIJ], self.c.reshape(8)[_REPORT_TO_BIJ]])

    @property
    def is_constant(self):
        return self.axis is None

    def at(self, speed_rpm=None, freq_hz=None):
        """Coefficients at the given speeds or frequencies: (k, c) each of shape (n, 2, 2, 2)."""
        x = speed_rpm if speed_rpm is not None else freq_hz
        n = np.size(x) if x is not None else 1
        if self.axis is None:
            return (np.broadcast_to(self.k, (n, 2, 2, 2)).copy(), np.broadcast_to(self.c, (n, 2, 2, 2)).copy())
        want = "speed_rpm" if speed_rpm is not None else "freq_hz"
        if want != self.axis_name:
            raise RotoridError(f"these coefficients are tabulated over {self.axis_name}, not {want}")
        x = np.atleast_1d(np.asarray(x, float))
        lo, hi = self.axis[0], self.axis[-1]
        if np.any(x < lo * (1 - 1e-12)) or np.any(x > hi * (1 + 1e-12)):
            raise RotoridError(f"{want} outside the coefficient table range [{lo:g}, {hi:g}]")
        flat_k = self.k.reshape(len(self.axis), 8)
        flat_c = self.c.reshape(len(self.axis), 8)
        kk = np.stack([np.interp(x, self.axis, flat_k[:, j]) for j in range(8)], -1).reshape(-1, 2, 2, 2)
        cc = np.stack([np.interp(x, self.axis, flat_c[:, j]) for j in range(8)], -1).reshape(-1, 2, 2, 2)
        return kk, cc

    def __repr__(self):
        if self.axis is None:
            return f"BearingCoefficients(k={self.k.tolist()}, c={self.c.tolist()})"
        return f"BearingCoefficients(table over {self.axis_name}, {self.axis.size} points)"


@dataclass(frozen=True)
class Imbalance:
    """Imbalance masses in the two planes of the rotor (report eq. 5 and Table 3).

    ``angle_deg`` is measured from the keyphasor mark opposite to the direction of rotation, so the
    forcing of plane i is f_i = m_i r_i exp(-j phi_i). Planes and radii belong to the rotor.
    """

    mass_kg: tuple
    angle_deg: tuple = (0.0, 0.0)
    name: str | None = field(default=None, compare=False)

    def __post_init__(self):
        m = real_array("mass_kg", self.mass_kg, shape=(2,), nonneg=True)
        a = real_array("angle_deg", self.angle_deg, shape=(2,))
        object.__setattr__(self, "mass_kg", tuple(map(float, m)))
        object.__setattr__(self, "angle_deg", tuple(map(float, a)))

    def forcing(self, rotor: RigidRotor) -> np.ndarray:
        """(f1, f2) = m_i r_i exp(-j phi_i), kg·m (eq. 5)."""
        return np.array(self._forcing(rotor))

    def generalized(self, rotor: RigidRotor) -> np.ndarray:
        """F_o / Omega^2 of eq. 4 (complex 4-vector, kg·m and kg·m²)."""
        return np.array(self._generalized(rotor))

    def _forcing(self, rotor: RigidRotor) -> tuple:
        """:meth:`forcing` as Python complex numbers (the identification's checks run on a few
        scalars, where NumPy's per-call cost is most of the time)."""
        return tuple(m * r * complex(math.cos(a), -math.sin(a))
                     for m, r, a in zip(self.mass_kg, rotor.r, map(math.radians, self.angle_deg)))

    def _generalized(self, rotor: RigidRotor) -> list:
        """:meth:`generalized` as a list of Python complex numbers."""
        f1, f2 = self._forcing(rotor)
        d1, d2 = rotor.d
        return [f1 + f2, -1j * (f1 + f2), -f1 * d1 + f2 * d2, -1j * (f1 * d1 - f2 * d2)]

    def to_ross(self, *, rotor: RigidRotor, ross_rotor, nodes=None) -> dict:
        """ROSS unbalance arguments, phase convention handled (see :func:`rotorid.ross.imbalance_to_ross`)."""
        from .ross import imbalance_to_ross

        return imbalance_to_ross(self, rotor=rotor, ross_rotor=ross_rotor, nodes=nodes)

    @classmethod
    def from_ross(cls, node, unbalance_magnitude, unbalance_phase, *, rotor: RigidRotor, ross_rotor,
                  name=None) -> "Imbalance":
        """An imbalance from ROSS unbalance arguments (see :func:`rotorid.ross.imbalance_from_ross`)."""
        from .ross import imbalance_from_ross

        return imbalance_from_ross(node, unbalance_magnitude, unbalance_phase, rotor=rotor, ross_rotor=ross_rotor,
                                   name=name)


@dataclass(frozen=True)
class Rig:
    """A rotor with its bearings and named imbalance sets (and impact tests, if any). Flexible
    pedestals are passed where they act (``pedestals=`` of the simulators and the modal analysis),
    not carried here: the studies do not model them yet."""

    rotor: RigidRotor
    bearings: BearingCoefficients
    imbalances: dict
    impacts: dict = field(default_factory=dict)
    name: str = ""


def nsf_rig() -> Rig:
    """The NSF-SFD test rig of the report: Table 2 rotor, Table 4 bearings, Table 3 imbalance sets.

    ``impacts`` holds the Table 6 tests: {name: (plane_m, direction, force_N)}.
    """
    rotor = RigidRotor(mass_kg=45.3, it_kgm2=0.704, ip_kgm2=0.299, l1=0.189, l2=0.217,
                       d=(0.067, 0.102), r=(0.114, 0.095), s=(0.119, 0.146))
    kb = np.array([[3.0e6, 5.0e4], [3.0e4, 3.5e6]])
    cb = np.array([[2000.0, 250.0], [800.0, 2200.0]])
    bearings = BearingCoefficients.identical(kb, cb)
    imb = {  # Table 3, grams -> kg
        "A": Imbalance((3.3e-3, 3.3e-3), (0.0, 0.0), name="A"),
        "B": Imbalance((4.1e-3, 5.1e-3), (90.0, 0.0), name="B"),
        "C": Imbalance((3.3e-3, 4.28e-3), (-90.0, -90.0), name="C"),
        "D": Imbalance((4.1e-3, 5.1e-3), (0.0, 90.0), name="D"),
    }
    impacts = {"A": (0.0, "x", 120.0), "B": (0.0, "y", 100.0)}
    return Rig(rotor=rotor, bearings=bearings, imbalances=imb, impacts=impacts, name="NSF-SFD rig (TRC-RD-1-01)")
