"""Index layout of the flat arrays the engine loops over: the one place that says where every
volume's and muscle's state lives (compile-time constants and pure index functions for Numba).

State vector y (n muscles), in this order (the solver's error norms and dense output see it):

    [m_s, p_s, m_e, p_e,  (m_1, p_1), ..., (m_n, p_n),  Q_1..Q_n, D_1..D_n, P]

where m [kg] and p [Pa abs] are each volume's air mass and pressure, Q_i the mass that has entered
muscle i through its charge valve, D_i the mass that has left through its discharge valve, and P the
mass the pump has moved (cumulative, kg). Each muscle has a block of :data:`MUSCLE_WIDTH` entries
(its fields MUSCLE_MASS, MUSCLE_PRESSURE, ... at fixed places in the block); the chambers and the
muscle blocks are the *physical* part (air masses and pressures, all positive, everything the
right-hand side reads), the cumulative masses follow.

Every other module asks this one: a muscle's entries through :func:`mass_index` and
:func:`pressure_index` (or the slices :func:`mass_slice`, :func:`pressure_slice`), the counters
through :func:`charged_index`, :func:`vented_index`, :func:`pump_index`, the sizes through
:func:`physical_size` and :func:`state_size`, the labels through :func:`state_labels`
(tests/test_layout.py fails on an offset computed anywhere else). A per-muscle state added later
(a wall temperature, a tube segment's pressure) is one more entry of MUSCLE_FIELDS here, with its
place as a MUSCLE_* constant.

The valve vector u (what the driver holds constant over a piece, :mod:`frogsim.engine.integrator`)
has :data:`VALVE_WIDTH` entries per muscle, its charge path then its discharge (vent) path
(:func:`valve_index`, :func:`charge_valve`, :func:`vent_valve`; :func:`valve_size` entries in
all). The same columns, one more after them, hold the right-hand side's diagnostic flows ``aux``
(each path's mass flow, then the pump's flow) and an output row of the valves (each path's state,
then the pump's switch): :func:`pump_entry`, :func:`flows_size`. The schedule's rows (sched_u) are
valve vectors. The right-hand side's scratch ``work`` has one block of n per field of
:data:`WORK_FIELDS` (a muscle's temperature, volume, volume rate, length): :func:`work_index`,
:func:`work_size`.

The index functions are plain Python for Python callers and inlined into each compiled caller's
Numba IR (``numba.extending.register_jitable`` with ``inline="always"``: no dispatcher of their own;
the caller compiles to the machine code the offsets written out in place gave it).
"""
from numba.extending import register_jitable

#: the right-hand side's model tuple, as :func:`frogsim.circuit.rhs.rhs` and the driver
#: (:func:`frogsim.engine.integrator.advance`, ``model``) take it: the names of its members in order
#: (:attr:`frogsim.circuit.model.PneumaticModel.rhs_model`)
MODEL_GROUP = ("g", "mp", "mot_t", "mot_L", "mot_d", "mot_n")
#: the driver's ``commands`` tuple: the valve schedule, the sampled laws, the controller period
COMMANDS_GROUP = ("sched_t", "sched_u", "laws", "ctrl_dt")
#: the driver's ``out`` tuple: output times, states, valve rows (:func:`flows_size` columns)
OUT_GROUP = ("out_t", "out_y", "out_u")

# global parameter vector g
G_K = 0            # heat capacity ratio [-]
G_R = 1            # gas constant [J/(kg K)]
G_PATM = 2         # atmospheric pressure [Pa abs]
G_RHOREF = 3       # ISO reference density [kg/m^3]
G_TREF = 4         # ISO reference temperature [K]
G_TAMB = 5         # ambient temperature [K]
G_VS = 6           # source volume [m^3]
G_VE = 7           # exhaust volume [m^3]
G_PUMP_ENABLED = 8  # 1 if the pump exists and is band-controlled
G_PUMP_DISP = 9    # pump displacement [m^3/s]
G_PUMP_RMAX = 10   # pump stall pressure ratio [-]
G_PUMP_ON = 11     # switch on below this source pressure [Pa abs]
G_PUMP_OFF = 12    # switch off above this source pressure [Pa abs]
G_SUPPLY_MODE = 13  # 0 none, 1 paper (Eq. 9 per-branch limit), 2 physical (shared tube)
G_BRANCH_LIMIT = 14  # paper mode: per-branch mass-flow limit [kg/s]
G_TUBE_C = 15      # physical mode: sonic conductance of the main tube(s) [m^3/(s Pa)]
G_TUBE_B = 16      # physical mode: critical ratio of the main tube [-]
G_TUBE_RLAM = 17   # physical mode: laminar ratio of the main tube [-]
G_H_S = 18         # source: heat transfer coefficient air-wall [W/(m^2 K)] (0: adiabatic)
G_A_S = 19         # source: inner wall area [m^2]
G_H_E = 20         # exhaust: heat transfer coefficient air-wall [W/(m^2 K)] (0: adiabatic)
G_A_E = 21         # exhaust: inner wall area [m^2]
G_HEAT = 22        # 1 if some wall passes heat (G_H_S, G_H_E or some mp[i, M_H] > 0), else 0
G_SIZE = 23

