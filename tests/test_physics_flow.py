"""Flow through valves and tubes: ISO 6358 / paper Eq. (8), the main-pipe limit Eq. (9) and the
tube's sonic conductance (frogsim.physics.flow, frogsim.physics.air).

Expected values come from closed forms written out in the tests (ISO 6358-1:2013, the paper,
textbook isentropic nozzle flow), not from the code's output.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import (B_MHJ9, C_MHJ9, K_AIR, MAIN_BORE, N_BRANCHES, P_ATM, P_REF, P_SOURCE0,
                      R_AIR, RHO_REF, SONIC_VELOCITY, T_REF)
from frogsim.physics.air import (choked_mass_flux_factor, critical_pressure_ratio, density,
                                 speed_of_sound)
from frogsim.physics.flow import (iso6358_flow_function, iso6358_mass_flow,
                                  main_pipe_branch_limit, tube_sonic_conductance)


def iso_omega(sigma, b, m, r_lam):
    """ISO 6358-1:2013 flow function written out independently of frogsim.

    q_m = C rho0 p1 sqrt(T0/T1) * omega, with
      omega = 1                                             p2/p1 <= b
      omega = [1 - ((sigma - b)/(1 - b))^2]^m               b < p2/p1 <= r_lam
      omega = (1 - sigma)/(1 - r_lam) [1 - ((r_lam - b)/(1 - b))^2]^m   r_lam < p2/p1 <= 1
    """
    if sigma <= b:
        return 1.0
    if sigma > r_lam:
        return (1.0 - sigma) / (1.0 - r_lam) * (1.0 - ((r_lam - b) / (1.0 - b)) ** 2) ** m
    return (1.0 - ((sigma - b) / (1.0 - b)) ** 2) ** m


def flow(p_a, T_a, p_b, T_b, C=C_MHJ9, b=B_MHJ9, m=0.5, r_lam=1.0):
    return iso6358_mass_flow(p_a, T_a, p_b, T_b, C, b, m, r_lam, RHO_REF, T_REF)


# ---------------------------------------------------------------------------------------------
# air helpers
# ---------------------------------------------------------------------------------------------

def test_air_constants_closed_forms():
    # ideal gas: rho = p/(R T); ISO 8778 reference density 100 kPa / (287 * 293.15) = 1.1886 kg/m^3
    assert density(P_REF, T_REF, R_AIR) == pytest.approx(1.0e5 / (287.0 * 293.15), rel=1e-14)
    # a = sqrt(k R T) = 343.2 m/s at 293.15 K (value used by the paper's Eq. (9) setting)
    assert speed_of_sound(T_REF, R_AIR, K_AIR) == pytest.approx(343.2, abs=0.05)
    # isentropic critical ratio (2/(k+1))^(k/(k-1)) = 0.5283 for k = 1.4 (any gas-dynamics text)
    assert critical_pressure_ratio(K_AIR) == pytest.approx((2.0 / 2.4) ** 3.5, rel=1e-14)
    assert critical_pressure_ratio(K_AIR) == pytest.approx(0.5283, abs=1e-4)
    # choked mass flux factor sqrt(k/R) (2/(k+1))^((k+1)/(2(k-1))) = 0.0404 s K^0.5/m for air
    assert choked_mass_flux_factor(R_AIR, K_AIR) == pytest.approx(
        math.sqrt(1.4 / 287.0) * (2.0 / 2.4) ** 3.0, rel=1e-14)


# ---------------------------------------------------------------------------------------------
# Eq. (8) / ISO 6358
# ---------------------------------------------------------------------------------------------

def test_mhj9_choked_flow_closed_form():
    # paper Sec. 3.3 + Eq. (8): choked (p2/p1 <= b) standard volume flow Q = C p1 sqrt(T0/T1).
    # MHJ9: C = 0.4 L/(s bar); from 7.01325 bar abs at T_ref into 1.01325 bar abs
    # (sigma = 0.1445 < 0.38): Q = 0.4 * 7.01325 L/s standard = 2.8053 L/s = 168.3 L/min.
    q_expected = 0.4 * 7.01325 * 1e-3                      # m^3/s standard
    mdot = flow(P_SOURCE0, T_REF, P_ATM, T_REF)
    assert mdot == pytest.approx(RHO_REF * q_expected, rel=1e-12)
    assert mdot / RHO_REF * 6e4 == pytest.approx(168.3, abs=0.05)      # L/min standard
    # same for any downstream pressure up to b p1 (choked: independent of p2)
    for p2 in (0.0, 2.0e5, 0.999999 * B_MHJ9 * P_SOURCE0, B_MHJ9 * P_SOURCE0):
        assert flow(P_SOURCE0, T_REF, p2, T_REF) == pytest.approx(RHO_REF * q_expected, rel=1e-12)


def test_choked_flow_scales_with_upstream_temperature():
    # Eq. (8): Q proportional to sqrt(T0/T1) (T0 = ISO reference temperature); the downstream
    # temperature plays no role.
    T1 = 350.0
    expected = RHO_REF * C_MHJ9 * P_SOURCE0 * math.sqrt(T_REF / T1)
    assert flow(P_SOURCE0, T1, P_ATM, 200.0) == pytest.approx(expected, rel=1e-12)
    assert flow(P_SOURCE0, T1, P_ATM, 400.0) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("b,m", [(0.38, 0.5), (0.2, 0.3), (0.5, 0.7)])
def test_omega_continuous_at_critical_ratio(b, m):
    # omega = 1 at sigma = b from the choked side, and [1 - (eps/(1-b))^2]^m -> 1 from the
    # subsonic side: the jump must vanish as eps -> 0 (deviation ~ m eps^2/(1-b)^2).
    assert iso6358_flow_function(b, b, m, 0.999) == 1.0
    for eps in (1e-3, 1e-5, 1e-7):
        below = iso6358_flow_function(b - eps, b, m, 0.999)
        above = iso6358_flow_function(b + eps, b, m, 0.999)
        assert below == 1.0
        assert abs(above - below) <= 2.0 * m * (eps / (1.0 - b)) ** 2 + 1e-15
    # and the mass flow itself is continuous at p2 = b p1
    f_lo = flow(P_SOURCE0, T_REF, b * P_SOURCE0 * (1 - 1e-9), T_REF, b=b, m=m)
    f_hi = flow(P_SOURCE0, T_REF, b * P_SOURCE0 * (1 + 1e-9), T_REF, b=b, m=m)
    assert f_hi == pytest.approx(f_lo, rel=1e-12)


@pytest.mark.parametrize("b,m,r_lam", [(0.38, 0.5, 0.999), (0.38, 0.5, 0.995), (0.2, 0.3, 0.997)])
def test_omega_continuous_at_laminar_ratio(b, m, r_lam):
    # ISO 6358-1:2013: the laminar branch starts from the subsonic value at r_lam.
    at = iso_omega(r_lam, b, m, r_lam)
    assert iso6358_flow_function(r_lam, b, m, r_lam) == pytest.approx(at, rel=1e-12)
    # both one-sided slopes are finite (subsonic: |d omega/d sigma| = 2 m x/(1-b) * omega/(1-x^2);
    # laminar: omega(r_lam)/(1 - r_lam)), so the jump must shrink linearly with eps; a bound of
    # 1000 * eps is far above both slopes (< 300 here) but far below any real jump.
    for eps in (1e-5, 1e-7, 1e-9):
        below = iso6358_flow_function(r_lam - eps, b, m, r_lam)
        above = iso6358_flow_function(r_lam + eps, b, m, r_lam)
        assert abs(above - below) <= 1000.0 * eps
        assert below == pytest.approx(at, abs=500.0 * eps)
        assert above == pytest.approx(at, abs=500.0 * eps)


@pytest.mark.parametrize("r_lam", [1.0, 0.999, 0.995])
def test_zero_flow_at_equal_pressures(r_lam):
    # sigma = 1: no pressure difference, no flow (ISO 6358 laminar branch: omega = 0 at sigma = 1;
    # paper Eq. (8): sqrt(1 - 1) = 0)
    assert iso6358_flow_function(1.0, B_MHJ9, 0.5, r_lam) == 0.0
    assert flow(P_SOURCE0, T_REF, P_SOURCE0, 330.0, r_lam=r_lam) == 0.0
    assert flow(P_ATM, 250.0, P_ATM, T_REF, r_lam=r_lam) == 0.0


@pytest.mark.parametrize("sigma", [0.1, 0.38, 0.5, 0.69, 0.9, 0.99, 0.9995])
def test_flow_in_either_direction(sigma):
    # The upstream side is the higher pressure: swapping the sides negates the flow, and the flow
    # from b to a uses T_b (the side it leaves), not T_a.
    p_hi = 6.0e5
    p_lo = sigma * p_hi
    T_hi, T_lo = 340.0, 260.0
    fwd = flow(p_hi, T_hi, p_lo, T_lo, r_lam=0.999)
    rev = flow(p_lo, T_lo, p_hi, T_hi, r_lam=0.999)
    assert fwd > 0.0
    assert rev == -fwd
    expected = RHO_REF * C_MHJ9 * p_hi * math.sqrt(T_REF / T_hi) * iso_omega(sigma, B_MHJ9, 0.5, 0.999)
    assert rev == pytest.approx(-expected, rel=1e-12)
    # the downstream side's temperature does not matter
    assert flow(p_lo, 150.0, p_hi, T_hi, r_lam=0.999) == pytest.approx(rev, rel=1e-14)
    assert flow(p_hi, T_hi, p_lo, 500.0, r_lam=0.999) == pytest.approx(fwd, rel=1e-14)


def test_paper_eq8_subsonic_values():
    # paper Eq. (8) (m = 1/2, no laminar region): omega = sqrt(1 - ((sigma - b)/(1 - b))^2).
    # b = 0.38, sigma = 0.69: (0.31/0.62) = 0.5 -> omega = sqrt(0.75) = 0.8660
    assert iso6358_flow_function(0.69, 0.38, 0.5, 1.0) == pytest.approx(math.sqrt(0.75), rel=1e-12)
    for sigma in np.linspace(0.381, 0.9999, 50):
        x = (sigma - 0.38) / 0.62
        assert iso6358_flow_function(sigma, 0.38, 0.5, 1.0) == pytest.approx(math.sqrt(1 - x * x),
                                                                             rel=1e-12)


@pytest.mark.parametrize("m", [0.3, 0.5, 0.65, 1.0])
def test_subsonic_index(m):
    # ISO 6358-1:2013 subsonic branch [1 - ((sigma - b)/(1 - b))^2]^m: at x = 0.5 it is 0.75^m
    b = 0.38
    sigma = b + 0.5 * (1 - b)
    assert iso6358_flow_function(sigma, b, m, 0.999) == pytest.approx(0.75 ** m, rel=1e-12)
    for sigma in (0.4, 0.6, 0.8, 0.95, 0.998):
        assert iso6358_flow_function(sigma, b, m, 0.999) == pytest.approx(
            iso_omega(sigma, b, m, 0.999), rel=1e-12)
    # mass flow: C rho_ref p1 sqrt(T_ref/T1) omega
    p1, T1 = 5.0e5, 310.0
    p2 = 0.8 * p1
    assert flow(p1, T1, p2, T_REF, m=m, r_lam=0.999) == pytest.approx(
        RHO_REF * C_MHJ9 * p1 * math.sqrt(T_REF / T1) * iso_omega(0.8, b, m, 0.999), rel=1e-12)


@pytest.mark.parametrize("b,m,r_lam", [(0.38, 0.5, 0.999), (0.3, 0.4, 0.995)])
def test_laminar_region_is_linear_in_pressure_difference(b, m, r_lam):
    # ISO 6358-1:2013 laminar region (r_lam < p2/p1 <= 1): omega proportional to (1 - sigma),
    # with the constant fixed by continuity at r_lam: omega(r_lam) / (1 - r_lam).
    slope = iso_omega(r_lam, b, m, r_lam) / (1.0 - r_lam)
    sig = np.linspace(r_lam + 1e-6, 1.0 - 1e-9, 101)
    om = np.array([iso6358_flow_function(s, b, m, r_lam) for s in sig])
    assert np.allclose(om / (1.0 - sig), slope, rtol=1e-9, atol=0.0)
    # so for a fixed upstream side the mass flow is linear in p2: second differences vanish
    p1 = 5.0e5
    p2 = p1 * np.linspace(r_lam + 1e-5, 1.0, 21)
    f = np.array([flow(p1, T_REF, q, T_REF, b=b, m=m, r_lam=r_lam) for q in p2])
    assert np.max(np.abs(np.diff(f, 2))) <= 1e-9 * np.max(np.abs(np.diff(f)))
    # and the slope there is finite, unlike the paper's Eq. (8) (r_lam = 1), whose slope grows
    # without bound as sigma -> 1
    assert np.all(np.diff(f) < 0)


def test_flow_decreases_monotonically_with_downstream_pressure():
    # Raising the downstream pressure never increases the flow from a fixed upstream state;
    # past p2 = b p1 it strictly decreases, through zero at p2 = p1 and negative beyond.
    p1, T1 = P_SOURCE0, T_REF
    p2 = np.linspace(0.0, 1.5 * p1, 3001)
    for m, r_lam in ((0.5, 1.0), (0.5, 0.999), (0.3, 0.995)):
        f = np.array([flow(p1, T1, q, T_REF, m=m, r_lam=r_lam) for q in p2])
        d = np.diff(f)
        assert np.all(d <= 0.0)
        strict = p2[:-1] >= B_MHJ9 * p1
        assert np.all(d[strict] < 0.0)
        assert f[0] > 0.0 and f[-1] < 0.0


# ---------------------------------------------------------------------------------------------
# Eq. (9) and the tube bore
# ---------------------------------------------------------------------------------------------

def test_main_pipe_branch_limit_eq9():
    # paper Eq. (9) Q = pi r^2 v with the paper's setting (Sec. 4: 4 mm bore; sonic velocity
    # 343.2 m/s; one main pipe; six branches): pi (2e-3)^2 343.2 / 6 m^3/s
    expected = math.pi * (2.0e-3) ** 2 * 343.2 / 6.0
    q = main_pipe_branch_limit(MAIN_BORE, 343.2, 1.0, float(N_BRANCHES))
    assert q == pytest.approx(expected, rel=1e-14)
    # paper Sec. 4.3: "set at 45 L/min" per branch; the exact value is 43.1 L/min
    assert 42.0 <= q * 6e4 <= 46.0
    # linear in the number of tubes, inverse in the number of branches
    assert main_pipe_branch_limit(MAIN_BORE, 343.2, 2.0, 3.0) == pytest.approx(4.0 * expected, rel=1e-14)
    assert main_pipe_branch_limit(MAIN_BORE, SONIC_VELOCITY, 1.0, 6.0) == pytest.approx(
        expected, rel=1e-4)


@pytest.mark.parametrize("d,cd,T1", [(4.0e-3, 1.0, T_REF), (4.0e-3, 0.8, 350.0), (2.5e-3, 1.0, 250.0)])
def test_tube_sonic_conductance_gives_isentropic_choked_flow(d, cd, T1):
    # Textbook choked isentropic nozzle (e.g. Anderson, Modern Compressible Flow):
    #   m_dot = Cd A p1 sqrt(k/(R T1)) (2/(k+1))^((k+1)/(2(k-1)))
    # The ISO form with the tube's sonic conductance must give the same mass flow when choked.
    k, R = K_AIR, R_AIR
    A = math.pi * d * d / 4.0
    C_tube = tube_sonic_conductance(d, cd, R, k, RHO_REF, T_REF)
    b_tube = critical_pressure_ratio(k)
    for p1 in (3.0e5, 7.01325e5):
        textbook = cd * A * p1 * math.sqrt(k / (R * T1)) * (2.0 / (k + 1.0)) ** ((k + 1.0) / (2.0 * (k - 1.0)))
        for sigma in (0.0, 0.2, 0.5):   # all below the isentropic critical ratio 0.528
            iso = iso6358_mass_flow(p1, T1, sigma * p1, T_REF, C_tube, b_tube, 0.5, 1.0, RHO_REF, T_REF)
            assert iso == pytest.approx(textbook, rel=1e-12)
    # the claim: a 4 mm bore at 7 bar abs passes ~1050 L/min standard, several times
    # Eq. (9)'s 258.8 L/min for the whole main pipe
    if d == 4.0e-3 and cd == 1.0 and T1 == T_REF:
        q = iso6358_mass_flow(7.0e5, T1, 1e5, T1, C_tube, b_tube, 0.5, 1.0, RHO_REF, T_REF) / RHO_REF
        assert q * 6e4 > 3.0 * math.pi * (2e-3) ** 2 * 343.2 * 6e4
