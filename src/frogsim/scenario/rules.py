"""Cross-field rules of a scenario: the checks no single field can make on its own.

:func:`check` runs every rule on a typed scenario (SI values). The loader calls it once the file is
read; :meth:`frogsim.scenario.core.Scenario.replace` calls it on every variant, so a sweep point
or a fit iterate is refused exactly as the same values written in a file would be.
"""
from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

from frogsim._budget import ASK_ABOVE, Need, check as check_size
from frogsim.errors import MISSING, ScenarioError
from frogsim.scenario.fields import shown
from frogsim.scenario.firmware import check_firmware
from frogsim.scenario.motion import build_motions
from frogsim.scenario.schema import MOTION_KINDS
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
    sc.valves.check("valves")           # the valve type's own checks
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
    # program steps after the end of the run are allowed: they simply never happen (but a program
    # of several cycles must end within the run, _check_programs)


def _check_programs(sc) -> None:
    """Every cycle of a cycle program must begin within the run: a cycle that would start at or
    after the run's end would be dropped without a word (the README's one-hip example once had 3
    cycles of 2 s in a 2 s run and ran one). A last cycle that begins but is cut by the end runs
    in part, as any program step after the end simply never happens."""
    seen = set()
    for mname, m in sc.muscles.items():
        prog = m.program
        if not prog.is_cycle or (prog.cycles or 1) <= 1:
            continue
        path = f"programs.{m.program_ref}.cycles" if m.program_ref else f"muscles.{mname}.program.cycles"
        if path in seen:
            continue
        seen.add(path)
        start, period, n = prog.start or 0.0, prog.pressurise + prog.release, prog.cycles
        last = start + (n - 1) * period
        if last >= sc.duration * (1.0 - 1e-12) - 1e-12:
            begun = max(1, math.ceil((sc.duration - start) / period - 1e-9))
            raise ScenarioError(path, n, f"{n} cycles of {period:g} s from {start:g} s: the last would begin at "
                                         f"{last:g} s, after the run (duration {sc.duration:g} s), which begins "
                                         f"{begun} of them: allowed {'1' if begun <= 1 else f'1 to {begun}'} in "
                                         f"this run, or a duration over {last:g} s")


def _check_motions(sc) -> None:
    build_motions(sc)      # overlapping strokes, joint-angle files


def check_controllers(sc: Scenario) -> None:
    """[controllers.NAME]: the muscles a controller drives exist, each is under one controller at
    most, a muscle under a closed-loop controller has no program and every other muscle has one,
    the metrics' settle time lies inside the run; then each kind's own checks
    (:meth:`frogsim.scenario.kinds.ControllerSettings.check`)."""
    driven = {}
    p_top = sc.source.initial_pressure_gauge
    if sc.pump.enabled and sc.pump.displacement > 0:
        p_top = max(p_top, sc.pump.off_above_gauge)
    for cname, c in sc.controllers.items():
        path = f"controllers.{cname}"
        c.check_target(sc, path)
        for m in c.driven():
            where, what = c.where(path)
            if m not in sc.muscles:
                raise ScenarioError(where, what, f"must name a muscle of this scenario ({', '.join(sc.muscles)})"
                                    if c.NAMED == "muscle" else f"its muscle {m!r} is not in this scenario")
            if m in driven:
                raise ScenarioError(where, what, f"already under controllers.{driven[m]}" if c.NAMED == "muscle"
                                    else f"its muscle {m!r} is already under controllers.{driven[m]}")
            driven[m] = cname
            has_program = bool(sc.muscles[m].program.steps)
            if not c.closed_loop and not has_program:
                raise ScenarioError(f"muscles.{m}.program", MISSING,
                                    f"{path} is of kind {c.kind!r}: the muscle needs a program")
            if c.closed_loop and has_program:
                raise ScenarioError(f"muscles.{m}.program", "(a program)",
                                    f"refused: the muscle is under the closed-loop {path} ({c.kind}), "
                                    "which drives its valves; remove its program")
        settle = getattr(c, "settle", None)
        if settle is not None and settle >= sc.duration:
            raise _err(f"{path}.settle", c, "settle", f"must be shorter than the run (duration "
                                                     f"{sc.duration:g} s): the metrics count from it on")
        c.check(sc, path, p_top)
        if c.kind == "pwm":
            _check_pwm_period(sc, c, path)
    for mname, m in sc.muscles.items():
        if not m.program.steps and mname not in driven:
            raise ScenarioError(f"muscles.{mname}.program", MISSING,
                                "required setting is missing (or put the muscle under a closed-loop "
                                "[controllers] section)")


