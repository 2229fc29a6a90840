"""The HTML of the report: one self-contained page (inline CSS, PNG figures as data URIs, no
script, no external reference). Every text that comes from a user (names, settings, paths,
warnings) passes through :func:`esc`."""

from __future__ import annotations

import html
import json
import math

import numpy as np

from ..model import REPORT_ORDER

#: display units: (stiffness label, factor from N/m), (damping label, factor from N*s/m)
DISPLAY = {"SI": (("MN/m", 1e-6), ("kN·s/m", 1e-3)),
           "US": (("lbf/in", 0.0254 / 4.4482216152605), ("lbf·s/in", 0.0254 / 4.4482216152605))}

#: what each flag reason means, and the diagnostic that shows it
REASONS = {
    "singular": "the response matrix of a bearing is singular (condition number above 1e14): the coefficients "
                "are not determined",
    "ill-conditioned": "the condition number of a bearing's response matrix is above cond_max: errors in the "
                       "responses are amplified by about that factor",
    "uncertain": "a standard error is above max_rel_std of the bearing's direct coefficients",
    "low amplitude": "the response amplitude is below min_rel_amplitude of its largest value over the axis",
    "coherence < 0.9": "the impact FRFs have a coherence below 0.9 at this frequency",
    "uncertainty unknown": "no standard error could be computed for this point",
}

CSS = """
body{font-family:"DejaVu Sans",Helvetica,Arial,sans-serif;font-size:14px;color:#1d2733;margin:0;background:#f4f6f8}
main{max-width:1180px;margin:0 auto;padding:24px 32px 48px;background:#fff}
h1{font-size:24px;margin:0 0 4px}h2{font-size:19px;border-bottom:2px solid #2c5d8a;padding-bottom:3px;margin-top:34px}
h3{font-size:15px;margin:20px 0 6px}.sub{color:#55606e;margin:0 0 14px}
table{border-collapse:collapse;margin:6px 0 14px;font-size:12.5px}
th,td{border:1px solid #cfd6de;padding:3px 7px;text-align:right;vertical-align:top}
th{background:#e9eef3;font-weight:600;text-align:center}td.l,th.l{text-align:left}
tr.flagged td{background:#fdf1ef}td.ok{color:#1e7b34;text-align:center}td.bad{color:#b03a2e;text-align:center}
.iv{display:block;color:#667281;font-size:11px;white-space:nowrap}
.kv td:first-child{text-align:left;color:#44505e;background:#f6f8fa}.kv td{text-align:left}
.mono,pre{font-family:"DejaVu Sans Mono",Consolas,monospace;font-size:12px}
pre{background:#f6f8fa;border:1px solid #dde3ea;padding:10px;overflow-x:auto;white-space:pre-wrap}
img{max-width:100%;border:1px solid #e3e8ee;margin:6px 0}
.badge{display:inline-block;padding:1px 8px;border-radius:9px;font-size:12px;font-weight:600}
.b-ok{background:#e3f4e6;color:#1e7b34}.b-bad{background:#fbe4e1;color:#b03a2e}
.warn{background:#fff7e0;border-left:4px solid #e0a800;padding:6px 10px;margin:4px 0}
.matrices{display:flex;flex-wrap:wrap;gap:18px}nav{font-size:13px;margin:10px 0}nav a{margin-right:12px}
a{color:#2c5d8a}footer{color:#667281;font-size:12px;margin-top:30px;border-top:1px solid #dde3ea;padding-top:8px}
.wide{overflow-x:auto}table.flagged ul{margin:0;padding-left:18px}table.flagged td{text-align:left}
@media print{body{background:#fff}main{padding:0}h2{page-break-after:avoid}img{page-break-inside:avoid}}
"""


def esc(value) -> str:
    """HTML text of any value (quotes escaped too, so it is safe in attributes)."""
    return html.escape(str(value), quote=True)


def num(v, digits: int = 5) -> str:
    v = float(v)
    if math.isnan(v):
        return "–"
    if math.isinf(v):
        return "∞" if v > 0 else "−∞"
    return f"{v:.{digits}g}"


def pct(v) -> str:
    v = float(v)
    return "–" if not math.isfinite(v) else f"{100 * v:.3g} %"


