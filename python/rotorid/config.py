"""The schema of rotorid's TOML config files, declared in one place (pydantic v2).

``rotorid identify imbalance|impact CONFIG.toml`` reads a config with :func:`load_config`, which
parses the TOML, validates every section and key, checks that the units parse and that every
referenced file exists, all before any processing. Everything wrong is reported at once (the first
few problems) as one :class:`ConfigError` whose message is a single line naming the file, the
location and what is wrong::

    rig.toml: [imbalance.runs][2] unknown key 'angle_degs' (did you mean 'angle_deg'?)
    rig.toml: [imbalance] steady must be true or false, got the string 'false'
    rig.toml: [channels."Prox DE X"] unit 'lbf' is a force, but x1 is a length

Every table forbids unknown keys and every value is checked strictly: no string for a boolean, no
float truncated to an integer, no boolean as a number (an integer is accepted where a float is
expected). The reference of all sections and keys is ``docs/config.md``.

The pipeline reads a validated :class:`Config` through a few helpers: :meth:`Config.rotor`,
:meth:`Config.channels_for`, :meth:`Config.files_for`, :meth:`Config.keyphasor_for`,
:meth:`FileEntry.paths`, :meth:`ImbalanceRun.mass_kg` (...); they turn the schema into the keyword
arguments of the readers and the chains.
"""

import datetime as _dt
import difflib
import math
import os
import re
import tomllib
import types
import typing
from pathlib import Path
from typing import Annotated, Literal, Optional, Union

from pydantic import BaseModel, ConfigDict, Field, PlainValidator, PrivateAttr, ValidationError, field_validator, \
    model_validator
from pydantic_core import PydanticCustomError

from . import units as _units
from .errors import RotoridError
from .probe_angles import ANGLED, MAX_ANGLE_DEG, plane_transform

__all__ = [
    "CANONICAL", "QUANTITY", "ChannelSpec", "Config", "ConfigError", "FileEntry", "FileOptions", "ImbalanceRun",
    "ImbalanceSection", "ImpactSection", "ImpactTest", "KeyphasorOptions", "KeyphasorOverride", "OneXColumn",
    "OneXColumns", "OneXTable", "OutputSection", "RigSection", "RotorSection", "load_config", "parse_config",
]

#: physical quantity of each canonical channel (the names of rotorid.units); kept here so the
#: schema does not depend on the readers
QUANTITY = {"x1": "length", "x2": "length", "y1": "length", "y2": "length", "kp": "voltage", "force": "force",
            "px1": "acceleration", "py1": "acceleration", "px2": "acceleration", "py2": "acceleration"}
#: canonical channel names a lab channel may be mapped to
CANONICAL = tuple(QUANTITY)
#: how many problems one ConfigError message spells out
MAX_REPORTED = 3

_SECTIONS = ("imbalance", "impact")
#: names of ``[rig] builtin``
BUILTIN_RIGS = ("nsf",)


# =============================================================================================
# errors

class ConfigError(RotoridError):
    """A config file that cannot be used: the message is one line naming the file, the location
    and what is wrong (the first few problems, ``; ``-joined).

    Attributes
    ----------
    source : str or None
        The config file (as given) or the ``source`` passed to :func:`parse_config`.
    problems : list of str
        Every problem found, one line each, without the ``source:`` prefix.
    """

    def __init__(self, message, *, source=None, problems=()):
        super().__init__(message)
        self.source = source
        self.problems = list(problems)

    @classmethod
    def from_problems(cls, source, problems):
        problems = _dedupe(_one_line(p) for p in problems)
        shown = problems[:MAX_REPORTED]
        more = len(problems) - len(shown)
        text = "; ".join(shown) + (f"; and {more} more" if more else "")
        return cls(_one_line(f"{source}: {text}"), source=source, problems=problems)


def _err(msg, *at, table=False, keyless=False):
    """A validation problem for the formatter. ``at``: location below the validated value (keys
    and indices); ``table``: the message describes the table at that location (no key prefix);
    ``keyless``: the message names the key itself (located in the key's table)."""
    return PydanticCustomError("rotorid", "{msg}", {"msg": msg, "at": tuple(at), "table": bool(table),
                                                    "keyless": bool(keyless)})


_LINE_BREAKS = "\n\r\v\f\x1c\x1d\x1e\x85\u2028\u2029"


def _one_line(text: str) -> str:
    """Escape everything ``str.splitlines`` would break on."""
    if not any(c in text for c in _LINE_BREAKS):
        return text
    return "".join(c.encode("unicode_escape").decode("ascii") if c in _LINE_BREAKS else c for c in text)


def _dedupe(items):
    seen, out = set(), []
    for x in items:
        if x not in seen:
            seen.add(x)
            out.append(x)
    return out


def _short(s: str, n: int = 60) -> str:
    return s if len(s) <= n else s[: n - 3] + "..."


def _int_text(v: int) -> str:
    if v.bit_length() > 70:
        return f"an integer of about {int(v.bit_length() * 0.30103) + 1} digits"
    return str(v)


def _toml(v, depth: int = 0) -> str:
    """A short TOML-like rendering of a value, for messages."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return _int_text(v)
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, str):
        return repr(_short(v))
    if isinstance(v, (list, tuple)):
        if depth > 1:
            return "[...]"
        items = [_toml(x, depth + 1) for x in v[:4]]
        return "[" + ", ".join(items + (["..."] if len(v) > 4 else [])) + "]"
    if isinstance(v, dict):
        return "{...}" if v else "{}"
    if isinstance(v, (_dt.date, _dt.time)):
        return v.isoformat()
    return type(v).__name__


def _describe(v) -> str:
    """'the string 'false'', 'true', '2.5', 'the array [1, 2]', 'a table' ..."""
    if isinstance(v, str):
        return f"the string {_toml(v)}"
    if isinstance(v, bool) or isinstance(v, (int, float)):
        return _toml(v)
    if isinstance(v, (list, tuple)):
        return f"the array {_toml(v)}" if v else "an empty array"
    if isinstance(v, dict):
        return "a table"
    if isinstance(v, (_dt.datetime, _dt.date, _dt.time)):
        return f"the date/time {v.isoformat()}"
    if v is None:
        return "nothing"
    return f"a {type(v).__name__}"


def _fmt(x) -> str:
    return str(x) if isinstance(x, int) else f"{x:g}"


def _suggest(word, options) -> str:
    """' (did you mean 'x'?)' or ''."""
    if not isinstance(word, str):
        return ""
    options = [o for o in options if isinstance(o, str)]
    for o in options:
        if o.lower() == word.lower():
            return f" (did you mean {o!r}?)"
    hit = difflib.get_close_matches(word, options, n=1, cutoff=0.6)
    if not hit:
        low = {o.lower(): o for o in options}
        hit = [low[h] for h in difflib.get_close_matches(word.lower(), list(low), n=1, cutoff=0.6)]
    return f" (did you mean {hit[0]!r}?)" if hit else ""


def _article(word: str) -> str:
    return ("an " if word[:1] in "aeiou" else "a ") + word


# =============================================================================================
# value types (strict, with rotorid's own messages)

def _as_float(v):
    """float of a TOML number (int or float, never a bool), or None."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    try:
        return float(v)
    except OverflowError:
        return math.inf if v > 0 else -math.inf


def _number_check(*, gt=None, ge=None, lt=None, le=None, integer=False, auto=False, nonzero=False, abs_lt=None):
    """The check of a float/int with bounds; ``auto`` also accepts the string "auto"."""
    bounds = []
    if abs_lt is not None:
        bounds.append(f"between {_fmt(-abs_lt)} and {_fmt(abs_lt)} (exclusive)")
    for op, b in ((">", gt), (">=", ge), ("<", lt), ("<=", le)):
        if b is not None:
            bounds.append(f"{op} {_fmt(b)}")
    kind = "an integer" if integer else "a number"
    if nonzero:
        kind = "a non-zero integer" if integer else "a non-zero number"
    want = "must be " + ("'auto' or " if auto else "") + kind + (" " + " and ".join(bounds) if bounds else "")

    def check(v):
        if auto and isinstance(v, str) and v == "auto":
            return "auto"
        x = (v if isinstance(v, int) and not isinstance(v, bool) else None) if integer else _as_float(v)
        if x is None:
            raise _err(f"{want}, got {_describe(v)}{_suggest(v, ['auto']) if auto else ''}")
        ok = (math.isfinite(x) and (gt is None or x > gt) and (ge is None or x >= ge) and (lt is None or x < lt)
              and (le is None or x <= le) and (abs_lt is None or abs(x) < abs_lt) and not (nonzero and x == 0))
        if not ok:
            raise _err(f"{want}, got {_toml(v)}")
        return x

    return check


def _number(*, integer=False, auto=False, **bounds):
    """Annotated float (or int) with bounds, see :func:`_number_check`."""
    tp = int if integer else float
    return Annotated[Union[tp, Literal["auto"]] if auto else tp,
                     PlainValidator(_number_check(integer=integer, auto=auto, **bounds))]


