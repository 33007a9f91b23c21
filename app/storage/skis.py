"""Ski files: neutral camber-measurement CSV and the ski HDF5 file (schema ``skisnow.ski/1``).

Neutral camber CSV (one row per sample; see docs/macro.md)::

    ski_id,side,load_kg,load_position_mm,position_mm,gap_mm
    ski-a,mean,40,-160,-970,4.512
    ...

- ``side`` is ``left``, ``right`` or ``mean``; positions are from the balance point, positive
  towards the tip; ``gap_mm`` is the gap between base and flat.
- One profile per case (side, load_kg, load_position_mm), positions strictly increasing within a
  case (or strictly decreasing in every case: a device that scans from the tip; read as the
  same samples in increasing order), the same positions in every case, one ski_id per file.
- Ranges: 0 ≤ load_kg ≤ 200, |positions| ≤ 1500 mm, −0.05 ≤ gap_mm ≤ 50. Gaps down to −0.05 mm are
  accepted as device noise around a touching point (a real stylus reads a few µm either side of
  zero) and kept as read; the macro solver clips them to zero.
- ``load_kg`` = 0 is the unloaded profile (at most one case per side, recorded first by real
  devices): its ``load_position_mm`` is ignored and stored as 0. In :class:`CamberData` (and in
  :func:`mean_profiles`) a case with F = 0 N is the unloaded profile, with x_F = 0 m
  (:func:`unloaded_mask`). Every other load is > 0.
- Spreadsheet dialects: ``,`` with decimal points, ``;`` or tab with decimal commas (or points);
  headers in any order and case, a unit in brackets read ("Load (kg)" is ``load_kg``); empty
  trailing columns ignored; UTF-8, UTF-16 or Windows-1252 text (docs/uploads.md).

Units are converted here, once: kg → N with g = 9.82 m/s² (docs/physics.md §2), mm → m.
"""

from __future__ import annotations

import codecs
import csv
import difflib
import io
import json
import os
import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np
from skisnow.app.storage.memory import SkiCache, not_owned
from skisnow.solvers.beam import G_STANDARD, BeamSki
from skisnow.solvers.errors import DataFileError, InputError

from .common import atomic_path, provenance, read_json_manifest, sha256_file, tables_dir
from .deadline import checkpoint

__all__ = [
    "CSV_COLUMNS",
    "GAP_MM_RANGE",
    "MAX_CAMBER_CASES",
    "MAX_CAMBER_ROWS",
    "SCHEMA",
    "CamberData",
    "SkiOutline",
    "SkiRecord",
    "camber_csv_text",
    "decode_camber_bytes",
    "read_camber_csv",
    "read_ski",
    "replace_ski_group",
    "unloaded_mask",
    "write_camber_csv",
    "write_ski",
]

SCHEMA = "skisnow.ski/1"
#: rows of a camber CSV between two :func:`app.storage.deadline.checkpoint` calls (~1 ms)
_CHECKPOINT_ROWS = 32
CSV_COLUMNS = ("ski_id", "side", "load_kg", "load_position_mm", "position_mm", "gap_mm")
SIDES = ("left", "right", "mean")
#: what devices write for a side, read as the side (``L`` / ``R``)
SIDE_ABBREVIATIONS = {"l": "left", "r": "right"}
#: columns a file may leave out (a device that measures one ski along its middle writes
#: neither): ``ski_id`` is then the caller's (the upload's name, a path's stem), ``side`` is
#: ``mean``; :attr:`CamberData.defaulted_columns` records which
OPTIONAL_CSV_COLUMNS = ("ski_id", "side")
LOAD_KG_RANGE = (0.0, 200.0)
POSITION_MM_LIMIT = 1500.0
#: accepted gap range [mm]; small negative values are device noise around contact
GAP_MM_RANGE = (-0.05, 50.0)


@dataclass
class CamberData:
    """Camber measurements of one ski (SI units).

    Attributes
    ----------
    ski_id : str
        Ski identifier.
    positions_m : ndarray (M,)
        Sample positions X from the balance point [m], increasing.
    loads_n : ndarray (K,)
        Load F of each case [N].
    load_positions_m : ndarray (K,)
        Load position x_F of each case [m].
    sides : list of str (K,)
        ``left``, ``right`` or ``mean`` per case.
    profiles_m : ndarray (K, M)
        Measured gaps H*(X) [m].
    read_descending : bool
        The CSV listed each case's positions from the tip to the tail (decreasing); read in
        that order and kept increasing here (the same samples; :func:`read_camber_csv`).
    load_unit_in_file : str
        The unit the CSV's header gave the load in: ``kg``, or ``kgf`` / ``kp``
        (kilogram-force, kilopond: the weight of one kg, so the same numbers).
    defaulted_columns : tuple of str
        Columns the CSV left out and their value used, as ``"name=value"``
        (:data:`OPTIONAL_CSV_COLUMNS`).
    ignored_columns : tuple of str
        Named columns of the CSV that are not read (as the header wrote them, lower case).
    renamed_columns : tuple of str
        Columns read by another name of theirs (:data:`COLUMN_SYNONYMS`), as ``"'pos (mm)' as
        position_mm"``.
    preamble_lines : tuple of str
        Lines before the header that are neither the header nor comments (a device's notes:
        ``Ski: …``, ``Date; …``), read past (:data:`MAX_PREAMBLE_LINES` at most).
    unmeasured_samples : int
        Samples the CSV gave no gap (:data:`UNMEASURED_TOKENS`: empty, ``NaN``, ``-`` …).
    dropped_positions_mm : tuple of float
        The positions [mm] dropped from every case for unmeasured samples: those outside the
        longest stretch every case measured (``unmeasured="drop"`` of :func:`read_camber_csv`);
        ``positions_m`` holds the others.
    dropped_measured_samples : int
        Measured samples set aside with those positions (in the cases that did measure them).
    position_shift_mm : float
        The largest |written − read| position [mm] where the CSV wrote its positions rounded
        (a step of 1/3 mm to 0.01 mm, 5.08 mm to whole mm): they are read as the uniform grid
        they round, each within half a unit of its last written digit
        (:func:`uniform_grid`); 0: read as written.
    absent_positions_mm : tuple of float
        Positions [mm] of the uniform grid that no case of the CSV lists (a device that skipped
        a step): read as unmeasured in every case, handled as ``unmeasured`` says.
    dropped_cases : tuple of str
        Cases left out whole for an unmeasured sample inside the kept stretch (``side=…,
        load_kg=…, load_position_mm=… (line …)``; ``unmeasured="drop"``): where that sets aside
        fewer measured samples than dropping positions from every case.
    omitted_samples : int
        Samples of the grid a case does not list while other cases do (a device started late
        or stopped early, a pass at twice the step): read as unmeasured, handled as
        ``unmeasured`` says.
    """

    ski_id: str
    positions_m: np.ndarray
    loads_n: np.ndarray
    load_positions_m: np.ndarray
    sides: list[str]
    profiles_m: np.ndarray
    read_descending: bool = False
    load_unit_in_file: str = "kg"
    defaulted_columns: tuple[str, ...] = ()
    ignored_columns: tuple[str, ...] = ()
    renamed_columns: tuple[str, ...] = ()
    preamble_lines: tuple[str, ...] = ()
    unmeasured_samples: int = 0
    dropped_positions_mm: tuple[float, ...] = ()
    dropped_measured_samples: int = 0
    position_shift_mm: float = 0.0
    absent_positions_mm: tuple[float, ...] = ()
    dropped_cases: tuple[str, ...] = ()
    omitted_samples: int = 0

    @property
    def sample_spacing_mm(self) -> float:
        """The median step of the sampling grid [mm] (a dropped position leaves one larger step:
        the median is the device's spacing)."""
        return float(np.median(np.diff(self.positions_m))) * 1e3


@dataclass
class SkiOutline:
    """Plan-form of the ski.

    Attributes
    ----------
    length_m : float
        Ski length [m].
    balance_point_from_tail_m : float
        Distance of the balance point (X = 0) from the tail end [m].
    positions_m, width_m : ndarray
        Width profile: positions X [m] and running-surface width [m].
    """

    length_m: float
    balance_point_from_tail_m: float
    positions_m: np.ndarray
    width_m: np.ndarray


@dataclass
class SkiRecord:
    """Everything a ski file holds.

    ``beam`` (demo skis only) lets the true loaded profile be recomputed for any load;
    ``beam_design`` holds the design parameters it was built from. ``network`` is the camber
    network as a dict of arrays with an ``"attrs"`` dict (nested dicts are subgroups).
    """

    measurements: CamberData
    outline: SkiOutline
    metadata: dict = field(default_factory=dict)
    beam: BeamSki | None = None
    beam_design: dict | None = None
    network: dict | None = None
    identified: dict | None = None
    #: per-process objects built from this record (the profile model, :mod:`app.service.profiles`),
    #: within the process-wide byte budget of :mod:`app.storage.memory` (SKISNOW_SKI_CACHE_MB)
    cache: SkiCache = field(default_factory=SkiCache, repr=False, compare=False)

    @property
    def ski_id(self) -> str:
        return self.measurements.ski_id


# a cached profile model refers to its record: the record is not part of the cache's size
not_owned(SkiRecord)


def _units_row(row: list[str], idx: list[int], lineno: int) -> bool:
    """Whether ``row`` (the first after the header) is a row of units ("kg", "[mm]", "-"): True
    when its numeric columns hold none of a number and each names its column's unit; a
    column in another unit is refused with the conversion to make (:func:`_unit_hint`)."""
    numeric = {name: row[k].strip() for name, k in zip(CSV_COLUMNS[2:], idx[2:], strict=True)}
    if any(re.search(r"\d", v) for v in numeric.values()) or not any(
        re.search(r"[^\W\d_]", v) for v in numeric.values()
    ):
        return False  # a number, or no unit's letter: a data row (its own checks say what)
    problems = []
    for name, text in numeric.items():
        unit = _column_key(text.lower()).strip("_")
        base, want = name.rsplit("_", 1)
        if not _reads_as(unit, want):
            hint = _unit_hint(f"{base}_{unit}") or f" (expected {want})"
            problems.append(f"{name} in {text!r}{hint}")
    if problems:
        raise InputError(f"line {lineno}: a row of units gives " + "; ".join(problems))
    return True


def _sampling_hint(cases: dict) -> str:
    """For the row cap: the first case's sampling, when finer than the job needs."""
    if not cases:
        return ""
    xs = next(iter(cases.values()))[0]
    if len(xs) < 3:
        return ""
    step_mm = abs(xs[-1] - xs[0]) / (len(xs) - 1)
    if step_mm >= 1.0:
        return ""
    return (
        f"; its first case has {len(xs)} samples every {step_mm:.3g} mm: every 1–5 mm is "
        "enough (the job needs ≤ 5 mm), so thinning the positions keeps it within the cap"
    )


