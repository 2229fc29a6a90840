"""Plots of responses, modal results and identified coefficients (matplotlib, Agg-safe)."""

from __future__ import annotations

import numpy as np

from . import _validate as _v
from .errors import RotoridError

DOF_TITLES = ("Drive end (1), horizontal x", "Free end (2), horizontal x", "Drive end (1), vertical y",
              "Free end (2), vertical y")


#: resolution of saved figures (dots per inch): print quality
DPI = 150


def _plt():
    import matplotlib

    if matplotlib.get_backend().lower() not in ("agg", "module://matplotlib_inline.backend_inline"):
        try:
            matplotlib.use("Agg")
        except Exception:  # pragma: no cover - backend already in use
            pass
    import matplotlib.pyplot as plt

    return plt


def _path(path):
    """The file to save a plot to: None (or "") for none, else a path."""
    return None if path is None or isinstance(path, str) and path == "" else _v.path("path", path)


def _text(name, value):
    """A title or label as matplotlib can draw it: mathtext (``"$\\omega$"``) where it parses, else
    every ``$`` drawn literally (a run named ``"$x^$"`` would make the figure fail to render)."""
    import re

    from matplotlib import cbook

    s = _v.text(name, value)
    if cbook.is_math_text(s):
        from matplotlib.mathtext import MathTextParser

        try:
            MathTextParser("path").parse(s)
        except Exception:  # noqa: BLE001 - pyparsing's errors (ValueError) and any other refusal
            s = re.sub(r"(?<!\\)\$", r"\\$", s)
    return s


def finish(fig, path=None):
    """Lay out the figure; with ``path``, save it as PNG and close it (keeps memory flat in loops)."""
    path = _path(path)
    fig.tight_layout()
    if path is not None:
        try:
            fig.savefig(path, dpi=DPI)
        except (OSError, ValueError) as exc:  # no such folder, no permission, an unknown image format
            _plt().close(fig)
            raise RotoridError(f"cannot save the plot to {str(path)!r}: {exc}") from None
        _plt().close(fig)
    return fig


def bode(response, *, title="", path=None, x_label="Rotor speed (rpm)", axis=None, units="SI", amplitude="0-pk",
         phase="lag"):
    """Amplitude and phase of the four responses: by default µm 0-pk and phase lag (deg, 0-360, as
    a vibration DAQ shows it).

    ``response``: a SyncResponse (plotted over its speeds), an ImpactResponse (over its
    frequencies) or a complex (n, 4) array [x1, x2, y1, y2] with ``axis`` (n,) given. ``units``
    ("SI": µm, "US": mil), ``amplitude`` ("0-pk", "pk-pk") and ``phase`` ("lag", "arg": -180..180
    deg) as :class:`rotorid.units.OutputUnits` takes them."""
    from .simulate import ImpactResponse, SyncResponse
    from .units import OutputUnits

    title, x_label, path = _text("title", title), _text("x_label", x_label), _path(path)
    conv = OutputUnits(units, amplitude=amplitude, phase=phase)
    if isinstance(response, SyncResponse):
        q, x = response.q, response.speed_rpm
    elif isinstance(response, ImpactResponse):
        q, x = response.q, response.freq_hz
    else:
        try:
            q = _v.complex_array("response", response, ndim=2, finite=False)
            if q.shape[1] != 4 or q.shape[0] == 0:
                raise RotoridError(f"got shape {q.shape}")
        except RotoridError as exc:
            raise RotoridError("response must be a SyncResponse, an ImpactResponse or a complex (n, 4) array "
                               f"[x1, x2, y1, y2], got {type(response).__name__} ({exc})") from None
        if axis is None:
            raise RotoridError("axis (the speeds or frequencies of the rows) is needed when response is an array")
        x = None
    if axis is not None:
        x = _v.real_array("axis", axis, ndim=1)
    if x.shape != (q.shape[0],):
        raise RotoridError(f"axis must hold {q.shape[0]} values (one per row of the response), got shape {x.shape}")
    plt = _plt()
    fig, axes = plt.subplots(2, 4, figsize=(15, 6), sharex=True)
    for j in range(4):
        amp = conv.amplitude_of(q[:, j])
        # phase lag as a DAQ shows it: wrapped to 0-360 deg (a slowly turning unwrapped phase
        # climbs past 360 and reads like a different angle); arg in -180..180
        ph = conv.phase_of(q[:, j])
        axes[0, j].plot(x, amp)
        axes[0, j].set_title(DOF_TITLES[j], fontsize=9)
        axes[1, j].plot(x, ph, ".", ms=2.5)
        lo = 0 if conv.phase == "lag" else -180
        axes[1, j].set_ylim(lo, lo + 360)
        axes[1, j].set_yticks([lo + 90 * k for k in range(5)])
        axes[1, j].set_xlabel(x_label)
    axes[0, 0].set_ylabel(f"Amplitude ({conv.amplitude_text()})")
    axes[1, 0].set_ylabel("Phase lag (deg)" if conv.phase == "lag" else "Phase, arg (deg)")
    for a in axes.flat:
        a.grid(True, alpha=0.3)
    fig.suptitle(title)
    return finish(fig, path)


