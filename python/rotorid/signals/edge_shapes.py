"""Edge shapes a keyphasor pulse may have, and how far they let an interpolated edge time be off
where the equivalent-time correction cannot reach it.

The interpolated mid-height crossing of an edge sampled at one position within a sample interval
is off by an amount that depends on the edge's shape between the samples, which the samples do
not show. Where the pulses of a steady stretch fall at only a few positions (a speed commensurate
with the sample rate), or creep across them too slowly to tell from a change of speed, no overlay
of pulses can measure that error. What the samples do show is which shapes are possible: a linear
ramp that reaches its top within a sample is not an RC edge with its long tail, and the two err in
different ways. :func:`interpolation_bound` fits a family of step responses (linear, first-order,
second-order with damping ratios 0.5-0.87, Bessel and Butterworth filters of orders 3-5, and those
time-reversed, Gaussian, a circular probe spot crossing a straight key edge) at every scale near the measured edge duration to the samples of
each position, keeps every shape that fits as well as the best within the noise, and returns
the largest timing error any of them implies there.

Every unit shape ``e(u)`` rises from 0 to 1, crosses 1/2 at u = 0 and takes u = 1/2 from 25 % to
75 % (an edge of "duration" 1: twice its 25-75 % time, as the keyphasor measures it).
"""

from __future__ import annotations

import numpy as np
from scipy.special import erf

#: fine grid of the unit shapes (u from -12 to 12, in units of the edge duration)
_U = np.linspace(-12.0, 12.0, 24001)


def _normalized(u, y):
    """The step response y(u) (tabulated, rising to its final value 1) shifted and scaled in u so it
    crosses 1/2 at 0 and takes 1/2 from 25 % to 75 % (on an overshoot, the first crossings), on
    the common grid _U."""
    rising = np.maximum.accumulate(y)
    t25, t50, t75 = np.interp([0.25, 0.5, 0.75], rising, u)
    return np.interp(_U, (u - t50) * (0.5 / (t75 - t25)), y, left=0.0, right=1.0)


def _second_order(zeta, t):
    """Step response of a second-order low-pass of damping ratio zeta < 1 (0 before t = 0)."""
    wd = np.sqrt(1.0 - zeta * zeta)
    tp = np.maximum(t, 0.0)
    return np.where(t > 0, 1.0 - np.exp(-zeta * tp) * (np.cos(wd * tp) + zeta / wd * np.sin(wd * tp)), 0.0)


def _all_pole_step(poles, t):
    """Step response of the all-pole low-pass of unit DC gain with these poles (left half-plane):
    y(t) = 1 + sum_k e^{p_k t} prod_j(-p_j) / (p_k prod_{j != k}(p_k - p_j)) for t > 0."""
    p = np.asarray(poles, dtype=complex)
    gain = np.prod(-p)
    res = np.array([gain / (pk * np.prod(np.delete(pk - p, k))) for k, pk in enumerate(p)])
    tp = np.maximum(t, 0.0)
    y = 1.0 + np.real(np.exp(np.outer(tp, p)) @ res)
    return np.where(t > 0, y, 0.0)


def _bessel_poles(n):
    """Roots of the reverse Bessel polynomial of order n, sum_k (2n-k)! / (2^(n-k) k! (n-k)!) s^k
    (unit group delay at DC; the scale of time does not matter here)."""
    from math import factorial
    coef = [factorial(2 * n - k) / (2 ** (n - k) * factorial(k) * factorial(n - k)) for k in range(n + 1)]
    return np.roots(coef[::-1])


def _butterworth_poles(n):
    return np.exp(1j * np.pi * (2 * np.arange(1, n + 1) + n - 1) / (2 * n))


