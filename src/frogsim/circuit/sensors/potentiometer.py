"""Sensor type "potentiometer": an analog joint-angle sensor (``[firmware] angle_sensor``), a
potentiometer with its amplifier, read by the board's ADC.

Its line: V = v0 + k (angle - q0) with v0 = low_voltage, k = (high_voltage - low_voltage) /
(high_angle - low_angle), q0 = low_angle; its count the ADC's; its fault limits as the
transducer's (:func:`frogsim.circuit.sensors.transducer.faults`).
"""
from __future__ import annotations

from frogsim.circuit.sensors.spec import SensorType, linear_count, linear_value
from frogsim.circuit.sensors.transducer import faults
from frogsim.scenario.firmware import AnglePotentiometer

CODE = 2.0


def line(s: AnglePotentiometer, vref: float, adc_full: int) -> tuple:
    return (s.low_voltage, (s.high_voltage - s.low_voltage) / (s.high_angle - s.low_angle), s.low_angle), adc_full


SENSOR = SensorType(settings=AnglePotentiometer, code=CODE, line=line, faults=faults, count=linear_count,
                    value=linear_value)
