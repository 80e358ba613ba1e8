"""The ``[firmware]`` section: how the scenario's valve controllers sit on the robot's board (an
Arduino Mega 2560, :mod:`frogsim.components.atmega2560`): valve pins, analog inputs, the sensors'
transfer functions, the serial log.

With a ``[firmware]`` section the model's sensed controllers read their muscles' pressures (and a
joint-angle controller its joint's angle) as the board does: through the transducer's voltage and
the ATmega2560's ADC count (datasheet: ADC = V_IN 1024 / V_REF, truncated, 0..1023), and their
laws run in integer arithmetic (:mod:`frogsim.control.firmware`). Without the section nothing
changes. Every setting has a default, so ``[firmware]`` alone works::

    [firmware]
    name = "hold_3bar"                  # the sketch's name, a C identifier (default: the scenario's)
    vref = "5 V"                        # the ADC's reference (AVcc)
    transducer = { type = "transducer", low_voltage = "0.5 V", high_voltage = "4.5 V",
                   low_pressure_gauge = "0 bar", high_pressure_gauge = "10 bar" }
    angle_sensor = { type = "potentiometer", low_voltage = "0.5 V", high_voltage = "4.5 V",
                     low_angle = "-90 deg", high_angle = "90 deg" }
    valve_pins = { hip = [22, 23] }     # muscle -> [charge, discharge]; others from D22 up
    pressure_inputs = { hip = 0 }       # muscle -> analog input (0 = A0); others from A0 up
    angle_inputs = { hip_left = 4 }     # joint -> analog input; others after the pressures
    angle_encoder = { counts_per_revolution = 2000 }   # joint angles from quadrature encoders
                                        # (the same as angle_sensor = { type = "encoder", ... })
    encoder_pins = { hip_left = [2, 46] }   # joint -> [A (an external-interrupt pin), B]
    busy_pin = 13                       # high while the controller's interrupt runs
    baud = 115200
    log_rate = "100 Hz"                 # serial log lines per second

Each sensor's table may name its type (a module of :mod:`frogsim.circuit.sensors`; without
``type``: "transducer" for the pressures, "potentiometer" for the angles); a type that reads
another quantity, or a pressure sensor the board would not read on an analog input, is refused.
:func:`firmware_layout` resolves the defaults (pins, channels) and :func:`check_firmware` (one of
the scenario's rules) refuses what the board cannot do, each with a one-line ScenarioError.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import ClassVar, NamedTuple

from frogsim.components import atmega2560 as chip
from frogsim.errors import ScenarioError
from frogsim.scenario.fields import build, choice, integer, quantity, unwrap
from frogsim.scenario.motion import command_sample
from frogsim.scenario.schema import BAR, GAUGE_MAX, GAUGE_MIN, AngleSetpoint
from frogsim.scenario import sensors as sensor_types
from frogsim.scenario.sensors import SensorSettings

FIRST_VALVE_PIN = 22          # the Mega's double header D22..D53: valve pins by default
LAST_VALVE_PIN = 53
OVERRUN_DIGITS = 5            # the log's overrun counter is a uint16 (at most 65535)
#: the largest magnitude [Q4 counts: sixteenths of an ADC count] a pressure or an angle may take in
#: the laws' fixed point (frogsim.control.fixed): int32 on the board, with room for a sum of two
Q4_LIMIT = 2**30
Q4_PER_COUNT = 16
ADC_FULL_MAX = 1024           # 10 bits: the most counts a volt gives
_C_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,31}")


@dataclass(frozen=True)
class Transducer(SensorSettings):
    """A pressure transducer with a voltage output linear in gauge pressure: low_voltage at
    low_pressure_gauge, high_voltage at high_pressure_gauge (outside the range the voltage goes on
    along the line, and the ADC clips it to 0..V_REF). Sensor type "transducer"
    (:mod:`frogsim.circuit.sensors.transducer`)."""
    TYPE: ClassVar[str] = "transducer"
    QUANTITY: ClassVar[str] = "pressure"
    low_voltage: float = quantity("voltage", ge=0.0, le=chip.VREF_MAX, display="V", default=0.5)
    high_voltage: float = quantity("voltage", ge=0.0, le=chip.VREF_MAX, display="V", default=4.5)
    low_pressure_gauge: float = quantity("pressure", ge=GAUGE_MIN, le=GAUGE_MAX, display="bar", default=0.0)
    high_pressure_gauge: float = quantity("pressure", ge=GAUGE_MIN, le=GAUGE_MAX, display="bar", default=10e5)
    fault_margin: float = quantity("voltage", ge=0.0, le=chip.VREF_MAX, display="V", default=0.2,
                                   doc="a reading this far below low_voltage or above high_voltage is a fault")

    def volts(self, p_gauge: float) -> float:
        """The output [V] at gauge pressure p_gauge [Pa]."""
        return self.low_voltage + (self.high_voltage - self.low_voltage) * (
            (p_gauge - self.low_pressure_gauge) / (self.high_pressure_gauge - self.low_pressure_gauge))

    def measured_range(self) -> tuple:
        return self.low_pressure_gauge, self.high_pressure_gauge

    def check(self, path: str, vref: float) -> None:
        """Its line rises, stays within 0..V_REF, and is not so steep over frogsim's gauge pressures
        that the firmware's fixed point overflows (:func:`_check_line`)."""
        _check_line(self, path, vref, "low_pressure_gauge", "high_pressure_gauge", BAR, "bar",
                    GAUGE_MAX - GAUGE_MIN, "gauge pressures")


