"""Robot scenarios: the robot of a parameter set, a gait, and where it runs (water or air, free or
fixed), validated into a :class:`RobotScenario`.

A robot scenario file holds the run's own settings and may override any parameter-set value like
any scenario (:mod:`frogsim.scenario.load`); instead of ``[muscles]`` it has ``[robot]`` and
``[gait]``, from which the muscles (two per joint and leg, or one and a spring) and their valve
programs are made::

    name = "swim"
    parameters = "fan2017"
    output_interval = "10 ms"
    [robot]
    environment = "water"     # "water" or "air"
    base = "free"             # "free": it swims; "fixed": the body is held on a base
    planar = true             # body held to the horizontal plane (x, y, yaw)
    recovery = "muscle"       # "muscle" (antagonistic pairs) or "spring" (paper Sec. 4.1 variant)
    timestep = "1 ms"         # MuJoCo step; the pneumatics adapt their own steps inside it
    [gait]                    # see frogsim.control.gait
"""
from __future__ import annotations

from dataclasses import dataclass, field

from frogsim.scenario.fields import build, choice, flag, quantity
from frogsim.scenario.core import Scenario
from frogsim.scenario.schema import Motion, Muscle
from frogsim.control.gait import Gait, muscle_programs
from frogsim.errors import MISSING, ScenarioError
from frogsim.scenario.load import merged_raw, scenario_from_raw
from frogsim.robot.geometry import Layout, layout
from frogsim.robot.params import JOINTS, SIDES, RobotParams, robot_params_from_raw


@dataclass(frozen=True)
class RobotOptions:
    """Where and how the robot runs (the scenario's ``[robot]`` table)."""
    environment: str = choice(("water", "air"), default="water")
    base: str = choice(("free", "fixed"), default="free")
    planar: bool = flag(default=True)
    recovery: str = choice(("muscle", "spring"), default="muscle")
    timestep: float = quantity("time", gt=0.0, le=0.01, display="ms", default=0.001)


@dataclass(frozen=True)
class RobotScenario:
    """Everything about one robot run: pneumatics (a validated Scenario), robot, gait, options."""
    name: str
    pneumatic: Scenario
    robot: RobotParams
    options: RobotOptions
    gait: Gait
    layout: Layout
    muscles: dict              # muscle name -> (joint, side, group "drive"/"recover")
    raw: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def duration(self) -> float:
        return self.gait.duration

    @property
    def medium_density(self) -> float:
        """Density of the water, or of the air at the ambient state p/(R T) [kg/m^3]."""
        if self.options.environment == "water":
            return self.robot.water.density
        a = self.pneumatic.air
        return a.atmospheric_pressure_abs / (a.gas_constant * a.ambient_temperature)


def muscle_names(recovery: str) -> dict:
    """Muscle name -> (joint, side, group): "hip_left" drives, "hip_left_recovery" recovers."""
    out = {}
    for side in SIDES:
        for j in JOINTS:
            out[f"{j}_{side}"] = (j, side, "drive")
    if recovery == "muscle":
        for side in SIDES:
            for j in JOINTS:
                out[f"{j}_{side}_recovery"] = (j, side, "recover")
    return out


def load_robot_scenario(source, cycles: int | None = None) -> RobotScenario:
    """Load and validate a robot scenario (a TOML path, a shipped name such as "swim", or a dict).

    ``cycles`` overrides ``gait.cycles``. Raises ScenarioError naming field, value and what is
    allowed; nothing is run.
    """
    raw, base_dir = merged_raw(source)
    if raw.get("muscles"):
        raise ScenarioError("muscles", "(a table)", "a robot scenario makes its muscles from "
                                                    "[joints] and [gait]: remove [muscles]")
    if "gait" not in raw:
        raise ScenarioError("gait", MISSING, "a robot scenario needs a [gait] table "
                                             "(see frogsim.control.gait)")
    options = build(RobotOptions, raw.get("robot", {}), "robot")
    gait = Gait.from_raw(raw["gait"], JOINTS, cycles)
    types = raw.get("muscle_types")
    robot = robot_params_from_raw(raw, types if isinstance(types, dict) else {})
    names = muscle_names(options.recovery)
    programs = muscle_programs(gait, {n: (j, g) for n, (j, _, g) in names.items()})
    muscles = {name: Muscle(type=robot.joints[joint].muscle_type, program=programs[name],
                            motion=Motion("constant"))
               for name, (joint, _, _) in names.items()}
    pneumatic = scenario_from_raw(raw, base_dir, duration=gait.duration, muscles=muscles)
    lay = layout(robot, pneumatic.muscle_types)
    return RobotScenario(name=pneumatic.name, pneumatic=pneumatic, robot=robot, options=options,
                         gait=gait, layout=lay, muscles=names, raw=raw)
