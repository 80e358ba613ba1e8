"""A gait as data: the phase timing of the valves and the palms over one stroke period.

A scenario's ``[gait]`` table says, within one period, when each muscle group's valves charge,
vent or hold, and when the palms open and fold::

    [gait]
    period = "2 s"
    cycles = 10
    drive   = [ { at = "0 s", state = "charge" }, { at = "1 s", state = "vent" } ]    # extensors
    recover = [ { at = "0 s", state = "vent" },   { at = "1 s", state = "charge" } ]  # flexors
    palms   = [ { at = "0 s", state = "open" },   { at = "1 s", state = "fold" } ]

    [gait.joints.knee]            # optional: one joint's own phases (e.g. a later knee)
    drive = [ { at = "0.05 s", state = "charge" }, { at = "1 s", state = "vent" } ]

The default above is the paper's open-loop timing (Sec. 4.1: pressurised for one second, released
for one second) with the palms synchronised: open for the power stroke, folded for the recovery.
Both legs move together. :func:`muscle_programs` turns the gait into one
:class:`frogsim.scenario.schema.Program` per muscle over all cycles; the valve dead time and
the controller's sampling are applied downstream exactly as for any program
(:func:`frogsim.circuit.model.build_schedule`). :func:`palm_commands` gives the steering motors'
command times, sampled on the same controller grid.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from frogsim.scenario.motion import command_time
from frogsim.scenario.fields import parse_field, unknown_key_error, unwrap
from frogsim.scenario.schema import VALVE_STATES, Program
from frogsim.errors import MISSING, ScenarioError

PALM_STATES = {"open": 1.0, "fold": 0.0}
GROUPS = ("drive", "recover")


def _steps(raw, path: str, states, period: float) -> tuple:
    if not isinstance(raw, list) or not raw:
        raise ScenarioError(path, raw, 'expected a list of steps such as [ { at = "0 s", state = "..." } ]')
    out = []
    for k, st in enumerate(raw):
        sp = f"{path}[{k}]"
        if not isinstance(st, dict) or set(st) != {"at", "state"}:
            raise ScenarioError(sp, st, f'expected {{ at = "<time>", state = "{"|".join(states)}" }}')
        t = parse_field(st["at"], dict(kind="time", ge=0.0, display="s"), f"{sp}.at")
        if t >= period:
            raise ScenarioError(f"{sp}.at", st["at"], f"must be within the period ({period:g} s)")
        state = parse_field(st["state"], dict(choices=tuple(states)), f"{sp}.state")
        if out and t <= out[-1][0]:
            raise ScenarioError(f"{sp}.at", st["at"], "step times must increase")
        out.append((t, state))
    return tuple(out)


@dataclass(frozen=True)
class Gait:
    """Phase timing over one period [s]: valve steps per joint and group, palm steps."""
    period: float
    cycles: int
    joints: dict        # joint -> {"drive": steps, "recover": steps}; steps = ((t, state), ...)
    palms: tuple

    @classmethod
    def from_raw(cls, raw, joints=("hip", "knee", "ankle"), cycles: int | None = None,
                 path: str = "gait") -> "Gait":
        """Validate a ``[gait]`` table; ``cycles`` (e.g. from the command line) overrides its own."""
        if not isinstance(raw, dict):
            raise ScenarioError(path, raw, "expected a [gait] table")
        allowed = {"period", "cycles", "drive", "recover", "palms", "joints"}
        for key in raw:
            if key not in allowed:
                raise unknown_key_error(path, key, allowed)
        for key in ("period", "drive", "palms"):
            if key not in raw:
                raise ScenarioError(f"{path}.{key}", MISSING, "required setting is missing")
        period = parse_field(raw["period"], dict(kind="time", gt=0.0, le=1e4, display="s"),
                             f"{path}.period")
        if cycles is None:
            cycles = parse_field(raw.get("cycles", 1), dict(integer=True, ge=1, le=100000),
                                 f"{path}.cycles")
        elif isinstance(cycles, bool) or not isinstance(cycles, int) or not 1 <= cycles <= 100000:
            raise ScenarioError("cycles", cycles, "must be a whole number from 1 to 100000")
        common = {"drive": _steps(raw["drive"], f"{path}.drive", VALVE_STATES, period),
                  "recover": _steps(raw.get("recover", [{"at": "0 s", "state": "vent"}]),
                                    f"{path}.recover", VALVE_STATES, period)}
        per_joint = raw.get("joints", {})
        if not isinstance(per_joint, dict):
            raise ScenarioError(f"{path}.joints", per_joint, "expected tables [gait.joints.<joint>]")
        table = {}
        for j in per_joint:
            if j not in joints:
                raise unknown_key_error(f"{path}.joints", j, joints)
        for j in joints:
            own = per_joint.get(j, {})
            if not isinstance(own, dict):
                raise ScenarioError(f"{path}.joints.{j}", own, "expected a table with drive and/or recover")
            for key in own:
                if key not in GROUPS:
                    raise unknown_key_error(f"{path}.joints.{j}", key, GROUPS)
            table[j] = {g: (_steps(own[g], f"{path}.joints.{j}.{g}", VALVE_STATES, period)
                            if g in own else common[g]) for g in GROUPS}
        palms = _steps(raw["palms"], f"{path}.palms", PALM_STATES, period)
        return cls(period, int(unwrap(cycles)), table, palms)

    @property
    def duration(self) -> float:
        """cycles x period [s]."""
        return self.cycles * self.period


def repeat(steps: tuple, period: float, cycles: int) -> tuple:
    """One period's steps repeated over ``cycles`` periods: ((t + k period, state), ...)."""
    return tuple((k * period + t, s) for k in range(cycles) for t, s in steps)


