"""Identification results in the files and structures of the field (issue 14, item 2): labeled
arrays (xarray, NetCDF), Excel workbooks with a units row, JSON. SI or US customary units.

The coefficients keep their structure: dimensions (speed_rpm or freq_hz, bearing, i, j) with
bearing = 1, 2 and i, j = x, y; the standard errors and 95 % intervals travel with them, so no
exported number loses its error bar.
"""

from __future__ import annotations

import json
import os

import numpy as np

from .errors import RotoridError

#: output unit systems: stiffness, damping units and their names in labels
UNIT_SYSTEMS = {"SI": ("N/m", "N*s/m"), "US": ("lbf/in", "lbf*s/in")}


def _units(units):
    from ._validate import text

    u = text("units", units).upper()
    if u not in UNIT_SYSTEMS:
        raise RotoridError(f"units must be 'SI' or 'US' (US customary: lbf/in, lbf*s/in), got {units!r}")
    return u


def _check_ident(ident):
    from .identify import Identification

    if not isinstance(ident, Identification):
        raise RotoridError(f"expected a rotorid Identification, got {type(ident).__name__}")


def _target(path, overwrite, suffixes):
    """The output path, checked: its suffix, an existing file only with ``overwrite``."""
    from ._validate import flag, path as _path

    p = _path("path", path)
    overwrite = flag("overwrite", overwrite)
    if p.suffix.lower() not in suffixes:
        raise RotoridError(f"path {str(p)!r} must end in {' or '.join(suffixes)}")
    if p.exists() and not overwrite:
        raise RotoridError(f"{str(p)!r} exists; pass overwrite=True (--overwrite) to replace it")
    if p.exists() and p.is_dir():
        raise RotoridError(f"{str(p)!r} is a folder")
    if not p.parent.exists():
        raise RotoridError(f"the folder of {str(p)!r} does not exist")
    return p


def _atomic(p, write) -> str:
    """``write(tmp)`` to a temporary file beside ``p`` (same suffix), then moved onto ``p``: a
    failed write leaves no half file."""
    tmp = p.with_name(f".{p.stem}.part{p.suffix}")
    try:
        write(tmp)
        os.replace(tmp, p)
    except OSError as exc:
        raise RotoridError(f"cannot write {str(p)!r}: {exc}") from None
    finally:
        if tmp.exists():
            tmp.unlink()
    return str(p)


def _in_units(a, unit, system):
    """A float copy of ``a`` (SI) in ``unit`` when ``system`` is "US", else in SI. A copy the
    export owns: writable, and not a view into the Identification (its NaN standard errors and
    constant degrees of freedom are read-only views)."""
    from .units import from_si

    return np.array(from_si(np.asarray(a, float), unit), float) if system == "US" else np.array(a, float)


