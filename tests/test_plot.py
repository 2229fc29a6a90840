"""Figures: the measured data in the output's conventions, and nothing hidden off scale."""

import numpy as np
import pytest


def test_measured_data_figures_follow_the_output_conventions():
    """plot.polar and plot.frf draw in the chosen units, amplitude and phase conventions."""
    import rotorid
    from rotorid import plot

    rig = rotorid.nsf_rig()
    r = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["A"], speed_rpm=np.arange(500, 9000, 100.0))
    si = plot.polar(r)
    us = plot.polar(r, units="US", amplitude="pk-pk")
    a, b = (f.axes[0].lines[0].get_ydata() for f in (si, us))
    np.testing.assert_allclose(b, a * 2 * 1e-6 / 25.4e-6, rtol=1e-12)      # µm 0-pk -> mil pk-pk
    lag = si.axes[0].lines[0].get_xdata()
    arg = plot.polar(r, phase="arg").axes[0].lines[0].get_xdata()
    np.testing.assert_allclose(np.exp(1j * lag), np.exp(-1j * np.angle(r.q[:, 0])), atol=1e-12)
    np.testing.assert_allclose(np.exp(1j * arg), np.exp(1j * np.angle(r.q[:, 0])), atol=1e-12)
    t = rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=1000, freq_hz=np.arange(2, 200, 1.0), plane=0.0,
                           direction="x")
    f_si, f_us = plot.frf(t), plot.frf(t, units="US", phase="arg")
    m_si, m_us = (f.axes[0].lines[0].get_ydata() for f in (f_si, f_us))
    np.testing.assert_allclose(m_us, m_si * 1e-6 / 25.4e-6 * 4.4482216152605, rtol=1e-12)   # µm/N -> mil/lbf
    assert f_us.axes[0].get_ylabel() == "|H| (mil/lbf)" and f_us.axes[4].get_ylabel() == "Phase arg (deg)"
    with pytest.raises(rotorid.RotoridError):
        plot.polar(r, amplitude="rms")


def test_coefficient_plot_marks_values_beyond_its_range():
    """Without a truth the y range follows the points flagged ok; every point beyond it is drawn
    as a triangle on the edge and counted in the legend (nothing disappears without a sign)."""
    import dataclasses

    import rotorid
    from rotorid import plot

    rig = rotorid.nsf_rig()
    rpm = np.arange(300, 9000, 100.0)
    rng = np.random.default_rng(1)
    runs = []
    for s in "ABCD":
        r = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=rpm, at="bearings")
        noise = 0.03e-6 * (rng.standard_normal(r.q.shape) + 1j * rng.standard_normal(r.q.shape))
        runs.append(dataclasses.replace(r, q=r.q + noise))
    ident = rotorid.identify_synchronous(rig.rotor, runs)
    assert 0 < ident.ok.sum() < ident.ok.size
    fig = plot.coefficients(ident)
    ax = fig.axes[0]   # direct stiffness, MN/m
    y0, y1 = ax.get_ylim()
    vals = np.concatenate([ident.k[:, b, i, i] for b in range(2) for i in range(2)]) * 1e-6
    beyond = int(((vals < y0) | (vals > y1)).sum())
    assert beyond > 0
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert f"off scale ({beyond})" in labels
    ok_vals = np.concatenate([ident.k[ident.ok, b, i, i] for b in range(2) for i in range(2)]) * 1e-6
    assert ((ok_vals >= y0) & (ok_vals <= y1)).mean() > 0.9


@pytest.mark.parametrize("title", ["run $x^$", "$$", r"$\undefinedcommand$", "cost $5 and $6", r"$\omega$ sweep"])
def test_titles_that_are_not_valid_mathtext_are_drawn_literally(tmp_path, title):
    """A '$' pair in a run or file name started matplotlib's mathtext; one it cannot parse made
    every figure raise ValueError (rotorid identify: 'internal error', half a results folder)."""
    import matplotlib.pyplot as plt

    import rotorid
    from rotorid import plot

    rig = rotorid.nsf_rig()
    r = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["A"], speed_rpm=[2000.0, 3000.0])
    runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=[2000.0, 3000.0])
            for s in "AB"]
    ident = rotorid.identify_synchronous(rig.rotor, runs)
    try:
        for draw in (lambda p: plot.bode(r, title=title, x_label=title, path=p), lambda p: plot.polar(r, title=title, path=p),
                     lambda p: plot.frf(r.q, axis=r.speed_rpm, title=title, path=p),
                     lambda p: plot.coefficients(ident, title=title, path=p)):
            p = tmp_path / "f.png"
            draw(str(p))
            assert p.stat().st_size > 0
            p.unlink()
    finally:
        plt.close("all")
    assert plot._text("title", r"$\omega$ sweep") == r"$\omega$ sweep"     # valid mathtext is kept
    assert plot._text("title", "run $x^$") == r"run \$x^\$"


def test_polar_labels_beyond_the_points_are_one_per_point():
    """labels=10**12 asked numpy for a linspace of 10**12 values (7 TiB)."""
    import matplotlib.pyplot as plt

    import rotorid
    from rotorid import plot

    rig = rotorid.nsf_rig()
    r = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["A"], speed_rpm=[2000.0, 3000.0, 4000.0])
    try:
        fig = plot.polar(r, labels=10 ** 12)
        assert len(fig.axes[0].texts) == 3
    finally:
        plt.close("all")
