"""The firmware's laws: a scenario's valve controllers as the board runs them (its plan and its C).

A scenario with a ``[firmware]`` section (:mod:`frogsim.scenario.firmware`) runs its sensed
controllers in integer arithmetic on ADC counts (:mod:`frogsim.control.fixed`): each kind's
module holds two twins of its law, ``fw_law`` (Numba, what the model's compiled sample runs) and
``c_source()`` (C99, what the board runs), on the same parameters and tables. This module puts
them together for one scenario:

* :func:`firmware_plan` -> :class:`FirmwarePlan`: the sketch's name, rate, muscles and valve
  pins, analog channels with their scales, the ADC's clock, the serial log's rate and the C
  translation unit ``c_source`` that defines ``frogsim_sample(k, adc, modes)``;
* :func:`adc_counts`: the counts the channels read at a plant state (the same function the
  model's sampling uses, :func:`frogsim.control.signals.adc_count`);
* :func:`firmware_modes`: the model's integer twin of ``frogsim_sample`` (every muscle's mode at
  sample k from the counts and the memory), for checks;
* :func:`host_library`: the C compiled for this machine (gcc, ctypes), for tests.

Muscles without a closed-loop controller run their program (the robot: its gait) from a table
of mode changes (:mod:`frogsim.control.kinds.program`); in the model they keep their schedule of
valve switchings, which changes at the same samples.
"""
from __future__ import annotations

import ctypes
import hashlib
import importlib
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from frogsim._files import user_cache_folder
from frogsim._jit import for_python, jit
from frogsim.circuit.layout import pressure_index
from frogsim.components import atmega2560 as chip
from frogsim.control import fixed, kinds
from frogsim.control.kinds import joint_angle, program
from frogsim.control.sampled import fw_dispatch
from frogsim.control.signals import FW_MEM, SINE_N, adc_count, fw_fault
from frogsim.control.table import (L_FAULT_AHI, L_FAULT_ALO, L_FAULT_PHI, L_FAULT_PLO, L_FW, L_JOINT1, L_KIND,
                                   L_MUSCLE, L_PATM)
from frogsim.errors import FrogsimError, ScenarioError
from frogsim.scenario.firmware import firmware_layout

#: kind code of the table -> the module of the kind with that code and a firmware twin (the registry's)
KIND_MODULES = {k.code: importlib.import_module(k.module) for k in kinds.with_twin() if k.code is not None}
#: every kind's firmware twin, in the order the C defines them (the registry's: program first, then by code)
TWINS = tuple(k.firmware for k in kinds.with_twin())


@dataclass(frozen=True)
class Channel:
    """One signal the firmware reads: an analog input it converts, or a quadrature encoder it
    counts. SI value of a count c: ``offset + c * unit_per_count`` (Pa gauge or rad; the offset
    includes half a count: the value is the middle of the readings that give c)."""
    signal: str             # "hip pressure", "hip_left angle"
    quantity: str           # "pressure" | "angle"
    name: str               # the muscle or the joint
    analog_input: int       # 0..15 (A0..A15); -1 for an encoder
    unit_per_count: float
    offset: float
    pins: tuple = ()        # an encoder's (A, B) digital pins
    start_count: int = 0    # an encoder's count at power-up (the joint at angle 0)
    full: int = 0           # counts span 0..full - 1 (2^bits of the ADC, 65536 for an encoder)

    @property
    def encoder(self) -> bool:
        return bool(self.pins)


@dataclass(frozen=True)
class AdcSettings:
    """The ADC's clock and timing for the plan (:func:`frogsim.components.atmega2560.plan_adc`):
    prescaler (ADPS), result bits (8: the left-adjusted ADCH only), ADC clock cycles of the
    first conversion after enabling and of each following one, and the plan's description."""
    prescaler: int
    bits: int
    first_cycles: int
    cycles: int
    text: str

    def cpu_cycles(self, first: bool = False) -> int:
        """CPU cycles of one conversion."""
        return (self.first_cycles if first else self.cycles) * self.prescaler


