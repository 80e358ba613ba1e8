"""``frogsim compare``: one signal of several runs in one figure and one CSV.

An input is a folder written by ``frogsim simulate`` or ``frogsim swim`` (its ``timeseries.csv``
is read, nothing is run), a CSV table with a ``time [s]`` column (a measured trace, another
compare's CSV), or a scenario (a TOML path or a shipped name, run here). A signal is named as a
reader would say it: ``"hip_left pressure"``, ``"source pressure"``, ``"knee_right charge flow"``,
``"pump on"``; a column header (``hip_left pressure [bar gauge]``, or the older
``hip_left_pressure_bar_gauge``) works too, and underscores and spaces are interchangeable.
``RUN:SIGNAL`` takes that run's own signal, so runs whose muscles are named differently overlay
(``one-hip:"hip pressure" paper-cycle:"hip_left pressure"``); ``--signal`` names it for the
inputs without one. Values are those of ``timeseries.csv`` (display units: bar gauge, L/min and L
at standard state, cm^3, mm). Headers follow :mod:`frogsim.scenario.tables`.

Outputs (the folder rules of :mod:`frogsim.io.outputs`): ``<signal>.csv`` with a time column and
one column per run, units in the header (``time [s]``, ``fast [bar gauge]``); where the runs' time
grids differ the rows are the union of their times and a run has empty cells where it has no
sample. ``<signal>.png``: the runs overlaid, labelled by run name (a folder's name, a file's stem,
a shipped scenario's name; repeated names get " (2)", " (3)").

Every input and the signal are checked before anything runs or is written (ScenarioError): a
table is read by :func:`frogsim.scenario.tables.read_table` (a row with a field too many or too
few, a cell that is no number, a file ending mid-line are refused), its time must be in seconds
and strictly increasing, and a run folder's ``timeseries.csv`` must be the file its manifest
recorded (not changed or truncated since), with every cell filled, up to the duration its
``summary.json`` records.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from frogsim.errors import ScenarioError
from frogsim.scenario.tables import header, model_columns, read_table, split_header, unit_headers

TIME = header("time", "s")
CSV_FORMAT = "%.8g"             # frogsim._files.write_csv
WHERE = "RUN_OR_SCENARIO"


def _norm(text: str) -> str:
    return " ".join(str(text).replace("_", " ").split()).lower()


def signal_of(column: str) -> tuple[str, str]:
    """(signal name, unit) of a table column in any spelling frogsim wrote:
    "hip_left_pressure_bar_gauge" and "hip_left pressure [bar gauge]" -> ("hip_left pressure",
    "bar gauge"); a column of no known form is its own name, no unit."""
    return split_header(column)


@dataclass
class Signal:
    name: str
    column: str
    unit: str


def _is_time(column: str) -> bool:
    return _norm(split_header(column)[0]) == "time"


def signals(columns) -> dict[str, Signal]:
    """Normalised name -> Signal of every column but time (the signal name, the header as written
    and the header in the older spelling all lead to it)."""
    out = {}
    for c in columns:
        if _is_time(c):
            continue
        name, unit = signal_of(c)
        sig = Signal(name, c, unit)
        out.setdefault(_norm(name), sig)
        out.setdefault(_norm(c), sig)
    return out


def scenario_columns(scenario) -> list[str]:
    """The column headers ``frogsim simulate`` writes for a scenario, known before it runs."""
    return [header(n, u) for n, u in model_columns(scenario.muscles)]


@dataclass
class Run:
    """One input: a run folder or CSV table (read), or a scenario (run by :func:`run_inputs`)."""
    given: str
    label: str
    folder: Path | None = None
    scenario: object = None
    table: object = None                       # pandas DataFrame once read or run
    columns: list = field(default_factory=list)
    signal_name: str | None = None             # RUN:SIGNAL's own signal, else --signal
    file: Path | None = None                   # the CSV read

    def lookup(self, name: str) -> Signal | None:
        """The column for a signal name (or a header in any spelling), None if the run has none."""
        table = signals(self.columns)
        return table.get(_norm(name)) or table.get(_norm(split_header(name)[0]))

    def signal(self, _name: str | None = None) -> Signal | None:
        """The run's signal: its own RUN:SIGNAL, else --signal (set by :func:`prepare`)."""
        return self.lookup(self.signal_name) if self.signal_name is not None else None

    @property
    def time(self) -> str:
        return next(c for c in self.columns if _is_time(c))