@dataclass(frozen=True)
class AnglePotentiometer(SensorSettings):
    """An analog angle sensor (a potentiometer on the joint, with its amplifier): low_voltage at
    low_angle, high_voltage at high_angle, linear between. Sensor type "potentiometer"
    (:mod:`frogsim.circuit.sensors.potentiometer`)."""
    TYPE: ClassVar[str] = "potentiometer"
    QUANTITY: ClassVar[str] = "angle"
    low_voltage: float = quantity("voltage", ge=0.0, le=chip.VREF_MAX, display="V", default=0.5)
    high_voltage: float = quantity("voltage", ge=0.0, le=chip.VREF_MAX, display="V", default=4.5)
    low_angle: float = quantity("angle", ge=-math.pi, le=math.pi, display="deg", default=-math.pi / 2)
    high_angle: float = quantity("angle", ge=-math.pi, le=math.pi, display="deg", default=math.pi / 2)
    fault_margin: float = quantity("voltage", ge=0.0, le=chip.VREF_MAX, display="V", default=0.2,
                                   doc="a reading this far below low_voltage or above high_voltage is a fault")

    def volts(self, angle: float) -> float:
        """The output [V] at the joint angle [rad]."""
        return self.low_voltage + (self.high_voltage - self.low_voltage) * (
            (angle - self.low_angle) / (self.high_angle - self.low_angle))

    def measured_range(self) -> tuple:
        return self.low_angle, self.high_angle

    def check(self, path: str, vref: float) -> None:
        """As :meth:`Transducer.check`, over a turn of angles."""
        _check_line(self, path, vref, "low_angle", "high_angle", math.pi / 180, "deg", 2.0 * math.pi, "angles")


@dataclass(frozen=True)
class AngleEncoder(SensorSettings):
    """Incremental quadrature encoders on the joints instead of potentiometers: channel A on one of
    the Mega's external-interrupt pins (INT0..INT5: D21, D20, D19, D18, D2, D3), channel B on any
    digital pin. The firmware counts every edge of A (both directions: "x2" decoding, B giving
    the direction), so a count is half a cycle of A: ``counts_per_revolution`` counts per turn of
    the joint (twice the encoder's lines per revolution, times any gear between joint and
    encoder). The count at the joint's zero angle (the flexed stop, the robot's start pose:
    power the board up with the legs there) is 32768, the middle of the uint16 counter:
    count = floor(angle counts_per_revolution / 2 pi) + 32768. Sensor type "encoder"
    (:mod:`frogsim.circuit.sensors.encoder`)."""
    TYPE: ClassVar[str] = "encoder"
    QUANTITY: ClassVar[str] = "angle"
    CHANNEL: ClassVar[str] = "counter"
    counts_per_revolution: int = integer(ge=16, le=32768, default=2000,
                                         doc="counts per turn of the joint: 2 x the encoder's lines (x2 decoding)")


#: the encoder count at a joint angle of 0 (the middle of the firmware's uint16 counter)
ENCODER_ZERO = 32768


@dataclass(frozen=True)
class SensorFault:
    """A fault put into the plant for a test of the firmware's fault handling: from ``at`` on, the
    named analog signal's wire carries ``voltage`` (0 V: a dead or disconnected transducer)
    instead of the sensor's output, in the model and in SIL alike."""
    signal: str = ""
    at: float = quantity("time", ge=0.0, display="s", default=0.0, doc="when the sensor fails")
    voltage: float = quantity("voltage", ge=0.0, le=chip.VREF_MAX, display="V", default=0.0,
                              doc="what the wire reads from then on")

    @classmethod
    def from_raw(cls, raw, path: str) -> "SensorFault":
        if not isinstance(raw, dict):
            raise ScenarioError(path, raw, 'expected { signal = "hip pressure", at = "1 s", voltage = "0 V" }')
        raw = dict(raw)
        signal = unwrap(raw.pop("signal", ""))
        if not isinstance(signal, str) or not signal:
            raise ScenarioError(f"{path}.signal", signal, 'expected a signal the firmware reads, e.g. "hip pressure"')
        f = build(cls, raw, path)
        return cls(signal=signal, at=f.at, voltage=f.voltage)


FAULT_MODES = ("vent", "hold")


