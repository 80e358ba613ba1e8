"""The parameter and scenario dataclasses: every field SI inside, with the unit kind it is read in.

Pressures say in their name whether they are gauge (``*_gauge``, relative to the atmosphere) or
absolute (``*_abs``). Bounds are checked when a file is loaded; nothing is clamped later.
"""
from __future__ import annotations

import math
import dataclasses
import functools
from dataclasses import dataclass, field
from typing import ClassVar

from frogsim.scenario.fields import (build, choice, flag, integer, parse_field, quantity, unknown_key_error,
                                     unwrap)
from frogsim.errors import MISSING, ScenarioError, Shown
from frogsim.scenario.files import read_text
from frogsim.scenario.actuators import ActuatorSettings
from frogsim.scenario.valves import ValveSettings
from frogsim.scenario.methods import MethodSettings, default_settings
from frogsim.components.atmega2560 import conversion_time
from frogsim.physics.heat import cylinder_wall_area
from frogsim.physics.muscle import braid_parameters, muscle_volume

BAR = 1e5
MAX_BRAID_ANGLE = math.acos(1.0 / math.sqrt(3.0))  # 54.7 deg: the ideal muscle's force vanishes
GAUGE_MIN = -1.0 * BAR  # below -1 bar gauge there is (almost) no air left: refused
GAUGE_MAX = 16.0 * BAR
# Eq. (5) computes the braid volume from b0^2 - L^2, where b0^2 - L0^2 = L0^2 tan^2(theta0): with
# tan^2(theta0) >= 1e-8 that difference stands clear of the rounding of b0^2 (2.2e-16 b0^2), so
# the volume keeps 7 good digits; below it the volume becomes noise (even negative)
MIN_BRAID_ANGLE = math.atan(1e-4)    # 0.0057 deg
# gas and wall temperatures: air stays an ideal gas of constant k from about 150 K (it liquefies
# near 80 K at 1 bar, and its c_p rises well before) to about 1000 K (c_p up by 10 % and k down to
# 1.34 there, dissociation and the tubes' plastics long before); outside it the model's constant
# R and k mean nothing
# the controller is the Arduino Mega's loop (paper, Sec. 4): each sample reads a sensor, and one
# ADC conversion takes 13 ADC clocks, at the fastest recommended ADC clock (1 MHz, 16 MHz / 16)
# 13 µs: 76.9 kHz at most ([firmware] checks the whole plan against the real budget)
CONTROLLER_RATE_MAX = 1.0 / conversion_time(16)
TEMPERATURE_MIN = 150.0
TEMPERATURE_MAX = 1000.0


def gas_temperature(doc: str = "", **kw):
    """A gas or wall temperature [K], within TEMPERATURE_MIN to TEMPERATURE_MAX."""
    return quantity("temperature", ge=TEMPERATURE_MIN, le=TEMPERATURE_MAX, display="K", doc=doc,
                    why="where air is an ideal gas of constant R and k, as the model has it", **kw)


def gauge_pressure(doc: str = "", default=None):
    kw = {} if default is None else {"default": default}
    return quantity("pressure", ge=GAUGE_MIN, le=GAUGE_MAX, display="bar", doc=doc, **kw)


@dataclass(frozen=True)
class Air:
    """Air properties and reference conditions."""
    gas_constant: float = quantity("gas_constant", gt=0, display="J/(kg*K)")
    heat_capacity_ratio: float = quantity("dimensionless", gt=1.0, le=5.0 / 3.0)
    atmospheric_pressure_abs: float = quantity("pressure", gt=0, display="kPa")
    reference_pressure_abs: float = quantity("pressure", gt=0, display="kPa",
                                             doc="ISO 8778 standard state for 'standard' volumes")
    reference_temperature: float = gas_temperature("ISO 8778 standard state for 'standard' volumes")
    ambient_temperature: float = gas_temperature("the air's and every wall's temperature at rest")

    @property
    def reference_density(self) -> float:
        """rho_ref = p_ref/(R T_ref) [kg/m^3]: converts standard volumes to mass."""
        return self.reference_pressure_abs / (self.gas_constant * self.reference_temperature)


