"""The bound on the interpolation error of keyphasor edges seen at few positions within a sample.

The edges here are step responses computed with scipy.signal (Bessel, Butterworth and Chebyshev
filters of orders 2-4; the Chebyshev ripple is outside the family the bound fits, whose filter
edges are computed from their poles) and closed forms (first-order, Gaussian, linear), sampled at
random positions; each is timed as the
keyphasor times it (linear crossing below 2.5 samples, the cubic above) and its true error compared
with the bound.
"""

import numpy as np
import pytest
from scipy import signal as ss
from scipy.special import erf

from rotorid.signals import edge_shapes
from rotorid.signals import keyphasor as kpmod


def _filter_edge(kind, order):
    """Unit step response of an analog filter of cut-off 1/3 per sample, 50 % crossing at 0, as a
    function of time in samples (a filter of cut-off 1/(3 s) is the same edge, s times as long)."""
    if kind == "bessel":
        b, a = ss.bessel(order, 2 * np.pi / 3.0, analog=True, norm="phase")
    elif kind == "butter":
        b, a = ss.butter(order, 2 * np.pi / 3.0, analog=True)
    else:
        b, a = ss.cheby1(order, 1.0, 2 * np.pi / 3.0, analog=True)
    t = np.linspace(0.0, 60.0, 60001)
    _, y = ss.step(ss.lti(b, a), T=t)
    y = y / y[-1]
    t50 = np.interp(0.5, np.maximum.accumulate(y), t)
    return lambda u: np.interp(u + t50, t, y, left=0.0, right=1.0)


CLOSED = {
    "rc": lambda u: np.where(u + np.log(2) > 0, -np.expm1(-np.maximum(u + np.log(2), 0)), 0.0),
    "erf": lambda u: 0.5 * (1 + erf(u / np.sqrt(2))),
    "ramp": lambda u: np.clip(u + 0.5, 0.0, 1.0),
}
EDGES = [(k, o) for k in ("bessel", "butter") for o in (2, 3)] + [("bessel", 4), ("cheby1", 2)] + [(k, 0) for k in CLOSED]


def _rise(e):
    u = np.linspace(-40, 40, 160001)
    y = np.maximum.accumulate(e(u))
    return 2.0 * (np.interp(0.75, y, u) - np.interp(0.25, y, u))


_UNIT = {}


def _edge(kind, order, scale):
    """The edge of that kind ``scale`` times as long as at scale 1, and its duration (samples)."""
    if (kind, order) not in _UNIT:
        e1 = CLOSED[kind] if kind in CLOSED else _filter_edge(kind, order)
        _UNIT[kind, order] = (e1, _rise(e1))
    e1, rise1 = _UNIT[kind, order]
    return (lambda u: e1(u / scale)), rise1 * scale


def _timed(e, phase, rise):
    """Samples of edge e at n + phase, and the error of their interpolated mid-height crossing."""
    n = np.arange(-6, 7).astype(float)
    y = e(n + phase)
    k = np.array([int(np.max(np.flatnonzero((y[:-1] < 0.5) & (y[1:] >= 0.5))))])
    f = (kpmod._cubic_crossing(y, k, 0.5) if rise >= 2.5 else kpmod._linear_crossing(y, k, 0.5))[0]
    t = n[k[0]] + f + phase            # the true crossing is at 0
    return n + phase - t, y, t


@pytest.mark.parametrize("kind,order", EDGES, ids=lambda v: str(v))
def test_the_bound_covers_the_interpolation_error_of_edges_in_and_outside_its_family(kind, order):
    rng = np.random.default_rng(7 + order)
    covered, fitted = 0, 0
    for scale in (0.5, 0.7, 1.0, 1.4, 2.0):
        e, rise = _edge(kind, order, scale)
        for phase in rng.uniform(0.0, 1.0, 4):
            p, y, err = _timed(e, phase, rise)
            bound = edge_shapes.interpolation_bound(p, y, np.zeros(p.size, int), rise)
            if bound is None:      # no shape fits: the keyphasor falls back to its family-wide figure
                assert abs(err) <= 2.0 * kpmod._interpolation_std(rise), (scale, phase, err)
                continue
            fitted += 1
            covered += abs(err) <= bound[0]
    assert covered == fitted and fitted >= 10


