"""Layout detection of delimited text files: preamble, header, separator and decimal mark.

The first 8 KiB of the file (64 KiB, then 1 MiB, if that is not enough) are examined. A line is *numeric*
under a (separator, decimal) pair when every field is a number (a trailing empty field, from a
separator ending the line, is allowed). The data start at the first block of 3 or more numeric
lines with one field count (or fewer, if they reach the end of the file); the header is the
last non-numeric line before them and must have as many fields. A header made only of units
(``s``, ``[mm]``, ...) under a line of names with as many fields is read as a units line.
Every pair that fits is tried; pairs that read the same fields are one reading. Of several
readings, those whose column names hold a separator character are discarded; if several remain,
the file is ambiguous and ``sep=``/``decimal=`` must be given.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass, field

from ..errors import RotoridError
from ._common import _cannot, _describe, _is_unit, _split_unit

_WS = " "  # internal name of "runs of whitespace"
_SEPS = (",", ";", "\t", _WS)
_SEP_NAMES = {",": "','", ";": "';'", "\t": "tab", _WS: "whitespace", "|": "'|'"}
_SEP_ALIASES = {"tab": "\t", "whitespace": _WS, r"\s+": _WS, " ": _WS}
_CONFIGS = [(s, d) for d in (".", ",") for s in _SEPS if not (s == "," and d == ",")]
_NUMBER = {
    ".": re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|[+-]?(?:nan|inf|infinity)", re.I),
    ",": re.compile(r"[+-]?(?:\d+,?\d*|,\d+)(?:[eE][+-]?\d+)?|[+-]?(?:nan|inf|infinity)", re.I),
}
_MIN_BLOCK = 3
_SAMPLE_SIZES = (1 << 13, 1 << 16, 1 << 20)  # most files show their layout in the first 8 KiB

_RATE_KEY = (r"(?:sample|sampling|scan)[\s_-]*(?:rate|frequency|freq\.?)|fs|rate|abtastrate|abtastfrequenz")
_RATE_UNIT = r"hz|khz|s/s|ks/s|sps|samples?/s|sa/s"
_RATE_NUM = {".": r"\d+(?:\.\d*)?(?:[eE][+-]?\d+)?", ",": r"\d+(?:,\d*)?(?:[eE][+-]?\d+)?"}
_RATE = {d: re.compile(rf"^[\s#;%!/*\"']*(?:{_RATE_KEY})\s*(?:[\[(]\s*(?P<u1>{_RATE_UNIT})\s*[\])])?\s*[:=,;\t ]\s*"
                       rf"[\"']?(?P<num>{num})[\"']?[\s,;\t\"']*(?P<u2>{_RATE_UNIT})?[\s,;\t\"']*$", re.I)
         for d, num in _RATE_NUM.items()}


@dataclass
class _Layout:
    sep: str                        # one character, or _WS
    decimal: str
    data: int                       # index of the first data line (lines to skip)
    k: int                          # fields per data line
    header: int | None = None       # index of the names line (None: no header)
    names: list = field(default_factory=list)
    units: list = field(default_factory=list)
    preamble: list = field(default_factory=list)   # [(line number, text)] before the header

    @property
    def pandas_sep(self) -> str:
        return r"\s+" if self.sep == _WS else self.sep


def _norm_sep(sep):
    if sep is None:
        return None
    if isinstance(sep, str):
        sep = _SEP_ALIASES.get(sep, sep)
        if len(sep) == 1 and not sep.isalnum() and sep not in "\"'.\r\n":
            return sep
    raise RotoridError(f"sep must be one of ',', ';', '\\t' (or 'tab'), 'whitespace' or another single "
                       f"punctuation character, got {sep!r}")


def _norm_decimal(decimal, sep):
    if decimal is None:
        return None
    if not isinstance(decimal, str) or decimal not in (".", ","):
        raise RotoridError(f"decimal must be '.' or ',', got {decimal!r}")
    if decimal == sep:
        raise RotoridError(f"sep and decimal must differ, both are {decimal!r}")
    return decimal


def _sample(path, size):
    """(lines of the first ``size`` bytes (whole lines), encoding, whether that is the whole file)."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read(size + 1)
    except OSError as exc:
        raise _cannot(path, "csv", _describe(exc)) from None
    whole = len(raw) <= size
    if not whole:
        raw = raw[: raw.rfind(b"\n", 0, size) + 1] or raw[:size]
    if b"\x00" in raw:
        raise _cannot(path, "csv", "it holds NUL bytes: it is not a text file (or it is UTF-16 text: save it as UTF-8)")
    for encoding in ("utf-8-sig", "cp1252", "latin-1"):
        try:
            text = raw.decode(encoding)
            break
        except UnicodeDecodeError:
            continue
    lines = [line.rstrip("\r") for line in text.split("\n")]
    if lines and lines[-1] == "":
        lines.pop()
    return lines, encoding, whole