def _number_list(*, integer=False, min_length=1, unique=False, must_contain=None, **bounds):
    """A non-empty array of numbers (a tuple once validated); element problems name the index."""
    elem = _number_check(integer=integer, **bounds)
    kind = "integers" if integer else "numbers"
    btext = " and ".join(f"{op} {_fmt(b)}" for op, b in ((">", bounds.get("gt")), (">=", bounds.get("ge")))
                         if b is not None)

    def check(v):
        if not isinstance(v, list) or len(v) < min_length:
            raise _err(f"must be a non-empty array of {kind}{' ' + btext if btext else ''}, got {_describe(v)}")
        out = _each(v, elem)
        if unique and len(set(out)) != len(out):
            dup = next(x for x in out if out.count(x) > 1)
            raise _err(f"must not repeat a value, got {_fmt(dup)} twice")
        if must_contain is not None and must_contain not in out:
            raise _err(f"must contain {must_contain}, got {_toml(v)}")
        return tuple(out)

    return Annotated[tuple[int, ...] if integer else tuple[float, ...], PlainValidator(check)]


def _pair(names: str, *, positive=False, nonneg=False):
    """Two finite numbers ``[a, b]`` (``names`` for messages, e.g. "d1, d2")."""

    def check(v):
        if not isinstance(v, list) or len(v) != 2:
            raise _err(f"must be an array of 2 numbers [{names}], got {_describe(v)}")
        out = []
        for i, e in enumerate(v):
            x = _as_float(e)
            if x is None:
                raise _err(f"must be a number, got {_describe(e)}", i)
            if not math.isfinite(x):
                raise _err(f"must be a finite number, got {_toml(e)}", i)
            if positive and not x > 0:
                raise _err(f"must be > 0, got {_toml(e)}", i)
            if nonneg and not x >= 0:
                raise _err(f"must be >= 0, got {_toml(e)}", i)
            out.append(x)
        return tuple(out)

    return Annotated[tuple[float, float], PlainValidator(check)]


def _band(v):
    if (isinstance(v, list) and len(v) == 2 and all(_as_float(e) is not None for e in v)
            and all(math.isfinite(_as_float(e)) for e in v)):
        lo, hi = (_as_float(e) for e in v)
        if 0 < lo < hi:
            return (lo, hi)
        raise _err(f"must be [lo, hi] in Hz with 0 < lo < hi, got {_toml(v)}")
    raise _err(f"must be an array of 2 numbers [lo, hi] in Hz with 0 < lo < hi, got {_describe(v)}")


def _choice(*options, ignore_case=False):
    """One of ``options`` (strings); ``ignore_case`` returns the option as spelled in ``options``."""

    def check(v):
        if isinstance(v, str):
            if v in options:
                return v
            if ignore_case:
                for o in options:
                    if o.lower() == v.lower():
                        return o
        got = repr(_short(v)) if isinstance(v, str) else _describe(v)
        anycase = " (any case)" if ignore_case else ""
        raise _err(f"must be one of {', '.join(map(repr, options))}{anycase}, got {got}{_suggest(v, options)}")

    return Annotated[Literal[options], PlainValidator(check)]


def _check_text(v):
    if not isinstance(v, str):
        raise _err(f"must be a string, got {_describe(v)}")
    if not v.strip():
        raise _err("must be a non-empty string, got an empty one")
    return v


def _check_sep(v):
    if not isinstance(v, str):
        raise _err(f"must be 'auto' or a separator string (e.g. ';' or '\\t'), got {_describe(v)}")
    if v == "":
        raise _err("must be 'auto' or a separator string (e.g. ';' or '\\t'), got an empty string")
    return v


def _check_path(v):
    if not isinstance(v, str):
        raise _err(f"must be a file path (a string), got {_describe(v)}")
    if not v.strip():
        raise _err("must be a file path, got an empty string")
    if "\x00" in v:
        raise _err(f"must be a file path, got {_toml(v)} (contains a NUL character)")
    return v


def _each(v, check) -> list:
    """Each element checked; a problem names the element's index."""
    out = []
    for i, e in enumerate(v):
        try:
            out.append(check(e))
        except PydanticCustomError as exc:
            raise _err(exc.context["msg"], i) from None
    return out


def _check_paths(v):
    if not isinstance(v, list) or not v:
        raise _err(f"must be a non-empty array of file paths, got {_describe(v)}")
    return tuple(_each(v, _check_path))


def _check_groups(v):
    """"*" (every group, also from ["*"]) or a tuple of group names."""
    if v == "*" and isinstance(v, str):
        return "*"
    if not isinstance(v, list) or not v:
        raise _err(f'must be "*" (every group) or a non-empty array of TDMS group names, got {_describe(v)}')
    out = []
    for i, e in enumerate(v):
        if not isinstance(e, str) or not e.strip():
            raise _err(f"must be a TDMS group name (a non-empty string), got {_describe(e)}", i)
        out.append(e)
    if "*" in out:
        if len(out) > 1:
            raise _err('"*" (every group) stands alone: give groups = "*" or a list of names')
        return "*"
    if len(set(out)) != len(out):
        dup = next(x for x in out if out.count(x) > 1)
        raise _err(f"must not name a group twice, got {dup!r} twice")
    return tuple(out)


def _check_time_column(v):
    if isinstance(v, bool):
        if v is False:
            return False
        raise _err("must be 'auto', a column name, or false (no time column), got true")
    if isinstance(v, str) and v.strip():
        return v
    raise _err(f"must be 'auto', a column name, or false (no time column), got {_describe(v)}")


def _check_sheet(v):
    if isinstance(v, str) and v.strip():
        return v
    if isinstance(v, int) and not isinstance(v, bool) and v >= 0:
        return v
    raise _err(f"must be a sheet name or a sheet index >= 0, got {_describe(v)}")


def _unit_of(quantity: str, subject: str):
    """A validator of a unit string that must be a unit of ``quantity``."""
    def check(v):
        _check_text(v)
        problem = _unit_problem(v, quantity, subject)
        if problem:
            raise _err(problem, keyless=True)
        return v
    return check


_check_length_unit = _unit_of("length", "the 1X amplitudes are lengths")
_check_accel_unit = _unit_of("acceleration", "the accelerometer amplitudes are accelerations")


def _unit_problem(unit: str, quantity: str, subject: str):
    """None if ``unit`` parses as a unit of ``quantity``, else the problem."""
    try:
        q = _units.quantity_of(unit)
    except RotoridError:
        known = [u for u, (qq, _) in getattr(_units, "_UNITS", {}).items() if qq == quantity]
        return (f"unknown unit {unit!r}{_suggest(unit, known)} ({subject}; known {quantity} units: "
                f"{', '.join(known)})")
    if q != quantity:
        return f"unit {unit!r} is {_article(q)}, but {subject}"
    try:
        _units.factor(unit, quantity)
    except RotoridError as exc:  # pragma: no cover - the table agrees with itself
        return str(exc)
    return None


Text = Annotated[str, PlainValidator(_check_text)]
Sep = Annotated[str, PlainValidator(_check_sep)]
PathStr = Annotated[str, PlainValidator(_check_path)]
PathList = Annotated[tuple[str, ...], PlainValidator(_check_paths)]
Groups = Annotated[Union[Literal["*"], tuple[str, ...]], PlainValidator(_check_groups)]
TimeColumn = Annotated[Union[str, Literal[False]], PlainValidator(_check_time_column)]
Sheet = Annotated[Union[str, int], PlainValidator(_check_sheet)]
LengthUnit = Annotated[str, PlainValidator(_check_length_unit)]
AccelUnit = Annotated[str, PlainValidator(_check_accel_unit)]
Band = Annotated[tuple[float, float], PlainValidator(_band)]
Finite = _number()
Positive = _number(gt=0)
NonNeg = _number(ge=0)
Format = _choice("auto", "native", "csv", "tdms", "uff58")
Decimal = _choice("auto", ".", ",")
Method = _choice("forces", "report")
ProbesAt = _choice("probes", "bearings")
Edge = _choice("auto", "rising", "falling")
Direction = _choice("x", "y")
SkipRows = _number(integer=True, ge=0, auto=True)
Level = _number(auto=True)
Hysteresis = _number(ge=0, auto=True)
Tolerance = _number(gt=0, lt=1)


class _Model(BaseModel):
    """Base of every config table: unknown keys forbidden, strict types, immutable."""

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)


# =============================================================================================
# tables

def _check_builtin(v):
    if isinstance(v, str) and v in BUILTIN_RIGS:
        return v
    got = repr(_short(v)) if isinstance(v, str) else _describe(v)
    raise _err(f"names an unknown builtin rig {got}{_suggest(v, BUILTIN_RIGS)} (known: "
               f"{', '.join(map(repr, BUILTIN_RIGS))}; or give a [rotor] table instead of [rig])")


class RigSection(_Model):
    """``[rig]``: a built-in rig."""

    builtin: Annotated[Literal[BUILTIN_RIGS], PlainValidator(_check_builtin)] = Field(
        description='built-in rig: "nsf" (the NSF-SFD rig of the report)')


