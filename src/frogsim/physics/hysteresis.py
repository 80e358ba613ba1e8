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
