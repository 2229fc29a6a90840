"""DAQ 1X tables: synchronous amplitude and phase per speed, as a vibration DAQ exports them.

Many labs never export waveforms: the DAQ (a Bently Nevada ADRE / System 1 style "tabular list",
or a report's appendix) gives, per speed, the 1X amplitude and phase of every probe, usually in
mils peak-to-peak with the phase as a *lag* in degrees, in its own column order, possibly already
slow-roll compensated, and at slightly different speeds in every run. This module turns such
tables into the :class:`~rotorid.signals.SyncTrack` that order tracking of waveforms gives, so the
rest of the chain (slow-roll and baseline compensation, common speed grid, identification) is
shared:

:func:`load_1x_table`     CSV / text (any of ``,`` ``;`` tab, decimal comma, a preamble) or Excel
                          -> :class:`TableTrack` (a SyncTrack; SI, 0-pk, rotorid's phase)
:func:`match_speeds`      common speed grid of several runs, 1X vectors interpolated to it
:func:`slow_roll_vector`  1X run-out from a table's slowest row(s)
:func:`save_1x_table`     write a table in a DAQ's layout (round trips, examples)
:func:`example_tables`    the bundled example tables (``data/example/daq_1x``)

Conventions at this edge: a DAQ's amplitude A (pk-pk or 0-pk, any length unit) and phase lag
``lag`` become X = (A_0pk in m) e^{-j lag}; a phase given as lead (= arg X) becomes
X = A e^{+j lead}. Inside rotorid x(t) = Re(X e^{jΩt}) with the keyphasor at rotor angle 0.

Flexible pedestals: a table may also hold the 1X amplitude and phase of the four bearing-housing
accelerometers px1, px2, py1, py2 (all four or none), in an acceleration unit (g, m/s^2) with the
same conventions. Each row's acceleration phasor A (m/s², 0-pk) becomes the housing displacement
P = -A / Ω² (Ω the row's speed in rad/s), the track's ``pedestal`` [xp1, xp2, yp1, yp2].
"""

from __future__ import annotations

import io as _io
import math
import os
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import units
from .errors import RotoridError
from .probe_angles import MAX_ANGLE_DEG, moved_covariance, plane_transform
from .recording import ACCELEROMETERS
from .signals import SyncTrack

__all__ = ["TableTrack", "load_1x_table", "match_speeds", "slow_roll_vector", "save_1x_table", "example_tables",
           "CHANNELS", "ACCELEROMETERS", "ADRE_POINTS", "ADRE_ACCEL_POINTS", "EXAMPLE_DIR", "EXAMPLE_COLUMNS",
           "EXAMPLE_FILES"]

CHANNELS = ("x1", "x2", "y1", "y2")                 # rotorid's q order
# ACCELEROMETERS = ("px1", "px2", "py1", "py2"): housing accelerometers, the order of SyncTrack.pedestal
ADRE_POINTS = {"x1": "DE X", "y1": "DE Y", "x2": "FE X", "y2": "FE Y"}   # DAQ point names, in the DAQ's order
# the housing accelerometers' point names (HSG = bearing housing), in the DAQ's order
ADRE_ACCEL_POINTS = {"px1": "DE HSG X", "py1": "DE HSG Y", "px2": "FE HSG X", "py2": "FE HSG Y"}
EXAMPLE_DIR = os.path.join(os.path.dirname(__file__), "data", "example", "daq_1x")
EXAMPLE_FILES = {"S0": "run_S0.csv", "C0": "run_C0.csv", "S90": "run_S90.csv", "C90": "run_C90.csv",
                 "baseline": "baseline.csv", "slow_roll": "slow_roll.csv"}

_TEXT_EXT = {".csv", ".txt", ".tsv", ".dat"}
_EXCEL_EXT = {".xlsx", ".xlsm"}
_PKPK = {"pk-pk", "pp", "p-p", "pkpk", "peak-to-peak", "peak-peak"}
_ZPK = {"0-pk", "0-p", "0pk", "peak", "pk", "0-peak", "zero-peak"}
_LAG = {"lag"}
_LEAD = {"lead", "arg"}
_DEG = {"deg", "degree", "degrees"}
_RAD = {"rad", "radian", "radians"}
# decimals a DAQ prints amplitudes with: 0.001 mil and the like
_AMP_DECIMALS = {"mil": 3, "mils": 3, "um": 2, "µm": 2, "micron": 2, "microns": 2, "mm": 5, "m": 8, "in": 6}
# ... and accelerations: 0.00001 g, 0.0001 m/s²
_ACC_DECIMALS = {"g": 5, "m/s^2": 4, "m/s2": 4}
_MAX_LIST = 8   # rows / speeds listed in one message


# ---------------------------------------------------------------------------------------------
# the track type


@dataclass
class TableTrack(SyncTrack):
    """A :class:`~rotorid.signals.SyncTrack` read from a DAQ table (orders ``(1,)``).

    ``vectors`` (n, 1, 4) complex, m 0-pk, rotorid's phase (arg X), q order [x1, x2, y1, y2];
    ``speed_rpm`` ascending. A table does not say how many revolutions each row averages or how
    much they scattered, so ``n_revs``, ``scatter`` and ``t_mid`` are NaN. ``name`` (default: the
    file name without extension), ``source`` (the file) and ``meta`` (the reader's arguments, the
    preamble lines, and the user's ``meta``) travel along; :meth:`minus` keeps them and records
    the compensation in ``meta["compensated"]``.

    A table with the housing accelerometers' columns (px1, px2, py1, py2) also carries
    ``pedestal`` (n, 1, 4) complex, the housings' displacement [xp1, xp2, yp1, yp2] (m, 0-pk,
    -A / Ω² of each row's acceleration A), and ``pedestal_cov`` / ``pedestal_cross`` (n, 8, 8)
    (NaN unless the DAQ's accuracy is given); ``has_pedestal`` is then True.
    """

    name: str | None = None
    source: str | None = None
    meta: dict = field(default_factory=dict)

    def minus(self, other, other_cov=None) -> "TableTrack":
        base = SyncTrack.minus(self, other, other_cov)
        what = getattr(other, "name", None) or ("a track" if isinstance(other, SyncTrack) else "a fixed run-out vector")
        meta = dict(self.meta)
        meta["compensated"] = list(meta.get("compensated", [])) + [f"minus {what}"]
        return TableTrack(base.speed_rpm, base.vectors, base.orders, base.n_revs, base.scatter, base.t_mid,
                          base.keyphasors, base.cov, base.dof, pedestal=base.pedestal, pedestal_cov=base.pedestal_cov,
                          pedestal_cross=base.pedestal_cross, name=self.name, source=self.source, meta=meta)


# ---------------------------------------------------------------------------------------------
# argument normalisation


def _norm(s) -> str:
    return str(s).strip().lower().replace(" ", "").replace("_", "-")


def _kind(value, name, kinds, hint) -> str:
    """The canonical spelling of ``value`` among ``kinds`` ({canonical: aliases}); else an error."""
    v = _norm(value)
    for canon, aliases in kinds.items():
        if v in aliases:
            return canon
    raise RotoridError(f"{name} must be {hint}, got {value!r}")


def _amplitude_kind(amplitude) -> str:
    return _kind(amplitude, "amplitude", {"pk-pk": _PKPK, "0-pk": _ZPK},
                 "'pk-pk' (also 'pp', 'peak-to-peak') or '0-pk' (also '0-p', 'peak')")


def _phase_kind(phase) -> str:
    return _kind(phase, "phase", {"lag": _LAG, "lead": _LEAD},
                 "'lag' (DAQ convention, X = A e^(-j lag)) or 'lead'/'arg' (X = A e^(+j phase))")


def _angle_kind(phase_unit) -> str:
    return _kind(phase_unit, "phase_unit", {"deg": _DEG, "rad": _RAD}, "'deg' or 'rad'")


def _quantity(unit):
    try:
        return units.quantity_of(unit)
    except RotoridError:
        return None


def _length_factor(unit) -> float:
    if _quantity(unit) == "acceleration":
        raise RotoridError(f"unit={unit!r} is an acceleration unit, but unit= is the length unit of the probe "
                           "channels x1, x2, y1, y2 (mil, um, µm, mm, m, in); give the housing accelerometers' "
                           "(px1, px2, py1, py2) unit as accel_unit=")
    try:
        return units.factor(unit, "length")
    except RotoridError as exc:
        raise RotoridError(f"unit: {exc} (a length unit: mil, um, µm, mm, m, in)") from None


def _accel_factor(accel_unit) -> float:
    if _quantity(accel_unit) == "length":
        raise RotoridError(f"accel_unit={accel_unit!r} is a length unit, but accel_unit= is the acceleration unit "
                           "of the housing accelerometer channels px1, px2, py1, py2 (g, m/s^2); the probes' "
                           "(x1, x2, y1, y2) length unit is unit=")
    try:
        return units.factor(accel_unit, "acceleration")
    except RotoridError as exc:
        raise RotoridError(f"accel_unit: {exc} (an acceleration unit: g, m/s^2, m/s2)") from None


def _unit_label(unit) -> str:
    """A unit as a header writes it: mil, um, g, m/s^2."""
    u = _norm(unit)
    return {"µm": "um", "μm": "um", "micron": "um", "microns": "um", "mils": "mil"}.get(u, u)