class _Given:
    """The value of a unit-neutral ``[rotor]`` key (``mass``, ``it``, ``ip``), carried onto its SI
    key (``mass_kg``, ...) so that both spellings are checked in one place and named as written."""

    __slots__ = ("key", "value", "conflict")

    def __init__(self, key, value, conflict=False):
        self.key, self.value, self.conflict = key, value, conflict


def _to_si(v, dimension):
    """A number (SI) or a quantity string (``"12.5 in"``) as an SI float, or a problem raised."""
    if isinstance(v, str):
        try:
            return _units._to_si_float(v, dimension)
        except RotoridError as exc:
            raise _err(str(exc)) from None
    x = _as_float(v)
    si = _units.DIMENSIONS[dimension]
    if x is None:
        raise _err(f"must be a number ({si}) or a string with its unit (e.g. {_units._EXAMPLE[dimension]!r}), got "
                   f"{_describe(v)}")
    if not math.isfinite(x):
        raise _err(f"must be a finite number, got {_toml(v)}")
    return x


def _quantity_check(dimension, *, positive=False):
    """A number in SI or a quantity string of ``dimension`` (``[rotor] l1 = "7.44 in"``)."""
    def check(v):
        x = _to_si(v, dimension)
        if positive and not x > 0:
            raise _err(f"must be > 0, got {_toml(v)}")
        return x
    return check


def _si_key(dimension, si_key, neutral, example):
    """An SI-named ``[rotor]`` key (``mass_kg``: a number in kg), or the value of its unit-neutral
    twin (``mass = "68 lb"``) carried onto it by :meth:`RotorSection._unit_neutral`."""
    number = _number_check(gt=0)

    def check(v):
        if isinstance(v, _Given):
            if v.conflict:
                raise _err(f"give {v.key} or {si_key}, not both", keyless=True)
            try:
                return _quantity_check(dimension, positive=True)(v.value)
            except PydanticCustomError as exc:
                raise _err(f"{v.key} {exc.context['msg']}", keyless=True) from None
        if isinstance(v, str) and any(c.isalpha() for c in v):
            raise _err(f"must be a number > 0 ({_units.DIMENSIONS[dimension]}), got {_describe(v)}; for a value "
                       f"with its unit write {neutral} = {_toml(v)}")
        return number(v)

    return Annotated[float, PlainValidator(check)]


def _quantity_pair(names: str, dimension: str, *, positive=False):
    """Two values ``[a, b]``, each a number in SI or a quantity string."""
    elem = _quantity_check(dimension, positive=positive)

    def check(v):
        if not isinstance(v, list) or len(v) != 2:
            raise _err(f"must be an array of 2 numbers [{names}], got {_describe(v)} (numbers in "
                       f"{_units.DIMENSIONS[dimension]} or strings with a unit, e.g. {_units._EXAMPLE[dimension]!r})")
        return tuple(_each(v, elem))

    return Annotated[tuple[float, float], PlainValidator(check)]


#: unit-neutral [rotor] keys -> (SI key, dimension)
ROTOR_NEUTRAL_KEYS = {"mass": ("mass_kg", "mass"), "it": ("it_kgm2", "inertia"), "ip": ("ip_kgm2", "inertia")}


class RotorSection(_Model):
    """``[rotor]``: a rigid rotor on two bearings (all quantities required).

    Each value is a number in SI units or a string with its unit (pint, ``"68 lb"``,
    ``"12.5 in"``; :func:`rotorid.units.quantity`): ``mass``, ``it``, ``ip`` take any unit
    (``mass_kg``, ``it_kgm2``, ``ip_kgm2``, their SI-named twins, numbers only; give one of each
    pair), ``l1``, ``l2``, ``d``, ``r``, ``s`` a number in m or a length with its unit. Once
    validated every field is in SI.
    """

    mass_kg: _si_key("mass", "mass_kg", "mass", "68 lb") = Field(
        description='rotor mass: mass = "68 lb" (any mass unit) or mass_kg (kg)')
    it_kgm2: _si_key("inertia", "it_kgm2", "it", "2405 lb*in**2") = Field(
        description='transverse moment of inertia about the CG: it = "2405 lb*in**2" or it_kgm2 (kg m^2)')
    ip_kgm2: _si_key("inertia", "ip_kgm2", "ip", "1022 lb*in**2") = Field(
        description='polar moment of inertia: ip = "1022 lb*in**2" or ip_kgm2 (kg m^2)')
    l1: Annotated[float, PlainValidator(_quantity_check("length"))] = Field(description="CG to bearing 1, m")
    l2: Annotated[float, PlainValidator(_quantity_check("length"))] = Field(description="CG to bearing 2, m")
    d: _quantity_pair("d1, d2", "length") = Field(description="imbalance planes [d1, d2] from the CG, m")
    r: _quantity_pair("r1, r2", "length", positive=True) = Field(description="imbalance radii [r1, r2], m")
    s: _quantity_pair("s1, s2", "length") = Field(description="probe planes [s1, s2] from the CG, m")

    @model_validator(mode="before")
    @classmethod
    def _unit_neutral(cls, data):
        if not isinstance(data, dict) or not any(k in data for k in ROTOR_NEUTRAL_KEYS):
            return data
        data = dict(data)
        for key, (si_key, _) in ROTOR_NEUTRAL_KEYS.items():
            if key in data:
                data[si_key] = _Given(key, data.pop(key), conflict=si_key in data)
        return data

    @model_validator(mode="after")
    def _rigid_rotor(self):
        if not self.l1 + self.l2 > 0:
            raise _err(f"bearing span l1 + l2 must be > 0, got {self.l1 + self.l2:g} m", table=True)
        try:
            self.build()
        except RotoridError as exc:
            raise _err(str(exc), table=True) from None
        return self

    def build(self):
        """The :class:`rotorid.RigidRotor` of this table."""
        from .model import RigidRotor

        return RigidRotor(mass_kg=self.mass_kg, it_kgm2=self.it_kgm2, ip_kgm2=self.ip_kgm2, l1=self.l1, l2=self.l2,
                          d=self.d, r=self.r, s=self.s)


def _map_entry(spec) -> dict:
    """A ChannelSpec as ``rotorid.io`` takes it (``override_file_unit`` and ``angle_deg`` only when
    set)."""
    d = spec.model_dump()
    if not d["override_file_unit"]:
        del d["override_file_unit"]
    if d["angle_deg"] is None:
        del d["angle_deg"]
    return d


class ChannelSpec(_Model):
    """One entry of a channel map: lab channel -> canonical channel, unit and calibration."""

    to: _choice(*CANONICAL) = Field(description=f"canonical channel, one of {', '.join(CANONICAL)}")
    unit: Optional[Text] = None
    scale: _number(nonzero=True) = 1.0
    offset: Finite = 0.0
    delay_s: _number(abs_lt=1) = 0.0
    override_file_unit: bool = False
    angle_deg: Optional[_number(ge=-MAX_ANGLE_DEG, le=MAX_ANGLE_DEG)] = None

    @model_validator(mode="before")
    @classmethod
    def _table_only(cls, v):
        if not isinstance(v, dict):
            raise _err(f'must be a table like {{to = "x1", unit = "mil"}}, got {_describe(v)}')
        return v

    @model_validator(mode="after")
    def _unit_matches(self):
        if self.override_file_unit and self.unit is None:
            raise _err("override_file_unit = true needs the unit that replaces the file's", table=True)
        if self.angle_deg is not None and self.to not in ANGLED:
            raise _err(f"angle_deg is the measuring direction of a probe or housing accelerometer "
                       f"({', '.join(ANGLED)}), not of {self.to}", table=True)
        if self.unit is not None:
            q = QUANTITY[self.to]
            problem = _unit_problem(self.unit, q, f"{self.to} is {_article(q)}")
            if problem:
                raise _err(problem, table=True)
        return self


def _check_probe_pairs(angles: dict, present):
    """A ConfigError when the two channels of a plane in ``present`` (one of them at an angle,
    ``angles`` {channel: deg}) are within the least separation of parallel (found here rather
    than when the files are read)."""
    try:
        plane_transform(angles, tuple(present))
    except ValueError as exc:
        raise _err(str(exc), table=True) from None


def _check_channel_map(v):
    seen = {}
    for lab, spec in v.items():
        if not lab.strip():
            raise _err("channel names must not be empty", table=True)
        if spec.to in seen:
            raise _err(f"{seen[spec.to]!r} and {lab!r} both map to {spec.to}", table=True)
        seen[spec.to] = lab
    _check_probe_pairs({s.to: s.angle_deg for s in v.values() if s.angle_deg is not None}, seen)
    return v


class FileOptions(_Model):
    """``[files]``: defaults for reading every lab file (a run or test may override each)."""

    fs_hz: Optional[Positive] = None
    format: Format = "auto"
    group: Optional[Text] = None
    skip_rows: SkipRows = "auto"
    sep: Sep = "auto"
    decimal: Decimal = "auto"
    time_column: TimeColumn = "auto"


