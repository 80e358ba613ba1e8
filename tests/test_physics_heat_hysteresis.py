"""Wall heat transfer and Maxwell-slip hysteresis, each against closed forms.

Heat: a closed rigid volume's air relaxes to the wall temperature as exp(-t / tau),
tau = m c_v / (h A), its pressure following p = m R T / V; the muscle's wall area is the mantle of
Eq. (5)'s cylinder. Hysteresis: loops close, their area is the closed form 4 f (X - f/k) per
element and equals the slip work, minor loops return to the major loop where they left it, the
loop does not depend on how finely (how fast) the path is sampled.
"""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from frogsim.physics.heat import (cooling_time_constant, cylinder_wall_area, heat_pressure_rate,
                                  muscle_wall_area, wall_heat_flow)
from frogsim.physics.hysteresis import loop_area, maxwell_slip_force, slip_work
from frogsim.physics.muscle import braid_parameters, muscle_volume

R, K = 287.0, 1.4


def test_closed_rigid_volume_cools_with_the_closed_form_time_constant():
    V, A, h, Tw = 2e-4, 0.02, 20.0, 293.15
    p0, T0 = 7e5, 359.0                      # a hip muscle just charged to 6 bar gauge
    m = p0 * V / (R * T0)
    tau = cooling_time_constant(m, R, K, h, A)
    assert tau == pytest.approx(m * R / (K - 1) / (h * A))

    def dp(t, p):
        T = p[0] * V / (m * R)
        return [heat_pressure_rate(wall_heat_flow(h, A, Tw, T), V, K)]
    t = np.linspace(0, 5 * tau, 51)
    sol = solve_ivp(dp, (0, t[-1]), [p0], t_eval=t, rtol=1e-11, atol=1e-6)
    T_closed = Tw + (T0 - Tw) * np.exp(-t / tau)
    np.testing.assert_allclose(sol.y[0], m * R * T_closed / V, rtol=1e-8)


def test_no_heat_without_a_temperature_difference_or_coefficient():
    assert wall_heat_flow(20.0, 0.01, 300.0, 300.0) == 0.0
    assert wall_heat_flow(0.0, 0.01, 300.0, 360.0) == 0.0
    assert wall_heat_flow(20.0, 0.01, 300.0, 360.0) < 0.0      # hot air loses heat


def test_muscle_wall_is_the_mantle_of_eq5s_cylinder():
    L0, D0, theta0 = 0.18, 0.02, math.radians(22.0)
    b0, n = braid_parameters(L0, D0, theta0)
    assert muscle_wall_area(L0, b0, n) == pytest.approx(math.pi * D0 * L0, rel=1e-12)
    for L in np.linspace(0.75 * L0, L0, 7):
        D = math.sqrt(b0 ** 2 - L ** 2) / (n * math.pi)
        # V = pi D^2 L / 4 and A = pi D L: V = A D / 4
        assert muscle_volume(L, b0, n) == pytest.approx(muscle_wall_area(L, b0, n) * D / 4, rel=1e-12)


def test_cylinder_area():
    D = 0.1
    assert cylinder_wall_area(math.pi * D ** 3 / 4, 1.0) == pytest.approx(1.5 * math.pi * D ** 2)


# --- hysteresis ----------------------------------------------------------------------------------------
K_I = np.array([2e5, 5e4, 1e4])            # [N/m]
F_I = np.array([20.0, 30.0, 15.0])         # [N]


def trace(path, anchors=None):
    a = np.zeros(K_I.size) if anchors is None else anchors
    F, work = [], 0.0
    for x in path:
        before = a.copy()
        F.append(maxwell_slip_force(x, a, K_I, F_I))
        work += slip_work(before, a, F_I)
    return np.array(F), work, a


def cycle(X, n=400):
    up = np.linspace(-X, X, n)
    return np.concatenate([up, up[::-1][1:]])


def test_loop_closes_and_its_area_is_the_closed_form_and_the_slip_work():
    X = 4e-3
    _, _, a = trace(cycle(X))                           # settle onto the loop
    path = cycle(X)
    F, work, _ = trace(path, a)
    assert F[-1] == pytest.approx(F[0], abs=1e-9)      # closes
    F2, _, _ = trace(path, a.copy())
    np.testing.assert_allclose(F2, F, atol=1e-9)       # and repeats
    area = -np.trapezoid(F, path)                      # clockwise in (x, F): the loss
    expected = loop_area(K_I, F_I, X)
    assert expected == pytest.approx(sum(4 * f * (X - f / k) for k, f in zip(K_I, F_I)))
    assert abs(area) == pytest.approx(expected, rel=1e-3)
    assert work == pytest.approx(expected, rel=1e-9)


def test_minor_loop_returns_to_the_major_loop_where_it_left_it():
    X, x1, x2 = 4e-3, 1.5e-3, -0.5e-3
    _, _, a = trace(cycle(X))
    up_to_x1 = np.linspace(-X, x1, 300)
    F_major, _, a_major = trace(np.concatenate([up_to_x1, np.linspace(x1, X, 300)[1:]]), a.copy())
    F_left, _, a1 = trace(up_to_x1, a.copy())
    F_minor, _, _ = trace(np.concatenate([np.linspace(x1, x2, 200), np.linspace(x2, x1, 200)[1:]]), a1)
    assert F_minor[-1] == pytest.approx(F_left[-1], abs=1e-9)          # back where it left
    F_after, _, _ = trace(np.linspace(x1, X, 300)[1:], a1)
    np.testing.assert_allclose(F_after, F_major[300:], atol=1e-9)       # and on the major loop again


def test_loop_does_not_depend_on_the_rate():
    X = 3e-3
    coarse = cycle(X, 11)                                  # the same turning points, fewer samples
    F_coarse, w_coarse, _ = trace(coarse)
    F_fine, w_fine, _ = trace(cycle(X, 1001))
    np.testing.assert_allclose(F_fine[::100], F_coarse, atol=1e-9)
    assert w_fine == pytest.approx(w_coarse, rel=1e-12)


def test_no_slip_force_no_hysteresis():
    a = np.zeros(3)
    for x in cycle(2e-3, 50):
        assert maxwell_slip_force(x, a, K_I, np.zeros(3)) == 0.0
