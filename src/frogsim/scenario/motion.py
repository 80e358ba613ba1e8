"""Prescribed muscle motions: each muscle's length over time as cubic Hermite knots.

The paper's Figure 8 model takes the muscle length as an input ("the muscle length is derived from
the joint angle"); :class:`frogsim.scenario.schema.Motion` says how, and this module turns it into
knots (times, lengths, slopes) or a fixed volume. Building them also validates what only shows
once they exist (overlapping strokes, joint-angle files), so the loader and every variant call it.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from frogsim.errors import ScenarioError
from frogsim.physics.muscle import crank_muscle_length

if TYPE_CHECKING:   # annotations only
    from frogsim.scenario.core import Scenario


@dataclass(frozen=True)
class MotionKnots:
    """Cubic Hermite knots of one muscle's length: times [s], lengths [m], slopes [m/s].

    Cached and shared (:func:`muscle_knots`): read them, never change them in place."""
    t: np.ndarray
    L: np.ndarray
    dL: np.ndarray
    fixed_volume: float = 0.0   # > 0: the total volume is held at this value [m^3]


def command_sample(t: float, rate: float) -> int:
    """The index k of the first controller sample at or after t [s] (t_k = k / rate; commands are
    issued at samples)."""
    return math.ceil(t * rate - 1e-9)


def command_time(t: float, rate: float) -> float:
    """The first controller sample at or after t [s] (commands are issued at samples)."""
    return command_sample(t, rate) / rate


def _stroke_knots(mname, m, mt, L0, rate):
    eps = mt.stroke_contraction if m.motion.contraction is None else m.motion.contraction
    L_c = L0 * (1.0 - eps)
    ts, Ls = [0.0], [L0]
    current = L0
    for t_cmd, state in m.program.steps:
        if state == "hold":
            continue
        target = L_c if state == "charge" else L0
        if target == current:
            continue
        dur = m.motion.rise if state == "charge" else m.motion.fall
        t0 = command_time(t_cmd, rate) + m.motion.delay
        if t0 <= ts[-1]:
            key = "fall" if state == "charge" else "rise"
            raise ScenarioError(f"muscles.{mname}.motion.{key}", f"{getattr(m.motion, key):g} s",
                                f"the previous stroke must end before the next command moves the "
                                f"muscle (at {t_cmd:g} s + delay)")
        ts += [t0, t0 + dur]
        Ls += [current, target]
        current = target
    t = np.array(ts)
    return MotionKnots(t, np.array(Ls), np.zeros_like(t))


def _pchip_knots(t, Lv):
    from scipy.interpolate import PchipInterpolator
    t = np.asarray(t, float)
    Lv = np.asarray(Lv, float)
    if t.size == 1:
        return MotionKnots(t, Lv, np.zeros(1))
    slopes = PchipInterpolator(t, Lv).derivative()(t)
    return MotionKnots(t, Lv, slopes)


def _joint_knots(mname, m, mt, L0, base_dir):
    from frogsim.scenario.tables import read_table
    path = Path(base_dir) / m.motion.file
    where = f"muscles.{mname}.motion.file"
    # a regular UTF-8 file, every row as many fields as the header (frogsim.scenario.tables)
    df = read_table(path, where, numbers=False)
    for key in (m.motion.time_column, m.motion.column):
        if key not in df.columns:
            raise ScenarioError(f"muscles.{mname}.motion.column", key,
                                f"must be a column of {path.name} ({', '.join(map(str, df.columns))})")
    try:
        t = df[m.motion.time_column].to_numpy(float)
        ang = np.radians(df[m.motion.column].to_numpy(float))
    except (TypeError, ValueError):
        raise ScenarioError(where, m.motion.file, f"columns {m.motion.time_column!r} and "
                                                  f"{m.motion.column!r} must hold numbers") from None
    if t.size == 0 or t.ndim != 1 or ang.ndim != 1:
        raise ScenarioError(where, m.motion.file, "expected at least one row of numbers")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(ang))) or np.any(np.diff(t) <= 0):
        raise ScenarioError(where, m.motion.file, "times must be finite and increasing, angles finite")
    Lv = np.array([crank_muscle_length(a, mt.anchor_distance, mt.crank_radius, mt.rest_angle, L0,
                                       float(mt.side)) for a in ang])
    contraction = 1.0 - Lv / L0
    worst = float(contraction.max())
    if worst > mt.max_contraction:
        raise ScenarioError(where, m.motion.file,
                            f"joint angles contract the muscle by {worst:.1%}, beyond its "
                            f"max_contraction ({mt.max_contraction:.0%})")
    if float(contraction.min()) < -1e-9:
        raise ScenarioError(where, m.motion.file,
                            f"joint angles stretch the muscle {-contraction.min():.1%} beyond its rest "
                            "length; the crank geometry (rest_angle, side) may not match the data")
    return _pchip_knots(t, Lv)


def build_motions(scenario: Scenario) -> dict[str, MotionKnots]:
    """Length knots (or a fixed volume) for every muscle; raises ScenarioError on bad motions.

    Each muscle's knots depend only on the muscle, its type, the controller rate and (for a
    joint-angle file) the file: they are built once per distinct combination and reused, so a
    variant that changes something else (a valve, the source) costs no rebuild.
    """
    rate = scenario.controller.rate
    out = {}
    for mname, m in scenario.muscles.items():
        file_key = None
        if m.motion.kind == "joint_angles":
            path = Path(scenario.base_dir) / m.motion.file
            st = path.stat() if path.is_file() else None
            file_key = (st.st_mtime_ns, st.st_size) if st else None
        out[mname] = muscle_knots(mname, m, scenario.muscle_types[m.type], rate, file_key, scenario.base_dir)
    return out


@functools.lru_cache(maxsize=4096)
def muscle_knots(mname, m, mt, rate, file_key, base_dir) -> MotionKnots:
    """The knots of one muscle (see :func:`build_motions`); file_key identifies a joint-angle file."""
    L0 = mt.nominal_length
    kind = m.motion.kind
    if kind == "stroke":
        knots = _stroke_knots(mname, m, mt, L0, rate)
    elif kind == "constant":
        eps = m.motion.contraction or 0.0
        knots = MotionKnots(np.zeros(1), np.array([L0 * (1.0 - eps)]), np.zeros(1))
    elif kind == "volume_constant":
        eps = mt.stroke_contraction if m.motion.contraction is None else m.motion.contraction
        v_rest = mt.volume(L0)          # the muscle type's actuator volume (frogsim.scenario.actuators)
        v_max = max(mt.volume(L0 * (1.0 - e)) for e in np.linspace(0.0, eps, 201))
        v = v_rest + m.motion.fraction * (v_max - v_rest) + mt.dead_volume
        knots = MotionKnots(np.zeros(1), np.array([L0]), np.zeros(1), fixed_volume=v)
    elif kind == "table":
        Lv = L0 * (1.0 - np.asarray(m.motion.contraction_percent) / 100.0)
        knots = _pchip_knots(m.motion.time_s, Lv)
    else:
        knots = _joint_knots(mname, m, mt, L0, base_dir)
    return knots


def whole_steps(value: float, step: float) -> int | None:
    """The whole number n >= 1 of ``step``s that ``value`` is, to a millionth of a step (the
    ratio's rounding error, 0.3 / 0.1 = 2.9999999999999996, is far below that); None if it is not
    a whole number of steps."""
    r = value / step
    n = round(r)
    return n if n >= 1 and abs(r - n) <= 1e-6 else None


def output_times(duration: float, interval: float) -> np.ndarray:
    """The output grid [s]: whole sample indices t_k = k * interval, the last row at the duration
    exactly.

    When the duration is a whole number n of intervals (:func:`whole_steps`), the grid has n + 1
    rows and its last time is set to the duration: 0.3 s / 0.1 s is 2.9999999999999996 in floating
    point and 3 * 0.1 = 0.30000000000000004, one unit in the last place past the end, a row no run
    reaches. Otherwise one more, shorter, last row at the duration follows the whole intervals. So
    every row lies in [0, duration], the grid is strictly increasing and ends at the duration: a
    run that reaches its end writes every row.
    """
    n = whole_steps(duration, interval)
    if n is not None:
        t = np.arange(n + 1) * interval
        t[-1] = duration
        return t
    return np.append(np.arange(math.floor(duration / interval) + 1) * interval, duration)
