"""Index layouts of the coupled engine's flat arrays (:mod:`frogsim.engine.coupled`).

The compiled kernel (:mod:`frogsim.engine.coupled_kernel`) reads and writes plain float arrays;
these constants name their columns: the muscle table mu[i, U_*], the leg joints' end stops
stops[j, STOP_*], each water part's last state vprev[e, V_*], the constants sc[S_*], the
kernel's own state st[T_*] (the pneumatic driver's and the controllers' state are arrays of their
own, :mod:`frogsim.engine.integrator` and :mod:`frogsim.control.sampled`), and one row of the
per-step record rec[row, R_*], whose variable part the rec_* functions (for compiled code) and
:func:`record_columns` (slices, for Python) lay out, inlined into the kernel as
:mod:`frogsim.circuit.layout`'s index functions are. No other module computes a record column.

The muscles' hysteresis memory is a plain 2-D array, anchors[i, j] (muscle i, slip element j;
:func:`frogsim.physics.hysteresis.muscle_hysteresis_force`), with N = 0 columns when the force law
has no memory. It is per-muscle state, but not an entry of the pneumatic state y
(:data:`frogsim.circuit.layout.MUSCLE_FIELDS`): the anchors are not integrated (they jump as an
element slides, once per MuJoCo step), and entries added to y would enter the solver's error norm
and change every run with hysteresis off.
"""
from __future__ import annotations

from numba.extending import register_jitable

from frogsim.circuit.layout import VALVE_WIDTH, valve_index, valve_size
from frogsim.engine.methods.spec import PAR_SIZE

# --- muscle table mu[i, :] -------------------------------------------------------------------------
U_TENDON = 0     # MuJoCo tendon id
U_ACT = 1        # MuJoCo actuator id
U_FITTINGS = 2   # tendon length - muscle length [m]
U_SIZE = 3

# --- end stops stops[j, :] (per leg joint, frogsim.physics.stop) -----------------------------------
STOP_LOWER = 0   # flexed end of the range [rad]
STOP_UPPER = 1   # extended end of the range [rad]
STOP_K = 2       # pad stiffness about the joint axis [N m/rad]
STOP_C = 3       # pad damping [N m s/rad]
STOP_DAMPING = 4  # the joint's own viscous damping, MuJoCo's dof_damping off the pads [N m s/rad]
STOP_SIZE = 5

# --- constants sc[:] ---------------------------------------------------------------------------------
S_DT = 0         # MuJoCo step [s]
S_RHO = 1        # density of the medium [kg/m^3]
S_G = 2          # gravity [m/s^2]
S_CTRL_DT = 3    # controller period [s]
S_RTOL = 4       # pneumatic relative tolerance
S_MAXSTEP = 5    # pneumatic largest step [s]
S_LAW = 6        # the muscles' force-law block (FORCE_PARAMS = 6 entries, written by their actuator type,
                 # frogsim.circuit.actuators.force_block; the McKibben muscle's: its model, then A, eps_c, k, a, b)
S_TRUNK = 12     # MuJoCo body id of the hull
S_VMAX = 13      # hull speed limit [m/s]
S_WMAX = 14      # joint speed limit [rad/s]
S_METHOD = 15    # the integration method's parameter block (PAR_SIZE entries, frogsim.engine.methods)
S_SIZE = S_METHOD + PAR_SIZE

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
# the water's forces of the last step other than -M_A a (drag, Kirchhoff's velocity terms, an
# opening palm's -dM_A/dt v), along that step's heading [N]: the record's thrust of a step is
# these plus -M_A a with that step's acceleration, known one step later (coupled_kernel)
T_LAST_THRUST = 9       # on the legs
T_LAST_THRUST_AM = 10   # its added-mass part (velocity terms)
T_LAST_HULL = 11        # on the hull
T_LAST_HEADING = 12     # the last step's heading, world (3)
T_SIZE = 15