@dataclass(frozen=True)
class Chamber:
    """A rigid air chamber (the source tanks or the exhaust space inside the hull).

    Its air starts at ``initial_temperature`` (the ambient temperature when not given) and
    exchanges heat with the wall (at the ambient temperature) by Newton's law,
    Q = h A (T_wall - T) (:mod:`frogsim.physics.heat`); h = 0 keeps it adiabatic (the paper's
    model). A is ``wall_area``, or when that is not given the inner wall of one closed cylinder of
    the chamber's volume and ``length_over_diameter``.
    """
    volume: float = quantity("volume", gt=0, display="L")
    initial_pressure_gauge: float = gauge_pressure()
    heat_transfer_coefficient: float = quantity("heat_transfer_coefficient", ge=0.0, le=1e5,
                                                display="W/(m^2*K)", default=0.0,
                                                doc="air to wall; 0: adiabatic")
    wall_area: float | None = quantity("area", gt=0.0, display="m^2", default=None,
                                       doc="inner wall area (none: a cylinder of length_over_diameter)")
    length_over_diameter: float = quantity("dimensionless", gt=0.0, le=100.0, default=1.0,
                                           doc="the cylinder's shape when wall_area is not given")
    initial_temperature: float | None = gas_temperature("the air's temperature at t = 0 (none: the ambient "
                                                        "temperature), e.g. a run started mid-way", default=None)

    @property
    def inner_wall_area(self) -> float:
        """The wall area the air exchanges heat with [m^2] (see the class docstring)."""
        if self.wall_area is not None:
            return self.wall_area
        return cylinder_wall_area(self.volume, self.length_over_diameter)


@dataclass(frozen=True)
class Pump:
    """Micro pump returning air from the exhaust chamber to the source, switched by a pressure band."""
    enabled: bool = flag()
    displacement: float = quantity("volume_flow", ge=0, display="L/min",
                                   doc="free-air flow at inlet conditions with no pressure rise")
    max_pressure_ratio: float = quantity("dimensionless", gt=1.0, doc="stall ratio p_out/p_in")
    on_below_gauge: float = gauge_pressure()
    off_above_gauge: float = gauge_pressure()


@dataclass(frozen=True)
class Valve:
    """A high-speed switching valve described by its ISO 6358 flow-rate characteristics."""
    sonic_conductance: float = quantity("conductance", gt=0, display="L/(s*bar)")
    critical_ratio: float = quantity("dimensionless", ge=0.0, lt=1.0)
    subsonic_index: float = quantity("dimensionless", gt=0.0, le=1.0, default=0.5)
    laminar_ratio: float = quantity("dimensionless", gt=0.0, le=1.0, default=1.0)
    dead_time: float = quantity("time", ge=0.0, le=1.0, display="ms", default=0.0)


@dataclass(frozen=True)
class Valves(ValveSettings):
    """The paper's switching valves, two per muscle: charge (source -> muscle) and discharge
    (muscle -> exhaust), each open or shut (valve type "switching", the first member of the valve
    family :mod:`frogsim.circuit.valves`; its module there declares this class its settings)."""
    TYPE: ClassVar[str] = "switching"
    charge: Valve
    discharge: Valve


@dataclass(frozen=True)
class Supply:
    """How the source reaches the charge valves: the main tube and its branches (Eq. (9))."""
    mode: str = choice(("paper", "physical", "none"),
                       doc="paper: Eq. (9) fixed per-branch limit; physical: shared choked tube; "
                           "none: no tube limit")
    main_tube_inner_diameter: float = quantity("length", gt=0, display="mm")
    main_tube_count: int = integer(ge=1, le=100)
    branch_count: int = integer(ge=1, le=100)
    velocity_limit: float = quantity("velocity", gt=0, display="m/s")
    discharge_coefficient: float = quantity("dimensionless", gt=0.0, le=1.0)
    branch_limit: float | None = quantity("volume_flow", gt=0, display="L/min", default=None,
                                          doc="paper mode: overrides Eq. (9)'s per-branch value")