def coefficients(ident, truth=None, *, title="", path=None, show_flagged=True, ylim_factor=3.0, units="SI"):
    """Four panels: direct K, cross-coupled K, direct C, cross-coupled C, both bearings.

    ``units``: "SI" (MN/m, kN·s/m) or "US" (klbf/in, lbf·s/in).

    Points flagged by the identification (ok == False) are drawn as hollow markers; ``truth``
    (BearingCoefficients) is drawn as lines. Error bars: the 95 % confidence intervals
    (``ident.interval(0.95)``) where the uncertainty is known. The y range is clipped to
    ``ylim_factor`` times the truth range so that wild low-speed values do not hide the rest.
    """
    from .identify import Identification
    from .model import BearingCoefficients

    _v.instance("ident", ident, Identification, what="rotorid Identification")
    _v.instance("truth", truth, BearingCoefficients, allow_none=True, what="rotorid.BearingCoefficients")
    title, path, show_flagged = _text("title", title), _path(path), _v.flag("show_flagged", show_flagged)
    ylim_factor = _v.number("ylim_factor", ylim_factor, nonneg=True)
    plt = _plt()
    x = ident.axis
    xlabel = "Rotor speed (rpm)" if ident.axis_name == "speed_rpm" else "Frequency (Hz)"
    from .units import OutputUnits, factor

    ku, cu = ("MN/m", "kN·s/m") if OutputUnits(units).units == "SI" else ("klbf/in", "lbf·s/in")
    ks, cs = 1.0 / factor(ku.replace("·", "*"), "stiffness"), 1.0 / factor(cu.replace("·", "*"), "damping")
    groups = [("K", [(0, 0), (1, 1)], f"Direct stiffness ({ku})", ks, ident.k),
              ("K", [(0, 1), (1, 0)], f"Cross-coupled stiffness ({ku})", ks, ident.k),
              ("C", [(0, 0), (1, 1)], f"Direct damping ({cu})", cs, ident.c),
              ("C", [(0, 1), (1, 0)], f"Cross-coupled damping ({cu})", cs, ident.c)]
    fig, axes = plt.subplots(2, 2, figsize=(13, 8.5), sharex=True)
    markers = ["o", "s", "^", "v"]
    iv = ident.interval(0.95)
    half_k = 0.5 * (iv.k_upper - iv.k_lower)
    half_c = 0.5 * (iv.c_upper - iv.c_lower)
    clipped_any = False
    for ax, (sym, pairs, label, scale, arr) in zip(axes.flat, groups):
        tvals = []
        shown = []    # (x, y, colour, marker) of every point drawn, for the off-scale marks
        m = 0
        for b in range(2):
            for (i, j) in pairs:
                name = f"{sym}{'xy'[i]}{'xy'[j]}{b + 1}"
                y = arr[:, b, i, j] * scale
                err = (half_k if sym == "K" else half_c)[:, b, i, j] * scale
                ok = ident.ok
                line = ax.plot(x[ok], y[ok], markers[m], ms=3.5, label=name)[0]
                has = np.isfinite(err)
                if (ok & has).any():
                    ax.errorbar(x[ok & has], y[ok & has], yerr=err[ok & has], fmt="none", ecolor=line.get_color(),
                                elinewidth=0.8, capsize=1.5, alpha=0.7)
                if show_flagged and (~ok).any():
                    ax.plot(x[~ok], y[~ok], markers[m], ms=3.5, mfc="none", color=line.get_color(), alpha=0.6)
                shown.append((x[ok | show_flagged], y[ok | show_flagged], ok[ok | show_flagged], line.get_color()))
                if truth is not None:
                    kk, cc = truth.at(**{ident.axis_name: x}) if not truth.is_constant else truth.at()
                    tv = (kk if sym == "K" else cc)
                    tv = np.broadcast_to(tv[..., b, i, j], x.shape) * scale
                    ax.plot(x, tv, "-", color=line.get_color(), lw=1)
                    tvals.append(tv)
                m += 1
        # what the line styles and hollow markers mean, in the legend
        if truth is not None:
            ax.plot([], [], "-", color="0.3", lw=1, label="truth")
        if show_flagged and (~ident.ok).any():
            ax.plot([], [], "o", ms=3.5, mfc="none", color="0.3", label="flagged")
        # the y range: around the truth when known, else around the points flagged ok (robustly:
        # 10th-90th percentile), so that wild flagged values do not squash the rest; points beyond it
        # are drawn as triangles on the edge and counted in the legend
        ref = np.concatenate(tvals) if tvals else np.concatenate([y[k] for _, y, k, _ in shown]) if shown else []
        ref = np.asarray(ref, float)
        ref = ref[np.isfinite(ref)]
        if ref.size:
            lo, hi = (ref.min(), ref.max()) if tvals else tuple(np.percentile(ref, [10, 90]))
            span = max(hi - lo, 0.25 * max(abs(hi), abs(lo)), 1e-12)
            y0, y1 = lo - ylim_factor * span / 2, hi + ylim_factor * span / 2
            ally = np.concatenate([p[1] for p in shown]) if shown else np.array([])
            if ally.size and np.isfinite(ally).any() and (np.nanmin(ally) >= y0 and np.nanmax(ally) <= y1):
                pass  # everything fits: keep matplotlib's own range
            else:
                ax.set_ylim(y0, y1)
                off = 0
                for px, py, _, colour in shown:
                    above, below = py > y1, py < y0
                    off += int(above.sum() + below.sum())
                    edge = 0.015 * (y1 - y0)    # just inside the frame, so the mark is seen whole
                    ax.plot(px[above], np.full(above.sum(), y1 - edge), "^", ms=6, color=colour, alpha=0.8)
                    ax.plot(px[below], np.full(below.sum(), y0 + edge), "v", ms=6, color=colour, alpha=0.8)
                if off:
                    clipped_any = True
                    ax.plot([], [], "^", ms=6, color="0.3", label=f"off scale ({off})")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, ncol=2)
    for ax in axes[1]:
        ax.set_xlabel(xlabel)
    notes = []
    if np.isfinite(half_k).any():
        notes.append(f"error bars: 95 % intervals ({ident.std_source})")
    if show_flagged and (~ident.ok).any():
        notes.append("hollow markers: points flagged as not trustworthy")
    if clipped_any:
        notes.append("triangles on an edge: values beyond the plotted range")
    fig.suptitle(title + ("\n(" + "; ".join(notes) + ")" if notes else ""))
    return finish(fig, path)