def muscle_programs(gait: Gait, muscles: dict) -> dict:
    """One valve Program per muscle for the whole run.

    ``muscles`` maps a muscle name to (joint, group), group "drive" or "recover".
    """
    return {name: Program(repeat(gait.joints[joint][group], gait.period, gait.cycles))
            for name, (joint, group) in muscles.items()}


def palm_commands(gait: Gait, rate: float):
    """Steering-motor commands: times [s] on the controller grid and targets (1 open, 0 folded)."""
    steps = repeat(gait.palms, gait.period, gait.cycles)
    t = np.array([command_time(ts, rate) for ts, _ in steps])
    target = np.array([PALM_STATES[s] for _, s in steps])
    return t, target


def phase_windows(gait: Gait, group: str = "drive", joint: str = "hip"):
    """[(start, end), ...] of each cycle's charge phase of a muscle group [s] (for summaries).

    The charge phase runs from a "charge" step to the next step of another state (or the end
    of the period)."""
    steps = gait.joints[joint][group]
    windows = []
    for k in range(gait.cycles):
        t0 = k * gait.period
        for i, (t, s) in enumerate(steps):
            if s != "charge":
                continue
            end = steps[i + 1][0] if i + 1 < len(steps) else gait.period
            windows.append((t0 + t, t0 + end))
    return windows


# --- writing a gait ------------------------------------------------------------------------------
def time_text(t: float, digits: int = 3) -> str:
    """A time as the gait table writes it: seconds with the unit, e.g. "0.125 s"."""
    return f"{round(float(t), digits):.{digits}f}".rstrip("0").rstrip(".") + " s"


def steps_raw(steps) -> list:
    """((t, state), ...) -> [{at = "t s", state = "..."}, ...] (the TOML form)."""
    return [{"at": time_text(t), "state": s} for t, s in steps]


def gait_raw(period: float, cycles: int, drive, recover, palms, joints: dict | None = None) -> dict:
    """A ``[gait]`` table (units written out) that :meth:`Gait.from_raw` reads back: the common
    drive, recover and palm steps ((t [s], state), ...) and optional per-joint overrides
    (joint -> {"drive": steps, "recover": steps})."""
    raw = {"period": time_text(period), "cycles": int(cycles), "drive": steps_raw(drive),
           "recover": steps_raw(recover), "palms": steps_raw(palms)}
    if joints:
        raw["joints"] = {j: {g: steps_raw(s) for g, s in own.items()} for j, own in joints.items()}
    return raw


def gait_table_of(gait: Gait) -> dict:
    """The ``[gait]`` table of a validated Gait (each joint's own steps written out)."""
    first = gait.joints[next(iter(gait.joints))]
    joints = {j: own for j, own in gait.joints.items() if own != first}
    return gait_raw(gait.period, gait.cycles, first["drive"], first["recover"], gait.palms, joints)