_NUMBER_AND_UNIT = re.compile(r"([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*([^\d\s].*)")


def _number_with_unit(body: str, raw: str, column: str, lineno: int) -> float:
    """A number written with its unit (``0.5 mm``, ``40 kg``): read when the unit is the
    column's (kgf and kp for kg: :data:`_KG_WEIGHT_UNITS`), refused with the conversion to make
    when it is another known one (:func:`_unit_hint`); anything else is no number."""
    m = _NUMBER_AND_UNIT.fullmatch(body.strip())
    base, want = column.rsplit("_", 1)
    if m:
        unit = _column_key(m.group(2).lower()).strip("_")
        if _reads_as(unit, want):
            return float(m.group(1))
        hint = _unit_hint(f"{base}_{unit}")
        if hint:
            raise InputError(f"line {lineno}: column {column!r} is {raw!r}{hint}")
    raise InputError(f"line {lineno}: column {column!r} is not a number: {raw!r}")


def _parse_float(text: str, column: str, lineno: int, decimal: list[str]) -> float:
    """One number of the CSV. ``decimal`` holds the file's decimal mark once a number showed
    it (``[","]`` or ``["."]``; empty: not yet seen, or ``,`` is the separator so ``.``). Only
    the decimal mark is read: a number with the other mark (a thousands separator, or a file
    mixing both) is refused, never guessed."""
    raw = text.strip()
    if not raw:
        raise InputError(
            f"line {lineno}: column {column!r} is empty: every row needs its {column} (only "
            "gap_mm may be left empty, for an unmeasured sample)"
        )
    if decimal and decimal[0] == "":  # comma-separated file: the decimal mark is "."
        body = raw
        if re.fullmatch(r"[+-]?\d*,\d+", raw):
            raise InputError(
                f"line {lineno}: column {column!r} is {raw!r}: a decimal comma in a "
                "comma-separated file (quoted by the spreadsheet); save it with ';' as the "
                "separator, or with decimal points"
            )
    else:
        marks = {m for m in (",", ".") if m in raw}
        if len(marks) > 1 or (marks and decimal and marks != {decimal[0]}):
            mark = decimal[0] if decimal else sorted(marks)[0]
            raise InputError(
                f"line {lineno}: column {column!r} is {raw!r}: this file's decimal mark is "
                f"{mark!r} (first number with one decides); thousands separators and mixed "
                "decimal marks are not read"
            )
        if marks and not decimal:
            decimal.append(marks.pop())
        body = raw.replace(",", ".")
    try:
        value = float(body)
    except ValueError:
        value = _number_with_unit(body, raw, column, lineno)
    if not np.isfinite(value):
        why = (
            "not a gap (an unmeasured sample is left empty or written NaN)"
            if column == "gap_mm"
            else "not allowed (only gap_mm may be NaN or empty, for an unmeasured sample)"
        )
        raise InputError(f"line {lineno}: column {column!r} is {raw!r}: {why}")
    return value


#: what camber devices and spreadsheets write for a sample without a reading (the laser lost the
#: base, a value out of range), compared in lower case after stripping: only in ``gap_mm``
UNMEASURED_TOKENS = frozenset(
    {"", "nan", "-nan", "n/a", "na", "#n/a", "-", "--", "---", "null", "none"}
)
#: what :func:`read_camber_csv` does with unmeasured samples: ``drop`` the positions unmeasured
#: in any case from every case (the default, recorded), or ``refuse`` the file
UNMEASURED_CHOICES = ("drop", "refuse")
#: at most this share of the measured samples may be set aside with dropped positions; more is
#: refused (a file that lost that much should be measured again)
MAX_DROPPED_MEASURED_FRACTION = 0.1

#: separators of the spreadsheet dialects, in the order the header line is tried for them
CSV_SEPARATORS = ("\t", ";", ",")
#: the separator of a text file whose header has none of :data:`CSV_SEPARATORS` but several
#: names apart: runs of spaces (a device's .txt export)
WHITESPACE = " "
#: load of the unloaded profile [kg]: its case is stored with F = 0 N and x_F = 0 m
UNLOADED_LOAD_KG = 0.0
#: caps of an uploaded camber CSV: a camber device records a few hundred cases of a few
#: thousand samples (13 loads × 9 positions × 2 sides at 1 mm over 2 m is 234 cases, 468 000
#: rows); reading stops at the first row beyond either cap. The upload check applies them
#: (defaults of ``Settings.max_camber_cases`` / ``max_camber_rows``, the same numbers); a
#: file already accepted (the ski job, the command line) is read without caps
MAX_CAMBER_CASES = 2000
MAX_CAMBER_ROWS = 600_000


#: lines before the header read past at most (a device's notes, without ``#``): the header
#: must come before the first data row and within this many lines
MAX_PREAMBLE_LINES = 50


def _numbers_in(cells: list[str]) -> int:
    """How many cells read as numbers (either decimal mark): a data row has several, a
    device's note before the header one at most."""
    count = 0
    for c in cells:
        try:
            float(c.strip().replace(",", "."))
            count += 1
        except ValueError:
            pass
    return count


def _did_you_mean(key: str, missing: list[str]) -> str:
    """A missing column whose name ``key`` is a near miss of (a typo: ``postion_mm``), as a
    hint; '' when none is close."""
    close = difflib.get_close_matches(key, missing, n=1, cutoff=0.8) if key else []
    return f" (did you mean {close[0]}?)" if close else ""


def _header_score(cells: list[str]) -> int:
    """How many cells name one of :data:`CSV_COLUMNS` in some unit or by another name of
    theirs: the line most like a header among a device's lines before it."""
    return sum(
        _split_unit(_synonym_key(_column_key(c))[0])[0] in (*_COLUMN_UNITS, "ski_id", "side")
        for c in cells
    )


def _split_header(line: str, sep: str | None = None) -> tuple[str, list[str]]:
    """The separator of a header line (``sep`` when the file named it) and its cells (lower
    case, spaces and BOM stripped)."""
    line = line.lstrip("\ufeff").rstrip("\r\n")
    if sep is None:
        sep = next((s for s in CSV_SEPARATORS if s in line), None)
        if sep is None:
            # none of them: a device's text file with columns separated by spaces
            sep = WHITESPACE if len(line.split()) > 1 else ","
    cells = line.split() if sep == WHITESPACE else next(csv.reader([line], delimiter=sep))
    return sep, [c.strip().strip("\ufeff").strip().lower() for c in cells]


def _split_rows(lines, sep: str):
    """The rows of the file's lines as lists of cells: :mod:`csv` for a separator (quotes
    read), runs of blanks for :data:`WHITESPACE`."""
    if sep == WHITESPACE:
        return (line.split() for line in lines)
    return csv.reader(lines, delimiter=sep)


#: units a header may give a column in brackets ("Load (kg)"), per column [its unit]
_COLUMN_UNITS = {"load": "kg", "load_position": "mm", "position": "mm", "gap": "mm"}
#: what to do with a column given in another unit, per unit the column is read in: the other
#: unit as normalised (:func:`_column_key`) → how to convert
_UNIT_HINTS = {
    "kg": {
        "n": "divide newtons by 9.82 for kg",
        "g": "divide g by 1000 for kg",
        "lb": "multiply lb by 0.4536 for kg",
    },
    "mm": {
        "um": "divide µm by 1000 for mm",
        "cm": "multiply cm by 10 for mm",
        "m": "multiply m by 1000 for mm",
        "in": "multiply inches by 25.4 for mm",
    },
}


#: load columns in kilogram-force (a weight; kp: kilopond, the same unit), read as load_kg: one
#: kgf is the weight of one kg, so the numbers are the kg values (no conversion; recorded as
#: :attr:`CamberData.load_unit_in_file`)
_KG_WEIGHT_UNITS = ("kgf", "kp")


def _reads_as(unit: str, want: str) -> bool:
    """Whether a number in ``unit`` (as normalised by :func:`_column_key`) is read unchanged in
    a column whose unit is ``want``: the same unit, or kgf / kp for kg
    (:data:`_KG_WEIGHT_UNITS`)."""
    return unit == want or (want == "kg" and unit in _KG_WEIGHT_UNITS)


def _column_key(cell: str) -> str:
    """A header cell as a column name: lower case (the caller), runs of spaces, hyphens and dots
    as ``_``, and a unit in brackets joined on ("Load (kg)", "load [kg]" → ``load_kg``;
    "Gap mm (mm)" → ``gap_mm``); µ as u."""
    text = cell.replace("µ", "u").replace("μ", "u")
    unit = ""
    m = re.fullmatch(r"(.*?)\s*[\(\[]\s*([^\)\]]*?)\s*[\)\]]", text)
    if m:
        text, unit = m.group(1), re.sub(r"[\s\-.]+", "_", m.group(2)).strip("_")
    name = re.sub(r"[\s\-.]+", "_", text).strip("_")
    if unit and not name.endswith("_" + unit):
        name = f"{name}_{unit}"
    return name


#: units a column name may end with, without brackets (``pos_mm``), as :func:`_column_key`
#: writes them: the longest first
_NAME_UNITS = ("kgf", "mm", "um", "cm", "kg", "kp", "in", "lb", "m", "n", "g")
#: other names a header may give a column (as :func:`_column_key` writes them, the unit apart):
#: read as the column when the unit is given ("Pos (mm)", "Height [mm]", "load_pos_mm"; the
#: upload's notes and :attr:`CamberData.renamed_columns` say so); without a unit the refusal
#: names the column to write
COLUMN_SYNONYMS = {
    "position": ("pos", "x", "distance", "dist", "station"),
    "load": ("weight", "mass", "force", "f"),
    "load_position": (
        "load_pos",
        "loadpos",
        "loadposition",
        "load_at",
        "load_x",
        "x_load",
        "xf",
        "x_f",
        "load_location",
    ),
    "gap": ("height", "gap_height", "camber", "camber_height", "clearance", "h"),
}
_SYNONYM_BASE = {name: base for base, names in COLUMN_SYNONYMS.items() for name in names}


def _split_unit(key: str) -> tuple[str, str]:
    """A column key as its name and unit (``load_pos_mm`` → ``("load_pos", "mm")``; no unit:
    ``(key, "")``)."""
    for unit in _NAME_UNITS:
        if key.endswith("_" + unit) and len(key) > len(unit) + 1:
            return key[: -len(unit) - 1], unit
    return key, ""