def pedestal_compensation(without, with_pedestal, truth, *, title="", path=None):
    """Direct stiffness and damping of both bearings identified from the same runs, ignoring the
    pedestals' motion (left) and with it (right), on shared axes, with 95 % intervals and the
    truth (BearingCoefficients) as lines."""
    from .identify import Identification
    from .model import BearingCoefficients

    for name, v in (("without", without), ("with_pedestal", with_pedestal)):
        _v.instance(name, v, Identification, what="rotorid Identification")
    _v.instance("truth", truth, BearingCoefficients, what="rotorid.BearingCoefficients")
    title, path = _text("title", title), _path(path)
    plt = _plt()
    fig, axes = plt.subplots(2, 2, figsize=(13, 8), sharex=True, sharey="row")
    direct = [(b, i) for b in range(2) for i in range(2)]
    for col, (ident, head) in enumerate(((without, "pedestal motion ignored"),
                                         (with_pedestal, "with the housing accelerometers"))):
        x = ident.axis
        kk, cc = truth.at(speed_rpm=x) if not truth.is_constant else truth.at()
        iv = ident.interval(0.95)
        for row, (sym, arr, lo, hi, tv, scale, unit) in enumerate((
                ("K", ident.k, iv.k_lower, iv.k_upper, kk, 1e-6, "Direct stiffness (MN/m)"),
                ("C", ident.c, iv.c_lower, iv.c_upper, cc, 1e-3, "Direct damping (kN·s/m)"))):
            ax = axes[row, col]
            for m, (b, i) in enumerate(direct):
                y = arr[:, b, i, i] * scale
                err = 0.5 * (hi - lo)[:, b, i, i] * scale
                line = ax.plot(x, y, "osv^"[m], ms=3, label=f"{sym}{'xy'[i] * 2}{b + 1}")[0]
                has = np.isfinite(err)
                ax.errorbar(x[has], y[has], yerr=err[has], fmt="none", ecolor=line.get_color(), elinewidth=0.7,
                            alpha=0.6)
                ax.plot(x, np.broadcast_to(tv[..., b, i, i], x.shape) * scale, "-", color=line.get_color(), lw=1)
            ax.set_title(head if row == 0 else "")
            ax.grid(True, alpha=0.3)
            if col == 0:
                ax.set_ylabel(unit)
            if row == 1:
                ax.set_xlabel("Rotor speed (rpm)")
            ax.legend(fontsize=8, ncol=2)
    # the axes follow the compensated result (the truth's scale); the erratic values leave them
    for row, arr, scale in ((0, with_pedestal.k, 1e-6), (1, with_pedestal.c, 1e-3)):
        vals = np.concatenate([arr[:, b, i, i] * scale for b, i in direct])
        vals = vals[np.isfinite(vals)]
        if vals.size:
            lo, hi = np.percentile(vals, [1, 99])
            span = max(hi - lo, 0.2 * abs(hi))
            axes[row, 0].set_ylim(lo - span, hi + span)
    fig.suptitle(title + "\n(lines: truth; error bars: 95 % intervals)")
    return finish(fig, path)


