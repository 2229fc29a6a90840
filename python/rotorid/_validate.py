"""Argument checks shared by the public API. Every failure raises RotoridError naming the argument."""

from __future__ import annotations

import math

import numpy as np

from ._corecall import core as _core
from .errors import RotoridError


def real_array(name, value, *, ndim=None, shape=None, positive=False, nonneg=False, nonzero=False, finite=True):
    """A real float array; ``finite=False`` lets NaN and inf through (arrays where NaN means unknown)."""
    if type(value) is float and ndim in (None, 0) and shape in (None, ()) and math.isfinite(value) and \
            (value > 0.0 or not positive and (value == 0.0 or not nonneg) and (value != 0.0 or not nonzero)):
        # a plain Python number within its bounds (speeds, planes): the array the checks below would
        # give, without their microseconds; anything else takes them for its message
        return np.asarray(value)
    if isinstance(value, (str, bytes)):
        raise RotoridError(f"{name} must be numeric real values, got the string {value!r}")
    if np.iscomplexobj(value):
        raise RotoridError(f"{name} must be real, got complex values (the imaginary part would be dropped); "
                           "complex data belong in the response arguments")
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise RotoridError(f"{name} must be numeric real values ({exc})") from None
    if raw.dtype == bool:
        raise RotoridError(f"{name} must be numbers, got booleans ({value!r})")
    if raw.dtype.kind in "USO" and raw.dtype.kind != "O" or raw.dtype.kind == "O" and any(
            v is None or isinstance(v, (str, bytes, bool, np.bool_)) for v in raw.ravel().tolist()):
        raise RotoridError(f"{name} must be numeric real values, got {value!r}")
    try:
        a = raw.astype(float, copy=False)  # the caller's array as it is when it already is float
    except (TypeError, ValueError) as exc:
        raise RotoridError(f"{name} must be numeric real values ({exc})") from None
    return _check(name, a, ndim, shape, positive, nonneg, nonzero, finite)


def flag(name, value):
    """A boolean argument: True or False only (no strings, no numbers)."""
    if not isinstance(value, (bool, np.bool_)):
        raise RotoridError(f"{name} must be True or False, got {value!r}")
    return bool(value)