def _fields(line, sep):
    if sep == _WS:
        return line.split()
    return [f.strip().strip('"').strip() for f in line.split(sep)]


def _numeric(line, sep, dec):
    """The field count of a numeric line, else None."""
    fields = _fields(line, sep)
    check = fields[:-1] if len(fields) > 1 and fields[-1] == "" else fields
    match = _NUMBER[dec].fullmatch
    if not check or not all(match(f) for f in check):
        return None
    return len(fields)


def _header_cells(line, sep):
    """The cells of a header line: csv quoting for one-character separators; for whitespace,
    unit tokens like '[s]' or '(mm)' are joined to the name before them."""
    if sep != _WS:
        # a stray carriage return inside a line (a damaged file) is not a line break of csv's
        line = line.replace("\r", " ").replace("\n", " ")
        return [c.strip() for c in next(csv.reader([line], delimiter=sep, skipinitialspace=True), [])]
    cells = []
    for tok in line.split():
        if cells and re.fullmatch(r"[\[(][^\[\]()]*[\])]", tok):
            cells[-1] += " " + tok
        else:
            cells.append(tok)
    return cells


def _is_units_row(cells):
    units = [c.strip().strip("[]()").strip() for c in cells]
    return any(units) and all(not u or _is_unit(u) for u in units)


def _fit(lines, start, sep, dec, whole, misses):
    """The layout under (sep, dec), or None when the lines do not read that way. A block of data
    under a line with another field count is described in ``misses``."""
    run_start = run_k = prev = None
    run_len, prev_numeric, before = 0, False, None
    for i in range(start, len(lines)):
        if not lines[i].strip():
            continue
        k = _numeric(lines[i], sep, dec)
        if k is None:
            run_start, run_len = None, 0
        elif run_start is not None and k == run_k:
            run_len += 1
        else:
            run_start, run_k, run_len, before = i, k, 1, (None if prev is None else (prev, prev_numeric))
        prev, prev_numeric = i, k is not None
        if run_len >= _MIN_BLOCK:
            break
    else:
        if run_start is None or not whole:
            return None
    if before is not None and before[1]:
        return None  # a numeric line of another field count right before the data
    trailing = _fields(lines[run_start], sep)[-1] == "" and run_k > 1
    lay = _Layout(sep, dec, run_start, run_k)
    if before is None:
        lay.names = [f"column {j + 1}" for j in range(run_k)]
        lay.units = [None] * run_k
        lay.preamble = [(j + 1, lines[j]) for j in range(run_start) if lines[j].strip()]
        return lay
    h = before[0]
    cells = _header_cells(lines[h], sep)
    if trailing and len(cells) == run_k - 1:
        cells.append("")
    if len(cells) != run_k:
        if run_len >= _MIN_BLOCK:
            misses.append(f"the data from line {run_start + 1} have {run_k} fields ({_SEP_NAMES.get(sep, repr(sep))}"
                          f"-separated, decimal {dec!r}), but line {h + 1} before them has {len(cells)}: "
                          f"{lines[h].strip()[:60]!r}")
        return None
    above = max((j for j in range(start, h) if lines[j].strip()), default=None)
    if above is not None and _is_units_row(cells) and _numeric(lines[above], sep, dec) is None:
        names = _header_cells(lines[above], sep)
        if trailing and len(names) == run_k - 1:
            names.append("")
        if len(names) == run_k:
            lay.names = [_split_unit(c)[0] for c in names]
            lay.units = [c.strip().strip("[]()").strip() or None for c in cells]
            h = above
    if not lay.names:
        lay.names, lay.units = (list(x) for x in zip(*(_split_unit(c) for c in cells)))
    lay.header = h
    lay.preamble = [(j + 1, lines[j]) for j in range(h) if lines[j].strip()]
    return lay


def _reading(lay, lines):
    """What a layout reads from the first data lines (to tell different readings apart)."""
    rows = []
    for line in lines[lay.data: lay.data + 12]:
        if line.strip():
            fields = _fields(line, lay.sep)
            rows.append(tuple(f.replace(",", ".") if lay.decimal == "," else f for f in fields))
    return lay.header, lay.k, tuple(rows)


