"""Units at the edges (config files, lab files, the API, the written tables). Inside rotorid
everything is SI.

Two tools, each where it is safest (docs/units.md):

- **Lab-file channel units** (``[channels] unit``, 1X table units, :func:`factor`, :func:`to_si`,
  :func:`from_si`) come from a small explicit table. Lab files write units in any case (``MIL``,
  ``G``, ``V``), which a general unit library cannot take safely (in pint ``G`` is the gauss and
  ``g`` the gram); the table matches case-insensitively except where case means milli or mega
  (``mV``, ``mN/m``, ``MN/m``), and refuses what it does not know.
- **Quantity strings** given by a user (``"68 lb"``, ``"12.5 in"``, ``"0.45 lb*in**2"``,
  ``"3000 rpm"``, ``"2.1 klbf/in"``) are parsed by pint (:func:`quantity`): any unit expression,
  case-sensitive (``mN/m`` is not ``MN/m``), with ``mil`` = 0.001 in (pint's own ``mil`` is an
  angle). pint is imported the first time a quantity string is parsed, never by ``import rotorid``.

:class:`OutputUnits` says how results are written: SI or US customary, amplitudes 0-pk or pk-pk,
phase as lag or as arg.
"""

from __future__ import annotations

import re

from .errors import RotoridError

# unit name (lower case, as written in lab files) -> (quantity, factor to SI)
_UNITS = {
    # displacement -> m
    "m": ("length", 1.0), "mm": ("length", 1e-3), "um": ("length", 1e-6), "µm": ("length", 1e-6),
    "μm": ("length", 1e-6),  # Greek mu (U+03BC) as well as the micro sign (U+00B5)
    "micron": ("length", 1e-6), "microns": ("length", 1e-6), "in": ("length", 0.0254),
    "mil": ("length", 25.4e-6), "mils": ("length", 25.4e-6),
    # force -> N
    "n": ("force", 1.0), "kn": ("force", 1e3), "lbf": ("force", 4.4482216152605), "klbf": ("force", 4448.2216152605),
    # acceleration -> m/s^2
    "m/s^2": ("acceleration", 1.0), "m/s2": ("acceleration", 1.0), "g": ("acceleration", 9.80665),
    # voltage (keyphasor) -> V ("Volts" is what NI DAQmx and LabVIEW write)
    "v": ("voltage", 1.0), "volt": ("voltage", 1.0), "volts": ("voltage", 1.0),
    "millivolt": ("voltage", 1e-3), "millivolts": ("voltage", 1e-3),
    # spelled-out names other DAQ software writes
    "meter": ("length", 1.0), "meters": ("length", 1.0), "metre": ("length", 1.0), "metres": ("length", 1.0),
    "millimeter": ("length", 1e-3), "millimeters": ("length", 1e-3), "millimetre": ("length", 1e-3),
    "millimetres": ("length", 1e-3), "micrometer": ("length", 1e-6), "micrometers": ("length", 1e-6),
    "micrometre": ("length", 1e-6), "micrometres": ("length", 1e-6), "inch": ("length", 0.0254),
    "inches": ("length", 0.0254), "newton": ("force", 1.0), "newtons": ("force", 1.0),
    # mass -> kg
    "kg": ("mass", 1.0), "g_mass": ("mass", 1e-3), "gram": ("mass", 1e-3), "grams": ("mass", 1e-3),
    "oz": ("mass", 0.028349523125), "lb": ("mass", 0.45359237),
    # stiffness -> N/m, damping -> N s/m
    "n/m": ("stiffness", 1.0), "kn/m": ("stiffness", 1e3), "n/mm": ("stiffness", 1e3), "n/um": ("stiffness", 1e6),
    "lbf/in": ("stiffness", 4.4482216152605 / 0.0254), "klbf/in": ("stiffness", 4448.2216152605 / 0.0254),
    "n*s/m": ("damping", 1.0), "n.s/m": ("damping", 1.0), "ns/m": ("damping", 1.0), "n·s/m": ("damping", 1.0),
    "n-s/m": ("damping", 1.0), "kn*s/m": ("damping", 1e3), "kn·s/m": ("damping", 1e3),
    "lbf*s/in": ("damping", 4.4482216152605 / 0.0254), "lbf.s/in": ("damping", 4.4482216152605 / 0.0254),
    "lbf-s/in": ("damping", 4.4482216152605 / 0.0254), "lbf·s/in": ("damping", 4.4482216152605 / 0.0254),
    # speed
    "rpm": ("speed", 3.141592653589793 / 30), "rad/s": ("speed", 1.0), "hz": ("frequency", 1.0),
}

