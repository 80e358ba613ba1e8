"""Right-hand side of the pneumatic circuit: Eqs. (2)-(9) assembled for n muscles.

``rhs(t, y, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, dydt, aux, work)`` writes dy/dt. ``u``
holds the valve states (each muscle's charge path and discharge path at its entries of the valve
vector, :func:`frogsim.circuit.layout.valve_index`; each its opening: 1 = open, 0 = shut, a
proportional valve's edges open in between), constant over the call's segment, turned into mass
flows by the circuit's valve type (:mod:`frogsim.circuit.valves`: one type per circuit, as a
scenario's ``[valves]`` names one, read off the first muscle's row and dispatched once per call,
:data:`muscle_branches`); muscle lengths come from the motion tables (cubic Hermite knots, see
:func:`motion_length`). ``aux`` receives each muscle's charge and discharge mass flows [kg/s] and
the pump's flow for diagnostics; ``work`` is scratch space (no allocation in the hot loop). ``aux``
and ``work`` are laid out by :mod:`frogsim.circuit.layout` (:func:`~frogsim.circuit.layout.flows_size`,
:func:`~frogsim.circuit.layout.work_index`).

Each volume whose heat transfer coefficient is positive (mp[i, M_H], g[G_H_S], g[G_H_E]) takes the
wall heat Q = h A (T_wall - T) into its energy balance (Eq. (**) of :mod:`frogsim.physics.heat`),
the wall at the ambient temperature. The heat's share of dp/dt, (k - 1) Q / V, is a term added to
the adiabatic rate, so :func:`rhs` computes the adiabatic circuit and, when some volume has heat
transfer (g[G_HEAT] > 0), adds the walls' shares at its end. Without any (every h = 0) no heat term
is computed or added: dp/dt is the same numbers as without the term.
"""
from __future__ import annotations

import math

import numpy as np
from frogsim._jit import jit, jit_inner, jit_step

from frogsim.circuit import valves as valve_types
from frogsim.circuit.actuators import actuator_wall_area, checked_volume
from frogsim.circuit.valves import valve_flows
from frogsim.circuit.layout import (
    G_A_E, G_A_S, G_BRANCH_LIMIT, G_H_E, G_H_S, G_HEAT, G_K, G_PUMP_DISP, G_PUMP_RMAX, G_R, G_RHOREF,
    G_SUPPLY_MODE, G_TAMB, G_TREF, G_TUBE_B, G_TUBE_C, G_TUBE_RLAM, G_VE, G_VS, M_ACT, M_DEAD, M_FIXEDV, M_H,
    M_VALVE, SUPPLY_PAPER, SUPPLY_PHYSICAL, WORK_DV, WORK_L, WORK_T, WORK_V, Y_ME, Y_MS, Y_PE, Y_PS,
    charge_valve, charged_index, mass_index, pressure_index, pump_entry, pump_index, vent_valve, vented_index,
    work_index,
)
from frogsim.physics.flow import iso6358_mass_flow, pump_mass_flow
from frogsim.physics.gas import pressure_rate
from frogsim.physics.heat import heat_pressure_rate, wall_heat_flow


@jit
def motion_length(t, i, mot_t, mot_L, mot_d, mot_n):
    """Muscle i's length L(t) [m] and rate dL/dt [m/s] from its cubic Hermite knots.

    Knots (t_k, L_k, dL_k); constant before the first and after the last knot.
    """
    nk = mot_n[i]
    if nk == 1 or t <= mot_t[i, 0]:
        return mot_L[i, 0], 0.0
    if t >= mot_t[i, nk - 1]:
        return mot_L[i, nk - 1], 0.0
    lo = 0
    hi = nk - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if mot_t[i, mid] <= t:
            lo = mid
        else:
            hi = mid
    return _hermite(t, i, lo, hi, mot_t, mot_L, mot_d)


