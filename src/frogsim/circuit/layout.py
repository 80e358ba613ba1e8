"""Index layout of the flat arrays the engine loops over (compile-time constants for Numba).

State vector y (n muscles):
    [m_s, p_s, m_e, p_e, m_1, p_1, ..., m_n, p_n, Q_1..Q_n, D_1..D_n, P]
where m [kg] and p [Pa abs] are each volume's air mass and pressure, Q_i the mass that has entered
muscle i through its charge valve, D_i the mass that has left through its discharge valve, and P the
mass the pump has moved (cumulative, kg).
"""

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
G_SIZE = 18

SUPPLY_NONE = 0
SUPPLY_PAPER = 1
SUPPLY_PHYSICAL = 2

# per-muscle parameter matrix mp[i, :]
M_B0 = 0        # braid thread length [m]
M_N = 1         # braid turns [-]
M_DEAD = 2      # dead volume of fittings and branch tube [m^3]
M_FIXEDV = 3    # fixed total volume [m^3], or <= 0 when the volume follows the length
M_CC = 4        # charge valve sonic conductance [m^3/(s Pa)]
M_CB = 5        # charge valve critical ratio [-]
M_CM = 6        # charge valve subsonic index [-]
M_CRL = 7       # charge valve laminar ratio [-]
M_DC = 8        # discharge valve sonic conductance
M_DB = 9
M_DM = 10
M_DRL = 11
M_L0 = 12       # rest length [m]
M_SIZE = 13

# fixed part of the state
Y_MS = 0
Y_PS = 1
Y_ME = 2
Y_PE = 3
Y_MUSCLE0 = 4


def state_size(n: int) -> int:
    """Length of the state vector for n muscles."""
    return 4 + 4 * n + 1


def charged_index(i: int, n: int) -> int:
    """Index of muscle i's cumulative charged mass in the state."""
    return 4 + 2 * n + i


def vented_index(i: int, n: int) -> int:
    """Index of muscle i's cumulative vented mass in the state."""
    return 4 + 3 * n + i


def pump_index(n: int) -> int:
    """Index of the cumulative pump mass in the state."""
    return 4 + 4 * n