def to_xarray(ident, *, units: str = "SI", level: float = 0.95):
    """The identification as an :class:`xarray.Dataset`.

    Variables ``K``, ``C`` and their ``*_std``, ``*_lower``, ``*_upper`` (the ``level`` interval)
    over (axis, bearing, i, j); ``cond`` (axis, bearing); ``residual``, ``rel_amplitude``, ``dof``,
    ``ok``, ``flag`` over the axis. Units as attributes (``units``), the method and the source of
    the uncertainty as dataset attributes.

    Examples
    --------
    >>> import numpy as np, rotorid
    >>> rig = rotorid.nsf_rig()
    >>> runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=[3000.0, 4000.0])
    ...         for s in "ABC"]
    >>> ds = rotorid.identify_synchronous(rig.rotor, runs).to_xarray()
    >>> ds.K.dims, [str(v) for v in ds.i.values]
    (('speed_rpm', 'bearing', 'i', 'j'), ['x', 'y'])
    >>> round(float(ds.K.sel(speed_rpm=3000.0, bearing=1, i="x", j="x")) / 1e6, 6)
    3.0
    """
    import xarray as xr

    from ._validate import number

    _check_ident(ident)
    u = _units(units)
    level = number("level", level)
    if not 0.0 < level < 1.0:
        raise RotoridError(f"level must be between 0 and 1, got {level:g}")
    ku, cu = UNIT_SYSTEMS[u]

    def conv(a, unit):
        return _in_units(a, unit, u)

    iv = ident.interval(level)
    dims = (ident.axis_name, "bearing", "i", "j")
    data = {}
    for name, arr, unit in (("K", ident.k, ku), ("C", ident.c, cu), ("K_std", ident.k_std, ku),
                            ("C_std", ident.c_std, cu), ("K_lower", iv.k_lower, ku), ("K_upper", iv.k_upper, ku),
                            ("C_lower", iv.c_lower, cu), ("C_upper", iv.c_upper, cu)):
        attrs = {"units": unit}
        if name.endswith(("_lower", "_upper")):
            attrs["confidence_level"] = level
        data[name] = (dims, conv(arr, unit), attrs)
    n = ident.axis.size
    data["cond"] = ((ident.axis_name, "bearing"), np.array(ident.cond, float), {"units": "1"})
    data["residual"] = ((ident.axis_name,), np.array(ident.residual, float), {"units": "1"})
    data["rel_amplitude"] = ((ident.axis_name,), np.array(ident.rel_amplitude, float), {"units": "1"})
    data["dof"] = ((ident.axis_name,), np.array(ident.dof if ident.dof is not None else np.full(n, np.nan), float),
                   {"units": "1", "long_name": "degrees of freedom of the standard errors"})
    data["ok"] = ((ident.axis_name,), np.array(ident.ok, bool), {})
    data["flag"] = ((ident.axis_name,), np.asarray(ident.flag, dtype=str), {})
    coords = {ident.axis_name: (ident.axis_name, np.asarray(ident.axis, float),
                                {"units": "rpm" if ident.axis_name == "speed_rpm" else "Hz"}),
              "bearing": ("bearing", np.array([1, 2])), "i": ("i", np.array(["x", "y"])),
              "j": ("j", np.array(["x", "y"]))}
    from . import __version__

    attrs = {"title": "rotorid identification", "method": ident.method, "std_source": ident.std_source,
             "estimator": ident.estimator, "unit_system": u, "rotorid_version": __version__,
             "conventions": "bearing 1, 2; i, j over x (horizontal), y (vertical); force = -(K X + C dX/dt)"}
    return xr.Dataset(data, coords=coords, attrs=attrs)


def to_netcdf(ident, path, *, units: str = "SI", overwrite: bool = False) -> str:
    """Write :func:`to_xarray` to a NetCDF file (NetCDF 3 through scipy, no extra library; the
    flags as fixed-width text). Refuses an existing file unless ``overwrite``."""
    p = _target(path, overwrite, (".nc",))
    ds = to_xarray(ident, units=units)
    ds["ok"] = ds["ok"].astype("i1")
    ds["ok"].attrs["flag_values"] = "0: flagged, 1: ok"
    ds["flag"] = ds["flag"].astype("S")
    for name in ("i", "j"):
        ds[name] = ds[name].astype("S")
    try:
        ds.to_netcdf(p, engine="scipy")
    except OSError as exc:
        raise RotoridError(f"cannot write {str(p)!r}: {exc}") from None
    return str(p)


def _wide_with_units(ident, units):
    """to_dataframe in the chosen units, and the unit of every column."""
    from .units import from_si

    df = ident.to_dataframe()
    ku, cu = UNIT_SYSTEMS[units]
    col_units = {}
    for col in df.columns:
        if col[:1] in "KC" and col[1:3] in ("xx", "xy", "yx", "yy"):
            unit = ku if col[0] == "K" else cu
            if units == "US":
                df[col] = from_si(df[col].to_numpy(float), unit)
            col_units[col] = unit
        elif col == "speed_rpm":
            col_units[col] = "rpm"
        elif col == "freq_hz":
            col_units[col] = "Hz"
        else:
            col_units[col] = ""
    return df, col_units


