"""FESTO DMSP-20 fluidic muscle: reference force-contraction data and the fit of the bladder force.

Reference data
    Force [N] against contraction [-] at gauge pressures 0-6.2 bar, as tabulated from FESTO's data
    for the DMSP-20 (the MuscleSIM sizing tool behind the catalogue's force-contraction diagram) in
    the public repository Agile-and-Adaptive-Robotics/Bipedal_Robot, file
    Code/Matlab/Functions/FestoLookup_v2.m ("Create Festo force lookup tables based on their
    datasheets", arrays x20_k/z20_k). FESTO's datasheet gives 1500 N at 6 bar and 0 % contraction
    and a maximum contraction of 25 %; the 600 kPa row (1515 N at 0 %) agrees with it.
    Negative forces in the table are the push needed to hold a muscle shorter than it contracts on
    its own; a muscle on a crank goes slack there instead.

The fit
    :func:`fit_bladder` fits the five constants of the corrected law
    (:mod:`frogsim.physics.muscle_force`) to the 1, 3 and 5 bar rows, by least squares on the
    points with positive force, each residual scaled by max(10 % of the force, 50 N) (the
    acceptance tolerance). The 2, 4 and 6 bar rows are left out so that the tests can check the
    law against data the fit has not seen. Run ``python -m frogsim.components.dmsp20`` to repeat it
    (``--plot FILE.png`` draws the law against the data).
"""
from __future__ import annotations

import math

import numpy as np

BAR = 1e5
#: gauge pressure [Pa] -> (contraction [-], force [N]) from FestoLookup_v2.m (see module docstring)
REFERENCE = {
    0.0: ((-0.04, -0.03, -0.02, -0.01, 0.0, 0.03, 0.125, 0.25),
          (684, 416, 229, 96, 0, -160, -270, -287)),
    1.0e5: ((-0.04, -0.03, -0.02, -0.01, 0.0, 0.02, 0.06, 0.17, 0.25),
            (940, 672, 486, 352, 253, 123, -8, -147, -218)),
    2.0e5: ((-0.04, -0.02, -0.01, 0.01, 0.05, 0.12, 0.155, 0.25),
            (1194, 743, 608, 429, 240, 112, 8.7, -150)),
    3.0e5: ((-0.04, -0.03, -0.01, 0.01, 0.04, 0.12, 0.21, 0.25),
            (1451, 1187, 864, 678, 507, 241, 13, -84)),
    4.0e5: ((-0.04, -0.02, 0.0, 0.01, 0.04, 0.09, 0.16, 0.24, 0.25),
            (1707, 1257, 1012, 926, 737, 518, 271, 13, -19)),
    5.0e5: ((-0.04, -0.02, 0.0, 0.01, 0.04, 0.08, 0.13, 0.195, 0.22, 0.25),
            (1963, 1514, 1264, 1173, 966, 756, 531, 262, 162, 45)),
    6.0e5: ((-0.04, 0.0, 0.035, 0.065, 0.11, 0.25),
            (2219, 1515, 1228, 1040, 791, 107)),
}
FIT_PRESSURES = (1.0e5, 3.0e5, 5.0e5)      # rows used by the fit; 2, 4, 6 bar are held out


def law_forces(pressure, contraction, constants, inner_diameter: float = 0.020,
               braid_angle: float = math.radians(25.3), model="dmsp20") -> np.ndarray:
    """The force law's tension [N] at gauge pressures [Pa] and contractions [-] (arrays of one shape).

    ``constants``: (force_scale, strain_scale, stiffness, stretch_stiffness, stretch_quadratic) in
    SI; ``model``: "dmsp20" (the corrected law) or "ideal" (Chou-Hannaford alone). Used by
    :func:`fit_bladder` and by ``frogsim fit`` for force tables (:mod:`frogsim.fit.force`).
    """
    from frogsim.physics.muscle import braid_parameters
    from frogsim.physics.muscle_force import MODEL_DMSP20, MODEL_IDEAL, muscle_force
    code = {"dmsp20": MODEL_DMSP20, "ideal": MODEL_IDEAL}.get(model, model)
    L0 = 0.18          # any length: the law depends on the contraction only
    b0, n = braid_parameters(L0, inner_diameter, braid_angle)
    c = [float(x) for x in constants]
    p = np.asarray(pressure, dtype=float)
    e = np.asarray(contraction, dtype=float)
    return np.array([muscle_force(code, float(pi), L0 * (1.0 - float(ei)), L0, b0, n, *c)
                     for pi, ei in zip(p.ravel(), e.ravel())]).reshape(p.shape)


