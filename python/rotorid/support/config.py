"""The TOML config of ``rotorid predict CONFIG``: two series supports (a tilting-pad bearing table
from any bearing code in series with a squeeze film damper through the damper journal's mass)
and where to evaluate them, declared once as a pydantic schema. Every key is documented in
docs/config.md ("Prediction configs"). Units are in the key names.

Examples
--------
>>> from rotorid.support.config import parse_predict_config
>>> sup = {"bearing": {"file": "fpjb.csv", "freq_axis": "ratio"}, "journal_mass_kg": 1.5,
...        "damper": {"builtin": "nsf", "spring_stiffness_n_m": 3.75e6}}
>>> cfg = parse_predict_config({"supports": [sup, sup], "predict": {"kind": "synchronous",
...                             "speeds_rpm": {"start": 1000, "stop": 3000, "step": 1000}}})
>>> cfg.predict.points()[0].tolist()
[1000.0, 2000.0, 3000.0]
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Literal, Optional, Union

import numpy as np
from pydantic import Field, PrivateAttr, ValidationError, model_validator

from ..config import ConfigError, PathStr, Text, _choice, _describe, _err, _messages, _Model, read_toml
from ..errors import RotoridError
from ..studies.config import Axis, _axis_values, _matrix2, _number

#: built-in dampers (``[supports.damper] builtin``)
BUILTIN_DAMPERS = ("nsf",)


class BearingTableSection(_Model):
    """``[supports.bearing]``: the bearing's coefficient table (see :func:`rotorid.support.tpjb.load_bearing_table`)."""

    file: PathStr = Field(description="CSV or Excel table: speed_rpm, freq_hz or freq_ratio, Kxx..Kyy, Cxx..Cyy")
    freq_axis: _choice("hz", "ratio") = Field("hz", description="the table's frequency column: freq_hz or freq_ratio")
    stiffness_unit: Text = "N/m"
    damping_unit: Text = "N*s/m"
    mass_unit: Text = "kg"
    sheet: Optional[Union[Text, _number(integer=True, ge=0)]] = None


class DamperSection(_Model):
    """``[supports.damper]``: a squeeze film damper (``builtin = "nsf"``: Table 1) and its centering springs."""

    builtin: Optional[_choice(*BUILTIN_DAMPERS)] = None
    spring_stiffness_n_m: Union[_number(gt=0), tuple] = Field(description="centering springs, N/m: a number or "
                                                                           "[[xx, xy], [yx, yy]]")
    radius_m: Optional[_number(gt=0)] = None
    clearance_m: Optional[_number(gt=0)] = None
    length_m: Optional[_number(gt=0)] = None
    n_lands: Optional[_number(integer=True, ge=1, le=36)] = None
    land_extent_deg: Optional[_number(gt=0, le=360)] = None
    first_center_deg: _number() = 0.0
    viscosity_pa_s: Optional[_number(gt=0)] = None
    density_kg_m3: _number(ge=0) = 850.0
    cavitation: _choice("none", "pi") = "none"
    inertia: bool = True

    @model_validator(mode="before")
    @classmethod
    def _spring(cls, data):
        if isinstance(data, dict) and isinstance(data.get("spring_stiffness_n_m"), list):
            m = _matrix2(data["spring_stiffness_n_m"])
            if not (m[0][0] > 0 and m[1][1] > 0):
                raise _err(f"the direct stiffnesses (xx, yy) of spring_stiffness_n_m must be > 0, got {m[0][0]:g} and "
                           f"{m[1][1]:g}")
            data = dict(data, spring_stiffness_n_m=m)
        return data

    @model_validator(mode="after")
    def _complete(self):
        geometry = ("radius_m", "clearance_m", "length_m", "n_lands", "land_extent_deg")
        if self.builtin is None:
            missing = [k for k in geometry + ("viscosity_pa_s",) if getattr(self, k) is None]
            if missing:
                raise _err(f"needs {', '.join(missing)} (or builtin = \"nsf\")", table=True)
        else:
            given = [k for k in geometry if getattr(self, k) is not None]
            if given:
                raise _err(f"builtin = {self.builtin!r} fixes the geometry; remove {', '.join(given)}", table=True)
        return self

    def build(self):
        from .sfd import SqueezeFilmDamper, nsf_damper

        spring = np.array(self.spring_stiffness_n_m, float)
        common = dict(spring_stiffness_n_m=spring, density_kg_m3=self.density_kg_m3, cavitation=self.cavitation,
                      inertia=self.inertia)
        if self.builtin == "nsf":
            kw = dict(common, first_center_deg=self.first_center_deg)
            if self.viscosity_pa_s is not None:
                kw["viscosity_pa_s"] = self.viscosity_pa_s
            return nsf_damper(**kw)
        return SqueezeFilmDamper.equal_lands(self.n_lands, self.land_extent_deg, first_center_deg=self.first_center_deg,
                                             radius_m=self.radius_m, clearance_m=self.clearance_m,
                                             length_m=self.length_m, viscosity_pa_s=self.viscosity_pa_s, **common)


