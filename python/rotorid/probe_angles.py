"""Probes mounted at an angle: the x and y motion of a measurement plane from two probes that
measure along other directions (API 670 mounts them 45° either side of vertical).

Angles are in degrees from +x (horizontal) toward +y (vertical), which is the direction of
rotation: rotorid's forward whirl goes from +x to +y (y lags x by 90°). Seen from the end where
the rotor turns counterclockwise, +x points right and +y up, so API 670's probes are at 45°
(upper right) and 135° (upper left). A probe measuring along the direction at angle ``a`` reads
``u = cos a x + sin a y``. With the plane's "x" probe at ``a`` and its "y" probe
at ``b``::

    [x, y] = R [u_a, u_b],   R = 1/sin(b - a) [[sin b, -sin a], [-cos b, cos a]]

(x and y probes, a = 0 and b = 90, give R = I). ``rotorid.io`` applies R to the time samples of
lab files, ``rotorid.tables`` to a DAQ's 1X phasors and their covariance.
"""

from __future__ import annotations

import math

import numpy as np

#: the x and y channels of each measurement plane (probes, then housing accelerometers)
PLANE_PAIRS = (("x1", "y1"), ("x2", "y2"), ("px1", "py1"), ("px2", "py2"))
#: the channels that may be mounted at an angle
ANGLED = tuple(c for pair in PLANE_PAIRS for c in pair)
#: the least angle between the two probes of a plane: closer to parallel, the plane's motion along
#: their common normal is amplified beyond use (1 / sin 20° = 2.9 times the probes' noise)
MIN_PROBE_SEPARATION_DEG = 20.0
#: the largest |angle_deg| accepted (one turn either way)
MAX_ANGLE_DEG = 360.0


def default_angle(channel: str) -> float:
    """The measuring direction a channel has without ``angle_deg``: 0 for x, 90 for y."""
    return 90.0 if channel.lstrip("p").startswith("y") else 0.0


def resolution(a_deg: float, b_deg: float) -> np.ndarray | None:
    """R (2, 2) taking the readings of probes measuring along ``a_deg`` and ``b_deg`` to the
    plane's [x, y] motion; None when they are within ``MIN_PROBE_SEPARATION_DEG`` of parallel.

    Examples
    --------
    >>> import numpy as np
    >>> from rotorid.probe_angles import resolution
    >>> r = resolution(45.0, 135.0)          # API 670: 45° either side of vertical
    >>> x, y = 3.0, 4.0
    >>> u = [np.cos(np.pi / 4) * x + np.sin(np.pi / 4) * y, np.cos(3 * np.pi / 4) * x + np.sin(3 * np.pi / 4) * y]
    >>> np.round(r @ u, 12).tolist()
    [3.0, 4.0]
    >>> resolution(0.0, 10.0) is None
    True
    """
    a, b = math.radians(a_deg), math.radians(b_deg)
    det = math.sin(b - a)
    if abs(det) < math.sin(math.radians(MIN_PROBE_SEPARATION_DEG)):
        return None
    return np.array([[math.sin(b), -math.sin(a)], [-math.cos(b), math.cos(a)]]) / det


def _per_plane(angles: dict, channels: tuple, block) -> np.ndarray | None:
    """The (C, C) map over ``channels`` with ``block(a, b, xn, yn)`` (2, 2) on each plane that has
    an angled channel (the other at its default angle), the identity elsewhere; None without
    angles."""
    if not angles:
        return None
    m = np.eye(len(channels))
    for xn, yn in PLANE_PAIRS:
        if xn not in channels or yn not in channels or (xn not in angles and yn not in angles):
            continue
        a, b = angles.get(xn, default_angle(xn)), angles.get(yn, default_angle(yn))
        i, j = channels.index(xn), channels.index(yn)
        m[np.ix_([i, j], [i, j])] = block(a, b, xn, yn)
    return m


def plane_transform(angles: dict, channels: tuple) -> np.ndarray | None:
    """The (C, C) real map from the readings of ``channels`` (names, e.g. [x1, x2, y1, y2]) to the
    planes' x and y motion, given ``angles`` {channel: deg} for the angled ones; None when no
    channel is angled. Raises ValueError naming the pair when one is within
    ``MIN_PROBE_SEPARATION_DEG`` of parallel."""
    def block(a, b, xn, yn):
        r = resolution(a, b)
        if r is None:
            raise ValueError(f"{xn} (angle_deg {a:g}) and {yn} (angle_deg {b:g}) are within "
                             f"{MIN_PROBE_SEPARATION_DEG:g}° of parallel: the plane's motion cannot be resolved "
                             "from them (check angle_deg)")
        return r

    return _per_plane(angles, channels, block)


def reading_map(angles: dict, channels: tuple) -> np.ndarray | None:
    """The (C, C) real map from the planes' x and y motion to what the probes of ``channels`` read
    (the inverse of :func:`plane_transform`: ``[u_a, u_b] = [[cos a, sin a], [cos b, sin b]] [x, y]``),
    given ``angles`` {channel: deg}; None when no channel is angled. For checks that belong to the
    readings themselves (a dead probe's 1X is noise, a clipped probe sits at its rail)."""
    def block(a, b, xn, yn):
        a, b = math.radians(a), math.radians(b)
        return [[math.cos(a), math.sin(a)], [math.cos(b), math.sin(b)]]

    return _per_plane(angles, channels, block)


def moved_covariance(cov, t):
    """The covariance (n, 8, 8) of [Re u, Im u] after u -> T u (``t`` (4, 4) real, the same map of
    both parts): A C Aᵀ with A = diag(T, T), by the core (exactly symmetric; a point with a NaN
    all NaN)."""
    from ._corecall import core

    return core.move_covariances(np.kron(np.eye(2), t), None, np.ascontiguousarray(cov, dtype=float))[0]


def recorded_angles(run) -> dict:
    """{channel: angle_deg} of a run's angled probes and accelerometers as it was loaded: a lab
    file's channel map (``meta["channel_sources"]``) or a 1X table's ``columns``
    (``meta["table"]["columns"]``); {} when none is angled or the run says nothing."""
    meta = getattr(run, "meta", None) or {}
    out = {}
    sources = meta.get("channel_sources")
    if isinstance(sources, dict):
        out.update({c: float(s["angle_deg"]) for c, s in sources.items()
                    if c in ANGLED and isinstance(s, dict) and s.get("angle_deg") is not None})
    table = meta.get("table")
    columns = table.get("columns") if isinstance(table, dict) else None
    if isinstance(columns, dict):
        out.update({c: float(s["angle_deg"]) for c, s in columns.items()
                    if c in ANGLED and isinstance(s, dict) and s.get("angle_deg") is not None})
    return out