# units whose letter case carries meaning (milli vs mega): matched exactly as written
_CASED = {"mV": ("voltage", 1e-3), "MN/m": ("stiffness", 1e6), "mN/m": ("stiffness", 1e-3),
          "MN*s/m": ("damping", 1e6), "kN*s/m": ("damping", 1e3)}
_CASED_LOWER = {k.lower() for k in _CASED}

SI_UNIT = {"length": "m", "force": "N", "acceleration": "m/s^2", "voltage": "V", "mass": "kg",
           "stiffness": "N/m", "damping": "N*s/m", "speed": "rad/s", "frequency": "Hz"}


def factor(unit: str, quantity: str | None = None) -> float:
    """Factor that converts a value in ``unit`` to SI; checks the quantity when given."""
    from ._validate import text

    quantity = text("quantity", quantity, allow_none=True)
    q, f = _lookup(unit)
    if quantity is not None and q != quantity:
        def an(w):
            return f"{'an' if w[:1] in 'aeiou' else 'a'} {w}"
        raise RotoridError(f"unit {unit!r} is {an(q)}, expected {an(quantity)}")
    return f


def to_si(value, unit: str, quantity: str | None = None):
    """``value`` (a number, an array or a pandas Series, in ``unit``) in SI; NaN stays NaN."""
    return _real(value) * factor(unit, quantity)


def from_si(value, unit: str, quantity: str | None = None):
    """``value`` (a number, an array or a pandas Series, in SI) in ``unit``; NaN stays NaN."""
    return _real(value) / factor(unit, quantity)


def _real(value):
    """``value`` checked to be real numbers (NaN allowed): itself, or as an array when it is a list."""
    from ._validate import real_array

    a = real_array("value", value, finite=False)
    return a if isinstance(value, (list, tuple)) else value


def _lookup(unit) -> tuple:
    """(quantity, factor) of a unit name: the case-carrying ones (mV, MN/m, mN/m) exactly as
    written, the others in any case; spaces are ignored."""
    raw = str(unit).strip().replace(" ", "")
    if raw in _CASED:
        return _CASED[raw]
    key = raw.lower()
    if key in _CASED_LOWER:
        options = sorted(k for k in _CASED if k.lower() == key)
        raise RotoridError(f"unit {unit!r}: the letter case matters here (milli or mega?); write one of "
                           f"{', '.join(options)}")
    if key not in _UNITS:
        raise RotoridError(f"unknown unit {unit!r}; known: {sorted(set(_UNITS) | set(_CASED))}")
    return _UNITS[key]


def quantity_of(unit: str) -> str:
    return _lookup(unit)[0]


# =============================================================================================
# quantity strings, through pint (imported on first use)

#: dimension name -> SI unit (the value :func:`quantity` returns is in this unit)
DIMENSIONS = {
    "length": "m", "mass": "kg", "inertia": "kg*m**2", "force": "N", "stiffness": "N/m", "damping": "N*s/m",
    "speed": "rad/s", "frequency": "Hz", "time": "s", "acceleration": "m/s**2", "voltage": "V",
    "imbalance": "kg*m",
}
#: how a dimension reads in a message
_DIMENSION_TEXT = {"inertia": "a moment of inertia", "imbalance": "an imbalance (mass x radius)",
                   "speed": "a rotational speed", "acceleration": "an acceleration"}
_DIMENSION_ALIASES = {"moment of inertia": "inertia", "unbalance": "imbalance", "angular speed": "speed"}

_REGISTRY = None
# pint's ``mil`` is an angle (pi/32000 rad); a lab's mil is 0.001 in: the word is read as ``thou``
# before pint sees it (a registry cannot redefine a unit once its cache is built)
_MIL_WORD = None


