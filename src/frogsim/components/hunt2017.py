"""A published force-hysteresis loop of a FESTO fluidic muscle: Hunt's model of the 10 mm muscle.

Source
    A. Hunt, N. Szczecinski and R. Quinn, "Development and training of a neural controller for hind
    leg walking in a dog robot", Front. Neurorobot. 11:18 (2017): a static model of FESTO's 10 mm
    fluidic muscle (DMSP-10) fitted to the authors' bench measurements, giving the gauge pressure
    that holds a tension F at a contraction eps,

        P = c0 + c1 tan(c2 (eps / (c4 F + eps_max) + c3)) + c5 F + c6 S                    (H)

    with S = 1 on one branch of the loop and 0 on the other: the loop is a constant 15.6 kPa wide
    in pressure at any tension and contraction. The constants are the ones the authors' lab uses
    in its public code (repository Agile-and-Adaptive-Robotics/Bipedal_Robot: file
    Code/Matlab/Functions/HuntEq.m, "Dr. Hunt's equation for the pressure-force-length relationship
    of Festo 10mm BPAs", and a pressure-computation script with the same values in SI, a muscle of
    18.9 cm at 0 kPa and 15.75 cm at 620 kPa); the same repository is the source of the DMSP-20
    data in :mod:`frogsim.components.dmsp20`.

Which branch is which
    The repository labels S only as "inflating / deflating" (one script is unsure of the order),
    so the order is taken from the physics: friction opposes the motion, so a muscle that shortens
    pulls less than one being stretched at the same pressure and contraction. In (H) the S = 1
    branch needs 15.6 kPa more pressure for the same tension, so at a given pressure it pulls less:
    S = 1 is the shortening (unloading) branch, S = 0 the stretched (loading) one.

Checks of the transcription (tests/test_hysteresis_published.py): with no tension the muscle sits
at its rest length at 0 kPa (P(0, 0) = -5.6 kPa, zero within the model's fit) and at its full
contraction eps_max at 620 kPa (P(eps_max, 0) = 623 kPa), as the repository's lengths say.

Units: SI inside (Pa gauge, N, contraction as a fraction). ``python -m frogsim.components.hunt2017
FILE.csv`` writes the loop as a force table with a direction column for ``frogsim fit``
(docs/fitting.md; examples/fit-hysteresis).
"""
from __future__ import annotations

import math

import numpy as np

#: (H)'s constants in SI, as published (module docstring)
C0 = 254.3e3            # [Pa]
C1 = 192.0e3            # [Pa]
C2 = 2.0265             # [-]
C3 = -0.461             # [-]
C4 = -0.331e-3          # [1/N]
C5 = 1.23e3             # [Pa/N]
C6 = 15.6e3             # [Pa]: the loop's width in pressure
#: the muscle's full contraction (18.9 cm at 0 kPa, 15.75 cm at 620 kPa)
REST_LENGTH = 0.189     # [m]
FULL_LENGTH = 0.1575    # [m]
EPS_MAX = (REST_LENGTH - FULL_LENGTH) / REST_LENGTH
#: the pressure range the model was fitted over [Pa gauge] (620 kPa, about 90 psi)
P_MAX = 620e3
#: S of each branch (module docstring: the shortening branch needs the extra pressure)
BRANCH_S = {"loading": 0.0, "unloading": 1.0}


def pressure(contraction: float, tension: float, branch: str) -> float:
    """(H): the gauge pressure [Pa] at which the muscle holds ``tension`` [N] at ``contraction``
    [-] on ``branch`` ("loading": being stretched, "unloading": shortening)."""
    arg = C2 * (contraction / (C4 * tension + EPS_MAX) + C3)
    return C0 + C1 * math.tan(arg) + C5 * tension + C6 * BRANCH_S[branch]


def tension_top(contraction: float) -> float:
    """The top of (H)'s tension domain [N] at ``contraction`` [-]: just below where c4 F + eps_max
    reaches 0 or the tangent's argument pi/2 (whichever comes first)."""
    f_top = EPS_MAX / -C4 * (1.0 - 1e-9)          # c4 F + eps_max > 0
    arg_limit = (math.pi / 2.0) / C2 - C3        # eps / (c4 F + eps_max) below it
    f_arg = (contraction / arg_limit - EPS_MAX) / C4 if contraction > 0.0 else f_top
    return min(f_top, f_arg * (1.0 - 1e-9)) if f_arg > 0.0 else f_top


def tension(p_gauge: float, contraction: float, branch: str) -> float:
    """The tension [N] (H) gives at gauge pressure ``p_gauge`` [Pa] and ``contraction`` [-], or NaN
    where no tension in (H)'s domain balances the pressure: the muscle cannot pull at all (it
    would contract further on its own), or the tension would pass the domain's top (where
    c4 F + eps_max or the tangent's argument reaches its limit, about 500 N near rest length: 614
    kPa at 0 %, just below the 620 kPa the model was fitted to).

    (H) rises with the tension on 0 <= F < eps_max / |c4| (the tangent's argument grows with F and
    c5 > 0), so the root is bracketed and unique there; it is found with scipy's brentq.
    """
    from scipy.optimize import brentq
    hi = tension_top(contraction)

    def gap(f):
        return pressure(contraction, f, branch) - p_gauge

    if gap(0.0) > 0.0:
        return float("nan")
    if gap(hi) < 0.0:
        return float("nan")
    return float(brentq(gap, 0.0, hi, xtol=1e-9, rtol=1e-12))