class KeyphasorOptions(_Model):
    """``[keyphasor]``: how the once-per-revolution pulses are found (defaults for every file)."""

    level: Level = "auto"
    hysteresis: Hysteresis = "auto"
    edge: Edge = "auto"
    mark_angle_deg: Finite = 0.0
    tolerance: Tolerance = 0.35
    fill_missing: bool = True
    refine: bool = True
    max_speed_step: Optional[_number(gt=0)] = None
    times_file: Optional[PathStr] = None


class KeyphasorOverride(_Model):
    """A run's or test's ``keyphasor = {...}``: any keys of ``[keyphasor]``, overriding them."""

    level: Optional[Level] = None
    hysteresis: Optional[Hysteresis] = None
    edge: Optional[Edge] = None
    mark_angle_deg: Optional[Finite] = None
    tolerance: Optional[Tolerance] = None
    fill_missing: Optional[bool] = None
    refine: Optional[bool] = None
    max_speed_step: Optional[_number(gt=0)] = None
    times_file: Optional[PathStr] = None


_READ_KEYS = ("fs_hz", "format", "group", "skip_rows", "sep", "decimal", "time_column")


class FileEntry(_Model):
    """A recording: a plain path, or a table with ``file``, ``files`` (one block per file) or
    ``file`` + ``groups`` (one block per TDMS group), plus per-file overrides.

    ``groups`` is ``"*"`` (every group of the file), a tuple of group names, or None: as
    ``rotorid.io.load_segmented(path, groups=...)`` takes it.
    """

    file: Optional[PathStr] = None
    files: Optional[PathList] = None
    groups: Optional[Groups] = None
    channels: Optional[dict[str, ChannelSpec]] = None
    format: Optional[Format] = None
    group: Optional[Text] = None
    fs_hz: Optional[Positive] = None
    skip_rows: Optional[SkipRows] = None
    sep: Optional[Sep] = None
    decimal: Optional[Decimal] = None
    time_column: Optional[TimeColumn] = None
    keyphasor: Optional[KeyphasorOverride] = None
    probes_at: Optional[ProbesAt] = None

    @field_validator("channels")
    @classmethod
    def _check_channels(cls, v):
        return None if v is None else _check_channel_map(v)

    @model_validator(mode="before")
    @classmethod
    def _from_path(cls, v):
        if isinstance(v, str):
            return {"file": v}
        if not isinstance(v, dict):
            raise _err(f'must be a file path or a table with file = "...", got {_describe(v)}')
        return v

    @model_validator(mode="after")
    def _one_source(self):
        if self.file is None and self.files is None:
            raise _err('needs file = "..." (one recording) or files = [...] (one recording saved as several '
                       'files)', table=True)
        if self.file is not None and self.files is not None:
            raise _err("give file or files, not both", table=True)
        if self.groups is not None and self.files is not None:
            raise _err('groups goes with file = "..." (one TDMS file), not with files = [...]', table=True)
        if self.groups is not None and self.group is not None:
            raise _err("give group or groups, not both", table=True)
        return self

    def paths(self, cfg: "Config") -> list:
        """The recording's files, resolved against the config's folder.

        Parameters
        ----------
        cfg : Config
            The config this entry belongs to.

        Returns
        -------
        list of pathlib.Path
            One path for ``file``, one per block for ``files``.

        Examples
        --------
        >>> from rotorid.config import parse_config
        >>> cfg = parse_config({"rig": {"builtin": "nsf"}, "impact": {"tests": [
        ...     {"files": ["a.csv", "b.csv"], "plane_m": 0.0, "direction": "x"}]}}, base_dir="/lab")
        >>> [p.as_posix() for p in cfg.impact.tests[0].paths(cfg)]
        ['/lab/a.csv', '/lab/b.csv']
        """
        return [cfg.resolve(p) for p in ((self.file,) if self.file is not None else self.files)]

    def meta(self) -> dict:
        """Recording metadata given by this entry (``load_recording(meta=...)``)."""
        return {"probes_at": self.probes_at} if self.probes_at is not None else {}


class ImbalanceRun(FileEntry):
    """One ``[[imbalance.runs]]`` entry: a recording with a known added imbalance."""

    name: Optional[Text] = None
    mass_g: Optional[_pair("m1, m2", nonneg=True)] = None
    mass_kg_: Optional[_pair("m1, m2", nonneg=True)] = Field(None, alias="mass_kg")
    angle_deg: Optional[_pair("phi1, phi2")] = None

    @model_validator(mode="after")
    def _imbalance(self):
        if self.mass_g is not None and self.mass_kg_ is not None:
            raise _err("give mass_g or mass_kg, not both", table=True)
        has_mass = self.mass_g is not None or self.mass_kg_ is not None
        if has_mass and self.angle_deg is None:
            raise _err("missing key 'angle_deg' (angles [phi1, phi2] of the added masses, deg), needed with "
                       f"{'mass_g' if self.mass_g is not None else 'mass_kg'}", table=True)
        if self.angle_deg is not None and not has_mass:
            raise _err("angle_deg without a mass: give mass_g = [m1, m2] or mass_kg = [m1, m2] too", table=True)
        return self

    def mass_kg(self):
        """The added masses in kg (``mass_g`` converted), or None when the config gives none.

        Returns
        -------
        tuple of 2 floats or None

        Examples
        --------
        >>> from rotorid.config import ImbalanceRun
        >>> ImbalanceRun.model_validate({"file": "run.tdms", "mass_g": [5, 2.5], "angle_deg": [0, 90]}).mass_kg()
        (0.005, 0.0025)
        """
        if self.mass_kg_ is not None:
            return self.mass_kg_
        if self.mass_g is not None:
            return tuple(m * 1e-3 for m in self.mass_g)
        return None

    def imbalance_meta(self):
        """``{"mass_kg": [m1, m2], "angle_deg": [a1, a2], "name": ...}`` (the ``imbalance`` entry of a
        Recording's meta), or None when the config gives no mass (the file's metadata must)."""
        m = self.mass_kg()
        if m is None:
            return None
        return {"mass_kg": list(m), "angle_deg": list(self.angle_deg), "name": self.name}

    def meta(self) -> dict:
        out = super().meta()
        if self.name is not None:
            out["name"] = self.name
        imb = self.imbalance_meta()
        if imb is not None:
            out["imbalance"] = imb
        return out


class ImpactTest(FileEntry):
    """One ``[[impact.tests]]`` entry: impacts at one plane in one direction."""

    plane_m: Finite = Field(description="axial position of the impacts from the CG, m (+ toward bearing 2)")
    direction: Direction = Field(description='direction of the impacts, "x" or "y"')
    name: Optional[Text] = None

    def meta(self) -> dict:
        out = super().meta()
        out.update(plane=self.plane_m, direction=self.direction)
        if self.name is not None:
            out["name"] = self.name
        return out


class OneXColumn(_Model):
    """Columns of one probe in a DAQ 1X table."""

    amplitude: Text = Field(description="name of the amplitude column")
    phase: Text = Field(description="name of the phase column")
    angle_deg: Optional[_number(ge=-MAX_ANGLE_DEG, le=MAX_ANGLE_DEG)] = Field(None, description="direction the probe measures along, "
                                                                          "degrees from +x toward +y (default x 0, y 90)")


class OneXColumns(_Model):
    """``columns`` of ``[imbalance.table]``: all four probes, and the four housing accelerometers
    (all or none) with ``[pedestals]``."""

    x1: OneXColumn = Field(description="x1 = {amplitude = ..., phase = ...}")
    x2: OneXColumn = Field(description="x2 = {amplitude = ..., phase = ...}")
    y1: OneXColumn = Field(description="y1 = {amplitude = ..., phase = ...}")
    y2: OneXColumn = Field(description="y2 = {amplitude = ..., phase = ...}")
    px1: Optional[OneXColumn] = Field(None, description="housing accelerometer, bearing 1 x")
    px2: Optional[OneXColumn] = Field(None, description="housing accelerometer, bearing 2 x")
    py1: Optional[OneXColumn] = Field(None, description="housing accelerometer, bearing 1 y")
    py2: Optional[OneXColumn] = Field(None, description="housing accelerometer, bearing 2 y")

    @model_validator(mode="after")
    def _all_or_none(self):
        names = ("px1", "px2", "py1", "py2")
        have = [n for n in names if getattr(self, n) is not None]
        if have and len(have) != 4:
            missing = [n for n in names if n not in have]
            raise _err(f"gives accelerometer columns {', '.join(have)} but not {', '.join(missing)}: give all four "
                       "housing accelerometers or none", missing[0])
        present = [n for n in ("x1", "x2", "y1", "y2", *names) if getattr(self, n) is not None]
        _check_probe_pairs({n: getattr(self, n).angle_deg for n in present if getattr(self, n).angle_deg is not None},
                           present)
        return self