def test_the_bound_covers_an_rc_edge_closely_and_a_ramp_by_what_else_fits_it():
    """An RC edge of two samples' duration, interpolated up to 0.13 sample late, gets a bound above
    its error by less than 0.05. A linear ramp two samples long is timed exactly by the
    interpolation, but with only two or three samples on it the edges of 3rd- to 5th-order
    filters fit its samples within 1 % of the swing too, and they would be interpolated 0.05-0.1
    sample off: its bound is 0.07-0.12 (0.016-0.12 with a family of first- and second-order edges
    only), below the family-wide figure's 2 x 0.09."""
    ramp = []
    for phase in (0.1, 0.35, 0.6, 0.85):
        e, rise = _edge("ramp", 0, 2.0)
        p, y, err = _timed(e, phase, rise)
        assert abs(err) < 1e-12
        ramp.append(edge_shapes.interpolation_bound(p, y, np.zeros(p.size, int), rise)[0])
        e, rise = _edge("rc", 0, 0.91)
        p, y, err = _timed(e, phase, rise)
        b = edge_shapes.interpolation_bound(p, y, np.zeros(p.size, int), rise)[0]
        assert abs(err) <= b < abs(err) + 0.05
    assert max(ramp) < 0.13 < 2 * kpmod._interpolation_std(2.0)


def test_groups_are_bounded_each_and_noise_widens_the_fit():
    e, rise = _edge("rc", 0, 1.0)
    parts = [_timed(e, ph, rise) for ph in (0.2, 0.7)]
    p = np.concatenate([q[0] for q in parts])
    y = np.concatenate([q[1] for q in parts])
    g = np.repeat([0, 1], parts[0][0].size)
    b = edge_shapes.interpolation_bound(p, y, g, rise)
    assert b.shape == (2,)
    for (_, _, err), bg in zip(parts, b):
        assert abs(err) <= bg
    assert np.all(edge_shapes.interpolation_bound(p, y, g, rise, noise=0.02) >= b)


@pytest.mark.parametrize("rise", [0.6, 1.0, 1.5, 2.2, 3.0, 4.4])
def test_the_family_wide_figure_bounds_the_rms_error_of_every_family(rise):
    """INTERPOLATION_STD, the uncertainty where no shape fits, is at least the rms interpolation
    error over positions of each closed-form and filter edge of that duration."""
    phases = np.linspace(0.0, 1.0, 64, endpoint=False)
    for kind, order in EDGES:
        _, rise1 = _edge(kind, order, 1.0)
        e, _ = _edge(kind, order, rise / rise1)
        errs = np.array([_timed(e, ph, rise)[2] for ph in phases])
        assert np.sqrt(np.mean(errs ** 2)) <= kpmod._interpolation_std(rise) * 1.02, (kind, order)


def test_bad_input_is_refused():
    p = np.linspace(-3, 3, 7)
    y = np.clip(p / 2 + 0.5, 0, 1)
    g = np.zeros(7, int)
    with pytest.raises(ValueError, match="p, y and group"):
        edge_shapes.interpolation_bound(p, y[:-1], g, 2.0)
    with pytest.raises(ValueError, match="finite"):
        edge_shapes.interpolation_bound(p, np.r_[y[:-1], np.nan], g, 2.0)
    with pytest.raises(ValueError, match="rise"):
        edge_shapes.interpolation_bound(p, y, g, 0.0)
    with pytest.raises(ValueError, match="group"):
        edge_shapes.interpolation_bound(p, y, g - 1, 2.0)
    with pytest.raises(ValueError, match="group 1 has none"):
        edge_shapes.interpolation_bound(p, y, np.r_[g[:-1], 2], 2.0)
    with pytest.raises(ValueError, match="at least one"):
        edge_shapes.interpolation_bound(p[:0], y[:0], g[:0], 2.0)
