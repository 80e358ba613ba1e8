"""``frogsim compare``: one signal of several runs in one figure and one CSV.

An input is a folder written by ``frogsim simulate`` (its ``timeseries.csv`` is read, nothing is
run) or a scenario (a TOML path or a shipped name, run here). A signal is named as a reader would
say it: ``"hip_left pressure"``, ``"source pressure"``, ``"knee_right charge flow"``,
``"pump on"``; the column name of timeseries.csv (``hip_left_pressure_bar_gauge``) works too, and
underscores and spaces are interchangeable. Values are those of ``timeseries.csv`` (display
units: bar gauge, L/min and L at standard state, cm^3, mm).

Outputs (the folder rules of :mod:`frogsim.io.outputs`): ``<signal>.csv`` with a time column and
one column per run, units in the header (``time [s]``, ``fast [bar (gauge)]``); where the runs'
time grids differ the rows are the union of their times and a run has empty cells where it has no
sample. ``<signal>.png``: the runs overlaid, labelled by run name (a folder's name, a scenario
file's stem, a shipped scenario's name; repeated names get " (2)", " (3)").

Every input and the signal are checked before anything runs or is written (ScenarioError).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from frogsim.errors import ScenarioError

TIME = "time_s"
CSV_FORMAT = "%.8g"             # frogsim._files.write_csv
#: column suffix of timeseries.csv -> (signal word, unit); longest first
SUFFIXES = (
    ("_discharge_flow_L_per_min_std", "discharge flow", "L/min (standard)"),
    ("_charge_flow_L_per_min_std", "charge flow", "L/min (standard)"),
    ("_angular_velocity_deg_per_s", "angular velocity", "deg/s"),
    ("_flow_L_per_min_std", "flow", "L/min (standard)"),
    ("_pressure_bar_gauge", "pressure", "bar (gauge)"),
    ("_pressure_Pa_abs", "pressure (absolute)", "Pa"),
    ("_discharge_valve", "discharge valve", "1 = open"),
    ("_charge_valve", "charge valve", "1 = open"),
    ("_temperature_K", "temperature", "K"),
    ("_charged_L_std", "charged air", "L (standard)"),
    ("_volume_cm3", "volume", "cm^3"),
    ("_length_mm", "length", "mm"),
    ("_velocity_m_per_s", "velocity", "m/s"),
    ("_angle_deg", "angle", "deg"),
    ("_moved_L_std", "moved air", "L (standard)"),
    ("_L_std", "", "L (standard)"),
    ("_distance_m", "distance", "m"),
    ("_deg", "", "deg"),
    ("_N", "", "N"),
    ("_kg", "", "kg"),
    ("_m", "", "m"),
    ("_on", "on", "1 = running"),
)
#: the display columns frogsim simulate writes (engine.result.Result.to_dataframe(units="display"))
_CHAMBER = ("_pressure_bar_gauge", "_temperature_K")
_MUSCLE = ("_pressure_bar_gauge", "_temperature_K", "_volume_cm3", "_length_mm", "_charge_flow_L_per_min_std",
           "_discharge_flow_L_per_min_std", "_charged_L_std", "_charge_valve", "_discharge_valve")


def _norm(text: str) -> str:
    return " ".join(str(text).replace("_", " ").split()).lower()


def signal_of(column: str) -> tuple[str, str]:
    """(signal name, unit) of a timeseries.csv column: "hip_left_pressure_bar_gauge" ->
    ("hip_left pressure", "bar (gauge)"); a column of no known form is its own name, no unit."""
    for suffix, word, unit in SUFFIXES:
        if column.endswith(suffix) and len(column) > len(suffix):
            who = column[: -len(suffix)]
            return (f"{who} {word}" if word else who), unit
    return column, ""


@dataclass
class Signal:
    name: str
    column: str
    unit: str


def signals(columns) -> dict[str, Signal]:
    """Normalised name -> Signal of every column but time (both the signal name and the column
    name lead to it)."""
    out = {}
    for c in columns:
        if c == TIME:
            continue
        name, unit = signal_of(c)
        sig = Signal(name, c, unit)
        out.setdefault(_norm(name), sig)
        out.setdefault(_norm(c), sig)
    return out


def scenario_columns(scenario) -> list[str]:
    """The columns ``frogsim simulate`` writes for a scenario, known before it runs."""
    cols = [TIME]
    for who in ("source", "exhaust"):
        cols += [who + s for s in _CHAMBER]
    cols += ["pump_on", "pump_flow_L_per_min_std"]
    for m in scenario.muscles:
        cols += [m + s for s in _MUSCLE]
    return cols


@dataclass
class Run:
    """One input: a simulate folder (its table read) or a scenario (run by :func:`load`)."""
    given: str
    label: str
    folder: Path | None = None
    scenario: object = None
    table: object = None                       # pandas DataFrame once read or run
    columns: list = field(default_factory=list)

    def signal(self, name: str) -> Signal | None:
        return signals(self.columns).get(_norm(name))


def open_input(text: str) -> Run:
    """A Run for a folder written by frogsim simulate, or a loaded (not yet run) scenario;
    ScenarioError (field RUN_OR_SCENARIO) otherwise."""
    import pandas as pd
    from frogsim.scenario.load import SCENARIOS_DIR, load_scenario
    path = Path(text)
    where = "RUN_OR_SCENARIO"
    if path.is_dir():
        csv = path / "timeseries.csv"
        if not csv.is_file():
            raise ScenarioError(where, text, "is a folder without timeseries.csv: expected a folder written by "
                                             "`frogsim simulate` or a scenario file")
        try:
            table = pd.read_csv(csv)
        except Exception as exc:  # pandas raises many parser errors
            raise ScenarioError(where, text, f"timeseries.csv is not a readable CSV ({type(exc).__name__})") from None
        if TIME not in table.columns or len(table) == 0:
            raise ScenarioError(where, text, f"timeseries.csv has no {TIME} column (or no rows): not written by "
                                             "`frogsim simulate`")
        return Run(text, path.resolve().name, folder=path, table=table, columns=list(table.columns))
    if not path.is_file() and not (SCENARIOS_DIR / f"{text}.toml").is_file():
        shipped = ", ".join(sorted(p.stem for p in SCENARIOS_DIR.glob("*.toml")))
        raise ScenarioError(where, text, f"no such folder or file: expected a folder written by `frogsim simulate`, "
                                         f"a scenario file, or a shipped scenario ({shipped})")
    scenario = load_scenario(text)
    label = path.stem if path.is_file() else text           # a file's stem, a shipped scenario's name
    return Run(text, label, scenario=scenario, columns=scenario_columns(scenario))


def prepare(inputs: list[str], signal: str) -> list[Run]:
    """Open every input and check the signal exists in each (nothing is run yet)."""
    if not inputs:
        raise ScenarioError("RUN_OR_SCENARIO", "", "give at least one run folder or scenario")
    runs = [open_input(text) for text in inputs]
    seen = {}
    for r in runs:                                  # distinct legend labels
        n = seen[r.label] = seen.get(r.label, 0) + 1
        if n > 1:
            r.label = f"{r.label} ({n})"
    if not isinstance(signal, str) or not signal.strip():
        raise ScenarioError("--signal", signal, "expected a signal name such as 'hip_left pressure'")
    for r in runs:
        if r.signal(signal) is None:
            common = [s for s in dict.fromkeys(signal_of(c)[0] for c in r.columns if c != TIME)
                      if all(x.signal(s) is not None for x in runs)]
            raise ScenarioError("--signal", signal, f"not a signal of {r.label}; available"
                                                    f"{' in every run' if len(runs) > 1 else ''}: {', '.join(common)}")
    units = {r.signal(signal).unit for r in runs}
    if len(units) > 1:
        raise ScenarioError("--signal", signal, f"has different units in these runs ({', '.join(sorted(units))})")
    return runs


def run_inputs(runs: list[Run], progress=None) -> None:
    """Simulate the scenario inputs (their tables as frogsim simulate writes them)."""
    import io

    import pandas as pd
    from frogsim.engine.pneumatic import simulate
    for r in runs:
        if r.table is None:
            if progress:
                progress(f"simulating {r.label!r} ...")
            df = simulate(r.scenario).to_dataframe(units="display")
            # as frogsim simulate writes it (8 significant digits), so a scenario and its run folder
            # give the same numbers and share one time column
            r.table = pd.read_csv(io.StringIO(df.to_csv(index=False, float_format=CSV_FORMAT)))
            r.columns = list(r.table.columns)


def slug(signal: str) -> str:
    """A file name stem for a signal ("hip_left pressure" -> "hip_left-pressure")."""
    s = re.sub(r"[^A-Za-z0-9_.]+", "-", signal.strip()).strip("-.")
    return s or "signal"


def table(runs: list[Run], signal: str):
    """The comparison table: time and one column per run, units in the header."""
    import pandas as pd
    sig = runs[0].signal(signal)
    unit = f" [{sig.unit}]" if sig.unit else ""
    merged = None
    same_grid = all(len(r.table) == len(runs[0].table) and
                    np.array_equal(r.table[TIME].to_numpy(), runs[0].table[TIME].to_numpy()) for r in runs)
    for r in runs:
        col = r.signal(signal).column
        part = pd.DataFrame({"time [s]": r.table[TIME].to_numpy(float), f"{r.label}{unit}": r.table[col].to_numpy(float)})
        if merged is None:
            merged = part
        elif same_grid:
            merged[f"{r.label}{unit}"] = part[f"{r.label}{unit}"].to_numpy()
        else:
            merged = merged.merge(part, on="time [s]", how="outer")
    return merged.sort_values("time [s]", kind="stable").reset_index(drop=True)


def draw(runs: list[Run], signal: str, path: str) -> None:
    """The runs' signal against time, one line per run, labelled by run name."""
    from frogsim._plotting import figure, save
    sig = runs[0].signal(signal)
    fig, ax = figure(1, 1, width=8.0, height=4.6)
    a = ax[0, 0]
    for k, r in enumerate(runs):
        s = r.signal(signal)
        a.plot(r.table[TIME].to_numpy(float), r.table[s.column].to_numpy(float), lw=1.6 if k == 0 else 1.3,
               ls=("-", "--", "-.", ":")[k // 10 % 4], label=r.label)
    a.set_xlabel("time [s]")
    a.set_ylabel(f"{sig.name} [{sig.unit}]" if sig.unit else sig.name)
    a.set_title(f"{sig.name}: {len(runs)} run{'s' if len(runs) != 1 else ''}")
    a.legend(fontsize=8, loc="best")
    save(fig, path, "frogsim compare; " + ", ".join(f"{r.label} = {r.given}" for r in runs)[:160])


def write(runs: list[Run], signal: str, out) -> dict[str, Path]:
    """Write <signal>.csv and <signal>.png into out; returns {"csv": path, "figure": path}."""
    from frogsim._files import write_csv, write_figure
    out = Path(out)
    stem = slug(runs[0].signal(signal).name)
    csv, png = out / f"{stem}.csv", out / f"{stem}.png"
    write_csv(csv, table(runs, signal))
    write_figure(png, lambda p: draw(runs, signal, p))
    return {"csv": csv, "figure": png}


def file_names(runs: list[Run], signal: str) -> list[str]:
    stem = slug(runs[0].signal(signal).name)
    return [f"{stem}.csv", f"{stem}.png"]


def inputs_record(runs: list[Run]) -> dict:
    """The manifest's "scenario" entry: every run's input files (a folder's timeseries.csv, a
    scenario's files), with one SHA-256 over them."""
    from frogsim.io.outputs import scenario_inputs, scenario_record
    from frogsim.sweep.spec import describe_inputs
    files = []
    for r in runs:
        if r.folder is not None:
            files += describe_inputs([(f"{r.label}: run timeseries.csv", r.folder / "timeseries.csv")])
            manifest = r.folder / "manifest.json"
            if manifest.is_file():
                files += describe_inputs([(f"{r.label}: run manifest.json", manifest)])
        else:
            files += [{**f, "role": f"{r.label}: {f['role']}"} for f in scenario_inputs(r.scenario, r.given)]
    return scenario_record("compare " + ", ".join(r.label for r in runs), files)
