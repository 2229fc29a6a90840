"""The context of a page from a config run (``rotorid identify``): settings, input files with
their checksums, warnings and log, the compensated responses."""

from __future__ import annotations

import contextlib
import datetime
import os
import warnings as _warnings

import numpy as np


@contextlib.contextmanager
def warning_log():
    """Collect the text of every warning shown inside the block (they are still shown as
    before: the current ``warnings.showwarning`` is called too)."""
    seen = []
    previous = _warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None):
        seen.append(str(message))
        previous(message, category, filename, lineno, file, line)

    _warnings.showwarning = show
    try:
        yield seen
    finally:
        if _warnings.showwarning is show:
            _warnings.showwarning = previous


def input_files(cfg, config_path, kind):
    """Config file and every file its ``[kind]`` section reads, with size and SHA-256."""
    from . import file_checksums

    paths, roles = [os.path.abspath(os.fspath(config_path))], ["config"]
    for loc, entry in cfg.entries():
        if loc[0] != kind:
            continue
        where = ".".join(str(x) for x in loc[1:2]) + "".join(f"[{x}]" for x in loc[2:])
        name = getattr(entry, "name", None)
        role = f"{where} ({name})" if name else where
        for q in entry.paths(cfg):
            paths.append(str(q))
            roles.append(role)
        times = cfg.keyphasor_for(entry).get("times_file") if hasattr(cfg, "keyphasor_for") else None
        if times is not None and str(times) not in paths:
            paths.append(str(times))
            roles.append(f"{role} keyphasor times")
    return file_checksums(paths, roles=roles, base_dir=cfg.base_dir)


def run_context(cfg, config_path, kind, *, command, responses, warnings, log, units) -> dict:
    """The keyword arguments of render_report for a config run (JSON-serializable)."""
    from .. import __version__

    resp = [{"name": str(r.name), "at": str(getattr(r, "at", "")), "axis": [float(v) for v in r.speed_rpm],
             "re": np.asarray(r.q).real.tolist(), "im": np.asarray(r.q).imag.tolist()} for r in responses or ()]
    return {"kind": kind, "command": command, "units": units, "version": __version__,
            "date": datetime.datetime.now().isoformat(timespec="seconds"),
            "settings": cfg.model_dump(mode="json", by_alias=True, exclude_none=True, warnings=False),
            "input_files": input_files(cfg, config_path, kind), "warnings": list(warnings), "log": list(log),
            "responses": resp}
