"""One self-contained HTML page per identification (issue 14, item 4; docs/report.md).

:func:`render_report` returns the page, :func:`write_report` writes it atomically; the page holds
its figures as embedded PNG, the coefficient tables with their 95 % intervals, the diagnostics,
the flagged points and why, the warnings and log of the run, the settings and the input files with
their SHA-256. It has inline CSS only, no script and no external reference: it renders offline.
:func:`load_result` reads what ``rotorid identify`` writes (``result_<kind>.json``) back into an
Identification and the context of the page, which is what ``rotorid report RESULT`` does.

matplotlib is imported only when a page is rendered (``import rotorid`` stays light).
"""

from __future__ import annotations

import datetime
import hashlib
import os

import numpy as np

from ..errors import RotoridError

__all__ = ["render_report", "write_report", "load_result", "file_checksums", "RESULT_FILE"]

#: the machine-readable result ``rotorid identify`` writes to its output folder (``<kind>`` =
#: imbalance or impact): the JSON export of the identification with the context of the run
RESULT_FILE = "result_{kind}.json"

_CONTEXT_KEYS = ("settings", "input_files", "warnings", "log", "responses", "units", "title", "command", "kind",
                 "version", "date")


def file_checksums(paths, *, roles=None, base_dir=None) -> list:
    """Name, size and SHA-256 of each file, as the report lists them.

    Parameters
    ----------
    paths : iterable of str or os.PathLike
        The files (each must exist).
    roles : iterable of str, optional
        What each file is (e.g. "config", "run 'S0'"), shown beside it.
    base_dir : str or os.PathLike, optional
        Names are shown relative to this folder where they lie below it.

    Returns
    -------
    list of dict
        ``{"name", "path", "size", "sha256", "role"}`` per file.

    Examples
    --------
    >>> import os, tempfile
    >>> from rotorid.report import file_checksums
    >>> p = os.path.join(tempfile.mkdtemp(), "run.csv")
    >>> _ = open(p, "w").write("abc")
    >>> f = file_checksums([p], roles=["run 'A'"])[0]
    >>> f["name"], f["size"], f["sha256"][:16]
    ('run.csv', 3, 'ba7816bf8f01cfea')
    """
    paths = [os.fspath(p) for p in paths]
    roles = [""] * len(paths) if roles is None else [str(r) for r in roles]
    if len(roles) != len(paths):
        raise RotoridError(f"roles must name each of the {len(paths)} files, got {len(roles)}")
    out = []
    for p, role in zip(paths, roles):
        full = os.path.abspath(p)
        h = hashlib.sha256()
        try:
            with open(full, "rb") as fh:
                for block in iter(lambda: fh.read(1 << 20), b""):
                    h.update(block)
        except OSError as exc:
            raise RotoridError(f"cannot read input file {p!r} for its checksum: {exc.strerror or exc}") from None
        name = os.path.basename(full)
        if base_dir is not None:
            rel = os.path.relpath(full, os.path.abspath(os.fspath(base_dir)))
            name = name if rel.startswith("..") else rel
        out.append({"name": name, "path": full, "size": os.path.getsize(full), "sha256": h.hexdigest(), "role": role})
    return out


def _input_files(files):
    if files is None:
        return None
    if isinstance(files, (str, bytes, os.PathLike)) or not hasattr(files, "__iter__"):
        raise RotoridError("input_files must be a list of paths or of {'name', 'size', 'sha256'} dicts, got "
                           f"{type(files).__name__}")
    files = list(files)
    paths = [f for f in files if isinstance(f, (str, os.PathLike))]
    out = file_checksums(paths) if len(paths) == len(files) else []
    if not out:
        for f in files:
            if not (isinstance(f, dict) and {"size", "sha256"} <= set(f) and ("name" in f or "path" in f)
                    and type(f["size"]) is int and isinstance(f["sha256"], str)):
                raise RotoridError("input_files must be a list of paths or of {'name', 'size', 'sha256'} dicts, got "
                                   f"an item {f!r}")
            out.append(f)
    return out


def _responses(responses):
    """[(name, axis, q (n, 4) complex)] of SyncResponses or of the dicts the result file holds."""
    from ..simulate import SyncResponse

    out = []
    for r in responses or ():
        if isinstance(r, SyncResponse):
            out.append((r.name or f"{len(out)}", np.asarray(r.speed_rpm, float), np.asarray(r.q)))
        elif isinstance(r, dict) and {"axis", "re", "im"} <= set(r):
            try:
                q = np.asarray(r["re"], float) + 1j * np.asarray(r["im"], float)
                axis = np.asarray(r["axis"], float)
            except (TypeError, ValueError):
                raise RotoridError(f"response {r.get('name', len(out))!r}: axis, re and im must be lists of numbers "
                                   "(re and im as [point][x1, x2, y1, y2])") from None
            out.append((str(r.get("name", len(out))), axis, q))
        else:
            raise RotoridError(f"responses must be SyncResponses (or the dicts of a result file), got "
                               f"{type(r).__name__}")
    return out


