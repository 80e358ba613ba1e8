"""Kind "program": the muscle keeps its open-loop program (no compiled law, no row).

In the model an open-loop program is a schedule of valve switchings
(:func:`frogsim.circuit.model.build_schedule`); on the board it is a table of the samples at
which the muscle's mode changes (:func:`firmware_table`), read by :func:`fw_law` (the model's
integer twin) and by its C twin. Every muscle without a closed-loop controller runs this way on
the board, the robot's gait too.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from frogsim._jit import jit
from frogsim.control.kinds.spec import ControllerKind, FirmwareTwin
from frogsim.scenario.kinds import ControllerSettings
from frogsim.scenario.motion import command_sample


@dataclass(frozen=True)
class ProgramSettings(ControllerSettings):
    """The muscle runs its open-loop program (it must have one); nothing else to set."""
    KIND = "program"
    closed_loop = False

    def write_rows(self, name: str, ctx) -> list:
        return []


_MODE = {"charge": 1, "hold": 0, "vent": -1}


def firmware_table(program, rate: float) -> np.ndarray:
    """The program as the board's table: entries ``(k << 2) | (mode + 1)`` (int32), one per sample
    k at which the mode (charge 1, hold 0, vent -1) changes, in order. A step at t is issued at
    the first sample at or after it (:func:`frogsim.scenario.motion.command_sample`, the model's
    rule); of steps on one sample the last holds. Before
    the first entry the valves are shut (hold), after the last its mode holds."""
    by_k = {}
    for t, state in program.steps:
        by_k[max(0, command_sample(t, rate))] = _MODE[state]
    out = []
    last = 0
    for k in sorted(by_k):
        if by_k[k] != last:
            out.append((k << 2) | (by_k[k] + 1))
            last = by_k[k]
    return np.array(out, np.int64)


@jit
def fw_law(P, T, mem, k, cp, ca):
    """The mode at sample k: the last table entry at or before k (binary search over the P[0]
    entries; hold before the first). No memory, no sensor."""
    lo = 0
    hi = int(P[0])
    mode = 0
    while lo < hi:
        mid = (lo + hi) >> 1
        e = int(T[mid])
        if (e >> 2) <= k:
            mode = (e & 3) - 1
            lo = mid + 1
        else:
            hi = mid
    return mode


C_NAME = "fs_program"


def c_source() -> str:
    """The C twin of :func:`fw_law`."""
    return """int8_t fs_program(uint32_t k, uint16_t cp, uint16_t ca, int32_t *mem, const int32_t *P,
                  const int32_t *T) {
    int32_t lo = 0, hi = P[0];
    int8_t mode = 0;
    (void)cp; (void)ca; (void)mem;
    while (lo < hi) {
        int32_t mid = (lo + hi) >> 1;
        int32_t e = (int32_t)FS_READ32(&T[mid]);
        if ((uint32_t)(e >> 2) <= k) {
            mode = (int8_t)((e & 3) - 1);
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    return mode;
}
"""


KIND = ControllerKind(
    settings=ProgramSettings, code=None, law=None,     # no row: the model runs the program as a schedule
    firmware=FirmwareTwin(fw_law=fw_law, c_name=C_NAME, c_source=c_source),
    tracks=None, metrics=(), gains=())