def _check_columns_arg(columns) -> dict:
    """``columns`` checked: {channel: {"amplitude": str, "phase": str}} for x1, x2, y1, y2 and, when
    the table has the housing accelerometers, px1, px2, py1, py2 (in that order)."""
    if not isinstance(columns, dict):
        raise RotoridError("columns must be a mapping {'x1': {'amplitude': <column>, 'phase': <column>}, ...} "
                           f"for x1, x2, y1, y2 (and px1, px2, py1, py2 with housing accelerometers); got "
                           f"{type(columns).__name__}")
    unknown = sorted(set(columns) - set(CHANNELS) - set(ACCELEROMETERS), key=str)
    missing = [c for c in CHANNELS if c not in columns]
    if unknown or missing:
        parts = []
        if missing:
            parts.append(f"missing {missing}")
        if unknown:
            parts.append(f"unknown {unknown}")
        raise RotoridError(f"columns must map all four channels x1, x2, y1, y2 (probe plane 1 = drive end) to "
                           f"their amplitude and phase columns: {', '.join(parts)}"
                           + (" (housing accelerometers: px1, px2, py1, py2)" if unknown else ""))
    acc_given = [c for c in ACCELEROMETERS if c in columns]
    if acc_given and len(acc_given) < len(ACCELEROMETERS):
        acc_missing = [c for c in ACCELEROMETERS if c not in columns]
        raise RotoridError(f"columns maps the housing accelerometer channel(s) {acc_given} but not {acc_missing}: a "
                           "table has all four accelerometers px1, px2, py1, py2 (bearing housings 1 and 2, x and y) "
                           "or none; map the missing channel(s) to their amplitude and phase columns")
    chans = CHANNELS + (ACCELEROMETERS if acc_given else ())
    out = {}
    for ch in chans:
        spec = columns[ch]
        if not isinstance(spec, dict) or not {"amplitude", "phase"} <= set(spec) <= {"amplitude", "phase", "angle_deg"}:
            raise RotoridError(f"columns[{ch!r}] must be {{'amplitude': <column name>, 'phase': <column name>}} "
                               f"(and 'angle_deg' for a probe mounted at an angle), got {spec!r}")
        out[ch] = {k: str(spec[k]) for k in ("amplitude", "phase")}
        angle = spec.get("angle_deg")
        if angle is not None:
            ok = not isinstance(angle, bool) and isinstance(angle, (int, float, np.integer, np.floating))
            try:
                ok = ok and abs(float(angle)) <= MAX_ANGLE_DEG
            except OverflowError:
                ok = False
            if not ok:
                raise RotoridError(f"columns[{ch!r}]['angle_deg'] must be a number of degrees within ±{MAX_ANGLE_DEG:g} "
                                   f"(the direction the probe measures along, from +x toward +y), got {angle!r}")
            out[ch]["angle_deg"] = float(angle)
    names = [_key(out[c][k]) for c in chans for k in ("amplitude", "phase")]
    dup = sorted({out[c][k] for c in chans for k in ("amplitude", "phase") if names.count(_key(out[c][k])) > 1})
    if dup:
        raise RotoridError(f"columns uses the column(s) {dup} for more than one channel or quantity")
    return out


# ---------------------------------------------------------------------------------------------
# what a column header states


_B = r"(?<![a-z0-9])"      # token boundaries (a letter or digit may not touch the token)
_E = r"(?![a-z0-9])"
_PKPK_RE = re.compile(_B + r"(?:peak\s*-?\s*to\s*-?\s*peak|peak\s*-\s*peak|pk\s*-?\s*pk|p\s*-\s*p|p/p|pp)" + _E)
_ZPK_RE = re.compile(_B + r"(?:zero\s*-?\s*(?:to\s*-?\s*)?peak|0\s*-?\s*(?:to\s*-?\s*)?(?:pk|peak|p)|pk|peak|zpk)" + _E)
_RMS_RE = re.compile(_B + r"rms" + _E)
_BRACKETS = re.compile(r"[(\[{]([^)\]}]*)[)\]}]")
_UNIT_TOKENS = {"mil": "mil", "mils": "mil", "um": "um", "µm": "um", "μm": "um", "micron": "um", "microns": "um",
                "mm": "mm", "m": "m", "in": "in", "inch": "in", "inches": "in"}
_AMBIGUOUS_OUTSIDE = {"m", "in", "inch"}   # English words / initials: only counted inside brackets
# accelerations: <length>/s^2 (also s2, s², s**2, /s/s, /sec^2) and g (inside brackets only, as "m")
_ACC_RE = re.compile(_B + r"(?P<u>[a-zµμ]+)\s*/\s*s(?:ec)?\s*(?:\^\s*2|\*\*\s*2|2|²|/\s*s(?:ec)?)" + _E)
_VEL_RE = re.compile(_B + r"(?:(?:m|mm|cm|um|µm|μm|in|mil|mils|ft)\s*/\s*s(?:ec)?|ips|in/sec)" + _E)


def _states(header: str) -> dict:
    """Units and conventions a column header states: {'unit': {...}, 'accel': {...},
    'velocity': {...}, 'amp': {...}, 'dir': {...}, 'angle': {...}, 'speed': {...}}. Empty sets
    where it says nothing. ``unit``: length units; ``accel``: acceleration units ("g",
    "m/s^2", or e.g. "mm/s^2", which rotorid does not convert); ``velocity``: velocity units."""
    low = str(header).lower()
    accel = {("m/s^2" if m.group("u") == "m" else f"{m.group('u')}/s^2") for m in _ACC_RE.finditer(low)}
    low = _ACC_RE.sub(" ", low)                 # "m/s^2" is no length "m"
    velocity = {m.group(0).replace(" ", "") for m in _VEL_RE.finditer(low)}
    inside = " ".join(_BRACKETS.findall(low))
    toks_all = re.findall(r"[a-zµμ]+", low)
    toks_in = set(re.findall(r"[a-zµμ]+", inside))
    unit = {_UNIT_TOKENS[t] for t in toks_all
            if t in _UNIT_TOKENS and (t not in _AMBIGUOUS_OUTSIDE or t in toks_in)}
    if "g" in toks_in:
        accel.add("g")
    amp = set()
    rest = low
    if _PKPK_RE.search(rest):
        amp.add("pk-pk")
        rest = _PKPK_RE.sub(" ", rest)
    if _ZPK_RE.search(rest):
        amp.add("0-pk")
    if _RMS_RE.search(rest):
        amp.add("rms")
    toks = set(toks_all)
    direction = ({"lag"} if toks & {"lag", "lagging"} else set()) | ({"lead"} if toks & {"lead", "leading"} else set())
    angle = ({"deg"} if (toks & {"deg", "degs", "degree", "degrees"} or "°" in low) else set()) | \
            ({"rad"} if toks & {"rad", "rads", "radian", "radians"} else set())
    speed = set()
    if toks & {"hz", "cps"}:
        speed.add("Hz")
    if "rad/s" in low.replace(" ", "") or "rad/sec" in low.replace(" ", ""):
        speed.add("rad/s")
    return {"unit": unit, "accel": accel, "velocity": velocity, "amp": amp, "dir": direction, "angle": angle,
            "speed": speed}


def _check_headers(where, cols, speed_col, unit, amp_kind, phase_kind, angle_kind, accel_unit="g",
                   accel_amp_kind=None):
    """A header that states a unit or convention contradicting the arguments raises; so does an
    acceleration unit on a probe column or a length (or velocity) unit on an accelerometer column."""
    f_arg = _length_factor(unit)
    for ch in cols:
        a, p = cols[ch]["amplitude"], cols[ch]["phase"]
        st = _states(a)
        is_acc = ch in ACCELEROMETERS
        if not is_acc and st["accel"]:
            stated = sorted(st["accel"])[0]
            raise RotoridError(f"{where}: column {a!r} ({ch} amplitude) states the acceleration unit {stated!r}, but "
                               f"{ch} is a proximity probe channel (a displacement: mil, um, mm, m, in); map the "
                               "housing accelerometers' columns to px1, px2, py1, py2 (or fix the header if it is "
                               "wrong)")
        if is_acc:
            f_acc = _accel_factor(accel_unit)
            if st["velocity"]:
                stated = sorted(st["velocity"])[0]
                raise RotoridError(f"{where}: column {a!r} ({ch} amplitude) states the velocity unit {stated!r}; the "
                                   f"accelerometer channel {ch} takes accelerations (g, m/s^2): convert the column")
            if st["unit"]:
                stated = sorted(st["unit"])[0]
                raise RotoridError(f"{where}: column {a!r} ({ch} amplitude) states the length unit {stated!r}, but "
                                   f"{ch} is a housing accelerometer channel (an acceleration: g, m/s^2); map "
                                   "displacement columns to x1, x2, y1, y2 (or fix the header if it is wrong)")
            unknown = sorted(u for u in st["accel"] if _quantity(u) != "acceleration")
            if unknown:
                raise RotoridError(f"{where}: column {a!r} ({ch} amplitude) states the unit {unknown[0]!r}, which "
                                   "rotorid does not convert; convert the column to g or m/s^2")
            wrong_units = sorted(u for u in st["accel"]
                                 if not math.isclose(units.factor(u, "acceleration"), f_acc, rel_tol=1e-9))
            if wrong_units:
                raise RotoridError(f"{where}: column {a!r} ({ch} amplitude) states the unit {wrong_units[0]!r} but "
                                   f"accel_unit={accel_unit!r} was passed; pass accel_unit={wrong_units[0]!r} (or fix "
                                   "the header if it is wrong)")
            kind, arg = accel_amp_kind or amp_kind, "accel_amplitude"
        else:
            wrong_units = sorted(u for u in st["unit"]
                                 if not math.isclose(units.factor(u, "length"), f_arg, rel_tol=1e-9))
            if wrong_units:
                raise RotoridError(f"{where}: column {a!r} ({ch} amplitude) states the unit {wrong_units[0]!r} but "
                                   f"unit={unit!r} was passed; pass unit={wrong_units[0]!r} (or fix the header if it "
                                   "is wrong)")
            kind, arg = amp_kind, "amplitude"
        if "rms" in st["amp"]:
            raise RotoridError(f"{where}: column {a!r} ({ch} amplitude) states rms; give pk-pk or 0-pk amplitudes "
                               "(for a pure 1X sinusoid 0-pk = sqrt(2) x rms)")
        if len(st["amp"]) > 1:
            raise RotoridError(f"{where}: column {a!r} ({ch} amplitude) states both pk-pk and 0-pk; fix the header")
        if st["amp"] and kind not in st["amp"]:
            stated = next(iter(st["amp"]))
            raise RotoridError(f"{where}: column {a!r} ({ch} amplitude) states {stated} but {arg}={kind!r} "
                               f"was passed: that is a factor 2 in every vector; pass {arg}={stated!r} (or fix "
                               "the header if it is wrong)")
        sp = _states(p)
        if len(sp["dir"]) > 1 or len(sp["angle"]) > 1:
            raise RotoridError(f"{where}: column {p!r} ({ch} phase) states contradictory conventions; fix the header")
        if sp["dir"] and phase_kind not in sp["dir"]:
            stated = next(iter(sp["dir"]))
            raise RotoridError(f"{where}: column {p!r} ({ch} phase) states a phase {stated} but phase="
                               f"{phase_kind!r} was passed: every phase would change "
                               f"sign; pass phase={stated!r} (or fix the header if it is wrong)")
        if sp["angle"] and angle_kind not in sp["angle"]:
            stated = next(iter(sp["angle"]))
            raise RotoridError(f"{where}: column {p!r} ({ch} phase) states {stated} but phase_unit={angle_kind!r} "
                               f"was passed; pass phase_unit={stated!r} (or fix the header if it is wrong)")
    ss = _states(speed_col)["speed"]
    if ss:
        raise RotoridError(f"{where}: speed column {speed_col!r} states {sorted(ss)[0]}; the table's speed must be "
                           "in rpm (convert the column)")


