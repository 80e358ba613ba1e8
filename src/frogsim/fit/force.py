"""Force-contraction tables in: fitting the muscle force law (``[muscle_force]``) to a datasheet or a
test bench.

A force table is a CSV (or Parquet) file with three columns, each header naming the quantity and
its unit in brackets, one row per measured point, several pressures in one file::

    pressure [bar gauge], contraction [%], force [N]
    1, 0, 253
    1, 2, 123

* ``pressure``: the muscle's pressure, gauge or abs (``[bar gauge]``, ``[kPa abs]``; abs values
  are made gauge with the scenario's atmospheric pressure); it must not be negative (gauge).
* ``contraction``: 1 - L/L0, a percentage (``[%]``) or a fraction (``[-]`` or ``[1]``), below
  100 %; negative for a muscle stretched beyond its rest length.
* ``force``: the muscle's tension (``[N]``, ``[kN]``, ``[lbf]``). Rows with a negative force (a push
  needed to hold the muscle shorter than it contracts on its own) cannot be matched by a
  tension-only law: they are left out, and the fit's warnings say how many.
* ``direction`` (optional, no unit): ``loading`` or ``unloading`` on each row, the branch of a
  measured hysteresis loop the point lies on, given explicitly (not derived from the order of the
  rows: a table may list its points in any order, and a datasheet's loop is read off a figure
  branch by branch). At constant pressure, loading is the muscle being stretched (its contraction
  falling, its tension rising) and unloading the muscle shortening (contraction rising, tension
  falling).

With hysteresis (the parameter set's ``hysteresis = "maxwell-slip"``, or a fit of
``muscle_force.slip_per_pressure`` / ``muscle_force.slip_strain``), a row's model force is the
static law less the Maxwell-slip force on its branch of the major loop between the smallest and
largest contraction the table holds at that pressure (each branch leaves its turning point with
the elements settled there: :func:`frogsim.physics.hysteresis.settle_on_major_loop`). A row
without a direction is on the static law (the loop's middle).

The model of a row is :func:`frogsim.components.dmsp20.law_forces`: the parameter set's force law
(:mod:`frogsim.physics.muscle_force`) for the braid of one muscle type of the base scenario
(inner diameter, braid angle), with the constants of ``[muscle_force]``, some of them fitted.
Every refusal is a one-line :class:`frogsim.ScenarioError` naming the file and the column.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from frogsim.errors import UNKNOWN, ScenarioError
from frogsim.fit.traces import _col_error, _parse_header, _pressure_unit, _read_table, _unit_scale, numeric_column
from frogsim.scenario.units import parse_quantity

#: the force law's constants, in the order of :func:`frogsim.physics.muscle_force.muscle_force`
CONSTANTS = ("force_scale", "strain_scale", "stiffness", "stretch_stiffness", "stretch_quadratic")
#: the hysteresis's fittable settings (the element count and the switch are not fitted)
HYSTERESIS = ("slip_per_pressure", "slip_strain")
PREFIX = "muscle_force."
COLUMNS = ("pressure", "contraction", "force")
#: the optional label column: its values, and the branch each means (+1: contraction rising)
DIRECTION = "direction"
DIRECTIONS = {"loading": -1, "unloading": 1}
#: braid settings of a muscle type that also enter the force law
GEOMETRY = ("inner_diameter", "braid_angle")


def law_meta() -> dict:
    """Dotted path -> field metadata of the force law's constants (``muscle_force.<name>``)."""
    from frogsim.robot.params import MuscleForceLaw
    return {PREFIX + f.name: dict(f.metadata) for f in dataclasses.fields(MuscleForceLaw)
            if f.name in CONSTANTS + HYSTERESIS}


def base_law(scenario):
    """The base scenario's parameter set's force law (:class:`frogsim.robot.params.MuscleForceLaw`)."""
    from frogsim.robot.params import parameter_set_law
    return parameter_set_law(scenario, "a force table cannot be fitted with it")


@dataclass(frozen=True)
class ForceTable:
    """One force-contraction table in SI: ``pressure`` [Pa gauge], ``contraction`` [-], ``force``
    [N], the rows with a negative force already left out (``dropped`` counts them)."""
    path: str
    pressure: np.ndarray
    contraction: np.ndarray
    force: np.ndarray
    columns: dict               # quantity -> header as written
    dropped: int = 0
    direction: np.ndarray | None = None     # per row: +1 unloading, -1 loading (None: no column)

    @property
    def name(self) -> str:
        return Path(self.path).name

    def pressures(self) -> list[float]:
        """The distinct pressures [Pa gauge], lowest first."""
        return sorted(set(self.pressure.tolist()))