class OneXTable(_Model):
    """``[imbalance.table]``: the run files are DAQ 1X tables (amplitude, phase per speed).

    Defaults follow :func:`rotorid.tables.load_1x_table` (mils peak-to-peak, degrees of lag);
    :meth:`reader_kwargs` gives its keyword arguments.
    """

    columns: OneXColumns = Field(description="x1, x2, y1, y2 = {amplitude = \"...\", phase = \"...\"}")
    speed_column: Text = "auto"
    amplitude: _choice("pk-pk", "0-pk") = "pk-pk"
    unit: LengthUnit = "mil"
    phase: _choice("lag", "lead") = "lag"
    phase_unit: _choice("deg", "rad") = "deg"
    sheet: Optional[Sheet] = None
    skip_rows: SkipRows = "auto"
    slow_roll_max_rpm: Optional[Positive] = None
    amplitude_std: Optional[NonNeg] = None
    phase_std_deg: Optional[NonNeg] = None
    accel_unit: AccelUnit = "g"
    accel_amplitude: Optional[_choice("pk-pk", "0-pk")] = None
    accel_amplitude_std: Optional[NonNeg] = None

    def reader_kwargs(self) -> dict:
        """Keyword arguments of ``rotorid.tables.load_1x_table`` (all but the path).

        Examples
        --------
        >>> from rotorid.config import OneXTable
        >>> cols = {k: {"amplitude": f"{k} amp", "phase": f"{k} ph"} for k in ("x1", "x2", "y1", "y2")}
        >>> kw = OneXTable.model_validate({"columns": cols, "unit": "um", "amplitude": "0-pk"}).reader_kwargs()
        >>> kw["columns"]["y2"], kw["unit"], kw["amplitude"], kw["phase"], kw["skip_rows"]
        ({'amplitude': 'y2 amp', 'phase': 'y2 ph'}, 'um', '0-pk', 'lag', 'auto')
        """
        return {"columns": self.columns.model_dump(exclude_none=True), "speed_column": self.speed_column,
                "amplitude": self.amplitude, "unit": self.unit, "phase": self.phase, "phase_unit": self.phase_unit,
                "sheet": self.sheet, "skip_rows": self.skip_rows, "amplitude_std": self.amplitude_std,
                "phase_std_deg": self.phase_std_deg, "accel_unit": self.accel_unit,
                "accel_amplitude": self.accel_amplitude, "accel_amplitude_std": self.accel_amplitude_std}


class ImbalanceSection(_Model):
    """``[imbalance]``: imbalance-response identification."""

    runs: list[ImbalanceRun] = Field(min_length=1, description="[[imbalance.runs]] tables, at least one")
    baseline: Optional[FileEntry] = None
    slow_roll: Optional[FileEntry] = None
    steady: bool = True
    speeds_rpm: Optional[_number_list(gt=0)] = None
    orders: _number_list(integer=True, ge=1, unique=True, must_contain=1) = (1, 2, 3)
    method: Method = "forces"
    identical: bool = False
    points_per_rev: _number(integer=True, ge=16, le=65536, auto=True) = "auto"
    min_revs: _number(integer=True, ge=2) = 8
    settle_revs: _number(integer=True, ge=0) = 2
    speed_tolerance: _number(gt=0, lt=0.5) = 0.005
    revs_per_block: _number(integer=True, ge=1) = 4
    speed_match_rpm: Optional[_number(gt=0)] = None
    cond_max: _number(gt=1) = 1e4
    min_rel_amplitude: _number(ge=0, lt=1) = 0.08
    max_rel_std: _number(gt=0) = 0.1
    estimator: _choice("ls", "bias-corrected") = "ls"
    phase_calibration: _choice("off", "report", "apply") = "report"
    keyphasor_angle_std_deg: _number(ge=0, lt=45) = 0.0
    keyphasor_delay_std_s: NonNeg = 0.0
    table: Optional[OneXTable] = None

    @model_validator(mode="after")
    def _table_mode(self):
        if self.table is None:
            return self
        for loc, entry in self.entries():
            for key in ("channels", "keyphasor", "groups", "fs_hz", "time_column"):
                if getattr(entry, key) is not None:
                    raise _err(f"has no meaning for a DAQ 1X table (with [imbalance.table] the files are 1X tables, "
                               "not waveforms)", *loc, key)
        return self

    def entries(self):
        """(location, FileEntry) of every run, the baseline and the slow roll, location relative
        to this section."""
        out = [(("runs", i), r) for i, r in enumerate(self.runs)]
        out += [((k,), getattr(self, k)) for k in ("baseline", "slow_roll") if getattr(self, k) is not None]
        return out


class ImpactSection(_Model):
    """``[impact]``: impact (hammer) identification."""

    tests: list[ImpactTest] = Field(min_length=1, description="[[impact.tests]] tables, at least one")
    band_hz: Band = (5.0, 150.0)
    record_s: Positive = 0.25
    pre_s: NonNeg = 0.01
    zero_pad_s: Optional[Positive] = None
    identical: bool = False
    method: Method = "forces"
    runout: bool = True
    revs_before: _number(integer=True, ge=1) = 8
    points_per_rev: _number(integer=True, ge=16, le=65536) = 256
    exp_window_tau_s: Optional[Positive] = None
    threshold_N: Optional[Positive] = None
    min_separation_s: Positive = 0.2
    double_hit_window_s: Positive = 0.02
    overload_N: Optional[Positive] = None
    coherence_min: _number(ge=0, le=1) = 0.9
    speed_rpm: Optional[Positive] = None
    cond_max: _number(gt=1) = 1e4
    min_rel_amplitude: _number(ge=0, lt=1) = 0.01
    max_rel_std: _number(gt=0) = 0.1
    estimator: _choice("ls", "bias-corrected") = "ls"
    kcm_band_hz: Optional[Band] = None

    @model_validator(mode="after")
    def _record(self):
        if not self.pre_s < self.record_s:
            raise _err(f"must be < record_s ({self.record_s:g} s), got {self.pre_s:g}", "pre_s")
        if self.zero_pad_s is not None and not self.zero_pad_s >= self.record_s:
            raise _err(f"must be >= record_s ({self.record_s:g} s), got {self.zero_pad_s:g}", "zero_pad_s")
        return self

    def entries(self):
        """(location, FileEntry) of every test, location relative to this section."""
        return [(("tests", i), t) for i, t in enumerate(self.tests)]


class PedestalsSection(_Model):
    """``[pedestals]``: flexible bearing housings whose motion accelerometers measure (channels
    px1, px2, py1, py2 on every run, baseline and test)."""

    measured: bool = Field(description="true: identify with the housings' motion from the accelerometers; "
                                       "false: ignore accelerometer channels")
    identify: Optional[bool] = Field(None, description="also identify the pedestals' mass, stiffness and damping "
                                                       "(pedestals_<kind>.csv); needs measured = true; default: "
                                                       "as measured")
    cross_coupled: bool = Field(False, description="pedestal stiffness and damping with xy, yx terms")
    freq_range_hz: Optional[Band] = Field(None, description="Hz: points used for the pedestal fit (default all)")
    accel_gain_std: _number(ge=0, lt=0.5) = Field(0.0, description="relative calibration uncertainty of each "
                                                                   "accelerometer's sensitivity (0.02 = 2 %)")
    accel_phase_std_deg: _number(ge=0, lt=45) = Field(0.0, description="calibration uncertainty of each "
                                                                       "accelerometer's phase, degrees")

    @model_validator(mode="after")
    def _identify_needs_measured(self):
        if self.identify and not self.measured:
            raise _err("needs measured = true (the pedestal parameters come from the accelerometers); leave it "
                       "out or set it false when the accelerometers are ignored", "identify")
        return self

    @property
    def fit_pedestals(self) -> bool:
        """Whether the pedestals' parameters are identified (``identify``, by default ``measured``)."""
        return self.measured if self.identify is None else self.identify


def _check_report(v):
    """``[output] report``: true/false, or a plain file name ending in .html (in the output folder)."""
    if isinstance(v, bool):
        return v
    if isinstance(v, str):
        if not v.lower().endswith((".html", ".htm")):
            raise _err(f"must be true, false or a file name ending in .html, got {_describe(v)}")
        if os.path.basename(v) != v or v.startswith("."):
            raise _err(f"must be a plain file name in the output folder (no folder part), got {_describe(v)}; "
                       "rotorid identify --report PATH writes elsewhere")
        return v
    raise _err(f"must be true, false or a file name ending in .html, got {_describe(v)}")