class SupportSection(_Model):
    """``[[supports]]``: one bearing support (bearing 1 first, then bearing 2)."""

    bearing: BearingTableSection
    damper: DamperSection
    journal_mass_kg: _number(ge=0) = Field(description="damper journal (ring + bearing shell), kg")
    name: Optional[Text] = None


class PredictSection(_Model):
    """``[predict]``: where to evaluate the supports, as the identification measured."""

    kind: _choice("synchronous", "frequency") = Field(description="synchronous: w = Omega at speeds_rpm "
                                                                   "(imbalance runs); frequency: one speed_rpm over "
                                                                   "freq_hz (impacts)")
    speeds_rpm: Optional[Axis] = None
    speed_rpm: Optional[_number(ge=0)] = None
    freq_hz: Optional[Axis] = None

    @model_validator(mode="after")
    def _axes(self):
        if self.kind == "synchronous":
            if self.speeds_rpm is None:
                raise _err("kind = \"synchronous\" needs speeds_rpm", table=True)
            if self.speed_rpm is not None or self.freq_hz is not None:
                raise _err("kind = \"synchronous\" takes speeds_rpm only (w = Omega)", table=True)
        else:
            if self.speed_rpm is None or self.freq_hz is None:
                raise _err("kind = \"frequency\" needs speed_rpm (the impacts' running speed) and freq_hz", table=True)
            if self.speeds_rpm is not None:
                raise _err("kind = \"frequency\" takes one speed_rpm, not speeds_rpm", table=True)
        return self

    def points(self):
        """(speed_rpm, freq_hz or None) as predict_coefficients takes them."""
        if self.kind == "synchronous":
            return _axis_values(self.speeds_rpm), None
        return np.array([self.speed_rpm]), _axis_values(self.freq_hz)


class PredictOutput(_Model):
    """``[output]``: where the predicted table goes and in which units."""

    dir: Optional[Text] = None
    units: _choice("SI", "US", ignore_case=True) = "SI"


class PredictConfig(_Model):
    """A validated prediction config (:func:`load_predict_config`)."""

    supports: list[SupportSection] = Field(min_length=2, max_length=2, description="bearing 1, then bearing 2")
    predict: PredictSection
    output: PredictOutput = Field(default_factory=PredictOutput)

    _base_dir: Path = PrivateAttr(default_factory=Path.cwd)

    def resolve(self, rel) -> Path:
        p = Path(os.path.expanduser(rel))
        return p if p.is_absolute() else self._base_dir / p

    def build_supports(self):
        """The two :class:`~rotorid.support.compare.SeriesSupport` (tables read now)."""
        from .compare import SeriesSupport
        from .tpjb import load_bearing_table

        out = []
        for i, s in enumerate(self.supports):
            b = s.bearing
            table = load_bearing_table(self.resolve(b.file), stiffness_unit=b.stiffness_unit,
                                       damping_unit=b.damping_unit, mass_unit=b.mass_unit, freq_axis=b.freq_axis,
                                       sheet=b.sheet)
            out.append(SeriesSupport(table, s.damper.build(), s.journal_mass_kg, s.name or f"bearing {i + 1}"))
        return out


def is_predict_config(data) -> bool:
    """Whether a parsed TOML table is a prediction config (it has [[supports]])."""
    return isinstance(data, dict) and "supports" in data


def parse_predict_config(data, *, source="<config>", base_dir=".", check_files=False) -> PredictConfig:
    """Validate a prediction config given as a table. Raises ConfigError (one line)."""
    from .._validate import flag, path as _path

    check_files = flag("check_files", check_files)
    base_dir = _path("base_dir", base_dir)
    if not isinstance(data, dict):
        raise ConfigError.from_problems(source, [f"a config must be a table of sections, got {_describe(data)}"])
    try:
        cfg = PredictConfig.model_validate(data)
    except ValidationError as exc:
        raise ConfigError.from_problems(source, _messages(exc, PredictConfig)) from None
    cfg._base_dir = Path(os.path.abspath(os.path.expanduser(os.fspath(base_dir))))
    if check_files:
        missing = [f"[[supports]] {i + 1} bearing file {s.bearing.file!r} does not exist ({cfg.resolve(s.bearing.file)})"
                   for i, s in enumerate(cfg.supports) if not cfg.resolve(s.bearing.file).is_file()]
        if missing:
            raise ConfigError.from_problems(source, missing)
        # the files read and the models built, here, so that `rotorid check` finds what `predict` would
        problems = _semantic_problems(cfg)
        if problems:
            raise ConfigError.from_problems(source, problems)
    return cfg


