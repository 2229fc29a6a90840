"""The report's figures as PNG bytes: the coefficients with their 95 % intervals (rotorid.plot),
the per-point diagnostics against their thresholds, the Bode plots of the imbalance runs."""

from __future__ import annotations

import base64
import io

import numpy as np

#: resolution of the embedded figures (screen; the PNG files of rotorid identify use plot.DPI)
DPI = 96


def png_bytes(fig) -> bytes:
    """The figure as PNG (no metadata, so no URL of the plotting library in the page), closed."""
    from ..plot import _plt

    buf = io.BytesIO()
    try:
        fig.savefig(buf, format="png", dpi=DPI, metadata={"Software": None})
    finally:
        _plt().close(fig)
    return buf.getvalue()


def data_uri(png: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def mpl_text(s) -> str:
    """A user's text as matplotlib draws it literally (a "$" would start mathtext, which can fail)."""
    return str(s).replace("$", r"\$")


def coefficients(ident, truth, title, units="SI"):
    from .. import plot

    return png_bytes(plot.coefficients(ident, truth, title=mpl_text(title), units=units))


def diagnostics(ident, thresholds):
    """Condition numbers, largest relative standard error, relative amplitude and residual per
    point; flagged points in red, the thresholds as dashed lines."""
    from ..plot import _plt, finish

    plt = _plt()
    x = ident.axis
    bad = ~ident.ok
    xlabel = "Rotor speed (rpm)" if ident.axis_name == "speed_rpm" else "Frequency (Hz)"
    fig, axes = plt.subplots(2, 2, figsize=(12, 6.5), sharex=True)
    rel_std = ident.rel_std if ident.rel_std is not None else np.full(x.size, np.nan)
    panels = [(axes[0, 0], [(ident.cond[:, 0], "bearing 1"), (ident.cond[:, 1], "bearing 2")],
               "Condition number", thresholds.get("cond_max"), True),
              (axes[0, 1], [(100 * rel_std, "largest")], "Relative standard error (%)",
               None if thresholds.get("max_rel_std") is None else 100 * thresholds["max_rel_std"], True),
              (axes[1, 0], [(ident.rel_amplitude, "rms")], "Relative response amplitude",
               thresholds.get("min_rel_amplitude"), False),
              (axes[1, 1], [(ident.residual, "relative")], "Least-squares residual", None, True)]
    for ax, series, label, limit, log in panels:
        for y, name in series:
            y = np.asarray(y, float)
            pos = np.isfinite(y) & ((y > 0) if log else True)
            line = ax.plot(x[pos], y[pos], "o-", ms=3, lw=0.8, label=name)[0]
            sel = pos & bad
            if sel.any():
                ax.plot(x[sel], y[sel], "x", ms=6, color="#c0392b", mew=1.4)
            line.set_zorder(2)
        if limit is not None and np.isfinite(limit):
            ax.axhline(limit, ls="--", lw=1, color="0.35", label="threshold")
        if log and any(np.any(np.isfinite(y) & (np.asarray(y, float) > 0)) for y, _ in series):
            ax.set_yscale("log")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3, which="both")
        if bad.any():
            ax.plot([], [], "x", color="#c0392b", label="flagged point")
        ax.legend(fontsize=8)
    for ax in axes[1]:
        ax.set_xlabel(xlabel)
    fig.suptitle("Diagnostics per point")
    return png_bytes(finish(fig))


def bode(name, axis, q, units="SI"):
    from .. import plot

    return png_bytes(plot.bode(q, axis=axis, title=f"Compensated 1X response, run {mpl_text(name)}", units=units))