@dataclass(frozen=True)
class MuscleType(ActuatorSettings):
    """A McKibben muscle model (FESTO DMSP-20 of a given length) and its crank mounting: the
    settings of actuator type "mckibben" (:mod:`frogsim.circuit.actuators.mckibben`), the
    default of a ``[muscle_types.NAME]`` table (:mod:`frogsim.scenario.actuators`)."""
    TYPE: ClassVar[str] = "mckibben"
    nominal_length: float = quantity("length", gt=0, le=2.0, display="mm")
    inner_diameter: float = quantity("length", gt=0, le=0.2, display="mm")
    braid_angle: float = quantity("angle", gt=0.0, lt=MAX_BRAID_ANGLE, display="deg")
    max_contraction: float = quantity("dimensionless", gt=0.0, lt=1.0, display="%")
    dead_volume: float = quantity("volume", ge=0.0, display="cm^3")
    stroke_contraction: float = quantity("dimensionless", ge=0.0, lt=1.0, display="%")
    crank_radius: float = quantity("length", gt=0, display="mm")
    anchor_distance: float = quantity("length", gt=0, display="mm")
    rest_angle: float = quantity("angle", ge=-math.pi, le=math.pi, display="deg")
    side: int = integer(ge=-1, le=1, default=1)
    heat_transfer_coefficient: float = quantity("heat_transfer_coefficient", ge=0.0, le=1e5,
                                                display="W/(m^2*K)", default=0.0,
                                                doc="air to the braided wall (Q = h A (T_wall - T), A the "
                                                    "braid cylinder's mantle as it contracts); 0: adiabatic")

    def volume(self, L: float) -> float:
        """Eq. (5) at length L [m^3] (the same numbers as the type's compiled volume)."""
        b0, n = braid_parameters(self.nominal_length, self.inner_diameter, self.braid_angle)
        return muscle_volume(L, b0, n)

    def check(self, path: str) -> None:
        if self.stroke_contraction > self.max_contraction:
            raise ScenarioError(f"{path}.stroke_contraction", f"{self.stroke_contraction:.1%}",
                                f"must be <= max_contraction ({self.max_contraction:.0%})")
        if self.side not in (-1, 1):
            raise ScenarioError(f"{path}.side", self.side, "must be 1 or -1")
        if self.anchor_distance <= self.crank_radius:
            raise ScenarioError(f"{path}.anchor_distance", f"{self.anchor_distance * 1e3:g} mm",
                                f"must exceed crank_radius ({self.crank_radius * 1e3:g} mm)")
        self._check_braid(path)

    def _check_braid(self, path: str) -> None:
        """The braid (Eq. (5)) must give the rest cylinder's volume at rest and a positive volume
        over the whole contraction range (V is concave in L: its ends bound it)."""
        where = f"{path}.braid_angle"
        if self.braid_angle < MIN_BRAID_ANGLE:
            raise ScenarioError(where, Shown(f"{math.degrees(self.braid_angle):.4g} deg"),
                                f"must be >= {math.degrees(MIN_BRAID_ANGLE):.2g} deg: Eq. (5) "
                                "V = (b0^2 - L^2) L/(4 pi n^2) cannot be computed for a "
                                "thinner braid (b0^2 - L0^2 = L0^2 tan^2 of the angle "
                                "vanishes against b0^2)")
        v_rest, v_cyl, v_short = _braid_volumes(self.nominal_length, self.inner_diameter, self.braid_angle,
                                                self.max_contraction)
        if not (v_rest > 0 and v_short > 0 and abs(v_rest / v_cyl - 1.0) <= 1e-6):
            raise ScenarioError(where, Shown(f"{math.degrees(self.braid_angle):.4g} deg"),
                                f"the braid gives a volume of {v_rest * 1e6:.4g} cm^3 at "
                                f"rest (the cylinder holds {v_cyl * 1e6:.4g} cm^3) and "
                                f"{v_short * 1e6:.4g} cm^3 at max_contraction: must be "
                                "positive and match")


@functools.lru_cache(maxsize=4096)
def _braid_volumes(L0: float, D0: float, braid_angle: float, max_contraction: float) -> tuple:
    """(Eq. (5) volume at rest, the rest cylinder's volume, Eq. (5) volume at max_contraction) [m^3]."""
    b0, n = braid_parameters(L0, D0, braid_angle)
    return (muscle_volume(L0, b0, n), math.pi * D0 * D0 * L0 / 4.0,
            muscle_volume(L0 * (1.0 - max_contraction), b0, n))


VALVE_STATES = {"charge": (1, 0), "vent": (0, 1), "hold": (0, 0)}