def loop_rows(pressures=(100e3, 200e3, 300e3, 400e3, 500e3, 600e3),
              contractions=tuple(np.round(np.arange(0.0, 0.165, 0.01), 4))) -> list[tuple]:
    """The loop as force-table rows (pressure [Pa gauge], contraction [-], tension [N], branch):
    both branches at every pressure and contraction where the muscle pulls (module docstring)."""
    rows = []
    for p in pressures:
        for e in contractions:
            for branch in ("loading", "unloading"):
                f = tension(float(p), float(e), branch)
                if np.isfinite(f):
                    rows.append((float(p), float(e), f, branch))
    return rows


def write_table(path, rows=None) -> int:
    """Write the loop (``rows`` from :func:`loop_rows`) as a force table CSV with a direction
    column (:mod:`frogsim.fit.force`); returns the number of rows."""
    import pandas as pd
    rows = loop_rows() if rows is None else rows
    p, e, f, d = zip(*rows)
    pd.DataFrame({"pressure [kPa gauge]": np.array(p) / 1e3, "contraction [%]": np.array(e) * 100,
                  "force [N]": f, "direction": d}).to_csv(path, index=False, float_format="%.6g")
    return len(rows)


def loop_width(p_gauge: float, contraction: float) -> float:
    """The loop's height in tension [N] at one pressure and contraction: loading less unloading."""
    return tension(p_gauge, contraction, "loading") - tension(p_gauge, contraction, "unloading")


#: the example fit's files (examples/fit/hysteresis, written by :func:`write_example`)
TABLE_NAME = "hunt2017-dmsp10.csv"
RIG_NAME = "rig-dmsp10.toml"
RIG_TOML = """# A FESTO 10 mm fluidic muscle for fitting the force law and its hysteresis to Hunt et al.'s loop
# (FIT.toml). Only the parameter set, the muscle type's braid and the force law's settings matter
# to a force-table fit; the run itself (one muscle held at its rest length) is never simulated.
name = "dmsp10-rig"
description = "hip muscle type with a FESTO 10 mm braid, for force-table fits"
parameters = "fan2017"
duration = "0.1 s"
output_interval = "1 ms"

[controller]
rate = "1 kHz"

[supply]
mode = "none"

[muscle_types.hip]
inner_diameter = "10 mm"    # FESTO DMSP-10: 10 mm inner diameter
braid_angle = "20.45 deg"   # start only (fitted): Chou-Hannaford 630 N at 6 bar and 0 %, the DMSP-10 datasheet's force

[muscle_force]
hysteresis = "maxwell-slip"
slip_strain = "0.1 %"       # Hunt's loop turns at once: the elements slide within 0.2 % of a turning point

[programs.hold]
pressurise = "0.05 s"
release = "0.05 s"

[muscles.hip]
type = "hip"
program = "hold"
motion = { kind = "constant" }
"""
FIT_TOML = """# Fit the force law and its Maxwell-slip hysteresis to a published loop of a FESTO 10 mm muscle:
# Hunt, Szczecinski and Quinn 2017 (Front. Neurorobot. 11:18), both branches of their model at
# 100-600 kPa (hunt2017-dmsp10.csv). This folder is written by python -m frogsim.components.hunt2017 DIR.
#   frogsim fit examples/fit/hysteresis/FIT.toml --out hysteresis-fit
# The braid angle is fitted with the law: the real muscle pulls 492 N at 6 bar and rest length in
# Hunt's model, less than the datasheet's 630 N (the braid angle's start).
scenario = "rig-dmsp10.toml"
starts = 4
seed = 1

[[force_tables]]
name = "Hunt et al. 2017, FESTO 10 mm"
table = "hunt2017-dmsp10.csv"
muscle = "hip"
noise = "2 N"               # the loop is 8-13 N high: a few newtons resolve it

[parameters]
"muscle_force.force_scale" = { min = "0 N", max = "1000 N", start = "50 N" }
"muscle_force.strain_scale" = { min = "0.2 %", max = "20 %", start = "3 %" }
"muscle_force.stiffness" = { min = "0 N", max = "5000 N", start = "500 N" }
"muscle_types.hip.braid_angle" = { min = "15 deg", max = "30 deg", start = "20.45 deg" }
"muscle_force.slip_per_pressure" = { min = "0 N/bar", max = "40 N/bar", start = "3 N/bar" }
"""


def write_example(folder) -> "Path":
    """Write the example fit against the published loop into ``folder`` (the loop as a force table,
    the 10 mm rig scenario and FIT.toml; examples/fit/hysteresis is this folder) and return the
    path of its FIT.toml."""
    from pathlib import Path
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    write_table(folder / TABLE_NAME)
    (folder / RIG_NAME).write_text(RIG_TOML)
    (folder / "FIT.toml").write_text(FIT_TOML)
    return folder / "FIT.toml"


if __name__ == "__main__":
    import sys
    if len(sys.argv) != 2:
        sys.exit("usage: python -m frogsim.components.hunt2017 DIR   (writes the example fit's files into DIR)")
    path = write_example(sys.argv[1])
    print(f"wrote {path.parent}: {TABLE_NAME} (Hunt et al. 2017, FESTO 10 mm muscle, both branches), "
          f"{RIG_NAME}, FIT.toml; run: frogsim fit {path} --out hysteresis-fit")
