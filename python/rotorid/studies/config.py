"""The TOML config of ``rotorid study CONFIG``: a Monte Carlo study of an imbalance or impact test
(and optionally a trial-mass design), declared once as a pydantic schema. Every key is documented
in docs/config.md ("Study configs"). Units are in the key names (``noise_um``, ``mass_g``, ...).

Examples
--------
>>> from rotorid.studies.config import parse_study_config
>>> cfg = parse_study_config({"rig": {"builtin": "nsf"}, "study": {"kind": "imbalance", "trials": 100},
...                           "imbalance": {"sets": ["A", "B"], "speeds_rpm": {"start": 3000, "stop": 5000,
...                                                                            "step": 1000}}})
>>> cfg.imbalance.speeds().tolist(), cfg.study.trials
([3000.0, 4000.0, 5000.0], 100)
"""

from __future__ import annotations

import re
import typing
from typing import Annotated, Optional, Union

import numpy as np
from pydantic import Field, PlainValidator, ValidationError, model_validator
from pydantic_core import PydanticCustomError

from ..config import (ConfigError, RigSection, RotorSection, Text, _choice, _describe, _err, _messages, _Model,
                      _number_check, _number_list, _pair, read_toml)

#: at most this many points on a study axis
MAX_AXIS = 100_000
#: at most this many percentiles (as ``synchronous_study`` takes them)
MAX_PERCENTILES = 99

_WITH_UNIT = re.compile(r"\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?\s*[^\W\d]")


def _number(*, integer=False, **bounds):
    """A number with bounds (``rotorid.config``'s check); a string like "10 us" is told that the
    unit belongs in the key's name (``channel_delay_us = 10``)."""
    check = _number_check(integer=integer, **bounds)

    def checked(v):
        try:
            return check(v)
        except PydanticCustomError as exc:
            if isinstance(v, str) and _WITH_UNIT.match(v):
                raise _err(exc.context["msg"] + " (units are in the key names: write the number alone, in the "
                           "key's unit)") from None
            raise

    return Annotated[int if integer else float, PlainValidator(checked)]


def _matrix2(v):
    """A 2 x 2 real matrix [[xx, xy], [yx, yy]]."""
    if (isinstance(v, list) and len(v) == 2 and all(isinstance(r, list) and len(r) == 2 for r in v)
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x) for r in v for x in r)):
        return tuple(tuple(float(x) for x in r) for r in v)
    raise _err(f"must be a 2 x 2 array of finite numbers [[xx, xy], [yx, yy]], got {_describe(v)}")


def _names(v):
    """A non-empty array of names."""
    if isinstance(v, list) and v and all(isinstance(x, str) and x.strip() for x in v):
        return tuple(v)
    raise _err(f"must be a non-empty array of names (strings), got {_describe(v)}")


Names = Annotated[tuple[str, ...], PlainValidator(_names)]
Matrix2 = Annotated[tuple[tuple[float, float], tuple[float, float]], PlainValidator(_matrix2)]


class BearingsSection(_Model):
    """``[bearings]``: the bearing coefficients the study takes as true (SI: N/m, N·s/m): ``k``
    and ``c`` for identical bearings, or ``k1``, ``c1``, ``k2``, ``c2``."""

    k: Optional[Matrix2] = Field(None, description="stiffness [[kxx, kxy], [kyx, kyy]] of both bearings, N/m")
    c: Optional[Matrix2] = Field(None, description="damping of both bearings, N s/m")
    k1: Optional[Matrix2] = None
    c1: Optional[Matrix2] = None
    k2: Optional[Matrix2] = None
    c2: Optional[Matrix2] = None

    @model_validator(mode="after")
    def _one_form(self):
        same = self.k is not None or self.c is not None
        each = any(v is not None for v in (self.k1, self.c1, self.k2, self.c2))
        if same and each:
            raise _err("give k and c (identical bearings) or k1, c1, k2, c2, not both", table=True)
        if same and (self.k is None or self.c is None):
            raise _err("give both k and c", table=True)
        if each and any(v is None for v in (self.k1, self.c1, self.k2, self.c2)):
            raise _err("give all of k1, c1, k2, c2", table=True)
        if not same and not each:
            raise _err("give k and c (identical bearings) or k1, c1, k2, c2", table=True)
        return self

    def build(self):
        from ..model import BearingCoefficients

        if self.k is not None:
            return BearingCoefficients.identical(np.array(self.k), np.array(self.c))
        return BearingCoefficients(k=np.array([self.k1, self.k2]), c=np.array([self.c1, self.c2]))