def _synonym_key(key: str) -> tuple[str, str]:
    """The key a column of another name is read as (:data:`COLUMN_SYNONYMS`: ``pos_mm`` →
    ``position_mm``), or ``key`` itself; and, for a known column named without a unit
    ("Gap", "Pos"), the hint of what to write, else ''."""
    name, unit = _split_unit(key)
    base = _SYNONYM_BASE.get(name, name if name in _COLUMN_UNITS else None)
    if base is None:
        return key, ""
    if not unit:
        want = _COLUMN_UNITS[base]
        return key, f" (no unit: name it {base}_{want} if it is in {want})"
    return f"{base}_{unit}", ""


def _unit_hint(key: str) -> str:
    """For an unknown column that is a known one in another unit, what to change."""
    for base, unit in _COLUMN_UNITS.items():
        if key.startswith(base + "_"):
            other = key[len(base) + 1 :]
            if other in _UNIT_HINTS[unit]:
                return f" ({base} is read in {unit} as {base}_{unit}: {_UNIT_HINTS[unit][other]})"
    return ""


#: a column name that carries a load (``40kg``, ``60 kg @ -100 mm``, ``F=40``): a sheet with one
#: column of gaps per load case
_KG = re.compile(
    r"\d\s*(kg|kp|kgf|n)(?![a-z])|^\s*[-+]?\d+([.,]\d+)?\s*$|\bf\s*=\s*\d", re.IGNORECASE
)


@dataclass(frozen=True)
class _Header:
    """What a camber CSV's header says: the index of each of :data:`CSV_COLUMNS` (-1: an
    optional column left out), the indices of the named columns not read, the load's unit in
    the file (``kg``, ``kgf``, ``kp``) and the columns read by another name (``"'pos (mm)' as
    position_mm"``)."""

    idx: list[int]
    ignored: list[int]
    load_unit: str
    renamed: tuple[str, ...]


def _header_columns(cells: list[str], lineno: int = 1) -> _Header:
    """The columns of the header cells (:func:`_column_key`: "Load (kg)" is ``load_kg``; another
    name of a column with its unit, :data:`COLUMN_SYNONYMS`: "Pos (mm)" is ``position_mm``),
    the other named columns not read (a device's time stamp or temperature). Empty trailing
    cells (a trailing separator, empty spreadsheet columns) are ignored. Refused: a needed
    column missing or repeated (the other columns named, a known one in another unit with the
    conversion to make, one without a unit with the name to write), or a column without a name
    among the named ones."""
    while cells and not cells[-1]:
        cells = cells[:-1]
    raw = [_column_key(c) for c in cells]

    def column(k: str) -> str:  # kgf / kp read as kg
        return "load_kg" if k.startswith("load_") and _reads_as(k[5:], "kg") else k

    named = [k if k in CSV_COLUMNS else _synonym_key(k)[0] for k in raw]
    # a column named by its own name wins over another name of it (that one is not read)
    own = {column(r) for r in raw} & set(CSV_COLUMNS)
    named = [r if n != r and column(n) in own else n for n, r in zip(named, raw, strict=True)]
    keys = [column(k) for k in named]
    expected = ",".join(CSV_COLUMNS)
    missing = [c for c in CSV_COLUMNS if c not in keys and c not in OPTIONAL_CSV_COLUMNS]
    unknown = [
        (repr(c) if c else "'(empty)'")
        + (_unit_hint(k) or _synonym_key(r)[1] or _did_you_mean(k, missing))
        for c, k, r in zip(cells, keys, raw, strict=True)
        if k not in CSV_COLUMNS
    ]
    if cells and cells[0] == "" and keys[0] not in CSV_COLUMNS:
        unknown[0] += (
            " (the first column, a row index as pandas' to_csv writes it without index=False?)"
        )
    doubled = sorted({k for k in keys if k in CSV_COLUMNS and keys.count(k) > 1})
    unnamed = [i + 1 for i, c in enumerate(cells) if not c]
    problems = []
    if missing:
        problems.append("missing " + ", ".join(missing))
    if unknown and (missing or doubled or unnamed):
        problems.append(f"other column(s) {', '.join(unknown)} (remove or rename them)")
    if doubled:
        problems.append(
            "repeated "
            + ", ".join(
                f"{d} ({', '.join(repr(c) for c, k in zip(cells, keys, strict=True) if k == d)})"
                for d in doubled
            )
        )
    if unnamed and not missing:
        problems.append(f"column {unnamed[0]} has no name")
    numbered = [
        c for c, k in zip(cells, keys, strict=True) if k not in CSV_COLUMNS and _KG.search(c)
    ]
    if "load_kg" in missing and "gap_mm" in missing and len(numbered) >= 2:
        problems.append(
            f"{', '.join(repr(c) for c in numbered[:3])} look like one column of gaps per load "
            "case: the file needs one row per sample, the load case in its own columns; unpivot "
            "the sheet into columns load_kg, load_position_mm, position_mm, gap_mm (the example "
            "CSV on /upload shows the layout)"
        )
    if problems:
        raise InputError(
            f"line {lineno}: header must name the columns {expected} (any order, any case; a "
            "unit in brackets, as in 'Load (kg)', is read; ski_id and side may be left out; "
            "other named columns are not read), got "
            f"{','.join(cells) or 'an empty line'}: " + "; ".join(problems)
        )
    idx = [keys.index(c) if c in keys else -1 for c in CSV_COLUMNS]
    renamed = tuple(
        f"{c!r} as {k}"
        for c, k, r in zip(cells, keys, raw, strict=True)
        if k in CSV_COLUMNS and _split_unit(r)[0] in _SYNONYM_BASE
    )
    return _Header(
        idx=idx,
        ignored=[i for i, k in enumerate(keys) if k not in CSV_COLUMNS],
        load_unit=named[idx[2]][len("load_") :],  # kg, or kgf / kp read as kg
        renamed=renamed,
    )


def _sniff_codec(head: bytes) -> str | None:
    """The codec the first bytes of a camber CSV call for: ``utf-16`` (a byte-order mark),
    ``utf-16-le`` / ``utf-16-be`` (every other byte of the start zero: a spreadsheet's "Unicode
    text" without its mark), ``""`` (a single-byte text: UTF-8 or Windows-1252, decided by the
    whole file), None (zero bytes in another pattern: no text)."""
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):
        return "utf-16"
    if b"\x00" not in head:
        return ""
    if len(head) < 4:
        return None
    even, odd = head[0::2], head[1::2]
    if not odd.strip(b"\x00") and b"\x00" not in even:
        return "utf-16-le"
    if not even.strip(b"\x00") and b"\x00" not in odd:
        return "utf-16-be"
    return None


#: a text without zero bytes is read in the first of these that decodes it (latin-1 decodes
#: anything: a Windows file with one of cp1252's five unassigned bytes)
_SINGLE_BYTE_CODECS = ("utf-8-sig", "cp1252", "latin-1")
#: the name an encoding read is kept under (``data.text_encoding``), per Python codec
_ENCODING_NAMES = {
    "utf-16": "UTF-16",
    "utf-16-le": "UTF-16",
    "utf-16-be": "UTF-16",
    "utf-8-sig": "UTF-8",
    "cp1252": "Windows-1252",
    "latin-1": "Windows-1252",
}


def decode_camber_bytes(data: bytes) -> tuple[str, str] | None:
    """The text of a camber CSV's bytes and the name of the encoding it was read in: UTF-8 (a
    BOM ignored); UTF-16 with a byte-order mark, or without one when every other byte of the
    start is zero (a spreadsheet's "Unicode text"); else Windows-1252 (a spreadsheet's "CSV"
    on Windows; a file with one of its five unassigned bytes as latin-1). The ASCII digits read
    the same in each: decoding changes no number. None for bytes that are no text (zero bytes
    in another pattern, or UTF-16 that does not decode)."""
    codec = _sniff_codec(data[:4096])
    if codec is None:
        return None
    for name in (codec,) if codec else _SINGLE_BYTE_CODECS:
        try:
            return data.decode(name), _ENCODING_NAMES[name]
        except UnicodeDecodeError:
            continue
    return None


_CHUNK_BYTES = 1 << 20


def _file_codec(path: Path) -> str:
    """The Python codec a camber CSV file is read in (:func:`decode_camber_bytes`'s choice),
    decided without holding the file: its start, then a single-byte file checked as UTF-8 in
    chunks (else Windows-1252, else latin-1). DataFileError for a file that is no text."""
    with open(path, "rb") as fh:
        codec = _sniff_codec(fh.read(4096))
        if codec is None:
            raise DataFileError(f"camber CSV {path} is not text (zero bytes)")
        if codec:
            return codec
        for name in _SINGLE_BYTE_CODECS[:-1]:
            fh.seek(0)
            decoder = codecs.getincrementaldecoder(name)()
            try:
                while chunk := fh.read(_CHUNK_BYTES):
                    decoder.decode(chunk)
                decoder.decode(b"", final=True)
            except UnicodeDecodeError:
                continue
            return name
    return _SINGLE_BYTE_CODECS[-1]


def _is_path(source: str | os.PathLike) -> bool:
    """Whether ``source`` names a file (a path, or a one-line string) rather than CSV text."""
    return isinstance(source, os.PathLike) or "\n" not in str(source)


#: a line's end: CRLF (Windows), LF, or a lone CR (a Mac spreadsheet's "CSV (Macintosh)")
_EOL = re.compile(r"\r\n|\r|\n")


def _lines(source: str | os.PathLike):
    """The lines of a CSV path (DataFileError when missing; read line by line in the encoding
    :func:`_file_codec` finds) or of the CSV text itself, each with its end (CRLF, LF or a
    lone CR)."""
    if _is_path(source):
        path = Path(source)
        if not path.is_file():
            raise DataFileError(f"camber CSV not found: {path}")
        codec = _file_codec(path)
        try:
            with open(path, encoding=codec, newline="") as fh:
                yield from fh  # newline="": split at CRLF, LF and CR, kept as read
        except UnicodeDecodeError as exc:  # UTF-16 that does not decode
            raise DataFileError(f"camber CSV {path} is not {codec} text: {exc}") from None
    else:  # one line at a time: no copy of a large text, read only as far as needed
        text, start = str(source), 0
        while start < len(text):
            m = _EOL.search(text, start)
            end = len(text) if m is None else m.end()
            yield text[start:end]
            start = end


