"""Index layouts of the coupled engine's flat arrays (:mod:`frogsim.engine.coupled`).

The compiled kernel (:mod:`frogsim.engine.coupled_kernel`) reads and writes plain float arrays;
these constants name their columns: the muscle table mu[i, U_*], the constants sc[S_*], the
kernel's own state st[T_*] (the pneumatic driver's and the controllers' state are arrays of their
own, :mod:`frogsim.engine.integrator` and :mod:`frogsim.control.sampled`), and one row of the
per-step record rec[row, R_*], whose variable part :func:`record_columns` lays out.
"""
from __future__ import annotations

# --- muscle table mu[i, :] -------------------------------------------------------------------------
U_TENDON = 0     # MuJoCo tendon id
U_ACT = 1        # MuJoCo actuator id
U_FITTINGS = 2   # tendon length - muscle length [m]
U_SIZE = 3

# --- constants sc[:] ---------------------------------------------------------------------------------
S_DT = 0         # MuJoCo step [s]
S_RHO = 1        # density of the medium [kg/m^3]
S_G = 2          # gravity [m/s^2]
S_CTRL_DT = 3    # controller period [s]
S_RTOL = 4       # pneumatic relative tolerance
S_MAXSTEP = 5    # pneumatic largest step [s]
S_LAW = 6        # muscle force model (MODEL_*)
S_BLADDER = 7    # bladder constants A, eps_c, k, a, b (5)
S_TRUNK = 12     # MuJoCo body id of the hull
S_VMAX = 13      # hull speed limit [m/s]
S_WMAX = 14      # joint speed limit [rad/s]
S_SIZE = 15

# --- mutable state st[:] -----------------------------------------------------------------------------
T_PALM_CMD = 0     # index of the next palm command
T_PALM_TARGET = 1  # commanded palm opening (0 folded, 1 open)
T_FIRST = 2      # 1 until the first step has run (no acceleration history yet)
T_FAIL = 3       # FAIL_* code
T_FAIL_ARG = 4   # which dof / joint / status
T_FAIL_VAL = 5   # the offending value
T_EXERGY = 6     # isothermal exergy of the air charged into muscles since t = 0 [J]
T_PEAK = 7       # largest thrust so far [N]
T_PEAK_TIME = 8
T_SIZE = 9

FAIL_PNEUMATIC = 1
FAIL_QPOS = 2
FAIL_QVEL = 3
FAIL_BODY_SPEED = 4
FAIL_JOINT_SPEED = 5

# --- per-step record rec[row, :] -------------------------------------------------------------------
R_TIME = 0
R_X = 1          # hull centre, world x, y, z [m] (3)
R_YAW = 4        # heading of the hull [rad]
R_V = 5          # velocity of the hull centre, world (3) [m/s]
R_THRUST = 8     # water force on the legs along the heading [N]
R_THRUST_AM = 9  # its added-mass part [N]
R_HULL = 10      # water force on the hull along the heading [N]
R_PS = 11        # source pressure [Pa abs]
R_PE = 12        # exhaust pressure [Pa abs]
R_CHARGED = 13   # air charged into all muscles since t = 0 [kg]
R_PUMPED = 14    # air moved by the pump since t = 0 [kg]
R_AIR = 15       # air in source, exhaust and muscles [kg]
R_EXERGY = 16    # exergy of the charged air since t = 0 [J]
R_PUMP_ON = 17
R_FIXED = 18     # then: n pressures, n lengths, n tensions, n charged masses, 2n valve states,
                 # np palm openings, nj joint angles, nj joint velocities, nq MuJoCo positions


def record_columns(n: int, npal: int, nj: int, nq: int) -> dict:
    """Start column of each per-muscle / per-palm / per-joint block in a record row."""
    c = {"pressure": R_FIXED, "length": R_FIXED + n, "tension": R_FIXED + 2 * n,
         "charged": R_FIXED + 3 * n, "valves": R_FIXED + 4 * n, "palm": R_FIXED + 6 * n}
    c["angle"] = c["palm"] + npal
    c["omega"] = c["angle"] + nj
    c["qpos"] = c["omega"] + nj
    c["size"] = c["qpos"] + nq
    return c
