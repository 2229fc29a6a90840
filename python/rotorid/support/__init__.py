"""Predicted force coefficients of the bearing supports (issue 13): the series support of the
report (integral squeeze film damper in series with a flexure-pivot tilting-pad bearing) as an
equivalent impedance, and the element models behind it.

- :func:`series_impedance` (``series.py``): Z_eq of a bearing film in series with a damper
  through the damper journal's mass (the physics in the Rust core, ``rust/core/src/series.rs``).
- ``sfd.py``: the integral squeeze film damper (arc lands, short-length Reynolds solution).
"""

from .series import series_impedance

__all__ = ["series_impedance"]