class OutputSection(_Model):
    """``[output]``: where the tables and plots go and in which units."""

    dir: Optional[Text] = None
    units: _choice("SI", "US", ignore_case=True) = "SI"
    amplitude: _choice("0-pk", "pk-pk") = Field("0-pk", description="1X amplitudes written and printed: "
                                                "zero-to-peak or peak-to-peak")
    phase: _choice("lag", "arg") = Field("lag", description="phases written and printed: lag (as a DAQ shows it, "
                                         "0-360 deg) or arg (of the complex amplitude, -180..180 deg)")
    formats: tuple[_choice("xlsx", "json", "nc"), ...] = Field((), description="coefficient files besides the CSV")
    report: Annotated[Union[bool, str], PlainValidator(_check_report)] = Field(
        False, description="an HTML report in the output folder: true (report_<kind>.html) or its file name")

    @field_validator("formats", mode="before")
    @classmethod
    def _unique_formats(cls, v):
        if isinstance(v, list) and len(set(map(str, v))) != len(v):
            raise _err(f"lists a format twice: {v}")
        return tuple(v) if isinstance(v, list) else v

    def conventions(self):
        """The :class:`rotorid.units.OutputUnits` of this section (units, amplitude, phase).

        Examples
        --------
        >>> from rotorid.config import OutputSection
        >>> OutputSection.model_validate({"units": "us", "amplitude": "pk-pk"}).conventions()
        OutputUnits('US', amplitude='pk-pk', phase='lag')
        """
        return _units.OutputUnits(self.units, amplitude=self.amplitude, phase=self.phase)


def _structure_problems(data) -> list:
    """Problems of the overall layout (checked on the raw table, so they are reported together
    with the problems inside the sections)."""
    out = []
    if "rig" in data and "rotor" in data:
        out.append('[rig] and [rotor] are both given: use one, [rig] builtin = "nsf" or your own [rotor]')
    elif "rig" not in data and "rotor" not in data:
        out.append('the config names no rotor: give [rig] builtin = "nsf" or a [rotor] table')
    if not any(k in data for k in _SECTIONS):
        out.append("the config has no [imbalance] section and no [impact] section: give at least one")
    return out


class Config(_Model):
    """A validated config. Build it with :func:`load_config` or :func:`parse_config`.

    Sections are attributes: ``rig``, ``rotor_table`` (the ``[rotor]`` table; :meth:`rotor` gives
    the RigidRotor of either), ``channels``, ``files``, ``keyphasor``, ``imbalance``, ``impact``,
    ``pedestals``, ``output``.
    """

    rig: Optional[RigSection] = None
    rotor_table: Optional[RotorSection] = Field(None, alias="rotor")
    channels: dict[str, ChannelSpec] = Field(default_factory=dict)
    files: FileOptions = Field(default_factory=FileOptions)
    keyphasor: KeyphasorOptions = Field(default_factory=KeyphasorOptions)
    imbalance: Optional[ImbalanceSection] = None
    impact: Optional[ImpactSection] = None
    pedestals: Optional[PedestalsSection] = None
    output: OutputSection = Field(default_factory=OutputSection)

    _source: str = PrivateAttr("<config>")
    _base_dir: Path = PrivateAttr(default_factory=Path.cwd)

    @field_validator("channels")
    @classmethod
    def _check_channels(cls, v):
        return _check_channel_map(v)

    @model_validator(mode="before")
    @classmethod
    def _legacy_fs_hz(cls, data):
        # backward compatibility: a numeric fs_hz inside [channels] belongs to [files]
        if not (isinstance(data, dict) and isinstance(data.get("channels"), dict) and "fs_hz" in data["channels"]):
            return data
        fs = data["channels"]["fs_hz"]
        if isinstance(fs, dict):
            return data  # a lab channel that happens to be called fs_hz
        if _as_float(fs) is None or not (math.isfinite(_as_float(fs)) and _as_float(fs) > 0):
            raise _err(f"must be a number > 0 (sample rate, Hz; its place is [files]), got {_describe(fs)}",
                       "channels", "fs_hz")
        files = data.get("files", {})
        if isinstance(files, dict) and "fs_hz" in files:
            raise _err("fs_hz is given both in [channels] (its old place) and in [files]: keep the one in [files]",
                       "channels", table=True)
        data = dict(data)
        data["channels"] = {k: v for k, v in data["channels"].items() if k != "fs_hz"}
        if isinstance(files, dict):
            data["files"] = {**files, "fs_hz": fs}
        return data

    @model_validator(mode="after")
    def _layout(self):
        data = {k: None for k in ("rig", "imbalance", "impact") if getattr(self, k) is not None}
        if self.rotor_table is not None:
            data["rotor"] = None
        problems = _structure_problems(data)
        if problems:
            raise _err(problems[0], table=True)
        return self

    # -- where the config lives ----------------------------------------------------------------
    @property
    def source(self) -> str:
        """The config file as given (or the ``source`` of :func:`parse_config`)."""
        return self._source

    @property
    def base_dir(self) -> Path:
        """The folder relative paths are resolved against (the config file's folder)."""
        return self._base_dir

    def resolve(self, relpath) -> Path:
        """A path of the config, relative to the config file's folder (``~`` expanded).

        Parameters
        ----------
        relpath : str or os.PathLike
            A path as written in the config; absolute paths are kept.

        Returns
        -------
        pathlib.Path

        Examples
        --------
        >>> from rotorid.config import parse_config
        >>> cfg = parse_config({"rig": {"builtin": "nsf"}, "impact": {"tests": [
        ...     {"file": "hits.tdms", "plane_m": 0.0, "direction": "x"}]}}, base_dir="/lab/day1")
        >>> cfg.resolve("../day2/hits.tdms").as_posix()
        '/lab/day2/hits.tdms'
        """
        p = Path(os.path.expanduser(os.fspath(relpath)))
        if not p.is_absolute():
            p = self._base_dir / p
        return Path(os.path.normpath(p))

    # -- what the pipeline needs ---------------------------------------------------------------
    def rotor(self):
        """The :class:`rotorid.RigidRotor` of ``[rig]`` or ``[rotor]``.

        Examples
        --------
        >>> from rotorid.config import parse_config
        >>> cfg = parse_config({"rig": {"builtin": "nsf"}, "impact": {"tests": [
        ...     {"file": "hits.tdms", "plane_m": 0.0, "direction": "x"}]}})
        >>> cfg.rotor().mass_kg
        45.3
        """
        if self.rotor_table is not None:
            return self.rotor_table.build()
        from .model import nsf_rig

        return nsf_rig().rotor

    def section(self, kind: str):
        """The ``[imbalance]`` or ``[impact]`` section; ConfigError when the config has none.

        Examples
        --------
        >>> from rotorid.config import parse_config
        >>> cfg = parse_config({"rig": {"builtin": "nsf"}, "impact": {"tests": [
        ...     {"file": "hits.tdms", "plane_m": 0.0, "direction": "x"}]}}, source="rig.toml")
        >>> cfg.section("impact").record_s
        0.25
        >>> cfg.section("imbalance")
        Traceback (most recent call last):
        ...
        rotorid.config.ConfigError: rig.toml: no [imbalance] section (the config has [impact])
        """
        if kind not in _SECTIONS:
            raise RotoridError(f"kind must be 'imbalance' or 'impact', got {kind!r}")
        sec = getattr(self, kind)
        if sec is None:
            has = [f"[{k}]" for k in _SECTIONS if getattr(self, k) is not None]
            raise ConfigError.from_problems(self._source, [f"no [{kind}] section (the config has {', '.join(has)})"])
        return sec

    def output_dir(self, kind: str) -> Path:
        """``[output] dir`` resolved (default ``rotorid_<kind>`` next to the config)."""
        return self.resolve(self.output.dir or f"rotorid_{kind}")

    def channels_for(self, entry=None, *, only=None) -> dict:
        """The channel map that applies to ``entry``: its own ``channels`` or ``[channels]``.

        Parameters
        ----------
        entry : FileEntry, optional
            A run, test, baseline or slow roll of this config; None for ``[channels]``.
        only : iterable of str, optional
            Keep only the lab channels mapped to these canonical names.

        Returns
        -------
        dict
            ``{lab channel: {"to", "unit", "scale", "offset", "delay_s"}}`` (plain dicts; ``unit``
            None means the unit the file states).

        Examples
        --------
        >>> from rotorid.config import parse_config
        >>> chans = {"DE X": {"to": "x1", "unit": "mil"}, "Hammer": {"to": "force", "unit": "N"}}
        >>> cfg = parse_config({"rig": {"builtin": "nsf"}, "channels": chans, "imbalance": {"runs": ["run.tdms"]}})
        >>> cfg.channels_for(cfg.imbalance.runs[0], only={"x1", "x2", "y1", "y2", "kp"})
        {'DE X': {'to': 'x1', 'unit': 'mil', 'scale': 1.0, 'offset': 0.0, 'delay_s': 0.0}}
        """
        m = entry.channels if entry is not None and entry.channels is not None else self.channels
        keep = None if only is None else set(only)
        return {lab: _map_entry(spec) for lab, spec in m.items() if keep is None or spec.to in keep}

    def files_for(self, entry=None) -> dict:
        """Reading options for ``entry``: ``[files]`` with the entry's overrides, "auto" -> None.

        Returns
        -------
        dict
            Keys ``fs_hz, fmt, group, skip_rows, sep, decimal, time_column`` (``time_column``
            False: the file has no time column; ``group`` None for an entry with ``groups``), the
            keyword arguments of ``rotorid.io.load_recording``.

        Examples
        --------
        >>> from rotorid.config import parse_config
        >>> cfg = parse_config({"rig": {"builtin": "nsf"}, "files": {"fs_hz": 10000, "sep": ";"},
        ...                     "imbalance": {"runs": [{"file": "run.csv", "decimal": ","}]}})
        >>> cfg.files_for(cfg.imbalance.runs[0])  # doctest: +NORMALIZE_WHITESPACE
        {'fs_hz': 10000.0, 'fmt': None, 'group': None, 'skip_rows': None, 'sep': ';', 'decimal': ',',
         'time_column': None}
        """
        out = {}
        for key in _READ_KEYS:
            v = getattr(entry, key, None) if entry is not None else None
            if v is None:
                v = getattr(self.files, key)
            out["fmt" if key == "format" else key] = None if isinstance(v, str) and v == "auto" else v
        if entry is not None and entry.groups is not None:
            out["group"] = None  # the entry's groups say which groups are read
        return out

    def keyphasor_for(self, entry=None) -> dict:
        """Keyphasor options for ``entry``: ``[keyphasor]`` with the entry's ``keyphasor`` overrides.

        Returns
        -------
        dict
            ``level, hysteresis`` (None for "auto"), ``edge`` ("auto", "rising", "falling", as
            ``signals.keyphasor_times`` takes it), ``mark_angle_deg, tolerance, fill_missing``
            (keyword arguments of ``signals.keyphasor_times``) and ``times_file`` (a resolved Path
            or None: pulse times given instead of detected; pop it before calling
            ``keyphasor_times``).

        Examples
        --------
        >>> from rotorid.config import parse_config
        >>> cfg = parse_config({"rig": {"builtin": "nsf"}, "keyphasor": {"level": 2.5},
        ...                     "imbalance": {"runs": [{"file": "run.tdms", "keyphasor": {"edge": "falling"}}]}})
        >>> cfg.keyphasor_for(cfg.imbalance.runs[0])  # doctest: +NORMALIZE_WHITESPACE
        {'level': 2.5, 'hysteresis': None, 'edge': 'falling', 'mark_angle_deg': 0.0, 'tolerance': 0.35,
         'fill_missing': True, 'refine': True, 'max_speed_step': None, 'times_file': None}
        """
        kp = self.keyphasor.model_dump()
        if entry is not None and entry.keyphasor is not None:
            kp.update({k: v for k, v in entry.keyphasor.model_dump().items() if v is not None})
        for key in ("level", "hysteresis"):
            if kp[key] == "auto":
                kp[key] = None
        kp["times_file"] = None if kp["times_file"] is None else self.resolve(kp["times_file"])
        return kp

    def entries(self):
        """(location, FileEntry) of every recording the config names, e.g.
        ``(("imbalance", "runs", 0), run)``."""
        out = []
        for kind in _SECTIONS:
            sec = getattr(self, kind)
            if sec is not None:
                out += [((kind,) + loc, e) for loc, e in sec.entries()]
        return out

    def check_files(self) -> None:
        """Raise ConfigError naming every referenced file that does not exist."""
        problems = _file_problems(self)
        if problems:
            raise ConfigError.from_problems(self._source, problems)