def _family():
    u = np.linspace(-30.0, 30.0, 120001)
    x = np.clip(-u, -1.0, 1.0)
    shapes = {
        "linear": np.clip(u + 0.5, 0.0, 1.0),
        "first-order": np.where(u > 0, -np.expm1(-np.maximum(u, 0.0)), 0.0),
        "gaussian": 0.5 * (1.0 + erf(u / np.sqrt(2.0))),
        "spot": (np.arccos(x) - x * np.sqrt(1.0 - x * x)) / np.pi,
    }
    for zeta in (0.5, 0.707, 0.866):
        shapes[f"second-order {zeta}"] = _second_order(zeta, u)
    # higher-order analog filters (a review found 4th-order Bessel edges of 1.5 samples 2.3 times
    # beyond a bound fitted without them)
    for kind, order in (("bessel", 3), ("bessel", 4), ("bessel", 5), ("butterworth", 3), ("butterworth", 4)):
        t = np.linspace(0.0, 60.0, 12001)
        y = _all_pole_step(_bessel_poles(order) if kind == "bessel" else _butterworth_poles(order), t)
        shapes[f"{kind} {order}"] = np.interp(u + 30.0, t, y)
    table = {name: _normalized(u, y) for name, y in shapes.items()}
    # the asymmetric ones time-reversed (a slow start and an abrupt top): 1 - e(-u)
    for name in ("first-order", "second-order 0.5", "second-order 0.707", "second-order 0.866", "bessel 3",
                 "bessel 4", "bessel 5", "butterworth 3", "butterworth 4"):
        table[name + " reversed"] = 1.0 - table[name][::-1]
    return table


_FAMILY = None
_TABLE = None


def family() -> dict:
    """The unit shapes, tabulated on _U (built once, on first use)."""
    global _FAMILY
    if _FAMILY is None:
        _FAMILY = _family()
    return _FAMILY


def family_table():
    """The unit shapes of :func:`family` as the rows of one array."""
    global _TABLE
    if _TABLE is None:
        _TABLE = np.stack(list(family().values()))
    return _TABLE


#: shifts tried (samples): the interpolated crossing is off by less than half a sample unless the
#: edge is a step; a coarse grid, then a fine one around its best
_COARSE = np.linspace(-0.75, 0.75, 61)
_FINE = np.linspace(-0.025, 0.025, 11)
#: scales tried, relative to the measured edge duration (which linear interpolation measures
#: only roughly on edges of one or two samples)
_SCALES = np.exp(np.linspace(np.log(0.35), np.log(2.5), 29))
#: a shape fits as well as the best when its largest misfit exceeds the best's by no more than this
#: (fraction of the swing) plus twice the noise of the averaged samples
FIT_TOLERANCE = 0.01
#: the bound is the largest shift of the shapes that fit times this, plus BOUND_FLOOR (samples):
#: the shifts are found to 0.005 sample, and edges outside the family (fourth-order
#: filters, Chebyshev ripple) err a little beyond the nearest shape of it
BOUND_MARGIN = 1.15
BOUND_FLOOR = 0.01
#: no shape of the family explains the samples when the best misfit exceeds this (fraction of the
#: swing, beyond the noise): the caller falls back to its bound for unknown shapes
MAX_MISFIT = 0.03


def _max_deviation(tabs, p, y, r, d, per_shape):
    """max_j |e_h((p_j + d) / r) - y_j| for every shape h (the rows of ``tabs``, tabulated on the
    uniform grid _U; linear interpolation by index, clamped at its ends) and every (r, d) of the
    arrays r and d, broadcast together; ``per_shape``: their first axis is the shape's (otherwise
    every shape takes every (r, d), in a new first axis)."""
    x = (p + d[..., None]) / r[..., None]
    pos = np.clip((x - _U[0]) / (_U[1] - _U[0]), 0.0, _U.size - 1.000001)
    i = pos.astype(np.int64)
    w = pos - i
    rows = np.arange(tabs.shape[0]).reshape((-1,) + (1,) * (x.ndim - 1)) if per_shape else slice(None)
    model = tabs[rows, i] * (1.0 - w) + tabs[rows, i + 1] * w
    return np.max(np.abs(model - y), axis=-1)


