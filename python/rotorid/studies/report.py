"""Files of a study: tables, figures and a summary, written through a ResultsFolder (atomic, never
over a user's files without ``overwrite``)."""

from __future__ import annotations

import numpy as np

from .. import plot
from ..errors import RotoridError
from ..model import REPORT_ORDER
from .monte_carlo import StudyResult

GROUPS = (("Direct stiffness", (0, 1, 6, 7)), ("Cross-coupled stiffness", (2, 3, 4, 5)),
          ("Direct damping", (8, 9, 14, 15)), ("Cross-coupled damping", (10, 11, 12, 13)))
#: the files a study may write (checked before anything is computed)
PATTERNS = ["study_*", "design_*"]


def _errors_text(errors) -> str:
    from dataclasses import fields

    parts = [f"{f.name} {getattr(errors, f.name):g}" for f in fields(errors) if getattr(errors, f.name)]
    return ", ".join(parts) if parts else "no errors"


def _median(res: StudyResult):
    """The 50th percentile (n, 16), or None when it was neither computed nor can be."""
    if 50.0 in res.percentiles or res.counts is not None:
        return res.percentile(50)
    return None


def plot_percentiles(res: StudyResult, *, path=None, title=None):
    """The central band (lowest to highest percentile) and the median of each coefficient's
    relative error (%) against speed or frequency, one panel per coefficient group; symmetric-log
    y axis (linear within ±0.1 %). Each coefficient has its colour: the median as a solid line,
    the band's edges dashed (the edges alone when the 50th percentile was not computed); the
    group's whole band is shaded grey. Points where every trial was singular are left out.

    Examples
    --------
    >>> import numpy as np, rotorid
    >>> from rotorid.studies import SyncErrors, synchronous_study
    >>> from rotorid.studies.report import plot_percentiles
    >>> rig = rotorid.nsf_rig()
    >>> res = synchronous_study(rig.rotor, rig.bearings, [rig.imbalances[s] for s in "AB"],
    ...                         np.linspace(3000, 6000, 7), SyncErrors(phase_deg=0.2), trials=50)
    >>> fig = plot_percentiles(res)
    """
    if not isinstance(res, StudyResult):
        raise RotoridError(f"res must be a rotorid.studies.StudyResult, got {type(res).__name__}")
    import textwrap
    import warnings

    plt = plot._plt()
    lo, hi = min(res.percentiles), max(res.percentiles)
    plo, phi = res.percentile(lo) * 100, res.percentile(hi) * 100
    med = _median(res)
    med = None if med is None else med * 100
    x = res.axis
    marker = "o" if x.size < 3 else None  # a band of one or two points would not show
    fig, axes = plt.subplots(2, 2, figsize=(12, 8), sharex=True)
    for ax, (name, idx) in zip(axes.ravel(), GROUPS):
        with warnings.catch_warnings():  # a point where every trial was singular: NaN, left out
            warnings.simplefilter("ignore", RuntimeWarning)
            ax.fill_between(x, np.nanmin(plo[:, idx], axis=1), np.nanmax(phi[:, idx], axis=1), color="0.5",
                            alpha=0.15, linewidth=0)
        for j, o in enumerate(idx):
            color = f"C{j}"
            ax.plot(x, plo[:, o], color=color, linewidth=0.8, linestyle="--", marker=marker, markersize=3)
            edge = ax.plot(x, phi[:, o], color=color, linewidth=0.8, linestyle="--", marker=marker, markersize=3)
            if med is not None:
                ax.plot(x, med[:, o], color=color, linewidth=1.6, marker=marker, label=REPORT_ORDER[o])
            else:
                edge[0].set_label(REPORT_ORDER[o])
        ax.axhline(0, color="k", linewidth=0.8)
        ax.set_yscale("symlog", linthresh=0.1)
        ax.set_title(name, fontsize=11)
        ax.set_ylabel("Relative error (%)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=9, loc="best", ncol=2, framealpha=0.85)
    for ax in axes[1]:
        ax.set_xlabel("Rotor speed (rpm)" if res.axis_name == "speed_rpm" else "Frequency (Hz)")
    text = title or f"{res.kind.capitalize()} study, {res.trials} trials; errors (std): {_errors_text(res.errors)}"
    key = (f"solid: median; dashed: {lo:g}th and {hi:g}th percentiles; grey: the group's {lo:g}-{hi:g} band"
           if med is not None else f"dashed: {lo:g}th and {hi:g}th percentiles; grey: the group's band")
    fig.suptitle("\n".join(textwrap.wrap(text, 130) + [key]), fontsize=11)
    return plot.finish(fig, path)


def plot_coverage(res: StudyResult, *, path=None, title=None):
    """Coverage of the identification's confidence intervals per coefficient against the axis, with
    the nominal level."""
    if not isinstance(res, StudyResult) or res.coverage is None:
        raise RotoridError("res must be a StudyResult with coverage (coverage_trials > 0)")
    import warnings

    plt = plot._plt()
    fig, ax = plt.subplots(figsize=(10, 5))
    for gi, (name, idx) in enumerate(GROUPS):
        with warnings.catch_warnings():  # no finite interval at a point: NaN, left out
            warnings.simplefilter("ignore", RuntimeWarning)
            cov = np.nanmean(res.coverage[:, list(idx)], axis=1)
        ax.plot(res.axis, cov, marker="o", markersize=3, label=f"{name} (mean of 4)", color=f"C{gi}")
    ax.axhline(res.level, color="k", linestyle="--", label=f"nominal {res.level:g}")
    ax.set_ylim(0, 1.02)
    ax.set_xlabel("Rotor speed (rpm)" if res.axis_name == "speed_rpm" else "Frequency (Hz)")
    ax.set_ylabel("Coverage of the intervals")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=9)
    ax.set_title(title or f"Interval coverage over {res.coverage_trials} trials (random and systematic errors as "
                          "simulated; the intervals know only the per-vector ones)", fontsize=10)
    return plot.finish(fig, path)