def to_excel(ident, path, *, units: str = "SI", overwrite: bool = False) -> str:
    """An Excel workbook: sheet ``coefficients`` (a row per point: the 16 coefficients, their
    standard errors and 95 % intervals, diagnostics, ok and flag; a units row under the header,
    so read it back with ``skiprows=[1]``)
    and sheet ``about`` (method, source of the uncertainty, unit system, rotorid version).
    Refuses an existing file unless ``overwrite``.

    Examples
    --------
    >>> import os, tempfile, numpy as np, pandas as pd, rotorid
    >>> rig = rotorid.nsf_rig()
    >>> runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=[3000.0])
    ...         for s in "AB"]
    >>> p = rotorid.identify_synchronous(rig.rotor, runs).to_excel(os.path.join(tempfile.mkdtemp(), "k.xlsx"))
    >>> units = pd.read_excel(p, sheet_name="coefficients", nrows=1)
    >>> units["Kxx1"][0], units["Cxx1"][0]
    ('N/m', 'N*s/m')
    >>> sheet = pd.read_excel(p, sheet_name="coefficients", skiprows=[1])
    >>> round(float(sheet["Kxx1"][0]) / 1e6, 6)
    3.0
    """
    import pandas as pd

    from . import __version__

    _check_ident(ident)
    u = _units(units)
    p = _target(path, overwrite, (".xlsx",))
    df, col_units = _wide_with_units(ident, u)
    # the header, then one row of units, then the points (read back with skiprows=[1])
    df = pd.concat([pd.DataFrame([col_units], columns=df.columns), df.astype(object)], ignore_index=True)
    about = pd.DataFrame({"item": ["method", "std_source", "estimator", "unit_system", "axis", "rotorid_version",
                                   "conventions"],
                          "value": [ident.method, ident.std_source, ident.estimator, u, ident.axis_name, __version__,
                                    "bearing 1, 2; x horizontal, y vertical; intervals at 95 %"]})
    def write(tmp):
        with pd.ExcelWriter(tmp, engine="openpyxl") as xw:
            df.to_excel(xw, sheet_name="coefficients", index=False)
            about.to_excel(xw, sheet_name="about", index=False)

    return _atomic(p, write)


def _jsonable(a):
    a = np.asarray(a)
    if a.dtype.kind == "f":
        return [_jsonable(x) for x in a] if a.ndim else (None if not np.isfinite(a) else float(a))
    if a.dtype.kind == "b":
        return a.tolist()
    return a.tolist()