@dataclass(frozen=True)
class Law:
    """One muscle's law on the board: the twin's module, its parameters P and table T, the
    indices into the channels of its pressure and angle (-1: none)."""
    module: object
    P: tuple
    T: np.ndarray = field(repr=False)
    pressure: int
    angle: int
    faults: tuple = (-1, 0, -1, 0)    # (lo, hi) of its pressure count, then of its angle count (lo -1: none)

    def __post_init__(self):
        # the Numba twin's arguments, made once (float arrays holding the whole numbers)
        object.__setattr__(self, "_Pf", np.asarray(self.P, float))
        object.__setattr__(self, "_Tf", np.asarray(self.T, float))

    @property
    def kind(self):
        """The declaration of the law's kind (:class:`frogsim.control.kinds.spec.ControllerKind`)."""
        return kinds.of_module(self.module)

    @property
    def twin(self):
        """The kind's firmware twin (:class:`frogsim.control.kinds.spec.FirmwareTwin`)."""
        return self.kind.firmware


@dataclass(frozen=True)
class FirmwarePlan:
    """What the firmware runs (see the module docstring and docs/control.md)."""
    name: str
    rate: float
    period_cycles: int
    muscles: list
    valve_pins: list
    channels: list
    adc: AdcSettings
    busy_pin: int
    baud: int
    log_every: int
    c_source: str = field(repr=False)
    laws: list = field(repr=False)
    table_bytes: int = 0
    fault_mode: int = -1         # a muscle's mode while a channel its law reads is in fault
    fault_resume: int = 10       # good samples before the law runs again
    injected: tuple = ()         # faults put into the plant: (channel index, from t [s], count)

    @property
    def signals(self) -> list:
        return [ch.signal for ch in self.channels]


def _model_of(model):
    """The PneumaticModel behind what was given (a model, a Scenario, a robot scenario)."""
    if hasattr(model, "laws") and hasattr(model, "scenario"):
        return model
    sc = getattr(model, "pneumatic", model)
    from frogsim.circuit.model import build_model
    return build_model(sc)


def firmware_plan(model) -> FirmwarePlan:
    """The firmware plan of a model built from a scenario with a ``[firmware]`` section (a
    :class:`frogsim.circuit.model.PneumaticModel`; a Scenario or a robot scenario is built first).
    ScenarioError when the scenario has no ``[firmware]`` or its tables do not fit the flash."""
    pm = _model_of(model)
    sc = pm.scenario
    fw = sc.firmware
    if fw is None:
        raise ScenarioError("firmware", "(missing)", "the scenario needs a [firmware] section to be exported "
                                                     "(`[firmware]` alone takes the defaults)")
    check_twins(sc)
    layout = firmware_layout(sc)
    rate = sc.controller.rate
    plan_adc = chip.plan_adc(sum(1 for s in layout.signals if not s.encoder), 1.0 / rate)
    full = 2 ** plan_adc.bits
    pline = fixed.pressure_volts(fw)
    aline, afull = fixed.angle_line(sc)
    channels = []
    for s in layout.signals:
        (v0, k, q0), f = (pline, full) if s.quantity == "pressure" else (aline, afull)
        upc = fw.vref / f / k
        start = adc_count(v0, k, q0, float(f), fw.vref, 0.0) if s.encoder else 0
        channels.append(Channel(s.label, s.quantity, s.name, s.analog_input, upc, q0 + (0.5 * fw.vref / f - v0) / k,
                                tuple(s.pins), start, f))
    index = {(ch.quantity, ch.name): j for j, ch in enumerate(channels)}
    rows = {}
    laws = pm.laws
    if laws.ndim == 2:
        for c in range(laws.shape[0]):
            code = float(laws[c, L_KIND])
            if code in RESERVED:
                continue
            if code not in KIND_MODULES:       # check_twins refused every kind without a twin
                raise FrogsimError(f"row {c} of the table of laws has kind code {code:g}, which no controller "
                                   "kind with a firmware twin declares")
            rows[pm.names[int(laws[c, L_MUSCLE])]] = c
    joints = list(sc.joints)
    plan_laws = []
    for i, m in enumerate(pm.names):
        if m in rows:
            c = rows[m]
            row = laws[c]
            if row[L_FW] <= 0.0:
                raise FrogsimError(f"the law of muscle {m!r} has no firmware block (model built without [firmware])")
            P, T = fixed.block(row)
            j = int(row[L_JOINT1]) - 1
            plan_laws.append(Law(KIND_MODULES[row[L_KIND]], tuple(int(v) for v in P), T,
                                 index.get(("pressure", m), -1),
                                 index[("angle", joints[j])] if j >= 0 else -1,
                                 tuple(int(row[x]) for x in (L_FAULT_PLO, L_FAULT_PHI, L_FAULT_ALO, L_FAULT_AHI))))
        else:
            T = program.firmware_table(sc.muscles[m].program, rate)
            plan_laws.append(Law(program, (int(T.size),), T if T.size else np.zeros(1, np.int64), -1, -1))
    biggest = max((4 * law.T.size for law in plan_laws), default=0)
    if biggest > fixed.TABLE_BYTES_ONE:
        raise ScenarioError("duration", f"{sc.duration:g} s",
                            f"one of the firmware's tables (a setpoint or program sample by sample) takes {biggest} "
                            f"bytes, more than the {fixed.TABLE_BYTES_ONE} bytes avr-gcc allows one array: shorten "
                            "the run, lower the controller rate or use constant setpoints")
    n_bytes = table_bytes(plan_laws)
    if n_bytes > fixed.TABLE_BYTES_MAX:
        raise ScenarioError("duration", f"{sc.duration:g} s",
                            f"the firmware's tables (setpoints and programs sample by sample) take {n_bytes} "
                            f"bytes, more than the {fixed.TABLE_BYTES_MAX} bytes of flash the AVR reads them from "
                            "(LPM reaches 64 KB): shorten the run or use constant setpoints")
    name = layout.name
    adc = AdcSettings(plan_adc.prescaler, plan_adc.bits, chip.ADC_CYCLES_FIRST, chip.ADC_CYCLES, plan_adc.describe())
    log_every = int(round(rate / fw.log_rate))
    fault_mode = -1 if fw.fault == "vent" else 0
    labels = [ch.signal for ch in channels]
    injected = tuple((labels.index(f.signal), float(at), int(count)) for f in fw.sensor_faults
                     for at, count in [fixed.injected_fault(sc, f.signal)])
    try:
        period = chip.period_cycles(rate)        # exact: the scenario's rules refused a rate Timer1 cannot make
    except ValueError as exc:
        raise ScenarioError("controller.rate", chip.rate_text(rate), str(exc)) from None
    return FirmwarePlan(name=name, rate=rate, period_cycles=period, muscles=list(pm.names),
                        valve_pins=[layout.valve_pins[m] for m in pm.names], channels=channels, adc=adc,
                        busy_pin=fw.busy_pin, baud=fw.baud, log_every=log_every,
                        c_source=c_source(name, plan_laws, fault_mode, fw.fault_resume), laws=plan_laws,
                        table_bytes=n_bytes, fault_mode=fault_mode, fault_resume=fw.fault_resume,
                        injected=injected)