def _dimensionless_scale(fname: str, col: str, unit: str) -> float:
    if unit.strip() in ("-", "1", ""):
        return 1.0
    try:
        return parse_quantity(f"1 {unit}", "dimensionless")
    except Exception:  # pint raises several error types for bad text or dimensions
        raise _col_error(fname, col, f"unit [{unit}] is not a fraction or a percentage: write [%] or [-]") from None


def read_force_table(path, scenario) -> ForceTable:
    """Read and check a force table (module docstring); values in SI.

    Refused, each with a one-line ScenarioError naming file and column: a header without a unit, a
    unit of the wrong kind, a pressure neither gauge nor abs, a column other than pressure,
    contraction and force, a missing column, non-numeric or missing values (NaN), a negative
    gauge pressure, a contraction of 100 % or more, no row with a positive force.
    """
    path = Path(path)
    fname = path.name
    df = _read_table(path, "force table")
    if df.shape[0] < 1:
        raise ScenarioError(f"force table {fname!r}", UNKNOWN, "holds no rows of data")
    patm = scenario.air.atmospheric_pressure_abs
    cols, unknown = {}, []
    direction = None
    for col in df.columns:
        col = str(col)
        if col.strip().lower() == DIRECTION:
            direction = _directions(df, fname, col)
            continue
        name, unit = _parse_header(fname, col)
        key = name.lower()
        if key not in COLUMNS:
            unknown.append(col)
            continue
        if key in cols:
            raise _col_error(fname, col, f"a second {key} column (the first is {cols[key][0]!r})")
        if key == "pressure":
            scale, offset = _pressure_unit(fname, col, unit, patm)
            cols[key] = (col, scale, offset - patm)            # to Pa gauge
        elif key == "contraction":
            cols[key] = (col, _dimensionless_scale(fname, col, unit), 0.0)
        else:
            cols[key] = (col, _unit_scale(fname, col, unit, "force", "a force unit such as N or kN"), 0.0)
    if unknown:
        raise ScenarioError(f"force table {fname!r}", UNKNOWN,
                            f"columns it cannot use: {', '.join(map(repr, unknown))} (a force table has "
                            "pressure, contraction and force, each with its unit, and optionally direction)")
    missing = [k for k in COLUMNS if k not in cols]
    if missing:
        raise ScenarioError(f"force table {fname!r}", UNKNOWN,
                            f"no {' and no '.join(missing)} column: the header must name pressure [bar gauge], "
                            "contraction [%] and force [N]")

    def numbers(key: str) -> np.ndarray:
        col, scale, offset = cols[key]
        return numeric_column(df, fname, col) * scale + offset

    p, eps, force = numbers("pressure"), numbers("contraction"), numbers("force")
    neg = np.flatnonzero(p < -1e-9 * max(1.0, patm))
    if neg.size:
        raise _col_error(fname, cols["pressure"][0], f"negative gauge pressure ({p[neg[0]] / 1e5:g} bar) in "
                                                     f"data row {neg[0] + 1}: the muscle law needs p >= 0 gauge")
    full = np.flatnonzero(eps >= 1.0)
    if full.size:
        raise _col_error(fname, cols["contraction"][0], f"contraction {eps[full[0]] * 100:g} % in data row "
                                                        f"{full[0] + 1}: it must be below 100 %")
    keep = force >= 0.0
    if not keep.any():
        raise _col_error(fname, cols["force"][0], "no row with a positive force (tension) to fit")
    return ForceTable(path=str(path), pressure=np.maximum(p[keep], 0.0), contraction=eps[keep],
                      force=force[keep], columns={k: c[0] for k, c in cols.items()},
                      dropped=int((~keep).sum()),
                      direction=None if direction is None else direction[keep])


def _directions(df, fname: str, col: str) -> np.ndarray:
    """The direction column as +1 (unloading) / -1 (loading), or a ScenarioError naming the row."""
    out = np.zeros(df.shape[0], np.int64)
    for k, v in enumerate(df[col]):
        key = str(v).strip().lower()
        if key not in DIRECTIONS:
            raise _col_error(fname, col, f"{str(v)[:40]!r} in data row {k + 1}: expected loading (the muscle "
                                         "stretched) or unloading (the muscle shortening)")
        out[k] = DIRECTIONS[key]
    return out