def registry():
    """rotorid's pint UnitRegistry (created once, on first use; ``mil`` = 0.001 in).

    Returns
    -------
    pint.UnitRegistry

    Examples
    --------
    >>> from rotorid.units import registry
    >>> ureg = registry()
    >>> str(ureg.parse_expression("2 mil").to("um"))
    '50.8 micrometer'
    """
    global _REGISTRY, _MIL_WORD
    if _REGISTRY is None:
        import pint

        _MIL_WORD = re.compile(r"(?<![A-Za-z_])mils?(?![A-Za-z0-9_])")
        ureg = pint.UnitRegistry(preprocessors=[_preprocess])
        for name, definition in (("rev", "rev = revolution"), ("lbm", "lbm = pound"), ("cpm", "cpm = cycle / minute"),
                                 ("microns", "microns = micrometer")):
            if name not in ureg:
                ureg.define(definition)
        _REGISTRY = ureg
    return _REGISTRY


def _preprocess(text: str) -> str:
    """Spellings pint does not take as written: mil(s) (0.001 in), middle dots, superscripts."""
    for dot in ("·", "⋅", "×"):
        text = text.replace(dot, "*")
    text = text.replace("²", "**2").replace("³", "**3")
    return _MIL_WORD.sub("thou", text)


def _dimension(dimension) -> str:
    if isinstance(dimension, str):
        d = _DIMENSION_ALIASES.get(dimension.strip().lower(), dimension.strip().lower())
        if d in DIMENSIONS:
            return d
    raise RotoridError(f"dimension must be one of {', '.join(DIMENSIONS)}, got {dimension!r}")


def _dim_text(d: str) -> str:
    return _DIMENSION_TEXT.get(d, f"a {d}")


def _what(q) -> str:
    """'a length', 'a speed or a frequency', or pint's dimensionality, of a parsed quantity."""
    ureg = registry()
    dim = q.dimensionality
    if not dim:
        return "a plain number (dimensionless)"
    names = [d for d, si in DIMENSIONS.items() if ureg.get_dimensionality(si) == dim]
    if set(names) == {"speed", "frequency"}:
        return "a speed or a frequency"
    if names:
        return _dim_text(names[0])
    return f"of dimension {dim}"


def _to_si_float(value, dimension: str) -> float:
    """``value`` (a number in SI, a quantity string or a pint Quantity) in the SI unit of
    ``dimension``; RotoridError (without a name) when it cannot be."""
    d = _dimension(dimension)
    if isinstance(value, bool):
        raise RotoridError(f"must be a number (in {DIMENSIONS[d]}) or a string with a unit, got {value!r}")
    import numbers

    if hasattr(value, "magnitude") and hasattr(value, "units") and not isinstance(value, str):
        # a pint Quantity (of any registry): its magnitude as a float (a numpy scalar's repr,
        # np.float64(2.0), is no number to pint), its unit as pint writes it
        import decimal

        import numpy as np

        mag = value.magnitude
        if isinstance(mag, (bool, np.bool_)) or not isinstance(mag, (numbers.Real, decimal.Decimal)):
            raise RotoridError(f"must be a single real value with its unit, got a quantity of {type(mag).__name__} "
                               f"{mag!r}"[:300])
        try:
            value = f"{float(mag)!r} {value.units}"
        except OverflowError:
            raise RotoridError(f"must be finite, got {value!r}"[:300]) from None
    if not isinstance(value, str):
        if not isinstance(value, numbers.Real):
            raise RotoridError(f"must be a number (in {DIMENSIONS[d]}) or a string with a unit (e.g. "
                               f"{_EXAMPLE[d]!r}), got {type(value).__name__} {value!r}"[:300])
        try:
            x = float(value)
        except OverflowError:   # an int beyond the float range (10**400)
            x = float("inf") if value > 0 else float("-inf")
        if x != x or x in (float("inf"), float("-inf")):
            raise RotoridError(f"must be finite, got {x}")
        return x
    return _parse(value, d)