#: the table's kind codes that are no controller kind's (an empty row, the pump's band, a Python law)
RESERVED = frozenset(kinds.RESERVED_CODES)


def check_twins(sc) -> None:
    """ScenarioError (one line, naming the controller and its kind) when a controller of
    scenario ``sc`` is of a kind without a firmware twin: the board could not run it."""
    for name, ctl in sc.controllers.items():
        kind = kinds.of(ctl)
        if kind.firmware is None:
            have = ", ".join(k.name for k in kinds.with_twin())
            raise ScenarioError(f"controllers.{name}.kind", kind.name,
                                f"controller {name!r} is of kind {kind.name!r}, which has no firmware twin, so "
                                f"the board cannot run it (kinds with one: {have})")


def c_source(name: str, laws: list, fault_mode: int = -1, fault_resume: int = 10) -> str:
    """The firmware's laws as one C99 translation unit: the kinds' C twins, each muscle's
    parameters (RAM), table (flash: FS_TABLE) and memory, ``frogsim_sample``, ``frogsim_reset``
    (memory to zero, as at power-up) and ``frogsim_faults`` (the channels in fault at the last
    sample, bit i channel i).

    Sensor faults: before a law runs, each channel it reads is checked against its fault limits
    (:func:`frogsim.control.signals.fw_fault`, the model's twin): while any is in fault the
    muscle takes ``fault_mode`` (-1 vent, 0 hold) and its law does not run (its memory waits);
    it runs again after ``fault_resume`` good samples."""
    used = TWINS        # every kind's twin (a few hundred bytes each; the tests call them one by one)
    out = [f"/* {name}: the valve controllers' laws, generated by frogsim (frogsim.control.firmware).\n"
           " * Integer arithmetic only (see frogsim.control.fixed); tables in flash through FS_TABLE and\n"
           " * FS_READ32, which the sketch defines (PROGMEM, pgm_read_dword) before including this file. */\n",
           "#include <stdint.h>\n\n",
           "#ifndef FS_TABLE\n#define FS_TABLE\n#endif\n",
           "#ifndef FS_READ16\n#define FS_READ16(p) (*(p))\n#endif\n",
           "#ifndef FS_READ32\n#define FS_READ32(p) (*(p))\n#endif\n",
           "/* channel i's count (the board defines FS_CH to wait for its conversion) */\n"
           "#ifndef FS_CH\n#define FS_CH(i) (adc[i])\n#endif\n\n",
           "void frogsim_sample(uint32_t k, const uint16_t *adc, int8_t *modes);\nvoid frogsim_reset(void);\n"
           "uint32_t frogsim_faults(void);\n",
           "".join(f"int8_t {twin.c_name}(uint32_t k, uint16_t cp, uint16_t ca, int32_t *mem, const int32_t *P, "
                   "const int32_t *T);\n" for twin in TWINS), "\n", fixed.C_COMMON, "\n"]
    out += [twin.c_source() + "\n" for twin in used]
    tables = _table_names(laws)
    for j, law in enumerate(laws):
        out.append(fixed.c_array(f"fs_P{j}", law.P, False))
        if tables[j] == f"fs_T{j}":
            out.append(fixed.c_array(f"fs_T{j}", law.T, True))
        out.append(f"static int32_t fs_M{j}[{FW_MEM}];\n")
        out.append(f"static uint16_t fs_F{j}[2];   /* good samples still needed: pressure, angle */\n")
    out.append(f"\n#define FS_FAULT_MODE ({int(fault_mode)})\n#define FS_FAULT_RESUME {int(fault_resume)}u\n"
               "static uint32_t fs_fault_bits;   /* bit i: channel i in fault at the last sample */\n"
               "uint32_t frogsim_faults(void) { return fs_fault_bits; }\n\n"
               "/* twin of frogsim.control.signals.fw_fault */\n"
               "static inline uint8_t fs_fault(uint16_t c, uint16_t lo, uint16_t hi, uint16_t *left) "
               "__attribute__((unused, always_inline));\n"
               "static inline uint8_t fs_fault(uint16_t c, uint16_t lo, uint16_t hi, uint16_t *left) {\n"
               "    if (c < lo || c > hi) { *left = FS_FAULT_RESUME; return 1; }\n"
               "    if (*left > 0) { (*left)--; return 1; }\n"
               "    return 0;\n}\n")
    out.append("\nvoid frogsim_reset(void) {\n    uint8_t i;\n    fs_fault_bits = 0;\n")
    for j in range(len(laws)):
        out.append(f"    for (i = 0; i < {FW_MEM}; i++) fs_M{j}[i] = 0;\n    fs_F{j}[0] = fs_F{j}[1] = 0;\n")
    out.append("}\n\nvoid frogsim_sample(uint32_t k, const uint16_t *adc, int8_t *modes) {\n"
               "    uint32_t faults = 0;\n    uint8_t bad = 0;\n    uint16_t cp = 0, ca = 0;\n"
               "    (void)adc;\n    (void)bad;\n    (void)cp;\n    (void)ca;\n")
    followers = _joint_pairs(laws, tables)
    leaders = {j: f for f, j in followers.items()}
    for j, law in enumerate(laws):
        if j in leaders:
            f = leaders[j]
            out.append(f"    uint8_t pair{f} = fs_joint_angle_pair(fs_M{j}, fs_M{f}, fs_P{f});   /* one joint's "
                       f"loop, laws {j} and {f} */\n")
        cp = ca = "0"
        if law.pressure >= 0:
            out.append(f"    cp = FS_CH({law.pressure});\n")
            cp = "cp"
        if law.angle >= 0:
            out.append(f"    ca = FS_CH({law.angle});\n")
            ca = "ca"
        plo, phi, alo, ahi = law.faults
        checks = []
        if law.pressure >= 0 and plo >= 0:
            checks.append(f"    if (fs_fault({cp}, {plo}u, {phi}u, &fs_F{j}[0])) {{ bad = 1; faults |= 1UL << {law.pressure}; }}\n")
        if law.angle >= 0 and alo >= 0:
            checks.append(f"    if (fs_fault({ca}, {alo}u, {ahi}u, &fs_F{j}[1])) {{ bad = 1; faults |= 1UL << {law.angle}; }}\n")
        call = f"{law.twin.c_name}(k, {cp}, {ca}, fs_M{j}, fs_P{j}, {tables[j]})"
        if j in followers:
            call = (f"(pair{j} ? fs_joint_angle_follow({cp}, {ca}, fs_M{followers[j]}, fs_M{j}, fs_P{j}) : {call})")
        if checks:
            out.append("    bad = 0;\n" + "".join(checks) + f"    modes[{j}] = bad ? FS_FAULT_MODE : {call};\n")
        else:
            out.append(f"    modes[{j}] = {call};\n")
        if j in leaders:
            out.append(f"    pair{leaders[j]} = pair{leaders[j]} && !bad;   /* the leader ran its law */\n")
    out.append("    fs_fault_bits = faults;\n}\n")
    return "".join(out)