class AxisRange(_Model):
    """``{start, stop, step}``: equally spaced values from start to stop (inclusive)."""

    start: _number(gt=0) = Field(description="first value")
    stop: _number(gt=0) = Field(description="last value (included when on the step grid)")
    step: _number(gt=0) = Field(description="step")

    @model_validator(mode="after")
    def _ordered(self):
        if self.stop < self.start:
            raise _err(f"stop ({self.stop:g}) must be >= start ({self.start:g})", table=True)
        n = int(np.floor((self.stop - self.start) / self.step + 1e-9)) + 1
        if n > MAX_AXIS:
            raise _err(f"gives {n} values; at most {MAX_AXIS} (a larger step?)", table=True)
        return self

    def values(self) -> np.ndarray:
        n = int(np.floor((self.stop - self.start) / self.step + 1e-9)) + 1
        return self.start + self.step * np.arange(n)


_VALUES_CHECK = typing.get_args(_number_list(gt=0, unique=True))[1].func


def _axis(v):
    """{start, stop, step} or an array of positive numbers."""
    if isinstance(v, dict):
        try:
            return AxisRange.model_validate(v)
        except ValidationError as exc:
            raise _err("{start, stop, step}: " + "; ".join(_messages(exc, AxisRange))) from None
    if isinstance(v, list):
        return _VALUES_CHECK(v)
    raise _err(f"must be {{start, stop, step}} or an array of values > 0, got {_describe(v)}")


Axis = Annotated[Union[AxisRange, tuple[float, ...]], PlainValidator(_axis)]


def _axis_values(v) -> np.ndarray:
    return v.values() if isinstance(v, AxisRange) else np.array(sorted(v), float)


class SyncErrorsSection(_Model):
    """``[imbalance.errors]``: standard deviations of the errors of an imbalance test (0 = off)."""

    amplitude_rel: _number(ge=0, le=10) = Field(0.0, description="relative error of each 1X amplitude")
    phase_deg: _number(ge=0, le=180) = Field(0.0, description="error of each 1X phase, deg")
    noise_um: _number(ge=0, le=1e4) = Field(0.0, description="complex noise added to each 1X vector, rms, µm")
    keyphasor_deg: _number(ge=0, le=180) = Field(0.0, description="keyphasor mark offset per test, deg")
    channel_delay_us: _number(ge=0, le=1e6) = Field(0.0, description="delay of each probe channel, µs")
    probe_position_mm: _number(ge=0, le=1e3) = Field(0.0, description="axial position error of each probe, mm")
    trial_mass_rel: _number(ge=0, le=10) = Field(0.0, description="relative error of each trial mass")
    trial_angle_deg: _number(ge=0, le=180) = Field(0.0, description="angular error of each trial mass, deg")
    speed_rel: _number(ge=0, le=0.5) = Field(0.0, description="relative error of the speed told to the analysis")

    def build(self):
        from .errors import SyncErrors

        return SyncErrors(amplitude_rel=self.amplitude_rel, phase_deg=self.phase_deg, noise_m=self.noise_um * 1e-6,
                          keyphasor_deg=self.keyphasor_deg, channel_delay_s=self.channel_delay_us * 1e-6,
                          probe_position_m=self.probe_position_mm * 1e-3, trial_mass_rel=self.trial_mass_rel,
                          trial_angle_deg=self.trial_angle_deg, speed_rel=self.speed_rel)


class TrialRun(_Model):
    """One ``[[imbalance.runs]]`` entry: trial masses (g) and their angles (deg) in planes 1 and 2."""

    name: Optional[Text] = None
    mass_g: _pair("m1, m2", nonneg=True) = Field(description="trial masses [m1, m2], g")
    angle_deg: _pair("phi1, phi2") = Field(description="angles [phi1, phi2] of the masses, deg")

    def build(self, i):
        from ..model import Imbalance

        return Imbalance(tuple(m * 1e-3 for m in self.mass_g), self.angle_deg, name=self.name or f"run {i}")