_EXAMPLE = {"length": "12.5 in", "mass": "68 lb", "inertia": "0.45 lb*in**2", "force": "20 lbf",
            "stiffness": "2.1 klbf/in", "damping": "12 lbf*s/in", "speed": "3000 rpm", "frequency": "50 Hz",
            "time": "20 ms", "acceleration": "0.5 g0", "voltage": "24 V", "imbalance": "2.5 oz*in"}


#: powers that pint would evaluate for ever (9**9**9): chained, or an exponent of 3 digits or more
_HUGE_POWER = re.compile(r"(\*\*|\^)[^*^]*(\*\*|\^)|(\*\*|\^)\s*\(?\s*[-+]?\d{3,}")


def _parse(text: str, d: str) -> float:
    import math

    import pint

    shown = text if len(text) <= 60 else text[:57] + "..."
    if not text.strip():
        raise RotoridError(f"is an empty string (write a number and a unit, e.g. {_EXAMPLE[d]!r})")
    if "," in text:   # pint drops it: "1,5 in" would be 15 in, "1, 5 in" 5 in
        raise RotoridError(f"cannot be read as a quantity: {shown!r} has a comma (write the decimal point as '.', "
                           f"and no thousands separators, e.g. {_EXAMPLE[d]!r})")
    if len(text) > 200 or _HUGE_POWER.search(text):
        raise RotoridError(f"cannot be read as a quantity: {shown!r} (too long, or a power too large: write a number "
                           f"and a unit, e.g. {_EXAMPLE[d]!r})")
    ureg = registry()
    try:
        q = ureg.parse_expression(text.strip())
    except pint.UndefinedUnitError as exc:
        names = [n for n in getattr(exc, "unit_names", ()) or ()] or [str(exc)]
        bad = names[0] if isinstance(names, (list, tuple)) else names
        variants = (bad.lower(), bad.upper(), bad[:1].lower() + bad[1:].upper(), bad[:1].upper() + bad[1:].lower(),
                    bad[:1].lower() + bad[1:], bad[:1].upper() + bad[1:])
        cands = [c for c in dict.fromkeys(variants) if c != bad and c in ureg and _fits(text, bad, c, d)]
        hint = ""
        if len(cands) == 1:
            hint = f" (units are case-sensitive: did you mean {cands[0]!r}?)"
        elif cands:
            hint = (f" (units are case-sensitive: did you mean {' or '.join(map(repr, cands))}? the letter "
                    "case says milli or mega)")
        raise RotoridError(f"has an unknown unit {bad!r} in {shown!r}{hint}") from None
    except pint.DimensionalityError:
        raise RotoridError(f"cannot be read: {shown!r} adds quantities of different dimensions") from None
    except Exception:  # noqa: BLE001 - pint's tokenizer and parser raise many kinds
        raise RotoridError(f"cannot be read as a quantity: {shown!r} (write a number and a unit, e.g. "
                           f"{_EXAMPLE[d]!r})") from None
    if not isinstance(q, ureg.Quantity) or (not q.dimensionality and not dict(q.unit_items())):
        raise RotoridError(f"{shown!r} has no unit (write e.g. {_EXAMPLE[d]!r}, or give a plain number, taken as "
                           f"{DIMENSIONS[d]})")
    si = DIMENSIONS[d]
    if q.dimensionality != ureg.get_dimensionality(si):
        hint = ""
        if d == "mass" and "force_pound" in str(q.units):
            hint = " (lb is the pound mass, lbf the pound force)"
        elif d == "acceleration" and q.dimensionality == ureg.get_dimensionality("kg"):
            hint = " (g is the gram here; standard gravity is g0)"
        raise RotoridError(f"{shown!r} is {_what(q)}, expected {_dim_text(d)} ({si}){hint}")
    try:
        if d in ("speed", "frequency"):
            # revolutions per time: with an angle in the unit (rpm, rad/s, deg/s) by that angle; a bare
            # frequency (Hz, 1/s, 1/min) counts revolutions
            root = q.to_root_units()
            angle = dict(root.unit_items()).get("radian", 0)
            if angle not in (0, 1):
                raise RotoridError(f"{shown!r} is not {_dim_text(d)} (an angle to the power {angle})")
            cycles = float(root.magnitude) / (2 * math.pi) if angle == 1 else float(root.magnitude)
            x = 2 * math.pi * cycles if d == "speed" else cycles
        else:
            x = float(q.to(si).magnitude)
    except RotoridError:
        raise
    except Exception as exc:  # noqa: BLE001 - e.g. offset units (degC) in a product
        raise RotoridError(f"cannot be converted to {si}: {shown!r} ({type(exc).__name__})") from None
    if not math.isfinite(x):
        raise RotoridError(f"{shown!r} is not a finite {d}")
    return x


