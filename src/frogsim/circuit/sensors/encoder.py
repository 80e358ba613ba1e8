"""Sensor type "encoder": incremental quadrature encoders on the joints (``[firmware]
angle_encoder``), counted by the board's interrupts on a 16-bit counter.

Its count, floor(angle cpr / 2 pi) + 32768 (:data:`frogsim.scenario.firmware.ENCODER_ZERO` at the
joint's zero angle), written in the form of an ADC line so that the same arithmetic gives it
(:func:`frogsim.circuit.sensors.spec.line_count`): v0 = 0, k = cpr / (2 pi) V_REF / 65536,
q0 = -32768 2 pi / cpr, full = 65536. Its counts are not a voltage: no fault limits.
"""
from __future__ import annotations

import math

from frogsim.circuit.sensors.spec import SensorType, linear_count, linear_value
from frogsim.scenario.firmware import ENCODER_ZERO, AngleEncoder

CODE = 3.0
#: an encoder count's range: the firmware's uint16 counter
ENCODER_FULL = 65536


def line(s: AngleEncoder, vref: float, adc_full: int) -> tuple:
    cpr = float(s.counts_per_revolution)
    return (0.0, cpr / (2.0 * math.pi) * vref / ENCODER_FULL, -ENCODER_ZERO * 2.0 * math.pi / cpr), ENCODER_FULL


def faults(s, vref: float, adc_full: int):
    return None


SENSOR = SensorType(settings=AngleEncoder, code=CODE, line=line, faults=faults, count=linear_count, value=linear_value)
