"""The added-mass and drag terms of frogsim.physics.hydro that the coupled engine calls each step,
against closed forms and values worked by hand."""
from __future__ import annotations

import numpy as np
import pytest

from frogsim.physics.hydro import (added_mass_rate_force, cross, fan_added_mass, gauss_strips,
                                   isotropic_added_mass, kirchhoff_velocity_force, munk_moment,
                                   strip_drag_wrench)

E1, E2, E3 = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
ORIGIN = (0.0, 0.0, 0.0)


def test_cross_product_of_the_axes():
    assert cross(*E1, *E2) == (0.0, 0.0, 1.0)
    assert cross(*E2, *E3) == (1.0, 0.0, 0.0)
    assert cross(1.0, 2.0, 3.0, 4.0, 5.0, 6.0) == (-3.0, 6.0, -3.0)


def test_kirchhoff_velocity_terms_vanish_without_rotation_or_with_equal_masses():
    # omega = 0: F = -M_A a only, the velocity terms are zero
    assert kirchhoff_velocity_force(1.0, 3.0, 7.0, 0.0, 0.0, 0.0, 0.3, -0.2, 0.5) == (0.0, 0.0, 0.0)
    # M_A = m I: m (omega x v) - omega x (m v) = 0 for any motion
    f = kirchhoff_velocity_force(2.5, 2.5, 2.5, 0.7, -1.1, 0.4, 0.3, -0.2, 0.5)
    assert f == pytest.approx((0.0, 0.0, 0.0), abs=1e-15)


def test_kirchhoff_velocity_terms_by_hand():
    # m = (1, 3, 0), v = (1, 0, 0), omega = (0, 0, 2):
    # omega x v = (0, 2, 0); M_A (omega x v) = (0, 6, 0); M_A v = (1, 0, 0); omega x M_A v = (0, 2, 0)
    # F_v = (0, 4, 0): a part turning while it moves along its axis is pushed sideways by the water
    # that must be set moving across it, (m_2 - m_1) omega v
    assert kirchhoff_velocity_force(1.0, 3.0, 0.0, 0.0, 0.0, 2.0, 1.0, 0.0, 0.0) == (0.0, 4.0, 0.0)


def test_added_mass_force_is_minus_m_a_for_pure_acceleration():
    # the whole added-mass force of a part is -M_A a + F_v - dM_A/dt v; accelerating from rest
    # (v = 0, omega = 0) with a constant added mass it is -M_A a
    m, a = (1.0, 3.0, 7.0), (0.5, -2.0, 1.5)
    fv = kirchhoff_velocity_force(*m, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    rate = [added_mass_rate_force(mj, mj, 1e-3, 0.0) for mj in m]
    total = [-mj * aj + fj + rj for mj, aj, fj, rj in zip(m, a, fv, rate)]
    assert total == [-0.5, 6.0, -10.5]


def test_munk_moment_closed_forms():
    # equal added masses: no moment
    assert munk_moment(2.0, 2.0, 2.0, 0.3, -0.4, 0.5) == pytest.approx((0.0, 0.0, 0.0), abs=1e-15)
    # motion along a principal axis: no moment
    assert munk_moment(1.0, 3.0, 3.0, 2.0, 0.0, 0.0) == (0.0, 0.0, 0.0)
    # by hand: m = (1, 3, 3), v = (1, 1, 0): (M_A v) x v = (1, 3, 0) x (1, 1, 0) = (0, 0, -2); it
    # turns the slender part (small m_1 along its axis) away from the flow, broadside (Munk 1924)
    assert munk_moment(1.0, 3.0, 3.0, 1.0, 1.0, 0.0) == (0.0, 0.0, -2.0)
    # in general (m_1 - m_2) v_1 v_2 about e3, and always normal to v
    m, v = (0.4, 1.7, 2.9), (0.3, -1.2, 0.8)
    M = munk_moment(*m, *v)
    assert M[2] == pytest.approx((m[0] - m[1]) * v[0] * v[1], rel=1e-14)
    assert np.dot(M, v) == pytest.approx(0.0, abs=1e-15)


def test_added_mass_rate_force():
    # added mass growing by 0.3 kg in 1 ms at 2 m/s: -(0.3 / 1e-3) * 2 = -600 N, against v
    assert added_mass_rate_force(1.0, 1.3, 1e-3, 2.0) == pytest.approx(-600.0, rel=1e-12)
    # shrinking gives the water's momentum back; constant gives nothing
    assert added_mass_rate_force(1.3, 1.0, 1e-3, 2.0) == pytest.approx(600.0, rel=1e-12)
    assert added_mass_rate_force(1.3, 1.3, 1e-3, 2.0) == 0.0


def test_fan_added_mass_scales_with_the_fan_angle():
    values = (1.0, 2.0, 3.0, 4.0, 5.0, 6.0)
    # phi = 1: a part of fixed shape keeps its values exactly
    assert fan_added_mass(*values, 1.0) == values
    # phi = 2: masses and cross-spoke inertias x 4 (h^2), the inertia about the spokes x 16 (h^4)
    assert fan_added_mass(*values, 2.0) == (4.0, 8.0, 12.0, 64.0, 20.0, 24.0)


def test_isotropic_added_mass_is_the_largest_free_direction():
    assert isotropic_added_mass(1.0, 2.0, 5.0, False) == 2.0     # e3 held: m_3 does not count
    assert isotropic_added_mass(1.0, 2.0, 5.0, True) == 5.0
    assert isotropic_added_mass(3.0, 2.0, 0.5, True) == 3.0


def test_strip_drag_wrench_translation_and_rotation_closed_forms():
    rho_cd_width = 0.5 * 998.2 * 1.17 * 0.1            # 1/2 rho C D [kg/m^2] of a 0.1 m wide plate
    length = 0.3
    s, ds = gauss_strips(6, 0.0, length)
    k = np.zeros((6, 3))
    k[:, 2] = rho_cd_width * ds                         # drag only normal to the plate (e3)
    # uniform translation along e3 at 2 m/s: F = -1/2 rho C D L |v| v, no moment about the centre
    F = strip_drag_wrench(s, k, 1.0, ORIGIN, E1, E2, E3, (0.0, 0.0, 0.0), (0.0, 0.0, 2.0),
                          ORIGIN, (length / 2, 0.0, 0.0))
    assert F[2] == pytest.approx(-rho_cd_width * length * 4.0, rel=1e-12)
    assert F[:2] == (0.0, 0.0)
    assert F[3:] == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    # rotation about the plate's edge (e2 axis through the origin) at omega: v_3(s) = -omega s,
    # F_3 = 1/2 rho C D omega^2 L^3 / 3, moment about the edge M_2 = -1/2 rho C D omega^2 L^4 / 4
    # (Gauss-Legendre is exact for these polynomials); a fan angle scales both
    w = 3.0
    F = strip_drag_wrench(s, k, 0.5, ORIGIN, E1, E2, E3, (0.0, w, 0.0), (0.0, 0.0, 0.0),
                          ORIGIN, ORIGIN)
    assert F[2] == pytest.approx(0.5 * rho_cd_width * w ** 2 * length ** 3 / 3, rel=1e-12)
    assert F[4] == pytest.approx(-0.5 * rho_cd_width * w ** 2 * length ** 4 / 4, rel=1e-12)
