"""Detection of saturated (clipped) displacement and force channels."""

from __future__ import annotations

import numpy as np

from ..recording import DISPLACEMENTS, Recording
from ._common import _warn

__all__ = ["CLIP_CHECKED", "CLIP_MIN_RUN", "check_clipping"]

#: channels whose saturation would corrupt the identification
CLIP_CHECKED = DISPLACEMENTS + ("force",)
CLIP_MIN_RUN = 5


def check_clipping(rec: Recording, *, min_run: int = CLIP_MIN_RUN) -> list[dict]:
    """Warn about displacement and force channels that look saturated.

    A channel is reported when it sits at its own maximum (or minimum) value for ``min_run`` or
    more consecutive samples. A level that is also the channel's median is its resting baseline
    (e.g. a hammer between impacts), not a rail, and is not reported; neither is a constant channel.

    Parameters
    ----------
    rec : Recording
    min_run : int
        Shortest run of samples at the extreme that counts as clipping.

    Returns
    -------
    list of dict
        One finding (channel, side, level, unit, first_index, run_length, runs) per warned
        channel and side.

    Examples
    --------
    >>> import numpy as np, warnings
    >>> from rotorid.recording import Recording
    >>> from rotorid.io import check_clipping
    >>> x = np.minimum(np.sin(np.linspace(0, 20, 2000)), 0.9)
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore")
    ...     [f["side"] for f in check_clipping(Recording(1000.0, {"x1": x}))]
    ['maximum']
    """
    from .._validate import index, instance

    instance("rec", rec, Recording)
    min_run = index("min_run", min_run, 1)
    findings = []
    for name in CLIP_CHECKED:
        a = rec.channels.get(name)
        if a is None or a.size < min_run:
            continue
        lo, hi = float(a.min()), float(a.max())
        if lo == hi:
            continue
        median = None
        for side, level in (("maximum", hi), ("minimum", lo)):
            at_level = a == level
            if np.count_nonzero(at_level) < min_run:  # cannot hold a run: the usual case, decided cheaply
                continue
            if median is None:
                median = float(np.median(a))
            if level == median:
                continue
            at = np.concatenate(([False], at_level, [False])).astype(np.int8)
            edges = np.diff(at)
            starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
            long = (ends - starts) >= min_run
            if not long.any():
                continue
            first = int(starts[long][0])
            item = dict(channel=name, side=side, level=level, unit=rec.units.get(name, ""), first_index=first,
                        run_length=int((ends - starts)[long][0]), runs=int(long.sum()))
            findings.append(item)
            _warn(f"{rec.source or 'recording'}: channel {name!r} possibly clipped: it sits at its {side} "
                  f"{level:.6g} {item['unit']} for {item['run_length']} consecutive samples from sample {first} "
                  f"({item['runs']} such run(s) of >= {min_run} samples)")
    return findings
