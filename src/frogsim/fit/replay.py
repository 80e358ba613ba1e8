"""An experiment driven by the valve commands a board issued: an open-loop replay.

A board's log of format 3 carries every valve command it issued (each record's valve histories,
:func:`frogsim.export.serial_log.commands`); `frogsim sil` and `frogsim log` write them as
``commands.csv`` beside ``serial.csv``::

    time [s],"hip command [1 = charge, 0 = hold, -1 = vent]"
    0,1
    0.049,0

one row where a command changes (a command holds until the next row). An experiment with
``commands = "commands.csv"`` runs its scenario with those commands as each muscle's program (one
step per change) and without the scenario's controllers and ``[firmware]`` section. Each step
comes at its sample's time k / rate plus the board's delay from the sample to the valve write
(``command_delay``: the conversions and the law run first; sample 0's is longer, the ADC's first
conversion taking 25 clocks instead of 13), and the model's valve schedule adds each valve's dead
time, as it does to a compiled law's command. So that a step can fall between two samples, the
replay's program runs at a multiple of the controller rate (:data:`FINE_RATE` at most: a step's
time is good to 1/(that rate), 20 µs at 1 kHz). A parameter change then moves the pressures
only, not the switching times: the fit's cost is smooth in the plant's parameters, where
re-running the closed loop makes it a staircase (a rise ends one sample earlier or later).

Refused in one line naming the file and column: a column that is no muscle of the scenario, a
command other than -1, 0, 1, times not increasing or off the controller's sample grid, a
controller left driving a muscle the file does not command.
"""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np

from frogsim.errors import ScenarioError
from frogsim.scenario.tables import read_table, split_header

COMMAND_UNIT = "1 = charge, 0 = hold, -1 = vent"
STATE = {1: "charge", 0: "hold", -1: "vent"}
#: [Hz] the highest rate the replay's program steps are placed on (a whole multiple of the rate)
FINE_RATE = 50e3


def read_commands(path, scenario) -> dict:
    """muscle -> [(time [s], state)], one step per change of a commands file (module docstring)."""
    df = read_table(Path(path), "commands file")
    where = f"commands file {Path(path).name}"
    cols = list(df.columns)
    name, unit = split_header(cols[0]) if cols else ("", "")
    if not cols or name != "time" or unit != "s":
        raise ScenarioError(f"{where}: {cols[0] if cols else '(no column)'}", "(first column)",
                            "must be 'time [s]': the sample times k / rate")
    t = df[cols[0]].to_numpy(dtype=float)
    rate = float(scenario.controller.rate)
    if len(t) < 1 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ScenarioError(f"{where}: time [s]", "(not increasing)", "must increase from row to row")
    k = np.rint(t * rate)
    if np.any(np.abs(t * rate - k) > 1e-6):
        bad = t[np.argmax(np.abs(t * rate - k))]
        raise ScenarioError(f"{where}: time [s]", f"{bad!r}", f"must lie on the controller's sample grid (1/{rate:g} s): "
                                                              "the log of a board at another rate")
    out = {}
    for col in cols[1:]:
        name, unit = split_header(col)
        muscle = name[:-len(" command")] if name.endswith(" command") else None
        if muscle not in scenario.muscles or unit != COMMAND_UNIT:
            raise ScenarioError(f"{where}: {col}", "(column)", f"must be '<muscle> command [{COMMAND_UNIT}]' "
                                                               f"for a muscle of the scenario ({', '.join(scenario.muscles)})")
        v = df[col].to_numpy(dtype=float)
        if np.any(np.isnan(v)):
            raise ScenarioError(f"{where}: {col}", f"(empty from {float(t[np.argmax(np.isnan(v))]):g} s)",
                                "the board's log lost valve commands there (more switchings than a record's "
                                "event slots): a replay needs every command; log at a higher rate or baud rate")
        if not np.all(np.isin(v, (-1.0, 0.0, 1.0))):
            bad = v[~np.isin(v, (-1.0, 0.0, 1.0))][0]
            raise ScenarioError(f"{where}: {col}", f"{bad!r}", "must be -1 (vent), 0 (hold) or 1 (charge)")
        steps, last = [], None
        for ti, vi in zip(k / rate, v.astype(int)):
            if vi != last:
                steps.append((float(ti), STATE[vi]))
                last = vi
        out[muscle] = steps
    if not out:
        raise ScenarioError(f"{where}", "(no command column)", f"needs a '<muscle> command [{COMMAND_UNIT}]' column")
    return out


def replayed(scenario, path, delay: tuple = (0.0, 0.0)):
    """``scenario`` with the commands of ``path`` as its muscles' programs, each step ``delay``
    [s] after its sample (sample 0's, the later samples'), its controllers and ``[firmware]``
    section left out (module docstring)."""
    from frogsim.scenario.load import scenario_from_raw
    steps = read_commands(path, scenario)
    for cname, c in scenario.controllers.items():
        left = [m for m in c.driven() if m not in steps]
        if left:
            raise ScenarioError(f"commands file {Path(path).name}", "(muscles)",
                                f"has no column for {left[0]!r}, which controller {cname!r} drives: the replay "
                                "takes every controlled muscle's commands from the log")
    rate = float(scenario.controller.rate)
    fine = rate * max(1, int(FINE_RATE // rate))
    raw = copy.deepcopy(scenario.raw)
    raw.pop("controllers", None)
    raw.pop("firmware", None)
    raw["controller"] = dict(raw.get("controller", {}), rate=f"{fine!r} Hz")
    for m, st in steps.items():
        at = [t + (delay[0] if t == 0.0 else delay[1]) for t, _ in st]
        # on the fine grid, rounded to its nearest point (a step is issued at the first point at or after it)
        at = [round(a * fine) / fine for a in at]
        raw["muscles"][m]["program"] = {"steps": [{"at": f"{a!r} s", "state": s} for a, (_, s) in zip(at, st)]}
    return scenario_from_raw(raw, scenario.base_dir)