def to_json(ident, path=None, *, units: str = "SI", overwrite: bool = False, context=None):
    """A JSON document of the identification: the axis, K and C and their standard errors and 95 %
    intervals as nested lists [point][bearing][i][j], the diagnostics, flags, units and
    provenance; NaN as null. With ``path`` written there (refusing an existing file unless
    ``overwrite``) and the path returned; without, the text returned.

    Everything the result object holds besides the covariance matrices travels too (the relative
    amplitudes and standard errors, the estimator's bias, the residual-based errors, the flag codes
    and reasons, the run labels), so :func:`from_json` gives back an equal
    :class:`~rotorid.Identification`. ``context``: an optional JSON-serializable dict stored under
    ``"context"`` (``rotorid identify`` puts the settings, input files with SHA-256, warnings and
    its log there; :mod:`rotorid.report` shows them).

    Examples
    --------
    >>> import json, rotorid
    >>> rig = rotorid.nsf_rig()
    >>> runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=[3000.0])
    ...         for s in "AB"]
    >>> doc = json.loads(rotorid.identify_synchronous(rig.rotor, runs).to_json())
    >>> doc["units"]["K"], round(doc["K"][0][0][0][0] / 1e6, 6)
    ('N/m', 3.0)
    """
    from . import __version__

    _check_ident(ident)
    u = _units(units)
    ku, cu = UNIT_SYSTEMS[u]

    def conv(a, unit):
        return _in_units(a, unit, u)

    iv = ident.interval(0.95)
    doc = {"format": "rotorid-identification", "version": 1, "rotorid_version": __version__,
           "axis_name": ident.axis_name, "axis": _jsonable(ident.axis),
           "units": {"K": ku, "C": cu, ident.axis_name: "rpm" if ident.axis_name == "speed_rpm" else "Hz"},
           "layout": "[point][bearing 1, 2][i: x, y][j: x, y]",
           "method": ident.method, "std_source": ident.std_source, "estimator": ident.estimator,
           "K": _jsonable(conv(ident.k, ku)), "C": _jsonable(conv(ident.c, cu)),
           "K_std": _jsonable(conv(ident.k_std, ku)), "C_std": _jsonable(conv(ident.c_std, cu)),
           "K_lower95": _jsonable(conv(iv.k_lower, ku)), "K_upper95": _jsonable(conv(iv.k_upper, ku)),
           "C_lower95": _jsonable(conv(iv.c_lower, cu)), "C_upper95": _jsonable(conv(iv.c_upper, cu)),
           "cond": _jsonable(ident.cond), "residual": _jsonable(ident.residual),
           "dof": _jsonable(ident.dof if ident.dof is not None else np.full(ident.axis.size, np.nan)),
           "ok": [bool(v) for v in ident.ok], "flag": [str(f) for f in ident.flag]}
    # the rest of the result (additions to version 1: readers of the keys above are unaffected)
    n = ident.axis.size

    def opt(a, unit=None):
        return None if a is None else _jsonable(conv(a, unit) if unit else np.asarray(a, float))

    doc.update({"rel_amplitude": _jsonable(ident.rel_amplitude), "rel_std": opt(ident.rel_std),
                "K_bias": opt(ident.k_bias, ku), "C_bias": opt(ident.c_bias, cu),
                "K_std_residual": opt(ident.k_std_residual, ku), "C_std_residual": opt(ident.c_std_residual, cu),
                # "dof" holds null for infinite degrees of freedom (a known covariance)
                "dof_infinite": [bool(v) for v in np.isinf(np.asarray(
                    ident.dof if ident.dof is not None else np.full(n, np.nan), float))],
                # "cond" holds null for an infinite condition number (a singular point) too
                "cond_infinite": np.isinf(np.asarray(ident.cond, float)).tolist(),
                "flag_code": [int(v) for v in np.asarray(ident.flag_code).reshape(n)],
                "flag_reasons": [str(r) for r in ident.flag_reasons], "runs": [str(r) for r in ident.runs]})
    if context is not None:
        if not isinstance(context, dict):
            raise RotoridError(f"context must be a dict (JSON-serializable), got {type(context).__name__}")
        doc["context"] = context
    try:
        text = json.dumps(doc, indent=1, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise RotoridError(f"context cannot be written as JSON: {exc}") from None
    if path is None:
        return text
    p = _target(path, overwrite, (".json",))
    return _atomic(p, lambda tmp: tmp.write_text(text, encoding="utf-8"))


#: the identification's keys every rotorid JSON document has (version 1)
_REQUIRED = ("axis_name", "axis", "units", "method", "K", "C", "K_std", "C_std", "cond", "residual", "ok", "flag")


def read_json_document(source) -> dict:
    """The JSON document of :func:`to_json` (a path, or the text itself), checked to be one.

    Raises RotoridError naming the file for a missing, unreadable or garbled file and for a JSON
    document that is not a rotorid identification (or is of a newer version)."""
    from ._validate import path as _path

    if isinstance(source, str) and source.lstrip().startswith("{"):
        name, text = "the JSON text", source
    else:
        p = _path("source", source)
        name = repr(str(p))
        if p.is_dir():
            raise RotoridError(f"{name} is a folder, not a rotorid JSON result")
        try:
            text = p.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise RotoridError(f"{name} not found") from None
        except UnicodeDecodeError:
            raise RotoridError(f"{name} is not UTF-8 text (not a rotorid JSON result)") from None
        except OSError as exc:
            raise RotoridError(f"cannot read {name}: {exc.strerror or exc}") from None
    try:
        doc = json.loads(text)
    except ValueError as exc:
        where = f" (line {exc.lineno}, column {exc.colno}: {exc.msg})" if hasattr(exc, "lineno") else ""
        raise RotoridError(f"{name} is not valid JSON{where}") from None
    if not isinstance(doc, dict) or doc.get("format") != "rotorid-identification":
        raise RotoridError(f"{name} is JSON but not a rotorid identification (no \"format\": "
                           "\"rotorid-identification\")")
    version = doc.get("version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise RotoridError(f"{name}: version must be a positive integer, got {version!r}")
    if version > 1:
        raise RotoridError(f"{name} is version {version} of the format, written by a newer rotorid; this one reads "
                           "version 1")
    missing = [k for k in _REQUIRED if k not in doc]
    if missing:
        raise RotoridError(f"{name}: missing {', '.join(repr(m) for m in missing)}")
    doc["_name"] = name
    return doc


def from_json(source):
    """The :class:`~rotorid.Identification` of a :func:`to_json` document (a file or the text),
    in SI whatever units it was written in.

    Documents of earlier rotorid versions (without the relative amplitudes, bias, flag codes)
    load too: the missing arrays are NaN, the flag codes are rebuilt from the flag strings, and the
    estimator's bias from the stored 95 % intervals, so :meth:`~rotorid.Identification.interval`
    gives the written bounds. The covariance matrices are not stored (``cov`` is None).

    Examples
    --------
    >>> import numpy as np, rotorid
    >>> from rotorid.exports import from_json
    >>> rig = rotorid.nsf_rig()
    >>> runs = [rotorid.imbalance_response(rig.rotor, rig.bearings, rig.imbalances[s], speed_rpm=[3000.0, 4000.0])
    ...         for s in "ABC"]
    >>> ident = rotorid.identify_synchronous(rig.rotor, runs)
    >>> back = from_json(ident.to_json(units="US"))
    >>> bool(np.allclose(back.k, ident.k, rtol=1e-12)), list(back.flag) == list(ident.flag)
    (True, True)
    """
    from .identify import Identification, _BASE_REASONS, _flag_strings
    from .units import to_si

    doc = read_json_document(source)
    name = doc["_name"]
    axis_name = doc["axis_name"]
    if axis_name not in ("speed_rpm", "freq_hz"):
        raise RotoridError(f"{name}: axis_name must be 'speed_rpm' or 'freq_hz', got {axis_name!r}")
    units = doc["units"] if isinstance(doc["units"], dict) else {}
    ku, cu = units.get("K"), units.get("C")
    if (ku, cu) not in set(UNIT_SYSTEMS.values()):
        raise RotoridError(f"{name}: units of K and C must be one of {list(UNIT_SYSTEMS.values())}, got {(ku, cu)}")

    def arr(key, shape, unit=None, optional=False):
        v = doc.get(key)
        if v is None:
            if optional:
                return None
            raise RotoridError(f"{name}: {key!r} is missing")
        try:
            a = np.array(v, dtype=float)   # null -> nan
        except (TypeError, ValueError):
            raise RotoridError(f"{name}: {key!r} must be (nested lists of) numbers") from None
        if a.shape != shape:
            raise RotoridError(f"{name}: {key!r} must have shape {shape}, got {a.shape}")
        return np.asarray(to_si(a, unit), float) if unit and unit not in ("N/m", "N*s/m") else a

    if not isinstance(doc["axis"], list):
        raise RotoridError(f"{name}: 'axis' must be a list of numbers")
    axis = arr("axis", (len(doc["axis"]),))
    n = axis.size
    if n == 0:
        raise RotoridError(f"{name}: no points")
    s4 = (n, 2, 2, 2)
    k, c = arr("K", s4, ku), arr("C", s4, cu)
    k_std, c_std = arr("K_std", s4, ku), arr("C_std", s4, cu)
    cond, residual = arr("cond", (n, 2)), arr("residual", (n,))
    dof = arr("dof", (n,), optional=True)
    rel_amp = arr("rel_amplitude", (n,), optional=True)
    rel_std = arr("rel_std", (n,), optional=True)
    k_bias, c_bias = arr("K_bias", s4, ku, optional=True), arr("C_bias", s4, cu, optional=True)
    k_res, c_res = arr("K_std_residual", s4, ku, optional=True), arr("C_std_residual", s4, cu, optional=True)
    inf = doc.get("dof_infinite")
    if dof is not None and isinstance(inf, list) and len(inf) == n:
        dof[np.array(inf, dtype=bool)] = np.inf
    elif dof is not None and "K_upper95" in doc:
        # older documents: null is infinite where the intervals are known
        known = np.isfinite(arr("K_upper95", s4, ku)).any(axis=(1, 2, 3))
        dof[np.isnan(dof) & known] = np.inf
    cinf = doc.get("cond_infinite")
    if isinstance(cinf, list) and np.shape(cinf) == (n, 2) and all(isinstance(v, bool) for r in cinf for v in r):
        cond[np.array(cinf, dtype=bool)] = np.inf   # singular points (null in "cond")
    ok, flag = doc["ok"], doc["flag"]
    if not (isinstance(ok, list) and len(ok) == n and all(isinstance(v, bool) for v in ok)):
        raise RotoridError(f"{name}: 'ok' must be a list of {n} true/false")
    if not (isinstance(flag, list) and len(flag) == n and all(isinstance(v, str) for v in flag)):
        raise RotoridError(f"{name}: 'flag' must be a list of {n} strings")
    ok = np.array(ok, dtype=bool)
    code = doc.get("flag_code")
    reasons = doc.get("flag_reasons")
    if not (isinstance(code, list) and len(code) == n and all(type(v) is int and 0 <= v < 2 ** 62 for v in code)
            and isinstance(reasons, list) and all(isinstance(r, str) for r in reasons)):
        code = reasons = None   # absent or garbled: rebuilt from the flag strings below
    if code is not None:
        code = np.array(code, dtype=np.int64)
        reasons = tuple(reasons)
        if list(_flag_strings(code, reasons)) != flag:
            code = None
    if code is None or reasons is None:
        # rebuilt from the strings (documents written before the codes were stored)
        found = [r.strip() for f in flag for r in f.split(";") if r.strip()]
        reasons = tuple(_BASE_REASONS) + tuple(dict.fromkeys(r for r in found if r not in _BASE_REASONS))
        code = np.zeros(n, dtype=np.int64)
        for i, f in enumerate(flag):
            for r in (p.strip() for p in f.split(";")):
                if r:
                    code[i] |= 1 << reasons.index(r)
    estimator = str(doc.get("estimator", "ls"))
    if "K_bias" not in doc and estimator == "ls" and "K_upper95" in doc and "C_upper95" in doc:
        # older documents (no "K_bias" key; null in newer ones means no bias)
        from .uncertainty import t_quantile

        t = t_quantile(0.95, dof if dof is not None else np.full(n, np.nan))[:, None, None, None]
        hk = 0.5 * (arr("K_upper95", s4, ku) - arr("K_lower95", s4, ku))
        hc = 0.5 * (arr("C_upper95", s4, cu) - arr("C_lower95", s4, cu))
        with np.errstate(invalid="ignore"):
            bk, bc = hk - t * k_std, hc - t * c_std
            k_bias = np.where(np.isfinite(bk), np.where(bk > 1e-9 * np.abs(hk), bk, 0.0), np.nan)
            c_bias = np.where(np.isfinite(bc), np.where(bc > 1e-9 * np.abs(hc), bc, 0.0), np.nan)
        if not (np.nanmax(k_bias, initial=0.0) > 0 or np.nanmax(c_bias, initial=0.0) > 0):
            k_bias = c_bias = None
    runs = doc.get("runs", [])
    if not (isinstance(runs, list) and all(isinstance(r, (str, int, float)) for r in runs)):
        raise RotoridError(f"{name}: 'runs' must be a list of run or test names")
    return Identification(axis_name, axis, k, c, cond, residual,
                          rel_amp if rel_amp is not None else np.full(n, np.nan), k_std, c_std, ok, code,
                          str(doc["method"]), [str(r) for r in runs], str(doc.get("std_source", "none")),
                          dof, None, rel_std, k_res, c_res, k_bias, c_bias, estimator, reasons)