def comparison(cmp, *, title="", path=None):
    """Identified coefficients (points, 95 % intervals; hollow where flagged) and predicted ones
    (lines) of a :class:`rotorid.support.compare.Comparison`, in four panels: direct and
    cross-coupled stiffness and damping of both bearings."""
    from .support.compare import Comparison

    _v.instance("cmp", cmp, Comparison, what="rotorid.support.compare.Comparison")
    title, path = _text("title", title), _path(path)
    plt = _plt()
    x = cmp.axis
    idx = {n: j for j, n in enumerate(cmp.names)}
    groups = [(("Kxx1", "Kyy1", "Kxx2", "Kyy2"), "Direct stiffness (MN/m)", 1e-6),
              (("Kxy1", "Kyx1", "Kxy2", "Kyx2"), "Cross-coupled stiffness (MN/m)", 1e-6),
              (("Cxx1", "Cyy1", "Cxx2", "Cyy2"), "Direct damping (kN·s/m)", 1e-3),
              (("Cxy1", "Cyx1", "Cxy2", "Cyx2"), "Cross-coupled damping (kN·s/m)", 1e-3)]
    fig, axes = plt.subplots(2, 2, figsize=(13, 8.5), sharex=True)
    ok = cmp.ok
    for ax, (names, label, scale) in zip(axes.flat, groups):
        for m, name in enumerate(names):
            j = idx[name]
            y, p = cmp.identified[:, j] * scale, cmp.predicted[:, j] * scale
            lo, hi = cmp.lower[:, j] * scale, cmp.upper[:, j] * scale
            line = ax.plot(x, p, "-", lw=1.2, label=f"{name} predicted")[0]
            col = line.get_color()
            has = ok & np.isfinite(lo) & np.isfinite(hi)
            ax.errorbar(x[has], y[has], yerr=[y[has] - lo[has], hi[has] - y[has]], fmt="osv^"[m], ms=3.5, color=col,
                        elinewidth=0.8, capsize=1.5, label=f"{name} identified")
            if (~ok).any():
                ax.plot(x[~ok], y[~ok], "osv^"[m], ms=3.5, mfc="none", color=col, alpha=0.5)
        # the range of the prediction and of the identified points (robust to wild flagged ones)
        vals = np.concatenate([cmp.predicted[:, idx[n]] * scale for n in names] +
                              [cmp.identified[ok if ok.any() else slice(None), idx[n]] * scale for n in names])
        vals = vals[np.isfinite(vals)]
        lo_, hi_ = (np.percentile(vals, 2), np.percentile(vals, 98)) if vals.size else (0.0, 1.0)
        span = max(hi_ - lo_, 0.25 * max(abs(hi_), abs(lo_)), 1e-12)
        ax.set_ylim(lo_ - 1.5 * span, hi_ + 1.5 * span)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, ncol=2)
    for ax in axes[1]:
        ax.set_xlabel("Rotor speed (rpm)" if cmp.axis_name == "speed_rpm" else "Frequency (Hz)")
    fig.suptitle(title + f"\n(lines: predicted; points: identified with {int(100 * cmp.level)} % intervals; hollow: "
                         "flagged)")
    return finish(fig, path)