# ---------------------------------------------------------------------------------------------
# reading the file into header + rows of cells


def _decode(path: Path) -> str:
    from .io._common import decode_text

    return decode_text(path.read_bytes())


def _split(line: str, sep: str) -> list:
    import csv

    try:
        row = next(csv.reader([line], delimiter=sep, quotechar='"', skipinitialspace=True), [])
    except csv.Error:
        row = line.split(sep)
    return [c.strip() for c in row]


def _key(name) -> str:
    return " ".join(str(name).split()).casefold()


def _wanted(cols, speed_column) -> list:
    names = [cols[c][k] for c in cols for k in ("amplitude", "phase")]
    if speed_column != "auto":
        names.append(str(speed_column))
    return names


def _score(cells, keys) -> tuple:
    have = {_key(c) for c in cells}
    return len(keys & have), sum(1 for c in cells if str(c).strip())


def _find_header(rows_of_cells, wanted, skip_rows, where):
    """Index of the header row among rows of cells: the first that holds all ``wanted`` names
    (``skip_rows="auto"``) or row ``skip_rows``. Returns (index, cells) or raises, naming the
    missing columns and what the most likely header row has."""
    keys = {_key(w) for w in wanted}
    if not rows_of_cells or not any(any(str(c).strip() for c in r) for r in rows_of_cells):
        raise RotoridError(f"{where}: the file is empty")
    if skip_rows == "auto":
        best = None
        for i, cells in enumerate(rows_of_cells):
            sc = _score(cells, keys)
            if sc[0] == len(keys):
                return i, cells
            if best is None or sc > best[0]:
                best = (sc, i)
        i = best[1]
        what = f"the most likely header (row {i + 1})"
    else:
        if not isinstance(skip_rows, (int, np.integer)) or isinstance(skip_rows, bool) or skip_rows < 0:
            raise RotoridError(f"skip_rows must be 'auto' or the number of rows before the header (>= 0), "
                               f"got {skip_rows!r}")
        i = int(skip_rows)
        if i >= len(rows_of_cells):
            raise RotoridError(f"{where}: skip_rows={skip_rows} but the file has only {len(rows_of_cells)} rows")
        if _score(rows_of_cells[i], keys)[0] == len(keys):
            return i, rows_of_cells[i]
        what = f"the header (row {i + 1}, after skip_rows={skip_rows})"
    cells = rows_of_cells[i]
    have = {_key(c) for c in cells}
    missing = [w for w in wanted if _key(w) not in have]
    raise _HeaderError(f"{where}: no column(s) {missing}; {what} has the columns {[c for c in cells if str(c).strip()]}",
                       _score(cells, keys))


class _HeaderError(RotoridError):
    def __init__(self, msg, score):
        super().__init__(msg)
        self.score = score


def _read_text(path: Path, wanted, skip_rows):
    """Header cells, data columns (list of lists of str) and the file row number of the first data
    row, for a delimited text file."""
    import pandas as pd

    where = str(path)
    text = _decode(path)
    lines = text.splitlines()
    # the separator is the one whose split of the header row holds the wanted names (tab, ';', ',')
    found = None
    errors = []
    for sep in ("\t", ";", ","):
        try:
            i, cells = _find_header([_split(ln, sep) for ln in lines], wanted, skip_rows, where)
        except _HeaderError as exc:
            errors.append(exc)
            continue
        found = (sep, i, cells)
        break
    if found is None:   # report the separator under which the header came closest
        raise max(errors, key=lambda e: e.score)
    sep, i, cells = found
    body = lines[i + 1:]
    ncol = len(cells)
    if not any(ln.strip() for ln in body):
        return cells, [[] for _ in range(ncol)], i + 2
    width = max([ncol] + [len(_split(ln, sep)) for ln in body])
    try:
        # names= and index_col=False: pandas must neither take a first column as the index when the
        # rows have one field more than the header (a trailing separator) nor drop extra fields
        df = pd.read_csv(_io.StringIO("\n".join(body) + "\n"), sep=sep, header=None, names=list(range(width)), dtype=str,
                         keep_default_na=False, na_filter=False, skip_blank_lines=False, skipinitialspace=True,
                         engine="python", quotechar='"', index_col=False)
    except Exception as exc:
        raise RotoridError(f"cannot read {where} as a 1X table (separator {sep!r}, header on row {i + 1}): "
                           f"{type(exc).__name__}: {str(exc).strip()}") from None
    if len(df) != len(body):
        raise RotoridError(f"cannot read {where} as a 1X table: {len(body)} lines after the header (row {i + 1}) "
                           f"give {len(df)} rows (a quoted cell with a line break?)")
    vals = df.to_numpy(dtype=object)
    present = np.array([[not (isinstance(v, float) and math.isnan(v)) for v in row] for row in vals],
                       dtype=bool).reshape(len(body), width)
    filled = np.array([[isinstance(v, str) and v.strip() != "" for v in row] for row in vals],
                      dtype=bool).reshape(len(body), width)
    nfield = np.where(present.any(axis=1), width - np.argmax(present[:, ::-1], axis=1), 0)
    blank_line = ~filled.any(axis=1)
    # every row must have the header's fields: a missing or an extra field shifts every column after
    # it (e.g. a thousands separator "3,000" in a comma-separated file); trailing empty fields are fine
    extra = filled[:, ncol:].any(axis=1) & ~blank_line
    short = (nfield < ncol) & ~blank_line
    for bad, what in ((extra, "more"), (short, "fewer")):
        if bad.any():
            r = np.nonzero(bad)[0]
            raise RotoridError(f"{where}: {_rows_text(r + i + 2)} ha{'ve' if r.size > 1 else 's'} {what} fields than "
                               f"the header (row {i + 1}, {ncol} columns, separator {sep!r}): e.g. row {r[0] + i + 2} "
                               f"has {nfield[r[0]]}; every column after a missing or extra field would shift")
    data = [["" if not present[k, j] else str(vals[k, j]) for k in range(len(body))] for j in range(ncol)]
    return cells, data, i + 2


def _read_excel(path: Path, wanted, skip_rows, sheet):
    from .io._common import read_excel_sheet

    raw, sh, names = read_excel_sheet(path, sheet)
    where = str(path) if sheet is None else f"{path} (sheet {sheet!r})"
    if sheet is None and len(names) > 1:
        where = f"{path} (sheet {sh!r})"
    grid = [["" if _blank_obj(v) else v for v in row] for row in raw.itertuples(index=False, name=None)]
    text_rows = [[_cell_text(v) for v in row] for row in grid]
    i, cells = _find_header(text_rows, wanted, skip_rows, where)
    body = grid[i + 1:]
    ncol = len(cells)
    data = [[row[j] if j < len(row) else "" for row in body] for j in range(ncol)]
    return cells, data, i + 2, where


def _blank_obj(v) -> bool:
    if v is None:
        return True
    if isinstance(v, float) and math.isnan(v):
        return True
    try:
        import pandas as pd

        return v is pd.NaT or (not isinstance(v, str) and bool(pd.isna(v)))
    except (TypeError, ValueError):
        return False


def _cell_text(v) -> str:
    if isinstance(v, str):
        return v.strip()
    if isinstance(v, float) and v.is_integer():
        return str(int(v))
    return str(v)


# ---------------------------------------------------------------------------------------------
# cells -> numbers


_NUM_DOT = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")
_NUM_COMMA = re.compile(r"^[+-]?(\d+,\d*|,\d+)([eE][+-]?\d+)?$")


def _rows_text(rows, unit="row") -> str:
    rows = list(rows)
    shown = ", ".join(str(r) for r in rows[:_MAX_LIST])
    more = f" and {len(rows) - _MAX_LIST} more" if len(rows) > _MAX_LIST else ""
    return f"{unit}{'s' if len(rows) > 1 else ''} {shown}{more}"