def _exists(text: str) -> bool:
    from frogsim.scenario.load import scenario_names
    try:
        return Path(text).exists() or text in scenario_names()
    except (OSError, ValueError):
        return False


def split_input(text: str) -> tuple[str, str | None]:
    """(input, its own signal or None) of a RUN[:SIGNAL] argument: the whole text if it names an
    existing path or shipped scenario, else split at its last ':'."""
    if not _exists(text) and ":" in text:
        run, sig = text.rsplit(":", 1)
        if run and _exists(run):
            if not sig.strip():
                raise ScenarioError(WHERE, text, "names no signal after ':' (RUN:SIGNAL, e.g. "
                                                 "runs/a:'hip_left pressure')")
            return run, sig
    return text, None


def _read_run_table(text: str, csv: Path, manifest: Path | None):
    """A run's table, checked: its manifest's record of it (when there is one) matches, every row
    complete, every cell a number, time [s] strictly increasing."""
    from frogsim.io.outputs import read_manifest
    if manifest is not None:
        m = read_manifest(manifest.parent)
        rec = next((f for f in (m or {}).get("files", []) if isinstance(f, dict) and f.get("name") == csv.name),
                   None)
        if rec is not None:
            from frogsim.sweep.spec import file_sha256
            if csv.stat().st_size != rec.get("bytes") or file_sha256(csv) != rec.get("sha256"):
                raise ScenarioError(WHERE, text, f"{csv.name} is not the file `frogsim {m['command']}` wrote "
                                                 f"(its size or SHA-256 differs from manifest.json): changed "
                                                 "or truncated since")
    table = read_table(csv, "run table")
    from frogsim.scenario.files import read_text
    if not read_text(csv, "run table file").endswith("\n"):
        raise ScenarioError(WHERE, text, f"{csv.name} ends in the middle of a line: a truncated file")
    times = [c for c in table.columns if _is_time(c)]
    if not times:
        raise ScenarioError(WHERE, text, f"{csv.name} has no time column 'time [s]'")
    if len(times) > 1:
        raise ScenarioError(WHERE, text, f"{csv.name} has two time columns ({times[0]!r}, {times[1]!r})")
    unit = split_header(times[0])[1]
    if unit != "s":
        raise ScenarioError(WHERE, text, f"{csv.name}: time column {times[0]!r} must be in seconds, 'time [s]'")
    t = table[times[0]].to_numpy(float)
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ScenarioError(WHERE, text, f"{csv.name}: time must be finite numbers, strictly increasing")
    if manifest is not None:                # a run folder: every cell written, up to the run's end
        empty = np.flatnonzero(table.isna().to_numpy().any(axis=1))
        if empty.size:
            raise ScenarioError(WHERE, text, f"{csv.name}: data row {empty[0] + 1} has an empty cell: not as "
                                             "frogsim wrote it")
        end = _summary_duration(manifest.parent)
        if end is not None and abs(t[-1] - end) > 1e-6 * max(1.0, end):
            raise ScenarioError(WHERE, text, f"{csv.name} ends at {t[-1]:g} s but the run's summary.json says "
                                             f"{end:g} s: a truncated file")
    return table


def _summary_duration(folder: Path) -> float | None:
    """The run's duration [s] as its summary.json records it, if it does."""
    import json
    try:
        value = json.loads((folder / "summary.json").read_text()).get("duration_s")
    except (OSError, ValueError, AttributeError):
        return None
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None


def open_input(text: str, signal: str | None = None) -> Run:
    """A Run for a run folder, a CSV table, or a loaded (not yet run) scenario; ScenarioError
    (field RUN_OR_SCENARIO) otherwise."""
    from frogsim.scenario.load import load_scenario, scenario_names
    path = Path(text)
    if path.is_dir():
        csv = path / "timeseries.csv"
        if not csv.is_file():
            raise ScenarioError(WHERE, text, "is a folder without timeseries.csv: expected a folder written by "
                                             "`frogsim simulate` or `frogsim swim`, a CSV table or a scenario file")
        table = _read_run_table(text, csv, path / "manifest.json")
        return Run(text, path.resolve().name, folder=path, table=table, columns=list(table.columns),
                   signal_name=signal, file=csv)
    if path.suffix.lower() == ".csv":
        table = _read_run_table(text, path, None)
        return Run(text, path.stem, table=table, columns=list(table.columns), signal_name=signal, file=path)
    if not path.exists() and text not in scenario_names():
        raise ScenarioError(WHERE, text, f"no such folder or file: expected a folder written by `frogsim simulate`, "
                                         f"a CSV table, a scenario file, or a shipped scenario "
                                         f"({', '.join(scenario_names())})")
    scenario = load_scenario(text)
    label = path.stem if path.is_file() else text           # a file's stem, a shipped scenario's name
    return Run(text, label, scenario=scenario, columns=scenario_columns(scenario), signal_name=signal)