def campbell(modal_result, *, crit=None, path=None, title="Campbell diagram"):
    """Damped natural frequencies (cpm) over speed with the 1X line; ``crit``, the DataFrame of
    :func:`rotorid.critical_speeds`, marks the critical speeds."""
    from .modal import ModalResult

    _v.instance("modal_result", modal_result, ModalResult, what="rotorid ModalResult (from modal_analysis)")
    title, path = _text("title", title), _path(path)
    if crit is not None:
        import pandas as pd

        need = ["speed_rpm", "freq_hz", "damping_ratio_wd", "whirl"]
        if not isinstance(crit, pd.DataFrame) or any(c not in crit.columns for c in need):
            raise RotoridError(f"crit must be the DataFrame of rotorid.critical_speeds (columns {need}) or None, got "
                               f"{type(crit).__name__}")
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 6))
    rpm = modal_result.speed_rpm
    f = modal_result.freq_hz * 60
    for m in range(f.shape[1]):
        ax.plot(rpm, f[:, m], label=f"mode {m + 1}")
    ax.plot(rpm, rpm, "k--", lw=1, label="1X")
    if crit is not None and len(crit):
        ax.plot(crit.speed_rpm, crit.freq_hz * 60, "ko", mfc="none", label="critical speeds")
        # labels right of each crossing, stepped down where crossings lie close together, never cut
        last_y = np.inf
        for _, r in crit.sort_values("speed_rpm", ascending=False).iterrows():
            y = min(r.freq_hz * 60, last_y - 0.06 * max(rpm.max(), 1.0))
            last_y = y
            ax.annotate(f"{r.speed_rpm:.0f} rpm, ζ = {r.damping_ratio_wd:.3f}, {r.whirl}",
                        (r.speed_rpm, r.freq_hz * 60), xytext=(r.speed_rpm + 0.02 * rpm.max(), y), fontsize=8,
                        va="center", arrowprops=dict(arrowstyle="-", lw=0.5, color="0.5"), annotation_clip=False)
    ax.set_xlabel("Rotor speed (rpm)")
    ax.set_ylabel("Damped natural frequency (cpm)")
    ax.set_xlim(rpm.min(), rpm.max() * 1.45)   # room for the labels on the right
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    ax.set_title(title)
    return finish(fig, path)