def _joint_pairs(laws: list, tables: list) -> dict:
    """{follower j: leader i < j}: the joint-angle laws that run one joint's loop, the same
    parameters but the sign (extensor +1, flexor -1), one setpoint table and one angle channel.
    The C runs the loop once for both while their memories agree (``fs_joint_angle_follow``: the
    follower's result is the one its own law would give, exactly: the same numbers in, the same
    arithmetic); after a fault that let one law run without the other, each runs its own."""
    out = {}
    taken = set()
    for j, law in enumerate(laws):
        if law.module is not joint_angle or j in taken:
            continue
        for f in range(j + 1, len(laws)):
            other = laws[f]
            if (other.module is joint_angle and f not in taken and f not in out and other.angle == law.angle
                    and tables[f] == tables[j] and len(other.P) == len(law.P)
                    and tuple(other.P[1:]) == tuple(law.P[1:])):
                out[f] = j
                taken.update((j, f))
                break
    return out


def _table_names(laws: list) -> list:
    """The C name of each law's table: fs_T<j>, or the first earlier law's with the same entries
    (a joint's pair reads one setpoint table)."""
    seen = {}
    names = []
    for j, law in enumerate(laws):
        key = np.asarray(law.T, np.int64).tobytes()
        names.append(seen.setdefault(key, f"fs_T{j}"))
    return names