def timed_steps(steps_raw, path: str, key: str, meta: dict, form: str) -> tuple:
    """((t [s], value), ...) from a list of { at = "<time>", <key> = ... } tables, times increasing;
    ScenarioError naming the step otherwise. ``meta`` reads the value (a choice, a quantity)."""
    if not isinstance(steps_raw, list) or not steps_raw:
        raise ScenarioError(path, steps_raw, "expected a non-empty list of steps")
    steps = []
    for j, st in enumerate(steps_raw):
        sp = f"{path}[{j}]"
        if not isinstance(st, dict) or set(st) != {"at", key}:
            raise ScenarioError(sp, st, f"expected {form}")
        t = parse_field(st["at"], dict(kind="time", ge=0.0, display="s"), f"{sp}.at")
        value = parse_field(st[key], meta, f"{sp}.{key}")
        if steps and t <= steps[-1][0]:
            raise ScenarioError(f"{sp}.at", st["at"], "step times must increase")
        steps.append((t, value))
    return tuple(steps)


def cycle_steps(pressurise: float, release: float, start: float, cycles: int) -> tuple:
    """Steps ((t [s], state), ...) of a cycle program: charge at start + c*period, vent pressurise later."""
    steps = []
    period = pressurise + release
    for c in range(cycles):
        t0 = start + c * period
        steps.append((t0, "charge"))
        steps.append((t0 + pressurise, "vent"))
    return tuple(steps)


@dataclass(frozen=True)
class Program:
    """An open-loop valve program: a list of (time [s], state) with state charge, vent or hold.

    Written either as a cycle, { pressurise = "1 s", release = "1 s", start = "0 s", cycles = 1 },
    or as steps, { steps = [ { at = "0 s", state = "charge" }, { at = "1 s", state = "vent" } ] }.
    A cycle keeps its settings (so a variant can change them, e.g. ``programs.stroke.pressurise``);
    its ``steps`` always follow from them.
    """
    steps: tuple = ()
    pressurise: float | None = quantity("time", gt=0, display="s", default=None, cycle=True)
    release: float | None = quantity("time", gt=0, display="s", default=None, cycle=True)
    start: float | None = quantity("time", ge=0, display="s", default=None, cycle=True)
    cycles: int | None = integer(ge=1, le=100000, default=None, cycle=True)

    def __post_init__(self):
        if self.is_cycle:
            object.__setattr__(self, "steps", cycle_steps(self.pressurise, self.release,
                                                          self.start or 0.0, self.cycles or 1))

    @property
    def is_cycle(self) -> bool:
        return self.pressurise is not None and self.release is not None

    @classmethod
    def from_raw(cls, raw, path: str) -> "Program":
        if not isinstance(raw, dict):
            raise ScenarioError(path, raw, "expected a program table (cycle or steps)")
        if "steps" in raw:
            extra = set(raw) - {"steps"}
            if extra:
                raise ScenarioError(f"{path}.{sorted(extra)[0]}", raw[sorted(extra)[0]],
                                    "a program has either steps or cycle settings, not both")
            return cls(timed_steps(raw["steps"], f"{path}.steps", "state", dict(choices=tuple(VALVE_STATES)),
                                   '{ at = "<time>", state = "charge|vent|hold" }'))
        cyc = build(_Cycle, raw, path)
        return cls(pressurise=cyc.pressurise, release=cyc.release, start=cyc.start, cycles=cyc.cycles)


@dataclass(frozen=True)
class _Cycle:
    pressurise: float = quantity("time", gt=0, display="s")
    release: float = quantity("time", gt=0, display="s")
    start: float = quantity("time", ge=0, display="s", default=0.0)
    cycles: int = integer(ge=1, le=100000, default=1)


MOTION_KINDS = {
    # kind: (required fields, optional fields)
    "stroke": ((), ("contraction", "delay", "rise", "fall")),
    "constant": ((), ("contraction",)),
    "volume_constant": (("fraction",), ("contraction",)),
    "table": (("time_s", "contraction_percent"), ()),
    "joint_angles": (("file", "column"), ("time_column",)),
}


_PCT = dict(kind="dimensionless", ge=0.0, lt=1.0, display="%")