def read_camber_csv(
    source: str | os.PathLike,
    *,
    max_cases: int | None = None,
    max_rows: int | None = None,
    default_ski_id: str | None = None,
    unmeasured: str = "drop",
) -> CamberData:
    """Read and validate a camber CSV (a path, or the CSV text itself), row by row.

    Spreadsheet dialects are read: blank lines, comment lines (``#`` first) and a separator
    line (``sep=;``) before the header, a row of units under it (the units expected:
    :func:`_units_row`), comment lines among the rows; ``,``-separated with
    decimal points, ``;``- or
    tab-separated with decimal commas or points (one decimal mark per file); header names in
    any order and any case (surrounding spaces and a BOM ignored; "Load (kg)" is ``load_kg``:
    :func:`_column_key`), empty trailing columns ignored, other named columns not read
    (:attr:`CamberData.ignored_columns`; named in the refusal, a known one in another unit with
    the conversion to make, when a needed column is missing). Only the decimal mark is read: no
    number is otherwise changed. A path is read in its encoding (:func:`decode_camber_bytes`).

    ``ski_id`` and ``side`` may be left out (:data:`OPTIONAL_CSV_COLUMNS`): ``ski_id`` is then
    ``default_ski_id`` (None: a path's stem, else ``ski``) and ``side`` is ``mean``, recorded in
    :attr:`CamberData.defaulted_columns`.

    Rows with ``load_kg`` = 0 are the unloaded profile (at most one case per side): its
    ``load_position_mm`` is ignored and stored as 0 (F = 0 N, x_F = 0 m; :func:`unloaded_mask`).
    Every other load must be > 0.

    A sample without a gap (empty, ``NaN``, ``-``, ``#N/A``: :data:`UNMEASURED_TOKENS`) is
    unmeasured. Nothing is filled in: with ``unmeasured="drop"`` (default) every case keeps the
    longest stretch of consecutive positions that every case measured (one uniform grid, as
    the beam's identification needs), the positions outside it recorded in
    :attr:`CamberData.dropped_positions_mm`; refused when that would set aside more than
    :data:`MAX_DROPPED_MEASURED_FRACTION` of the measured samples (an unmeasured sample inside
    the span, not near an end). ``"refuse"`` refuses the first one with its line.

    Parameters
    ----------
    max_cases, max_rows : int, optional
        Caps on load cases (side, load, load position) and data rows (None: none); reading
        stops at the first row beyond either, so an oversized file costs no more than the cap.
        The upload check passes :data:`MAX_CAMBER_CASES` / :data:`MAX_CAMBER_ROWS` or the
        settings.

    Raises
    ------
    InputError
        With the line number and what is wrong (header, number, range, order, grid, caps).
    """
    if unmeasured not in UNMEASURED_CHOICES:
        raise InputError(
            f"unmeasured must be one of {', '.join(UNMEASURED_CHOICES)}, got {unmeasured!r}"
        )
    lines = _lines(source)
    header_line, sep_line = 0, None
    refusal: tuple[int, InputError] | None = None  # the likeliest header's refusal
    preamble: list[str] = []  # a device's lines before the header (not camber data)
    while True:
        first = next(lines, None)
        header_line += 1
        if first is None:
            if refusal is not None:
                raise refusal[1]
            where = "empty file" if header_line == 1 else "no header line after the comments"
            raise InputError(f"line 1: {where}, expected header " + ",".join(CSV_COLUMNS))
        text = first.lstrip("\ufeff").rstrip("\r\n")
        if not text.strip() or text.lstrip().startswith("#"):
            continue  # blank lines and a device's comment lines before the header
        hint = re.fullmatch(r'"?sep=(.)"?', text.strip(" "), flags=re.IGNORECASE)
        if hint and sep_line is None:
            sep_line = hint.group(1)  # a spreadsheet's separator line ("sep=;")
            continue
        sep, cells = _split_header(first, sep_line)
        try:
            header = _header_columns(cells, header_line)
            break
        except InputError as exc:
            # a device's lines before the header ("Ski: …", "Date; …"): read past while no
            # data row comes; else the first line's refusal
            score = _header_score(cells)
            if refusal is None or score >= refusal[0] > 0 or (score and not refusal[0]):
                refusal = (score, exc)  # the line naming most columns (the last of equals)
            if len(preamble) >= MAX_PREAMBLE_LINES or _numbers_in(cells) >= 3:
                raise refusal[1] from None
            preamble.append(text.strip())
    idx, ignored = header.idx, header.ignored
    readable = set(idx) | set(ignored)  # a value elsewhere has no column name
    if default_ski_id is None:
        default_ski_id = Path(source).stem if _is_path(source) else "ski"
    defaults = {"ski_id": default_ski_id, "side": "mean"}
    defaulted = tuple(
        f"{c}={defaults[c]}" for c, k in zip(CSV_COLUMNS[:2], idx[:2], strict=True) if k < 0
    )
    width = max(idx) + 1
    decimal: list[str] = [""] if sep == "," else []
    ski_id: str | None = None
    cases: dict[tuple[str, float, float], tuple[list[float], list[float], int]] = {}
    unloaded: dict[str, tuple[float, int]] = {}  # side -> (load position read, first line)
    order = 0  # +1: positions increase within a case, -1: decrease (tip first); 0: not yet seen
    rows = 0
    below: tuple[int, float] | None = None  # the first gap below GAP_MM_RANGE: (line, gap)
    largest_gap, lowest_gap = -np.inf, np.inf
    unmeasured_first: int | None = None  # the first line of an unmeasured sample
    written: dict[float, tuple[float, int]] = {}  # position -> (its last digit's unit, line)
    n_unmeasured = 0
    for lineno, row in enumerate(_split_rows(lines, sep), start=header_line + 1):
        if not row or all(not c.strip() for c in row) or row[0].lstrip().startswith("#"):
            continue  # blank and comment lines
        if rows == 0 and len(row) >= width and _units_row(row, idx, lineno):
            continue  # a spreadsheet's row of units under the header, the units expected
        rows += 1
        if not rows % _CHECKPOINT_ROWS:
            checkpoint()  # let the event loop run; the upload's time bound
        if max_rows is not None and rows > max_rows:
            raise InputError(
                f"line {lineno}: more than {max_rows} data rows, the cap of a camber CSV "
                "(max_camber_rows, SKISNOW_MAX_CAMBER_ROWS); a camber device records a few "
                "hundred cases of a few thousand samples: send one ski's measurements"
                + _sampling_hint(cases)
            )
        if len(row) < width:
            note = (
                ": a note among the rows? start it with # (a comment) or remove it"
                if _numbers_in(row) < 2
                else ""
            )
            raise InputError(
                f"line {lineno}: expected {len(CSV_COLUMNS)} columns, got {len(row)}{note}"
            )
        extra = [k + 1 for k in range(len(row)) if k not in readable and row[k].strip()]
        if extra:
            raise InputError(
                f"line {lineno}: a value in column {extra[0]}, which has no name in the header"
            )
        sid, side_raw = (
            row[k].strip() if k >= 0 else defaults[c]
            for c, k in zip(CSV_COLUMNS[:2], idx[:2], strict=True)
        )
        side = SIDE_ABBREVIATIONS.get(side_raw.lower(), side_raw.lower())
        if not sid:
            raise InputError(f"line {lineno}: ski_id is empty")
        if ski_id is None:
            ski_id = sid
        elif sid != ski_id:
            raise InputError(
                f"line {lineno}: ski_id {sid!r} differs from {ski_id!r} (one ski per file)"
            )
        if side not in SIDES:
            raise InputError(
                f"line {lineno}: side must be left, right or mean (L and R read as left and "
                f"right), got {side_raw!r}"
            )
        load_kg = _parse_float(row[idx[2]], "load_kg", lineno, decimal)
        load_pos = _parse_float(row[idx[3]], "load_position_mm", lineno, decimal)
        pos = _parse_float(row[idx[4]], "position_mm", lineno, decimal)
        if pos not in written:  # how precisely the file writes each position, and where
            written[pos] = (_written_unit_mm(row[idx[4]]), lineno)
        if row[idx[5]].strip().lower() in UNMEASURED_TOKENS:
            if unmeasured == "refuse":
                raise InputError(
                    f"line {lineno}: column 'gap_mm' is {row[idx[5]].strip() or 'empty'!r}, an "
                    "unmeasured sample, refused (unmeasured=refuse): leave its position out of "
                    "every case, or upload with unmeasured=drop (every case then keeps the "
                    "longest stretch of positions that every case measured)"
                )
            gap = np.nan
            n_unmeasured += 1
            if unmeasured_first is None:
                unmeasured_first = lineno
        else:
            gap = _parse_float(row[idx[5]], "gap_mm", lineno, decimal)
        if load_kg < 0:
            raise InputError(
                f"line {lineno}: load_kg must be > 0 (or 0 for the unloaded profile), "
                f"got {load_kg:g}"
            )
        if load_kg > LOAD_KG_RANGE[1]:
            raise InputError(
                f"line {lineno}: load_kg must be in [0, 200], got {load_kg:g}: loads above "
                "200 kg look like newtons; load_kg is in kg (divide N by 9.82)"
            )
        for name, v in (("load_position_mm", load_pos), ("position_mm", pos)):
            if abs(v) > POSITION_MM_LIMIT:
                raise InputError(
                    f"line {lineno}: {name} must be within ±1500 mm, got {v:g}: positions are "
                    "from the balance point (0 mm, negative towards the tail); a position "
                    "this far looks measured from the ski's end: subtract the balance "
                    "point's distance from it"
                )
        if gap > GAP_MM_RANGE[1]:
            raise InputError(
                f"line {lineno}: gap_mm must be in [{GAP_MM_RANGE[0]}, {GAP_MM_RANGE[1]}] "
                f"(small negative values are device noise), got {gap}; {gap:g} is above the "
                f"device's range of {GAP_MM_RANGE[1]:g} mm: values look like µm; gap_mm is in "
                "mm (divide µm by 1000)"
            )
        if gap < GAP_MM_RANGE[0] and below is None:
            below = (lineno, gap)  # refused after the rows: the file's largest gap says why
        if gap == gap:  # not an unmeasured sample (NaN)
            largest_gap, lowest_gap = max(largest_gap, gap), min(lowest_gap, gap)
        if load_kg == UNLOADED_LOAD_KG:
            seen = unloaded.setdefault(side, (load_pos, lineno))
            prev = cases.get((side, 0.0, 0.0))
            # a second profile starts again at (or before) the first one's first position
            again = prev is not None and (
                (pos - prev[0][0]) * order <= 0 if order else pos == prev[0][0]
            )
            if seen[0] != load_pos or again:
                raise InputError(
                    f"line {lineno}: a second unloaded profile (load_kg 0) of side {side}; the "
                    f"first starts at line {seen[1]}: at most one unloaded profile per side"
                )
            load_pos = 0.0  # ignored: no load, no load position
        key = (side, load_kg, load_pos)
        if key not in cases:
            if max_cases is not None and len(cases) >= max_cases:
                raise InputError(
                    f"line {lineno}: more than {max_cases} load cases (side, load_kg, "
                    "load_position_mm), the cap of a camber CSV (max_camber_cases, "
                    "SKISNOW_MAX_CAMBER_CASES); a camber device records a few hundred"
                )
            cases[key] = ([], [], lineno)
        xs, gs, _ = cases[key]
        if xs:
            if order == 0 and pos != xs[-1]:
                order = 1 if pos > xs[-1] else -1  # the file's order: the first step decides
            if (pos - xs[-1]) * order <= 0:
                way = "greater" if order >= 0 else "smaller"
                if pos == xs[0] and len(xs) > 1:  # back at its first position: a second pass
                    raise InputError(
                        f"line {lineno}: case side={side}, load_kg={load_kg:g}, "
                        f"load_position_mm={load_pos:g} starts again at position_mm {pos:g} "
                        f"(its first pass starts at line {cases[key][2]}): a case measured "
                        "twice; keep one pass per case in the file (or average the passes "
                        "yourself, and say so in the notes)"
                    )
                if pos == xs[-1]:
                    raise InputError(
                        f"line {lineno}: position_mm {pos:g} of case side={side}, "
                        f"load_kg={load_kg:g}, load_position_mm={load_pos:g} is written twice "
                        "(the line before lists it too): keep one sample per position"
                    )
                raise InputError(
                    f"line {lineno}: position_mm {pos:g} is not {way} than the previous "
                    f"position {xs[-1]:g} of case side={side}, load_kg={load_kg:g}, "
                    f"load_position_mm={load_pos:g} (positions must run one way within a case, "
                    "the same way in every case: increasing, or decreasing from the tip)"
                )
        xs.append(pos)
        gs.append(gap)
    if not cases:
        raise InputError("no data rows after the header")
    if below is not None:
        raise InputError(_negative_gap_message(*below, lowest_gap, largest_gap))
    if order < 0:  # listed from the tip: the same samples, kept in increasing order
        cases = {k: (xs[::-1], gs[::-1], line) for k, (xs, gs, line) in cases.items()}
    keys = list(cases)
    grid = _shared_positions(cases, keys)
    if grid.size < 2:
        raise InputError("each case needs at least 2 positions")
    units = np.array([written[v][0] for v in grid])
    full, at, shift = uniform_grid(grid, units, [written[v][1] for v in grid])
    absent = np.ones(full.size, dtype=bool)
    absent[at] = False
    if absent.any() and unmeasured == "refuse":
        raise InputError(
            f"file: {_absent_words(full, absent)}, refused (unmeasured=refuse): upload with "
            "unmeasured=drop (every case then keeps the longest stretch of positions that every "
            "case measured)"
        )
    listed = np.full((len(keys), grid.size), np.nan)
    omitted = np.zeros((len(keys), full.size), dtype=bool)  # rows a case does not list
    for row, key in enumerate(keys):
        xs, gs, _ = cases[key]
        where = np.searchsorted(grid, xs)
        listed[row, where] = gs
        omitted[row, at] = True
        omitted[row, at[where]] = False
    if omitted.any() and unmeasured == "refuse":
        row = int(np.argmax(omitted.any(axis=1)))
        side, load_kg, load_pos = keys[row]
        raise InputError(
            f"line {cases[keys[row]][2]}: case side={side}, load_kg={load_kg:g}, "
            f"load_position_mm={load_pos:g} does not list {int(omitted[row].sum())} of the "
            f"positions other cases list ({mm_ranges(full[omitted[row]])}), refused "
            "(unmeasured=refuse): upload with unmeasured=drop (every case then keeps the "
            "longest stretch of positions that every case measured)"
        )
    profiles_mm = np.full((len(keys), full.size), np.nan)
    profiles_mm[:, at] = listed
    keep, keep_cases, dropped_measured = _drop_unmeasured(
        profiles_mm, full, keys, cases, unmeasured_first, absent, omitted
    )
    left_out = tuple(
        f"side={s}, load_kg={f:g}, load_position_mm={xf:g} (line {cases[(s, f, xf)][2]})"
        for (s, f, xf), kept in zip(keys, keep_cases, strict=True)
        if not kept
    )
    keys = [k for k, kept in zip(keys, keep_cases, strict=True) if kept]
    return CamberData(
        ski_id=str(ski_id),
        positions_m=full[keep] * 1e-3,
        loads_n=np.array([k[1] for k in keys]) * G_STANDARD,
        load_positions_m=np.array([k[2] for k in keys]) * 1e-3,
        sides=[k[0] for k in keys],
        profiles_m=profiles_mm[np.ix_(keep_cases, keep)] * 1e-3,
        read_descending=order < 0,
        load_unit_in_file=header.load_unit,
        renamed_columns=header.renamed,
        preamble_lines=tuple(preamble),
        defaulted_columns=defaulted,
        ignored_columns=tuple(cells[k] for k in ignored),
        unmeasured_samples=n_unmeasured,
        dropped_positions_mm=tuple(float(v) for v in full[~keep]),
        dropped_measured_samples=dropped_measured,
        position_shift_mm=shift,
        absent_positions_mm=tuple(float(v) for v in full[absent]),
        dropped_cases=left_out,
        omitted_samples=int(omitted.sum()),
    )


