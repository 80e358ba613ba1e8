"""Settings and row-writing that the sensed kinds share (not a kind: it registers nothing)."""
from __future__ import annotations

from dataclasses import dataclass, field

from frogsim.errors import MISSING, ScenarioError
from frogsim.scenario.fields import quantity
from frogsim.scenario.kinds import ControllerSettings
from frogsim.scenario.rules import check_pressure_setpoint
from frogsim.scenario.schema import Sensor, Setpoint

DEFAULT_SETTLE = 0.2     # [s] the metrics' settle time when none is written (a tenth of a run not longer)


@dataclass(frozen=True)
class SensedLoop(ControllerSettings):
    """A controller that reads its muscle's pressure through a sensor, with tracking metrics."""
    sensor: Sensor = field(default_factory=Sensor)
    settle: float | None = quantity("time", ge=0.0, display="s", default=None,
                                    doc="tracking metrics count from this time on (default 0.2 s, a "
                                        "tenth of a run not longer than that); must be shorter than the run")

    def settle_time(self, duration: float) -> float:
        """[s] the time from which the tracking metrics of a run of ``duration`` [s] count: the
        written ``settle`` (the rules keep it shorter than the run), else 0.2 s, or a tenth of a
        run not longer than 0.2 s (so that a short run has metrics, over its last nine tenths)."""
        if self.settle is not None:
            return self.settle
        return DEFAULT_SETTLE if duration > DEFAULT_SETTLE else duration / 10.0


@dataclass(frozen=True)
class PressureTracking(SensedLoop):
    """A sensed controller that needs a pressure setpoint the valves can reach."""
    setpoint: Setpoint | None = None

    def check(self, sc, path: str, p_top: float) -> None:
        if self.setpoint is None:
            raise ScenarioError(f"{path}.setpoint", MISSING, f"required for kind {self.KIND!r}")
        check_pressure_setpoint(sc, self.setpoint, f"{path}.setpoint", p_top)