@dataclass(frozen=True)
class Motion:
    """How a muscle's length is prescribed (the paper's Figure 8 model takes it as an input).

    kinds:
      stroke          contraction follows each charge/vent command after a delay, over rise/fall
                      (smooth; defaults: the muscle type's stroke_contraction, 0.1 s, 0.3 s, 0.3 s)
      constant        fixed contraction (default 0 %)
      volume_constant fixed volume: rest volume + fraction x (volume at the stroke contraction -
                      rest volume) (the paper's Fig. 16 "muscle volume constant")
      table           time_s = [...], contraction_percent = [...], monotone cubic between points
      joint_angles    a CSV of joint angles in degrees (file, column, time_column = "time_s")
                      turned into muscle length through the muscle type's crank geometry
    """
    kind: str = choice(tuple(MOTION_KINDS))
    contraction: float | None = quantity(default=None, **_PCT)
    delay: float = quantity("time", ge=0.0, display="s", default=0.1)
    rise: float = quantity("time", gt=0.0, display="s", default=0.3)
    fall: float = quantity("time", gt=0.0, display="s", default=0.3)
    fraction: float | None = quantity("dimensionless", ge=0.0, le=1.0, display="%", default=None)
    time_s: tuple = ()
    contraction_percent: tuple = ()
    file: str | None = None
    column: str | None = None
    time_column: str = "time_s"

    @classmethod
    def from_raw(cls, raw, path: str) -> "Motion":
        if not isinstance(raw, dict) or "kind" not in raw:
            raise ScenarioError(path, raw, f"expected a table with kind = one of {', '.join(MOTION_KINDS)}")
        kind = parse_field(raw["kind"], dict(choices=tuple(MOTION_KINDS)), f"{path}.kind")
        required, optional = MOTION_KINDS[kind]
        allowed = set(required) | set(optional) | {"kind"}
        for key in raw:
            if key not in allowed:
                raise unknown_key_error(path, key, allowed)
        for key in required:
            if key not in raw:
                raise ScenarioError(f"{path}.{key}", MISSING, f"required for kind {kind!r}")
        fields = {f.name: f for f in dataclasses.fields(cls)}
        kw = {"kind": kind}
        for key in ("contraction", "delay", "rise", "fall", "fraction"):
            if key in raw:
                kw[key] = parse_field(raw[key], fields[key].metadata, f"{path}.{key}")
        if kind == "table":
            ts, cs = raw["time_s"], raw["contraction_percent"]
            for key, arr in (("time_s", ts), ("contraction_percent", cs)):
                if not isinstance(arr, list) or not arr or not all(
                        isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                        for x in arr):
                    raise ScenarioError(f"{path}.{key}", arr, "expected a non-empty list of finite numbers")
            if len(ts) != len(cs):
                raise ScenarioError(f"{path}.contraction_percent", cs,
                                    f"must have as many entries as time_s ({len(ts)})")
            if any(b <= a for a, b in zip(ts, ts[1:])):
                raise ScenarioError(f"{path}.time_s", ts, "times must increase")
            for c in cs:
                if not 0.0 <= c < 100.0:
                    raise ScenarioError(f"{path}.contraction_percent", c, "must be in [0, 100)")
            kw["time_s"] = tuple(float(x) for x in ts)
            kw["contraction_percent"] = tuple(float(x) for x in cs)
        if kind == "joint_angles":
            for key in ("file", "column", "time_column"):
                if key in raw:
                    if not isinstance(raw[key], str) or not raw[key]:
                        raise ScenarioError(f"{path}.{key}", raw[key], "expected text")
                    kw[key] = raw[key]
        return cls(**kw)