SUPPLY_NONE = 0
SUPPLY_PAPER = 1
SUPPLY_PHYSICAL = 2

# per-muscle parameter matrix mp[i, :]
M_ACT = 0       # the muscle's actuator type: its CODE in the actuator family (frogsim.circuit.actuators)
M_AP = 1        # the actuator type's parameter block: ACTUATOR_PARAMS columns from here, each type's own
ACTUATOR_PARAMS = 4
M_DEAD = M_AP + ACTUATOR_PARAMS     # dead volume of fittings and branch tube [m^3]
M_FIXEDV = M_DEAD + 1   # fixed total volume [m^3], or <= 0 when the volume follows the length
M_L0 = M_DEAD + 2       # rest length [m]
M_H = M_DEAD + 3        # heat transfer coefficient air-wall [W/(m^2 K)] (0: adiabatic)
M_VALVE = M_DEAD + 4    # the muscle's valve type: its CODE in the valve family (frogsim.circuit.valves)
M_VP = M_DEAD + 5       # the valve type's parameter block: VALVE_PARAMS columns from here, each type's own
VALVE_PARAMS = 12
M_SIZE = M_VP + VALVE_PARAMS

# fixed part of the state: the source and exhaust chambers
Y_MS = 0
Y_PS = 1
Y_ME = 2
Y_PE = 3
Y_MUSCLE0 = 4      # first muscle's block

# one muscle's block: its fields (label, unit) in block order, and each field's place in it
MUSCLE_FIELDS = (("mass", "kg"), ("pressure", "Pa abs"))
MUSCLE_MASS = 0        # air mass [kg]
MUSCLE_PRESSURE = 1    # pressure [Pa abs]
MUSCLE_WIDTH = len(MUSCLE_FIELDS)     # entries per muscle

# the cumulative masses after the physical part: one block of n per counter, then the pump's
_CHARGED = 0
_VENTED = 1
_COUNTERS = 2          # per-muscle counters


@register_jitable(inline="always", _nrt=False)
def muscle_index(i, field):
    """Index of field ``field`` (a MUSCLE_* place) of muscle i's block in the state."""
    return Y_MUSCLE0 + MUSCLE_WIDTH * i + field


@register_jitable(inline="always", _nrt=False)
def mass_index(i):
    """Index of muscle i's air mass [kg] in the state."""
    return Y_MUSCLE0 + MUSCLE_WIDTH * i + MUSCLE_MASS


@register_jitable(inline="always", _nrt=False)
def pressure_index(i):
    """Index of muscle i's pressure [Pa abs] in the state."""
    return Y_MUSCLE0 + MUSCLE_WIDTH * i + MUSCLE_PRESSURE


@register_jitable(inline="always", _nrt=False)
def physical_size(n):
    """Entries of the physical part for n muscles (chambers and muscle blocks: the air masses and
    pressures, each positive; the right-hand side reads no entry after them)."""
    return Y_MUSCLE0 + MUSCLE_WIDTH * n


@register_jitable(inline="always", _nrt=False)
def charged_index(i, n):
    """Index of muscle i's cumulative charged mass in the state."""
    return Y_MUSCLE0 + MUSCLE_WIDTH * n + _CHARGED * n + i


@register_jitable(inline="always", _nrt=False)
def vented_index(i, n):
    """Index of muscle i's cumulative vented mass in the state."""
    return Y_MUSCLE0 + MUSCLE_WIDTH * n + _VENTED * n + i


@register_jitable(inline="always", _nrt=False)
def pump_index(n):
    """Index of the cumulative pump mass in the state."""
    return Y_MUSCLE0 + MUSCLE_WIDTH * n + _COUNTERS * n


@register_jitable(inline="always", _nrt=False)
def state_size(n):
    """Length of the state vector for n muscles."""
    return Y_MUSCLE0 + MUSCLE_WIDTH * n + _COUNTERS * n + 1


@register_jitable(inline="always", _nrt=False)
def muscle_count(ny):
    """Number of muscles of a state of ny entries (the inverse of :func:`state_size`)."""
    return (ny - Y_MUSCLE0 - 1) // (MUSCLE_WIDTH + _COUNTERS)


def mass_slice(n: int) -> slice:
    """The muscles' air masses [kg], in muscle order, as a slice of the state."""
    return slice(mass_index(0), physical_size(n), MUSCLE_WIDTH)


def pressure_slice(n: int) -> slice:
    """The muscles' pressures [Pa abs], in muscle order, as a slice of the state."""
    return slice(pressure_index(0), physical_size(n), MUSCLE_WIDTH)


def charged_slice(n: int) -> slice:
    """The muscles' cumulative charged masses [kg], in muscle order, as a slice of the state."""
    return slice(charged_index(0, n), charged_index(0, n) + n)