def interpolation_bound(p, y, group, rise, noise=0.0):
    """How far the interpolated edge times of pulses at few positions within a sample can be off.

    Parameters
    ----------
    p : (m,) array
        Each sample's time (samples) relative to its pulse's interpolated mid-height crossing.
    y : (m,) array
        The samples, as fractions of the swing above the pulse's base.
    group : (m,) int array
        The position group (pulses at one position within a sample) each sample belongs to.
    rise : float
        The measured edge duration (samples): twice the 25-75 % time.
    noise : float
        The samples' noise, as a fraction of the swing.

    Returns
    -------
    bound : (g,) array or None
        Per group, the largest |error| of the interpolated time over the shapes that fit its
        samples (samples), or None when no shape of the family fits them.

    Examples
    --------
    A linear edge two samples long, seen at two positions: its interpolation is exact. Where
    three of its samples lie on it, no other shape fits them (the bound is its floor); where only
    two do, a second-order edge fits as well and would be interpolated 0.07 sample off.

    >>> import numpy as np
    >>> p = np.r_[np.arange(-3, 4) - 0.5, np.arange(-3, 4) - 0.2]
    >>> y = np.clip(p / 2 + 0.5, 0, 1)
    >>> interpolation_bound(p, y, np.repeat([0, 1], 7), 2.0).round(3)
    array([0.01 , 0.091])
    """
    p = np.asarray(p, dtype=float)
    y = np.asarray(y, dtype=float)
    group = np.asarray(group)
    if not (p.ndim == y.ndim == group.ndim == 1 and p.size == y.size == group.size):
        raise ValueError(f"p, y and group must be 1-D arrays of one length, got shapes {p.shape}, {y.shape}, "
                         f"{group.shape}")
    if p.size == 0:
        raise ValueError("interpolation_bound needs at least one sample")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(y))):
        raise ValueError("p and y must be finite")
    if not (np.isfinite(rise) and rise > 0):
        raise ValueError(f"rise must be a positive number of samples, got {rise!r}")
    if not np.issubdtype(group.dtype, np.integer) or group.min() < 0:
        raise ValueError("group must hold non-negative integers (0, 1, ... per position)")
    ng = int(group.max()) + 1
    if np.bincount(group, minlength=ng).min() == 0:
        raise ValueError(f"every group 0 to {ng - 1} needs samples; group {int(np.argmin(np.bincount(group)))} has none")
    # per group, the median sample at each offset (pulses at one position repeat their samples)
    keys = np.round(p * 64.0).astype(np.int64)
    pts = []
    for g in range(ng):
        sel = group == g
        kk, inv = np.unique(keys[sel], return_inverse=True)
        med = np.array([np.median(y[sel][inv == i]) for i in range(kk.size)])
        cnt = np.bincount(inv)
        keep = (kk / 64.0 >= -4.0) & (kk / 64.0 <= 4.0)
        pts.append((kk[keep] / 64.0, med[keep], max(int(np.median(cnt)), 1)))
    tabs = family_table()
    # misfit[h, s, g], shift[h, s, g]: each shape at each scale, at its best shift for each group
    misfit = np.empty((tabs.shape[0], _SCALES.size, ng))
    shift = np.empty_like(misfit)
    r = rise * _SCALES
    hs = np.arange(tabs.shape[0])[:, None]
    ss = np.arange(r.size)[None, :]
    for g, (pp, yy, _) in enumerate(pts):
        # the shift on a coarse grid (the same for every shape: (scales, shifts) broadcast to
        # (shapes, scales, shifts)), then on the fine grid around each shape's best coarse one
        dev = _max_deviation(tabs, pp, yy, r[:, None], np.broadcast_to(_COARSE, (r.size, _COARSE.size)), False)
        fine = _COARSE[np.argmin(dev, axis=-1)][..., None] + _FINE
        dev = _max_deviation(tabs, pp, yy, np.broadcast_to(r[None, :, None], fine.shape), fine, True)
        k = np.argmin(dev, axis=-1)
        misfit[:, :, g] = dev[hs, ss, k]
        shift[:, :, g] = fine[hs, ss, k]
    bound = np.empty(ng)
    for g, (_, _, n_each) in enumerate(pts):
        m = misfit[:, :, g]
        floor = 2.0 * noise / np.sqrt(n_each)
        if m.min() > MAX_MISFIT + floor:
            return None
        ok = m <= m.min() + FIT_TOLERANCE + floor
        bound[g] = BOUND_MARGIN * float(np.max(np.abs(shift[:, :, g][ok]))) + BOUND_FLOOR
    return bound