@dataclass(frozen=True)
class Muscle:
    """One muscle in the circuit: its type, its valve program and how its length moves.

    ``program_ref`` names the entry of ``[programs]`` the program came from ("" for a program
    written in the muscle's own table); a variant of that entry reaches every muscle using it.
    """
    type: str = field(metadata=dict(choices_from="muscle_types"))
    program: Program = field(default_factory=Program)
    motion: Motion = field(default_factory=lambda: Motion("stroke"))
    initial_pressure_gauge: float | None = quantity("pressure", ge=GAUGE_MIN, le=GAUGE_MAX, display="bar",
                                                    default=None)
    program_ref: str = ""

    @classmethod
    def from_raw(cls, raw, path: str, programs: dict | None = None) -> "Muscle":
        if not isinstance(raw, dict):
            raise ScenarioError(path, raw, "expected a muscle table")
        allowed = {"type", "program", "motion", "initial_pressure_gauge"}
        for key in raw:
            if key not in allowed:
                raise unknown_key_error(path, key, allowed)
        if "type" not in raw:
            raise ScenarioError(f"{path}.type", MISSING, "required setting is missing")
        mtype = unwrap(raw["type"])
        if not isinstance(mtype, str):
            raise ScenarioError(f"{path}.type", mtype, "expected the name of a muscle type")
        prog_raw = raw.get("program")       # none: the muscle must be under a closed-loop controller
        ref = ""
        if prog_raw is None:
            program = Program()
        elif isinstance(prog_raw, str):
            if programs is None or prog_raw not in programs:
                known = ", ".join(sorted(programs or {})) or "none defined"
                raise ScenarioError(f"{path}.program", prog_raw,
                                    f"must name a program in [programs] (known: {known}) or be a table")
            program, ref = programs[prog_raw], prog_raw
        else:
            program = Program.from_raw(prog_raw, f"{path}.program")
        motion = Motion.from_raw(raw.get("motion", {"kind": "stroke"}), f"{path}.motion")
        p0 = None
        if "initial_pressure_gauge" in raw:
            p0 = parse_field(raw["initial_pressure_gauge"],
                             dataclasses.fields(cls)[3].metadata, f"{path}.initial_pressure_gauge")
        return cls(mtype, program, motion, p0, ref)


@dataclass(frozen=True)
class Controller:
    """The microcontroller loop that samples commands: valve states change only at its samples.

    Its rate is at most CONTROLLER_RATE_MAX, the board's: the loop reads its sensors each sample,
    and one conversion of the ATmega2560's ADC at its fastest recommended clock takes 13 µs."""
    rate: float = quantity("frequency", gt=0.0, le=CONTROLLER_RATE_MAX, display="Hz", default=1000.0,
                           why="the board's loop reads a sensor each sample, and one ADC conversion takes 13 µs "
                               "(13 clocks at the fastest recommended ADC clock, 1 MHz)")


@dataclass(frozen=True)
class Solver:
    """The integration method, its tolerances and the wall-time limit of one run (a stiff circuit,
    e.g. a tiny chamber behind a large valve, forces steps of microseconds: the run stops with a
    hint instead of going on for hours).

    ``method`` is the integration method by name, with its own settings
    (:mod:`frogsim.scenario.methods`; the methods are the modules of :mod:`frogsim.engine.methods`):
    the default, "dopri-rosenbrock", is adaptive, and reads ``rtol`` (which also scales the state's
    absolute tolerances) and ``max_step``; a fixed-step method reads its own ``step``."""
    rtol: float = quantity("dimensionless", gt=1e-13, le=1e-2, default=1e-7)
    max_step: float = quantity("time", gt=0.0, display="ms", default=0.05)
    max_wall_time: float = quantity("time", gt=0.0, le=1e7, display="s", default=300.0,
                                    doc="wall-clock seconds one run may take (frogsim.simulate)")
    method: MethodSettings = None

    def __post_init__(self):
        if self.method is None:             # no method written: the registry's default, its defaults
            object.__setattr__(self, "method", default_settings())


# --- closed-loop controllers ([controllers.NAME]): the shared setpoint and sensor types ---------------------
# (each controller kind's settings live in its own module, frogsim.control.kinds, found through
# the registry frogsim.scenario.kinds)
SETPOINT_KINDS = ("constant", "steps", "sine", "table")
SETPOINT_FIELDS = {"constant": ("value",), "steps": ("steps",), "sine": ("mean", "amplitude", "frequency", "start"),
                   "table": ("file", "time_column", "column")}