def _fits(text: str, bad: str, cand: str, d: str) -> bool:
    """Whether ``text`` with the unit ``bad`` spelled ``cand`` parses as a quantity of dimension ``d``."""
    ureg = registry()
    try:
        q = ureg.parse_expression(re.sub(rf"(?<![A-Za-z_]){re.escape(bad)}(?![A-Za-z0-9_])", cand, text.strip()))
        return q.dimensionality == ureg.get_dimensionality(DIMENSIONS[d])
    except Exception:  # noqa: BLE001 - any failure: not a suggestion
        return False


def quantity(value, dimension: str, name: str = "value") -> float:
    """A value given with its unit, in SI: a number is taken as SI already, a string is parsed
    with its unit (pint; ``mil`` = 0.001 in).

    Parameters
    ----------
    value : float or str or pint.Quantity
        A number (SI), or a string such as ``"68 lb"``, ``"12.5 in"``, ``"0.45 lb*in**2"`` (also
        ``"lb in^2"``), ``"3000 rpm"``, ``"2.1 klbf/in"``, ``"12 lbf·s/in"``.
    dimension : str
        What the value is: ``length`` (m), ``mass`` (kg), ``inertia`` (kg m²), ``force`` (N),
        ``stiffness`` (N/m), ``damping`` (N s/m), ``speed`` (rad/s), ``frequency`` (Hz), ``time``
        (s), ``acceleration`` (m/s²), ``voltage`` (V), ``imbalance`` (kg m). A speed or frequency
        without an angle in its unit (``Hz``, ``1/min``) counts revolutions: ``"50 Hz"`` as a
        speed is 3000 rpm.
    name : str
        The field, for messages (``"rotor.mass"``).

    Returns
    -------
    float
        The value in the SI unit of ``dimension``.

    Raises
    ------
    RotoridError
        One line naming the field: an unknown unit (units are case-sensitive: ``mN/m`` is milli,
        ``MN/m`` mega), a unit of another dimension, no unit, not finite.

    Examples
    --------
    >>> from rotorid.units import quantity
    >>> round(quantity("68 lb", "mass", "rotor.mass"), 4)
    30.8443
    >>> quantity("12.5 in", "length"), quantity(0.3, "length")
    (0.3175, 0.3)
    >>> round(quantity("3000 rpm", "speed"), 3), round(quantity("50 Hz", "speed"), 3)
    (314.159, 314.159)
    >>> round(quantity("2 mil", "length") * 1e6, 6)
    50.8
    >>> quantity("3 in", "mass", "rotor.mass")
    Traceback (most recent call last):
    ...
    rotorid.errors.RotoridError: rotor.mass: '3 in' is a length, expected a mass (kg)
    """
    from ._validate import text

    name = text("name", name)
    try:
        return _to_si_float(value, dimension)
    except RotoridError as exc:
        raise RotoridError(f"{name}: {exc}") from None


# =============================================================================================
# how results are written

