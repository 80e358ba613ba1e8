"""Measured traces in: CSV (or Parquet) columns with their units in the header, turned into SI.

A trace file has one time column and one column per measured signal, each header naming the signal
and its unit in brackets::

    time [s], hip_left pressure [bar gauge], source pressure [kPa abs]

Signals are the ones the pneumatic model computes: ``<muscle> pressure``, ``source pressure`` and
``exhaust pressure``, and the air temperatures ``<muscle> temperature``, ``source temperature``
and ``exhaust temperature`` (the model's T = p V/(m R), :meth:`frogsim.Result.temperature`). A
pressure unit must say whether it is ``gauge`` or ``abs`` (``absolute``); gauge values are made
absolute with the scenario's atmospheric pressure. A temperature unit is a temperature, never
gauge or abs: K, or an offset unit such as degC (20 degC is 293.15 K); a difference unit
(delta_degC) is refused, and so is a value outside the air temperatures the model holds (150 K to
1000 K, as in a scenario). Every unit goes through frogsim's own unit parser
(:mod:`frogsim.scenario.units`). Columns the fit is not to use (a joint angle, a temperature
measured somewhere the model has none) are named in the experiment's ``ignore_columns``; the other
columns frogsim simulate writes (volumes, flows, valve states) are left out without being named;
any other column the model has no signal for is refused, so that a misspelt signal is never
silently dropped. A temperature column is read as a signal; the fit spec fits it only when it has
a noise of its own, and otherwise leaves it out with a note (:mod:`frogsim.fit.spec`), so a
simulate folder's ``timeseries.csv`` is a trace as it is. The file is read by
:func:`frogsim.scenario.tables.read_table` (headers in any spelling frogsim wrote, every row as
many fields as the header).

Every refusal is a one-line :class:`frogsim.ScenarioError` naming the file and the column.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from frogsim.errors import UNKNOWN, ScenarioError
from frogsim.scenario.files import read_text
from frogsim.scenario.motion import output_times
from frogsim.scenario.schema import TEMPERATURE_MAX, TEMPERATURE_MIN
from frogsim.scenario.tables import model_columns, read_table, split_header
from frogsim.scenario.units import TemperatureDifference, parse_quantity, temperature_scale_offset

#: a sampling step larger than this many times the median step is a gap
GAP_FACTOR = 5.0
_GAUGE = ("gauge", "g")
_ABS = ("abs", "absolute", "a")
#: a trace may run on past the scenario's end, to at most this many times its duration
LENGTH_FACTOR = 2.0
#: time may end this much before the scenario's duration (rounding of a logger's clock) [s]
_TIME_SLACK = 1e-9


@dataclass(frozen=True)
class Trace:
    """One measured trace in SI.

    ``time`` [s], strictly increasing without gaps; ``signals``: signal name -> values (pressures in
    Pa absolute, temperatures in K); ``columns``: signal name -> its header as written; ``ignored``: headers left out.
    """
    path: str
    time: np.ndarray
    signals: dict
    columns: dict
    ignored: tuple = ()
    median_step: float = field(default=0.0)

    @property
    def name(self) -> str:
        return Path(self.path).name

    def resample(self, t: np.ndarray) -> dict:
        """Every signal linearly interpolated onto the times t [s] (which must lie inside the trace)."""
        return {s: np.interp(t, self.time, v) for s, v in self.signals.items()}


TEMPERATURE = " temperature"


def model_signals(scenario) -> list[str]:
    """The signals a scenario's pneumatic run computes (what a trace may hold): the pressures,
    then the air temperatures."""
    volumes = list(scenario.muscles) + ["source", "exhaust"]
    return [f"{m} pressure" for m in volumes] + [f"{m}{TEMPERATURE}" for m in volumes]


def signal_kind(signal: str) -> str:
    """The unit kind of a signal: "temperature" [K] or "pressure" [Pa absolute]."""
    return "temperature" if signal.endswith(TEMPERATURE) else "pressure"


def simulated(result, signal: str) -> np.ndarray:
    """A signal of a :class:`frogsim.Result` in SI (pressures in Pa absolute, temperatures in K)."""
    if signal == "source pressure":
        return result.source_pressure
    if signal == "exhaust pressure":
        return result.exhaust_pressure
    if signal.endswith(" pressure"):
        return result.muscle_pressure(signal[: -len(" pressure")])
    if signal.endswith(TEMPERATURE):
        return result.temperature(signal[: -len(TEMPERATURE)])
    raise KeyError(signal)


def numeric_column(df, fname: str, col: str) -> np.ndarray:
    """Column ``col`` of a table as finite floats, or a ScenarioError naming the file, the column
    and the first bad data row."""
    try:
        x = np.asarray(df[col].to_numpy(), dtype=float)
    except (TypeError, ValueError):
        cells = list(df[col])
        k = next(k for k, v in enumerate(cells) if not _is_number(v))
        raise _col_error(fname, col, f"holds values that are not numbers: {str(cells[k])[:40]!r} in data "
                                     f"row {k + 1}") from None
    bad = np.flatnonzero(~np.isfinite(x))
    if bad.size:
        raise _col_error(fname, col, f"missing or non-finite value (NaN) in data row {bad[0] + 1} "
                                     f"({bad.size} in all)")
    return x


def _is_number(v) -> bool:
    try:
        float(v)
        return True
    except (TypeError, ValueError):
        return False


def _col_error(fname: str, col: str, allowed: str) -> ScenarioError:
    return ScenarioError(f"{fname}: column {col!r}", UNKNOWN, allowed)


def _parse_header(fname: str, col: str) -> tuple[str, str]:
    name, unit = split_header(col)
    if not name or not unit:
        raise _col_error(fname, str(col), "the header has no unit: write it as 'signal [unit]', "
                                          "e.g. 'hip_left pressure [bar gauge]' or 'time [s]'")
    return name, unit


def _unit_scale(fname: str, col: str, unit: str, kind: str, what: str) -> float:
    try:
        return parse_quantity(f"1 {unit}", kind)
    except Exception:  # pint raises several error types for bad text or dimensions
        raise _col_error(fname, col, f"unit [{unit}] is not {what}") from None


def _pressure_unit(fname: str, col: str, unit: str, patm: float) -> tuple[float, float]:
    """(scale, offset) turning the column's numbers into Pa absolute."""
    words = unit.replace("(", " ").replace(")", " ").split()
    if len(words) < 2 or words[-1].lower() not in _GAUGE + _ABS:
        raise _col_error(fname, col, f"pressure unit [{unit}] must say gauge or abs, e.g. "
                                     "[bar gauge] or [kPa abs]")
    base = " ".join(words[:-1])
    scale = _unit_scale(fname, col, base, "pressure", "a pressure unit such as bar or kPa")
    return scale, (patm if words[-1].lower() in _GAUGE else 0.0)