@dataclass(frozen=True)
class Firmware:
    """The ``[firmware]`` section (module docstring). ``valve_pins``, ``pressure_inputs`` and
    ``angle_inputs`` hold what the file wrote; :func:`firmware_layout` adds the defaults."""
    name: str = ""
    vref: float = quantity("voltage", gt=0.0, le=chip.VREF_MAX, display="V", default=5.0,
                           doc="the ADC's reference voltage (AVcc on the Mega 2560)")
    transducer: Transducer = field(default_factory=Transducer)
    angle_sensor: AnglePotentiometer = field(default_factory=AnglePotentiometer)
    angle_encoder: AngleEncoder | None = None
    busy_pin: int = integer(ge=0, le=chip.DIGITAL_PINS - 1, default=13,
                            doc="digital pin high while the controller's interrupt runs")
    baud: int = integer(ge=300, le=2_000_000, default=115200, doc="serial log's baud rate")
    log_rate: float = quantity("frequency", gt=0.0, le=1e6, display="Hz", default=100.0,
                               doc="serial log lines per second (a divisor of controller.rate)")
    velocity_filter: int = integer(ge=1, le=64, default=8,
                                   doc="samples of the joint-angle laws' velocity filter (a power of two)")
    velocity_window: int | None = integer(ge=1, le=64, default=None,
                                          doc="samples the joint-angle laws' velocity difference spans (at most "
                                              "the angle loop's period; default: that period)")
    fault: str = choice(FAULT_MODES, default="vent",
                        doc="what a muscle's valves do while a sensor its law reads is in fault")
    fault_resume: int = integer(ge=0, le=60000, default=10,
                                doc="good samples after a fault before the law runs again")
    sensor_faults: tuple = field(default=(), metadata={"fixed": True})
    # (name, value) pairs as written (tuples: the section hashes by value, as the model's cached
    # parts need); read them as dicts through pins() and inputs()
    valve_pins: tuple = field(default=(), metadata={"fixed": True})
    pressure_inputs: tuple = field(default=(), metadata={"fixed": True})
    angle_inputs: tuple = field(default=(), metadata={"fixed": True})
    encoder_pins: tuple = field(default=(), metadata={"fixed": True})

    def pins(self) -> dict:
        """{muscle: (charge pin, discharge pin)} as written."""
        return dict(self.valve_pins)

    def inputs(self, quantity: str) -> dict:
        """{muscle (pressure) or joint (angle): analog input} as written."""
        return dict(self.pressure_inputs if quantity == "pressure" else self.angle_inputs)

    @classmethod
    def from_raw(cls, raw, path: str = "firmware") -> "Firmware":
        """The section from a file's table, every value checked."""
        if not isinstance(raw, dict):
            raise ScenarioError(path, raw, "expected a table of firmware settings")
        raw = dict(raw)
        tables = {}
        for key, what in (("valve_pins", "pin"), ("pressure_inputs", "input"), ("angle_inputs", "input"),
                          ("encoder_pins", "pin")):
            tables[key] = tuple(_read_table(raw.pop(key, {}), f"{path}.{key}", what).items())
        faults = unwrap(raw.pop("sensor_faults", []))
        if not isinstance(faults, list):
            raise ScenarioError(f"{path}.sensor_faults", faults, "expected a list of "
                                '{ signal = "hip pressure", at = "1 s", voltage = "0 V" }')
        faults = tuple(SensorFault.from_raw(f, f"{path}.sensor_faults[{k}]") for k, f in enumerate(faults))
        name = unwrap(raw.pop("name", ""))
        if not isinstance(name, str):
            raise ScenarioError(f"{path}.name", name, "expected text: the sketch's name, a C identifier")
        given = {key: raw.pop(key) for key in ("transducer", "angle_sensor") if key in raw}
        fw = build(cls, raw, path)
        transducer, angle_sensor, angle_encoder = fw.transducer, fw.angle_sensor, fw.angle_encoder
        if "transducer" in given:
            transducer = sensor_types.from_raw(given["transducer"], f"{path}.transducer", "pressure", "transducer")
            if transducer.CHANNEL != "adc":
                raise ScenarioError(f"{path}.transducer.type", transducer.TYPE,
                                    "the board reads the muscles' pressures on analog inputs: a pressure sensor "
                                    "read through the ADC")
        if "angle_sensor" in given:
            sensor = sensor_types.from_raw(given["angle_sensor"], f"{path}.angle_sensor", "angle", "potentiometer")
            if sensor.CHANNEL == "counter":          # encoders: what angle_encoder says
                if angle_encoder is not None:
                    raise ScenarioError(f"{path}.angle_sensor.type", sensor.TYPE,
                                        f"the joints' encoders are given twice: keep {path}.angle_encoder or "
                                        f"angle_sensor = {{ type = {sensor.TYPE!r}, ... }}, not both")
                angle_encoder = sensor
            else:
                angle_sensor = sensor
        return cls(name=name, vref=fw.vref, transducer=transducer, angle_sensor=angle_sensor,
                   angle_encoder=angle_encoder, velocity_filter=fw.velocity_filter,
                   velocity_window=fw.velocity_window, fault=fw.fault, fault_resume=fw.fault_resume,
                   sensor_faults=faults, busy_pin=fw.busy_pin, baud=fw.baud, log_rate=fw.log_rate, **tables)