@dataclass(frozen=True)
class Setpoint:
    """A pressure setpoint (gauge) as a function of time, evaluated in compiled code at each sample.

    Written "3 bar" (constant) or as a table with a kind:
      constant  { kind = "constant", value = "3 bar" }
      steps     { kind = "steps", steps = [ { at = "0 s", value = "0 bar" }, { at = "0.1 s", value = "3 bar" } ] }
                (the value of the last step at or before t; the first before it)
      sine      { kind = "sine", mean = "3 bar", amplitude = "1 bar", frequency = "0.5 Hz", start = "0 s" }
                (mean before start, mean + amplitude sin(2 pi f (t - start)) from it)
      table     { kind = "table", file = "sp.csv", time_column = "time_s", column = "pressure_bar" }
                (a CSV of times [s] and gauge pressures [bar], linear between rows, constant outside)

    A table's file is read once, by the loader (:func:`with_table`): its rows are ``knots``
    ((t [s], value [SI]), ...) and ``digest`` the SHA-256 of the file's bytes (for a run's
    manifest); nothing reads the file again.
    """
    SCALE: ClassVar[float] = BAR        # a table's column (bar gauge) in SI
    kind: str = choice(SETPOINT_KINDS, default="constant")
    value: float | None = quantity("pressure", ge=GAUGE_MIN, le=GAUGE_MAX, display="bar", default=None)
    mean: float | None = quantity("pressure", ge=GAUGE_MIN, le=GAUGE_MAX, display="bar", default=None)
    amplitude: float | None = quantity("pressure", ge=0.0, le=GAUGE_MAX, display="bar", default=None)
    frequency: float | None = quantity("frequency", gt=0.0, le=1e3, display="Hz", default=None)
    start: float = quantity("time", ge=0.0, display="s", default=0.0)
    steps: tuple = ()
    file: str | None = None
    time_column: str = "time_s"
    column: str = "pressure_bar"
    knots: tuple = ()
    digest: str = ""

    def unused(self, name: str) -> str:
        if name == "kind" or name in SETPOINT_FIELDS[self.kind]:
            return ""
        return f"not used by setpoint kind {self.kind!r} (it uses: {', '.join(SETPOINT_FIELDS[self.kind])})"

    def bounds(self) -> tuple[float, float]:
        """Lowest and highest value [SI: Pa gauge, rad, duty] the setpoint takes."""
        if self.kind == "constant":
            return self.value, self.value
        if self.kind == "sine":
            return self.mean - self.amplitude, self.mean + self.amplitude
        vals = [p for _, p in self.points()]
        return min(vals), max(vals)

    def points(self) -> tuple:
        """((t [s], value [SI]), ...): the steps, or a table's rows."""
        return self.steps if self.kind == "steps" else self.knots

    def check_complete(self, path: str, word: str = "setpoint kind") -> None:
        """Every setting the setpoint's kind needs is there (a variant may have left one out)."""
        for key in SETPOINT_FIELDS[self.kind]:
            if key not in ("start", "time_column", "column") and getattr(self, key) in (None, ()):
                raise ScenarioError(f"{path}.{key}", MISSING, f"required for {word} {self.kind!r}")

    @classmethod
    def from_raw(cls, raw, path: str) -> "Setpoint":
        raw = unwrap(raw)
        fields = {f.name: f.metadata for f in dataclasses.fields(cls)}
        if not isinstance(raw, dict):
            return cls("constant", value=parse_field(raw, fields["value"], path))
        kind = parse_field(raw.get("kind", "constant"), fields["kind"], f"{path}.kind")
        allowed = set(SETPOINT_FIELDS[kind]) | {"kind"}
        for key in raw:
            if key not in allowed:
                raise unknown_key_error(path, key, allowed)
        required = {"constant": ("value",), "steps": ("steps",), "sine": ("mean", "amplitude", "frequency"),
                    "table": ("file",)}[kind]
        for key in required:
            if key not in raw:
                raise ScenarioError(f"{path}.{key}", MISSING, f"required for setpoint kind {kind!r}")
        kw = {"kind": kind}
        for key in ("value", "mean", "amplitude", "frequency", "start"):
            if key in raw:
                kw[key] = parse_field(raw[key], fields[key], f"{path}.{key}")
        if kind == "steps":
            kw["steps"] = timed_steps(raw["steps"], f"{path}.steps", "value", fields["value"],
                                      '{ at = "<time>", value = "<pressure>" }')
        for key in ("file", "time_column", "column"):
            if key in raw:
                if not isinstance(unwrap(raw[key]), str) or not unwrap(raw[key]):
                    raise ScenarioError(f"{path}.{key}", raw[key], "expected text")
                kw[key] = unwrap(raw[key])
        return cls(**kw)