#: a case that lists fewer than this share of the positions the cases list between them is
#: refused (a typo in its load_kg or load_position_mm that starts a case of its own), not read
#: as a case with rows left out
MIN_LISTED_SHARE = 0.25


def _shared_positions(cases: dict, keys: list) -> np.ndarray:
    """The positions the cases list between them [mm] (sorted): a case may leave out rows of
    the others' grid (a device started late, or stopped early; a pass at twice the step), read
    as its unmeasured samples. Refused, naming the case against the first one: a case with
    positions between the others' (a case's grid shifted: the positions then interleave, their
    smallest step under half the cases' own or their median step under 3/4 of it), or a case
    listing under :data:`MIN_LISTED_SHARE` of them."""
    first = np.asarray(cases[keys[0]][0], dtype=float)
    if all(np.array_equal(cases[k][0], first) for k in keys[1:]):
        return first  # one list of positions in every case (uniform_grid judges it)
    shared = np.unique(np.concatenate([np.asarray(cases[k][0], dtype=float) for k in keys]))
    steps = np.concatenate([np.diff(cases[k][0]) for k in keys])
    step = float(np.median(steps)) if steps.size else 0.0
    few = [k for k in keys if len(cases[k][0]) < MIN_LISTED_SHARE * shared.size]
    gaps = np.diff(shared)
    interleaved = shared.size > 1 and (
        float(np.min(gaps)) < 0.5 * step or float(np.median(gaps)) < 0.75 * step
    )
    outside = [k for k in keys if not np.isin(cases[k][0], first).all()]
    if not (few or (interleaved and outside)):
        return shared  # rows left out of one grid (an uneven grid: uniform_grid says where)
    bad = few[0] if few else outside[0]
    xs, _, first_line = cases[bad]
    raise InputError(
        f"line {first_line}: case side={bad[0]}, load_kg={bad[1]:g}, "
        f"load_position_mm={bad[2]:g} has {len(xs)} positions "
        f"({xs[0]:g}..{xs[-1]:g} mm) but the first case has {first.size} "
        f"({first[0]:g}..{first[-1]:g} mm): all cases must share one sampling grid (a "
        "device that records each pass at its own positions: interpolate every case "
        "onto the first case's positions; the upload resamples nothing"
        + ("; a case of a few rows: check its load_kg and load_position_mm" if few else "")
        + ")"
    )


def check_load_positions(data: CamberData) -> None:
    """Refuse a loaded case whose load stands outside the measured span (the positions kept),
    as the beam's identification would (the device model puts each load between the ends)."""
    lo, hi = float(data.positions_m[0]) * 1e3, float(data.positions_m[-1]) * 1e3
    for side, f, xf in zip(data.sides, data.loads_n, data.load_positions_m, strict=True):
        load_kg, load_pos = float(f) / G_STANDARD, float(xf) * 1e3
        if f > 0 and not lo < load_pos < hi:
            raise InputError(
                f"file: case side={side}, load_kg={load_kg:.6g}, load_position_mm="
                f"{load_pos:.6g} has its load outside "
                f"the measured span {lo:g} … {hi:g} mm (the positions every case keeps): the "
                "load must stand between the first and the last measured position; check "
                "load_position_mm (from the balance point, + towards the tip, like position_mm)"
            )


def _written_unit_mm(text: str) -> float:
    """The unit of the last digit a position was written with [mm] (``"12.35"``: 0.01; ``"12"``:
    1; a number with an exponent: 0, taken as exact)."""
    raw = text.strip()
    if "e" in raw.lower():
        return 0.0
    m = re.search(r"[.,](\d+)", raw)
    return 10.0 ** -len(m.group(1)) if m else 1.0


def uniform_grid(
    positions_mm: np.ndarray, unit_mm: np.ndarray, lines: list[int] | None = None
) -> tuple[np.ndarray, np.ndarray, float]:
    """The uniform grid a file's sample positions lie on, as the beam's identification needs.

    Positions on a uniform grid to 1e-6 of the step are read as written. Otherwise the
    positions must be the grid's nodes written rounded, each within half a unit of its last
    written digit (``unit_mm``; a step of 1/3 mm written to 0.01 mm, 5.08 mm written in whole
    mm), with the nodes no position names absent (a device that skipped a step): the grid
    X_j = a + b·j closest to them in that sense (a Chebyshev fit, scaled by each position's
    half unit) is read. Nothing finer than the file wrote is changed.

    Parameters
    ----------
    positions_mm : ndarray (M,)
        The written positions [mm], increasing.
    unit_mm : ndarray (M,)
        The unit of each position's last written digit [mm] (0: exact).
    lines : list of int, optional
        Each position's line in the file, for the messages.

    Returns
    -------
    grid_mm, index, shift_mm
        The grid's nodes [mm] from the first position to the last, the node of each written
        position, and the largest |written − read| [mm] (0 when read as written).

    Raises
    ------
    InputError
        When the positions are not such a grid, naming the position farthest from it.
    """
    x = np.asarray(positions_mm, dtype=float)
    where = (lambda i: f"line {lines[i]}: ") if lines is not None else (lambda i: "")
    d = np.diff(x)
    h0 = float(np.median(d))
    if np.ptp(d) <= 1e-6 * h0:
        return x, np.arange(x.size), 0.0
    tol = np.maximum(0.5 * np.asarray(unit_mm, dtype=float), 1e-9 * np.maximum(1.0, abs(x)))
    # the step: the mean one (no node absent), else the median one (nodes absent)
    best = None
    for h in ((x[-1] - x[0]) / (x.size - 1), h0):
        steps = np.rint(d / h)
        if np.all(steps >= 1):
            fit = _chebyshev_grid(x, np.concatenate([[0.0], np.cumsum(steps)]), tol)
            if best is None or fit[2] < best[2]:
                best = fit
            if fit[2] <= 1 + 1e-6:
                break
    if best is None:
        i = int(np.argmin(d / h0)) + 1
        raise InputError(
            f"{where(i)}position_mm {x[i]:g} follows {x[i - 1]:g} by {d[i - 1]:g} mm, where the "
            f"file's steps are mostly {h0:g} mm: the sample positions must be one uniform grid "
            "(the beam's identification needs one): measure every case at the same uniform "
            "steps, or interpolate every case onto a uniform grid (the upload resamples "
            "nothing)"
        )
    a, b, t, j = best
    if t > 1 + 1e-6:
        # named: the position farthest from a robust line (a lone misplaced position stands
        # out there; the closest grid spreads its offset over all)
        b = float(np.median(np.diff(x) / np.diff(j)))
        a = float(np.median(x - b * j))
        dev = x - (a + b * j)
        worst = int(np.argmax(np.abs(dev) / tol))
        unit = float(unit_mm[worst])
        written = f"written to {unit:g} mm" if unit > 0 else "written exactly"
        raise InputError(
            f"{where(worst)}position_mm {x[worst]:g} lies {abs(dev[worst]):.3g} mm off the "
            f"uniform grid of {b:.6g} mm steps that the positions lie closest to ({written}, "
            "a rounded grid position lies within half its last digit): the sample positions "
            "must be one uniform grid (the beam's identification needs one): write the "
            "positions the device was set to, or interpolate every case onto a uniform grid "
            "(the upload resamples nothing)"
        )
    grid = a + b * np.arange(int(j[-1]) + 1)
    index = j.astype(int)
    dev = x - grid[index]
    if np.all(np.abs(dev) <= 1e-9 * np.maximum(1.0, abs(x))):
        grid[index] = x  # on the grid as written: only absent nodes are added
        return grid, index, 0.0
    return grid, index, float(np.max(np.abs(dev)))