def _temperature_unit(fname: str, col: str, unit: str) -> tuple[float, float]:
    """(scale, offset) turning the column's numbers into K."""
    words = unit.replace("(", " ").replace(")", " ").split()
    if words and words[-1].lower() in _GAUGE + _ABS:
        raise _col_error(fname, col, f"temperature unit [{unit}] takes no gauge or abs: write [K] or [degC]")
    try:
        return temperature_scale_offset(unit)
    except TemperatureDifference:
        raise _col_error(fname, col, f"unit [{unit}] is a temperature difference: a temperature column "
                                     "is written in [K], [degC] or [degF]") from None
    except Exception:  # pint raises several error types for bad text or dimensions
        raise _col_error(fname, col, f"unit [{unit}] is not a temperature unit such as K or degC") from None


def _check_temperatures(fname: str, col: str, kelvin: np.ndarray) -> None:
    """Refuse a temperature column with a value outside the gas temperatures the model holds
    (:data:`frogsim.scenario.schema.TEMPERATURE_MIN` to ``TEMPERATURE_MAX``), naming the first."""
    slack = 1e-9        # K: the rounding of an offset unit's sum (-123.15 degC is 149.99999999999997 K)
    bad = np.flatnonzero((kelvin < TEMPERATURE_MIN - slack) | (kelvin > TEMPERATURE_MAX + slack))
    if bad.size:
        k = bad[0]
        raise _col_error(fname, col, f"{kelvin[k]:g} K in data row {k + 1} ({bad.size} in all) is not an air "
                                     f"temperature the model holds (allowed: {TEMPERATURE_MIN:g} K to "
                                     f"{TEMPERATURE_MAX:g} K)")


def _read_table(path: Path, what: str = "trace"):
    import pandas as pd
    fname = path.name
    if path.suffix.lower() in (".parquet", ".pq"):
        if not path.is_file():
            read_text(path, f"{what} file")     # says why: not found, a directory, a device, ...
        try:
            import pyarrow  # noqa: F401
        except ImportError:
            raise ScenarioError(f"{what} {fname!r}", UNKNOWN,
                                "reading Parquet needs pyarrow (pip install pyarrow); or write the trace as CSV") from None
        try:
            return pd.read_parquet(path)
        except Exception as exc:  # pyarrow raises several types for a file that is not Parquet
            raise ScenarioError(f"{what} {fname!r}", UNKNOWN,
                                f"not a readable Parquet file ({type(exc).__name__})") from None
    return read_table(path, what, numbers=False)