# =============================================================================================
# formatting pydantic's errors as one-line messages

def _field_map(model) -> dict:
    """{key as written in TOML: FieldInfo}."""
    return {(f.alias or name): f for name, f in model.model_fields.items()}


def _unwrap(tp):
    while True:
        origin = typing.get_origin(tp)
        if origin is Annotated:
            tp = typing.get_args(tp)[0]
        elif origin in (Union, types.UnionType):
            args = [a for a in typing.get_args(tp) if a is not type(None)]
            if len(args) != 1:
                return tp
            tp = args[0]
        else:
            return tp


def _is_model(tp) -> bool:
    return isinstance(tp, type) and issubclass(tp, BaseModel)


def _type_at(loc, root=None):
    """The declared type at a location (model class, list[...], dict[...], ...) or None, in the
    schema ``root`` (default: the identification config)."""
    tp = Config if root is None else root
    for el in loc:
        tp = _unwrap(tp)
        if _is_model(tp):
            f = _field_map(tp).get(el) if isinstance(el, str) else None
            if f is None:
                return None
            tp = f.annotation
        elif typing.get_origin(tp) is list and isinstance(el, int):
            tp = typing.get_args(tp)[0]
        elif typing.get_origin(tp) is dict:
            tp = typing.get_args(tp)[1]
        else:
            return None
    return _unwrap(tp)


_BARE = re.compile(r"[A-Za-z0-9_-]+")


def _key(k) -> str:
    """A key as TOML writes it: bare or quoted."""
    k = str(k)
    if _BARE.fullmatch(k):
        return k
    esc = "".join("\\" + c if c in '"\\' else (c if c.isprintable() else c.encode("unicode_escape").decode("ascii"))
                  for c in k)
    return f'"{esc}"'


def _where(loc) -> str:
    """("imbalance", "runs", 2, "keyphasor") -> '[imbalance.runs][2].keyphasor'."""
    out, pending = "", []

    def flush():
        nonlocal out
        if pending:
            out += ("[" + ".".join(pending) + "]") if not out else "." + ".".join(pending)
            pending.clear()

    for el in loc:
        if isinstance(el, int):
            flush()
            out += f"[{el}]"
        else:
            pending.append(_key(el))
    flush()
    return out


def _split(loc):
    """Table part and key part (last key plus the indices after it) of a location."""
    loc = tuple(loc)
    k = max((i for i, el in enumerate(loc) if not isinstance(el, int)), default=None)
    if k is None:
        return loc, ""
    return loc[:k], _key(loc[k]) + "".join(f"[{i}]" for i in loc[k + 1:])


def _join(where: str, text: str) -> str:
    return f"{where} {text}" if where else text


def _keyed(loc, text: str) -> str:
    table, key = _split(loc)
    return _join(_where(table), f"{key} {text}" if key else text)


_TYPE_WANTS = {
    "bool_type": "must be true or false", "bool_parsing": "must be true or false",
    "string_type": "must be a string", "int_type": "must be an integer", "int_parsing": "must be an integer",
    "int_from_float": "must be an integer", "float_type": "must be a number", "float_parsing": "must be a number",
    "finite_number": "must be a finite number", "list_type": "must be an array", "tuple_type": "must be an array",
    "dict_type": "must be a table", "model_type": "must be a table", "model_attributes_type": "must be a table",
}


def _message(e, root=None) -> str:
    typ, loc, ctx = e["type"], tuple(e["loc"]), e.get("ctx") or {}
    inp = e.get("input")
    if typ == "rotorid":
        full = loc + tuple(ctx.get("at", ()))
        if ctx.get("table"):
            return _join(_where(full), ctx["msg"])
        if ctx.get("keyless"):
            return _join(_where(_split(full)[0]), ctx["msg"])
        return _keyed(full, ctx["msg"])
    if typ == "extra_forbidden" and loc:
        parent, key = loc[:-1], loc[-1]
        model = _type_at(parent, root)
        allowed = list(_field_map(model)) if _is_model(model) else []
        hint = _suggest(str(key), allowed)
        if not parent:
            return f"unknown top-level key {str(key)!r}{hint}"
        return f"{_where(parent)} unknown key {str(key)!r}{hint}"
    if typ == "missing" and loc:
        parent, key = loc[:-1], loc[-1]
        model = _type_at(parent, root)
        f = _field_map(model).get(key) if _is_model(model) and isinstance(key, str) else None
        desc = f" ({f.description})" if f is not None and f.description else ""
        return _join(_where(parent), f"missing required key {str(key)!r}{desc}")
    if typ in ("too_short", "too_long"):
        n = ctx.get("min_length" if typ == "too_short" else "max_length")
        what = "at least" if typ == "too_short" else "at most"
        return _keyed(loc, f"must have {what} {n} entr{'y' if n == 1 else 'ies'}, got {ctx.get('actual_length')}")
    want = _TYPE_WANTS.get(typ)
    if want == "must be an array":
        target = _type_at(loc, root)
        if typing.get_origin(target) is list and _is_model(_unwrap(typing.get_args(target)[0])):
            name = ".".join(str(x) for x in loc if isinstance(x, str))
            want = f"must be an array of tables ([[{name}]])"
    if want is None:
        want = str(e.get("msg", "is not valid"))
        want = want[:1].lower() + want[1:]
    return _keyed(loc, f"{want}, got {_describe(inp)}")


def _messages(exc: ValidationError, root=None) -> list:
    """One line per problem of a failed validation against the schema ``root`` (default: the
    identification config)."""
    errors = exc.errors(include_url=False)
    missing = {}  # several missing keys of one table -> one message
    for e in errors:
        if e["type"] == "missing" and e["loc"]:
            missing.setdefault(tuple(e["loc"][:-1]), []).append(e["loc"][-1])
    out, done = [], set()
    for e in errors:
        parent = tuple(e["loc"][:-1])
        if e["type"] == "missing" and e["loc"] and len(missing[parent]) > 1:
            if parent not in done:
                done.add(parent)
                keys = ", ".join(repr(str(k)) for k in missing[parent])
                out.append(_one_line(_join(_where(parent), f"missing required keys {keys}")))
            continue
        out.append(_one_line(_message(e, root)))
    return out