def table_bytes(laws: list) -> int:
    """[B] flash the laws' tables take (int32 entries; shared tables once), and the sine
    generator's table (int16, :data:`frogsim.control.signals.FW_SINE`) when a law that can call it
    is linked."""
    names = _table_names(laws)
    sine = 2 * SINE_N if any(law.twin.sine for law in laws) else 0
    return sine + sum(4 * max(1, law.T.size) for j, law in enumerate(laws) if names[j] == f"fs_T{j}")


def adc_counts(plan: FirmwarePlan, model, y, qpos=None) -> np.ndarray:
    """The counts (uint16, one per channel of the plan) the board's ADC reads at the plant state y
    (gauge pressures of the muscles from y) and the joint angles ``qpos`` [rad] (a dict joint ->
    angle, or the angles in the scenario's joint order; None without a robot): the same
    conversion (:func:`frogsim.control.signals.adc_count`) with the same numbers as the model's
    compiled sample (an encoder's count through its line, :func:`frogsim.control.fixed.angle_line`)."""
    return _counter(plan, model)(y, qpos)


_COUNTERS: dict = {}


def _counter(plan: FirmwarePlan, model):
    """A function (y, qpos) -> counts for the plan's channels, its numbers made once (SIL calls
    it every sample). Each count is :func:`frogsim.control.signals.adc_count`'s arithmetic, in
    the same order of operations: floor((v0 + k (q - q0)) full / vref), clipped."""
    key = (id(plan), id(model))
    hit = _COUNTERS.get(key)
    if hit is not None and hit[0] is plan and hit[1] is model:
        return hit[2]
    pm = _model_of(model)
    sc = pm.scenario
    fw = sc.firmware
    full = float(2 ** plan.adc.bits)
    aline, afull = fixed.angle_line(sc)
    patm = float(pm.laws[0, L_PATM]) if pm.laws.ndim == 2 and pm.laws.shape[0] else None
    if patm is None or patm == 0.0:
        from frogsim.circuit.layout import G_PATM
        patm = float(pm.g[G_PATM])
    pv0, pk, pq0 = fixed.pressure_volts(fw)
    av0, ak, aq0 = aline
    # a type whose count is not the ADC's truncated line (frogsim.circuit.sensors.spec.linear_count)
    # is counted by its own compiled count
    pcount, acount = _own_count(fw.transducer), _own_count(fixed.angle_sensor(fw))
    joints = list(sc.joints)
    p_ch = [j for j, ch in enumerate(plan.channels) if ch.quantity == "pressure"]
    p_idx = np.array([pressure_index(pm.names.index(plan.channels[j].name)) for j in p_ch], np.int64)
    a_ch = [j for j, ch in enumerate(plan.channels) if ch.quantity != "pressure"]
    a_names = [plan.channels[j].name for j in a_ch]
    a_idx = [joints.index(n) if n in joints else -1 for n in a_names]
    vref = float(fw.vref)

    import math
    p_pairs = list(zip(p_ch, p_idx.tolist()))
    a_pairs = list(zip(a_ch, a_names, a_idx))
    top_p, top_a = full - 1.0, float(afull) - 1.0
    afull_f = float(afull)

    def counts(y, qpos=None):
        out = [0] * len(plan.channels)
        for j, i in p_pairs:
            if pcount is not None:
                out[j] = int(pcount(pv0, pk, pq0, full, vref, float(y[i]) - patm))
                continue
            x = math.floor((pv0 + pk * ((float(y[i]) - patm) - pq0)) * full / vref)
            out[j] = int(min(max(x, 0.0), top_p))
        if a_pairs and qpos is None:
            raise FrogsimError(f"channel {plan.channels[a_ch[0]].signal!r}: the joint angles (qpos) are needed")
        for j, n, i in a_pairs:
            th = float(qpos[n] if isinstance(qpos, dict) else qpos[i])
            if acount is not None:
                out[j] = int(acount(av0, ak, aq0, afull_f, vref, th))
                continue
            x = math.floor((av0 + ak * (th - aq0)) * afull_f / vref)
            out[j] = int(min(max(x, 0.0), top_a))
        return np.array(out, np.uint16)
    if len(_COUNTERS) > 32:
        _COUNTERS.clear()
    _COUNTERS[key] = (plan, model, counts)
    return counts


