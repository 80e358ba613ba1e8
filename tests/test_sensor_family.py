"""The sensor family: the firmware's sensors (pressure transducer, joint potentiometer, quadrature
encoder) one module each, found through their registry; their counts are the ADC's and the
encoder counter's closed forms; an unknown sensor code is an error; a new sensor type is one new
module, nothing else edited."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from numba import njit

from frogsim.circuit.sensors import sensor_count
from tests.package_copy import package_copy, run_copy as _run_copy


def test_the_registry_holds_the_shipped_sensors_with_unique_codes():
    from frogsim.circuit import sensors
    from frogsim.scenario import sensors as loader
    from frogsim.scenario.firmware import AngleEncoder, AnglePotentiometer, Transducer
    assert {"transducer", "potentiometer", "encoder"} <= set(sensors.TYPES)
    assert [sensors.of(s()).quantity for s in (Transducer, AnglePotentiometer, AngleEncoder)] == \
        ["pressure", "angle", "angle"]
    codes = [s.code for s in sensors.TYPES.values()]
    assert len(codes) == len(set(codes))
    assert all(loader.TYPES[n] is s.settings for n, s in sensors.TYPES.items())


@njit
def _count(code, v0, k, q0, full, vref, q):
    return sensor_count(code, v0, k, q0, full, vref, q)


def _counts(code, line, full, vref, q):
    (v0, k, q0) = line
    return _count(code, v0, k, q0, float(full), vref, q)


def test_the_transducer_count_is_the_datasheet_conversion():
    """0.5-4.5 V over 0-10 bar on a 10-bit ADC at V_REF 5 V (the ATmega2560 datasheet's
    ADC = V_in 1024 / V_REF, truncated): 3 bar is 1.7 V, count floor(348.16) = 348; 0 bar 102;
    past the top the count clips at 1023."""
    from frogsim.circuit import sensors
    from frogsim.scenario.firmware import Transducer
    t = Transducer()
    line, full = sensors.line(t, 5.0, 1024)
    code = sensors.of(t).code
    assert _counts(code, line, full, 5.0, 3e5) == 348
    assert _counts(code, line, full, 5.0, 0.0) == 102
    assert _counts(code, line, full, 5.0, 20e5) == 1023
    # fault limits: (0.5 - 0.2) V and (4.5 + 0.2) V as counts
    assert sensors.faults(t, 5.0, 1024) == (math.floor(0.3 * 1024 / 5), math.floor(4.7 * 1024 / 5))


def test_the_encoder_count_is_the_counter_closed_form():
    """count = floor(angle cpr / 2 pi) + 32768 on the 16-bit counter, no fault limits."""
    from frogsim.circuit import sensors
    from frogsim.scenario.firmware import AngleEncoder
    e = AngleEncoder(counts_per_revolution=2000)
    line, full = sensors.line(e, 5.0, 1024)
    assert full == 65536 and sensors.faults(e, 5.0, 1024) is None
    code = sensors.of(e).code
    for turns in (0.0, 5.5 / 2000, -7.25 / 2000, 0.1):
        angle = 2 * math.pi * turns
        assert _counts(code, line, full, 5.0, angle) == math.floor(turns * 2000 + 1e-9) + 32768


def test_an_unknown_sensor_code_is_an_error():
    with pytest.raises(ValueError, match="sensor code is no sensor type's"):
        _count(9.0, 0.5, 4e-6, 0.0, 1024.0, 5.0, 3e5)


SENSOR_MODULE = '''
"""A throw-away sensor type: a pressure transducer read as its count rounded to the nearest."""
import math
from dataclasses import dataclass
from typing import ClassVar

from frogsim._jit import jit_inner
from frogsim.circuit.sensors.spec import SensorType, linear_value
from frogsim.scenario.fields import quantity
from frogsim.scenario.sensors import SensorSettings

CODE = {code}


@dataclass(frozen=True)
class Rounding(SensorSettings):
    TYPE: ClassVar[str] = "rounding"
    QUANTITY: ClassVar[str] = "pressure"
    span: float = quantity("pressure", gt=0.0, display="bar", default=10e5)


def line(s, vref, adc_full):
    return (0.0, vref / s.span, 0.0), adc_full


def faults(s, vref, adc_full):
    return None


@jit_inner
def count(v0, k, q0, full, vref, q):
    x = math.floor((v0 + k * (q - q0)) * full / vref + 0.5)
    return int(min(max(x, 0.0), full - 1.0))


SENSOR = SensorType(settings=Rounding, code=CODE, line=line, faults=faults, count=count, value=linear_value)
'''

SENSOR_RUN = r'''
import json
from numba import njit
import frogsim
from frogsim.circuit import sensors

@njit
def count(code, v0, k, q0, full, vref, q):
    return sensors.sensor_count(code, v0, k, q0, full, vref, q)

s = sensors.TYPES["rounding"].settings()
(v0, k, q0), full = sensors.line(s, 5.0, 1024)
out = {"module": sensors.TYPES["rounding"].module, "quantity": sensors.TYPES["rounding"].quantity,
       "c": count(9.0, v0, k, q0, float(full), 5.0, 300488.28),
       "t": count(1.0, 0.5, 4e-6, 0.0, 1024.0, 5.0, 3e5)}

# chosen by name in a scenario's [firmware]: the model's firmware row carries its code, and the board's
# count of the muscle at 300488.28 Pa gauge is its own (SIL's counts, frogsim.control.firmware.adc_counts)
import pathlib, tomllib
from frogsim.circuit.layout import G_PATM, pressure_index
from frogsim.circuit.model import build_model
from frogsim.control.firmware import adc_counts, firmware_plan
from frogsim.control.table import L_ADC_CODE
d = tomllib.loads((pathlib.Path(frogsim.__file__).parent / "scenarios" / "hold-3bar.toml").read_text())
for name, table in (("rounding", {"type": "rounding", "span": "10 bar"}), ("transducer", {"type": "transducer"})):
    sc = frogsim.load_scenario(dict(d, duration="1 s", firmware=dict(d["firmware"], transducer=table)))
    m = build_model(sc)
    y = m.y0.copy()
    y[pressure_index(0)] = m.g[G_PATM] + 300488.28
    r = frogsim.simulate(sc)
    out[name] = {"type": sc.firmware.transducer.TYPE, "code": float(m.laws[0, L_ADC_CODE]),
                 "count": int(adc_counts(firmware_plan(m), m, y)[0]),
                 "p_end": float(r.muscle_pressure("hip")[-1] - r.atmospheric_pressure)}
print(json.dumps(out))
'''


def _sensor_copy(root, modules: dict):
    """A copy of the package under root/src with ``modules`` ({file name: text}) added to
    circuit/sensors/ (:func:`tests.package_copy.package_copy`). Returns root/src."""
    return package_copy(root, {f"circuit/sensors/{name}": text for name, text in modules.items()})


def test_a_duplicate_sensor_code_is_refused_naming_both_modules(tmp_path):
    src = _sensor_copy(tmp_path, {"rounding.py": SENSOR_MODULE.format(code=1.0)})
    done = _run_copy(src, "-c", "import frogsim", cwd=tmp_path)
    assert done.returncode != 0
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("ImportError: sensor types: "), done.stderr[-2000:]
    assert "CODE 1.0 of frogsim.circuit.sensors.transducer (type 'transducer') is already taken by " \
           "frogsim.circuit.sensors.rounding" in last, last


# --- a sensor type chosen by name in [firmware] -------------------------------------------------------
def _hold(firmware: dict) -> dict:
    import tomllib
    from tests.package_copy import PACKAGE
    d = tomllib.loads((PACKAGE / "scenarios" / "hold-3bar.toml").read_text())
    d["firmware"] = dict(d["firmware"], **firmware)
    return d


def test_a_sensor_type_is_chosen_by_name():
    """``type`` names a sensor's type in its [firmware] table: the shipped names give the settings the
    keys gave without one, and an encoder named as the angle sensor is the joints' encoders
    (angle_encoder)."""
    import frogsim
    from frogsim.scenario.firmware import AngleEncoder, AnglePotentiometer, Transducer
    line = {"low_voltage": "0.5 V", "high_voltage": "4.5 V"}
    named = frogsim.load_scenario(_hold({"transducer": {"type": "transducer", **line},
                                         "angle_sensor": {"type": "potentiometer", **line}})).firmware
    plain = frogsim.load_scenario(_hold({"transducer": line, "angle_sensor": line})).firmware
    assert named == plain
    assert type(named.transducer) is Transducer and type(named.angle_sensor) is AnglePotentiometer
    fw = frogsim.load_scenario(_hold({"angle_sensor": {"type": "encoder", "counts_per_revolution": 1000}})).firmware
    assert fw.angle_encoder == AngleEncoder(counts_per_revolution=1000)
    assert fw == frogsim.load_scenario(_hold({"angle_encoder": {"counts_per_revolution": 1000}})).firmware


@pytest.mark.parametrize("firmware, field, words", [
    ({"transducer": {"type": "thermocouple"}}, "firmware.transducer.type",
     "must be one of the sensor types that read pressure: 'transducer'"),
    ({"transducer": {"type": "potentiometer"}}, "firmware.transducer.type",
     "reads angle; firmware.transducer is a sensor that reads pressure: 'transducer'"),
    ({"angle_sensor": {"type": "transducer"}}, "firmware.angle_sensor.type",
     "reads pressure; firmware.angle_sensor is a sensor that reads angle: 'encoder', 'potentiometer'"),
    ({"angle_sensor": {"type": "encoder"}, "angle_encoder": {}}, "firmware.angle_sensor.type",
     "the joints' encoders are given twice"),
    ({"transducer": {"type": "transducer", "span": "10 bar"}}, "firmware.transducer.span", "unknown"),
])
def test_a_wrong_sensor_type_is_refused_naming_the_field(firmware, field, words):
    import frogsim
    from frogsim.errors import ScenarioError
    with pytest.raises(ScenarioError) as e:
        frogsim.load_scenario(_hold(firmware))
    assert e.value.field == field and words in str(e.value), str(e.value)


def test_the_cli_refuses_a_wrong_sensor_type_in_one_line(tmp_path):
    import subprocess
    import sys
    from frogsim.sweep.spec import dumps_toml
    (tmp_path / "s.toml").write_text(dumps_toml(_hold({"transducer": {"type": "potentiometer"}})))
    done = subprocess.run([sys.executable, "-m", "frogsim", "simulate", "s.toml", "--out", "out"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "firmware.transducer.type" in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "out").exists()
