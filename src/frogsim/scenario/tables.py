"""frogsim's CSV tables: one reader and one unit-in-header convention for every table it writes or reads.

The convention
    Every column header names its quantity and its unit in brackets: ``time [s]``,
    ``hip_left pressure [bar gauge]``, ``source pressure [kPa abs]``, ``hip_left volume [cm^3]``,
    ``hip_left charge flow [L/min std]``, ``hip_left charge valve [1 = open]``. A pressure's unit
    ends in ``gauge`` or ``abs``; ``std`` is the standard state of ISO 8778; a pure number is
    ``[-]``. frogsim writes every CSV this way (``timeseries.csv`` of simulate and swim, compare's
    CSV, the studies' CSVs of reproduce, design and control, optimize-gait's ``trials.csv``), and
    reads the same headers in fit traces, force tables and compare inputs: :func:`read_table`
    reads every CSV frogsim writes, and :func:`split_header` gives each column's unit; the only
    columns without one are the label columns of :data:`LABEL_COLUMNS` (text, or a trial's
    number). simulate's and swim's ``timeseries.csv`` are valid fit traces and compare inputs.

Older spellings, still read
    ``timeseries.csv`` of frogsim 0.1 spelt the unit into the name (``time_s``,
    ``hip_left_pressure_bar_gauge``, ``hip_left_charge_flow_L_per_min_std``) and compare's CSV
    wrote ``[bar (gauge)]``, ``[L/min (standard)]``: :func:`split_header` reads both as the new
    spelling.

The reader
    :func:`read_table` accepts only a regular UTF-8 text file (not a directory, device or binary
    file: :func:`frogsim.scenario.files.read_text`), whose every data row has exactly as many
    fields as the header (a truncated or hand-edited row with a field too many or too few is
    refused, never shifted into the wrong column), each field a number or empty (NaN). Lines
    starting with ``#`` and blank lines are skipped. Every refusal is a one-line ScenarioError
    naming the file, the row and the column.
"""
from __future__ import annotations

import csv
import io
import re
from pathlib import Path

import numpy as np

from frogsim.errors import UNKNOWN, ScenarioError
from frogsim.scenario.files import read_text

#: the old name suffixes of timeseries.csv -> (signal word, unit as now written); longest first
SUFFIXES = (
    ("_discharge_flow_L_per_min_std", "discharge flow", "L/min std"),
    ("_charge_flow_L_per_min_std", "charge flow", "L/min std"),
    ("_angular_velocity_deg_per_s", "angular velocity", "deg/s"),
    ("_angular_velocity_rad_per_s", "angular velocity", "rad/s"),
    ("_flow_L_per_min_std", "flow", "L/min std"),
    ("_flow_kg_per_s", "flow", "kg/s"),
    ("_pressure_bar_gauge", "pressure", "bar gauge"),
    ("_pressure_Pa_abs", "pressure", "Pa abs"),
    ("_contraction_percent", "contraction", "%"),
    ("_opening_percent", "opening", "%"),
    ("_discharge_valve", "discharge valve", "1 = open"),
    ("_charge_valve", "charge valve", "1 = open"),
    ("_temperature_K", "temperature", "K"),
    ("_charged_L_std", "charged air", "L std"),
    ("_volume_cm3", "volume", "cm^3"),
    ("_length_mm", "length", "mm"),
    ("_tension_N", "tension", "N"),
    ("_velocity_m_per_s", "velocity", "m/s"),
    ("_angle_deg", "angle", "deg"),
    ("_moved_L_std", "moved air", "L std"),
    ("_L_std", "", "L std"),
    ("_distance_m", "distance", "m"),
    ("_deg", "", "deg"),
    ("_N", "", "N"),
    ("_kg", "", "kg"),
    ("_m", "", "m"),
    ("_s", "", "s"),
    ("_on", "on", "1 = on"),
)
#: unit spellings of older compare CSVs -> as now written
_OLD_UNITS = {"bar (gauge)": "bar gauge", "Pa (absolute)": "Pa abs", "L/min (standard)": "L/min std",
              "L (standard)": "L std", "1 = running": "1 = on"}
_HEADER = re.compile(r"^\s*(?P<name>[^\[\]]*?)\s*\[(?P<unit>[^\[\]]*)\]\s*$")
TIME = "time"
#: the label columns frogsim writes, with no unit: a study's "mode", "experiment", "controller",
#: "joint"; optimize-gait's "trial" (its number), "state", "failure"
LABEL_COLUMNS = ("mode", "experiment", "controller", "valve", "joint", "trial", "state", "failure")


def header(name: str, unit: str) -> str:
    """A column header as frogsim writes it: ``name [unit]`` (``name`` alone without a unit)."""
    return f"{name} [{unit}]" if unit else name


