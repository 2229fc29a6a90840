"""Predicted force coefficients of the bearing supports (issue 13): the series support of the
report (integral squeeze film damper in series with a flexure-pivot tilting-pad bearing) as an
equivalent impedance, and the element models behind it.

- :func:`series_impedance` (``series.py``): Z_eq of a bearing film in series with a damper
  through the damper journal's mass (the physics in the Rust core, ``rust/core/src/series.rs``).
- ``sfd.py``: the integral squeeze film damper (arc lands, short-length Reynolds solution, docs/sfd.md).
- ``tpjb.py``: tilting-pad bearing coefficient tables from any bearing code (speed x frequency
  or frequency ratio), interpolated.
- ``compare.py``: :class:`SeriesSupport`, :func:`predict_coefficients` where an identification
  measured, :func:`compare` with the identified intervals (``rotorid compare``).
"""

from .compare import Comparison, SeriesSupport, compare, compare_tables, predict_coefficients
from .series import coefficients_of, series_impedance
from .sfd import SFDCoefficients, SqueezeFilmDamper, nsf_damper
from .tpjb import BearingTable, load_bearing_table

__all__ = ["series_impedance", "coefficients_of", "SqueezeFilmDamper", "SFDCoefficients", "nsf_damper",
           "SeriesSupport", "predict_coefficients", "compare", "compare_tables", "Comparison", "BearingTable",
           "load_bearing_table"]