def _check_pwm_period(sc: Scenario, c, path: str) -> None:
    """A PWM's period must lie within the run (a longer one never ends its first pulse); with the
    kind's own checks (at least twice the larger valve dead time, the valves' switching time, and
    two controller samples) the message names the whole allowed range."""
    period = 1.0 / c.frequency
    if period <= sc.duration:
        return
    dead = max(sc.valves.charge.dead_time, sc.valves.discharge.dead_time)
    hi = min(sc.controller.rate / 2.0, 1.0 / (2.0 * dead) if dead > 0 else float("inf"),
             _meta(c, "frequency")["le"])
    raise err(f"{path}.frequency", c, "frequency",
              f"its period {period:g} s must lie within the run (duration {sc.duration:g} s): allowed "
              f"{1.0 / sc.duration:g} Hz to {hi:g} Hz (the top: a period of at least twice the valve dead "
              f"time, {dead * 1e3:g} ms, and two controller samples)")


def check_pressure_setpoint(sc: Scenario, sp, path: str, p_top: float) -> None:
    """A pressure setpoint has the settings its kind needs and stays where the valves can take
    the muscle: at most the source pressure ``p_top`` [Pa gauge], above absolute zero."""
    sp.check_complete(path)
    lo, hi = sp.bounds()
    if hi > p_top:
        raise ScenarioError(path, f"{hi / 1e5:g} bar (highest value)",
                            f"must not exceed the source pressure ({p_top / 1e5:g} bar gauge): "
                            "the charge valve cannot reach it")
    if lo < -sc.air.atmospheric_pressure_abs:
        raise ScenarioError(path, f"{lo / 1e5:g} bar (lowest value)", "must be above absolute zero")


def check_below_source(obj, name: str, path: str, p_top: float) -> None:
    """A gauge pressure setting the charge valve must reach: at most the source pressure."""
    if getattr(obj, name) > p_top:
        raise _err(path, obj, name, f"must not exceed the source pressure ({p_top / 1e5:g} bar gauge): "
                                    "the charge valve cannot reach it")


def _check_solver(sc) -> None:
    """The integration method's own checks (a fixed step against the controller period: its
    settings class's ``check``, :mod:`frogsim.scenario.methods`)."""
    sc.solver.method.check(sc, "solver.method")


def err(path: str, obj, name: str, allowed: str) -> ScenarioError:
    """ScenarioError for setting ``name`` of obj, its value shown in its display unit."""
    return _err(path, obj, name, allowed)


#: The cross-field rules in the order they are checked: (top-level settings it reads, rule).
RULES = (
    (("output_interval", "duration"), _check_output_grid),
    (("air", "source", "exhaust", "muscles"), _check_initial_pressures),
    (("pump",), _check_pump),
    (("valves",), _check_valves),
    (("muscle_types",), _check_muscle_types),
    (("muscles", "muscle_types"), _check_muscles),
    (("muscles", "duration"), _check_programs),
    (("valves", "controller", "source", "pump", "controllers", "muscles", "air", "joints", "duration"),
     check_controllers),
    (("controller", "muscles", "muscle_types", "base_dir"), _check_motions),
    (("firmware", "name", "controllers", "muscles", "controller", "duration"), check_firmware),
    (("solver", "controller"), _check_solver),
)