def _read_table(raw, path: str, what: str) -> dict:
    """{name: pin pair (valve_pins) or analog input number} as written, checked to be whole numbers."""
    raw = unwrap(raw)
    if not isinstance(raw, dict):
        raise ScenarioError(path, raw, "expected a table of names, e.g. { hip = "
                                       + ("[22, 23] }" if path.endswith("valve_pins") else "0 }"))
    out = {}
    for name, val in raw.items():
        here = f"{path}.{name}"
        val = unwrap(val)
        if path.endswith("valve_pins") or path.endswith("encoder_pins"):
            if (not isinstance(val, (list, tuple)) or len(val) != 2
                    or not all(isinstance(v, int) and not isinstance(v, bool) for v in val)):
                what = "[charge pin, discharge pin]" if path.endswith("valve_pins") else "[A pin, B pin]"
                raise ScenarioError(here, val, f"expected {what}, two whole numbers")
            out[str(name)] = (int(val[0]), int(val[1]))
        else:
            if not isinstance(val, int) or isinstance(val, bool):
                raise ScenarioError(here, val, "expected an analog input number 0..15 (A0..A15)")
            out[str(name)] = int(val)
    return out


class Signal(NamedTuple):
    """One signal the firmware reads: quantity ("pressure" | "angle"), the muscle or joint it
    belongs to, its analog input (0..15 = A0..A15; -1 for an encoder) and an encoder's (A, B)
    pins (empty for an analog signal)."""
    quantity: str
    name: str
    analog_input: int
    pins: tuple = ()

    @property
    def encoder(self) -> bool:
        return bool(self.pins)

    @property
    def label(self) -> str:
        """"hip pressure", "hip_left angle"."""
        return f"{self.name} {self.quantity}"


class Layout(NamedTuple):
    """The board's wiring with the defaults filled in: the sketch's name, every muscle's (charge,
    discharge) pins in the scenario's muscle order, the analog signals (pressures in controller
    order, then angles)."""
    name: str
    valve_pins: dict
    signals: list


def sensed_signals(sc) -> list:
    """[(quantity, name)] the scenario's controllers read, in controller order: each sensed
    controller's muscles' pressures, then (after all pressures) the joint angles."""
    pressures, angles = [], []
    for c in sc.controllers.values():
        for q, n in c.sensed():
            (pressures if q == "pressure" else angles).append((q, n))
    seen = set()
    out = []
    for s in pressures + angles:
        if s not in seen:
            seen.add(s)
            out.append(s)
    return out


def sketch_name(sc) -> str:
    """The firmware's name: ``[firmware] name``, else the scenario's name made a C identifier."""
    if sc.firmware.name:
        return sc.firmware.name
    name = re.sub(r"[^A-Za-z0-9_]", "_", sc.name) or "frogsim"
    if name[0].isdigit():
        name = "fs_" + name
    return name[:32]


def firmware_layout(sc) -> Layout:
    """The pins and analog inputs of scenario ``sc`` (which has a ``[firmware]`` section), with
    the defaults: valve pins from D22 up for every muscle without its own (skipping pins in use),
    analog inputs from A0 up for every signal without its own."""
    fw = sc.firmware
    given_pins = fw.pins()
    used = set(chip.SERIAL_PINS) | {fw.busy_pin} | {p for pair in given_pins.values() for p in pair}
    pins = {}
    free = (p for p in range(FIRST_VALVE_PIN, LAST_VALVE_PIN + 1) if p not in used)
    for m in sc.muscles:
        if m in given_pins:
            pins[m] = given_pins[m]
        else:
            pair = (next(free, None), next(free, None))
            if None in pair:
                raise ScenarioError("firmware.valve_pins", f"{len(sc.muscles)} muscles",
                                    f"the default valve pins D{FIRST_VALVE_PIN}..D{LAST_VALVE_PIN} are used up: "
                                    "give the other muscles' pins in firmware.valve_pins")
            pins[m] = pair
    wanted = sensed_signals(sc)
    encoders = fw.angle_encoder is not None
    given = {(q, n): ch for q in ("pressure", "angle") for n, ch in fw.inputs(q).items()}
    taken = set(given.values())
    nxt = (ch for ch in range(10**6) if ch not in taken)
    enc_given = dict(fw.encoder_pins)
    in_use = used | {p for pair in pins.values() for p in pair} | {p for pair in enc_given.values() for p in pair}
    free_a = (p for p in chip.INTERRUPT_PINS if p not in in_use)
    free_b = (p for p in range(LAST_VALVE_PIN, FIRST_VALVE_PIN - 1, -1) if p not in in_use)
    signals = []
    for q, n in wanted:
        if q == "angle" and encoders:
            pair = enc_given.get(n)
            if pair is None:
                pair = (next(free_a, None), next(free_b, None))
                if None in pair:
                    raise ScenarioError("firmware.encoder_pins", f"{sum(1 for qq, _ in wanted if qq == q)} encoders",
                                        "the Mega 2560 has six external-interrupt pins (D2, D3, D18..D21) for "
                                        "the encoders' A channels and too few free pins for B: give "
                                        "firmware.encoder_pins")
            signals.append(Signal(q, n, -1, tuple(pair)))
        else:
            signals.append(Signal(q, n, given[(q, n)] if (q, n) in given else next(nxt)))
    return Layout(sketch_name(sc), pins, signals)