def read_trace(path, scenario, ignore_columns=()) -> Trace:
    """Read and check a trace for a scenario (see module docstring); values in SI.

    Refused, each with a one-line ScenarioError naming file and column: a header without a unit, a
    unit of the wrong kind, a pressure neither gauge nor abs, a temperature with gauge or abs or in
    a difference unit, a temperature outside 150 K to 1000 K, a column for a signal the model does
    not have (all such columns listed), no time column, non-numeric or missing values (NaN), time
    not strictly increasing, a gap (a step more than 5 times the median step), a trace that does not
    cover the scenario's run from 0 to its duration, a trace running on past
    LENGTH_FACTOR times the duration.
    """
    path = Path(path)
    fname = path.name
    df = _read_table(path)
    if df.shape[0] < 2:
        raise ScenarioError(f"trace {fname!r}", UNKNOWN, "needs at least two rows of data")
    ignore = {str(c).strip() for c in ignore_columns}
    missing_ignored = sorted(ignore - {str(c).strip() for c in df.columns})
    if missing_ignored:
        raise ScenarioError(f"trace {fname!r}", UNKNOWN,
                            f"ignore_columns names columns it does not have: {', '.join(map(repr, missing_ignored))}")
    known = model_signals(scenario)
    others = {n for n, _ in model_columns(scenario.muscles)} - set(known)
    patm = scenario.air.atmospheric_pressure_abs
    time_col, cols, unknown, ignored = None, {}, [], []
    for col in df.columns:
        col = str(col)
        if col.strip() in ignore:
            ignored.append(col)
            continue
        name, unit = _parse_header(fname, col)
        if name.lower() == "time":
            if time_col is not None:
                raise _col_error(fname, col, f"a second time column (the first is {time_col[0]!r})")
            time_col = (col, _unit_scale(fname, col, unit, "time", "a time unit such as s or ms"))
            continue
        if name not in known:
            if name in others:              # a frogsim output the fit does not use (volume, valve, ...)
                ignored.append(col)
            else:
                unknown.append(col)
            continue
        if name in cols:
            raise _col_error(fname, col, f"signal {name!r} appears twice")
        if signal_kind(name) == "temperature":
            cols[name] = (col, *_temperature_unit(fname, col, unit))
        else:
            cols[name] = (col, *_pressure_unit(fname, col, unit, patm))
    if unknown:
        raise ScenarioError(f"trace {fname!r}", UNKNOWN,
                            f"columns for signals the model does not have: {', '.join(map(repr, unknown))} "
                            f"(it has: {', '.join(known)}); leave them out with ignore_columns = [...]")
    if time_col is None:
        raise ScenarioError(f"trace {fname!r}", UNKNOWN, "no time column: name one 'time [s]'")
    if not cols:
        raise ScenarioError(f"trace {fname!r}", UNKNOWN, f"no signal to fit (the model has: {', '.join(known)})")

    def numbers(col: str) -> np.ndarray:
        return numeric_column(df, fname, col)

    t = numbers(time_col[0]) * time_col[1]
    dt = np.diff(t)
    back = np.flatnonzero(dt <= 0)
    if back.size:
        k = back[0]
        raise _col_error(fname, time_col[0], f"time is not strictly increasing at data row {k + 2} "
                                             f"({t[k]:g} s, then {t[k + 1]:g} s)")
    med = float(np.median(dt))
    gaps = np.flatnonzero(dt > GAP_FACTOR * med)
    if gaps.size:
        k = gaps[0]
        raise _col_error(fname, time_col[0], f"a gap of {dt[k]:g} s after {t[k]:g} s (more than "
                                             f"{GAP_FACTOR:g} x the median step {med:g} s)")
    if t[0] > _TIME_SLACK:
        raise _col_error(fname, time_col[0], f"starts at {t[0]:g} s: it must cover the run from 0 s")
    if t[-1] < scenario.duration - _TIME_SLACK * max(1.0, scenario.duration):
        raise _col_error(fname, time_col[0], f"ends at {t[-1]:g} s, before the end of the scenario "
                                             f"({scenario.duration:g} s)")
    if t[-1] > LENGTH_FACTOR * scenario.duration + med:
        raise _col_error(fname, time_col[0], f"ends at {t[-1]:g} s, more than {LENGTH_FACTOR:g} x the "
                                             f"scenario's {scenario.duration:g} s: a trace of another run, "
                                             "or a wrong time unit (ms written as s)?")
    signals = {name: numbers(col) * scale + offset for name, (col, scale, offset) in cols.items()}
    for name, x in signals.items():
        if signal_kind(name) == "temperature":
            _check_temperatures(fname, cols[name][0], x)
    return Trace(path=str(path), time=t, signals=signals, columns={n: c[0] for n, c in cols.items()},
                 ignored=tuple(ignored), median_step=med)


def model_grid(scenario) -> np.ndarray:
    """The scenario's output times [s] (those of its Result)."""
    return output_times(scenario.duration, scenario.output_interval)


def information_factor(trace: Trace, scenario) -> float:
    """The fraction of a model-grid point's worth of independent data each resampled point holds.

    A trace sampled more coarsely than the model's output grid gives fewer independent samples than
    grid points once interpolated; each grid residual is weighted by sqrt of this factor so that
    the fit counts the trace's own number of samples (never more), and its intervals stay honest.
    """
    return min(1.0, scenario.output_interval / trace.median_step) if trace.median_step > 0 else 1.0