def split_header(col: str) -> tuple[str, str]:
    """(name, unit) of a column header in any spelling frogsim wrote: "hip_left pressure [bar gauge]",
    "hip_left_pressure_bar_gauge" and "hip_left pressure [bar (gauge)]" all give ("hip_left pressure",
    "bar gauge"); a header of no known form is its own name with no unit ("")."""
    col = str(col).strip()
    m = _HEADER.match(col)
    if m and m.group("name"):
        unit = " ".join(m.group("unit").split())
        return m.group("name").strip(), _OLD_UNITS.get(unit, unit)
    for suffix, word, unit in SUFFIXES:
        if col.endswith(suffix) and len(col) > len(suffix):
            who = col[: -len(suffix)]
            return (f"{who} {word}" if word else who), unit
    return col, ""


def unit_headers(df):
    """The DataFrame with its columns renamed to the ``name [unit]`` convention (a copy); for the
    tables frogsim writes (``Result.to_dataframe(units="display")``, ``SwimResult``'s)."""
    return df.rename(columns={c: header(*split_header(c)) for c in df.columns})


def model_columns(muscles) -> list[tuple[str, str]]:
    """(name, unit) of every column ``frogsim simulate`` writes for a scenario with these
    muscles, known before it runs (time first)."""
    cols = [(TIME, "s")]
    for who in ("source", "exhaust"):
        cols += [(f"{who} pressure", "bar gauge"), (f"{who} temperature", "K")]
    cols += [("pump on", "1 = on"), ("pump flow", "L/min std")]
    for m in muscles:
        cols += [(f"{m} pressure", "bar gauge"), (f"{m} temperature", "K"), (f"{m} volume", "cm^3"),
                 (f"{m} length", "mm"), (f"{m} charge flow", "L/min std"), (f"{m} discharge flow", "L/min std"),
                 (f"{m} charged air", "L std"), (f"{m} charge valve", "1 = open"),
                 (f"{m} discharge valve", "1 = open")]
    return cols


def _refuse(what: str, path, why: str) -> ScenarioError:
    return ScenarioError(f"{what} {Path(path).name!r}", UNKNOWN, why)


def read_table(path, what: str = "table", numbers: bool = True, max_bytes: int | None = None):
    """A CSV table as a pandas DataFrame of floats (empty cells NaN), headers as written (stripped);
    ScenarioError(``what 'name'``) for a file that is not a regular UTF-8 text file, has no header
    or no data row, a row with more or fewer fields than the header, a repeated or empty header, or
    (``numbers``) a field that is not a number; without ``numbers`` a column holding text is kept
    as text, for the caller to refuse if it uses it."""
    import pandas as pd
    kw = {} if max_bytes is None else {"max_bytes": max_bytes}
    text = read_text(path, what if what.endswith("file") else f"{what} file", **kw)
    lines = [(k, line) for k, line in enumerate(text.splitlines(), start=1)
             if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise _refuse(what, path, "is empty: expected a header line and rows of numbers")
    rows = list(csv.reader(io.StringIO("\n".join(line for _, line in lines)), skipinitialspace=True))
    if len(rows) != len(lines):
        raise _refuse(what, path, "is not a CSV table (a quoted field runs over several lines)")
    head = [h.strip() for h in rows[0]]
    if any(not h for h in head):
        raise _refuse(what, path, f"line {lines[0][0]}: a column without a header")
    dup = sorted({h for h in head if head.count(h) > 1})
    if dup:
        raise _refuse(what, path, f"line {lines[0][0]}: column {dup[0]!r} appears twice")
    if len(rows) < 2:
        raise _refuse(what, path, "has a header but no rows of data")
    data = np.empty((len(rows) - 1, len(head)))
    text_cols: dict[int, list] = {}
    for j, ((lineno, _), row) in enumerate(zip(lines[1:], rows[1:])):
        if len(row) != len(head):
            raise _refuse(what, path, f"line {lineno} has {len(row)} field{'s' if len(row) != 1 else ''}, "
                                      f"the header {len(head)}: a truncated or altered file")
        for i, cell in enumerate(row):
            cell = cell.strip()
            if not cell:
                data[j, i] = np.nan
                continue
            try:
                data[j, i] = float(cell)
            except ValueError:
                if not numbers:
                    text_cols.setdefault(i, []).append(j)
                    data[j, i] = np.nan
                    continue
                raise ScenarioError(f"{what} {Path(path).name!r}: column {head[i]!r}", UNKNOWN,
                                    f"line {lineno}: {cell[:40]!r} is not a number") from None
    df = pd.DataFrame({h: data[:, i] for i, h in enumerate(head)})
    for i in text_cols:                       # kept as written: text is never silently a number
        df[head[i]] = [row[i].strip() if k + 1 < len(rows) else "" for k, row in enumerate(rows[1:])]
    return df