def _chebyshev_grid(
    x: np.ndarray, j: np.ndarray, tol: np.ndarray
) -> tuple[float, float, float, np.ndarray]:
    """The grid a + b·j closest to positions ``x`` at nodes ``j`` in units of ``tol``: (a, b,
    the largest |x − a − b·j| / tol, j); a linear programme: minimise t subject to
    |x_i − a − b·j_i| ≤ t·tol_i."""
    from scipy.optimize import linprog

    one = np.ones_like(j)
    fit = linprog(
        [0.0, 0.0, 1.0],
        A_ub=np.concatenate([np.stack([-one, -j, -tol], 1), np.stack([one, j, -tol], 1)]),
        b_ub=np.concatenate([-x, x]),
        bounds=[(None, None), (None, None), (0, None)],
        method="highs",
    )
    if fit.success:
        a, b = (float(v) for v in fit.x[:2])
    else:  # not expected (the programme is always feasible): the end-to-end line
        a, b = float(x[0]), float((x[-1] - x[0]) / max(j[-1], 1.0))
    return a, b, float(np.max(np.abs(x - a - b * j) / tol)), j


def _absent_words(grid_mm: np.ndarray, absent: np.ndarray) -> str:
    """The grid's nodes that no case lists, in words."""
    step = float(np.median(np.diff(grid_mm)))
    n = int(absent.sum())
    return (
        f"{n} position{'s' if n > 1 else ''} of the grid of {step:.6g} mm steps absent from "
        f"every case ({mm_ranges(grid_mm[absent])})"
    )


#: at most this many edges of unmeasured runs are tried as the ends of the kept stretch (their
#: pairs are each scored); beyond, only the stretch every case measured is
_MAX_STRETCH_EDGES = 400


def _cheapest_stretch(
    missing: np.ndarray, units: np.ndarray | None = None
) -> tuple[int, int, np.ndarray] | None:
    """The stretch [a, b) of positions and the cases to keep that set aside the fewest measured
    samples: a case with an unmeasured sample inside the stretch is left out whole, with every
    case of its unit (``units``, an integer per case: the left and right profiles of one load
    case, which are averaged; default each case its own), every kept case loses its samples
    outside it; ties go to fewer cases left out, then the longer stretch. None when no stretch
    of 2 positions keeps a case."""
    k, n = missing.shape
    units = np.arange(k) if units is None else np.asarray(units)
    zeros = np.zeros((k, 1), dtype=np.int64)
    gaps = np.concatenate([zeros, np.cumsum(missing, axis=1)], axis=1)  # (K, N + 1)
    meas = np.concatenate([zeros, np.cumsum(~missing, axis=1)], axis=1)
    flips = np.diff(np.concatenate([zeros, missing, zeros], axis=1).astype(np.int8), axis=1)
    edges = np.unique(np.concatenate([[0, n], np.flatnonzero(flips.any(axis=0))]))
    if edges.size > _MAX_STRETCH_EDGES:  # scattered losses: the stretch every case measured
        full = np.concatenate([[False], ~missing.any(axis=0), [False]]).astype(np.int8)
        run = np.flatnonzero(np.diff(full))
        edges = np.unique(np.concatenate([[0, n], run]))
    best, best_key = None, None
    for a in edges[:-1]:
        b = edges[edges >= a + 2]
        if not b.size:
            continue
        inside = gaps[:, b] - gaps[:, [a]]  # (K, B) unmeasured samples inside [a, b)
        per_unit = np.zeros((int(units.max()) + 1, b.size), dtype=np.int64)
        np.add.at(per_unit, units, inside)
        kept = (per_unit == 0)[units]
        kept_samples = np.where(kept, meas[:, b] - meas[:, [a]], 0).sum(axis=0)
        left_out = (~kept).sum(axis=0)
        for m in range(b.size):
            if not kept[:, m].any():
                continue
            key = (-int(kept_samples[m]), int(left_out[m]), -int(b[m] - a))
            if best_key is None or key < best_key:
                best_key, best = key, (int(a), int(b[m]), kept[:, m].copy())
    return best


def _drop_unmeasured(
    profiles_mm: np.ndarray,
    grid_mm: np.ndarray,
    keys: list,
    cases: dict,
    first_line: int | None,
    absent: np.ndarray | None = None,
    omitted: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, int]:
    """The positions and the cases to keep, and how many measured samples the rest sets
    aside: the cheapest of one uniform stretch of positions (as the beam's identification
    needs) and the cases with no unmeasured sample inside it (:func:`_cheapest_stretch`;
    readings lost near the tip or the tail cost those positions, a reading lost inside the span
    costs its case); refused, with what to change, when no 2 neighbouring positions are left or
    more than :data:`MAX_DROPPED_MEASURED_FRACTION` of the measured samples would go."""
    missing = np.isnan(profiles_mm)
    if not missing.any():
        return np.ones(missing.shape[1], dtype=bool), np.ones(missing.shape[0], dtype=bool), 0
    measured = int(np.count_nonzero(~missing))
    absent = np.zeros(missing.shape[1], dtype=bool) if absent is None else absent
    omitted = np.zeros(missing.shape, dtype=bool) if omitted is None else omitted
    listed = (missing & ~omitted)[:, ~absent]  # the samples the file lists without a gap
    parts = []
    if listed.any():
        worst = int(np.argmax(listed.sum(axis=1)))
        side, load_kg, load_pos = keys[worst]
        parts.append(
            f"{int(listed.sum())} unmeasured samples (the first at line {first_line}; the most "
            f"in case side={side}, load_kg={load_kg:g}, load_position_mm={load_pos:g}, line "
            f"{cases[keys[worst]][2]}: {int(listed[worst].sum())} of {listed.shape[1]})"
        )
    if omitted.any():
        worst = int(np.argmax(omitted.sum(axis=1)))
        side, load_kg, load_pos = keys[worst]
        parts.append(
            f"{int(omitted.sum())} samples of the grid not listed by their case (the most in "
            f"case side={side}, load_kg={load_kg:g}, load_position_mm={load_pos:g}, line "
            f"{cases[keys[worst]][2]}: {int(omitted[worst].sum())}, "
            f"{mm_ranges(grid_mm[omitted[worst]])})"
        )
    if absent.any():
        parts.append(_absent_words(grid_mm, absent))
    where = "; ".join(parts)
    sides = {key[0] for key in keys}
    if "mean" not in sides and sides == {"left", "right"}:
        # left and right are averaged per load case (camber_training_arrays): a case left out
        # takes its twin on the other side with it
        pairs = {pk: i for i, pk in enumerate(dict.fromkeys(k[1:] for k in keys))}
        units = np.array([pairs[key[1:]] for key in keys])
    else:
        units = None
    best = _cheapest_stretch(missing, units)
    if best is None:
        raise InputError(
            f"file: {where}: no two neighbouring positions are measured in any case, so no "
            "grid is left: measure the ski again"
        )
    a, b, keep_cases = best
    keep = np.zeros(missing.shape[1], dtype=bool)
    keep[a:b] = True
    lost = measured - int(np.count_nonzero(~missing[np.ix_(keep_cases, keep)]))
    if lost > MAX_DROPPED_MEASURED_FRACTION * measured:
        out = int((~keep_cases).sum())
        cost = f"dropping the {int((~keep).sum())} positions outside it from every case" + (
            f" and leaving out the {out} case{'s' if out > 1 else ''} with an unmeasured "
            "sample inside it"
            if out
            else ""
        )
        raise InputError(
            f"file: {where}: the least that keeps one uniform grid is the stretch "
            f"{grid_mm[a]:g} … {grid_mm[b - 1]:g} mm; {cost} would set aside {lost} "
            f"of the {measured} measured samples ({100 * lost / measured:.0f} %, more than "
            f"{100 * MAX_DROPPED_MEASURED_FRACTION:.0f} %; the cases keep one uniform grid, so "
            "an unmeasured sample inside the span costs its case or everything beyond it): "
            + (
                "measure the cases with unmeasured samples again, or leave them out"
                if listed.any() or omitted.any()
                else "measure every case at every position of the grid (a device that skips "
                "a step: set it to the grid's step)"
            )
        )
    return keep, keep_cases, lost


def mm_ranges(values_mm, most: int = 4) -> str:
    """Positions [mm] as runs of consecutive ones, e.g. ``-1000 … -985 mm, 40 mm`` (at most
    ``most`` runs named, then how many more)."""
    v = sorted(values_mm)
    step = float(np.min(np.diff(v))) if len(v) > 1 else 0.0
    runs: list[list[float]] = [[v[0], v[0]]]
    for x in v[1:]:
        if step and x - runs[-1][1] <= 1.5 * step:
            runs[-1][1] = x
        else:
            runs.append([x, x])
    words = [f"{a:g} … {b:g} mm" if b > a else f"{a:g} mm" for a, b in runs[:most]]
    if len(runs) > most:
        words.append(f"{len(runs) - most} more stretches")
    return ", ".join(words)