class ForceModel:
    """The model forces of one table for a point of the fit (SI values of the fitted paths)."""

    def __init__(self, table: ForceTable, scenario, muscle_type: str, law):
        self.table = table
        self.muscle_type = muscle_type
        self.law = law
        mt = scenario.muscle_types[muscle_type]
        self.geometry = {g: float(getattr(mt, g)) for g in GEOMETRY}
        self.model = law.model

    def constants(self, point: dict) -> list[float]:
        return [float(point.get(PREFIX + k, getattr(self.law, k))) for k in CONSTANTS]

    def braid(self, point: dict) -> tuple[float, float]:
        pre = f"muscle_types.{self.muscle_type}."
        return tuple(float(point.get(pre + g, self.geometry[g])) for g in GEOMETRY)

    def hysteresis(self, point: dict) -> tuple | None:
        """(stiffness, slip) per pascal of the law's slip elements at this point, or None when the
        law has no memory (module docstring)."""
        from frogsim.physics.hysteresis import element_table
        fitted = any(PREFIX + k in point for k in HYSTERESIS)
        if self.law.hysteresis == "none" and not fitted:
            return None
        c, s = (float(point.get(PREFIX + k, getattr(self.law, k))) for k in HYSTERESIS)
        return element_table(self.law.slip_elements, c, s)

    def forces(self, point: dict, pressure=None, contraction=None, direction=None) -> np.ndarray:
        """Model forces [N] at the table's rows (or at the given pressures, contractions and
        directions: +1 unloading, -1 loading, 0 or None the static law)."""
        from frogsim.components.dmsp20 import law_forces
        rows = pressure is None
        pressure = self.table.pressure if rows else np.asarray(pressure, float)
        contraction = self.table.contraction if rows else np.asarray(contraction, float)
        if rows:
            direction = self.table.direction
        d, theta = self.braid(point)
        static = law_forces(pressure, contraction, self.constants(point), d, theta, model=self.model)
        elements = self.hysteresis(point)
        if elements is None or direction is None:
            return static
        return branch_forces(static, pressure, contraction, np.asarray(direction), *elements,
                             self.table.pressure, self.table.contraction)


def branch_forces(static, pressure, contraction, direction, stiffness, slip, table_pressure,
                  table_contraction) -> np.ndarray:
    """Tensions [N] on the major loop's branches: at each row, the static tension less the slip
    elements' force after the branch (direction +1 rising, -1 falling contraction) has left its
    turning point, the table's smallest / largest contraction at that row's pressure; rows of
    direction 0 keep the static tension."""
    from frogsim.physics.hysteresis import settle_on_major_loop
    from frogsim.physics.muscle_force import hysteretic_tension
    out = np.array(static, dtype=float)
    anchors = np.zeros(stiffness.size)
    for k in range(out.size):
        if direction[k] == 0:
            continue
        at = table_contraction[table_pressure == pressure[k]]
        low, high = (float(at.min()), float(at.max())) if at.size else (contraction[k], contraction[k])
        settle_on_major_loop(anchors, min(low, contraction[k]), max(high, contraction[k]), stiffness,
                             slip, direction[k] > 0)
        out[k] = hysteretic_tension(float(static[k]), float(pressure[k]), float(contraction[k]), anchors,
                                    stiffness, slip)
    return out



def worst_errors(table: ForceTable, model: np.ndarray) -> list[dict]:
    """Per pressure: the number of rows, the rms and the worst absolute error of model - measured
    [N], and where the worst occurs (contraction, measured and model force)."""
    out = []
    err = model - table.force
    for p in table.pressures():
        idx = np.flatnonzero(table.pressure == p)
        k = idx[np.argmax(np.abs(err[idx]))]
        out.append({"pressure_Pa_gauge": p, "rows": int(idx.size),
                    "rms_error_N": float(np.sqrt(np.mean(err[idx] ** 2))),
                    "worst_abs_error_N": float(abs(err[k])), "worst_at_contraction": float(table.contraction[k]),
                    "worst_measured_N": float(table.force[k]), "worst_model_N": float(model[k])})
    return out