def length_turning_times(i, mot_t, mot_L, mot_d, mot_n):
    """Times [s] at which muscle i's length path may turn (dL/dt = 0 or a knot), sorted: every
    knot and every root of dL/dt inside a piece (the derivative of a cubic Hermite piece is a
    quadratic in its parameter s). A path monotone between consecutive times listed here is what a
    rate-independent memory (the muscles' slip elements) needs to follow it exactly; listing a
    time where the path does not turn changes nothing for such a memory."""
    import numpy as np
    nk = int(mot_n[i])
    times = [float(x) for x in mot_t[i, :nk]]
    for lo in range(nk - 1):
        t0, t1 = float(mot_t[i, lo]), float(mot_t[i, lo + 1])
        h = t1 - t0
        y0, y1 = float(mot_L[i, lo]), float(mot_L[i, lo + 1])
        d0, d1 = float(mot_d[i, lo]) * h, float(mot_d[i, lo + 1]) * h
        # dL/ds = a s^2 + b s + c (the derivative _hermite evaluates)
        a = 6.0 * y0 + 3.0 * d0 - 6.0 * y1 + 3.0 * d1
        b = -6.0 * y0 - 4.0 * d0 + 6.0 * y1 - 2.0 * d1
        roots = np.roots([a, b, d0]) if (a != 0.0 or b != 0.0) else []
        times += [t0 + float(r.real) * h for r in np.atleast_1d(roots)
                  if abs(r.imag) < 1e-12 and 0.0 < r.real < 1.0]
    return np.array(sorted(times))


@jit_step
def _hermite(t, i, lo, hi, mot_t, mot_L, mot_d):
    """Muscle i's (L, dL/dt) on its path's piece between knots lo and hi = lo + 1."""
    h = mot_t[i, hi] - mot_t[i, lo]
    s = (t - mot_t[i, lo]) / h
    y0 = mot_L[i, lo]
    y1 = mot_L[i, hi]
    d0 = mot_d[i, lo] * h
    d1 = mot_d[i, hi] * h
    s2 = s * s
    s3 = s2 * s
    L = (2 * s3 - 3 * s2 + 1) * y0 + (s3 - 2 * s2 + s) * d0 + (-2 * s3 + 3 * s2) * y1 + (s3 - s2) * d1
    dLds = (6 * s2 - 6 * s) * y0 + (3 * s2 - 4 * s + 1) * d0 + (-6 * s2 + 6 * s) * y1 + (3 * s2 - 2 * s) * d1
    return L, dLds / h


@jit_step
def common_piece(t, mp, mot_t, mot_n):
    """The knot index lo such that every muscle's length path has t strictly inside its knots
    and on its piece [t_lo, t_lo+1) (what :func:`motion_length`'s search finds for each), or -1
    if there is none (a muscle of fixed volume, t outside a path, or paths cut differently).

    The coupled engine gives all muscles paths with the same knot times, so one search serves
    them all, and the volume loop of :func:`rhs` then reads every muscle's path at the same
    column (a loop the compiler vectorizes; with a search per muscle it cannot).
    """
    n = mp.shape[0]
    if n == 0 or mot_n[0] < 2 or not (t > mot_t[0, 0] and t < mot_t[0, mot_n[0] - 1]):
        return -1
    lo = 0
    hi = mot_n[0] - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if mot_t[0, mid] <= t:
            lo = mid
        else:
            hi = mid
    for i in range(n):
        nk = mot_n[i]
        # knots sorted: t_lo <= t < t_lo+1 inside (t_0, t_last) makes lo the one answer
        if not (mp[i, M_FIXEDV] <= 0.0 and lo + 1 < nk and t > mot_t[i, 0] and t < mot_t[i, nk - 1]
                and mot_t[i, lo] <= t and t < mot_t[i, lo + 1]):
            return -1
    return lo


@jit
def muscle_volume_state(t, i, mp, mot_t, mot_L, mot_d, mot_n):
    """Total volume V [m^3] (the actuator type's volume, Eq. (5) for the McKibben muscle, plus dead
    volume, or the fixed volume), dV/dt [m^3/s] and the length L [m] (a muscle of fixed volume: its
    one knot's length, the rest length)."""
    if mp[i, M_FIXEDV] > 0.0:
        return mp[i, M_FIXEDV], 0.0, mot_L[i, 0]
    L, dL = motion_length(t, i, mot_t, mot_L, mot_d, mot_n)
    V, dVdL = checked_volume(mp[i, M_ACT], mp, i, L)
    return V + mp[i, M_DEAD], dVdL * dL, L