def rel_std_groups(ident):
    """Median over points of the standard errors relative to the bearing's direct coefficients:
    {"K direct": .., "K cross": .., "C direct": .., "C cross": ..} over the ok points (all points
    when none is ok) and which points they are."""
    sel = ident.ok if ident.ok.any() else np.ones(ident.axis.size, bool)
    out = {}
    for sym, val, std in (("K", ident.k, ident.k_std), ("C", ident.c, ident.c_std)):
        scale = 0.5 * (np.abs(val[..., 0, 0]) + np.abs(val[..., 1, 1]))[..., None, None]  # (n, 2, 1, 1)
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = std / scale
        direct = np.stack([rel[:, :, 0, 0], rel[:, :, 1, 1]], -1)[sel].ravel()
        cross = np.stack([rel[:, :, 0, 1], rel[:, :, 1, 0]], -1)[sel].ravel()
        for what, a in (("direct", direct), ("cross-coupled", cross)):
            a = a[np.isfinite(a)]
            out[f"{sym} {what}"] = float(np.median(a)) if a.size else math.nan
    return out, bool(ident.ok.any())


def kv_table(rows) -> str:
    body = "".join(f"<tr><td>{esc(k)}</td><td>{v}</td></tr>" for k, v in rows)
    return f'<table class="kv">{body}</table>'


def axis_label(ident) -> str:
    return "speed (rpm)" if ident.axis_name == "speed_rpm" else "frequency (Hz)"


def status_cell(ident, i) -> str:
    if ident.ok[i]:
        return '<td class="ok">ok</td>'
    return f'<td class="bad"><a href="#flag-{i}">flagged</a></td>'


def coefficient_tables(ident, units) -> str:
    """One table per quantity and bearing; rows are the points, columns xx, xy, yx, yy, each the
    value with its 95 % interval below. Every cell carries its SI numbers as data attributes."""
    iv = ident.interval(0.95)
    (ku, kf), (cu, cf) = DISPLAY[units]
    parts = []
    for sym, val, lo, hi, unit, f, what in (("K", ident.k, iv.k_lower, iv.k_upper, ku, kf, "Stiffness"),
                                            ("C", ident.c, iv.c_lower, iv.c_upper, cu, cf, "Damping")):
        for b in range(2):
            head = "".join(f"<th>{sym}<sub>{i}{j}</sub></th>" for i in "xy" for j in "xy")
            rows = []
            for p in range(ident.axis.size):
                cells = []
                for i in range(2):
                    for j in range(2):
                        name = f"{sym}{'xy'[i]}{'xy'[j]}{b + 1}"
                        v, a, z = (float(x[p, b, i, j]) for x in (val, lo, hi))
                        interval = f"[{num(a * f)}, {num(z * f)}]" if math.isfinite(a) and math.isfinite(z) else \
                            "[unknown]"
                        cells.append(f'<td data-coef="{name}" data-value="{v!r}" data-lo="{a!r}" data-hi="{z!r}">'
                                     f'{num(v * f)}<span class="iv">{interval}</span></td>')
                cls = "" if ident.ok[p] else ' class="flagged"'
                rows.append(f"<tr{cls}><td>{num(ident.axis[p], 6)}</td>{status_cell(ident, p)}{''.join(cells)}</tr>")
            parts.append(f'<div><h3 id="table-{sym}{b + 1}">{what}, bearing {b + 1} ({esc(unit)})</h3>'
                         f'<div class="wide"><table class="coef" data-quantity="{sym}" '
                         f'data-bearing="{b + 1}"><thead><tr><th>{esc(axis_label(ident))}</th><th>status</th>{head}'
                         f'</tr></thead><tbody>{"".join(rows)}</tbody></table></div></div>')
    note = ("<p>Each cell: the identified value and, below it, its 95 % confidence interval. Tinted rows are "
            "flagged points (see below).</p>")
    return note + "".join(f'<div class="matrices">{parts[i]}{parts[i + 1]}</div>' for i in (0, 2))