class ImbalanceStudySection(_Model):
    """``[imbalance]``: the imbalance test of a study."""

    speeds_rpm: Axis = Field(description="speeds: {start, stop, step} or an array, rpm")
    sets: Optional[Names] = Field(None, description="names of the built-in rig's imbalance sets")
    runs: Optional[list[TrialRun]] = Field(None, description="trial-mass runs ([[imbalance.runs]])")
    errors: SyncErrorsSection = Field(default_factory=SyncErrorsSection)

    @model_validator(mode="after")
    def _runs(self):
        if (self.sets is None) == (self.runs is None):
            raise _err("give sets = [names of the rig's imbalance sets] or [[imbalance.runs]] tables (one of them)",
                       table=True)
        n = len(self.sets if self.sets is not None else self.runs)
        if n < 2:
            raise _err(f"an imbalance test needs two or more runs, got {n}", table=True)
        return self

    def speeds(self) -> np.ndarray:
        return _axis_values(self.speeds_rpm)


class ImpactErrorsSection(_Model):
    """``[impact.errors]``: the errors of an impact test."""

    coherence: _number(gt=0, le=1) = Field(1.0, description="ordinary coherence of every FRF")
    impacts: _number(integer=True, ge=1, le=10 ** 6) = Field(1, description="impacts averaged per test")
    force_calibration_rel: _number(ge=0, le=10) = Field(0.0, description="relative error of the force gain")
    impact_position_mm: _number(ge=0, le=1e3) = Field(0.0, description="axial error of the impact point, mm")
    channel_delay_us: _number(ge=0, le=1e6) = Field(0.0, description="delay of each probe channel, µs")
    probe_position_mm: _number(ge=0, le=1e3) = Field(0.0, description="axial position error of each probe, mm")

    def build(self):
        from .errors import ImpactErrors

        return ImpactErrors(coherence=self.coherence, impacts=self.impacts,
                            force_calibration_rel=self.force_calibration_rel,
                            impact_position_m=self.impact_position_mm * 1e-3,
                            channel_delay_s=self.channel_delay_us * 1e-6,
                            probe_position_m=self.probe_position_mm * 1e-3)


class ImpactPlan(_Model):
    """One test of ``[impact] tests``: where the impacts land and in which direction."""

    plane_mm: _number() = Field(description="axial position from the CG, mm (positive toward bearing 2)")
    direction: _choice("x", "y") = Field(description='"x" or "y"')


class ImpactStudySection(_Model):
    """``[impact]``: the impact test of a study."""

    speed_rpm: _number(ge=0, le=1e6) = Field(description="running speed, rpm")
    freq_hz: Axis = Field(description="frequencies: {start, stop, step} or an array, Hz")
    tests: list[ImpactPlan] = Field(description="the tests: [{plane_mm = 0, direction = \"x\"}, ...]")
    errors: ImpactErrorsSection = Field(default_factory=ImpactErrorsSection)

    @model_validator(mode="after")
    def _two(self):
        if len(self.tests) < 2:
            raise _err(f"an impact test needs two or more tests, got {len(self.tests)}", table=True)
        return self

    def freqs(self) -> np.ndarray:
        return _axis_values(self.freq_hz)


class StudySection(_Model):
    """``[study]``: what to run and how."""

    kind: _choice("imbalance", "impact") = Field(description='"imbalance" or "impact"')
    trials: _number(integer=True, ge=1, le=10 ** 9) = Field(1000, description="simulated tests")
    seed: _number(integer=True, ge=0, lt=2 ** 63) = Field(0, description="seed of the random numbers")
    percentiles: _number_list(ge=0, le=100, unique=True) = Field(
        (5.0, 50.0, 95.0), description="two or more percentiles, 0-100 (the band: lowest to highest)")
    coverage_trials: _number(integer=True, ge=0, le=100_000) = Field(
        100, description="trials identified through the public API to measure interval coverage")
    level: _number(gt=0, lt=1) = Field(0.95, description="confidence level of the intervals")
    method: _choice("forces", "report") = "forces"
    at: _choice("probes", "bearings") = "probes"
    scheduler: Optional[Text] = Field(None, description="Dask scheduler address (tcp://host:port); none: this machine")

    @model_validator(mode="after")
    def _pct(self):
        if len(self.percentiles) < 2:
            raise _err("must list two or more values (the band of the errors runs from the lowest to the "
                       f"highest), got {len(self.percentiles)}", "percentiles")
        if len(self.percentiles) > MAX_PERCENTILES:
            raise _err(f"must list at most {MAX_PERCENTILES} values, got {len(self.percentiles)}", "percentiles")
        return self