def _thresholds(settings, kind):
    from ..identify import COND_MAX, MAX_REL_STD, MIN_REL_AMPLITUDE, MIN_REL_AMPLITUDE_IMPACT

    th = {"cond_max": COND_MAX, "max_rel_std": MAX_REL_STD,
          "min_rel_amplitude": MIN_REL_AMPLITUDE_IMPACT if kind == "impact" else MIN_REL_AMPLITUDE}
    sec = settings.get(kind) if isinstance(settings, dict) and kind else None
    if isinstance(sec, dict):
        th.update({k: sec[k] for k in th if isinstance(sec.get(k), (int, float))})
    return th


def render_report(ident, *, settings=None, input_files=None, truth=None, warnings=None, log=None, responses=None,
                  units="SI", title=None, command=None, kind=None, version=None, date=None) -> str:
    """The HTML page of an identification.

    Parameters
    ----------
    ident : rotorid.Identification
    settings : dict, str or rotorid.config.Config, optional
        The settings of the run (a config is shown with every default filled in), as pretty JSON.
    input_files : list, optional
        Paths (their size and SHA-256 are computed) or the dicts of :func:`file_checksums`.
    truth : rotorid.BearingCoefficients, optional
        Known coefficients: drawn in the plot, and a section of errors and interval coverage.
    warnings, log : list of str, optional
        Warnings raised during the run; the run's progress lines.
    responses : list of SyncResponse, optional
        Imbalance runs (compensated 1X vectors) to show as Bode plots.
    units : {"SI", "US"}
        Units of the tables: MN/m and kN·s/m, or lbf/in and lbf·s/in.
    title, command, kind : str, optional
        Page title, the command that ran, "imbalance" or "impact".
    version, date : str, optional
        rotorid version and date of the identification (default: this rotorid, now).

    Returns
    -------
    str
        A complete HTML document.

    Examples
    --------
    >>> import numpy as np, rotorid
    >>> from rotorid.report import render_report
    >>> rig = rotorid.nsf_rig()
    >>> runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=[3000.0, 4000.0])
    ...         for s in "ABC"]
    >>> page = render_report(rotorid.identify_synchronous(rig.rotor, runs), truth=rig.bearings)
    >>> page.startswith("<!DOCTYPE html>"), "data:image/png;base64," in page, "http://" in page
    (True, True, False)
    """
    from .. import __version__
    from .._validate import instance, text
    from ..exports import _units
    from ..identify import Identification
    from ..model import BearingCoefficients
    from . import _figures as fg
    from ._page import (CSS, coefficient_tables, diagnostics_table, esc, files_table, flagged_section, kv_table,
                        median_matrices, num, pct, rel_std_groups, settings_block, truth_section)

    instance("ident", ident, Identification, what="rotorid Identification")
    instance("truth", truth, BearingCoefficients, allow_none=True, what="rotorid.BearingCoefficients")
    units = _units(units)
    title, command, kind = (text(n, v, allow_none=True) for n, v in (("title", title), ("command", command),
                                                                      ("kind", kind)))
    version = text("version", version, allow_none=True) or __version__
    date = text("date", date, allow_none=True) or datetime.datetime.now().isoformat(timespec="seconds")
    if settings is not None and not isinstance(settings, (dict, str)):
        dump = getattr(settings, "model_dump", None)
        if dump is None:
            raise RotoridError(f"settings must be a dict, a str or a rotorid config, got {type(settings).__name__}")
        settings = dump(mode="json", by_alias=True, exclude_none=True, warnings=False)
    for name, v in (("warnings", warnings), ("log", log)):
        if v is not None and (isinstance(v, str) or not all(isinstance(s, str) for s in v)):
            raise RotoridError(f"{name} must be a list of strings, got {v!r}")
    files = _input_files(input_files)
    resp = _responses(responses)
    kind_text = kind or ("imbalance" if ident.axis_name == "speed_rpm" else "impact")
    title = title or f"Bearing coefficients identified from {kind_text} {'runs' if kind_text == 'imbalance' else 'tests'}"
    th = _thresholds(settings, kind_text)

    n, n_bad = ident.axis.size, int((~ident.ok).sum())
    unit_ax = "rpm" if ident.axis_name == "speed_rpm" else "Hz"
    rel, on_ok = rel_std_groups(ident)
    status = (f'<span class="badge b-ok">{n} of {n} points ok</span>' if not n_bad else
              f'<span class="badge b-bad">{n_bad} of {n} points flagged</span>')
    summary = kv_table([
        ("identification", esc(f"{kind_text}; method {ident.method}, estimator {ident.estimator}")),
        ("axis", esc(f"{'speed' if unit_ax == 'rpm' else 'frequency'} {num(ident.axis.min(), 6)}–"
                     f"{num(ident.axis.max(), 6)} {unit_ax}, {n} points")),
        ("points", f"{n - n_bad} ok, <a href=\"#flagged\">{n_bad} flagged</a> {status}"),
        ("runs / tests", esc(", ".join(map(str, ident.runs)) or "–")),
        ("uncertainty from", esc(ident.std_source)),
        (f"median relative standard error ({'ok points' if on_ok else 'all points, none ok'})",
         esc("; ".join(f"{k} {pct(v)}" for k, v in rel.items()))),
        ("warnings", f'<a href="#warnings">{len(warnings or [])}</a>'),
        ("units of the tables", esc(f"{units} (stiffness {'MN/m' if units == 'SI' else 'lbf/in'}, damping "
                                    f"{'kN·s/m' if units == 'SI' else 'lbf·s/in'})")),
        ("command", f'<span class="mono">{esc(command)}</span>' if command else "–"),
        ("identified", esc(f"{date}, rotorid {version}")),
    ])
    figs = [(fg.coefficients(ident, truth, title, units), "Identified coefficients with their 95 % intervals"
                                                          + ("; lines: the known truth" if truth is not None else "")
                                                          + "; hollow markers: flagged points; triangles on an edge: "
                                                            "values beyond the plotted range"
                                                          + ("; in klbf/in and lbf·s/in" if units == "US" else ""))]
    diag_png = fg.diagnostics(ident, th)
    bodes = [(fg.bode(name, ax, q, units), f"Compensated 1X response of run {name}") for name, ax, q in resp]
    img = "".join(f'<figure><img alt="{esc(cap)}" src="{fg.data_uri(png)}"><figcaption>{esc(cap)}</figcaption>'
                  "</figure>" for png, cap in figs)
    warn_html = ("".join(f'<div class="warn">{esc(w)}</div>' for w in warnings) if warnings else
                 "<p>None recorded.</p>")
    sections = [
        ("summary", "Summary", summary + median_matrices(ident, units)),
        ("figures", "Coefficients", img),
        ("tables", "Coefficient tables", coefficient_tables(ident, units)),
        ("diagnostics", "Diagnostics",
         f'<figure><img alt="diagnostics per point" src="{fg.data_uri(diag_png)}"><figcaption>Condition number, '
         "largest relative standard error, relative amplitude and residual per point; dashed: the thresholds "
         "(cond_max, max_rel_std, min_rel_amplitude); red crosses: flagged points</figcaption></figure>"
         + diagnostics_table(ident)),
        ("flagged", "Flagged points and why", flagged_section(ident, th)),
    ]
    if truth is not None:
        sections.append(("truth", "Against the known coefficients", truth_section(ident, truth)))
    if bodes:
        sections.append(("responses", "Responses", "".join(
            f'<figure><img alt="{esc(cap)}" src="{fg.data_uri(png)}"><figcaption>{esc(cap)}</figcaption></figure>'
            for png, cap in bodes)))
    sections += [("warnings", "Warnings", warn_html),
                 ("log", "Log of the run", f'<pre class="log">{esc(chr(10).join(log))}</pre>' if log else
                  "<p>Not recorded.</p>"),
                 ("settings", "Settings", settings_block(settings)),
                 ("files", "Input files", files_table(files))]
    nav = "".join(f'<a href="#{sid}">{esc(head)}</a>' for sid, head, _ in sections)
    body = "".join(f'<section id="{sid}"><h2>{esc(head)}</h2>{content}</section>' for sid, head, content in sections)
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
            f"<meta name=\"generator\" content=\"rotorid {esc(__version__)}\"><title>{esc(title)}</title>"
            f"<style>{CSS}</style></head><body><main><h1>{esc(title)}</h1>"
            f"<p class=\"sub\">rotorid {esc(version)} · {esc(date)} · {status}</p><nav>{nav}</nav>{body}"
            f"<footer>Rendered by rotorid {esc(__version__)} on "
            f"{esc(datetime.datetime.now().isoformat(timespec='seconds'))}. Self-contained page: figures embedded, "
            "no script, no external resource.</footer></main></body></html>\n")