def _response_and_axis(response, axis, what):
    """(q (n, 4), x (n,), x label) of a SyncResponse, an ImpactResponse or an (n, 4) array + axis."""
    from .simulate import ImpactResponse, SyncResponse

    if isinstance(response, SyncResponse):
        q, x, label = response.q, response.speed_rpm, "Rotor speed (rpm)"
    elif isinstance(response, ImpactResponse):
        q, x, label = response.q, response.freq_hz, "Frequency (Hz)"
    else:
        try:
            q = _v.complex_array(what, response, ndim=2, finite=False)
            if q.shape[1] != 4 or q.shape[0] == 0:
                raise RotoridError(f"got shape {q.shape}")
        except RotoridError as exc:
            raise RotoridError(f"{what} must be a SyncResponse, an ImpactResponse or a complex (n, 4) array "
                               f"[x1, x2, y1, y2], got {type(response).__name__} ({exc})") from None
        if axis is None:
            raise RotoridError("axis (the speeds or frequencies of the rows) is needed when the response is an array")
        x, label = None, "Frequency (Hz)"
    if axis is not None:
        x = _v.real_array("axis", axis, ndim=1)
    if x.shape != (q.shape[0],):
        raise RotoridError(f"axis must hold {q.shape[0]} values (one per row of the response), got shape {x.shape}")
    return q[:, :4], x, label


def polar(response, *, title="", path=None, axis=None, labels=5, units="SI", amplitude="0-pk", phase="lag"):
    """Polar plot of the measured 1X vectors, one panel per probe, as a vibration DAQ draws it.

    Radius: amplitude (``units`` "SI": µm, "US": mil; ``amplitude`` "0-pk" or "pk-pk"); angle:
    with ``phase="lag"`` the phase lag, 0° at the top and increasing clockwise, with ``"arg"``
    arg(X), 0° to the right and increasing counter-clockwise. The curve runs from the lowest to
    the highest speed; ``labels`` speeds along it are written beside their points (rpm).
    ``response``: a SyncResponse, or a complex (n, 4) array with ``axis`` (rpm).

    Examples
    --------
    >>> import rotorid, numpy as np
    >>> rig = rotorid.nsf_rig()
    >>> r = rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances["A"], speed_rpm=np.arange(500, 9000, 100.0))
    >>> fig = rotorid.plot.polar(r, title="set A")
    >>> len(fig.axes)
    4
    """
    from .units import OutputUnits

    q, x, _ = _response_and_axis(response, axis, "response")
    title, path = _text("title", title), _path(path)
    labels = int(_v.number("labels", labels, nonneg=True))
    conv = OutputUnits(units, amplitude=amplitude, phase=phase)
    lag_view = conv.phase == "lag"
    plt = _plt()
    fig, axes = plt.subplots(1, 4, figsize=(16, 4.6), subplot_kw={"projection": "polar"})
    order = np.argsort(x)
    # at most one label per point (labels=10**12 would ask linspace for terabytes)
    pick = (order[np.unique(np.linspace(0, x.size - 1, min(labels, x.size)).round().astype(int))] if labels and x.size
            else [])
    sign = -1.0 if lag_view else 1.0
    for j, ax in enumerate(axes):
        amp = conv.amplitude_of(q[order, j])
        # the angle unwrapped along the sweep, so the curve does not cut back across the plot at 0/360
        th = sign * np.unwrap(np.angle(q[order, j]))
        th -= 2 * np.pi * np.floor(th[0] / (2 * np.pi)) if th.size and np.isfinite(th[0]) else 0.0
        if lag_view:
            ax.set_theta_zero_location("N")
            ax.set_theta_direction(-1)        # lag grows clockwise
        ax.plot(th, amp, "-o", lw=1, ms=2.5 if x.size <= 60 else 0)
        ax.plot(th[:1], amp[:1], "o", ms=4, color="0.3")      # where the sweep starts
        for i in pick:
            ax.annotate(f"{x[i]:.0f}", (sign * np.angle(q[i, j]), conv.amplitude_of(q[i, j])), fontsize=7,
                        color="0.25", xytext=(3, 3), textcoords="offset points")
        ax.set_title(DOF_TITLES[j], fontsize=9, pad=14)
        ax.tick_params(labelsize=7)
    angle = "phase lag (deg, clockwise from the top)" if lag_view else "arg(X) (deg, counter-clockwise)"
    fig.suptitle((title + "\n" if title else "") + f"1X vectors: radius amplitude ({conv.amplitude_text()}), angle "
                 f"{angle}; labels: rpm; dot: lowest speed", fontsize=10)
    return finish(fig, path)


