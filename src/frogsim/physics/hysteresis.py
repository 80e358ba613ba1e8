"""Force hysteresis of a McKibben muscle: a Maxwell-slip model on top of the static force law.

The paper (Sec. 3) notes the muscles' "apparent nonlinearity and hysteresis characteristics";
measured force-length loops at constant pressure are not traversed the same way loading and
unloading, and minor loops close inside the major one (Vo-Minh, Tjahjowidodo, Ramon and Van
Brussel 2011, IEEE/ASME Trans. Mechatronics 16:177, who fit exactly this model to a pneumatic
muscle; Liu et al. 2017, Strojniski vestnik 63:56). The loss comes from friction between the
braid's threads and between the braid and the bladder, which the pressure presses together.

Maxwell-slip (Lampaert, Al-Bender and Swevers 2003): N elasto-slide elements in parallel, each a
spring of stiffness k_i whose anchor a_i slides when the spring force reaches its slip force f_i:

    F_h = sum_i k_i (x - a_i),   |k_i (x - a_i)| <= f_i

where x is the muscle's contraction [m]. With the anchors a_i as the model's state, an update from
x_old to x_new is exact for any step (the model is rate independent: only the path's turning
points matter). Here the slip forces scale with the gauge pressure, f_i = phi_i p_gauge (friction
proportional to the contact pressure), so the loop widens with pressure and vanishes at 0 bar.

Closed forms the tests use: between turning points -X and +X (k_i X > f_i) element i traces a
parallelogram of height 2 f_i and width 2 (X - f_i / k_i), area 4 f_i (X - f_i / k_i), which is
also the work its slipping dissipates, f_i sum |da_i|; the model has return-point memory (a minor
loop closes where it left the major loop), as Preisach-type operators do.

The muscle's model (:func:`muscle_hysteresis_force`). Why Maxwell-slip: it is the model fitted to
a pneumatic muscle by Vo-Minh et al. (2011); its elements are the physical picture of the braid's
friction (contacts that stick, deform elastically, then slide), so its state (the anchors) has a
meaning and its dissipation is the slip work; its update is exact and rate independent for any
step, so the engines can update it at their own step (no integration of a non-smooth ODE). The
alternatives behave the same way on a loop: a Prandtl-Ishlinskii operator is the same sum of
play/stop operators (a Maxwell-slip model with fixed element ratios), and the asymmetric
modifications (Liu et al. 2017) add fitted shape functions that a force table of a few points
cannot pin down. A braid-friction model (Tondu 2012, Int. J. Intell. Mater. Syst. Struct. 23:225,
review: "hysteresis ... essentially due to strand-on-strand friction") gives the loop's size from
a friction coefficient and a contact geometry that are hard to know; the elements here give it
directly, fitted to a measured loop.

The muscle's elements act on the contraction eps = 1 - L/L0 (as the bladder force does, so a
muscle's loop does not depend on its length), and both the slip forces and the elements'
stiffnesses are proportional to the gauge pressure (friction grows with the contact pressure that
the air presses the threads together with: an assumption, the simplest one that makes the loop
vanish at 0 bar and widen with pressure). Element j slips when its contraction from its anchor
reaches its width w_j, with slip force c_j p_g (stiffness c_j p_g / w_j):

    F_h = p_g sum_j c_j z_j,   z_j = (eps - a_j) / w_j  in [-1, 1]

and the tension is max(0, F_static - F_h): shortening (eps rising) the muscle pulls less than the
static law, stretched it pulls more; the loop's full height is 2 p_g sum_j c_j. With the widths
fixed, the anchors do not depend on the pressure: the memory is the contraction's path alone.
"""
from __future__ import annotations

from frogsim._jit import jit


