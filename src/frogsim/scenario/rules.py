"""Cross-field rules of a scenario: the checks no single field can make on its own.

:func:`check` runs every rule on a typed scenario (SI values). The loader calls it once the file is
read; :meth:`frogsim.scenario.core.Scenario.replace` calls it on every variant, so a sweep point
or a fit iterate is refused exactly as the same values written in a file would be.
"""
from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

from frogsim._budget import ASK_ABOVE, Need, check as check_size
from frogsim.errors import MISSING, ScenarioError
from frogsim.scenario.fields import shown
from frogsim.scenario.motion import build_motions
from frogsim.scenario.schema import MOTION_KINDS, SETPOINT_FIELDS
from frogsim.scenario.view import Settings

if TYPE_CHECKING:   # annotations only
    from frogsim.scenario.core import Scenario

MAX_OUTPUT_ROWS = 5_000_000
#: [bytes] memory an output row takes at least: time, one muscle's state, the source, the exhaust
#: and two valves (10 floats), held as the result's arrays and again as a table
ROW_BYTES = 2 * 10 * 8


def _meta(obj, name: str) -> dict:
    return next(f.metadata for f in dataclasses.fields(obj) if f.name == name)


def _err(path: str, obj, name: str, allowed: str) -> ScenarioError:
    return ScenarioError(path, shown(getattr(obj, name), _meta(obj, name)), allowed)


def check(sc: Scenario) -> None:
    """Raise ScenarioError (field, value, what is allowed) on the first rule the scenario breaks.

    Each rule of :data:`RULES` sees only the top-level settings it declares (a
    :class:`frogsim.scenario.view.Settings`), so a batch of variants can check it once per
    distinct combination of them (:mod:`frogsim.scenario.variants`)."""
    values, owner = sc.__dict__, type(sc)
    for names, rule in RULES:
        rule(Settings(values, names, owner))


def _check_output_grid(sc) -> None:
    if sc.output_interval > sc.duration:
        raise _interval_err(sc, f"must not exceed the duration ({sc.duration:g} s)")
    rows = sc.duration / sc.output_interval
    if rows > MAX_OUTPUT_ROWS or rows * ROW_BYTES > ASK_ABOVE:
        n = int(min(rows, 2**62)) + 1
        check_size("output_interval", shown(sc.output_interval, sc.meta("output_interval")),
                   Need(f"a run of {n:,} output rows ({sc.duration:g} s every {sc.output_interval:g} s)",
                        n, "output rows", MAX_OUTPUT_ROWS, memory=n * ROW_BYTES))


def _interval_err(sc, allowed: str) -> ScenarioError:
    return ScenarioError("output_interval", shown(sc.output_interval, sc.meta("output_interval")), allowed)


def _check_initial_pressures(sc) -> None:
    p_atm = sc.air.atmospheric_pressure_abs
    starts = [("source.initial_pressure_gauge", sc.source, "initial_pressure_gauge"),
              ("exhaust.initial_pressure_gauge", sc.exhaust, "initial_pressure_gauge")]
    starts += [(f"muscles.{n}.initial_pressure_gauge", m, "initial_pressure_gauge")
               for n, m in sc.muscles.items() if m.initial_pressure_gauge is not None]
    for path, obj, name in starts:
        if p_atm + getattr(obj, name) <= 0.0:     # air in a chamber has a positive absolute pressure
            raise _err(path, obj, name, f"must be above -{p_atm / 1e5:g} bar: the atmosphere is "
                                        f"{p_atm / 1e3:g} kPa (air.atmospheric_pressure_abs)")


def _check_pump(sc) -> None:
    if sc.pump.on_below_gauge >= sc.pump.off_above_gauge:
        off = shown(sc.pump.off_above_gauge, _meta(sc.pump, "off_above_gauge"))
        raise _err("pump.on_below_gauge", sc.pump, "on_below_gauge", f"must be below pump.off_above_gauge ({off})")


def _check_valves(sc) -> None:
    for vname in ("charge", "discharge"):
        v = getattr(sc.valves, vname)
        if v.laminar_ratio <= v.critical_ratio:
            raise ScenarioError(f"valves.{vname}.laminar_ratio", v.laminar_ratio,
                                f"must exceed critical_ratio ({v.critical_ratio:g})")


def _check_muscle_types(sc) -> None:
    if not sc.muscle_types:
        raise ScenarioError("muscle_types", {}, "expected at least one muscle type")
    for tname, mt in sc.muscle_types.items():
        mt.check(f"muscle_types.{tname}")


