"""A joint's end stops as elastomer pads: a one-sided spring and damper at each end of its range.

A hinge of range [lower, upper] meets a pad at each end. Past an end by the penetration delta > 0
the pad pushes back with the Kelvin-Voigt torque

    tau = -(k delta + c d(delta)/dt),  held at 0 if that would pull (a pad does not stick)    (S)

k [N m/rad] the stop's stiffness and c [N m s/rad] its damping about the joint axis (a pad of
linear stiffness k_p at lever arm r gives k = k_p r^2, and c = c_p r^2 likewise). Within the range
the torque is zero. :func:`stop_torque` evaluates (S). The coupled engine
(:mod:`frogsim.engine.coupled_kernel`) applies the spring as a joint torque and the damping as
MuJoCo's dof damping while the joint is on a pad (:func:`pad_spring_and_damping`), which MuJoCo's
implicitfast integrator takes at the step's end velocity: an explicit damping of c dt / I > 1
would overshoot every step on the light distal segments in air (palm: I about 0.003 kg m^2 with
the other joints free, c dt / I near 1.4 at 1 ms).

Why a spring and damper and not MuJoCo's limit constraint. MuJoCo's soft limit fixes the
*acceleration* of a joint past its limit, a1 + d (b v + k' r) = (1 - d) a0, with k' and b per unit
of the joint's effective inertia (negative solref values give k' and b directly, but still in
1/s^2 and 1/s) and the impedance d absorbing a fixed share of every applied torque: a stop that
is the same time constant whatever the inertia behind it, not a pad with a stiffness. The old
stop (time constant 5 ms, critically damped) stopped a swimming leg, with about 2.5 kg m^2 of
leg and entrained water about the hip, within 2-3 ms of touching: the leg's water was stopped as
fast, and its added-mass reaction, -m_A a, came as a thrust step of -100 to -175 N in one
1-ms sample (the issue's "one-sample spike" on the 10 ms output grid).

The jump a stop can make. Touching the pad between two samples (interval h, the joint turning at
omega_0), the torque rises from zero to at most

    d_tau <= c omega_0 + k omega_0 h                                                          (J)

(damping at the impact speed, plus the spring over at most omega_0 h of penetration; the engine
takes the damping at the step's end velocity, which is smaller). A torque change d_tau at joint j
changes the accelerations by M^-1 e_j d_tau (M the mass matrix, which holds the parts' added
masses; e_j the joint's unit vector) and the water's added-mass force along the heading h by

    d F = g_j d_tau,   g_j = -h^T sum_p M_A,p J_p M^-1 e_j,   |g_j| <= sqrt(m_A / I_j)        (B)

(J_p the Jacobian of part p's added-mass centre, M_A,p its added-mass matrix; the closed form
from M >= sum_p J_p^T M_A,p J_p and Cauchy-Schwarz, m_A the sum of the largest added masses of
the parts the joint moves, I_j = 1 / (M^-1)_jj its effective inertia with every other joint free).
The thrust can so jump by at most sum_j |g_j| (c_j omega_j + k_j omega_j h) over the joints that
touch a pad in the same interval; the drag changes continuously with the velocities. The swim
scenario's hips touch at 1.6 rad/s: |g| about 0.6 /m, c omega_0 = 90 N m, a bound near 125 N
against the 68 N seen, and the 174 N step of the rigid stop (tests/test_stops.py).

The impulse per stroke. The pads take from a leg and its water the momentum they carry at impact,
whatever their stiffness, as a rigid stop does; a pad spreads it over a longer time (the drag
meanwhile differs a little) and gives a share e = exp(-pi zeta / sqrt(1 - zeta^2)) of it back
(restitution, zeta = c / (2 sqrt(k I)) its damping ratio), throwing the leg back from its stop.
So a stroke's impulse (the thrust's integral) changes, against a rigid stop, by at most about e
times the momentum the stop takes: 0.62 x 3.2 Ns in the swim scenario's first stroke, where it
changes by 0.49 Ns (of 9.45 Ns): the rebound leaves the hip 3 deg short of its stop when the valves
switch to the recovery at 1 s, and the recovery starts from there.
"""
from __future__ import annotations

from frogsim._jit import jit


@jit
def pad_spring_and_damping(q: float, w: float, lower: float, upper: float, k: float, c: float):
    """Eq. (S) split into its spring torque [N m] and the damping coefficient in force [N m s/rad]
    for a joint at angle q [rad] turning at w [rad/s], range [lower, upper] [rad], stiffness k
    [N m/rad], damping c [N m s/rad]: the torque is spring - damping w. (0, 0) within the range and
    where the pad would pull."""
    if q > upper:
        if k * (q - upper) + c * w > 0.0:
            return -k * (q - upper), c
        return 0.0, 0.0
    if q < lower:
        if k * (lower - q) - c * w > 0.0:
            return k * (lower - q), c
        return 0.0, 0.0
    return 0.0, 0.0


@jit
def stop_torque(q: float, w: float, lower: float, upper: float, k: float, c: float) -> float:
    """Eq. (S): torque [N m] of the end stops of a joint at angle q [rad], turning at w [rad/s],
    range [lower, upper] [rad], stiffness k [N m/rad], damping c [N m s/rad]."""
    spring, damping = pad_spring_and_damping(q, w, lower, upper, k, c)
    return spring - damping * w


def torque_jump(k: float, c: float, speed: float, interval: float) -> float:
    """Eq. (J): the most a stop's torque rises between two samples ``interval`` [s] apart when the
    joint touches it at ``speed`` [rad/s]  [N m]."""
    return c * abs(speed) + k * abs(speed) * interval