def _own_count(settings):
    """None for a sensor whose count is the ADC's truncated line (:func:`_counter` counts it
    inline), else its type's compiled ``count`` compiled once more for Python callers."""
    from frogsim.circuit import sensors
    from frogsim.circuit.sensors.spec import linear_count
    count = sensors.of(settings).count
    return None if count is linear_count else for_python(count)


def firmware_memory(plan: FirmwarePlan) -> np.ndarray:
    """The memory :func:`firmware_modes` keeps, as at power-up: per law its FW_MEM words and its
    two fault counters (float array (laws, FW_MEM + 2))."""
    return np.zeros((len(plan.laws), FW_MEM + 2))


def firmware_modes(plan: FirmwarePlan, k: int, adc, mem: np.ndarray) -> np.ndarray:
    """The model's integer twin of ``frogsim_sample``: every muscle's mode (int8, -1 vent, 0 hold,
    1 charge) at sample k from the channels' counts ``adc``: each channel the law reads checked
    for a fault (:func:`frogsim.control.signals.fw_fault`), then each law's ``fw_law`` on its
    memory (``mem`` from :func:`firmware_memory`, updated in place as the board's), all in one
    compiled call (:func:`_plan_modes`, the plan's numbers packed once)."""
    packed = _packed(plan)
    out = np.zeros(len(plan.laws), np.int8)
    _plan_modes(*packed, float(plan.fault_mode), float(plan.fault_resume), mem, int(k),
                np.asarray(adc, np.float64).reshape(-1), out)
    return out


_PACKED: dict = {}
#: the kind code of a program law in the packed plan (the others are their modules' CODE)
PROGRAM_CODE = 0.0