def _to_numbers(cols: dict, first_row: int, where: str) -> tuple:
    """{column name: list of cells} -> ({name: float array, NaN where blank}, blank masks).
    Non-numeric cells raise, naming column and rows."""
    # decimal separator, decided over all used cells of text
    n_comma = n_dot = 0
    ex_comma = ex_dot = None
    for name, cells in cols.items():
        for k, c in enumerate(cells):
            if isinstance(c, str):
                s = c.strip()
                if _NUM_COMMA.match(s):
                    n_comma += 1
                    ex_comma = ex_comma or (name, first_row + k, s)
                elif "." in s and _NUM_DOT.match(s):
                    n_dot += 1
                    ex_dot = ex_dot or (name, first_row + k, s)
    if n_comma and n_dot:
        raise RotoridError(f"{where}: mixed decimal separators: {ex_comma[2]!r} (column {ex_comma[0]!r}, row "
                           f"{ex_comma[1]}) has a decimal comma, {ex_dot[2]!r} (column {ex_dot[0]!r}, row {ex_dot[1]}) "
                           "a decimal point (thousands separators are not supported)")
    comma = n_comma > 0
    out, blank = {}, {}
    for name, cells in cols.items():
        vals = np.full(len(cells), np.nan)
        bl = np.zeros(len(cells), bool)
        bad = []
        for k, c in enumerate(cells):
            if isinstance(c, bool):
                bad.append((first_row + k, c))
                continue
            if isinstance(c, (int, float, np.integer, np.floating)):
                v = float(c)
                if math.isnan(v):
                    bl[k] = True
                elif not math.isfinite(v):
                    bad.append((first_row + k, c))
                else:
                    vals[k] = v
                continue
            s = str(c).strip()
            if s == "" or s.lower() == "nan":
                bl[k] = True
                continue
            if comma and _NUM_COMMA.match(s):
                s = s.replace(",", ".")
            if not _NUM_DOT.match(s):
                bad.append((first_row + k, c))
                continue
            vals[k] = float(s)
        if bad:
            shown = ", ".join(f"row {r}: {v!r}" for r, v in bad[:_MAX_LIST])
            raise RotoridError(f"{where}: column {name!r} has non-numeric cells ({shown}"
                               f"{' ...' if len(bad) > _MAX_LIST else ''}); fix or delete those rows")
        out[name] = vals
        blank[name] = bl
    return out, blank


# ---------------------------------------------------------------------------------------------
# load