@jit_step
def _manifold_residual(pm, p_s, T_s, y, u, g, mp, n, work):
    """Main-tube inflow minus the open branches' outflow at manifold pressure pm [kg/s]."""
    R = g[G_R]
    rho_ref = g[G_RHOREF]
    T_ref = g[G_TREF]
    f = iso6358_mass_flow(p_s, T_s, pm, T_s, g[G_TUBE_C], g[G_TUBE_B], 0.5, g[G_TUBE_RLAM],
                          rho_ref, T_ref)
    for i in range(n):
        u_c = u[charge_valve(i)]
        if u_c > 0.0:
            p_i = y[pressure_index(i)]
            T_i = work[work_index(WORK_T, i, n)]
            mc, _ = valve_flows(mp[i, M_VALVE], mp, i, u_c, 0.0, pm, T_s, p_i, T_i, p_i, T_i, rho_ref, T_ref)
            f -= mc
    return f


@jit_step
def manifold_pressure(p_s, T_s, y, u, g, mp, n, work):
    """Physical tube mode: pressure where the main tube feeds the open branches [Pa abs].

    Solves main-tube flow(p_s -> pm) = sum of open charge-path flows(pm -> p_i) (a path of zero
    opening is left out of the balance: a proportional valve's leakage through a shut edge too); the
    residual is monotonically decreasing in pm, so a bracketed Illinois (regula falsi) iteration
    converges.
    """
    lo = p_s
    hi = p_s
    any_open = False
    for i in range(n):
        if u[charge_valve(i)] > 0.0:
            any_open = True
            p_i = y[pressure_index(i)]
            lo = min(lo, p_i)
            hi = max(hi, p_i)
    if not any_open or hi - lo <= 0.0:
        return p_s
    f_lo = _manifold_residual(lo, p_s, T_s, y, u, g, mp, n, work)
    f_hi = _manifold_residual(hi, p_s, T_s, y, u, g, mp, n, work)
    side = 0
    pm = 0.5 * (lo + hi)
    for _ in range(100):
        if f_lo == f_hi:
            pm = 0.5 * (lo + hi)
        else:
            pm = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        f = _manifold_residual(pm, p_s, T_s, y, u, g, mp, n, work)
        if f > 0.0:
            lo = pm
            f_lo = f
            if side == 1:
                f_hi *= 0.5
            side = 1
        else:
            hi = pm
            f_hi = f
            if side == -1:
                f_lo *= 0.5
            side = -1
        if hi - lo <= 1e-12 * hi or f == 0.0:
            break
    return pm


def _branches_of(flows):
    """The muscles' branches under one valve type whose ``flows`` (its compiled mass flows,
    :class:`frogsim.circuit.valves.spec.ValveType`) is inlined into the loop (a copy of it compiled
    for compiled callers only, as :func:`frogsim._jit.jit_inner` makes: the loop pays no call per
    muscle): each muscle's charge and discharge flows, its dm/dt, dp/dt and counters, aux's entries,
    and the chambers' sums (mass in, enthalpy in (sum m_dot T_in), mass out of the source and of the
    exhaust) returned."""
    flows = jit_inner(getattr(flows, "py_func", flows))

    @jit_inner
    def branches(n, y, u, mp, p_up, T_s, p_e, T_e, rho_ref, T_ref, mode, limit, R, k, dydt, aux, work):
        min_s = 0.0
        hin_s = 0.0
        out_s = 0.0
        min_e = 0.0
        hin_e = 0.0
        out_e = 0.0
        for i in range(n):
            p_i = y[pressure_index(i)]
            T_i = work[work_index(WORK_T, i, n)]
            hin_i = 0.0
            out_i = 0.0
            # 0.0 exactly through a shut path
            mc, md = flows(mp, i, u[charge_valve(i)], u[vent_valve(i)], p_up, T_s, p_i, T_i, p_e, T_e, rho_ref,
                           T_ref)
            if mc != 0.0:
                if mode == SUPPLY_PAPER:
                    mc = min(max(mc, -limit), limit)
                if mc >= 0.0:          # source -> muscle, at the source temperature
                    out_s += mc
                    hin_i += mc * T_s
                else:                  # muscle -> source (source below the muscle)
                    out_i -= mc
                    min_s -= mc
                    hin_s -= mc * T_i
            if md != 0.0:
                if md >= 0.0:          # muscle -> exhaust, at the muscle temperature
                    out_i += md
                    min_e += md
                    hin_e += md * T_i
                else:                  # exhaust -> muscle
                    out_e -= md
                    hin_i -= md * T_e
            dydt[mass_index(i)] = mc - md
            V_i = work[work_index(WORK_V, i, n)]
            dydt[pressure_index(i)] = pressure_rate(p_i, V_i, work[work_index(WORK_DV, i, n)], hin_i, out_i, T_i, R, k)
            dydt[charged_index(i, n)] = mc
            dydt[vented_index(i, n)] = md
            aux[charge_valve(i)] = mc
            aux[vent_valve(i)] = md
        return min_s, hin_s, out_s, min_e, hin_e, out_e
    return branches


