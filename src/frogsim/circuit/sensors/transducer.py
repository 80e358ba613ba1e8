"""Sensor type "transducer": a pressure transducer with a voltage output linear in gauge pressure
(``[firmware] transducer``), read by the board's ADC.

Its line: V = v0 + k (p - q0) with v0 = low_voltage, k = (high_voltage - low_voltage) /
(high_pressure_gauge - low_pressure_gauge), q0 = low_pressure_gauge; its count the ADC's
(:func:`frogsim.circuit.sensors.spec.line_count`); a count below (low_voltage - fault_margin)
or above (high_voltage + fault_margin) is a fault (a dead or shorted transducer).
"""
from __future__ import annotations

import math

from frogsim.circuit.sensors.spec import SensorType, linear_count, linear_value
from frogsim.scenario.firmware import Transducer

CODE = 1.0


def line(s: Transducer, vref: float, adc_full: int) -> tuple:
    return (s.low_voltage, (s.high_voltage - s.low_voltage) / (s.high_pressure_gauge - s.low_pressure_gauge),
            s.low_pressure_gauge), adc_full


def faults(s, vref: float, adc_full: int) -> tuple:
    """(lo, hi): floor((low_voltage - margin) full / V_REF), floor((high_voltage + margin) full / V_REF),
    within the ADC's range."""
    lo = math.floor((s.low_voltage - s.fault_margin) * adc_full / vref)
    hi = math.floor((s.high_voltage + s.fault_margin) * adc_full / vref)
    return max(lo, 0), min(hi, adc_full - 1)


SENSOR = SensorType(settings=Transducer, code=CODE, line=line, faults=faults, count=linear_count, value=linear_value)