def load_1x_table(path, *, columns, speed_column="auto", amplitude="pk-pk", unit="mil", phase="lag",
                  phase_unit="deg", sheet=None, skip_rows="auto", name=None, meta=None, amplitude_std=None,
                  phase_std_deg=None, accel_unit="g", accel_amplitude=None, accel_amplitude_std=None) -> TableTrack:
    """Read a DAQ's 1X table (amplitude and phase per speed) into a SyncTrack.

    Parameters
    ----------
    path : str or path-like
        ``.csv``, ``.txt``, ``.tsv``, ``.dat``: delimited text, separator ``,``, ``;`` or tab
        (the one whose split of the header row holds the column names), decimal point or
        decimal comma, any number of preamble lines before the header. ``.xlsx``/``.xlsm``: an
        Excel sheet (needs openpyxl).
    columns : dict
        ``{"x1": {"amplitude": <column>, "phase": <column>}, "x2": ..., "y1": ..., "y2": ...}``:
        the table's columns of each canonical channel (x horizontal, y vertical, 1 = drive-end
        probe plane). All four are required. With flexible pedestals also ``"px1"``, ``"px2"``,
        ``"py1"``, ``"py2"`` (same form): the 1X acceleration of the bearing-housing
        accelerometers (housing 1 = drive end, x and y), all four or none. Column names are matched
        ignoring case and repeated blanks; other columns of the file are ignored. A probe mounted
        at an angle adds ``"angle_deg"``: the direction it measures along, in degrees from +x
        toward +y (x probes 0 and y probes 90 by default; API 670's 45° either side of vertical
        are 45 for the one mapped to x and 135 for the one mapped to y); each plane's two phasors
        (and their covariance) are resolved into its x and y motion (``rotorid.probe_angles``).
    speed_column : str
        Column of the speed in rpm. ``"auto"``: the one column (not used in ``columns``) whose
        name contains "speed" or "rpm", case-insensitive.
    amplitude : {"pk-pk", "0-pk"}
        What the amplitude columns hold (also "pp", "peak-to-peak"; "0-p", "peak").
    unit : str
        Length unit of the probes' amplitudes (any of ``rotorid.units``: mil, um, µm, mm, m, in).
    phase : {"lag", "lead"}
        "lag": the DAQ convention, X = A e^{-j lag}; "lead" or "arg": X = A e^{+j phase}. The
        accelerometers' phases too.
    phase_unit : {"deg", "rad"}
    sheet : str or int, optional
        Excel sheet (name or 0-based index); default the first.
    skip_rows : "auto" or int
        Rows before the header. "auto": the header is the first row holding all the named columns.
    name : str, optional
        Name of the run (default: file name without extension).
    meta : dict, optional
        Stored in the result's ``meta`` (with the reader's arguments and the preamble lines).
    amplitude_std, phase_std_deg : float, optional
        The DAQ's stated accuracy: standard deviation of an amplitude (in ``unit``, as
        ``amplitude``) and of a phase (deg), independent errors; gives ``cov`` (``dof`` inf).
        Default: unknown (NaN).
    accel_unit : str
        Acceleration unit of the accelerometers' amplitudes: "g" (9.80665 m/s²), "m/s^2" or
        "m/s2". Used only with accelerometer columns.
    accel_amplitude : {"pk-pk", "0-pk"}, optional
        What the accelerometers' amplitude columns hold; default: as ``amplitude``.
    accel_amplitude_std : float, optional
        Standard deviation of an accelerometer amplitude (in ``accel_unit``, as
        ``accel_amplitude``); needed for ``pedestal_cov`` when ``amplitude_std`` is given.

    Returns
    -------
    TableTrack
        A :class:`~rotorid.signals.SyncTrack` with ``orders=(1,)``, ``vectors`` (n, 1, 4) complex
        (m, 0-pk, x(t) = Re(X e^{jΩt})), ``speed_rpm`` ascending, ``n_revs``, ``scatter`` and
        ``t_mid`` NaN. With accelerometer columns also ``pedestal`` (n, 1, 4) complex, the
        housings' displacement [xp1, xp2, yp1, yp2] = -A / Ω² of each row's acceleration
        phasor A (m/s², 0-pk) at the row's speed Ω (rad/s), ``pedestal_cov`` (n, 8, 8) its
        covariance when the accuracy is given (``pedestal_cross`` then 0: the channels' errors
        are independent), else NaN.

    Raises
    ------
    RotoridError
        One clear message naming the file, the column and the rows (numbered as in the file:
        CSV line, spreadsheet row) for: a named column missing; a header stating a unit, pk-pk /
        0-pk, lag / lead or deg / rad that contradicts the arguments (e.g. ``Amp (mil pp)`` read with
        ``amplitude="0-pk"``: a factor 2); an acceleration unit on a probe column or a length or
        velocity unit on an accelerometer column (naming column and channel); some but not all
        four accelerometer channels in ``columns``; non-numeric cells; blank speeds; rows with some
        channels blank (nothing is dropped silently; rows blank in every used column are blank
        lines; "NaN" cells are blank); duplicated speeds; speeds <= 0; negative amplitudes; phases
        beyond ±360 deg or beyond ±2π rad ("looks like degrees"); degree phases that all lie within
        ±2π in a table of more than 5 rows ("looks like radians labelled degrees"); fewer than 2
        rows.

    Examples
    --------
    >>> import rotorid.tables as tb
    >>> import os
    >>> path = os.path.join(tb.EXAMPLE_DIR, "run_S0.csv")
    >>> t = tb.load_1x_table(path, columns=tb.EXAMPLE_COLUMNS)    # mils pk-pk, degrees lag
    >>> t.vectors.shape, t.orders
    ((13, 1, 4), (1,))
    >>> round(float(t.speed_rpm[0]))
    3000

    A table with the housing accelerometers (here in g 0-pk beside the probes' mil pk-pk):

    >>> import tempfile, numpy as np
    >>> p = os.path.join(tempfile.mkdtemp(), "ped.csv")
    >>> amp = ",".join(f"{c} amp,{c} ph" for c in ("x1", "x2", "y1", "y2", "px1", "px2", "py1", "py2"))
    >>> row = ",".join(["1.0,30.0"] * 4 + ["0.01,100.0"] * 4)
    >>> _ = open(p, "w").write(f"rpm,{amp}\\n3000,{row}\\n3600,{row}\\n")
    >>> cols = {c: {"amplitude": f"{c} amp", "phase": f"{c} ph"} for c in tb.CHANNELS + tb.ACCELEROMETERS}
    >>> t = tb.load_1x_table(p, columns=cols, accel_unit="g", accel_amplitude="0-pk")
    >>> t.has_pedestal, t.pedestal.shape
    (True, (2, 1, 4))
    >>> round(float(np.abs(t.pedestal[0, 0, 0])) * 1e6, 3)      # 0.01 g at 50 Hz: 0.994 µm
    0.994
    """
    from ._validate import mapping, number, path as _path, text

    path = _path("path", path)
    cols = _check_columns_arg(columns)
    chans = tuple(cols)                                   # CHANNELS (+ ACCELEROMETERS)
    has_ped = len(chans) > len(CHANNELS)
    speed_column = text("speed_column", speed_column)
    if not (isinstance(skip_rows, str) and skip_rows == "auto") and (
            isinstance(skip_rows, (bool, np.bool_)) or not isinstance(skip_rows, (int, np.integer)) or skip_rows < 0):
        raise RotoridError(f"skip_rows must be 'auto' or the number of rows before the header (>= 0), got "
                           f"{skip_rows!r}")
    if sheet is not None and (isinstance(sheet, (bool, np.bool_)) or not isinstance(sheet, (str, int, np.integer))):
        raise RotoridError(f"sheet must be a sheet name or a 0-based index, got {sheet!r}")
    name = text("name", name, allow_none=True)
    meta = mapping("meta", meta)
    amplitude_std = number("amplitude_std", amplitude_std, nonneg=True, allow_none=True)
    phase_std_deg = number("phase_std_deg", phase_std_deg, nonneg=True, allow_none=True)
    accel_amplitude_std = number("accel_amplitude_std", accel_amplitude_std, nonneg=True, allow_none=True)
    amp_kind = _amplitude_kind(amplitude)
    phase_kind = _phase_kind(phase)
    angle_kind = _angle_kind(phase_unit)
    f_len = _length_factor(unit)
    f_acc = _accel_factor(accel_unit)
    acc_amp_kind = amp_kind if accel_amplitude is None else \
        _kind(accel_amplitude, "accel_amplitude", {"pk-pk": _PKPK, "0-pk": _ZPK},
              "'pk-pk' (also 'pp', 'peak-to-peak') or '0-pk' (also '0-p', 'peak')")
    if accel_amplitude_std is not None:
        if not has_ped:
            raise RotoridError("accel_amplitude_std was given but columns maps no housing accelerometer channels "
                               "(px1, px2, py1, py2)")
        if amplitude_std is None and phase_std_deg is None:
            raise RotoridError("accel_amplitude_std was given without amplitude_std / phase_std_deg: give the "
                               "probes' accuracy too (the phase accuracy is shared)")
    if has_ped and amplitude_std is not None and accel_amplitude_std is None:
        raise RotoridError("amplitude_std was given for the probes but accel_amplitude_std (in accel_unit) is "
                           "missing for the housing accelerometers px1, px2, py1, py2: give both (0 if exact)")
    if not path.is_file():
        raise RotoridError(f"no such file: {path}")
    ext = path.suffix.lower()
    wanted = _wanted(cols, speed_column)
    where = str(path)
    if ext in _TEXT_EXT:
        if sheet is not None:
            raise RotoridError(f"sheet={sheet!r} was given but {path} is a text file, not a workbook")
        header, data, first_row = _read_text(path, wanted, skip_rows)
    elif ext in _EXCEL_EXT:
        header, data, first_row, where = _read_excel(path, wanted, skip_rows, sheet)
    elif ext == ".xls":
        raise RotoridError(f"{path}: the old .xls format is not supported; save the sheet as .xlsx or CSV")
    else:
        raise RotoridError(f"{path}: unknown table format {ext!r}; give a .csv/.txt/.tsv/.dat text file or an "
                           ".xlsx workbook")
    keys = [_key(c) for c in header]
    pos = {k: j for j, k in enumerate(keys) if k}
    # speed column
    used = {_key(cols[c][k]) for c in chans for k in ("amplitude", "phase")}
    if speed_column == "auto":
        cand = [header[j] for j, k in enumerate(keys) if k and k not in used and ("speed" in k or "rpm" in k)]
        if len(cand) != 1:
            listing = [c for c in header if str(c).strip()]
            if not cand:
                raise RotoridError(f"{where}: no speed column: none of the columns {listing} has 'speed' or 'rpm' in "
                                   "its name; pass speed_column=<the column of the speed in rpm>")
            raise RotoridError(f"{where}: several columns could be the speed: {cand}; pass speed_column= one of them")
        speed_col = str(cand[0]).strip()
    else:
        speed_col = str(speed_column)
    names = [speed_col] + [cols[c][k] for c in chans for k in ("amplitude", "phase")]
    if _key(speed_col) in used:
        raise RotoridError(f"speed_column={speed_col!r} is also one of the channel columns")
    for nm in names:
        j = [jj for jj, k in enumerate(keys) if k == _key(nm)]
        if not j:
            raise RotoridError(f"{where}: no column {nm!r}; the header has {[c for c in header if str(c).strip()]}")
        if len(j) > 1:
            raise RotoridError(f"{where}: the header names the column {nm!r} {len(j)} times (columns "
                               f"{', '.join(str(x + 1) for x in j)}); which one holds the data is ambiguous")
    _check_headers(where, cols, speed_col, unit, amp_kind, phase_kind, angle_kind, accel_unit, acc_amp_kind)
    raw = {n: data[pos[_key(n)]] for n in names}
    nums, blank = _to_numbers(raw, first_row, where)
    nrow = len(raw[speed_col])
    rownum = first_row + np.arange(nrow)
    ch_names = names[1:]
    ch_blank = np.stack([blank[n] for n in ch_names], axis=1)        # (rows, 8 or 16)
    sp_blank = blank[speed_col]
    empty = sp_blank & ch_blank.all(axis=1)
    # rows blank in every used column are blank lines (e.g. at the end of an export)
    if (sp_blank & ~empty).any():
        r = rownum[sp_blank & ~empty]
        raise RotoridError(f"{where}: speed column {speed_col!r} is blank in {_rows_text(r)}, which hold(s) "
                           "channel values; fill in the speed or delete the rows")
    part = ~sp_blank & ch_blank.any(axis=1)
    if part.any():
        r = rownum[part]
        which = sorted({ch_names[j] for j in np.nonzero(ch_blank[part].any(axis=0))[0]}, key=ch_names.index)
        raise RotoridError(f"{where}: {_rows_text(r)} ha{'ve' if r.size > 1 else 's'} blank cells in column(s) {which}; nothing is dropped "
                           "silently: fill them in or delete the rows")
    keep = ~empty
    rownum = rownum[keep]
    speed = nums[speed_col][keep]
    n = speed.size
    if n < 2:
        raise RotoridError(f"{where}: the table has {n} data row{'s' if n != 1 else ''}; a 1X table needs at least 2 "
                           "(one speed per row)")
    if np.any(speed <= 0):
        r = rownum[speed <= 0]
        raise RotoridError(f"{where}: speed column {speed_col!r} has values <= 0 rpm in {_rows_text(r)}")
    # duplicated speeds
    uniq, inv, cnt = np.unique(speed, return_inverse=True, return_counts=True)
    if np.any(cnt > 1):
        parts = [f"{uniq[u]:g} rpm in rows {', '.join(str(x) for x in rownum[inv == u])}"
                 for u in np.nonzero(cnt > 1)[0][:_MAX_LIST]]
        raise RotoridError(f"{where}: duplicated speeds in column {speed_col!r}: {'; '.join(parts)}; a table must have "
                           "one row per speed (average or delete the repeats)")
    amp = np.stack([nums[cols[c]["amplitude"]][keep] for c in chans], axis=1)
    ph = np.stack([nums[cols[c]["phase"]][keep] for c in chans], axis=1)
    for j, c in enumerate(chans):
        neg = amp[:, j] < 0
        if neg.any():
            raise RotoridError(f"{where}: column {cols[c]['amplitude']!r} ({c} amplitude) has negative amplitudes in "
                               f"{_rows_text(rownum[neg])}; an amplitude is a magnitude (the sign belongs in the phase)")
    lim = 360.0 if angle_kind == "deg" else 2 * np.pi
    for j, c in enumerate(chans):
        over = np.abs(ph[:, j]) > lim * (1 + 1e-9)
        if over.any():
            col = cols[c]["phase"]
            if angle_kind == "deg":
                raise RotoridError(f"{where}: column {col!r} ({c} phase) has phases beyond ±360 deg in "
                                   f"{_rows_text(rownum[over])} (e.g. {ph[over, j][0]:g}); wrap them to one turn")
            raise RotoridError(f"{where}: column {col!r} ({c} phase) has phases beyond ±2π rad in "
                               f"{_rows_text(rownum[over])} (e.g. {ph[over, j][0]:g}): looks like degrees; pass "
                               "phase_unit='deg'")
    if angle_kind == "deg" and n > 5 and np.all(np.abs(ph) <= 2 * np.pi):
        # every phase column within ±2π over more than 5 speeds: radians. (All columns, not each
        # one alone: one probe's degree phase can stay within ±6° over a run, four together cannot.)
        raise RotoridError(f"{where}: the phase columns {[cols[c]['phase'] for c in chans]} all lie within ±2π "
                           f"over {n} rows (rows {rownum[0]}-{rownum[-1]}): looks like radians labelled degrees; "
                           "pass phase_unit='rad'")
    half = {"pk-pk": 0.5, "0-pk": 1.0}
    f_amp = np.array([f_len * half[amp_kind]] * len(CHANNELS) + [f_acc * half[acc_amp_kind]] * (len(chans) - 4))
    a_si = amp * f_amp[None, :]
    ph_rad = np.deg2rad(ph) if angle_kind == "deg" else ph
    sign = -1.0 if phase_kind == "lag" else 1.0
    z = a_si * np.exp(1j * sign * ph_rad)
    # probes (and accelerometers) mounted at an angle: the readings' map to each plane's x and y
    # motion, for the phasors and, below, for their covariance (the errors are the readings')
    angles = {c: cols[c]["angle_deg"] for c in chans if "angle_deg" in cols[c]}
    try:
        t_probe = plane_transform({c: a for c, a in angles.items() if c in CHANNELS}, CHANNELS)
        t_acc = plane_transform({c: a for c, a in angles.items() if c in ACCELEROMETERS}, ACCELEROMETERS)
    except ValueError as exc:
        raise RotoridError(f"{where}: {exc}") from None
    order = np.argsort(speed, kind="stable")
    z = z[order]
    speed = speed[order]
    q_read = z[:, :4]
    q = q_read if t_probe is None else q_read @ t_probe.T
    info = {"columns": cols, "speed_column": speed_col, "amplitude": amp_kind, "unit": str(unit),
            "phase": phase_kind, "phase_unit": angle_kind, "rows": [int(r) for r in rownum[order]]}
    ped = {}
    if has_ped:
        # housing displacement from its 1X acceleration at the row's speed: a = -Ω² x
        om2 = (speed * units.factor("rpm", "speed")) ** 2
        acc = z[:, 4:] if t_acc is None else z[:, 4:] @ t_acc.T
        ped["pedestal"] = (-acc / om2[:, None])[:, None, :]
        info.update(accel_unit=str(accel_unit), accel_amplitude=acc_amp_kind)
    if ext in _TEXT_EXT:
        info["preamble"] = _preamble(path, first_row - 2)
    if sheet is not None:
        info["sheet"] = sheet
    m = dict(meta or {})
    m.setdefault("table", info)
    cov, dof = None, None
    if amplitude_std is not None or phase_std_deg is not None:
        sa = number("amplitude_std", amplitude_std or 0.0, nonneg=True) * f_len * half[amp_kind]
        sp = np.deg2rad(number("phase_std_deg", phase_std_deg or 0.0, nonneg=True))
        sa_acc = (accel_amplitude_std or 0.0) * f_acc * half[acc_amp_kind]
        if not (np.isfinite(sa) and np.isfinite(sp) and sa >= 0 and sp >= 0) or (sa == 0 and sp == 0 and sa_acc == 0):
            raise RotoridError(f"{where}: amplitude_std and phase_std_deg must be finite and >= 0 (one > 0), got "
                               f"{amplitude_std!r}, {phase_std_deg!r}")
        cov = polar_covariance(q_read, sa, sp)
        cov = cov if t_probe is None else moved_covariance(cov, t_probe)
        dof = np.full(n, np.inf)
        if has_ped:
            # the acceleration's covariance scaled by 1/Ω⁴ (P = -A/Ω²: the sign leaves it unchanged);
            # every channel's reading has its own error: no cross-covariance with the probes
            acc_cov = polar_covariance(z[:, 4:], sa_acc, sp)
            acc_cov = acc_cov if t_acc is None else moved_covariance(acc_cov, t_acc)
            ped["pedestal_cov"] = acc_cov / (om2 ** 2)[:, None, None]
            ped["pedestal_cross"] = np.zeros((n, 8, 8))
    return TableTrack(speed.astype(float), q[:, None, :], (1,), np.full(n, np.nan), np.full((n, 4), np.nan),
                      np.full(n, np.nan), [], cov, dof, name=name if name is not None else path.stem,
                      source=str(path), meta=m, **ped)


