"""Kind "program": the muscle keeps its open-loop program (no compiled law, no row)."""
from __future__ import annotations

from dataclasses import dataclass

from frogsim.scenario.kinds import ControllerSettings, register


@register
@dataclass(frozen=True)
class ProgramSettings(ControllerSettings):
    """The muscle runs its open-loop program (it must have one); nothing else to set."""
    KIND = "program"
    closed_loop = False

    def write_rows(self, name: str, ctx) -> list:
        return []