# =============================================================================================
# checks after the schema

def _effective_format(cfg: Config, entry: FileEntry) -> str:
    return entry.format if entry.format is not None else cfg.files.format


def _semantic_problems(cfg: Config) -> list:
    """Problems that involve more than one table (no file system access)."""
    out = []
    f = cfg.files
    if f.sep == f.decimal and f.sep != "auto":
        out.append(f"[files] sep and decimal are both {f.sep!r}")
    if cfg.pedestals is None:
        # accelerometers mapped but no pedestal model: they would be silently ignored
        maps = [(("channels",), cfg.channels)] + [(loc + ("channels",), e.channels) for loc, e in cfg.entries()
                                                  if e.channels is not None]
        for loc, m in maps:
            for lab, spec in m.items():
                if spec.to in ("px1", "px2", "py1", "py2"):
                    out.append(_keyed(loc + (lab,), f"maps to the accelerometer channel {spec.to} but the config has "
                                      "no [pedestals] section: add [pedestals] measured = true to identify with the "
                                      "housings' motion (or measured = false to ignore the accelerometers)"))
    for loc, entry in cfg.entries():
        kw = cfg.files_for(entry)
        own = entry.sep is not None or entry.decimal is not None
        if own and kw["sep"] is not None and kw["sep"] == kw["decimal"]:
            out.append(_join(_where(loc), f"sep and decimal are both {kw['sep']!r} (with [files])"))
        if entry.groups is not None:
            fmt = _effective_format(cfg, entry)
            if fmt not in ("tdms",) and not (fmt == "auto" and entry.file.lower().endswith(".tdms")):
                out.append(_keyed(loc + ("groups",), f"needs a TDMS file, but {entry.file!r} is read as "
                                  f"{fmt if fmt != 'auto' else 'not TDMS (by its extension)'}"))
    return out


def _path_problem(cfg: Config, rel: str):
    p = cfg.resolve(rel)
    try:
        if p.is_file():
            return None
        if p.is_dir():
            return f"{rel!r} is a directory, not a file"
        if p.exists():
            return None  # a device or a pipe: let the reader try
        parent = p.parent
        gone = "" if parent.is_dir() else ", which does not exist"
        return f"{rel!r} not found (looked in {parent}{gone})"
    except OSError as exc:
        return f"{rel!r} cannot be checked ({exc.strerror or exc})"


def _file_problems(cfg: Config) -> list:
    """Every referenced file that does not exist (relative to the config's folder)."""
    out = []
    if cfg.keyphasor.times_file is not None:
        prob = _path_problem(cfg, cfg.keyphasor.times_file)
        if prob:
            out.append(f"[keyphasor] times_file {prob}")
    for loc, entry in cfg.entries():
        if entry.file is not None:
            prob = _path_problem(cfg, entry.file)
            if prob:
                if entry.model_fields_set == {"file"} and isinstance(loc[-1], str):
                    out.append(_keyed(loc, prob))  # written as baseline = "file"
                else:
                    out.append(_join(_where(loc), f"file {prob}"))
        for j, rel in enumerate(entry.files or ()):
            prob = _path_problem(cfg, rel)
            if prob:
                out.append(_join(_where(loc), f"files[{j}] {prob}"))
        if entry.keyphasor is not None and entry.keyphasor.times_file is not None:
            prob = _path_problem(cfg, entry.keyphasor.times_file)
            if prob:
                out.append(_join(_where(loc + ("keyphasor",)), f"times_file {prob}"))
    return out


# =============================================================================================
# public entry points

def parse_config(data, *, source="<config>", base_dir=".", check_files=False) -> Config:
    """Validate a config given as a table (the result of ``tomllib.load``).

    Parameters
    ----------
    data : dict
        The parsed TOML.
    source : str
        Name of the config for messages (``"rig.toml: ..."``).
    base_dir : str or os.PathLike
        Folder that relative paths are resolved against (the config file's folder).
    check_files : bool
        Also check that every referenced file exists (:func:`load_config` does by default).

    Returns
    -------
    Config

    Raises
    ------
    ConfigError
        One line naming ``source``, the locations and what is wrong (first few problems).

    Examples
    --------
    >>> from rotorid.config import parse_config
    >>> cfg = parse_config({"rig": {"builtin": "nsf"},
    ...                     "imbalance": {"runs": [{"file": "run.tdms", "mass_g": [5, 5], "angle_deg": [0, 90]}]}})
    >>> cfg.imbalance.runs[0].mass_kg(), cfg.imbalance.steady, cfg.imbalance.orders
    ((0.005, 0.005), True, (1, 2, 3))
    >>> parse_config({"rig": {"builtin": "nsf"}, "imbalance": {"steady": "false", "runs": [
    ...     {"file": "run.tdms", "angle_degs": [0, 0]}]}}, source="rig.toml")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    rotorid.config.ConfigError: rig.toml: [imbalance.runs][0] unknown key 'angle_degs' (did you mean 'angle_deg'?); ...
    """
    if not isinstance(data, dict):
        raise ConfigError.from_problems(source, [f"a config must be a table of sections, got {_describe(data)}"])
    try:
        cfg = Config.model_validate(data)
    except ValidationError as exc:
        raise ConfigError.from_problems(source, _messages(exc) + _structure_problems(data)) from None
    cfg._source = str(source)
    cfg._base_dir = Path(os.path.abspath(os.path.expanduser(os.fspath(base_dir))))
    problems = _semantic_problems(cfg)
    if check_files:
        problems += _file_problems(cfg)
    if problems:
        raise ConfigError.from_problems(cfg._source, problems)
    return cfg


def read_toml(path):
    """Read a UTF-8 TOML config file: (table, name for messages, folder of the file). Every failure
    (missing, a folder, unreadable, not UTF-8, not TOML) is one ConfigError line naming the file."""
    from ._validate import path as _path

    src = os.fspath(path) if isinstance(path, (str, bytes, os.PathLike)) else path
    src = src.decode(errors="replace") if isinstance(src, bytes) else src
    p = _path("path", src)
    where = Path(os.path.abspath(p)).parent
    if p.is_dir():
        raise ConfigError.from_problems(src, ["is a directory, not a config file"])
    try:
        raw = p.read_bytes()
    except FileNotFoundError:
        raise ConfigError.from_problems(src, [f"config file not found (looked in {where})"]) from None
    except PermissionError:
        raise ConfigError.from_problems(src, ["cannot read the config file (permission denied)"]) from None
    except OSError as exc:
        raise ConfigError.from_problems(src, [f"cannot read the config file ({exc.strerror or exc})"]) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        col = exc.start - (raw.rfind(b"\n", 0, exc.start) + 1) + 1
        raise ConfigError.from_problems(src, [f"not UTF-8 text (byte 0x{raw[exc.start]:02x} at line {line}, column "
                                              f"{col}); save the config as UTF-8"]) from None
    text = text.removeprefix("\ufeff")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        msg = str(exc)
        msg = msg[:1].lower() + msg[1:] if msg[1:2].islower() else msg
        hint = ""
        if "escape" in msg.lower() or "\\" in msg:
            hint = " (for Windows paths use single quotes, 'C:\\data\\run.tdms', or forward slashes)"
        raise ConfigError.from_problems(src, [f"not valid TOML: {msg}{hint}"]) from None
    except RecursionError:
        raise ConfigError.from_problems(src, ["not valid TOML: nested too deeply"]) from None
    return data, src, where


def load_config(path, *, check_files=True) -> Config:
    """Read, validate and check a TOML config file before any processing.

    Parameters
    ----------
    path : str or os.PathLike
        The config file (UTF-8 TOML). Paths in it are relative to its folder.
    check_files : bool
        Check that every referenced recording (and keyphasor times file) exists (default True).

    Returns
    -------
    Config

    Raises
    ------
    ConfigError
        One line, e.g. ``rig.toml: [imbalance.runs][0] file 'run_S0.tdms' not found (looked in
        /lab/day1)``, for a missing, unreadable, non-UTF-8 or invalid TOML file and for every
        problem :func:`parse_config` finds.

    Examples
    --------
    >>> from pathlib import Path
    >>> import rotorid
    >>> from rotorid.config import load_config
    >>> cfg = load_config(Path(rotorid.__file__).parent / "data" / "example" / "imbalance.toml")
    >>> [r.name for r in cfg.imbalance.runs], cfg.imbalance.runs[0].mass_kg()
    (['S0', 'C0', 'S90', 'C90'], (0.005, 0.005))
    >>> cfg.channels_for(None)["Prox DE X"]["unit"], cfg.rotor().l1
    ('mil', 0.189)
    """
    from ._validate import flag

    check_files = flag("check_files", check_files)
    data, src, where = read_toml(path)
    return parse_config(data, source=src, base_dir=where, check_files=check_files)