def log_line_bytes(n_signals: int, n_muscles: int, samples: int, bits: int = 10, n_encoders: int = 0,
                   log_every: int = 1, events: int = 0) -> int:
    """The longest serial log line [bytes]: "k,count_0,...,count_n-1,valvebits,faultbits,overruns,
    dropped,history_0,...,history_m-1\\n" (each history at most 4^log_every - 1; none above 16) with k at most ``samples``, each ADC count at most 2^bits - 1 and each of the
    ``n_encoders`` encoder counts (among the n_signals) at most 65535, valvebits at most
    4^n_muscles - 1, faultbits at most 2^n_signals - 1, the two counters at most 65535. With
    ``events`` (format 4's event slots, no histories) the line ends instead in "events,lost,
    event_1,...": every slot full, each event at most 64 (log_every - 1) + 4 (n_muscles - 1) + 2,
    lost at most 65535."""
    digits = len(str(max(samples, 0)))
    counts = (n_signals - n_encoders) * len(str(2 ** bits - 1)) + n_encoders * 5
    valves = len(str(4 ** n_muscles - 1))
    faults = len(str(2 ** n_signals - 1))
    history = n_muscles * (len(str(4 ** int(log_every) - 1)) + 1) if int(log_every) <= 16 else 0
    if events:
        history = 1 + len(str(int(events))) + 1 + OVERRUN_DIGITS + \
            int(events) * (1 + len(str(64 * (int(log_every) - 1) + 4 * (n_muscles - 1) + 2)))
    return digits + counts + valves + faults + 2 * OVERRUN_DIGITS + (n_signals + 4) + 1 + history