def median_matrices(ident, units) -> str:
    """Median K and C of each bearing over the ok points, with the median half-width of the
    95 % intervals."""
    sel = ident.ok
    if not sel.any():
        return "<p>No point is flagged ok: no summary coefficients (see the tables and the flagged points).</p>"
    iv = ident.interval(0.95)
    (ku, kf), (cu, cf) = DISPLAY[units]
    out = []
    for sym, val, lo, hi, unit, f in (("K", ident.k, iv.k_lower, iv.k_upper, ku, kf),
                                      ("C", ident.c, iv.c_lower, iv.c_upper, cu, cf)):
        for b in range(2):
            rows = []
            for i in range(2):
                cells = []
                for j in range(2):
                    med = float(np.median(val[sel, b, i, j]))
                    half = 0.5 * (hi - lo)[sel, b, i, j]
                    half = half[np.isfinite(half)]
                    pm = f" ± {num(np.median(half) * f, 3)}" if half.size else ""
                    cells.append(f'<td data-coef="{sym}{"xy"[i]}{"xy"[j]}{b + 1}" data-median="{med!r}">'
                                 f"{num(med * f)}{pm}</td>")
                rows.append(f"<tr><th>{'xy'[i]}</th>{''.join(cells)}</tr>")
            out.append(f'<table class="median"><caption>{sym}, bearing {b + 1} ({esc(unit)})</caption><tr><th></th>'
                       f"<th>x</th><th>y</th></tr>{''.join(rows)}</table>")
    return "".join(f'<div class="matrices">{out[i]}{out[i + 1]}</div>' for i in (0, 2))


def diagnostics_table(ident) -> str:
    rel_std = ident.rel_std if ident.rel_std is not None else np.full(ident.axis.size, np.nan)
    dof = ident.dof if ident.dof is not None else np.full(ident.axis.size, np.nan)
    rows = []
    for p in range(ident.axis.size):
        cls = "" if ident.ok[p] else ' class="flagged"'
        rows.append(f"<tr{cls}><td>{num(ident.axis[p], 6)}</td><td>{num(ident.cond[p, 0], 3)}</td>"
                    f"<td>{num(ident.cond[p, 1], 3)}</td><td>{num(ident.residual[p], 3)}</td>"
                    f"<td>{num(ident.rel_amplitude[p], 3)}</td><td>{pct(rel_std[p])}</td><td>{num(dof[p], 3)}</td>"
                    f"{status_cell(ident, p)}<td class=\"l\">{esc(ident.flag[p])}</td></tr>")
    return (f'<div class="wide"><table class="diagnostics"><thead><tr><th>{esc(axis_label(ident))}</th>'
            "<th>cond, bearing 1</th><th>cond, bearing 2</th><th>residual</th><th>rel. amplitude</th>"
            "<th>largest rel. std. error</th><th>dof</th><th>status</th><th class=\"l\">flag</th></tr></thead>"
            f"<tbody>{''.join(rows)}</tbody></table></div>")


def point_evidence(ident, p, reason, thresholds) -> str:
    """The numbers behind one reason at one point."""
    if reason in ("singular", "ill-conditioned"):
        lim = thresholds.get("cond_max")
        return (f"cond {num(ident.cond[p, 0], 3)} (bearing 1), {num(ident.cond[p, 1], 3)} (bearing 2)"
                + (f"; cond_max {num(lim, 3)}" if lim is not None and reason != "singular" else ""))
    if reason == "uncertain" and ident.rel_std is not None:
        lim = thresholds.get("max_rel_std")
        return f"largest relative standard error {pct(ident.rel_std[p])}" + (f"; max_rel_std {pct(lim)}" if lim else "")
    if reason == "low amplitude":
        lim = thresholds.get("min_rel_amplitude")
        return f"relative amplitude {num(ident.rel_amplitude[p], 3)}" + (f"; min_rel_amplitude {num(lim, 3)}"
                                                                         if lim is not None else "")
    return ""