def _branch_chain(types):
    """``muscle_branches(code, n, y, u, mp, ...)``: :func:`_branches_of` the valve type whose code is
    ``code``, the circuit's one type (a scenario's ``[valves]`` writes one type into every muscle
    row, :func:`frogsim.circuit.model.build_model`), tested once per call instead of once per
    muscle; one inlined branch per type of the registry, in the order of their codes (as
    :data:`frogsim.circuit.valves.valve_flows`), the last raising for a code no type declares. A
    circuit without muscles passes code 0.0 and runs no branch's loop."""
    def last(code, flows):
        body = _branches_of(flows)

        @jit_inner
        def branch(vc, n, y, u, mp, p_up, T_s, p_e, T_e, rho_ref, T_ref, mode, limit, R, k, dydt, aux, work):
            if vc != code and n > 0:
                raise ValueError("rhs: a muscle row's valve code is no valve type's (frogsim.circuit.valves)")
            return body(n, y, u, mp, p_up, T_s, p_e, T_e, rho_ref, T_ref, mode, limit, R, k, dydt, aux, work)
        return branch

    def link(code, flows, rest):
        body = _branches_of(flows)

        @jit_inner
        def branch(vc, n, y, u, mp, p_up, T_s, p_e, T_e, rho_ref, T_ref, mode, limit, R, k, dydt, aux, work):
            if vc == code:
                return body(n, y, u, mp, p_up, T_s, p_e, T_e, rho_ref, T_ref, mode, limit, R, k, dydt, aux, work)
            return rest(vc, n, y, u, mp, p_up, T_s, p_e, T_e, rho_ref, T_ref, mode, limit, R, k, dydt, aux, work)
        return branch

    out = last(types[-1].code, types[-1].flows)
    for vt in reversed(types[:-1]):
        out = link(vt.code, vt.flows, out)
    return out


#: the muscles' branches of the right-hand side under the circuit's valve type (row 0's code)
muscle_branches = _branch_chain(sorted(valve_types.BY_CODE.values(), key=lambda vt: vt.code))