def _semantic_problems(cfg) -> list:
    """Each support's damper built and bearing table read, and the prediction points inside every
    table: the problems, each naming its [[supports]] entry."""
    import warnings

    from .compare import SeriesSupport
    from .tpjb import load_bearing_table

    out = []
    rpm, f = cfg.predict.points()
    for i, s in enumerate(cfg.supports):
        where = f"[[supports]] {i + 1}"
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # validity warnings come when the prediction runs
                damper = s.damper.build()
        except RotoridError as exc:
            out.append(f"{where} damper: {exc}")
            continue
        b = s.bearing
        try:
            table = load_bearing_table(cfg.resolve(b.file), stiffness_unit=b.stiffness_unit,
                                       damping_unit=b.damping_unit, mass_unit=b.mass_unit, freq_axis=b.freq_axis,
                                       sheet=b.sheet)
        except RotoridError as exc:
            out.append(f"{where} bearing {b.file!r}: {exc}")
            continue
        sup = SeriesSupport(table, damper, s.journal_mass_kg)
        ss, ff = (rpm, rpm / 60.0) if f is None else (np.full(f.size, rpm[0]), f)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                sup.impedance(ss, ff)
        except RotoridError as exc:
            out.append(f"{where} at the [predict] points: {exc}")
    return out


def load_predict_config(path) -> PredictConfig:
    """Read and validate a prediction config file (UTF-8 TOML); file paths are relative to it."""
    data, src, where = read_toml(path)
    return parse_predict_config(data, source=src, base_dir=where, check_files=True)


def run_predict_config(path, *, out_dir=None, overwrite: bool = False, log=print):
    """``rotorid predict CONFIG``: the two supports' coefficients where the config says, as a table
    ``predicted_<kind>.csv`` (the axis and Kxx1 ... Cyy2, SI or US, what ``rotorid compare``
    reads) and a figure ``predicted_<kind>.png``. Returns the list of written files."""
    import pandas as pd

    from .. import plot
    from .._validate import flag
    from ..model import REPORT_ORDER, _REPORT_TO_BIJ
    from ..outputs import ResultsFolder
    from .compare import predict_coefficients

    overwrite = flag("overwrite", overwrite)
    cfg = load_predict_config(path)
    supports = cfg.build_supports()
    rpm, f = cfg.predict.points()
    k, c = predict_coefficients(supports, speed_rpm=rpm, freq_hz=f)
    kind = cfg.predict.kind
    axis_name, axis = ("speed_rpm", rpm) if f is None else ("freq_hz", f)
    data = {axis_name: axis}
    if f is not None:
        data["speed_rpm"] = np.full(f.size, rpm[0])  # the running speed, which rotorid compare checks
    us = cfg.output.units.upper() == "US"
    from ..units import from_si

    kr, cr = k.reshape(-1, 8)[:, _REPORT_TO_BIJ], c.reshape(-1, 8)[:, _REPORT_TO_BIJ]
    for j, name in enumerate(REPORT_ORDER):
        v = (kr if j < 8 else cr)[:, j % 8]
        if us:
            unit, tag = ("lbf/in", "_lbf_per_in") if j < 8 else ("lbf*s/in", "_lbf_s_per_in")
            data[name + tag] = from_si(v, unit)
        else:
            data[name] = v
    base = os.path.dirname(os.path.abspath(os.fspath(path)))
    out = out_dir if out_dir else os.path.join(base, cfg.output.dir or f"rotorid_predict_{kind}")
    folder = ResultsFolder(str(out), patterns=[f"predicted_{kind}.*"], overwrite=overwrite,
                           command=f"rotorid predict {path}")
    files = []
    with folder.atomic(f"predicted_{kind}.csv") as tmp:
        pd.DataFrame(data).to_csv(tmp, index=False, float_format="%.6g")
    files.append(os.path.join(folder.path, f"predicted_{kind}.csv"))
    plt = plot._plt()
    fig, axes = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    for b in range(2):
        for i, d in enumerate("xy"):
            axes[0].plot(axis, k[:, b, i, i] * 1e-6, label=f"K{d}{d}{b + 1}")
            axes[1].plot(axis, c[:, b, i, i] * 1e-3, label=f"C{d}{d}{b + 1}")
    axes[0].set_ylabel("Direct stiffness (MN/m)")
    axes[1].set_ylabel("Direct damping (kN·s/m)")
    axes[1].set_xlabel("Rotor speed (rpm), w = Omega" if f is None else f"Frequency (Hz), {rpm[0]:g} rpm")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, ncol=2)
    fig.suptitle(f"Predicted series-support coefficients ({kind}), {os.path.basename(os.fspath(path))}")
    with folder.atomic(f"predicted_{kind}.png") as tmp:
        plot.finish(fig, tmp)
    files.append(os.path.join(folder.path, f"predicted_{kind}.png"))
    folder.finish()
    log(f"predicted {kind} coefficients of 2 series supports at {axis.size} points ({axis_name} "
        f"{axis.min():g}-{axis.max():g}); wrote {len(files)} files to {folder.path}/")
    return files