def polar_covariance(q, amplitude_std_m: float, phase_std_rad: float) -> np.ndarray:
    """Covariance (n, 8, 8) of 1X vectors q (n, 4) whose amplitude and phase carry independent
    errors of the given standard deviations (a DAQ's stated accuracy), as the real 8-vector
    [Re x1..y2, Im x1..y2]: per channel, variance sa² along the vector and (|q| sp)² across it."""
    from ._validate import complex_array, number

    q = complex_array("q", q, shape=(None, 4))
    amplitude_std_m = number("amplitude_std_m", amplitude_std_m, nonneg=True)
    phase_std_rad = number("phase_std_rad", phase_std_rad, nonneg=True)
    n = q.shape[0]
    cov = np.zeros((n, 8, 8))
    with np.errstate(over="ignore", invalid="ignore"):  # an overflow is refused below
        u = q / np.where(np.abs(q) > 0, np.abs(q), 1.0)
        u = np.where(np.abs(q) > 0, u, 1.0)
        for j in range(4):
            ur, ui = u[:, j].real, u[:, j].imag
            va, vt = np.float64(amplitude_std_m) ** 2, (np.abs(q[:, j]) * phase_std_rad) ** 2
            cov[:, j, j] = va * ur * ur + vt * ui * ui
            cov[:, j + 4, j + 4] = va * ui * ui + vt * ur * ur
            cov[:, j, j + 4] = cov[:, j + 4, j] = (va - vt) * ur * ui
    if not np.all(np.isfinite(cov)):
        raise RotoridError(f"amplitude_std_m = {amplitude_std_m:g} m and phase_std_rad = {phase_std_rad:g} rad with "
                           f"amplitudes up to {np.abs(q).max():g} m give a covariance that overflows")
    return cov


def _preamble(path: Path, n_lines: int) -> list:
    if n_lines <= 0:
        return []
    lines = _decode(path).splitlines()[:n_lines]
    return [ln.strip() for ln in lines if ln.strip()]


# ---------------------------------------------------------------------------------------------
# common speed grid


def _label(t, i, key=None):
    if key is not None:
        return str(key)
    nm = getattr(t, "name", None)
    return str(nm) if nm else f"run {i}"


def _interp_1x(sp, v, g):
    """Linear interpolation of complex v (n, 4) at speeds sp (ascending) to g; beyond the ends the
    end segment is extended (used only within the matching tolerance)."""
    if sp.size == 1:
        return np.repeat(v, g.size, axis=0)
    i = np.clip(np.searchsorted(sp, g) - 1, 0, sp.size - 2)
    w = (g - sp[i]) / (sp[i + 1] - sp[i])
    return v[i] * (1 - w)[:, None] + v[i + 1] * w[:, None]


def match_speeds(tracks, *, grid=None, tolerance_rpm=2.0, pedestal=False, tolerance_rel=0.0):
    """A common speed grid for several runs, with each run's 1X vectors on it.

    Runs recorded at "the same" speeds never are: a DAQ's speeds differ by fractions of an rpm
    from run to run. Each run's 1X vectors are interpolated linearly (real and imaginary parts) to
    the grid; a grid speed is kept only where *every* run has a measured speed within
    ``tolerance_rpm`` of it (interpolating across a gap between measured speeds would invent
    data), so the interpolation only corrects small speed offsets.

    Parameters
    ----------
    tracks : list of SyncTrack, or dict name -> SyncTrack
        The runs (tables from :func:`load_1x_table` or order tracks of waveforms); compensate them
        (``track.minus(...)``) first.
    grid : array_like, optional
        Speeds (rpm). Default: the first run's speeds inside the speed range all runs share
        (widened by ``tolerance_rpm``, so that runs whose ends differ by a fraction of an rpm keep
        their end speeds).
    tolerance_rpm : float
        Largest distance (rpm) from a grid speed to the nearest measured speed of every run.
    tolerance_rel : float
        The same relative to the grid speed: the distance allowed at grid speed g is
        max(tolerance_rpm, tolerance_rel * g) (default 0: tolerance_rpm alone).
    pedestal : bool
        Also return each run's 1X pedestal (housing) motion on the grid, interpolated in the same
        way; every run must then carry it (tables with accelerometer columns px1, px2, py1, py2,
        or tracks with ``pedestal=True``).

    Returns
    -------
    grid : ndarray (n,)
        Ascending speeds, rpm.
    vectors : list of ndarray (n, 4) complex
        Each run's 1X vectors [x1, x2, y1, y2] at ``grid`` (SI, as in the tracks).
    pedestals : list of ndarray (n, 4) complex
        Only with ``pedestal=True``: each run's 1X housing displacement [xp1, xp2, yp1, yp2] at
        ``grid`` (m, 0-pk), for ``SyncResponse(..., pedestal=...)``.

    Warns
    -----
    UserWarning
        When grid speeds are dropped: how many, which, and which run had no speed near them; and
        when the default grid leaves out speeds of the first run outside the shared range.

    Raises
    ------
    RotoridError
        No common speed range, or no grid speed left; the message names the runs and their ranges.
        With ``pedestal=True``, a run without pedestal motion (named).

    Examples
    --------
    >>> import numpy as np, rotorid.tables as tb
    >>> from rotorid.signals import SyncTrack
    >>> def tr(speeds):
    ...     s = np.asarray(speeds, float); n = s.size
    ...     v = (s / 1000.0)[:, None, None] * np.ones((1, 1, 4)) * 1e-6 + 0j
    ...     return SyncTrack(s, v, (1,), np.full(n, np.nan), np.full((n, 4), np.nan), np.full(n, np.nan))
    >>> grid, (a, b) = tb.match_speeds([tr([3000.0, 3500.0, 4000.0]), tr([3000.3, 3499.8, 4000.2])])
    >>> grid
    array([3000., 3500., 4000.])
    >>> np.allclose(b, a)
    True
    """
    if isinstance(tracks, dict):
        keys = list(tracks)
        tracks = [tracks[k] for k in keys]
    elif isinstance(tracks, (SyncTrack, str, bytes)):
        raise RotoridError(f"match_speeds: tracks must be a list or dict of tracks, got one {type(tracks).__name__}")
    else:
        try:
            tracks = list(tracks)
        except TypeError:
            raise RotoridError(f"match_speeds: tracks must be a list or dict of tracks, got "
                               f"{type(tracks).__name__}") from None
        keys = [None] * len(tracks)
    if not tracks:
        raise RotoridError("match_speeds: no tracks given")
    from ._validate import number

    from ._validate import flag

    tol = number("tolerance_rpm", tolerance_rpm, positive=True)
    rel = number("tolerance_rel", tolerance_rel, nonneg=True)
    if not rel < 0.5:
        raise RotoridError(f"tolerance_rel must be below 0.5 (relative to the grid speed), got {tolerance_rel!r}")

    def tol_at(speed):
        return np.maximum(tol, rel * np.asarray(speed, dtype=float))

    pedestal = flag("pedestal", pedestal)
    labels, sps, vs, ps = [], [], [], []
    for i, (t, k) in enumerate(zip(tracks, keys)):
        if not isinstance(t, SyncTrack):
            raise RotoridError(f"match_speeds: track {i} must be a SyncTrack (from load_1x_table or signals.track), "
                               f"got {type(t).__name__}")
        lab = _label(t, i, k)
        sp = np.asarray(t.speed_rpm, float)
        if sp.ndim != 1 or sp.size == 0 or not np.all(np.isfinite(sp)):
            raise RotoridError(f"match_speeds: {lab!r} has no valid speeds")
        v = np.asarray(t.order(1))
        o = np.argsort(sp, kind="stable")
        sp, v = sp[o], v[o]
        if pedestal:
            ps.append(np.asarray(t.pedestal[:, t.orders.index(1), :])[o] if t.has_pedestal else None)
        if np.any(np.diff(sp) == 0):
            d = sp[1:][np.diff(sp) == 0]
            raise RotoridError(f"match_speeds: {lab!r} has the speed(s) {np.unique(d).tolist()} rpm more than once")
        labels.append(lab)
        sps.append(sp)
        vs.append(v)
    dup = sorted({x for x in labels if labels.count(x) > 1})
    if dup:  # name runs unambiguously in messages
        labels = [f"{lab} (#{i})" if lab in dup else lab for i, lab in enumerate(labels)]
    if pedestal and any(p is None for p in ps):
        without = [lab for lab, p in zip(labels, ps) if p is None]
        raise RotoridError(f"match_speeds: pedestal=True but {without} carr{'y' if len(without) > 1 else 'ies'} no "
                           "pedestal motion (no accelerometer columns px1, px2, py1, py2 / channels tracked)")
    lo = max(s[0] for s in sps)
    hi = min(s[-1] for s in sps)
    ranges = "; ".join(f"{lab!r}: {s[0]:.1f}-{s[-1]:.1f} rpm" for lab, s in zip(labels, sps))
    if lo - hi > tol_at(lo):
        raise RotoridError(f"match_speeds: the runs share no speed range ({ranges})")
    if grid is None:
        g0 = sps[0]
        inside = (g0 >= lo - tol_at(g0)) & (g0 <= hi + tol_at(g0))
        if not inside.all():
            out = g0[~inside]
            warnings.warn(f"match_speeds: {out.size} speed(s) of {labels[0]!r} ({_speeds_text(out)}) lie outside the "
                          f"range all runs share ({lo:.1f}-{hi:.1f} rpm) and are not in the grid", stacklevel=2)
        g = g0[inside]
    else:
        from ._validate import real_array

        g = np.atleast_1d(real_array("grid", grid))
        if g.ndim != 1 or g.size == 0 or not np.all(np.isfinite(g)) or np.any(g <= 0):
            raise RotoridError("grid must be a non-empty 1-D array of speeds > 0 rpm")
        g = np.sort(g)
        if np.any(np.diff(g) == 0):
            raise RotoridError(f"grid has repeated speeds {np.unique(g[1:][np.diff(g) == 0]).tolist()} rpm")
    # nearest measured speed of every run
    far = np.zeros(g.size, bool)
    why = [[] for _ in range(g.size)]
    for lab, sp in zip(labels, sps):
        j = np.clip(np.searchsorted(sp, g), 1, max(sp.size - 1, 1))
        near = np.where(np.abs(sp[j - 1] - g) <= np.abs(sp[np.minimum(j, sp.size - 1)] - g),
                        sp[j - 1], sp[np.minimum(j, sp.size - 1)])
        d = np.abs(near - g)
        bad = d > tol_at(g)
        far |= bad
        for k in np.nonzero(bad)[0]:
            why[k].append(f"{lab!r} nearest {near[k]:.1f}")
    if far.any():
        idx = np.nonzero(far)[0]
        detail = "; ".join(f"{g[k]:.1f} rpm ({', '.join(why[k])})" for k in idx[:_MAX_LIST])
        more = f"; and {idx.size - _MAX_LIST} more" if idx.size > _MAX_LIST else ""
        allowed = f"tolerance_rpm={tol:g} rpm" if rel == 0 else f"max({tol:g} rpm, {rel * 100:g} % of the speed)"
        msg = (f"match_speeds: dropped {idx.size} of {g.size} grid speed(s): {detail}{more}: farther "
               f"than {allowed} from every measured speed of the run(s) named, so they cannot be "
               "matched reliably")
        if idx.size == g.size:
            raise RotoridError(f"{msg}; no grid speed left (runs: {ranges})")
        warnings.warn(msg, stacklevel=2)
        g = g[~far]
    if g.size == 0:
        raise RotoridError(f"match_speeds: no grid speed inside the range all runs share ({ranges})")
    out = [_interp_1x(sp, v, g) for sp, v in zip(sps, vs)]
    if pedestal:
        return g, out, [_interp_1x(sp, p, g) for sp, p in zip(sps, ps)]
    return g, out


