"""Cross-field rules of a scenario: the checks no single field can make on its own.

:func:`check` runs every rule on a typed scenario (SI values). The loader calls it once the file is
read; :meth:`frogsim.scenario.core.Scenario.replace` calls it on every variant, so a sweep point
or a fit iterate is refused exactly as the same values written in a file would be.
"""
from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

from frogsim.errors import MISSING, ScenarioError
from frogsim.scenario.fields import shown
from frogsim.scenario.motion import build_motions
from frogsim.scenario.schema import MOTION_KINDS

if TYPE_CHECKING:   # annotations only
    from frogsim.scenario.core import Scenario

MAX_OUTPUT_ROWS = 5_000_000


def _meta(obj, name: str) -> dict:
    return next(f.metadata for f in dataclasses.fields(obj) if f.name == name)


def _err(path: str, obj, name: str, allowed: str) -> ScenarioError:
    return ScenarioError(path, shown(getattr(obj, name), _meta(obj, name)), allowed)


def check(sc: Scenario) -> None:
    """Raise ScenarioError (field, value, what is allowed) on the first rule the scenario breaks."""
    if sc.output_interval > sc.duration:
        raise _err("output_interval", sc, "output_interval", f"must not exceed the duration ({sc.duration:g} s)")
    if sc.duration / sc.output_interval > MAX_OUTPUT_ROWS:
        raise _err("output_interval", sc, "output_interval",
                   "too fine for the duration (more than 5 million output rows)")
    p_atm = sc.air.atmospheric_pressure_abs
    starts = [("source.initial_pressure_gauge", sc.source, "initial_pressure_gauge"),
              ("exhaust.initial_pressure_gauge", sc.exhaust, "initial_pressure_gauge")]
    starts += [(f"muscles.{n}.initial_pressure_gauge", m, "initial_pressure_gauge")
               for n, m in sc.muscles.items() if m.initial_pressure_gauge is not None]
    for path, obj, name in starts:
        if p_atm + getattr(obj, name) <= 0.0:     # air in a chamber has a positive absolute pressure
            raise _err(path, obj, name, f"must be above -{p_atm / 1e5:g} bar: the atmosphere is "
                                        f"{p_atm / 1e3:g} kPa (air.atmospheric_pressure_abs)")
    if sc.pump.on_below_gauge >= sc.pump.off_above_gauge:
        off = shown(sc.pump.off_above_gauge, _meta(sc.pump, "off_above_gauge"))
        raise _err("pump.on_below_gauge", sc.pump, "on_below_gauge", f"must be below pump.off_above_gauge ({off})")
    for vname in ("charge", "discharge"):
        v = getattr(sc.valves, vname)
        if v.laminar_ratio <= v.critical_ratio:
            raise ScenarioError(f"valves.{vname}.laminar_ratio", v.laminar_ratio,
                                f"must exceed critical_ratio ({v.critical_ratio:g})")
    if not sc.muscle_types:
        raise ScenarioError("muscle_types", {}, "expected at least one muscle type")
    for tname, mt in sc.muscle_types.items():
        mt.check(f"muscle_types.{tname}")
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
    build_motions(sc)      # overlapping strokes, joint-angle files