def write_study(res: StudyResult, folder, *, bands=None, design=None, settings=None) -> list:
    """Write ``study_errors.csv``, ``study_bands.csv``, ``study_percentiles.png``,
    ``study_coverage.png`` (with coverage), ``study_summary.txt`` and, with a ``design``
    (DesignResult), ``design_ranking.csv`` and ``design_comparison.csv`` into the ResultsFolder
    ``folder``. ``bands``: as :meth:`StudyResult.band_summary` (default: four equal bands, or one
    per point for fewer than five points). Returns the file names."""
    names = []

    def put(name, write):
        with folder.atomic(name) as tmp:
            write(tmp)
        names.append(name)

    put("study_errors.csv", lambda p: res.to_dataframe().to_csv(p, index=False, float_format="%.6g"))
    if bands is None and np.unique(res.axis).size < 5:  # the default four bands would repeat points
        bands = [(float(v), float(v)) for v in np.unique(res.axis)]
    band = res.band_summary(bands)
    put("study_bands.csv", lambda p: band.to_csv(p, index=False, float_format="%.6g"))
    put("study_percentiles.png", lambda p: plot_percentiles(res, path=p))
    if res.coverage is not None:
        put("study_coverage.png", lambda p: plot_coverage(res, path=p))
    if design is not None:
        put("design_ranking.csv", lambda p: design.ranking.to_csv(p, index=False, float_format="%.6g"))
        put("design_comparison.csv", lambda p: design.comparison.to_csv(p, index=False, float_format="%.6g"))

    def summary(p):
        import pandas as pd

        with open(p, "w", encoding="utf-8") as fh:
            fh.write(f"rotorid {res.kind} study: {res.trials} trials, seed {res.seed}, method {res.method}\n")
            fh.write(f"runs/tests: {', '.join(res.runs)}\n")
            unit = "rpm" if res.axis_name == "speed_rpm" else "Hz"
            fh.write(f"{'speeds' if unit == 'rpm' else 'frequencies'}: {res.axis.size} from {res.axis.min():g} to "
                     f"{res.axis.max():g} {unit}\n")
            fh.write(f"percentiles: {', '.join(f'{q:g}' for q in res.percentiles)}\n")
            fh.write("interval coverage: " + (f"{res.coverage_trials} trials, level {res.level:g}\n"
                                               if res.coverage is not None else "not computed\n"))
            fh.write(f"errors (standard deviations): {_errors_text(res.errors)}\n")
            for k, v in (settings or {}).items():
                fh.write(f"{k}: {v}\n")
            lo, hi = min(res.percentiles), max(res.percentiles)
            cov = ", and the mean coverage" if res.coverage is not None else ""
            fh.write(f"\nMedian over each band of the half-width (p{hi:g} - p{lo:g})/2 of the relative errors "
                     f"(fractions, 0.01 = 1 %){cov}:\n")
            with pd.option_context("display.width", 160, "display.float_format", "{:.4g}".format):
                fh.write(band.to_string(index=False) + "\n")
            if design is not None:
                fh.write("\nTest design (expected coefficient error, fraction of the direct coefficients):\n")
                with pd.option_context("display.width", 200, "display.float_format", "{:.4g}".format):
                    fh.write(design.comparison.to_string(index=False) + "\n")
                for size, runs in design.best.items():
                    fh.write(f"recommended {size} runs: {' + '.join(r.name for r in runs)}\n")

    put("study_summary.txt", summary)
    return names