def _speeds_text(s) -> str:
    s = np.asarray(s)
    shown = ", ".join(f"{x:.1f}" for x in s[:_MAX_LIST])
    return f"{shown}{' ...' if s.size > _MAX_LIST else ''} rpm"


# ---------------------------------------------------------------------------------------------
# slow roll


def slow_roll_vector(track, *, max_rpm=None) -> np.ndarray:
    """1X run-out of a slow-roll table: its slowest row, or the mean of the rows at or below ``max_rpm``.

    For tables that are not already slow-roll compensated (a DAQ may have subtracted a slow-roll
    vector before exporting: then do not subtract again). The slow roll must be slow enough for the
    dynamic response to be negligible (it scales with speed² well below the first critical speed).

    Run-out is the probes' alone (a shaft surface seen by a proximity probe): a table's housing
    accelerometers (``pedestal``) have none, and ``track.minus(vector)`` leaves its pedestal
    motion as it is.

    Parameters
    ----------
    track : SyncTrack
        A slow-roll table (or any track; for a waveform track every tracked order is returned).
    max_rpm : float, optional
        Average all rows at or below this speed instead of taking the slowest row.

    Returns
    -------
    ndarray (n_orders, 4) complex
        (1, 4) for a table: the vector to pass to ``track.minus(...)``.

    Examples
    --------
    >>> import os, numpy as np, rotorid.tables as tb
    >>> sr = tb.load_1x_table(os.path.join(tb.EXAMPLE_DIR, "slow_roll.csv"), columns=tb.EXAMPLE_COLUMNS)
    >>> ro = tb.slow_roll_vector(sr, max_rpm=310)          # mean of the readings at ~300 rpm
    >>> ro.shape
    (1, 4)
    >>> bool(np.all(np.abs(ro) < 10e-6))                   # a few µm of run-out
    True
    """
    if not isinstance(track, SyncTrack):
        raise RotoridError(f"slow_roll_vector needs a SyncTrack (from load_1x_table), got {type(track).__name__}")
    sp = np.asarray(track.speed_rpm, float)
    v = np.asarray(track.vectors)
    lab = _label(track, 0)
    from ._validate import number

    max_rpm = number("max_rpm", max_rpm, positive=True, allow_none=True)
    if max_rpm is None:
        return v[int(np.argmin(sp))].copy()
    sel = sp <= max_rpm
    if not sel.any():
        raise RotoridError(f"slow_roll_vector: {lab!r} has no row at or below max_rpm={max_rpm:g} (slowest "
                           f"{sp.min():.1f} rpm)")
    return v[sel].mean(axis=0)


# ---------------------------------------------------------------------------------------------
# write


def _adre_columns(amp_kind, unit, phase_kind, accel=None) -> dict:
    """Column names of the "adre" layout, in the DAQ's order; ``accel`` = (amplitude kind, unit)
    adds the housing accelerometers' columns after the probes'."""
    pts = [(ADRE_POINTS, amp_kind, unit)] + ([(ADRE_ACCEL_POINTS, *accel)] if accel is not None else [])
    return {ch: {"amplitude": f"{pt} 1X Amp ({_unit_label(u)} {'pp' if kind == 'pk-pk' else '0-pk'})",
                 "phase": f"{pt} 1X Phase (deg {phase_kind})"}
            for points, kind, u in pts for ch, pt in points.items()}