# --- per part in the water, vprev[e, :]: its state at the last step --------------------------------
V_VEL = 0        # velocity of the added-mass centre, world (3) [m/s]
V_MA = 3         # added-mass matrix in world axes: xx, yy, zz, xy, xz, yz (6) [kg]
V_SIZE = 9

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
R_FIXED = 18     # then the blocks of :func:`record_columns`
R_POSITION = slice(R_X, R_X + 3)
R_VELOCITY = slice(R_V, R_V + 3)

# the variable part: blocks of n columns (one per muscle) in this order, then the valves (laid out
# as the valve vector, frogsim.circuit.layout.valve_index), then np palm openings, nj joint angles,
# nj joint velocities, nq MuJoCo positions
_REC_PRESSURE = 0    # muscle pressures [Pa abs]
_REC_LENGTH = 1      # muscle lengths [m]
_REC_TENSION = 2     # muscle tensions [N]
_REC_CHARGED = 3     # air charged into each muscle since t = 0 [kg]
_REC_VALVES = 4      # first block after the per-muscle ones
_REC_MUSCLE_WIDTH = _REC_VALVES + VALVE_WIDTH    # columns per muscle: four values and the valve states


@register_jitable(inline="always", _nrt=False)
def rec_pressure(i, n):
    """Column of muscle i's pressure (of n muscles)."""
    return R_FIXED + _REC_PRESSURE * n + i


@register_jitable(inline="always", _nrt=False)
def rec_length(i, n):
    """Column of muscle i's length."""
    return R_FIXED + _REC_LENGTH * n + i


@register_jitable(inline="always", _nrt=False)
def rec_tension(i, n):
    """Column of muscle i's tension."""
    return R_FIXED + _REC_TENSION * n + i


@register_jitable(inline="always", _nrt=False)
def rec_charged(i, n):
    """Column of the air charged into muscle i."""
    return R_FIXED + _REC_CHARGED * n + i


@register_jitable(inline="always", _nrt=False)
def rec_valve(i, n, which):
    """Column of muscle i's valve ``which`` (VALVE_CHARGE or VALVE_VENT, frogsim.circuit.layout)."""
    return R_FIXED + _REC_VALVES * n + valve_index(i, which)


@register_jitable(inline="always", _nrt=False)
def rec_palm(p, n):
    """Column of palm p's opening."""
    return R_FIXED + _REC_MUSCLE_WIDTH * n + p


@register_jitable(inline="always", _nrt=False)
def rec_angle(j, n, npal):
    """Column of leg joint j's angle."""
    return R_FIXED + _REC_MUSCLE_WIDTH * n + npal + j


@register_jitable(inline="always", _nrt=False)
def rec_omega(j, n, npal, nj):
    """Column of leg joint j's angular velocity."""
    return R_FIXED + _REC_MUSCLE_WIDTH * n + npal + nj + j


@register_jitable(inline="always", _nrt=False)
def rec_qpos(j, n, npal, nj):
    """Column of MuJoCo's position j (qpos[j])."""
    return R_FIXED + _REC_MUSCLE_WIDTH * n + npal + 2 * nj + j


def record_columns(n: int, npal: int, nj: int, nq: int) -> dict:
    """Each per-muscle / per-palm / per-joint block of a record row as a slice of its columns, and
    "size": the row's length."""
    return {"pressure": slice(rec_pressure(0, n), rec_pressure(0, n) + n),
            "length": slice(rec_length(0, n), rec_length(0, n) + n),
            "tension": slice(rec_tension(0, n), rec_tension(0, n) + n),
            "charged": slice(rec_charged(0, n), rec_charged(0, n) + n),
            "valves": slice(rec_valve(0, n, 0), rec_valve(0, n, 0) + valve_size(n)),
            "palm": slice(rec_palm(0, n), rec_palm(0, n) + npal),
            "angle": slice(rec_angle(0, n, npal), rec_angle(0, n, npal) + nj),
            "omega": slice(rec_omega(0, n, npal, nj), rec_omega(0, n, npal, nj) + nj),
            "qpos": slice(rec_qpos(0, n, npal, nj), rec_qpos(0, n, npal, nj) + nq),
            "size": rec_qpos(0, n, npal, nj) + nq}