def check_firmware(sc) -> None:
    """The ``[firmware]`` section's refusals (a no-op without one): pins the board lacks or uses
    twice (the serial port's D0/D1, the busy pin, the valve pins, the analog inputs' pins), an
    analog input beyond A15 or used twice, more analog signals than 16, names that are no muscle
    or joint sensed here, sensors the firmware does not model, transfer functions that are not
    increasing or leave 0..V_REF, a log the baud rate cannot carry, conversions that do not fit
    the controller period (:func:`frogsim.components.atmega2560.plan_adc`); a controller rate
    Timer1 cannot make exactly (:func:`_check_rate`), a sensor span so narrow that the laws' fixed
    point would overflow, a setpoint or a hold band outside its sensor's range
    (:func:`_check_setpoints`)."""
    fw = sc.firmware
    if fw is None:
        return
    path = "firmware"
    if fw.name and not _C_NAME.fullmatch(fw.name):
        raise ScenarioError(f"{path}.name", fw.name, "must be a C identifier of at most 32 characters "
                                                     "(letters, digits, _; not starting with a digit)")
    _check_rate(sc.controller.rate)
    _check_transfer(fw, path, {q for q, _ in sensed_signals(sc)})
    for cname, c in sc.controllers.items():
        s = getattr(c, "sensor", None)
        if s is not None and (s.noise > 0.0 or s.lag > 0.0 or s.bits is not None):
            raise ScenarioError(f"controllers.{cname}.sensor", "(noise, lag or bits given)",
                                "with [firmware] the transducer and the ADC are the sensor: leave the sensor "
                                "settings out (the firmware's counts are exact, no noise or lag modelled)")
        a = getattr(c, "angle_sensor", None)
        if a is not None and (a.noise > 0.0 or a.lag > 0.0 or a.bits is not None):
            raise ScenarioError(f"controllers.{cname}.angle_sensor", "(noise, lag or bits given)",
                                "with [firmware] firmware.angle_sensor and the ADC are the angle sensor: "
                                "leave these settings out")
    _check_setpoints(sc, fw)
    wanted = sensed_signals(sc)
    encoders = fw.angle_encoder is not None
    if fw.velocity_filter & (fw.velocity_filter - 1):
        raise ScenarioError(f"{path}.velocity_filter", fw.velocity_filter,
                            "must be a power of two (1, 2, 4, 8, 16, 32 or 64 samples: the filter is a shift)")
    if fw.velocity_window is not None:
        for cname, ctl in sc.controllers.items():
            n = ctl.angle_every(sc.controller.rate) if hasattr(ctl, "angle_every") else None
            if n is not None and fw.velocity_window > n:
                raise ScenarioError(f"{path}.velocity_window", fw.velocity_window,
                                    f"must be at most the angle loop's period of controllers.{cname} ({n} "
                                    f"sample{'s' if n != 1 else ''}: the controller rate over its angle_rate): the "
                                    "difference is taken between two of its runs at the most")
    if fw.encoder_pins and not encoders:
        raise ScenarioError(f"{path}.encoder_pins", dict(fw.encoder_pins),
                            "needs firmware.angle_encoder (the encoders' counts per revolution)")
    if encoders and fw.angle_inputs:
        raise ScenarioError(f"{path}.angle_inputs", dict(fw.angle_inputs),
                            "with firmware.angle_encoder the joint angles come from encoders, not analog inputs: "
                            "give their pins in firmware.encoder_pins")
    joints_read = [n for q, n in wanted if q == "angle"]
    for n, pair in fw.encoder_pins:
        where = f"{path}.encoder_pins.{n}"
        if n not in joints_read:
            raise ScenarioError(where, list(pair), f"must name a joint whose angle a controller reads "
                                                   f"({', '.join(joints_read) or 'none here'})")
        if pair[0] not in chip.EXTERNAL_INTERRUPT:
            raise ScenarioError(where, list(pair), "the A channel must be on an external-interrupt pin: "
                                                   f"{', '.join(map(str, chip.INTERRUPT_PINS))}")
    for key, q, what in (("pressure_inputs", "pressure", "muscle"), ("angle_inputs", "angle", "joint")):
        names = [n for qq, n in wanted if qq == q]
        for n, ch in fw.inputs(q).items():
            if n not in names:
                raise ScenarioError(f"{path}.{key}.{n}", ch,
                                    f"must name a {what} whose {q} a controller reads "
                                    f"({', '.join(names) or 'none here'})")
    for m, pair in fw.pins().items():
        if m not in sc.muscles:
            raise ScenarioError(f"{path}.valve_pins.{m}", list(pair),
                                f"must name a muscle of this scenario ({', '.join(sc.muscles)})")
    n_encoders = sum(1 for q, _ in wanted if q == "angle") if encoders else 0
    n_analog = len(wanted) - n_encoders
    if n_analog > chip.ANALOG_INPUTS:
        n_p = sum(1 for q, _ in wanted if q == "pressure")
        raise ScenarioError(path, f"{n_analog} analog signals ({n_p} pressures, {n_analog - n_p} angles)",
                            f"the Mega 2560 has {chip.ANALOG_INPUTS} analog inputs (A0-A15): read the joint "
                            "angles from quadrature encoders on the interrupt pins instead "
                            "(firmware.angle_encoder = { counts_per_revolution = 2000 }), or control fewer "
                            "joints or muscles")
    for key, q in (("pressure_inputs", "pressure"), ("angle_inputs", "angle")):
        for n, ch in fw.inputs(q).items():
            if not 0 <= ch < chip.ANALOG_INPUTS:
                raise ScenarioError(f"{path}.{key}.{n}", ch, "must be an analog input of the Mega 2560: "
                                                            "0..15 (A0..A15)")
    layout = firmware_layout(sc)
    owner = {}
    for s in layout.signals:
        if s.encoder:
            continue
        where = f"{path}.{s.quantity}_inputs.{s.name}"
        if s.analog_input in owner:
            raise ScenarioError(where, s.analog_input, f"analog input A{s.analog_input} is already "
                                                       f"{owner[s.analog_input]}'s")
        owner[s.analog_input] = s.label
    _check_pins(sc, layout, path)
    labels = {s.label: s for s in layout.signals}
    for k, f in enumerate(fw.sensor_faults):
        where = f"{path}.sensor_faults[{k}].signal"
        if f.signal not in labels:
            raise ScenarioError(where, f.signal, f"must be a signal the firmware reads ({', '.join(labels) or 'none'})")
        if labels[f.signal].encoder:
            raise ScenarioError(where, f.signal, "is an encoder's count: a voltage fault is for analog signals")
        if f.at > sc.duration:
            raise ScenarioError(f"{path}.sensor_faults[{k}].at", f"{f.at:g} s", f"must lie within the run "
                                                                             f"(0..{sc.duration:g} s)")
    rate = sc.controller.rate
    ratio = rate / fw.log_rate
    if fw.log_rate > rate or abs(ratio - round(ratio)) > 1e-9 * ratio:
        raise ScenarioError(f"{path}.log_rate", f"{fw.log_rate:g} Hz",
                            f"must divide the controller rate ({rate:g} Hz): a line every whole number of "
                            "samples")
    samples = command_sample(sc.duration, rate)      # the last sample's index (its digits in a log line)
    # the lines without the valve histories must fit (the firmware leaves the histories out where the
    # baud rate cannot carry them: frogsim.export.sketch.history_samples)
    line = log_line_bytes(len(wanted), len(sc.muscles), samples, n_encoders=n_encoders, log_every=10 ** 9)
    if line * fw.log_rate > fw.baud / 10.0:
        raise ScenarioError(f"{path}.log_rate", f"{fw.log_rate:g} Hz",
                            f"lines of up to {line} bytes at {fw.log_rate:g} Hz need {line * fw.log_rate:.0f} "
                            f"bytes/s, more than {fw.baud} baud carries ({fw.baud / 10:.0f} bytes/s, 10 bits a "
                            f"byte): at most {fw.baud / 10 / line:.4g} Hz, or raise firmware.baud")
    try:
        chip.plan_adc(n_analog, 1.0 / rate)
    except ValueError as exc:
        raise ScenarioError("controller.rate", f"{rate:g} Hz", f"the firmware's sampling does not fit: {exc}") \
            from None