@jit
def rhs(t, y, u, pump_on, g, mp, mot_t, mot_L, mot_d, mot_n, dydt, aux, work):
    """dy/dt of the whole circuit (see the module docstring and :mod:`frogsim.circuit.layout`).

    Every transfer moves mass out of one volume at that volume's temperature and into another, so
    the sum of the mass rates is zero term by term: air is conserved to rounding.

    The walls' heat is added at the end, behind one test of g[G_HEAT] (see the module docstring):
    an adiabatic run pays that one well-predicted branch per evaluation, and the body is compiled
    once.
    """
    n = mp.shape[0]
    k = g[G_K]
    R = g[G_R]
    rho_ref = g[G_RHOREF]
    T_ref = g[G_TREF]
    p_s = y[Y_PS]
    p_e = y[Y_PE]
    V_s = g[G_VS]
    V_e = g[G_VE]
    T_s = p_s * V_s / (y[Y_MS] * R)
    T_e = p_e * V_e / (y[Y_ME] * R)
    mode = int(g[G_SUPPLY_MODE])
    # work holds the muscles' temperatures, volumes, volume rates and lengths (the last for the wall
    # heat): its WORK_* blocks (frogsim.circuit.layout)
    lo = common_piece(t, mp, mot_t, mot_n)
    if lo >= 0:
        # the same numbers as the loop below (motion_length's piece, muscle_volume_state's sums)
        for i in range(n):
            L, dL = _hermite(t, i, lo, lo + 1, mot_t, mot_L, mot_d)
            Va, dVdL = checked_volume(mp[i, M_ACT], mp, i, L)
            V = Va + mp[i, M_DEAD]
            work[work_index(WORK_V, i, n)] = V
            work[work_index(WORK_DV, i, n)] = dVdL * dL
            work[work_index(WORK_L, i, n)] = L
            work[work_index(WORK_T, i, n)] = y[pressure_index(i)] * V / (y[mass_index(i)] * R)
    else:
        for i in range(n):
            V, dV, L = muscle_volume_state(t, i, mp, mot_t, mot_L, mot_d, mot_n)
            work[work_index(WORK_V, i, n)] = V
            work[work_index(WORK_DV, i, n)] = dV
            work[work_index(WORK_L, i, n)] = L
            work[work_index(WORK_T, i, n)] = y[pressure_index(i)] * V / (y[mass_index(i)] * R)
    p_up = p_s
    if mode == SUPPLY_PHYSICAL:
        p_up = manifold_pressure(p_s, T_s, y, u, g, mp, n, work)
    # the muscles' valves: the circuit's one valve type, dispatched once (see _branches)
    min_s, hin_s, out_s, min_e, hin_e, out_e = muscle_branches(
        mp[0, M_VALVE] if n > 0 else 0.0, n, y, u, mp, p_up, T_s, p_e, T_e, rho_ref, T_ref, mode,
        g[G_BRANCH_LIMIT], R, k, dydt, aux, work)
    m_pump = 0.0
    if pump_on > 0.5:
        m_pump = pump_mass_flow(p_e, T_e, p_s, g[G_PUMP_DISP], g[G_PUMP_RMAX], R)
        out_e += m_pump
        min_s += m_pump
        hin_s += m_pump * g[G_TAMB]   # delivered through the pump's cooling fin at ambient T
    aux[pump_entry(n)] = m_pump
    dydt[Y_MS] = min_s - out_s
    dydt[Y_PS] = pressure_rate(p_s, V_s, 0.0, hin_s, out_s, T_s, R, k)
    dydt[Y_ME] = min_e - out_e
    dydt[Y_PE] = pressure_rate(p_e, V_e, 0.0, hin_e, out_e, T_e, R, k)
    dydt[pump_index(n)] = m_pump
    if g[G_HEAT] > 0.0:
        # the walls' heat, (k - 1) Q / V on each volume's pressure rate (Eq. (**)); Q = h A (T_wall - T)
        # with a muscle's A its actuator type's wall at its length (work's WORK_L block; a muscle of fixed
        # volume keeps its one knot's length, the rest length); h = 0 gives Q = 0
        T_wall = g[G_TAMB]
        for i in range(n):
            Q = wall_heat_flow(mp[i, M_H], actuator_wall_area(mp[i, M_ACT], mp, i, work[work_index(WORK_L, i, n)]),
                               T_wall, work[work_index(WORK_T, i, n)])
            dydt[pressure_index(i)] += heat_pressure_rate(Q, work[work_index(WORK_V, i, n)], k)
        dydt[Y_PS] += heat_pressure_rate(wall_heat_flow(g[G_H_S], g[G_A_S], T_wall, T_s), V_s, k)
        dydt[Y_PE] += heat_pressure_rate(wall_heat_flow(g[G_H_E], g[G_A_E], T_wall, T_e), V_e, k)