def _packed(plan: FirmwarePlan) -> tuple:
    """(codes, P_all, P_off, T_all, T_off, pressure channel, angle channel, fault limits) of the
    plan's laws as flat arrays, made once per plan."""
    hit = _PACKED.get(id(plan))
    if hit is not None and hit[0] is plan:
        return hit[1]
    laws = plan.laws
    codes = np.array([PROGRAM_CODE if law.module is program else law.kind.code for law in laws], np.float64)
    P_off = np.cumsum([0] + [len(law._Pf) for law in laws]).astype(np.int64)
    T_off = np.cumsum([0] + [len(law._Tf) for law in laws]).astype(np.int64)
    P_all = np.concatenate([law._Pf for law in laws]) if laws else np.zeros(0)
    T_all = np.concatenate([law._Tf for law in laws]) if laws else np.zeros(0)
    p_ch = np.array([law.pressure for law in laws], np.int64)
    a_ch = np.array([law.angle for law in laws], np.int64)
    faults = np.array([law.faults for law in laws], np.float64).reshape(len(laws), 4)
    packed = (codes, P_all, P_off, T_all, T_off, p_ch, a_ch, faults)
    if len(_PACKED) > 32:
        _PACKED.clear()
    _PACKED[id(plan)] = (plan, packed)
    return packed


@jit
def _plan_modes(codes, P_all, P_off, T_all, T_off, p_ch, a_ch, faults, fault_mode, resume, mem, k, adc, out):
    """:func:`firmware_modes`' loop, compiled: for each law its channels' fault checks (both
    evaluated), then its program's or its kind's ``fw_law`` (the model's compiled sample's
    dispatch, :func:`frogsim.control.sampled.fw_dispatch`)."""
    for j in range(codes.size):
        cp = int(adc[p_ch[j]]) if p_ch[j] >= 0 else 0
        ca = int(adc[a_ch[j]]) if a_ch[j] >= 0 else 0
        m = mem[j]
        bad = False
        if p_ch[j] >= 0 and faults[j, 0] >= 0.0:
            bad = fw_fault(cp, faults[j, 0], faults[j, 1], m, FW_MEM, resume)
        if a_ch[j] >= 0 and faults[j, 2] >= 0.0:
            if fw_fault(ca, faults[j, 2], faults[j, 3], m, FW_MEM + 1, resume):
                bad = True
        if bad:
            out[j] = int(fault_mode)
            continue
        P = P_all[P_off[j]:P_off[j + 1]]
        T = T_all[T_off[j]:T_off[j + 1]]
        if codes[j] == PROGRAM_CODE:
            out[j] = program.fw_law(P, T, m, k, cp, ca)
        else:
            out[j] = fw_dispatch(codes[j], P, T, m, k, cp, ca)


def host_library(plan_or_source) -> ctypes.CDLL:
    """The plan's C (or C source text) compiled for this machine (``gcc -O2 -std=c99 -shared``),
    cached by the source's hash in frogsim's cache folder, loaded with ctypes; argument types
    set for frogsim_sample, frogsim_reset and the kinds' functions."""
    src = plan_or_source.c_source if isinstance(plan_or_source, FirmwarePlan) else str(plan_or_source)
    digest = hashlib.sha256(src.encode()).hexdigest()[:20]
    folder = user_cache_folder("firmware-host")
    folder = Path(folder) if folder else Path(tempfile.gettempdir()) / "frogsim-firmware-host"
    folder.mkdir(parents=True, exist_ok=True)
    lib = folder / f"laws_{digest}.so"
    if not lib.exists():
        c = folder / f"laws_{digest}.c"
        c.write_text(src)
        tmp = folder / f"laws_{digest}.{np.random.randint(1 << 30)}.tmp.so"
        run = subprocess.run(["gcc", "-O2", "-std=c99", "-Wall", "-Werror", "-shared", "-fPIC", "-o", str(tmp), str(c)],
                             capture_output=True, text=True)
        if run.returncode != 0:
            raise FrogsimError(f"gcc failed on the firmware's laws: {run.stderr.strip()[:2000]}")
        tmp.replace(lib)
    h = ctypes.CDLL(str(lib))
    i32p = ctypes.POINTER(ctypes.c_int32)
    h.frogsim_sample.argtypes = [ctypes.c_uint32, ctypes.POINTER(ctypes.c_uint16), ctypes.POINTER(ctypes.c_int8)]
    h.frogsim_sample.restype = None
    h.frogsim_reset.argtypes = []
    h.frogsim_reset.restype = None
    for twin in TWINS:
        fn = getattr(h, twin.c_name, None)
        if fn is not None:
            fn.argtypes = [ctypes.c_uint32, ctypes.c_uint16, ctypes.c_uint16, i32p, i32p, i32p]
            fn.restype = ctypes.c_int8
    return h