@dataclass(frozen=True)
class Sensor:
    """The pressure sensor between the muscle and its controller: first-order lag, then Gaussian
    noise (seeded: the same seed gives the same run), then an ADC of ``bits`` (at least 1) over
    0..full_scale gauge (no bits written: no quantisation)."""
    noise: float = quantity("pressure", ge=0.0, le=GAUGE_MAX, display="bar", default=0.0,
                            doc="standard deviation of the noise")
    seed: int = integer(ge=0, le=2**31 - 1, default=0)
    bits: int | None = integer(ge=1, le=24, default=None, doc="ADC resolution (none: no quantisation)")
    full_scale: float = quantity("pressure", gt=0.0, le=GAUGE_MAX, display="bar", default=10.0 * BAR)
    lag: float = quantity("time", ge=0.0, le=1.0, display="ms", default=0.0)


@dataclass(frozen=True)
class AngleSetpoint(Setpoint):
    """A joint-angle setpoint, written as :class:`Setpoint` with angles (degrees or radians):
    "20 deg", steps, a sine (mean, amplitude) or a table (CSV column ``angle_deg``, degrees)."""
    SCALE: ClassVar[float] = math.pi / 180.0
    value: float | None = quantity("angle", ge=-math.pi, le=math.pi, display="deg", default=None)
    mean: float | None = quantity("angle", ge=-math.pi, le=math.pi, display="deg", default=None)
    amplitude: float | None = quantity("angle", ge=0.0, le=math.pi, display="deg", default=None)
    column: str = "angle_deg"


@dataclass(frozen=True)
class DutySchedule(Setpoint):
    """An open-loop PWM duty as a function of time, written as :class:`Setpoint` with duties
    (fractions 0..1 or percentages): "steps", a "sine" (mean, amplitude) or a "table" (CSV column
    ``duty``, fractions). The duty of each PWM period is the schedule's value at the period's
    first sample."""
    SCALE: ClassVar[float] = 1.0
    value: float | None = quantity("dimensionless", ge=0.0, le=1.0, display="%", default=None)
    mean: float | None = quantity("dimensionless", ge=0.0, le=1.0, display="%", default=None)
    amplitude: float | None = quantity("dimensionless", ge=0.0, le=1.0, display="%", default=None)
    column: str = "duty"


@dataclass(frozen=True)
class AngleSensor:
    """The joint-angle sensor of a joint-angle controller (an encoder): first-order lag, then
    Gaussian noise (seeded), then ``bits`` (at least 1) of resolution over 0..full_scale (no bits
    written: none). The velocity the law reads goes through the same lag (no noise, no
    quantisation)."""
    noise: float = quantity("angle", ge=0.0, le=math.pi, display="deg", default=0.0,
                            doc="standard deviation of the noise")
    seed: int = integer(ge=0, le=2**31 - 1, default=0)
    bits: int | None = integer(ge=1, le=24, default=None, doc="encoder resolution (none: no quantisation)")
    full_scale: float = quantity("angle", gt=0.0, le=2.0 * math.pi, display="deg", default=0.5 * math.pi)
    lag: float = quantity("time", ge=0.0, le=1.0, display="ms", default=0.0)


def with_table(sp: Setpoint, base_dir: str, path: str) -> Setpoint:
    """A table setpoint with its file read (``knots``, ``digest``); other setpoints as they are.

    The rows ((t [s], value [SI]), ...) of the CSV (times increasing; the column times
    ``sp.SCALE``: bar gauge -> Pa, degrees -> rad, duty fractions as they are)."""
    if sp is None or sp.kind != "table" or sp.knots:
        return sp
    import hashlib
    from pathlib import Path

    from frogsim.scenario.tables import read_table
    where = f"{path}.file"
    file = Path(base_dir) / sp.file
    # a regular UTF-8 file, every row as many fields as the header (frogsim.scenario.tables)
    table = read_table(file, where, numbers=False)
    text = read_text(file, where)
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
    digest = hashlib.sha256(text.encode()).hexdigest()
    return dataclasses.replace(sp, knots=tuple(out), digest=digest)