def flagged_section(ident, thresholds) -> str:
    bad = np.flatnonzero(~ident.ok)
    if bad.size == 0:
        return "<p>No point is flagged: every point passed the checks.</p>"
    rows = []
    for p in bad:
        reasons = [r.strip() for r in str(ident.flag[p]).split(";") if r.strip()] or ["(no reason recorded)"]
        items = "".join(f"<li><b>{esc(r)}</b>: {esc(REASONS.get(r, 'a reason given by the analysis'))}"
                        + (f" <span class=\"mono\">({esc(point_evidence(ident, p, r, thresholds))})</span>"
                           if point_evidence(ident, p, r, thresholds) else "") + "</li>" for r in reasons)
        rows.append(f'<tr id="flag-{p}" class="flagged-point" data-index="{p}"><td>{num(ident.axis[p], 6)}</td>'
                    f'<td class="l flag">{esc(ident.flag[p])}</td><td class="l"><ul>{items}</ul></td></tr>')
    return (f"<p>{bad.size} of {ident.axis.size} points are flagged. They keep their numbers in the tables "
            "(tinted rows) and are drawn hollow in the coefficient plot, but should not be trusted.</p>"
            f'<div class="wide"><table class="flagged"><thead><tr><th>{esc(axis_label(ident))}</th>'
            '<th class="l">flag</th><th class="l">why</th></tr></thead><tbody>' + "".join(rows) + "</tbody></table></div>")


def truth_section(ident, truth) -> str:
    """Median relative error (to the bearing's direct coefficients) and interval coverage per
    coefficient over the ok points."""
    x = ident.axis
    kk, cc = truth.at(**{ident.axis_name: x}) if not truth.is_constant else truth.at()
    kk = np.broadcast_to(kk, ident.k.shape)
    cc = np.broadcast_to(cc, ident.c.shape)
    sel = ident.ok if ident.ok.any() else np.ones(x.size, bool)
    iv = ident.interval(0.95)
    rows = []
    for name in REPORT_ORDER:
        sym, i, j, b = name[0], "xy".index(name[1]), "xy".index(name[2]), int(name[3]) - 1
        est, tv, lo, hi = ((ident.k, kk, iv.k_lower, iv.k_upper) if sym == "K" else (ident.c, cc, iv.c_lower, iv.c_upper))
        scale = 0.5 * (np.abs(tv[sel, b, 0, 0]) + np.abs(tv[sel, b, 1, 1]))
        with np.errstate(divide="ignore", invalid="ignore"):
            err = np.abs(est[sel, b, i, j] - tv[sel, b, i, j]) / scale
        inside = (lo[sel, b, i, j] <= tv[sel, b, i, j]) & (tv[sel, b, i, j] <= hi[sel, b, i, j])
        known = np.isfinite(lo[sel, b, i, j])
        cover = f"{int(inside[known].sum())} of {int(known.sum())}" if known.any() else "–"
        rows.append(f'<tr><td class="l">{name}</td><td>{pct(np.nanmedian(err) if err.size else np.nan)}</td>'
                    f"<td>{pct(np.nanmax(err) if err.size else np.nan)}</td><td>{cover}</td></tr>")
    which = "ok points" if ident.ok.any() else "all points (none is ok)"
    return (f"<p>Errors relative to the bearing's direct coefficients of the known truth, over the {which}.</p>"
            '<table class="truth"><thead><tr><th class="l">coefficient</th><th>median |error|</th><th>max |error|</th>'
            f"<th>95 % intervals holding the truth</th></tr></thead><tbody>{''.join(rows)}</tbody></table>")


def settings_block(settings) -> str:
    if settings is None:
        return "<p>Not recorded.</p>"
    text = settings if isinstance(settings, str) else json.dumps(settings, indent=2, ensure_ascii=False, default=str)
    return f'<pre class="settings">{esc(text)}</pre>'


def files_table(files) -> str:
    if not files:
        return "<p>Not recorded.</p>"
    rows = "".join(f'<tr><td class="l">{esc(f.get("role", ""))}</td><td class="l mono" title="{esc(f.get("path", ""))}">'
                   f'{esc(f.get("name", f.get("path", "")))}</td><td>{int(f["size"]):,}</td>'
                   f'<td class="l mono sha256">{esc(f["sha256"])}</td></tr>' for f in files)
    return ('<div class="wide"><table class="files"><thead><tr><th class="l">role</th><th class="l">file</th>'
            f'<th>bytes</th><th class="l">SHA-256</th></tr></thead><tbody>{rows}</tbody></table></div>')