def _check_muscles(sc) -> None:
    if not sc.muscles:
        raise ScenarioError("muscles", {}, "expected at least one muscle, e.g. [muscles.hip]")
    for mname, m in sc.muscles.items():
        path = f"muscles.{mname}"
        if m.type not in sc.muscle_types:
            raise ScenarioError(f"{path}.type", m.type,
                                f"must name a muscle type ({', '.join(sorted(sc.muscle_types))})")
        mt = sc.muscle_types[m.type]
        mo = m.motion
        for key in MOTION_KINDS[mo.kind][0]:
            if getattr(mo, key) in (None, ()):
                raise ScenarioError(f"{path}.motion.{key}", MISSING, f"required for kind {mo.kind!r}")
        if mo.contraction is not None and mo.contraction > mt.max_contraction:
            raise _err(f"{path}.motion.contraction", mo, "contraction",
                       f"must be <= the muscle's max_contraction ({mt.max_contraction:.0%})")
        for c in mo.contraction_percent:
            if c / 100.0 > mt.max_contraction:
                raise ScenarioError(f"{path}.motion.contraction_percent", c,
                                    f"must be <= the muscle's max_contraction ({mt.max_contraction:.0%})")
    # program steps after the end of the run are allowed: they simply never happen


def _check_motions(sc) -> None:
    build_motions(sc)      # overlapping strokes, joint-angle files


def _check_duty_schedule(ds, base_dir: str, path: str) -> None:
    """A duty schedule's settings are there and every duty it takes lies in 0..1."""
    for key in SETPOINT_FIELDS[ds.kind]:
        if key not in ("start", "time_column", "column") and getattr(ds, key) in (None, ()):
            raise ScenarioError(f"{path}.{key}", MISSING, f"required for kind {ds.kind!r}")
    knots = setpoint_knots(ds, base_dir, path) if ds.kind == "table" else ()
    lo, hi = ds.bounds(knots)
    if lo < 0.0 or hi > 1.0:
        shown = f"{lo:g}..{hi:g} (lowest..highest duty)"
        raise ScenarioError(path, shown, "a duty lies in 0..1 (0 %..100 %): for a sine mean - amplitude >= 0 "
                                         "and mean + amplitude <= 1")


def setpoint_knots(sp, base_dir: str, path: str) -> tuple:
    """The rows ((t [s], p [Pa gauge]), ...) of a table setpoint's CSV file (times increasing);
    an angle setpoint's ((t [s], angle [rad]), ...) from degrees."""
    import math
    from pathlib import Path

    from frogsim.scenario.tables import read_table
    where = f"{path}.file"
    # a regular UTF-8 file, every row as many fields as the header (frogsim.scenario.tables)
    table = read_table(Path(base_dir) / sp.file, where, numbers=False)
    head = list(table.columns)
    for col in (sp.time_column, sp.column):
        if col not in head:
            raise ScenarioError(where, sp.file, f"has no column {col!r} (columns: {', '.join(head)})")
    out = []
    for k, (tv, pv) in enumerate(zip(table[sp.time_column], table[sp.column]), start=2):
        try:
            t, p = float(tv), float(pv) * sp.SCALE
        except (ValueError, TypeError):
            raise ScenarioError(where, sp.file, f"line {k}: expected numbers in {sp.time_column} and "
                                                f"{sp.column}") from None
        if not (math.isfinite(t) and math.isfinite(p)):
            raise ScenarioError(where, sp.file, f"line {k}: must be finite numbers")
        if out and t <= out[-1][0]:
            raise ScenarioError(where, sp.file, f"line {k}: times must increase")
        out.append((t, p))
    if not out:
        raise ScenarioError(where, sp.file, "has no rows")
    return tuple(out)


