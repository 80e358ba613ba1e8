"""Thermodynamics of the air volumes (paper Eqs. (2)-(4), (6), (7)) and muscle geometry (Eq. (5),
crank mounting): frogsim.physics.gas and frogsim.physics.muscle, plus one integration test of
Eq. (3) through frogsim.simulate.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import frogsim
from conftest import K_AIR, P_ATM, P_SOURCE0, R_AIR, T_REF, one_muscle_scenario, steps
from frogsim.physics.gas import (adiabatic_temperature, exhaust_pressure_rate,
                                 muscle_charge_pressure_rate, muscle_discharge_pressure_rate,
                                 pressure_rate, source_pressure_rate)
from frogsim.physics.muscle import (braid_parameters, crank_muscle_length, muscle_volume,
                                    muscle_volume_slope)

k, R = K_AIR, R_AIR


# ---------------------------------------------------------------------------------------------
# Gas: Eqs. (2), (3), (4), (6), (7) and the general open-volume balance
# ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("mdot,T_s,V_s", [(3.3e-3, T_REF, 4e-3), (1e-4, 250.0, 1e-3), (0.0, 300.0, 2e-3)])
def test_eq2_source_is_pressure_rate_without_inflow(mdot, T_s, V_s):
    # paper Eq. (2): dp_s = -k R T_s dM / V_s  (rigid, adiabatic, no supply)
    expected = -k * R * T_s * mdot / V_s
    assert source_pressure_rate(mdot, T_s, V_s, R, k) == pytest.approx(expected, rel=1e-14, abs=0.0)
    # the same from the general balance with no inflow, no volume change (p does not enter)
    for p in (2e5, P_SOURCE0):
        assert pressure_rate(p, V_s, 0.0, 0.0, mdot, T_s, R, k) == pytest.approx(expected, rel=1e-14,
                                                                                  abs=0.0)


@pytest.mark.parametrize("p", [6.0e5, 3.0e5, 1.2e5])
def test_eq3_adiabatic_temperature(p):
    # paper Eq. (3): T/T0 = (p/p0)^((k-1)/k); with k = 1.4 the exponent is 2/7
    T0, p0 = T_REF, P_SOURCE0
    assert adiabatic_temperature(p, p0, T0, k) == pytest.approx(T0 * (p / p0) ** (2.0 / 7.0), rel=1e-14)
    assert adiabatic_temperature(p0, p0, T0, k) == pytest.approx(T0, rel=1e-15)


@pytest.mark.parametrize("p,T", [(P_SOURCE0, T_REF), (3.0e5, 260.0)])
def test_eq3_follows_from_the_balance_for_a_discharging_rigid_chamber(p, T):
    # A rigid chamber losing mass at its own temperature: with m = pV/(RT),
    # d ln T = d ln p - d ln m; Eq. (3) says d ln T / d ln p = (k - 1)/k exactly.
    V, mdot = 4e-3, 2e-3
    m = p * V / (R * T)
    dp = pressure_rate(p, V, 0.0, 0.0, mdot, T, R, k)
    dm = -mdot
    dlnT = dp / p - dm / m
    assert dlnT / (dp / p) == pytest.approx((k - 1.0) / k, rel=1e-12)


@pytest.mark.parametrize("mdot,T_in,V_e", [(2e-3, T_REF, 6e-3), (5e-4, 230.0, 1e-3)])
def test_eq4_exhaust_is_pressure_rate_with_inflow_only(mdot, T_in, V_e):
    # paper Eq. (4): k R T dm = V_e dp_e (rigid exhaust receiving air at the muscle's T)
    expected = k * R * T_in * mdot / V_e
    assert exhaust_pressure_rate(mdot, T_in, V_e, R, k) == pytest.approx(expected, rel=1e-14)
    # general balance: enthalpy inflow mdot*T_in, no outflow; the exhaust's own T and p do not matter
    for p, T in ((P_ATM, T_REF), (1.5e5, 330.0)):
        assert pressure_rate(p, V_e, 0.0, mdot * T_in, 0.0, T, R, k) == pytest.approx(expected, rel=1e-14)


@pytest.mark.parametrize("p,V,dVdt,mdot,T_s", [(2e5, 6e-5, 1e-4, 3e-3, T_REF),
                                                (6e5, 5e-5, -2e-5, 1e-3, 250.0),
                                                (1.1e5, 6e-5, 0.0, 2e-3, 300.0)])
def test_eq6_muscle_charging(p, V, dVdt, mdot, T_s):
    # paper Eq. (6): k R T_s dM = k P dV + V dP
    dp = muscle_charge_pressure_rate(p, V, dVdt, mdot, T_s, R, k)
    assert k * R * T_s * mdot == pytest.approx(k * p * dVdt + V * dp, rel=1e-12)
    # general balance with inflow at T_s, no outflow (the muscle's own T is irrelevant)
    for T in (T_REF, 400.0):
        assert pressure_rate(p, V, dVdt, mdot * T_s, 0.0, T, R, k) == pytest.approx(dp, rel=1e-12)


@pytest.mark.parametrize("p,V,dVdt,mdot,T", [(6e5, 6e-5, -1e-4, 3e-3, 400.0),
                                              (2e5, 5e-5, 2e-5, 1e-3, 250.0)])
def test_eq7_muscle_discharging(p, V, dVdt, mdot, T):
    # paper Eq. (7): -k R T dm = k P dV + V dP (air leaves at the muscle's own T)
    dp = muscle_discharge_pressure_rate(p, V, dVdt, mdot, T, R, k)
    assert -k * R * T * mdot == pytest.approx(k * p * dVdt + V * dp, rel=1e-12)
    assert pressure_rate(p, V, dVdt, 0.0, mdot, T, R, k) == pytest.approx(dp, rel=1e-12)


def test_closed_volume_compression_is_isentropic():
    # no mass flow: dp/p = -k dV/V (isentropic p V^k = const)
    p, V, dVdt = 3e5, 6e-5, -1e-4
    assert pressure_rate(p, V, dVdt, 0.0, 0.0, 300.0, R, k) == pytest.approx(-k * p * dVdt / V, rel=1e-14)


def test_source_discharge_follows_eq3_in_simulation():
    # A rigid 1 L source at 6 bar gauge discharges through the (open) charge valve into a big
    # low-pressure volume: a fixed-length "muscle" of 1 m x 100 mm (pi 0.1^2/4 * 1 = 7.85 L).
    # Adiabatic, outflow only: the source must follow paper Eq. (3), T/T0 = (p/p0)^((k-1)/k).
    big = {"nominal_length": "1 m", "inner_diameter": "100 mm", "braid_angle": "25.3 deg",
           "max_contraction": "25 %", "dead_volume": "0 cm^3", "stroke_contraction": "0 %",
           "crank_radius": "30 mm", "anchor_distance": "250 mm", "rest_angle": "0 deg"}
    d = one_muscle_scenario(steps((0.0, "charge")), 2.0, muscle_type="tank",
                            motion={"kind": "constant"},
                            muscle_types={"tank": big},
                            source={"volume": "1 L"},
                            supply={"mode": "none"},
                            solver={"rtol": 1e-10})
    res = frogsim.simulate(frogsim.load_scenario(d))
    p = res.source_pressure
    T = res.temperature("source")
    p0, T0 = p[0], T[0]
    assert p0 == pytest.approx(P_SOURCE0, rel=1e-12)       # fan2017: 6 bar gauge
    assert T0 == pytest.approx(T_REF, rel=1e-12)           # fan2017: ambient 293.15 K
    # the run must cover a wide pressure range for the test to mean something
    assert p[-1] < 0.5 * p0
    # the muscle stays below the source (flow one way only, the premise of Eq. (3))
    assert np.all(res.muscle_pressure("m0") <= p * (1 + 1e-9))
    expected = T0 * (p / p0) ** ((K_AIR - 1.0) / K_AIR)
    assert np.max(np.abs(T / expected - 1.0)) < 1e-6


# ---------------------------------------------------------------------------------------------
# Muscle: Eq. (5) and crank geometry
# ---------------------------------------------------------------------------------------------

# FESTO DMSP-20 (datasheet: 20 mm inner diameter); paper Sec. 2.2.2: 180 mm hip, 150 mm knee;
# braid angle 25.3 deg (fan2017.toml) and a few others
GEOMS = [(0.18, 0.02, math.radians(25.3)), (0.15, 0.02, math.radians(25.3)),
         (0.30, 0.01, math.radians(20.0)), (0.10, 0.04, math.radians(40.0))]


@pytest.mark.parametrize("L0,D0,theta0", GEOMS)
def test_rest_volume_is_the_cylinder(L0, D0, theta0):
    # Eq. (5) with b0 = L0/cos(theta0), n = b0 sin(theta0)/(pi D0): at rest the braided tube is a
    # cylinder of diameter D0 and length L0, volume pi D0^2 L0 / 4
    b0, n = braid_parameters(L0, D0, theta0)
    assert b0 == pytest.approx(L0 / math.cos(theta0), rel=1e-14)
    assert muscle_volume(L0, b0, n) == pytest.approx(math.pi * D0 ** 2 * L0 / 4.0, rel=1e-12)
    # DMSP-20, 180 mm: 56.5 cm^3
    if (L0, D0) == (0.18, 0.02):
        assert muscle_volume(L0, b0, n) * 1e6 == pytest.approx(56.55, abs=0.01)


@pytest.mark.parametrize("L0,D0,theta0", GEOMS)
def test_volume_is_largest_at_b0_over_sqrt3(L0, D0, theta0):
    # dV/dL = (b0^2 - 3 L^2)/(4 pi n^2) = 0 at L* = b0/sqrt(3) (braid angle 54.7 deg);
    # V(L*) = b0^3 / (6 sqrt(3) pi n^2)
    b0, n = braid_parameters(L0, D0, theta0)
    Ls = b0 / math.sqrt(3.0)
    assert abs(muscle_volume_slope(Ls, b0, n)) <= 1e-12 * b0 ** 2 / n ** 2
    vmax = b0 ** 3 / (6.0 * math.sqrt(3.0) * math.pi * n * n)
    assert muscle_volume(Ls, b0, n) == pytest.approx(vmax, rel=1e-12)
    grid = np.linspace(0.01 * b0, 0.99 * b0, 9999)
    vols = np.array([muscle_volume(x, b0, n) for x in grid])
    assert np.all(vols <= vmax * (1 + 1e-12))
    assert grid[np.argmax(vols)] == pytest.approx(Ls, abs=2 * (grid[1] - grid[0]))
    # the muscle shortens from rest towards L*, and its volume grows on the way
    assert Ls < L0
    assert muscle_volume(0.9 * L0, b0, n) > muscle_volume(L0, b0, n)


@pytest.mark.parametrize("L0,D0,theta0", GEOMS)
def test_volume_slope_matches_finite_difference(L0, D0, theta0):
    b0, n = braid_parameters(L0, D0, theta0)
    for L in (0.75 * L0, 0.87 * L0, L0, b0 / math.sqrt(3.0) * 1.01):
        h = 1e-6 * L0
        fd = (muscle_volume(L + h, b0, n) - muscle_volume(L - h, b0, n)) / (2.0 * h)
        # central difference of a cubic: error h^2 * |V'''|/6 = h^2 * 6/(4 pi n^2)/6, negligible
        scale = b0 * b0 / (4.0 * math.pi * n * n)
        assert muscle_volume_slope(L, b0, n) == pytest.approx(fd, rel=1e-6, abs=1e-8 * scale)


# fan2017.toml hip mounting (chosen values): crank 30 mm, anchor 250 mm, rest length 180 mm
CRANK = dict(anchor_distance=0.25, crank_radius=0.03, rest_length=0.18)


def crank_geometry(theta, d, r, rest, L0, side):
    """Independent geometry: joint at the origin, anchor at (d, 0); the crank pin at radius r makes
    the angle gamma = 90 deg - side (theta - rest) with the joint-anchor line."""
    gamma = 0.5 * math.pi - side * (theta - rest)
    pin = np.array([r * math.cos(gamma), r * math.sin(gamma)])
    pin0 = np.array([0.0, r])
    anchor = np.array([d, 0.0])
    return L0 + np.linalg.norm(anchor - pin) - np.linalg.norm(anchor - pin0)


@pytest.mark.parametrize("rest", [0.0, math.radians(20.0), math.radians(-35.0)])
def test_crank_length_rest_and_symmetry(rest):
    d, r, L0 = CRANK["anchor_distance"], CRANK["crank_radius"], CRANK["rest_length"]
    for side in (1.0, -1.0):
        assert crank_muscle_length(rest, d, r, rest, L0, side) == pytest.approx(L0, rel=1e-14)
    for delta in (0.05, 0.3, 0.8):
        plus = crank_muscle_length(rest + delta, d, r, rest, L0, 1.0)
        minus = crank_muscle_length(rest - delta, d, r, rest, L0, -1.0)
        # mirror symmetry: side -1 at rest - delta is side +1 at rest + delta
        assert minus == pytest.approx(plus, rel=1e-14)
        # the driving muscle (side +1) shortens as theta grows, its antagonist lengthens
        assert plus < L0
        assert crank_muscle_length(rest + delta, d, r, rest, L0, -1.0) > L0
        # law of cosines against explicit coordinates
        assert plus == pytest.approx(crank_geometry(rest + delta, d, r, rest, L0, 1.0), rel=1e-12)


def test_crank_moment_arm_at_rest():
    # With the crank perpendicular to the joint-anchor line, the muscle line's distance from the
    # joint axis (moment arm) is d r / sqrt(d^2 + r^2): dL/dtheta = -side * d r / sqrt(d^2 + r^2)
    d, r, L0 = CRANK["anchor_distance"], CRANK["crank_radius"], CRANK["rest_length"]
    arm = d * r / math.hypot(d, r)
    h = 1e-6
    for side in (1.0, -1.0):
        fd = (crank_muscle_length(h, d, r, 0.0, L0, side)
              - crank_muscle_length(-h, d, r, 0.0, L0, side)) / (2 * h)
        assert fd == pytest.approx(-side * arm, rel=1e-6)