def _describe_layout(lay):
    return (f"{lay.k} column(s) separated by {_SEP_NAMES.get(lay.sep, repr(lay.sep))} with decimal "
            f"{lay.decimal!r}")


def _detect(path, lines, whole, skip_rows, sep, decimal) -> _Layout | None:
    """The layout of the sampled lines, or None when no block of numeric lines shows it."""
    start = skip_rows or 0
    configs = [(s, d) for s, d in _CONFIGS if (sep is None or s == sep) and (decimal is None or d == decimal)]
    if sep is not None and sep not in _SEPS:
        configs = [(sep, d) for d in (".", ",") if d != sep and (decimal is None or d == decimal)]
    first = next((j for j in range(start, len(lines)) if lines[j].strip()), None)
    readings, misses = {}, []
    for s, d in configs:
        lay = _fit(lines, start, s, d, whole, misses)
        if lay is None or (skip_rows is not None and lay.header != first):
            continue
        if d == "," and lay.k == 1 and lay.header is not None and "," in lines[lay.header]:
            continue  # one column with decimal commas under a header with commas: a comma-separated file
        readings.setdefault(_reading(lay, lines), lay)
    found = list(readings.values())
    if not found and misses:
        raise _cannot(path, "csv", f"cannot find the header line: {misses[0]}; pass skip_rows= (the number of "
                                   "lines before the header)")
    if len(found) > 1:
        clean = [lay for lay in found if not any(ch in n for n in lay.names for ch in ",;\t")]
        found = clean or found
    if len(found) > 1:
        a, b = found[:2]
        raise _cannot(path, "csv", f"the layout is ambiguous: from line {a.data + 1} the file reads as "
                                   f"{_describe_layout(a)} or as {_describe_layout(b)}; pass sep= and decimal=")
    return found[0] if found else None


def _fallback(path, lines, skip_rows, sep, decimal) -> _Layout:
    """The first non-blank line (after skip_rows) is the header; the separator is the most frequent
    of , ; and tab in it (for files whose data lines are not all numeric, e.g. a text column); the
    decimal mark a comma if the next lines show decimal commas and no decimal points."""
    start = skip_rows or 0
    h = next((j for j in range(start, len(lines)) if lines[j].strip()), None)
    if h is None:
        raise _cannot(path, "csv", "the file is empty (no header row)" if not skip_rows
                      else f"nothing follows the {skip_rows} skipped line(s)")
    if sep is None:
        sep = max((",", ";", "\t"), key=lines[h].count)
    if decimal is None:
        # decimal commas if some cells of the next lines have one and none has a decimal point
        cells = [f for line in lines[h + 1: h + 21] for f in _fields(line, sep)]
        commas = any("," in f and _NUMBER[","].fullmatch(f) for f in cells)
        points = any("." in f and _NUMBER["."].fullmatch(f) for f in cells)
        decimal = "," if sep != "," and commas and not points else "."
    cells = _header_cells(lines[h], sep)
    names, units = (list(x) for x in zip(*(_split_unit(c) for c in cells)))
    return _Layout(sep, decimal, h + 1, len(cells), h, names, units,
                   [(j + 1, lines[j]) for j in range(h) if lines[j].strip()])


def _layout(path, skip_rows, sep, decimal) -> tuple[_Layout, str]:
    for size in _SAMPLE_SIZES:
        lines, encoding, whole = _sample(path, size)
        lay = _detect(path, lines, whole, skip_rows, sep, decimal)
        if lay is not None or whole:
            break
    if not lines:
        raise _cannot(path, "csv", "the file is empty (no header row)")
    lay = lay or _fallback(path, lines, skip_rows, sep, decimal)
    if encoding == "utf-8-sig" and lay.data > 0:
        encoding = "utf-8"  # a byte-order mark sits in a skipped line; plain utf-8 is pandas' fast path
    return lay, encoding


def _stated_rate(path, lay) -> tuple[float, int, str] | None:
    """The sample rate the preamble states: (Hz, line number, line), or None."""
    found = []
    for number, text in lay.preamble:
        m = _RATE[lay.decimal].match(text)
        if m:
            unit = (m.group("u1") or m.group("u2") or "hz").lower()
            value = float(m.group("num").replace(",", ".")) * (1e3 if unit.startswith("k") else 1.0)
            if value > 0:
                found.append((value, number, text.strip()))
    if len({v for v, _, _ in found}) > 1:
        listing = "; ".join(f"line {n}: {t!r}" for _, n, t in found)
        raise RotoridError(f"{path}: the preamble states different sample rates ({listing}): which one is the "
                           "sample rate? Remove the other line from the file")
    return found[0] if found else None