def check_controllers(sc: Scenario) -> None:
    """[controllers.NAME]: a muscle that exists, one controller per muscle, the settings the kind
    needs, a setpoint the source can reach, a PWM period of at least two valve dead times (and two
    controller samples); a muscle under a closed-loop controller has no program, every other
    muscle has one."""
    driven = {}
    dead = max(sc.valves.charge.dead_time, sc.valves.discharge.dead_time)
    dt = 1.0 / sc.controller.rate
    p_top = sc.source.initial_pressure_gauge
    if sc.pump.enabled and sc.pump.displacement > 0:
        p_top = max(p_top, sc.pump.off_above_gauge)
    for cname, c in sc.controllers.items():
        path = f"controllers.{cname}"
        if c.kind == "joint-angle":
            _check_joint_controller(sc, cname, c, driven, p_top)
            continue
        if c.muscle not in sc.muscles:
            raise ScenarioError(f"{path}.muscle", c.muscle,
                                f"must name a muscle of this scenario ({', '.join(sc.muscles)})")
        if c.muscle in driven:
            raise ScenarioError(f"{path}.muscle", c.muscle, f"already under controllers.{driven[c.muscle]}")
        driven[c.muscle] = cname
        m = sc.muscles[c.muscle]
        if c.kind == "program":
            if not m.program.steps:
                raise ScenarioError(f"muscles.{c.muscle}.program", MISSING,
                                    f"{path} is of kind 'program': the muscle needs a program")
            continue
        if m.program.steps:
            raise ScenarioError(f"muscles.{c.muscle}.program", "(a program)",
                                f"refused: the muscle is under the closed-loop {path} ({c.kind}), "
                                "which drives its valves; remove its program")
        if c.kind == "pwm":
            given = [k for k in ("duty", "duty_schedule", "setpoint") if getattr(c, k) is not None]
            if len(given) != 1:
                raise ScenarioError(f"{path}.duty", MISSING if not given else f"{' and '.join(given)} given",
                                    "a pwm controller takes one of: a duty or a duty_schedule (open loop), or "
                                    "a setpoint")
            if c.duty_schedule is not None:
                _check_duty_schedule(c.duty_schedule, sc.base_dir, f"{path}.duty_schedule")
            period = 1.0 / c.frequency
            if period < 2.0 * dead:
                raise _err(f"{path}.frequency", c, "frequency",
                           f"the period {period * 1e3:g} ms must be at least twice the valve dead time "
                           f"({dead * 1e3:g} ms): at most {1.0 / (2.0 * dead):g} Hz")
            if period < 2.0 * dt - 1e-12:
                raise _err(f"{path}.frequency", c, "frequency",
                           f"the period must span at least two controller samples (at most "
                           f"{sc.controller.rate / 2:g} Hz at controller.rate = {sc.controller.rate:g} Hz)")
        elif c.setpoint is None:
            raise ScenarioError(f"{path}.setpoint", MISSING, f"required for kind {c.kind!r}")
        sp = c.setpoint
        if sp is None:
            continue
        for key in SETPOINT_FIELDS[sp.kind]:
            if key not in ("start", "time_column", "column") and getattr(sp, key) in (None, ()):
                raise ScenarioError(f"{path}.setpoint.{key}", MISSING, f"required for setpoint kind {sp.kind!r}")
        knots = setpoint_knots(sp, sc.base_dir, f"{path}.setpoint") if sp.kind == "table" else ()
        lo, hi = sp.bounds(knots)
        if hi > p_top:
            raise ScenarioError(f"{path}.setpoint", f"{hi / 1e5:g} bar (highest value)",
                                f"must not exceed the source pressure ({p_top / 1e5:g} bar gauge): "
                                "the charge valve cannot reach it")
        if lo < -sc.air.atmospheric_pressure_abs:
            raise ScenarioError(f"{path}.setpoint", f"{lo / 1e5:g} bar (lowest value)",
                                "must be above absolute zero")
    for mname, m in sc.muscles.items():
        if not m.program.steps and mname not in driven:
            raise ScenarioError(f"muscles.{mname}.program", MISSING,
                                "required setting is missing (or put the muscle under a closed-loop "
                                "[controllers] section)")


def _check_joint_controller(sc: Scenario, cname: str, c, driven: dict, p_top: float) -> None:
    """A joint-angle controller: a joint of the robot with an antagonistic pair, both muscles free
    of programs and of other controllers, a setpoint, a co-contraction the source can reach. The
    setpoint's range against the joint's is checked by the robot's loader, which knows it."""
    path = f"controllers.{cname}"
    if not sc.joints:
        raise ScenarioError(f"{path}.kind", c.kind, "a joint-angle controller needs a robot scenario "
                                                    "([robot] and [gait]; frogsim.load_robot_scenario)")
    if c.joint not in sc.joints:
        raise ScenarioError(f"{path}.joint", c.joint, f"must name a joint of the robot ({', '.join(sc.joints)})")
    if not c.antagonist:
        raise ScenarioError(f"{path}.joint", c.joint, "has no antagonistic pair (robot.recovery = \"spring\"): "
                                                      "a joint-angle controller needs robot.recovery = \"muscle\"")
    for m in (c.muscle, c.antagonist):
        if m not in sc.muscles:
            raise ScenarioError(f"{path}.joint", c.joint, f"its muscle {m!r} is not in this scenario")
        if m in driven:
            raise ScenarioError(f"{path}.joint", c.joint, f"its muscle {m!r} is already under "
                                                          f"controllers.{driven[m]}")
        driven[m] = cname
        if sc.muscles[m].program.steps:
            raise ScenarioError(f"muscles.{m}.program", "(a program)",
                                f"refused: the muscle is under the closed-loop {path} (joint-angle)")
    if c.setpoint is None:
        raise ScenarioError(f"{path}.setpoint", MISSING, "required for kind 'joint-angle'")
    sp = c.setpoint
    for key in SETPOINT_FIELDS[sp.kind]:
        if key not in ("start", "time_column", "column") and getattr(sp, key) in (None, ()):
            raise ScenarioError(f"{path}.setpoint.{key}", MISSING, f"required for setpoint kind {sp.kind!r}")
    if c.co_contraction > p_top:
        raise _err(f"{path}.co_contraction", c, "co_contraction",
                   f"must not exceed the source pressure ({p_top / 1e5:g} bar gauge): the charge valve "
                   "cannot reach it")


#: The cross-field rules in the order they are checked: (top-level settings it reads, rule).
RULES = (
    (("output_interval", "duration"), _check_output_grid),
    (("air", "source", "exhaust", "muscles"), _check_initial_pressures),
    (("pump",), _check_pump),
    (("valves",), _check_valves),
    (("muscle_types",), _check_muscle_types),
    (("muscles", "muscle_types"), _check_muscles),
    (("valves", "controller", "source", "pump", "controllers", "muscles", "air", "base_dir", "joints"),
     check_controllers),
    (("controller", "muscles", "muscle_types", "base_dir"), _check_motions),
)