@jit
def maxwell_slip_force(x: float, anchors, stiffness, slip) -> float:
    """The hysteresis force [N] at contraction x [m], sliding the anchors [m] (updated in place).

    Args:
        x: contraction (or any length coordinate) [m].
        anchors: a_i [m], the elements' state (length N).
        stiffness: k_i [N/m] (length N).
        slip: f_i [N] >= 0, the elements' slip forces at the present pressure (length N).
    Returns sum_i k_i (x - a_i) after each a_i has slid so that |k_i (x - a_i)| <= f_i.
    """
    F = 0.0
    for i in range(anchors.size):
        k = stiffness[i]
        f = slip[i]
        z = x - anchors[i]
        if k * z > f:
            anchors[i] = x - f / k
        elif k * z < -f:
            anchors[i] = x + f / k
        F += k * (x - anchors[i])
    return F


@jit
def muscle_hysteresis_force(p_gauge: float, contraction: float, anchors, stiffness, slip) -> float:
    """The muscle's hysteresis force F_h [N] (module docstring), sliding the anchors (in place).

    Args:
        p_gauge: the muscle's gauge pressure [Pa].
        contraction: eps = 1 - L/L0 [-].
        anchors: a_j [-], the muscle's elements' state (length N), in contraction.
        stiffness: c_j / w_j [N/Pa per unit contraction] (length N; :func:`element_table`).
        slip: c_j [N/Pa], element j's slip force per gauge pressure (length N).
    Returns p_g sum_j c_j (eps - a_j) / w_j after each a_j has slid so that |eps - a_j| <= w_j:
    :func:`maxwell_slip_force` on the contraction, per pascal, times p_g. Subtract it from the
    static tension.
    """
    return p_gauge * maxwell_slip_force(contraction, anchors, stiffness, slip)


def element_table(elements: int, slip_per_pressure: float, slip_strain: float):
    """(stiffness [N/Pa], slip [N/Pa]) of the muscle's N elements, per pascal of gauge pressure,
    from the parameter set's three values (:func:`muscle_hysteresis_force`'s arrays).

    N = ``elements`` equal shares c_j = c / N of the total slip force per gauge pressure c
    (``slip_per_pressure`` [N/Pa]), widths w_j = s j / N, j = 1..N (``slip_strain`` s [-]: the
    widest element's), stiffness c_j / w_j: a branch leaving a turning point bends in N straight
    pieces and runs parallel to the static law (every element sliding) after a contraction change
    of 2 s. The loop's full height at gauge pressure p_g is 2 c p_g.
    """
    import numpy as np
    n = int(elements)
    widths = slip_strain * np.arange(1, n + 1, dtype=float) / n
    slip = np.full(n, slip_per_pressure / n)
    return slip / widths, slip


def settle_on_major_loop(anchors, low: float, high: float, stiffness, slip, rising: bool) -> None:
    """Put the anchors (in place) where a path swinging between ``low`` and ``high`` leaves them at
    its last turning point: ``low`` if ``rising`` (the branch that follows climbs from it), else
    ``high``. Two full swings wipe out the memory of any start inside [low, high] (every element
    that can slide within the swing has slid to the same place); elements narrower than the swing
    keep nothing of the start, the others do not slide at all and start at its middle."""
    anchors[:] = 0.5 * (low + high)
    for x in ((high, low, high, low) if rising else (low, high, low, high)):
        maxwell_slip_force(x, anchors, stiffness, slip)


@jit
def slip_work(anchors_before, anchors_after, slip) -> float:
    """Work the elements' slipping dissipates over one update: sum_i f_i |a_i' - a_i|  [J]."""
    w = 0.0
    for i in range(slip.size):
        w += slip[i] * abs(anchors_after[i] - anchors_before[i])
    return w


def loop_area(stiffness, slip, amplitude: float) -> float:
    """Area of the symmetric loop between contractions -X and +X (X = amplitude) [J]:
    sum over the elements that slip (k_i X > f_i) of 4 f_i (X - f_i / k_i)."""
    return float(sum(4.0 * f * (amplitude - f / k) for k, f in zip(stiffness, slip) if k * amplitude > f))