def fit_bladder(inner_diameter: float = 0.020, braid_angle: float = math.radians(25.3),
                pressures=FIT_PRESSURES) -> dict:
    """Least-squares fit of the bladder constants to the reference rows at ``pressures``.

    Returns {"force_scale": A [N], "strain_scale": eps_c [-], "stiffness": k [N],
    "stretch_stiffness": a [N], "stretch_quadratic": b [N]} for the braid of the given inner
    diameter [m] and braid angle [rad] (the parameter set's DMSP-20: 20 mm, 25.3 deg).
    """
    from scipy.optimize import least_squares

    rows = []
    for p in pressures:
        eps, force = (np.asarray(v, float) for v in REFERENCE[p])
        keep = force >= 0.0
        rows += [(p, e, f) for e, f in zip(eps[keep], force[keep])]
    p_rows, e_rows, f_rows = (np.array(v) for v in zip(*rows))
    sigma = np.maximum(0.1 * f_rows, 50.0)

    def residuals(c):
        return (law_forces(p_rows, e_rows, c, inner_diameter, braid_angle) - f_rows) / sigma

    sol = least_squares(residuals, [120.0, 0.02, 600.0, 7000.0, 2.5e5],
                        bounds=([0.0, 1e-3, 0.0, 0.0, 0.0], [1e4, 0.5, 1e5, 1e6, 1e8]))
    keys = ("force_scale", "strain_scale", "stiffness", "stretch_stiffness", "stretch_quadratic")
    return dict(zip(keys, (float(x) for x in sol.x)))


def plot_fit(path: str, constants: dict, inner_diameter: float = 0.020,
             braid_angle: float = math.radians(25.3)) -> None:
    """Draw the corrected law and the ideal law against the reference rows (docs/robot.md)."""
    from frogsim.physics.muscle import braid_parameters
    from frogsim.physics.muscle_force import MODEL_DMSP20, MODEL_IDEAL, muscle_force
    from frogsim._plotting import figure, save
    L0 = 0.18
    b0, n = braid_parameters(L0, inner_diameter, braid_angle)
    c = [constants[k] for k in ("force_scale", "strain_scale", "stiffness", "stretch_stiffness",
                                "stretch_quadratic")]
    eps = np.linspace(-0.04, 0.25, 117)
    fig, ax = figure(width=7.5, height=5.0)
    a = ax[0, 0]
    for k, p in enumerate(sorted(REFERENCE)):
        if p == 0.0:
            continue
        color = f"C{k}"
        e_ref, f_ref = (np.asarray(v, float) for v in REFERENCE[p])
        fitted = p in FIT_PRESSURES
        a.plot(e_ref * 100, f_ref, "o" if fitted else "s", color=color, mfc="none" if fitted else color,
               label=f"{p / BAR:g} bar data ({'fitted' if fitted else 'held out'})")
        a.plot(eps * 100, [muscle_force(MODEL_DMSP20, p, L0 * (1 - e), L0, b0, n, *c) for e in eps],
               color=color)
        a.plot(eps * 100, [muscle_force(MODEL_IDEAL, p, L0 * (1 - e), L0, b0, n, *c) for e in eps],
               color=color, ls=":", lw=1)
    a.set_xlabel("contraction [%] (negative: stretched)")
    a.set_ylabel("force [N]")
    a.set_ylim(-50, 2400)
    a.set_title("DMSP-20: corrected law (solid), Chou-Hannaford alone (dotted), FESTO data")
    a.legend(fontsize=7, ncol=2)
    save(fig, path, "data: FestoLookup_v2.m (Agile-and-Adaptive-Robotics/Bipedal_Robot); frogsim fit")


if __name__ == "__main__":
    import sys
    fit = fit_bladder()
    print("bladder constants fitted to the DMSP-20 rows at 1, 3, 5 bar:")
    print(f"  force_scale       = {fit['force_scale']:.1f} N")
    print(f"  strain_scale      = {fit['strain_scale'] * 100:.3f} %")
    print(f"  stiffness         = {fit['stiffness']:.1f} N")
    print(f"  stretch_stiffness = {fit['stretch_stiffness']:.0f} N")
    print(f"  stretch_quadratic = {fit['stretch_quadratic']:.4g} N")
    if len(sys.argv) > 2 and sys.argv[1] == "--plot":
        plot_fit(sys.argv[2], fit)
        print(f"wrote {sys.argv[2]}")