def _check_transfer(fw, path: str, quantities: set) -> None:
    """Each sensor a signal uses passes its type's own checks (its line rises and stays within
    0..V_REF, :meth:`frogsim.scenario.sensors.SensorSettings.check`)."""
    for key, obj, quantity in (("transducer", fw.transducer, "pressure"), ("angle_sensor", fw.angle_sensor, "angle")):
        if quantity in quantities:
            obj.check(f"{path}.{key}", fw.vref)


def _check_line(obj, path: str, vref: float, lo: str, hi: str, unit: float, u: str, width: float,
                what: str) -> None:
    """A linear sensor's settings (low_voltage at ``lo``, high_voltage at ``hi``, ``unit`` its
    display unit ``u`` in SI): the line rises, its high end stays within the ADC's reference, and
    ``width`` (the widest span a value may take, frogsim's ``what``) is not so many Q4 counts that
    the firmware's int32 fixed point overflows."""
    if obj.high_voltage <= obj.low_voltage:
        raise ScenarioError(f"{path}.high_voltage", f"{obj.high_voltage:g} V",
                            f"must exceed low_voltage ({obj.low_voltage:g} V)")
    if obj.high_voltage > vref:
        raise ScenarioError(f"{path}.high_voltage", f"{obj.high_voltage:g} V",
                            f"must not exceed the ADC's reference firmware.vref ({vref:g} V)")
    if getattr(obj, hi) <= getattr(obj, lo):
        raise ScenarioError(f"{path}.{hi}", f"{getattr(obj, hi) / unit:g} {u}",
                            f"must exceed {lo} ({getattr(obj, lo) / unit:g} {u})")
    # Q4 counts per unit (10 bits at most) times the widest range a value may span
    per_volt = Q4_PER_COUNT * ADC_FULL_MAX / vref
    span = getattr(obj, hi) - getattr(obj, lo)
    q4 = per_volt * (obj.high_voltage - obj.low_voltage) / span * width
    if q4 > Q4_LIMIT:
        least = per_volt * (obj.high_voltage - obj.low_voltage) * width / Q4_LIMIT
        raise ScenarioError(
            f"{path}.{hi}", f"{getattr(obj, hi) / unit:g} {u}",
            f"the span {getattr(obj, lo) / unit:g}..{getattr(obj, hi) / unit:g} {u} is so narrow that the "
            f"firmware's fixed point overflows: {width / unit:.3g} {u} (the range of frogsim's {what}) would be "
            f"{q4:.3g} sixteenths of an ADC count, more than the 2^30 its int32 arithmetic holds; the span must "
            f"be at least {least / unit:.3g} {u}")


def _check_rate(rate: float) -> None:
    """The controller rate is one the board's Timer1 makes exactly: 16e6/rate a whole number of
    CPU cycles N (1 + OCR1A) (:func:`frogsim.components.atmega2560.period_cycles`); the message
    names the nearest rates that are."""
    try:
        chip.period_cycles(rate)
    except ValueError as exc:
        near = [chip.rate_text(r) for r in working_rates(rate)]
        near = ", ".join(near[:-1]) + " or " + near[-1] if len(near) > 1 else "".join(near)
        raise ScenarioError("controller.rate", chip.rate_text(rate),
                            f"{exc}; {near} work (the board's Timer1 makes the period from whole CPU "
                            "cycles)") from None


def working_rates(rate: float) -> list:
    """Controller rates [Hz] near ``rate`` that Timer1 makes exactly, written with few digits: the
    nearest below and above with two significant digits and with three (0.01 Hz .. 1 MHz)."""
    from fractions import Fraction
    best = {}
    for k in range(-4, 7):
        for m in range(1, 1000):
            if m % 10 == 0:
                continue                       # the same rate as m / 10 at k + 1
            r = Fraction(m) * Fraction(10) ** k
            if r > 10**6:
                break
            cycles = Fraction(chip.F_CPU) / r
            if cycles.denominator != 1 or chip.timer1_prescaler(cycles.numerator) is None:
                continue
            digits = len(str(m))
            for d in (2, 3):
                if digits <= d:
                    side = "below" if r < rate else "above"
                    if r == rate:
                        continue
                    old = best.get((d, side))
                    if old is None or abs(r - Fraction(rate)) < abs(old - Fraction(rate)):
                        best[(d, side)] = r
    return sorted({float(r) for r in best.values()})