def write_report(path, ident, *, overwrite: bool = False, **context) -> str:
    """Write :func:`render_report` to ``path`` (an .html file) atomically: rendered completely,
    written to a temporary file beside it and renamed. An existing file is refused unless
    ``overwrite``. ``context``: the keyword arguments of :func:`render_report`.

    Examples
    --------
    >>> import os, tempfile, rotorid
    >>> from rotorid.report import write_report
    >>> rig = rotorid.nsf_rig()
    >>> runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=[3000.0, 4000.0])
    ...         for s in "AB"]
    >>> p = write_report(os.path.join(tempfile.mkdtemp(), "page.html"), rotorid.identify_synchronous(rig.rotor, runs))
    >>> write_report(p, rotorid.identify_synchronous(rig.rotor, runs))
    Traceback (most recent call last):
    ...
    rotorid.errors.RotoridError: '.../page.html' exists; pass overwrite=True (--overwrite) to replace it
    """
    from .._validate import flag, path as _path
    from ..exports import _atomic, _target

    if not flag("overwrite", overwrite) and _path("path", path).is_file():
        raise RotoridError(f"{str(path)!r} exists; pass overwrite=True (--overwrite) to replace it")
    p = _target(path, overwrite, (".html", ".htm"))
    page = render_report(ident, **context)  # before anything is written
    return _atomic(p, lambda tmp: tmp.write_text(page, encoding="utf-8"))