def frf(response, coherence=None, *, coherence_min=None, title="", path=None, axis=None, units="SI", phase="lag"):
    """FRFs with their coherence: magnitude (``units`` "SI": µm/N, "US": mil/lbf; log scale),
    phase (``phase`` "lag": 0-360 deg as a DAQ shows it, "arg": -180..180) and, under them, the
    coherence of each of the four probes.

    ``response``: an ImpactResponse (its FRF, i.e. response per unit force), a
    ``rotorid.signals.FRF`` (H1 with its coherence) or a complex (n, 4) array with ``axis`` (Hz).
    ``coherence``: (n, 4) or None (taken from an FRF object; without it the coherence row is left out).
    ``coherence_min`` draws the threshold below which points are flagged.

    Examples
    --------
    >>> import rotorid, numpy as np
    >>> rig = rotorid.nsf_rig()
    >>> t = rotorid.impact_frf(rig.rotor, rig.bearings, speed_rpm=1000, freq_hz=np.arange(2, 200, 0.5), plane=0.0, direction="x")
    >>> fig = rotorid.plot.frf(t, np.ones((t.freq_hz.size, 4)), coherence_min=0.9, title="test x")
    >>> len(fig.axes)
    12
    """
    from .signals.impacts import FRF
    from .simulate import ImpactResponse

    if isinstance(response, FRF):
        coherence = response.coherence if coherence is None else coherence
        response, axis = response.h, response.freq_hz if axis is None else axis
    elif isinstance(response, ImpactResponse):
        response, axis = response.frf(), response.freq_hz if axis is None else axis
    from .units import OutputUnits, factor

    q, x, _ = _response_and_axis(response, axis, "response")
    title, path = _text("title", title), _path(path)
    conv = OutputUnits(units, phase=phase)
    per_force = factor(conv.force_unit) / factor(conv.length_unit)   # m/N -> length unit per force unit
    if coherence is not None:
        coherence = _v.real_array("coherence", coherence, ndim=2, finite=False)
        if coherence.shape[0] != q.shape[0] or coherence.shape[1] < 4:
            raise RotoridError(f"coherence must be ({q.shape[0]}, 4) like the FRFs, got {coherence.shape}")
    if coherence_min is not None:
        coherence_min = _v.number("coherence_min", coherence_min, nonneg=True)
    plt = _plt()
    rows = 3 if coherence is not None else 2
    fig, axes = plt.subplots(rows, 4, figsize=(15, 2.6 * rows + 1), sharex=True,
                             gridspec_kw={"height_ratios": [2, 1.4, 1][:rows]})
    for j in range(4):
        mag = per_force * np.abs(q[:, j])
        axes[0, j].semilogy(x, np.where(mag > 0, mag, np.nan), lw=1)
        axes[0, j].set_title(DOF_TITLES[j], fontsize=9)
        axes[1, j].plot(x, conv.phase_of(q[:, j]), ".", ms=2)
        axes[1, j].set_ylim(*((0, 360) if conv.phase == "lag" else (-180, 180)))
        axes[1, j].set_yticks([0, 90, 180, 270, 360] if conv.phase == "lag" else [-180, -90, 0, 90, 180])
        if coherence is not None:
            c = coherence[:, j]
            axes[2, j].plot(x, c, lw=1, color="tab:green")
            axes[2, j].set_ylim(0, 1.05)
            if coherence_min is not None:
                axes[2, j].axhline(coherence_min, color="tab:red", lw=0.8, ls="--",
                                   label=f"flag below {coherence_min:g}")
                low = c < coherence_min
                if low.any():
                    axes[2, j].plot(x[low], c[low], "x", ms=4, color="tab:red")
                axes[2, j].legend(fontsize=7, loc="lower left")
        axes[-1, j].set_xlabel("Frequency (Hz)")
    axes[0, 0].set_ylabel(f"|H| ({conv.length_label}/{conv.force_unit})")
    axes[1, 0].set_ylabel("Phase lag (deg)" if conv.phase == "lag" else "Phase arg (deg)")
    if coherence is not None:
        axes[2, 0].set_ylabel("Coherence")
    for a in axes.flat:
        a.grid(True, alpha=0.3)
    fig.suptitle(title)
    return finish(fig, path)