def index(name, value, lo=0, hi=None):
    """A whole number in [lo, hi]."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) and not (
            isinstance(value, (float, np.floating)) and float(value).is_integer()):
        raise RotoridError(f"{name} must be a whole number, got {value!r}")
    v = int(value)
    if v < lo or (hi is not None and v > hi):
        raise RotoridError(f"{name} must be between {lo} and {hi}, got {v}" if hi is not None else
                           f"{name} must be >= {lo}, got {v}")
    return v


def complex_array(name, value, *, ndim=None, shape=None, finite=True):
    """A complex128 array (the caller's own when it already is one); ``finite=False`` leaves NaN
    and inf to the caller (the core marks such points itself)."""
    try:
        a = np.asarray(value)
        if a.dtype == bool:
            raise TypeError("booleans are not numbers here")
        if not np.issubdtype(a.dtype, np.number):
            raise TypeError(f"dtype {a.dtype}")
        a = a.astype(complex, copy=False)  # the caller's array as it is when it already is complex
    except (TypeError, ValueError) as exc:
        raise RotoridError(f"{name} must be numeric complex values ({exc})") from None
    return _check(name, a, ndim, shape, False, False, False, finite)


def _check(name, a, ndim, shape, positive, nonneg, nonzero, finite=True):
    if a.dtype == bool:
        raise RotoridError(f"{name} must be numbers, got booleans")
    if ndim is not None and a.ndim != ndim:
        raise RotoridError(f"{name} must have {ndim} dimension(s), got shape {a.shape}")
    if shape is not None:
        if len(shape) != a.ndim or any(s is not None and s != t for s, t in zip(shape, a.shape)):
            want = tuple("n" if s is None else s for s in shape)
            raise RotoridError(f"{name} has shape {a.shape}, expected {want}")
    # real arrays: bounds by reductions, not element-wise comparisons (no temporary array, one pass
    # each; min and max propagate NaN, so a NaN or an inf makes one of them non-finite); complex
    # arrays (complex_array) only have the finiteness check
    real = a.dtype.kind == "f"
    lo = hi = math.nan
    if a.size and real and (finite or positive or nonneg):
        lo, hi = float(a.min()), float(a.max())
    if finite and a.size and not (math.isfinite(lo) and math.isfinite(hi) if real else all_finite(a)):
        bad = np.argwhere(~np.isfinite(a))[0]
        raise RotoridError(f"{name} contains NaN or inf (first at index {tuple(int(i) for i in bad)})")
    # NaN (finite=False) passes every bound; the minimum is then NaN, which no comparison fails
    if positive and a.size and (lo <= 0 or math.isnan(lo) and np.any(a <= 0)):
        raise RotoridError(f"{name} must be > 0 (got min {np.min(a, where=a <= 0, initial=0.0):g})")
    if nonneg and a.size and (lo < 0 or math.isnan(lo) and np.any(a < 0)):
        raise RotoridError(f"{name} must be >= 0 (got min {np.min(a, where=a < 0, initial=0.0):g})")
    if nonzero and a.size and np.any(a == 0):
        raise RotoridError(f"{name} must be non-zero")
    return a


def frozen(a):
    """``a`` copied onto an immutable buffer: read-only, and it cannot be made writeable (for an
    array cached and handed out again on later calls, where a restored write flag would let one
    caller change what the others read)."""
    a = np.ascontiguousarray(a)
    return np.frombuffer(a.tobytes(), dtype=a.dtype).reshape(a.shape)


def all_finite(a):
    """True when no value (no real or imaginary part) of ``a`` is NaN or inf. A C-contiguous
    float64 or complex128 array (the latter as its float64 pairs) is read by the core in one pass
    without a temporary (0.25 against 0.37 ms for NumPy's isfinite and all at 100,000 x 4 complex
    values); other layouts go through NumPy."""
    if a.dtype in (np.float64, np.complex128) and a.flags.c_contiguous:
        return _core.first_outside(a.reshape(-1).view(np.float64), -math.inf, math.inf) is None
    return bool(np.all(np.isfinite(a)))


def positive_scalar(name, value):
    a = real_array(name, value, ndim=0)
    if not a > 0:
        raise RotoridError(f"{name} must be > 0, got {float(a):g}")
    return float(a)


def finite_scalar(name, value):
    return float(real_array(name, value, ndim=0))


def speeds_rpm(name, value):
    a = np.atleast_1d(real_array(name, value, finite=False))
    if a.ndim == 1 and a.size and _core.first_outside(a, 0.0, math.inf) is None:  # one pass (NaN is outside)
        return a
    a = _check(name, a, None, None, False, False, False)  # the error naming what is wrong
    if a.ndim != 1:
        raise RotoridError(f"{name} must be a scalar or a 1-D array, got shape {a.shape}")
    if a.size == 0:
        raise RotoridError(f"{name} is empty")
    if np.any(a <= 0):
        raise RotoridError(f"{name} must be > 0 rpm (got min {a.min():g}); zero speed has no synchronous response")
    return a


def choice(name, value, options):
    try:
        ok = isinstance(value, str) and value in options
    except (TypeError, ValueError):  # unhashable values (lists, arrays) are no option
        ok = False
    if not ok:
        raise RotoridError(f"{name} must be one of {sorted(options)}, got {value!r}")
    return value


def number(name, value, *, positive=False, nonneg=False, allow_none=False):
    """A real, finite scalar: refuses strings, booleans, complex numbers, arrays and None (unless
    ``allow_none``), naming the argument."""
    if type(value) is float and math.isfinite(value) and value >= 0.0 and (value > 0.0 or not positive):
        return value  # the common case, without the checks below (they cost microseconds per argument)
    if value is None and allow_none:
        return None
    ok_type = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
    if not ok_type:
        if isinstance(value, np.ndarray) and value.shape == () and value.dtype.kind in "iuf":
            value = value.item()
        else:
            raise RotoridError(f"{name} must be a real number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise RotoridError(f"{name} must be finite, got {value!r}")
    if positive and not v > 0:
        raise RotoridError(f"{name} must be > 0, got {value!r}")
    if nonneg and v < 0:
        raise RotoridError(f"{name} must be >= 0, got {value!r}")
    return v


def seed(name, value):
    """A random seed: a whole number >= 0 (what numpy's generators take)."""
    return index(name, value, 0)


def path(name, value):
    """A file or folder path: a non-empty str or os.PathLike (not bytes, numbers or None)."""
    import os
    from pathlib import Path

    if isinstance(value, os.PathLike):
        value = os.fspath(value)
    if not isinstance(value, str) or not value.strip():
        raise RotoridError(f"{name} must be a file path (a non-empty str or pathlib.Path), got {value!r}")
    return Path(value)


def mapping(name, value, *, allow_none=True):
    """A dict argument (None allowed unless ``allow_none=False``); returns a copy (None: {})."""
    if value is None and allow_none:
        return {}
    if not isinstance(value, dict):
        raise RotoridError(f"{name} must be a dict{' or None' if allow_none else ''}, got {type(value).__name__} "
                           f"{value!r}"[:300])
    return dict(value)


def text(name, value, *, allow_none=False):
    """A str argument (None allowed with ``allow_none``)."""
    if value is None and allow_none:
        return None
    if not isinstance(value, str):
        raise RotoridError(f"{name} must be a string, got {type(value).__name__} {value!r}"[:300])
    return value


def instance(name, value, cls, *, allow_none=False, what=None):
    """An argument of class ``cls`` (or None with ``allow_none``)."""
    if value is None and allow_none:
        return None
    if not isinstance(value, cls):
        want = what or (cls.__name__ if isinstance(cls, type) else " or ".join(c.__name__ for c in cls))
        raise RotoridError(f"{name} must be a {want}{' (or None)' if allow_none else ''}, got {type(value).__name__}")
    return value