def unmeasured_note(data: CamberData) -> str | None:
    """What reading ``data`` dropped for unmeasured samples, in words (None: nothing)."""
    dropped = data.dropped_positions_mm
    left_out = data.dropped_cases
    if not dropped and not left_out:
        return None
    what = []
    if data.unmeasured_samples:
        what.append(f"{data.unmeasured_samples} unmeasured samples (no gap)")
    if data.omitted_samples:
        what.append(
            f"{data.omitted_samples} sample{'s' if data.omitted_samples > 1 else ''} of the "
            "grid not listed by their case (rows left out)"
        )
    absent = data.absent_positions_mm
    if absent:
        what.append(
            f"{len(absent)} position{'s' if len(absent) > 1 else ''} of the grid absent from "
            f"every case ({mm_ranges(absent)})"
        )
    done = dropped_words(dropped, left_out)
    return (
        f"{' and '.join(what)}: the cases keep one stretch of the grid, "
        f"{mm_ranges(data.positions_m * 1e3)}; {' and '.join(done)}, "
        f"{data.dropped_measured_samples} measured samples with them; nothing is filled in "
        "(unmeasured=refuse refuses such files)"
    )


def dropped_words(dropped_mm, left_out, *, past: bool = False) -> list[str]:
    """The positions dropped from every case and the cases left out (``side=… (line …)``), in
    words: the upload's note (present) and the ski page's (``past``)."""
    out = []
    if dropped_mm:
        out.append(
            f"the {len(dropped_mm)} positions outside the stretch kept ({mm_ranges(dropped_mm)}) "
            f"{'were' if past else 'are'} dropped from every case"
        )
    if left_out:
        n = len(left_out)
        shown = "; ".join(left_out[:3]) + (f"; {n - 3} more" if n > 3 else "")
        verb = ("was" if n == 1 else "were") if past else ("is" if n == 1 else "are")
        out.append(
            f"{'the case' if n == 1 else f'the {n} cases'} with an unmeasured sample inside it "
            f"{verb} left out ({shown})"
        )
    return out


def reading_notes(data: CamberData) -> list[str]:
    """What reading ``data`` did beyond the neutral format's way, in words: a device's lines
    before the header read past, columns read by another name, positions written rounded read
    as their grid (:func:`grid_note`), positions dropped for unmeasured or absent samples
    (:func:`unmeasured_note`)."""
    notes = []
    if data.preamble_lines:
        n = len(data.preamble_lines)
        notes.append(
            f"{n} line{'s' if n > 1 else ''} before the header read past (not camber data): "
            + ", ".join(repr(t) for t in data.preamble_lines[:3])
            + (f" and {n - 3} more" if n > 3 else "")
        )
    if data.renamed_columns:
        notes.append("columns read by another name: " + ", ".join(data.renamed_columns))
    return notes + [n for n in (grid_note(data), unmeasured_note(data)) if n]


def grid_note(data: CamberData) -> str | None:
    """How reading ``data`` took positions written rounded, in words (None: as written)."""
    if not data.position_shift_mm:
        return None
    return (
        f"positions read as the uniform grid of {data.sample_spacing_mm:.6g} mm steps they are "
        f"written rounded from (each within half its last written digit; the largest shift "
        f"{data.position_shift_mm:.3g} mm); the gaps as written"
    )


#: a file whose gaps reach above this has a camber: its gaps below the range are a device zero
#: set above the flat, not a column of the opposite sign [mm]
_CAMBER_SEEN_MM = 0.1


def _negative_gap_message(
    lineno: int, gap: float, lowest_gap_mm: float, largest_gap_mm: float
) -> str:
    """Why a gap below :data:`GAP_MM_RANGE` is refused, and what to change: the sign of the
    column when no gap of the file shows a camber (at most :data:`_CAMBER_SEEN_MM`), else the
    device's zero (the base's touching part reads below the flat)."""
    head = (
        f"line {lineno}: gap_mm must be in [{GAP_MM_RANGE[0]}, {GAP_MM_RANGE[1]}] (small "
        f"negative values are device noise), got {gap}"
    )
    if largest_gap_mm > _CAMBER_SEEN_MM:
        return (
            f"{head}; gap_mm is the gap between the base and the flat, 0 where the base touches, "
            f"and the file's gaps reach {largest_gap_mm:g} mm elsewhere, so the touching base "
            f"reads down to {lowest_gap_mm:g} mm: the device's zero looks set about "
            f"{-lowest_gap_mm:g} mm above the flat: zero it on the flat and measure again"
        )
    return (
        f"{head}; gap_mm is the gap between the base and the flat, ≥ 0 (0 where the base "
        "touches), and no gap of the file is above "
        f"{_CAMBER_SEEN_MM:g} mm: if the device writes the base's height below the flat as "
        "negative, change the sign of the column"
    )


def unloaded_mask(data: CamberData) -> np.ndarray:
    """Which cases of ``data`` are the unloaded profile (F = 0 N; its x_F is 0 m).

    Returns
    -------
    ndarray of bool, shape (K,)
    """
    return np.asarray(data.loads_n, dtype=float) == 0.0


def camber_csv_text(data: CamberData, *, decimals: int = 4) -> str:
    """``data`` as the text of a neutral camber CSV, gaps rounded to ``decimals`` mm, positions
    to 1e-6 mm (the unloaded profile, F = 0, is written with load_kg 0 and load_position_mm
    0)."""
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(CSV_COLUMNS)
    pos_mm = np.round(data.positions_m * 1e3, 6)
    for k in range(len(data.sides)):
        load_kg = round(float(data.loads_n[k]) / G_STANDARD, 6)
        load_pos = round(float(data.load_positions_m[k]) * 1e3, 6)
        gaps = np.round(data.profiles_m[k] * 1e3, decimals)
        for x, g in zip(pos_mm, gaps, strict=True):
            w.writerow(
                [
                    data.ski_id,
                    data.sides[k],
                    f"{load_kg:g}",
                    f"{load_pos:g}",
                    f"{x + 0.0:.6f}".rstrip("0").rstrip("."),  # 1e-6 mm: a 1/3 mm grid stays one
                    f"{g:.{decimals}f}",
                ]
            )
    return buf.getvalue()


def write_camber_csv(path: str | os.PathLike, data: CamberData, *, decimals: int = 4) -> None:
    """Write ``data`` as a neutral camber CSV (atomic), gaps rounded to ``decimals`` mm."""
    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        fh.write(camber_csv_text(data, decimals=decimals))


def _write_dict(group: h5py.Group, content: dict) -> None:
    for key, value in content.items():
        if key == "attrs":
            for a, v in value.items():
                group.attrs[a] = v
        elif isinstance(value, dict):
            _write_dict(group.create_group(key), value)
        else:
            group.create_dataset(key, data=np.asarray(value))


def _read_dict(group: h5py.Group) -> dict:
    out: dict = {"attrs": {k: _attr(v) for k, v in group.attrs.items()}}
    for key, item in group.items():
        out[key] = _read_dict(item) if isinstance(item, h5py.Group) else item[()]
    return out


def _attr(v):
    if isinstance(v, bytes):
        return v.decode()
    if isinstance(v, np.generic):
        return v.item()
    return v


def write_ski(
    path: str | os.PathLike,
    ski: SkiRecord,
    network: dict | None = None,
    *,
    parameters: dict | None = None,
) -> None:
    """Write a ski file atomically (schema ``skisnow.ski/1``, provenance attributes).

    Parameters
    ----------
    path : path
        Target ``.h5`` file.
    ski : SkiRecord
        Measurements, outline, metadata and, for demo skis, the beam model.
    network : dict, optional
        Camber network to store in group ``network``: arrays (datasets), an ``"attrs"`` dict
        (attributes) and nested dicts (subgroups). Default: ``ski.network``.
    parameters : dict, optional
        Generating parameters recorded in the provenance.
    """
    net = network if network is not None else ski.network
    m = ski.measurements
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.attrs["schema"] = SCHEMA
        f.attrs["ski_id"] = m.ski_id
        for k, v in provenance(parameters).items():
            f.attrs[k] = v
        g = f.create_group("measurements")
        g.attrs["description"] = "loaded camber gaps H*(X) of a rigid-flat measuring device"
        g.attrs["g_m_per_s2"] = G_STANDARD
        for name, arr, unit in (
            ("positions_m", m.positions_m, "m, from the balance point, + towards the tip"),
            ("loads_n", m.loads_n, "N"),
            ("load_positions_m", m.load_positions_m, "m, from the balance point"),
            ("profiles_m", m.profiles_m, "m, gap between base and flat; axis 0 case, axis 1 X"),
        ):
            d = g.create_dataset(name, data=np.asarray(arr, dtype=float))
            d.attrs["units"] = unit
        g.create_dataset("sides", data=np.array(m.sides, dtype=h5py.string_dtype()))
        o = f.create_group("outline")
        o.attrs["length_m"] = ski.outline.length_m
        o.attrs["balance_point_from_tail_m"] = ski.outline.balance_point_from_tail_m
        for name, arr in (
            ("positions_m", ski.outline.positions_m),
            ("width_m", ski.outline.width_m),
        ):
            o.create_dataset(name, data=np.asarray(arr, dtype=float)).attrs["units"] = "m"
        md = f.create_group("metadata")
        for k, v in ski.metadata.items():
            md.attrs[k] = v
        if ski.beam is not None:
            b = f.create_group("beam")
            b.attrs["description"] = (
                "Euler-Bernoulli beam model of the ski (solvers.beam): recompute H*(X) for any load"
            )
            if ski.beam_design is not None:
                b.attrs["design_json"] = json.dumps(ski.beam_design, sort_keys=True)
            for name, arr, unit in (
                ("positions_m", ski.beam.positions_m, "m"),
                ("bending_stiffness_nm2", ski.beam.bending_stiffness_nm2, "N m^2"),
                ("unloaded_gap_m", ski.beam.unloaded_gap_m, "m"),
            ):
                b.create_dataset(name, data=arr).attrs["units"] = unit
        if net is not None:
            _write_dict(f.create_group("network"), net)
        if ski.identified is not None:
            _write_dict(f.create_group("identified"), ski.identified)


