"""Sensor types, one module each, and their registry (docs/architecture.md, "Adding a sensor type").

No list of sensor types is kept by hand: every module of this package is imported here (pkgutil,
in the order of their file names) and a module that declares ``SENSOR = SensorType(...)``
(:mod:`frogsim.circuit.sensors.spec`) is a sensor type; ``spec`` is a helper. A sensor type is
what the firmware reads of the plant: a muscle's pressure or a joint's angle, as the integer the
board sees (an ADC count, an encoder count). What the rest of frogsim reads comes from here: the
type's line and count range (:func:`line`: the firmware rows' L_ADC_* / L_AADC_* columns, the
firmware plan's channels, the SIL's counts), its fault limits (:func:`faults`), its code
(:func:`of`), and the compiled dispatch on a row's sensor code, :func:`sensor_count` (the reading's
integer form) and :func:`sensor_value` (the reading a count stands for), which the model's
firmware sample calls (:func:`frogsim.control.sampled.firmware_mode`).

Checked at import by the shared registry (:mod:`frogsim._registry`), each failure an ImportError
naming the modules: two types with one name or one ``CODE``, a code that is not a finite float
> 0, a declaration without its parts, a settings class without its ``SENSOR`` declaration. A
sensor code no type declares stops a run with an error, never a silent default.
"""
from __future__ import annotations

from frogsim._registry import Registry, dispatch
from frogsim.circuit.sensors.spec import SensorType
from frogsim.scenario import sensors as settings_registry
from frogsim.scenario.sensors import SensorSettings

QUANTITIES = ("pressure", "angle")


def _check(st, module: str) -> None:
    if st.quantity not in QUANTITIES:
        REGISTRY.refuse(f"{module}: sensor type {st.name!r} reads {st.quantity!r}: one of {', '.join(QUANTITIES)}")


REGISTRY = Registry("sensor types", "SENSOR", SensorType, SensorSettings, "TYPE", "type",
                    loader=lambda cls, st: settings_registry.register(cls), check=_check,
                    parts=("line", "faults", "count", "value"))
#: type name -> its declaration, in the order of the modules' file names
TYPES: dict[str, SensorType] = REGISTRY.by_name
#: sensor code -> its type
BY_CODE: dict[float, SensorType] = REGISTRY.by_code


#: the declaration of the sensor type of ``settings`` (a sensor's settings or class)
of = REGISTRY.of


def line(settings, vref: float, adc_full: int) -> tuple:
    """((v0 [V], k [V per unit], q0), full) of the sensor ``settings`` on an ADC of reference
    ``vref`` [V] and ``adc_full`` = 2^bits counts (its type's ``line``)."""
    return of(settings).line(settings, vref, adc_full)


def faults(settings, vref: float, adc_full: int):
    """(lo, hi) counts outside which the sensor's reading is a fault, or None (its type's ``faults``)."""
    return of(settings).faults(settings, vref, adc_full)


_ORDER = REGISTRY.discover_all(__name__, __path__)
_UNKNOWN = "a row's sensor code is no sensor type's (frogsim.circuit.sensors)"
#: ``sensor_count(code, v0, k, q0, full, vref, q) -> int``: the firmware's integer of reading q
sensor_count = dispatch([(s.code, s.count) for s in _ORDER], "v0, k, q0, full, vref, q",
                        unknown="sensor_count: " + _UNKNOWN)
#: ``sensor_value(code, v0, k, q0, full, vref, count) -> q``: the reading in the middle of a count
sensor_value = dispatch([(s.code, s.value) for s in _ORDER], "v0, k, q0, full, vref, c")