def prepare(inputs: list[str], signal: str | None) -> list[Run]:
    """Open every input and check its signal (its own RUN:SIGNAL, else ``signal``) exists in it and
    has the same unit in every run (nothing is run yet)."""
    if not inputs:
        raise ScenarioError(WHERE, "", "give at least one run folder or scenario")
    if signal is not None and (not isinstance(signal, str) or not signal.strip()):
        raise ScenarioError("--signal", signal, "expected a signal name such as 'hip_left pressure'")
    runs = [open_input(*split_input(text)) for text in inputs]
    seen = {"time": 1}                              # "time" is the table's time column
    for r in runs:                                  # distinct legend labels
        n = seen[r.label] = seen.get(r.label, 0) + 1
        if n > 1:
            r.label = f"{r.label} ({n})"
    for r in runs:
        if r.signal_name is None:
            if signal is None:
                raise ScenarioError("--signal", "(missing)", f"{r.given!r} names no signal: give --signal NAME, "
                                                             f"or write it RUN:SIGNAL")
            r.signal_name = signal
    for r in runs:
        # a bare muscle name means its pressure: one:hip overlays with two:hip_left
        if r.signal() is None and r.lookup(f"{r.signal_name} pressure") is not None:
            r.signal_name = f"{r.signal_name} pressure"
    for r in runs:
        if r.signal() is None:
            own = r.signal_name != signal
            names = list(dict.fromkeys(signal_of(c)[0] for c in r.columns if not _is_time(c)))
            common = [n for n in names if all(x.lookup(n) is not None for x in runs)] if not own else names
            field_ = f"{r.given}:SIGNAL" if own else "--signal"
            raise ScenarioError(field_, r.signal_name, f"not a signal of {r.label}; available"
                                                       f"{' in every run' if len(runs) > 1 and not own else ''}: "
                                                       f"{', '.join(common)}")
    units = {r.signal().unit for r in runs}
    if len(units) > 1:
        raise ScenarioError("--signal", signal or runs[0].signal_name,
                            f"has different units in these runs ({', '.join(sorted(units))})")
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
            # the engine's bar on stderr once a run takes 2 s, unless progress is off (--quiet)
            df = unit_headers(simulate(r.scenario, progress=progress is not None).to_dataframe(units="display"))
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
    merged = None
    same_grid = all(len(r.table) == len(runs[0].table) and
                    np.array_equal(r.table[r.time].to_numpy(), runs[0].table[runs[0].time].to_numpy()) for r in runs)
    for r in runs:
        col, name = r.signal(signal).column, header(r.label, sig.unit)
        part = pd.DataFrame({TIME: r.table[r.time].to_numpy(float), name: r.table[col].to_numpy(float)})
        if merged is None:
            merged = part
        elif same_grid:
            merged[name] = part[name].to_numpy()
        else:
            merged = merged.merge(part, on=TIME, how="outer")
    return merged.sort_values(TIME, kind="stable").reset_index(drop=True)


def draw(runs: list[Run], signal: str, path: str) -> None:
    """The runs' signal against time, one line per run, labelled by run name."""
    from frogsim._plotting import figure, save
    sig = runs[0].signal(signal)
    fig, ax = figure(1, 1, width=8.0, height=4.6)
    a = ax[0, 0]
    for k, r in enumerate(runs):
        s = r.signal(signal)
        a.plot(r.table[r.time].to_numpy(float), r.table[s.column].to_numpy(float), lw=1.6 if k == 0 else 1.3,
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
        elif r.file is not None:
            files += describe_inputs([(f"{r.label}: table", r.file)])
        else:
            files += [{**f, "role": f"{r.label}: {f['role']}"} for f in scenario_inputs(r.scenario, r.given)]
    return scenario_record("compare " + ", ".join(r.label for r in runs), files)