def find_result(path) -> str:
    """The result file of ``path``: a JSON file itself, or the one in an output folder
    (``result_<kind>.json``; else a ``coefficients_<kind>.json`` export)."""
    from .._validate import path as _path

    p = _path("RESULT", path)
    if not p.exists():
        raise RotoridError(f"{str(p)!r} not found (give the output folder of rotorid identify or its "
                           "result_<kind>.json)")
    if p.is_file():
        return str(p)
    for pattern in ("result_{kind}.json", "coefficients_{kind}.json"):
        found = [p / pattern.format(kind=k) for k in ("imbalance", "impact") if (p / pattern.format(kind=k)).is_file()]
        if len(found) == 2:
            raise RotoridError(f"{str(p)!r} holds results of both kinds ({found[0].name}, {found[1].name}); name one "
                               "of the files")
        if found:
            return str(found[0])
    raise RotoridError(f"{str(p)!r} holds no rotorid result (result_imbalance.json or result_impact.json, written "
                       "by rotorid identify)")


def load_result(path):
    """Read a result back: the Identification and the context of its page.

    Parameters
    ----------
    path : str or os.PathLike
        ``result_<kind>.json`` (or any :func:`rotorid.exports.to_json` document), or the output
        folder of ``rotorid identify`` that holds it.

    Returns
    -------
    (rotorid.Identification, dict)
        The dict holds the keyword arguments of :func:`render_report` that the file records
        (settings, input_files, warnings, log, responses, units, command, kind, version, date).

    Examples
    --------
    >>> import os, tempfile, rotorid
    >>> from rotorid.report import load_result, render_report
    >>> rig = rotorid.nsf_rig()
    >>> runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=[3000.0, 4000.0])
    ...         for s in "AB"]
    >>> p = rotorid.identify_synchronous(rig.rotor, runs).to_json(os.path.join(tempfile.mkdtemp(), "r.json"))
    >>> ident, context = load_result(p)
    >>> ident.axis.tolist(), context["version"] == rotorid.__version__
    ([3000.0, 4000.0], True)
    >>> page = render_report(ident, **context)
    """
    from ..exports import from_json, read_json_document

    f = find_result(path)
    doc = read_json_document(f)
    ident = from_json(f)
    ctx = doc.get("context") or {}
    if not isinstance(ctx, dict):
        raise RotoridError(f"{f!r}: 'context' must be a JSON object")
    out = {k: ctx[k] for k in _CONTEXT_KEYS if ctx.get(k) is not None}
    out.setdefault("version", str(doc.get("rotorid_version", "")) or None)
    if "units" not in out and doc["units"].get("K") == "lbf/in":
        out["units"] = "US"   # a document without context (coefficients_<kind>.json): the units it was written in
    if out.get("units") not in ("SI", "US"):
        out.pop("units", None)
    return ident, {k: v for k, v in out.items() if v is not None}
