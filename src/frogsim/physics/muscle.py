"""McKibben muscle geometry (paper Sec. 3.2, Eq. (5); Chou and Hannaford 1996) and crank mounting.

The braid is n turns of an inextensible thread of length b0. At length L the diameter is
D = sqrt(b0^2 - L^2)/(n pi) and the braid angle theta satisfies cos(theta) = L/b0. At rest length
L0 with inner diameter D0 and braid angle theta0: b0 = L0/cos(theta0), n = b0 sin(theta0)/(pi D0).
"""
from __future__ import annotations

import math

from frogsim._jit import jit


@jit
def braid_parameters(rest_length: float, rest_diameter: float, braid_angle: float):
    """Thread length b0 [m] and number of turns n [-] from rest length, diameter and braid angle.

    b0 = L0 / cos(theta0);  n = b0 sin(theta0) / (pi D0)   (cylinder of diameter D0 at rest).
    """
    b0 = rest_length / math.cos(braid_angle)
    n = b0 * math.sin(braid_angle) / (math.pi * rest_diameter)
    return b0, n


@jit
def muscle_volume(L: float, b0: float, n: float) -> float:
    """Eq. (5): V = (b0^2 - L^2) L / (4 pi n^2), internal volume of the braided cylinder  [m^3].

    At rest it equals the cylinder volume pi D0^2 L0 / 4. It is largest at L = b0/sqrt(3), the
    length at which the ideal muscle's force vanishes (theta = 54.7 deg).
    """
    return (b0 * b0 - L * L) * L / (4.0 * math.pi * n * n)


@jit
def muscle_volume_slope(L: float, b0: float, n: float) -> float:
    """dV/dL of Eq. (5): (b0^2 - 3 L^2) / (4 pi n^2)  [m^2]; negative for L > b0/sqrt(3)."""
    return (b0 * b0 - 3.0 * L * L) / (4.0 * math.pi * n * n)


@jit
def crank_muscle_length(theta: float, anchor_distance: float, crank_radius: float,
                        rest_angle: float, rest_length: float, side: float) -> float:
    """Active muscle length for a joint angle, muscle between a frame anchor and a crank pin  [m].

    The anchor sits at distance d from the joint axis; the crank pin at radius r turns with the
    joint. With gamma the angle between the crank and the line joint-anchor, the anchor-to-pin
    distance is s(gamma) = sqrt(d^2 + r^2 - 2 d r cos(gamma)) (law of cosines). At the rest angle
    the crank is perpendicular to that line (gamma = 90 deg, largest moment arm) and the muscle has
    its rest length; side = +1 for a muscle that shortens as theta grows, -1 for its antagonist:

        L(theta) = L0 + s(pi/2 - side (theta - theta_rest)) - s(pi/2)

    Args: theta, rest_angle [rad]; anchor_distance, crank_radius, rest_length [m]; side [+1 or -1].
    """
    d = anchor_distance
    r = crank_radius
    gamma = 0.5 * math.pi - side * (theta - rest_angle)
    s = math.sqrt(d * d + r * r - 2.0 * d * r * math.cos(gamma))
    s0 = math.sqrt(d * d + r * r)
    return rest_length + s - s0