class OutputUnits:
    """How results are written and printed: unit system, amplitude and phase conventions.

    Parameters
    ----------
    units : {"SI", "US"}
        SI (µm, N, N/m, N s/m) or US customary (mil, lbf, lbf/in, lbf s/in); any case.
    amplitude : {"0-pk", "pk-pk"}
        Amplitudes of 1X vectors as zero-to-peak (the modulus of the complex amplitude) or
        peak-to-peak (twice it, as most proximity-probe DAQs show).
    phase : {"lag", "arg"}
        Phases as lag (degrees in [0, 360), how a vibration DAQ shows it: lag = -arg mod 360) or as
        the argument of the complex amplitude (degrees in (-180, 180]).

    Examples
    --------
    >>> import numpy as np
    >>> from rotorid.units import OutputUnits
    >>> out = OutputUnits("US", amplitude="pk-pk", phase="lag")
    >>> z = np.array([25.4e-6 * np.exp(-1j * np.pi / 2)])     # 1 mil 0-pk, 90 deg behind
    >>> out.amplitude_of(z), out.phase_of(z)
    (array([2.]), array([90.]))
    >>> out.amplitude_column("x1"), out.phase_column("x1")
    ('x1_amp_mil_pkpk', 'x1_phase_deg_lag')
    >>> OutputUnits("imperial")
    Traceback (most recent call last):
    ...
    rotorid.errors.RotoridError: units must be 'SI' or 'US' (US customary: mil, lbf, lbf/in, lbf*s/in), got 'imperial'
    """

    SYSTEMS = {"SI": dict(length="um", length_label="µm", force="N", stiffness="N/m", damping="N*s/m"),
               "US": dict(length="mil", length_label="mil", force="lbf", stiffness="lbf/in", damping="lbf*s/in")}

    def __init__(self, units: str = "SI", amplitude: str = "0-pk", phase: str = "lag"):
        if not isinstance(units, str) or units.upper() not in self.SYSTEMS:
            raise RotoridError(f"units must be 'SI' or 'US' (US customary: mil, lbf, lbf/in, lbf*s/in), got {units!r}")
        if not isinstance(amplitude, str) or amplitude not in ("0-pk", "pk-pk"):   # (an array compares elementwise)
            raise RotoridError(f"amplitude must be '0-pk' or 'pk-pk', got {amplitude!r}")
        if not isinstance(phase, str) or phase not in ("lag", "arg"):
            raise RotoridError(f"phase must be 'lag' (as a DAQ shows it) or 'arg' (of the complex amplitude), "
                               f"got {phase!r}")
        self.units, self.amplitude, self.phase = units.upper(), amplitude, phase
        s = self.SYSTEMS[self.units]
        self.length_unit, self.length_label, self.force_unit = s["length"], s["length_label"], s["force"]
        self.stiffness_unit, self.damping_unit = s["stiffness"], s["damping"]

    def __repr__(self):
        return f"OutputUnits({self.units!r}, amplitude={self.amplitude!r}, phase={self.phase!r})"

    @property
    def _amp_tag(self) -> str:
        return "0pk" if self.amplitude == "0-pk" else "pkpk"

    def amplitude_of(self, z):
        """Amplitudes of complex 1X vectors ``z`` (m) in ``length_unit``, 0-pk or pk-pk."""
        import numpy as np

        return np.abs(z) * (2.0 if self.amplitude == "pk-pk" else 1.0) / factor(self.length_unit)

    def amplitude_std_of(self, std_m):
        """A standard deviation of amplitude (m, 0-pk) in the amplitude convention."""
        import numpy as np

        return np.asarray(std_m, float) * (2.0 if self.amplitude == "pk-pk" else 1.0) / factor(self.length_unit)

    def phase_of(self, z):
        """Phases (deg) of complex vectors ``z``: lag in [0, 360) or arg in (-180, 180]."""
        import numpy as np

        arg = np.rad2deg(np.angle(z))
        if self.phase == "arg":
            return arg + 360.0 * (arg == -180.0)   # (-180, 180]: -180 (a -0.0 imaginary part) is 180
        lag = np.mod(-arg, 360.0) + 0.0   # + 0.0: no -0
        return lag - 360.0 * (lag == 360.0)   # [0, 360): the mod of a tiny negative rounds up to 360

    def amplitude_column(self, name: str) -> str:
        return f"{name}_amp_{self.length_unit}_{self._amp_tag}"

    def phase_column(self, name: str) -> str:
        return f"{name}_phase_deg_{self.phase}"

    def amplitude_text(self) -> str:
        """e.g. 'µm 0-pk' or 'mil pk-pk'."""
        return f"{self.length_label} {self.amplitude}"

    def _polar(self, data, names, vectors, cov):
        import numpy as np

        from .simulate import polar_std

        for j, nm in enumerate(names):
            data[self.amplitude_column(nm)] = self.amplitude_of(vectors[:, j])
            data[self.phase_column(nm)] = self.phase_of(vectors[:, j])
            if cov is not None:
                sa, sp = polar_std(vectors[:, j], cov, j)
                data[f"{nm}_amp_std_{self.length_unit}_{self._amp_tag}"] = self.amplitude_std_of(sa)
                data[f"{nm}_phase_std_deg"] = np.rad2deg(sp)

    def sync_table(self, response):
        """The 1X vectors of a :class:`rotorid.SyncResponse` as a table in these conventions:
        ``speed_rpm``, then per probe (and housing, with pedestal motion) amplitude, phase and
        their standard errors, the headers naming unit and convention (``x1_amp_mil_pkpk``,
        ``x1_phase_deg_lag``, ``x1_amp_std_mil_pkpk``, ``x1_phase_std_deg``).

        Examples
        --------
        >>> import numpy as np, rotorid
        >>> from rotorid.units import OutputUnits
        >>> rig = rotorid.nsf_rig()
        >>> resp = rotorid.imbalance_response(rig.rotor, rig.bearings, rotorid.Imbalance((1e-3, 0), (0, 0)),
        ...                                   speed_rpm=[2000.0, 3000.0])
        >>> a = OutputUnits("SI", "0-pk", "arg").sync_table(resp)
        >>> b = OutputUnits("US", "pk-pk", "lag").sync_table(resp)
        >>> list(b.columns[:3])
        ['speed_rpm', 'x1_amp_mil_pkpk', 'x1_phase_deg_lag']
        >>> bool(np.allclose(b.x1_amp_mil_pkpk * 25.4, 2 * a.x1_amp_um_0pk))
        True
        >>> bool(np.allclose(b.x1_phase_deg_lag, np.mod(-a.x1_phase_deg_arg, 360)))
        True
        """
        import pandas as pd

        from .simulate import DOFS, SyncResponse

        if not isinstance(response, SyncResponse):
            raise RotoridError(f"response must be a rotorid.SyncResponse, got {type(response).__name__}")
        data = {"speed_rpm": response.speed_rpm}
        self._polar(data, DOFS, response.q, response.cov)
        if response.pedestal is not None:
            from .pedestal import PEDESTAL_DOFS

            self._polar(data, PEDESTAL_DOFS, response.pedestal, response.pedestal_cov)
        return pd.DataFrame(data)

    def frf_table(self, response):
        """The FRFs of a :class:`rotorid.ImpactResponse` as a table: ``freq_hz``, then per probe (and
        housing) amplitude in µm/N or mil/lbf (``x1_amp_um_per_N``, ``x1_amp_mil_per_lbf``; an FRF
        is a ratio, so 0-pk and pk-pk coincide) and phase in the phase convention
        (``x1_phase_deg_lag`` or ``x1_phase_deg_arg``)."""
        import pandas as pd

        from .simulate import DOFS, ImpactResponse

        if not isinstance(response, ImpactResponse):
            raise RotoridError(f"response must be a rotorid.ImpactResponse, got {type(response).__name__}")
        scale = factor(self.force_unit) / factor(self.length_unit)
        tag = f"{self.length_unit}_per_{self.force_unit}"
        data = {"freq_hz": response.freq_hz}
        h = response.frf()
        blocks = [(DOFS, h)]
        if response.pedestal is not None:
            from .pedestal import PEDESTAL_DOFS

            blocks.append((PEDESTAL_DOFS, response.pedestal))
        import numpy as np

        for names, arr in blocks:
            for j, nm in enumerate(names):
                data[f"{nm}_amp_{tag}"] = np.abs(arr[:, j]) * scale
                data[self.phase_column(nm)] = self.phase_of(arr[:, j])
        return pd.DataFrame(data)

    def coefficient(self, value, symbol: str):
        """Stiffness (``symbol`` "K") or damping ("C") values (SI) in these units."""
        return from_si(value, self.stiffness_unit if symbol == "K" else self.damping_unit)
