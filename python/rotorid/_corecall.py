"""The compiled core, seen through one error boundary.

The core checks its arguments again (shapes, contiguity, index ranges) and raises ValueError,
OverflowError or TypeError where they do not fit; the public API should have caught all of that
first, so such an error reaching a user is rotorid's own bad input path, and it is reported as a
RotoridError naming the core function. A RuntimeError (a caught panic: a bug) passes unchanged.
"""

from __future__ import annotations

import functools

from .errors import RotoridError

try:
    from . import _core as _raw
except ValueError as exc:  # the module's only refusal at import: a ROTORID_SIMD it does not know
    raise RotoridError(f"cannot load rotorid's compiled core: {exc}") from None


def _guard(fn):
    @functools.wraps(fn)
    def call(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except (ValueError, OverflowError, TypeError) as exc:
            raise RotoridError(f"invalid arguments to the core ({fn.__name__}): {exc}") from None
    return call


class _Core:
    def __getattr__(self, name):
        attr = getattr(_raw, name)
        attr = _guard(attr) if callable(attr) else attr
        # built once: __getattr__ is not called again for this name (wrapping on every access
        # cost ~20 µs per core call)
        setattr(self, name, attr)
        return attr


core = _Core()