def setpoint_range(sp, duration: float) -> tuple:
    """The lowest and highest value [SI] a setpoint takes over a run of ``duration`` [s], from
    t = 0: a constant's value; the steps in force up to the end (the first step's value holds
    before it); a sine's extremes over the phase it reaches (its mean before its start); a table
    between its rows and at 0 and the end."""
    if sp.kind == "constant":
        return sp.value, sp.value
    if sp.kind == "sine":
        if duration <= sp.start:
            return sp.mean, sp.mean
        phase = 2.0 * math.pi * sp.frequency * (duration - sp.start)
        up = 1.0 if phase >= 0.5 * math.pi else math.sin(phase)
        down = -1.0 if phase >= 1.5 * math.pi else min(0.0, math.sin(phase))
        return sp.mean + sp.amplitude * down, sp.mean + sp.amplitude * up
    pts = list(sp.points())
    if not pts:
        return sp.bounds()
    if sp.kind == "steps":
        vals = [pts[0][1]] + [v for t, v in pts if t <= duration]
    else:
        import numpy as np
        ts, vs = [t for t, _ in pts], [v for _, v in pts]
        vals = [float(np.interp(0.0, ts, vs)), float(np.interp(duration, ts, vs))]
        vals += [v for t, v in pts if 0.0 <= t <= duration]
    return min(vals), max(vals)


def _check_setpoints(sc, fw) -> None:
    """Every sensed controller's setpoint over the run stays within its sensor's range: a pressure
    setpoint and its hold band (setpoint +- band/2) within the transducer's measured range
    (low_pressure_gauge .. high_pressure_gauge), an angle setpoint within the angle sensor's (a
    joint-angle pair's co-contraction pressure and band within the transducer's). Beyond it the
    transducer's line is not the sensor's (its output saturates): the firmware would hold a
    pressure its sensor does not measure."""
    p_lo, p_hi = fw.transducer.measured_range()
    a_lo, a_hi = fw.angle_sensor.measured_range()
    p_range = f"firmware.transducer's {p_lo / BAR:g}..{p_hi / BAR:g} bar gauge"

    def bar(x):
        return f"{x / BAR:g} bar"

    for name, c in sc.controllers.items():
        sp = getattr(c, "setpoint", None)
        if sp is None or not c.sensed():
            continue
        where = f"controllers.{name}"
        lo, hi = setpoint_range(sp, sc.duration)
        ends = ((hi, "" if lo == hi else " (highest value)"), (lo, " (lowest value)"))
        if isinstance(sp, AngleSetpoint):
            for v, end in ends:
                if not a_lo <= v <= a_hi:
                    raise ScenarioError(f"{where}.setpoint", f"{math.degrees(v):g} deg{end}",
                                        f"must lie within the angle sensor's range, firmware.angle_sensor's "
                                        f"{math.degrees(a_lo):g}..{math.degrees(a_hi):g} deg: beyond it the "
                                        "firmware cannot measure the angle it must hold")
            p0 = getattr(c, "co_contraction", None)
            if p0 is None:
                continue
            lo = hi = p0
            what = "co_contraction"
        else:
            for v, end in ends:
                if not p_lo <= v <= p_hi:
                    raise ScenarioError(f"{where}.setpoint", f"{bar(v)}{end}",
                                        f"must lie within the transducer's range, {p_range}: beyond it the "
                                        "firmware cannot measure the pressure it must hold")
            what = "setpoint"
        if what == "co_contraction" and not p_lo <= lo <= p_hi:
            raise ScenarioError(f"{where}.co_contraction", bar(lo),
                                f"must lie within the transducer's range, {p_range}")
        band = getattr(c, "band", None)
        if band is not None and (lo - 0.5 * band < p_lo or hi + 0.5 * band > p_hi):
            raise ScenarioError(f"{where}.band", bar(band),
                                f"the hold band around the {what} ({(lo - 0.5 * band) / BAR:g}.."
                                f"{bar(hi + 0.5 * band)} over the run) must lie within the transducer's range, "
                                f"{p_range}")


def _check_pins(sc, layout: Layout, path: str) -> None:
    fw = sc.firmware
    owner = {p: "the serial port's (USART0, the USB link the log uses)" for p in chip.SERIAL_PINS}
    for s in layout.signals:
        if not s.encoder:
            owner[chip.analog_pin(s.analog_input)] = f"analog input A{s.analog_input} ({s.label})"

    def take(pin, where, what):
        if not 0 <= pin < chip.DIGITAL_PINS:
            raise ScenarioError(where, pin, f"must be a digital pin of the Mega 2560: 2..{chip.DIGITAL_PINS - 1} "
                                            "(0 and 1 are the serial port; 54..69 are A0..A15)")
        if pin in owner:
            raise ScenarioError(where, pin, f"pin {pin} is already {owner[pin]}")
        owner[pin] = what

    take(fw.busy_pin, f"{path}.busy_pin", "the busy pin")
    for m, (pc, pd) in layout.valve_pins.items():
        where = f"{path}.valve_pins.{m}"
        take(pc, where, f"{m}'s charge valve pin")
        take(pd, where, f"{m}'s discharge valve pin")
    for s in layout.signals:
        if s.encoder:
            where = f"{path}.encoder_pins.{s.name}"
            take(s.pins[0], where, f"{s.name}'s encoder A")
            take(s.pins[1], where, f"{s.name}'s encoder B")