def save_1x_table(track, path, *, layout="adre", amplitude="pk-pk", unit="mil", phase="lag", preamble=None,
                  accel_unit="g", accel_amplitude=None) -> dict:
    """Write a 1X table as a vibration DAQ exports it (CSV), and return the ``columns`` that read it back.

    Layout ``"adre"`` (a Bently Nevada ADRE / System 1 style tabular list)::

        Machine: ...                       preamble: "Key: value" lines
        Data type: 1X filtered             (from ``preamble``, else the track's meta)
        ...
        <blank line>
        Sample,Speed (rpm),DE X 1X Amp (mil pp),DE X 1X Phase (deg lag),DE Y ...,FE X ...,FE Y ...

    Points DE X, DE Y, FE X, FE Y = x1, y1, x2, y2. Amplitudes rounded as a DAQ prints them (0.001
    mil, 0.01 µm, ...), phases to 0.1 deg (lag in [0, 360), lead in (-180, 180]), speeds to 0.1 rpm.

    A track with pedestal motion (``track.has_pedestal``) also gets the housing accelerometers'
    columns after the probes': points DE HSG X, DE HSG Y, FE HSG X, FE HSG Y = px1, py1, px2, py2,
    e.g. ``DE HSG X 1X Amp (g pp)``, holding the 1X acceleration A = -Ω² P of the pedestal
    displacement P at the track's (unrounded) speed, in ``accel_unit`` to 0.00001 g or 0.0001 m/s²,
    with the phase of A.

    Parameters
    ----------
    track : SyncTrack
        Order 1 is written (speeds ascending).
    path : str or path-like
        The CSV file.
    layout : {"adre"}
    amplitude : {"pk-pk", "0-pk"}
    unit : str
        Length unit of the amplitudes.
    phase : {"lag", "lead"}
    preamble : dict, optional
        Preamble lines ``{key: value}``; default: Machine, Run (the track's name), Data type and the
        track's ``meta["preamble"]`` entries if it is a dict.
    accel_unit : {"g", "m/s^2", "m/s2"}
        Acceleration unit of the accelerometers' amplitudes (tracks with pedestal motion).
    accel_amplitude : {"pk-pk", "0-pk"}, optional
        What the accelerometers' amplitudes are; default: as ``amplitude``.

    Returns
    -------
    dict
        The ``columns`` mapping for :func:`load_1x_table` (with the same ``amplitude``, ``unit``,
        ``phase``, and ``accel_unit``, ``accel_amplitude`` for a track with pedestal motion), with
        px1, px2, py1, py2 when the track has pedestal motion.

    Examples
    --------
    >>> import os, tempfile, numpy as np, rotorid.tables as tb
    >>> t = tb.load_1x_table(os.path.join(tb.EXAMPLE_DIR, "run_C0.csv"), columns=tb.EXAMPLE_COLUMNS)
    >>> out = os.path.join(tempfile.mkdtemp(), "c0_um.csv")
    >>> cols = tb.save_1x_table(t, out, unit="um", amplitude="0-pk", phase="lead")
    >>> cols["x1"]
    {'amplitude': 'DE X 1X Amp (um 0-pk)', 'phase': 'DE X 1X Phase (deg lead)'}
    >>> back = tb.load_1x_table(out, columns=cols, unit="um", amplitude="0-pk", phase="lead")
    >>> bool(np.allclose(back.vectors, t.vectors, atol=0.01e-6))     # printed to 0.01 µm, 0.1 deg
    True
    """
    from ._validate import mapping, path as _path

    if not isinstance(layout, str) or layout != "adre":
        raise RotoridError(f"layout must be 'adre', got {layout!r}")
    if not isinstance(track, SyncTrack):
        raise RotoridError(f"save_1x_table needs a SyncTrack, got {type(track).__name__}")
    path = _path("path", path)
    if preamble is not None:
        preamble = mapping("preamble", preamble)
    amp_kind = _amplitude_kind(amplitude)
    phase_kind = _phase_kind(phase)
    f_len = _length_factor(unit)
    f_acc = _accel_factor(accel_unit)
    acc_amp_kind = amp_kind if accel_amplitude is None else \
        _kind(accel_amplitude, "accel_amplitude", {"pk-pk": _PKPK, "0-pk": _ZPK},
              "'pk-pk' (also 'pp', 'peak-to-peak') or '0-pk' (also '0-p', 'peak')")
    u = _norm(unit)
    has_ped = track.has_pedestal
    chans = CHANNELS + (ACCELEROMETERS if has_ped else ())
    dec = [_AMP_DECIMALS.get(u, 3)] * 4 + [_ACC_DECIMALS.get(_norm(accel_unit), 5)] * (len(chans) - 4)
    sp = np.asarray(track.speed_rpm, float)
    v = np.asarray(track.order(1))
    if has_ped:
        # the accelerometers read A = -Ω² P (1X, at the track's speed)
        a_acc = -(sp * units.factor("rpm", "speed"))[:, None] ** 2 * np.asarray(track.pedestal)[:, track.orders.index(1), :]
        if not np.all(np.isfinite(a_acc)):
            raise RotoridError("save_1x_table: the track has NaN or inf pedestal motion")
        v = np.concatenate([v, a_acc], axis=1)
    if not (np.all(np.isfinite(sp)) and np.all(np.isfinite(v))):
        raise RotoridError("save_1x_table: the track has NaN or inf speeds or vectors")
    o = np.argsort(sp, kind="stable")
    sp, v = sp[o], v[o]
    scale = np.array([(2.0 if amp_kind == "pk-pk" else 1.0) / f_len] * 4
                     + [(2.0 if acc_amp_kind == "pk-pk" else 1.0) / f_acc] * (len(chans) - 4))
    amp = np.abs(v) * scale[None, :]
    ang = np.rad2deg(np.angle(v)) * (-1.0 if phase_kind == "lag" else 1.0)
    ang = np.round(ang, 1)
    if phase_kind == "lag":
        ang = np.mod(ang, 360.0)
        ang = np.where(ang >= 359.95, 0.0, ang)
    else:
        ang = np.where(ang <= -180.0, ang + 360.0, ang)
    cols = _adre_columns(amp_kind, unit, phase_kind, (acc_amp_kind, accel_unit) if has_ped else None)
    meta = getattr(track, "meta", {}) or {}
    if preamble is None:
        preamble = {"Machine": meta.get("machine", "rotorid"), "Run": getattr(track, "name", None) or "",
                    "Data type": "1X filtered"}
        if isinstance(meta.get("preamble"), dict):
            preamble.update(meta["preamble"])
    order_pts = list(ADRE_POINTS.items()) + (list(ADRE_ACCEL_POINTS.items()) if has_ped else [])
    header = ["Sample", "Speed (rpm)"]
    for ch, _ in order_pts:
        header += [cols[ch]["amplitude"], cols[ch]["phase"]]
    idx = {ch: chans.index(ch) for ch in chans}
    lines = [f"{k}: {val}" for k, val in preamble.items()]
    broken = [ln for ln in lines if "\n" in ln or "\r" in ln]
    if broken:
        raise RotoridError(f"save_1x_table: preamble entries must be one line each, got {broken[0]!r}")
    lines.append("")
    lines.append(",".join(header))
    for r in range(sp.size):
        cells = [str(r + 1), f"{sp[r]:.1f}"]
        for ch, _ in order_pts:
            j = idx[ch]
            a = round(float(amp[r, j]), dec[j])
            cells += [f"{a:.{dec[j]}f}", f"{ang[r, j] + 0.0:.1f}"]
        lines.append(",".join(cells))
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    except OSError as exc:
        raise RotoridError(f"cannot write {path}: {exc.strerror or exc}") from None
    return cols


EXAMPLE_COLUMNS = _adre_columns("pk-pk", "mil", "lag")


# ---------------------------------------------------------------------------------------------
# the example data set


def example_tables(out_dir=EXAMPLE_DIR) -> dict:
    """Write the example 1X tables (six CSV files in a DAQ's layout) and return {name: path}.

    Truth: ``rawsim.example_rig()`` (rotor, bearings, remnant imbalance). Runs ``S0``, ``C0``,
    ``S90``, ``C90``: 5 g static and couple sets as in :mod:`rotorid.example`, at 3000-6000 rpm every
    250 rpm; ``baseline``: the same speeds without added mass; ``slow_roll``: five readings at about
    300 rpm. Each run's speeds are jittered by up to ±0.5 rpm (as real runs are). Every response is
    added + remnant imbalance + a fixed 1X run-out of a few µm per probe, printed as a DAQ prints it
    (mils pk-pk to 0.001 mil, phase lag to 0.1 deg, speed to 0.1 rpm); not slow-roll compensated.
    Read them with ``load_1x_table(path, columns=EXAMPLE_COLUMNS)``. Deterministic.

    Examples
    --------
    >>> import tempfile, rotorid.tables as tb
    >>> paths = tb.example_tables(tempfile.mkdtemp())
    >>> sorted(paths)
    ['C0', 'C90', 'S0', 'S90', 'baseline', 'slow_roll']
    """
    from . import rawsim
    from .example import SETS
    from .model import Imbalance
    from .simulate import imbalance_response

    from ._validate import path as _path

    out_dir = str(_path("out_dir", out_dir))
    rotor, brg, remnant = rawsim.example_rig()
    runout = rawsim.Runout(amplitudes_m=(4e-6,), seed=7).vectors()[0]   # (4,) 1X run-out, ~3-5 µm
    nominal = np.arange(3000.0, 6000.0 + 1e-9, 250.0)
    rng = np.random.default_rng(2001)
    try:
        os.makedirs(out_dir, exist_ok=True)
    except OSError as exc:
        raise RotoridError(f"cannot create the folder {out_dir}: {exc.strerror or exc}") from None

    def table(speeds, added, run):
        q = imbalance_response(rotor, brg, remnant, speed_rpm=speeds, at="probes").q + runout[None, :]
        if added is not None:
            q = q + imbalance_response(rotor, brg, added, speed_rpm=speeds, at="probes").q
        n = speeds.size
        return TableTrack(speeds, q[:, None, :], (1,), np.full(n, np.nan), np.full((n, 4), np.nan),
                          np.full(n, np.nan), name=run)

    def preamble(run, note, comp="none (not slow-roll compensated)"):
        return {"Machine": "rotorid example rig (NSF rotor on test bearings)", "Run": run, "Date": "2024-05-14",
                "Data type": "1X filtered", "Compensation": comp, "Speed": "Keyphasor 1, 1 event/rev",
                "Note": note}

    paths = {}
    runs = [(k, Imbalance(tuple(m * 1e-3 for m in mass_g), ang, name=k)) for k, (mass_g, ang) in SETS.items()]
    runs.append(("baseline", None))
    for key, imb in runs:
        # each run at its own speeds, within 0.5 rpm of the nominal ones (printed to 0.1 rpm)
        speeds = nominal + rng.uniform(-0.5, 0.5, nominal.size)
        if imb is None:
            note = "no added mass (remnant imbalance only)"
        else:
            note = (f"added imbalance {imb.mass_kg[0] * 1e3:g} g at {imb.angle_deg[0]:g} deg (DE plane) and "
                    f"{imb.mass_kg[1] * 1e3:g} g at {imb.angle_deg[1]:g} deg (FE plane); angles against rotation "
                    "from the keyphasor mark")
        p = os.path.join(out_dir, EXAMPLE_FILES[key])
        save_1x_table(table(speeds, imb, key), p, preamble=preamble(key, note))
        paths[key] = p
    speeds = 300.0 + np.array([-0.43, -0.18, 0.07, 0.21, 0.38])   # five distinct printed speeds
    p = os.path.join(out_dir, EXAMPLE_FILES["slow_roll"])
    save_1x_table(table(speeds, None, "slow_roll"), p,
                  preamble=preamble("slow_roll", "five readings at about 300 rpm (run-out)", "none"))
    paths["slow_roll"] = p
    return paths