class DesignSection(_Model):
    """``[design]`` (imbalance studies): rank trial-mass sets for this rig."""

    holes: _number(integer=True, ge=1, le=360) = Field(16, description="tapped holes per balance plane")
    masses_g: _number_list(gt=0, le=1e4) = Field(description="trial masses at hand, g")
    max_response_um: Optional[_number(gt=0)] = Field(None, description="largest 1X response allowed, µm")
    runs: _number_list(integer=True, ge=2, le=3) = Field((2, 3), description="set sizes: 2 and/or 3")
    screen_keep: _number(integer=True, ge=1, le=1000) = 10
    trials: _number(integer=True, ge=1, le=100_000) = 200
    dwell_s: _number(gt=0) = Field(2.0, description="dwell per speed, s")
    probe_noise_um: _number(ge=0, le=1e4) = Field(0.5, description="probe noise, rms, µm")
    fs_hz: _number(gt=0) = Field(5000.0, description="sampling rate, Hz")
    compare_sets: bool = Field(True, description="compare with the study's own runs")


class StudyOutput(_Model):
    """``[output]``: where the results go."""

    dir: Optional[Text] = None


class StudyConfig(_Model):
    """A validated study config (see :func:`load_study_config`)."""

    rig: Optional[RigSection] = None
    rotor: Optional[RotorSection] = None
    bearings: Optional[BearingsSection] = None
    study: StudySection
    imbalance: Optional[ImbalanceStudySection] = None
    impact: Optional[ImpactStudySection] = None
    design: Optional[DesignSection] = None
    output: StudyOutput = Field(default_factory=StudyOutput)

    def system(self):
        """(rotor, bearings, built-in rig or None)."""
        from ..model import nsf_rig

        rig = nsf_rig() if self.rig is not None else None
        rotor = rig.rotor if rig is not None else self.rotor.build()
        bearings = self.bearings.build() if self.bearings is not None else rig.bearings
        return rotor, bearings, rig


def _study_problems(data, cfg=None) -> list:
    out = []
    if "rig" in data and "rotor" in data:
        out.append('[rig] and [rotor] are both given: use one, [rig] builtin = "nsf" or your own [rotor]')
    elif "rig" not in data and "rotor" not in data:
        out.append('the config names no rotor: give [rig] builtin = "nsf" or a [rotor] table')
    if "rotor" in data and "bearings" not in data:
        out.append("a [rotor] of your own needs [bearings] (the coefficients the study takes as true)")
    kind = data.get("study", {}).get("kind") if isinstance(data.get("study"), dict) else None
    if kind in ("imbalance", "impact") and kind not in data:
        out.append(f'[study] kind = "{kind}" needs an [{kind}] section')
    if "design" in data and kind == "impact":
        out.append("[design] ranks trial-mass sets: it belongs to an imbalance study")
    if cfg is not None and cfg.imbalance is not None and cfg.imbalance.sets is not None:
        if cfg.rig is None:
            out.append("[imbalance] sets names the built-in rig's sets: give [rig] builtin, or [[imbalance.runs]]")
        else:
            from ..model import nsf_rig

            known = list(nsf_rig().imbalances)
            for i, name in enumerate(cfg.imbalance.sets):
                if name not in known:
                    out.append(f"[imbalance] sets[{i}] names an unknown imbalance set {name!r} (the rig has "
                               f"{', '.join(map(repr, known))})")
    return out


def parse_study_config(data, *, source="<config>") -> StudyConfig:
    """Validate a study config given as a table (``tomllib.load``). Raises ConfigError (one line)."""
    if not isinstance(data, dict):
        raise ConfigError.from_problems(source, [f"a config must be a table of sections, got {_describe(data)}"])
    try:
        cfg = StudyConfig.model_validate(data)
    except ValidationError as exc:
        raise ConfigError.from_problems(source, _messages(exc, StudyConfig) + _study_problems(data)) from None
    problems = _study_problems(data, cfg)
    if problems:
        raise ConfigError.from_problems(source, problems)
    return cfg


def load_study_config(path) -> StudyConfig:
    """Read and validate a study config file (UTF-8 TOML); every problem is one ConfigError line
    naming the file and the key.

    Examples
    --------
    >>> import os, rotorid.example
    >>> from rotorid.studies.config import load_study_config
    >>> cfg = load_study_config(os.path.join(rotorid.example.path(), "study_imbalance.toml"))
    >>> cfg.study.kind, cfg.imbalance.sets
    ('imbalance', ('A', 'B', 'C', 'D'))
    """
    data, src, _ = read_toml(path)
    return parse_study_config(data, source=src)


def is_study_config(data) -> bool:
    """Whether a parsed TOML table is a study config (it has a [study] table)."""
    return isinstance(data, dict) and "study" in data
