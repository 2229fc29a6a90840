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
    "micron": ("length", 1e-6), "microns": ("length", 1e-6), "in": ("length", 0.0254),
    "mil": ("length", 25.4e-6), "mils": ("length", 25.4e-6),
    # force -> N
    "n": ("force", 1.0), "kn": ("force", 1e3), "lbf": ("force", 4.4482216152605),
    # acceleration -> m/s^2
    "m/s^2": ("acceleration", 1.0), "m/s2": ("acceleration", 1.0), "g": ("acceleration", 9.80665),
    # voltage (keyphasor) -> V
    "v": ("voltage", 1.0), "mv": ("voltage", 1e-3),
    # mass -> kg
    "kg": ("mass", 1.0), "g_mass": ("mass", 1e-3), "gram": ("mass", 1e-3), "grams": ("mass", 1e-3),
    "oz": ("mass", 0.028349523125), "lb": ("mass", 0.45359237),
    # stiffness -> N/m, damping -> N s/m
    "n/m": ("stiffness", 1.0), "mn/m": ("stiffness", 1e6), "lbf/in": ("stiffness", 4.4482216152605 / 0.0254),
    "n*s/m": ("damping", 1.0), "n.s/m": ("damping", 1.0), "ns/m": ("damping", 1.0),
    "lbf*s/in": ("damping", 4.4482216152605 / 0.0254), "lbf.s/in": ("damping", 4.4482216152605 / 0.0254),
    # speed
    "rpm": ("speed", 3.141592653589793 / 30), "rad/s": ("speed", 1.0), "hz": ("frequency", 1.0),
}

SI_UNIT = {"length": "m", "force": "N", "acceleration": "m/s^2", "voltage": "V", "mass": "kg",
           "stiffness": "N/m", "damping": "N*s/m", "speed": "rad/s", "frequency": "Hz"}


def factor(unit: str, quantity: str | None = None) -> float:
    """Factor that converts a value in ``unit`` to SI; checks the quantity when given."""
    from ._validate import text

    quantity = text("quantity", quantity, allow_none=True)
    key = str(unit).strip().lower().replace(" ", "")
    if key not in _UNITS:
        raise RotoridError(f"unknown unit {unit!r}; known: {sorted(_UNITS)}")
    q, f = _UNITS[key]
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


def quantity_of(unit: str) -> str:
    key = str(unit).strip().lower().replace(" ", "")
    if key not in _UNITS:
        raise RotoridError(f"unknown unit {unit!r}; known: {sorted(_UNITS)}")
    return _UNITS[key][0]