def read_ski(path: str | os.PathLike) -> SkiRecord:
    """Read a ski file written by :func:`write_ski`.

    Raises
    ------
    DataFileError
        Missing file, unknown schema, a missing group/dataset or damaged content; the message
        names the file.
    """
    path = Path(path)
    if not path.is_file():
        raise DataFileError(f"ski file not found: {path}")
    try:
        with h5py.File(path, "r") as f:
            schema = _attr(f.attrs.get("schema", ""))
            if schema != SCHEMA:
                raise DataFileError(f"{path}: schema {schema!r}, expected {SCHEMA!r}")
            g = f["measurements"]
            meas = CamberData(
                ski_id=str(_attr(f.attrs["ski_id"])),
                positions_m=g["positions_m"][()],
                loads_n=g["loads_n"][()],
                load_positions_m=g["load_positions_m"][()],
                sides=[_attr(s) for s in g["sides"][()]],
                profiles_m=g["profiles_m"][()],
            )
            o = f["outline"]
            outline = SkiOutline(
                length_m=float(o.attrs["length_m"]),
                balance_point_from_tail_m=float(o.attrs["balance_point_from_tail_m"]),
                positions_m=o["positions_m"][()],
                width_m=o["width_m"][()],
            )
            metadata = {k: _attr(v) for k, v in f["metadata"].attrs.items()}
            beam = design = None
            if "beam" in f:
                b = f["beam"]
                beam = BeamSki(
                    b["positions_m"][()], b["bending_stiffness_nm2"][()], b["unloaded_gap_m"][()]
                )
                if "design_json" in b.attrs:
                    design = json.loads(_attr(b.attrs["design_json"]))
            network = _read_dict(f["network"]) if "network" in f else None
            identified = _read_dict(f["identified"]) if "identified" in f else None
    except (OSError, KeyError, ValueError, TypeError) as exc:  # ValueError: undecodable text
        raise DataFileError(f"{path}: unreadable or incomplete ski file ({exc})") from exc
    return SkiRecord(meas, outline, metadata, beam, design, network, identified)


#: Directory of the shipped demo skis (``tables/skis``)
SHIPPED_SKI_DIR = tables_dir() / "skis"
SKI_MANIFEST = "manifest.json"
SKI_MANIFEST_SCHEMA = "skisnow.ski-manifest/1"


def read_ski_manifest(ski_dir: str | os.PathLike) -> dict:
    """Read ``skis/manifest.json`` (DataFileError naming the file if missing or invalid)."""
    return read_json_manifest(Path(ski_dir) / SKI_MANIFEST, SKI_MANIFEST_SCHEMA, "ski manifest")


def write_ski_manifest(ski_dir: str | os.PathLike) -> Path:
    """(Re)write ``skis/manifest.json`` with sha256 and size of every ski file (atomic)."""
    ski_dir = Path(ski_dir)
    files = {
        p.name: {"sha256": sha256_file(p), "size_bytes": p.stat().st_size}
        for p in sorted(ski_dir.glob("*.h5"))
    }
    out = ski_dir / SKI_MANIFEST
    with atomic_path(out) as tmp:
        tmp.write_text(json.dumps({"schema": SKI_MANIFEST_SCHEMA, "files": files}, indent=2) + "\n")
    return out


def replace_ski_group(path: str | os.PathLike, name: str, content: dict) -> None:
    """Store ``content`` as group ``name`` of an existing ski file, atomically: the file is
    copied beside itself, the group replaced in the copy (layout of :func:`write_ski`: arrays
    as datasets, ``content["attrs"]`` as attributes, nested dicts as subgroups), and the copy
    renamed onto the original only on success; the rest of the file (measurements, the ski's
    provenance) is untouched."""
    path = Path(path)
    if not path.is_file():
        raise DataFileError(f"ski file not found: {path}")
    with atomic_path(path) as tmp:
        shutil.copyfile(path, tmp)
        with h5py.File(tmp, "r+") as fh:
            if name in fh:
                del fh[name]
            _write_dict(fh.create_group(name), content)


def identified_to_dict(
    ident, parameters: dict | None = None, profile_sd_m: np.ndarray | None = None
) -> dict:
    """An :class:`solvers.identify.IdentifiedBeam` as the ``identified`` group of a ski file:
    the beam, its bands and diagnostics (SI, units in the names), the camber's B-spline and the
    fit's covariance (when the forward fit ran), the loaded profile's standard deviation along
    the ski (``profile_sd_m``, the band's camber-model part), and provenance attributes."""
    b = ident.beam
    attrs = {
        "description": "beam identified from the camber measurements (solvers.identify)",
        "ok": bool(ident.ok),
        "reason": ident.reason,
        "noise_m": float(ident.noise_m),
        "misfit_m": float(ident.misfit_m),
        "iterations": int(ident.iterations),
        "contact_passes": int(ident.contact_passes),
        "solve_time_s": float(ident.solve_time_s),
        **provenance(parameters),
    }
    out = {
        "attrs": attrs,
        "positions_m": b.positions_m,
        "bending_stiffness_nm2": b.bending_stiffness_nm2,
        "unloaded_gap_m": b.unloaded_gap_m,
        "stiffness_band_nm2": ident.stiffness_band_nm2,
        "camber_band_m": ident.camber_band_m,
        "case_misfit_m": ident.case_misfit_m,
        "knots_m": ident.knots_m,
        "log_compliance": ident.log_compliance,
        "log_compliance_covariance": ident.log_compliance_covariance,
    }
    if ident.camber_knots_m is not None:
        out["camber_knots_m"] = ident.camber_knots_m
        out["camber_coefficients_m"] = ident.camber_coefficients
        out["parameter_covariance"] = ident.parameter_covariance
        out["kinks_m"] = np.asarray(ident.extra.get("kinks_m", []), dtype=float)
        share = ident.extra.get("stiffness_data_share")
        if share:
            out["stiffness_data_share"] = np.asarray(share, dtype=float)
    if profile_sd_m is not None:
        out["profile_sd_m"] = np.asarray(profile_sd_m, dtype=float)
    alts = getattr(ident, "alternative_beams", ())
    if alts:
        out["alternatives"] = alternatives_to_dict(alts)
    return out


def alternatives_to_dict(beams) -> dict:
    """Alternative beams of an identification (:attr:`solvers.identify.IdentifiedBeam.
    alternative_beams`, on the identified beam's nodes) as the ``identified/alternatives``
    group: one row per beam."""
    return {
        "attrs": {
            "description": "other converged forward fits that explain the cases almost as well "
            "as the identified beam (solvers.identify.alternative_fits); the error band answers "
            "with them too"
        },
        "bending_stiffness_nm2": np.array([b.bending_stiffness_nm2 for b in beams], dtype=float),
        "unloaded_gap_m": np.array([b.unloaded_gap_m for b in beams], dtype=float),
    }


def identified_beam(identified: dict | None) -> BeamSki | None:
    """The beam of a stored identification, or None when there is none or it failed."""
    if not identified or not identified.get("attrs", {}).get("ok", False):
        return None
    return BeamSki(
        np.asarray(identified["positions_m"], dtype=float),
        np.asarray(identified["bending_stiffness_nm2"], dtype=float),
        np.asarray(identified["unloaded_gap_m"], dtype=float),
    )


def identified_alternatives(identified: dict | None) -> list[BeamSki]:
    """The alternative beams stored with a served identification (``identified/alternatives``,
    on its nodes); empty when there are none, the file predates them, or it failed."""
    beam = identified_beam(identified)
    alts = (identified or {}).get("alternatives")
    if beam is None or not isinstance(alts, dict):
        return []
    ei = np.atleast_2d(np.asarray(alts["bending_stiffness_nm2"], dtype=float))
    c = np.atleast_2d(np.asarray(alts["unloaded_gap_m"], dtype=float))
    if ei.shape != c.shape or ei.shape[1] != beam.positions_m.size:
        raise DataFileError(
            "identified/alternatives: arrays must be (k, nodes) like the identified beam, got "
            f"{ei.shape} and {c.shape} for {beam.positions_m.size} nodes"
        )
    return [BeamSki(beam.positions_m, e, g) for e, g in zip(ei, c, strict=True)]


def identification_for_sampling(identified: dict | None):
    """The stored identification as a :class:`solvers.identify.IdentifiedBeam` that
    :func:`solvers.identify.sample_beams` can draw plausible beams from, or None: it failed, or
    it stores no forward-fit covariance (``parameter_covariance`` with the camber's B-spline).

    The file does not store the variable-projection fallback's ``camber_sensitivity`` and
    ``camber_sd_m``; they are NaN here, so a draw that would need them cannot pass unnoticed."""
    from skisnow.solvers.identify import IdentifiedBeam

    beam = identified_beam(identified)
    keys = ("parameter_covariance", "camber_knots_m", "camber_coefficients_m", "knots_m")
    if beam is None or any(k not in identified for k in keys):
        return None
    a = identified["attrs"]
    knots = np.asarray(identified["knots_m"], dtype=float)
    n = beam.positions_m.size
    return IdentifiedBeam(
        beam=beam,
        ok=True,
        reason="",
        noise_m=float(a.get("noise_m", np.nan)),
        misfit_m=float(a.get("misfit_m", np.nan)),
        case_misfit_m=np.asarray(identified.get("case_misfit_m", []), dtype=float),
        stiffness_band_nm2=np.asarray(identified["stiffness_band_nm2"], dtype=float),
        camber_band_m=np.asarray(identified["camber_band_m"], dtype=float),
        iterations=int(a.get("iterations", 0)),
        contact_passes=int(a.get("contact_passes", 0)),
        knots_m=knots,
        log_compliance=np.asarray(identified["log_compliance"], dtype=float),
        log_compliance_covariance=np.asarray(identified["log_compliance_covariance"], dtype=float),
        camber_sensitivity=np.full((n, knots.size), np.nan),
        camber_sd_m=np.full(n, np.nan),
        camber_knots_m=np.asarray(identified["camber_knots_m"], dtype=float),
        camber_coefficients=np.asarray(identified["camber_coefficients_m"], dtype=float),
        parameter_covariance=np.asarray(identified["parameter_covariance"], dtype=float),
    )


def mean_profiles(data: CamberData) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """One profile per (load, position) for beam identification: left and right profiles of a
    case averaged (the measurements themselves are not changed). The unloaded profile, if
    measured, stays one case with F = 0 N and x_F = 0 m (its sides averaged like the others;
    :func:`unloaded_mask`). Returns F [N], x_F [m], profiles [m] and a note saying what was
    done."""
    keys = list(zip(np.round(data.loads_n, 9), np.round(data.load_positions_m, 9), strict=True))
    if all(s == "mean" for s in data.sides) and len(set(keys)) == len(keys):
        return data.loads_n, data.load_positions_m, data.profiles_m, "one profile per case"
    groups: dict = {}
    for k, key in enumerate(keys):
        groups.setdefault(key, []).append(k)
    f = np.array([data.loads_n[v[0]] for v in groups.values()])
    x = np.array([data.load_positions_m[v[0]] for v in groups.values()])
    y = np.stack([data.profiles_m[v].mean(axis=0) for v in groups.values()])
    return f, x, y, "left and right profiles of each case averaged"