def state_labels(names) -> list[tuple[str, str]]:
    """(label, unit) of every state entry, in state order, for muscles ``names``."""
    n = len(names)
    out = [None] * state_size(n)
    out[Y_MS], out[Y_PS] = ("source mass", "kg"), ("source pressure", "Pa abs")
    out[Y_ME], out[Y_PE] = ("exhaust mass", "kg"), ("exhaust pressure", "Pa abs")
    for i, name in enumerate(names):
        for f, (label, unit) in enumerate(MUSCLE_FIELDS):
            out[muscle_index(i, f)] = (f"{name} {label}", unit)
        out[charged_index(i, n)] = (f"{name} charged mass", "kg")
        out[vented_index(i, n)] = (f"{name} vented mass", "kg")
    out[pump_index(n)] = ("pumped mass", "kg")
    return out


# --- the valve vector u, the right-hand side's flows aux, an output row's valve columns -------------
VALVE_CHARGE = 0       # a muscle's charge path (source -> muscle)
VALVE_VENT = 1         # its discharge path (muscle -> exhaust)
VALVE_WIDTH = 2        # entries per muscle


@register_jitable(inline="always", _nrt=False)
def valve_index(i, which):
    """Entry of muscle i's path ``which`` (VALVE_CHARGE or VALVE_VENT) in the valve vector (and in
    aux and an output row's valve columns)."""
    return VALVE_WIDTH * i + which


@register_jitable(inline="always", _nrt=False)
def charge_valve(i):
    """Entry of muscle i's charge path in the valve vector (its mass flow's in aux)."""
    return VALVE_WIDTH * i + VALVE_CHARGE


@register_jitable(inline="always", _nrt=False)
def vent_valve(i):
    """Entry of muscle i's discharge (vent) path in the valve vector (its mass flow's in aux)."""
    return VALVE_WIDTH * i + VALVE_VENT


@register_jitable(inline="always", _nrt=False)
def valve_size(n):
    """Entries of the valve vector for n muscles."""
    return VALVE_WIDTH * n


@register_jitable(inline="always", _nrt=False)
def pump_entry(n):
    """The entry after the n muscles' valves: the pump's flow in aux, the pump's switch in an output
    row of the valves."""
    return VALVE_WIDTH * n


@register_jitable(inline="always", _nrt=False)
def flows_size(n):
    """Entries of aux (and of an output row of the valves) for n muscles: the valves, then the pump."""
    return VALVE_WIDTH * n + 1


@register_jitable(inline="always", _nrt=False)
def valve_muscles(nu):
    """Number of muscles of a valve vector of nu entries (the inverse of :func:`valve_size`)."""
    return nu // VALVE_WIDTH


def charge_slice(n: int) -> slice:
    """The muscles' charge paths, in muscle order, as a slice of the valve vector (or of aux, or of
    an output row of the valves)."""
    return slice(VALVE_CHARGE, VALVE_WIDTH * n, VALVE_WIDTH)


def vent_slice(n: int) -> slice:
    """The muscles' discharge paths, in muscle order, as a slice of the valve vector (or aux)."""
    return slice(VALVE_VENT, VALVE_WIDTH * n, VALVE_WIDTH)


def per_valve(n: int, charge, vent):
    """A valve vector for n muscles holding ``charge`` at every charge path's entry and ``vent`` at
    every discharge path's (e.g. each valve's dead time [s])."""
    import numpy as np
    out = np.empty(valve_size(n))
    out[charge_slice(n)] = charge
    out[vent_slice(n)] = vent
    return out


def valve_slice(n: int) -> slice:
    """The valve entries (without the pump's entry after them) of aux or an output row."""
    return slice(0, VALVE_WIDTH * n)


def muscle_valve_slice(i: int) -> slice:
    """Muscle i's two entries (charge, discharge) of the valve vector."""
    return slice(VALVE_WIDTH * i, VALVE_WIDTH * i + VALVE_WIDTH)


# --- the right-hand side's scratch work: one block of n per field -----------------------------------
WORK_FIELDS = (("temperature", "K"), ("volume", "m^3"), ("volume rate", "m^3/s"), ("length", "m"))
WORK_T = 0             # a muscle's air temperature [K]
WORK_V = 1             # its total volume [m^3]
WORK_DV = 2            # its volume's rate dV/dt [m^3/s]
WORK_L = 3             # its length [m] (the wall area's)
_WORK_BLOCKS = len(WORK_FIELDS)


@register_jitable(inline="always", _nrt=False)
def work_index(field, i, n):
    """Entry of muscle i's field ``field`` (a WORK_* block) in work, for n muscles."""
    return field * n + i


@register_jitable(inline="always", _nrt=False)
def work_size(n):
    """Entries of work for n muscles."""
    return _WORK_BLOCKS * n


def work_slice(field: int, n: int) -> slice:
    """The n muscles' entries of field ``field`` (a WORK_* block) as a slice of work."""
    return slice(field * n, field * n + n)
