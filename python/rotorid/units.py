"""Unit conversion at the edges (config files, lab files, reports). Inside rotorid everything is SI.

A small explicit table rather than a general unit library: the quantities a rotordynamics lab
records are few, and an unknown unit must fail loudly rather than be guessed.
"""

from __future__ import annotations

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
    # voltage (keyphasor) -> V
    "v": ("voltage", 1.0),
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
