"""The firmware's laws: the ADC's counts against the datasheet, each kind's C twin against its Numba
twin (gcc on this machine, ctypes), the model's compiled sample against the twins, the
[firmware] section's refusals, and a pressure held through the ADC."""
from __future__ import annotations

import ctypes
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, event, given, settings, strategies as st

import frogsim
from frogsim.circuit.layout import pressure_index
from frogsim.components import atmega2560 as chip
from frogsim.control import firmware as fwm
from frogsim.control import fixed
from frogsim.control.kinds import bang_bang, joint_angle, program, pwm, sliding_mode
from frogsim.control.sampled import B_MODE, B_SENSED, CS_BLOCK, sample_controllers, start_controllers
from frogsim.control.signals import CS_SIZE
from frogsim.control.signals import FW_MEM, SN_SIZE, fw_sine
from frogsim.control.table import L_FW, L_MUSCLE
from frogsim.errors import ScenarioError
from frogsim.scenario.load import merged_raw, with_firmware

BAR = 1e5
P_ATM = 101325.0
COUNT = 10 * BAR / 819.2        # [Pa] one count of a 0.5-4.5 V / 0-10 bar transducer at 5 V, 10 bits

@pytest.fixture(scope="session")
def gcc_present():
    """gcc on PATH: a test that needs it fails in CI without it, and is skipped elsewhere."""
    from avr_tools import need_tool
    need_tool("gcc")


needs_gcc = pytest.mark.usefixtures("gcc_present")


def pneumatic(controllers: dict, muscles=("hip",), firmware=None, duration="0.2 s", **extra) -> dict:
    d = {"name": "fw", "duration": duration, "output_interval": "1 ms",
         "muscles": {m: {"type": "hip", "motion": {"kind": "constant"}} for m in muscles},
         "controllers": controllers, "firmware": {} if firmware is None else firmware}
    d.update(extra)
    return d


HOLD = {"hold": {"kind": "bang-bang", "muscle": "hip", "setpoint": "3 bar", "band": "0.1 bar"}}


# --- the ADC: the datasheet's transfer function ----------------------------------------------------------
def test_adc_count_is_the_datasheets_formula():
    # ATmega2560 datasheet Sec. 26.7: ADC = V_IN 1024 / V_REF (truncated); 5 V reference
    assert chip.adc_count(0.5, 5.0) == 102          # 102.4
    assert chip.adc_count(4.5, 5.0) == 921          # 921.6
    assert chip.adc_count(2.5, 5.0) == 512
    assert chip.adc_count(5.0, 5.0) == 1023         # clipped: the largest result
    assert chip.adc_count(-0.2, 5.0) == 0
    assert chip.adc_count(1.0, 3.3) == 310          # 310.3
    assert chip.adc_count(4.5, 5.0, bits=8) == 230  # ADCH of the left-adjusted result: 921 >> 2


def test_the_models_counts_are_the_transducers_volts_through_the_datasheet_formula():
    m = frogsim.build_model(frogsim.load_scenario(pneumatic(HOLD)))
    plan = fwm.firmware_plan(m)
    y = m.y0.copy()
    # 0.5 V at 0 bar, 4.5 V at 10 bar: 3 bar is 1.7 V, 348.16 -> 348; 10 bar 921; 12 bar 5.3 V -> 1023
    for gauge, count in ((0.0, 102), (3 * BAR, 348), (10 * BAR, 921), (12 * BAR, 1023), (-0.9 * BAR, 28)):
        y[pressure_index(0)] = P_ATM + gauge
        assert fwm.adc_counts(plan, m, y, None)[0] == count
    ch = plan.channels[0]
    assert ch.unit_per_count == pytest.approx(COUNT)
    assert ch.offset + 348 * ch.unit_per_count == pytest.approx((348.5 * 5 / 1024 - 0.5) / 0.4 * BAR)


# --- C twin == Numba twin, kind by kind (random parameters, tables, memory, counts, samples) ------------
@pytest.fixture(scope="module")
def lib():
    from avr_tools import need_tool
    need_tool("gcc")
    plan = fwm.firmware_plan(frogsim.build_model(frogsim.load_scenario(pneumatic(HOLD))))
    return fwm.host_library(plan)


@pytest.fixture(scope="module")
def probe(lib):
    """The laws compiled with FS_CHECK_FAST: the joint-angle law returns 2 where it leaves its fast
    path (so a test sees which path the C takes on this machine)."""
    plan = fwm.firmware_plan(frogsim.build_model(frogsim.load_scenario(pneumatic(HOLD))))
    return fwm.host_library("#define FS_CHECK_FAST 1\n" + plan.c_source)


def _path(probe, P, T, mem, k, cp, ca) -> bool:
    """True where the C twin takes the joint-angle law's fast path."""
    P32 = (ctypes.c_int32 * len(P))(*[int(v) for v in P])
    T32 = (ctypes.c_int32 * len(T))(*[int(v) for v in T])
    M32 = (ctypes.c_int32 * FW_MEM)(*[int(v) for v in mem])
    return probe.fs_joint_angle(k, cp, ca, M32, P32, T32) != 2


def _both(lib, module, P, T, mem, k, cp, ca):
    """(mode, memory after) of the C twin and of the Numba twin."""
    P32 = (ctypes.c_int32 * len(P))(*[int(v) for v in P])
    T32 = (ctypes.c_int32 * len(T))(*[int(v) for v in T])
    M32 = (ctypes.c_int32 * FW_MEM)(*[int(v) for v in mem])
    c_mode = getattr(lib, module.C_NAME)(k, cp, ca, M32, P32, T32)
    mem_f = np.array(mem, float)
    n_mode = module.fw_law(np.array(P, float), np.array(T, float), mem_f, k, cp, ca)
    return (int(c_mode), list(M32)), (int(n_mode), [int(v) for v in mem_f])


KS = st.integers(0, 2**31)
COUNTS = st.integers(0, 1023)
Q4S = st.integers(0, 16 * 1023 + 8)
SETTINGS = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _sine_or_table(data):
    """A sine block (random, its mean within the sensor's range) or NO_SINE, half each."""
    if data.draw(st.booleans(), label="sine"):
        block = list(data.draw(SINE_BLOCKS, label="block"))
        block[3] = data.draw(Q4S, label="mean")
        return block
    return fixed.NO_SINE


@needs_gcc
@SETTINGS
@given(P_half=st.integers(0, 4000), T=st.lists(Q4S, min_size=1, max_size=30), k=KS, cp=COUNTS, data=st.data())
def test_bang_bang_twins_agree(lib, P_half, T, k, cp, data):
    P = [P_half, len(T)] + _sine_or_table(data)
    c, n = _both(lib, bang_bang, P, T, [0] * FW_MEM, k % 64 if P[2] < 0 else k, cp, 0)
    assert c == n


@needs_gcc
@SETTINGS
@given(starts=st.lists(st.integers(0, 2**29 - 1), max_size=40, unique=True), data=st.data(), k=st.integers(0, 2**29))
def test_program_twins_agree(lib, starts, data, k):
    starts = sorted(starts)
    modes = data.draw(st.lists(st.sampled_from((-1, 0, 1)), min_size=len(starts), max_size=len(starts)))
    T = [(s << 2) | (m + 1) for s, m in zip(starts, modes)] or [0]
    c, n = _both(lib, program, [len(starts)], T, [0] * FW_MEM, k, 0, 0)
    assert c == n
    expect = 0
    for s, m in zip(starts, modes):
        if s <= k:
            expect = m
    assert n[0] == expect                     # the table's meaning: the last change at or before k


@needs_gcc
@SETTINGS
@given(data=st.data(), k=st.integers(0, 5000), cp=COUNTS, how=st.sampled_from((0, 1, 2)))
def test_pwm_twins_agree(lib, data, k, cp, how):
    N = data.draw(st.integers(1, 2000))
    pb = data.draw(st.integers(1, min(40000, (2**31 - 1) // (2 * N + 1))))
    nmin = data.draw(st.integers(0, N))
    T = data.draw(st.lists(st.integers(0, N) if how == 2 else Q4S, min_size=1, max_size=20))
    P = [N, how, data.draw(st.integers(0, N)), pb, nmin, data.draw(st.integers(0, 1)), len(T)]
    P += _sine_or_table(data) if how == 0 else fixed.NO_SINE
    mem = [data.draw(st.integers(0, N - 1)), data.draw(st.integers(-N, N))] + [0] * (FW_MEM - 2)
    c, n = _both(lib, pwm, P, T, mem, k, cp, 0)
    assert c == n


@needs_gcc
@SETTINGS
@given(data=st.data(), k=st.integers(0, 100), cp=COUNTS, last=st.sampled_from((-1, 0, 1)), seed=st.integers(0, 2**31))
def test_sliding_mode_twins_agree(lib, data, k, cp, last, seed):
    n = data.draw(st.integers(1, 8))
    rng = np.random.default_rng(seed)
    rates = rng.integers(-2**24, 2**24, 2 * 1024)
    sp = data.draw(st.lists(Q4S, min_size=n, max_size=n))
    dsp = data.draw(st.lists(st.integers(-2**24, 2**24), min_size=n, max_size=n))
    rho = data.draw(st.integers(0, sliding_mode.S_MAX))
    sine = _sine_or_table(data)
    if sine[0] >= 0:        # a generated setpoint: no setpoint tables, and its rate below 2^16
        sine[6] = data.draw(st.integers(0, 2**16 - 1))
        n, sp, dsp = 0, [], []
    P = [data.draw(st.integers(0, 2**20)), data.draw(st.integers(0, 2**20)), rho * rho, n, 1024] + sine
    c, nb = _both(lib, sliding_mode, P, sp + dsp + list(rates), [last] + [0] * (FW_MEM - 1), k, cp, 0)
    assert c == nb


# the joint-angle law: the C twin's fast path (16-bit products) and its int64 fallback, against the
# Numba twin's int64 sums; each case drawn around the fast path's edges (joint_angle.c_source)
EDGES16 = (-2**15 - 1, -2**15, -2**15 + 1, -1, 0, 1, 2**15 - 2, 2**15 - 1, 2**15)
DIFFS = st.one_of(st.integers(-2**15 - 4, 2**15 + 4), st.sampled_from(EDGES16), st.integers(-2**24, 2**24))
GAINS = st.one_of(st.integers(0, 2**31 - 1), st.integers(-2**31 + 1, 2**31 - 1),
                  st.sampled_from((0, 1, 0xFFFF, 0x10000, 0x10001, 2**29 - 1, 2**29, -2**29, -2**29 - 1, 2**30,
                                   2**31 - 1, -2**31 + 1)))
INTEGRALS = st.one_of(st.integers(-2**30, 2**30), st.sampled_from((-2**30, -2**30 + 7, -65537, -65536, -1, 0, 65535,
                                                                    65536, 2**30 - 7, 2**30)))
# the sine generator: random blocks (phases, steps, means, amplitudes, in and out of their ranges)
INT32S = st.integers(-2**31 + 1, 2**31 - 1)
SINE_BLOCKS = st.tuples(st.one_of(st.integers(0, 200), st.integers(0, 2**31 - 1)), INT32S, INT32S,
                        st.one_of(Q4S, st.integers(-2**30, 2**30)), st.one_of(st.integers(0, 2**17 - 1), INT32S),
                        st.one_of(st.integers(0, 2**15 - 1), INT32S), st.one_of(st.integers(0, 2**16 - 1), INT32S))
SAMPLES = st.one_of(st.integers(0, 100), st.integers(0, 10**7), st.integers(0, 2**32 - 1))


def _fast(P, e, r) -> bool:
    """Whether the C twin takes its fast path (e, r: the true differences sp - angle, dsp - vf)."""
    return (-2**15 <= e < 2**15 and -2**15 <= r < 2**15 and -2**29 <= P[4] < 2**29 and -2**29 <= P[5] < 2**29
            and 0 <= P[6] < 2**16)


def _joint_case(data, sine: bool):
    """(P, T, mem, k, cp, ca, fast) of a joint-angle case: the angle error e and the rate error r
    aimed at the fast path's edges (through the table's setpoint and rate), or a sine block."""
    ca = data.draw(st.one_of(COUNTS, st.just(65535)), label="ca")
    aq = 16 * ca + 8
    mem = [data.draw(INTEGRALS, label="integral"), data.draw(Q4S, label="last angle"), data.draw(st.integers(0, 1)),
           data.draw(st.integers(0, 2**31 - 2)), data.draw(st.integers(-2**24, 2**24), label="vf")]
    shift = data.draw(st.integers(0, 8))
    dth = aq - mem[1] if mem[2] > 0 else 0
    vf = mem[4] + ((256 * dth - mem[4]) >> shift)
    k = data.draw(SAMPLES if sine else st.integers(0, 100), label="k")
    n = data.draw(st.integers(1, 8))
    kk = min(k, n - 1)
    T = data.draw(st.lists(Q4S, min_size=n, max_size=n)) + data.draw(
        st.lists(st.integers(-2**24, 2**24), min_size=n, max_size=n))
    T[kk] = data.draw(st.one_of(DIFFS.map(lambda e: aq + e), st.sampled_from((-2**31 + 1, 2**31 - 1))), label="sp")
    T[n + kk] = data.draw(st.one_of(DIFFS.map(lambda r: max(-2**31 + 1, min(2**31 - 1, vf + r))),
                                    st.sampled_from((-2**31 + 1, 2**31 - 1))), label="dsp")
    lo = data.draw(st.integers(0, 20000))
    P = [data.draw(st.sampled_from((-1, 1))), data.draw(st.integers(0, 30000)), lo, data.draw(st.integers(lo, 30000)),
         data.draw(GAINS, label="Kp"), data.draw(GAINS, label="Kd"), data.draw(GAINS, label="Ki"),
         data.draw(st.integers(0, 2000)), n, shift]
    P += list(data.draw(SINE_BLOCKS, label="sine")) if sine else fixed.NO_SINE
    # the angle loop's schedule: every N samples from its phase; mem[5] the samples left (0: first)
    every = data.draw(st.one_of(st.integers(1, 8), st.sampled_from((0, -3, 2**31 - 1))), label="N")
    phase = data.draw(st.one_of(st.integers(0, 8), st.sampled_from((-1, 2**31 - 1))), label="phase")
    window = data.draw(st.one_of(st.integers(0, 9), st.sampled_from((-1, 2**31 - 1))), label="W")
    P += [every, phase, window]
    mem += [data.draw(st.one_of(st.integers(0, 9), st.sampled_from((-5, 2**31 - 1))), label="left"),
            data.draw(Q4S, label="held target"), data.draw(INTEGRALS, label="half difference")]
    if sine:
        sp, dsp = fw_sine(np.array(P, float), joint_angle.P_SINE, k)
    else:
        sp, dsp = T[kk], T[n + kk]
    due = (phase if mem[5] <= 0 else mem[5] - 1) <= 0           # the loop runs at this sample
    return P, T, mem, k, data.draw(COUNTS, label="cp"), ca, (not due) or _fast(P, sp - aq, dsp - vf)


@needs_gcc
@settings(SETTINGS, max_examples=1500)
@given(data=st.data())
def test_joint_angle_twins_agree(lib, probe, data):
    P, T, mem, k, cp, ca, fast = _joint_case(data, sine=False)
    event("fast path" if fast else "int64 fallback")
    assert _path(probe, P, T, mem, k, cp, ca) == fast
    c, nb = _both(lib, joint_angle, P, T, mem, k, cp, ca)
    assert c == nb


@needs_gcc
@settings(SETTINGS, max_examples=500)
@given(data=st.data())
def test_joint_angle_twins_agree_on_a_sine(lib, probe, data):
    P, T, mem, k, cp, ca, fast = _joint_case(data, sine=True)
    event("fast path" if fast else "int64 fallback")
    assert _path(probe, P, T, mem, k, cp, ca) == fast
    c, nb = _both(lib, joint_angle, P, T, mem, k, cp, ca)
    assert c == nb


def _edge_cases() -> list:
    """Joint-angle cases at the fast path's limits and just past them: (P, T, mem, ca, fast)."""
    ca = 500
    aq = 16 * ca + 8
    out = []
    for e in EDGES16:
        for r in EDGES16:
            for kp, kd, ki in ((2**29 - 1, 2**29 - 1, 0xFFFF), (-2**29, -2**29, 0), (2**29, 1, 1), (1, -2**29 - 1, 1),
                               (0, 0, 0x10000), (0x10000, 0xFFFF, -1), (0, 0, 0), (2**31 - 1, 2**31 - 1, 2**31 - 1)):
                for integral in (-2**30, 2**30 - 1, 0):
                    mem = [integral, aq, 1, 0, 0, 0, 0, 0]   # vf stays 0: dsp = r; the loop's first run
                    P = [1, 20000, 0, 2**30, kp, kd, ki, 100, 1, 3] + fixed.NO_SINE + [1, 0, 0]
                    out.append((P, [aq + e, r], mem, ca, _fast(P, e, r)))
    return out


@needs_gcc
def test_joint_angle_twins_agree_at_the_fast_paths_edges(lib, probe):
    cases = _edge_cases()
    assert {fast for *_, fast in cases} == {True, False}
    for P, T, mem, ca, fast in cases:
        assert _path(probe, P, T, mem, 0, 300, ca) == fast, (P, T, mem)
        c, nb = _both(lib, joint_angle, P, T, mem, 0, 300, ca)
        assert c == nb, (P, T, mem, fast)


def test_the_fast_paths_sums_stay_in_int32_at_its_extremes():
    # the bounds joint_angle.c_source proves, checked at the corners (Python integers, no overflow)
    worst_H, worst_L = 0, 0
    for g in (2**29 - 1, -2**29):
        a, b = g >> 16, g & 0xFFFF
        assert -2**13 <= a < 2**13 and 0 <= b < 2**16
        for x in (-2**15, 2**15 - 1):
            assert g * x == a * x * 2**16 + b * x
            worst_L = max(worst_L, abs(b * x), 0xFFFF + b * x)
            worst_H = max(worst_H, abs(a * x))
    assert worst_L < 2**31
    ih_max = (2**30) >> 16
    H = 2 * worst_H + 2 * 2**15 + 0xFFFF * ih_max + 2**16
    assert H < 2**31
    for i in (-2**30, -1, 0, 2**30):                        # the integral's split
        assert i == (i >> 16) * 2**16 + (i & 0xFFFF) and -2**14 <= i >> 16 <= 2**14


@needs_gcc
@settings(SETTINGS, max_examples=2000)
@given(block=SINE_BLOCKS, k=SAMPLES)
def test_the_sine_generators_twins_agree(lib, block, k):
    S = (ctypes.c_int32 * SN_SIZE)(*block)
    rate = ctypes.c_int32(0)
    lib.fs_sine.argtypes = [ctypes.c_uint32, ctypes.POINTER(ctypes.c_int32), ctypes.POINTER(ctypes.c_int32)]
    lib.fs_sine.restype = ctypes.c_int32
    value = lib.fs_sine(k, S, ctypes.byref(rate))
    assert (value, rate.value) == fw_sine(np.array(block, float), 0, k)


@settings(max_examples=300, deadline=None)
@given(m=st.floats(-2000.0, 18000.0), a=st.floats(0.0, fixed.SINE_AMP_MAX), f=st.floats(0.01, 50.0),
       start=st.sampled_from((0.0, 0.25, 1e-3 / 3, 2.0)) | st.floats(0.0, 3.0),
       rate=st.sampled_from((1000.0, 500.0, 2000.0)))
def test_the_integer_sine_follows_the_float_sine_within_one_q4_count(m, a, f, start, rate):
    # the closed form m + a sin(2 pi f (t - start)) from start, m before, at t_k = k / rate (Q4 counts);
    # the rate a 2 pi f cos(...) in Q4 counts per sample x 256 (the joint-angle law's unit)
    dt = 1.0 / rate
    unit = dt * 256.0
    assume(a * 2 * math.pi * f * unit * 32768 / 32767 < 2**16 - 1)     # else tabulated (the next test)
    block = fixed.sine_params(m, a, f, start, rate, unit)
    assert block is not None
    P = np.array(block, float)
    ks = np.unique(np.concatenate([np.arange(0, 10001, 7), np.arange(max(0, int(start * rate) - 3),
                                                                     int(start * rate) + 4)]))
    worst = 0.0
    for k in ks:
        t = k * dt
        sp, dsp = fw_sine(P, 0, int(k))
        if t < start:
            assert (sp, dsp) == (math.floor(m + 0.5), 0)
            continue
        ph = 2 * math.pi * f * (t - start)
        err = abs(sp - (m + a * math.sin(ph)))
        worst = max(worst, err)
        # the rate: two roundings, the nearest entry (half a step of phase), the entry's rounding,
        # the phase's drift
        R = a * 2 * math.pi * f * unit
        drift = 2 * math.pi * (64.5 + 0.5 * k) / 2**32
        assert abs(dsp - R * math.cos(ph)) <= 1.0 + R * (math.pi / 1024 + 2**-15 + drift)
        assert err <= 0.625 + 2**-18 + 1.16 * a / 32767 + a * drift
    assert worst <= 1.0


def test_the_sine_generator_refuses_what_it_cannot_hold():
    assert fixed.sine_params(8000.0, fixed.SINE_AMP_MAX, 1.0, 0.0, 1000.0, 0.256) is not None
    assert fixed.sine_params(8000.0, fixed.SINE_AMP_MAX + 1, 1.0, 0.0, 1000.0, 0.256) is None
    assert fixed.sine_params(8000.0, 4000.0, 11.0, 0.0, 1000.0, 0.256) is None      # 70,774 > 2^16 - 1
    assert fixed.sine_params(8000.0, 4000.0, 1.0, 0.0, 1000.0, 0.256) is not None


# --- whole plans: frogsim_sample (C) == firmware_modes (Numba) over random runs of counts ----------------
def _kinds_scenario() -> dict:
    sine = {"kind": "sine", "mean": "3 bar", "amplitude": "1 bar", "frequency": "2 Hz"}
    return pneumatic({
        "a": {"kind": "bang-bang", "muscle": "m0", "setpoint": sine, "band": "0.1 bar"},
        "b": {"kind": "pwm", "muscle": "m1", "setpoint": "2 bar", "frequency": "50 Hz", "minimum_pulse": "2 ms"},
        "c": {"kind": "sliding-mode", "muscle": "m2", "setpoint": sine},
        "d": {"kind": "pwm", "muscle": "m3", "duty_schedule": {"kind": "sine", "mean": "50 %", "amplitude": "30 %",
                                                                "frequency": "3 Hz"}},
        "e": {"kind": "pwm", "muscle": "m4", "duty": "30 %", "rest": "hold"},
        "f": {"kind": "program", "muscle": "m5"}},
        muscles=("m0", "m1", "m2", "m3", "m4", "m5"), duration="0.5 s",
        programs={"p": {"steps": [{"at": "0 s", "state": "charge"}, {"at": "0.1003 s", "state": "hold"},
                                  {"at": "0.2 s", "state": "vent"}]}})


def _with_program(d: dict) -> dict:
    d["muscles"]["m5"]["program"] = "p"
    return d


def _run_both(plan, steps: int, seed: int, draw=None):
    """The plan's C (host build) and its twin on the same counts, sample by sample: each draw's
    (``draw(rng)``: the counts of the next sample; by default within 40 of a random centre)
    modes equal. Returns the twin's memory at the end."""
    h = fwm.host_library(plan)
    h.frogsim_reset()
    rng = np.random.default_rng(seed)
    n_ch, n_m = len(plan.channels), len(plan.muscles)
    mem = fwm.firmware_memory(plan)
    modes = (ctypes.c_int8 * n_m)()
    adc = (ctypes.c_uint16 * max(1, n_ch))()
    centre = rng.integers(0, 1024, n_ch)
    if draw is None:
        def draw(rng):
            return np.clip(centre + rng.integers(-40, 41, n_ch), 0, 1023)
    for k in range(steps):
        counts = draw(rng)
        for j in range(n_ch):
            adc[j] = int(counts[j])
        h.frogsim_sample(k, adc, modes)
        want = fwm.firmware_modes(plan, k, counts, mem)
        assert list(modes) == list(want), f"sample {k}"
    return mem


@needs_gcc
@pytest.mark.parametrize("seed", [1, 2])
def test_every_kind_in_one_firmware_c_equals_the_numba_twin_sample_by_sample(seed):
    sc = frogsim.load_scenario(_with_program(_kinds_scenario()))
    plan = fwm.firmware_plan(frogsim.build_model(sc))
    assert [law.module for law in plan.laws] == [bang_bang, pwm, sliding_mode, pwm, pwm, program]
    _run_both(plan, 600, seed)


@needs_gcc
def test_the_robots_joint_angle_and_gait_firmware_agree_with_the_twin():
    rs = frogsim.load_robot_scenario(with_firmware("hip-angle-in-air"))
    plan = fwm.firmware_plan(rs)
    assert [ch.signal for ch in plan.channels] == ["hip_left pressure", "hip_left_recovery pressure",
                                                   "hip_left angle"]
    _run_both(plan, 400, 3)
    swim = fwm.firmware_plan(frogsim.load_robot_scenario("swim"))
    assert swim.channels == [] and {law.module for law in swim.laws} == {program}
    _run_both(swim, 2200, 4)         # past the gait's first switch at 1 s


def test_the_gait_table_switches_where_the_models_schedule_does():
    rs = frogsim.load_robot_scenario("swim")
    m = frogsim.build_model(rs.pneumatic)
    plan = fwm.firmware_plan(m)
    mem = fwm.firmware_memory(plan)
    rate = rs.pneumatic.controller.rate
    dead = rs.pneumatic.valves.charge.dead_time
    assert rs.pneumatic.valves.discharge.dead_time == dead     # (else the valves' times differ)
    checked = 0
    for t_s, u in zip(m.sched_t, m.sched_u):
        k = round((t_s - dead) * rate)        # the sample whose command switches the valves at t_s
        modes = fwm.firmware_modes(plan, k, [], mem)
        for i in range(len(plan.muscles)):
            assert modes[i] == (1 if u[2 * i] == 1.0 else -1 if u[2 * i + 1] == 1.0 else 0)
        checked += 1
    assert checked >= 20                      # every switching of ten gait cycles

# --- the model's compiled sample == the twin on the counts of the same state ----------------------------
def test_the_models_compiled_sample_commands_what_the_twin_commands():
    sc = frogsim.load_scenario(_with_program(_kinds_scenario()))
    m = frogsim.build_model(sc)
    plan = fwm.firmware_plan(m)
    rng = np.random.default_rng(7)
    y = m.y0.copy()
    u = np.zeros(2 * m.n)
    dt = 1.0 / sc.controller.rate
    cs = start_controllers(m.laws, m.mp, 0.0, y, u, dt)
    mem = fwm.firmware_memory(plan)
    rows = {int(m.laws[c, L_MUSCLE]): c for c in range(m.laws.shape[0]) if m.laws[c, L_FW] > 0}
    for k in range(300):
        if k:
            for i in range(m.n):
                y[pressure_index(i)] = P_ATM + rng.uniform(0.0, 6.0) * BAR
            sample_controllers(m.laws, m.mp, k * dt, y, u, cs)
        want = fwm.firmware_modes(plan, k, fwm.adc_counts(plan, m, y, None), mem)
        for i, c in rows.items():
            b = int(CS_SIZE + c * cs[CS_BLOCK])
            assert cs[b + B_MODE] == want[i], f"sample {k}, muscle {m.names[i]}"


# --- a pressure held through the ADC -------------------------------------------------------------------
def test_hold_3bar_holds_three_bar_through_the_adc():
    sc = frogsim.load_scenario("hold-3bar")
    assert sc.firmware is not None
    r = frogsim.simulate(sc)
    t = np.asarray(r.t)
    p = (r.muscle_pressure("hip") - r.atmospheric_pressure)[t >= 0.5]
    # the relay holds the sensed count within sp +- band/2; the count is the pressure to within one
    # count (12.2 mbar: 10 bar / 819.2); no valve opens once it is held (a closed muscle, no leak)
    band = 0.1 * BAR
    assert np.all(np.abs(p - 3 * BAR) <= band / 2 + COUNT)
    metrics = r.control_metrics()["hold"]
    assert metrics["tracking_error_max_bar"] * BAR <= band / 2 + COUNT


def test_the_sensed_pressure_is_a_count_only_with_firmware():
    base = pneumatic(HOLD)
    del base["firmware"]
    for d, quantised in ((base, False), (pneumatic(HOLD), True)):
        m = frogsim.build_model(frogsim.load_scenario(d))
        y = m.y0.copy()
        y[pressure_index(0)] = P_ATM + 2.345678 * BAR
        u = np.zeros(2)
        cs = start_controllers(m.laws, m.mp, 0.0, y, u, 1e-3)
        b = int(CS_SIZE + 0 * cs[CS_BLOCK])
        sensed = cs[b + B_SENSED] - P_ATM
        if quantised:
            # the middle of count floor((0.5 + 0.4 * 2.345678) 1024 / 5) = 294
            assert sensed == pytest.approx(((294.5 * 5 / 1024) - 0.5) / 0.4 * BAR)
        else:
            assert m.laws[0, L_FW] == 0.0
            assert sensed == pytest.approx(2.345678 * BAR, abs=1e-6)


# --- refusals --------------------------------------------------------------------------------------------
def _refused(d: dict, match: str):
    with pytest.raises(ScenarioError, match=match):
        frogsim.load_scenario(d)


@pytest.mark.parametrize("firmware, match", [
    ({"valve_pins": {"hip": [22, 70]}}, r"firmware\.valve_pins\.hip = 70: must be a digital pin of the Mega 2560"),
    ({"busy_pin": 70}, r"firmware\.busy_pin = 70: must be <= 69"),
    ({"valve_pins": {"hip": [13, 23]}}, r"firmware\.valve_pins\.hip = 13: pin 13 is already the busy pin"),
    ({"valve_pins": {"hip": [1, 23]}}, r"firmware\.valve_pins\.hip = 1: pin 1 is already the serial port"),
    ({"valve_pins": {"hip": [22, 22]}}, r"pin 22 is already hip's charge valve pin"),
    ({"valve_pins": {"hip": [54, 23]}}, r"pin 54 is already analog input A0 \(hip pressure\)"),
    ({"pressure_inputs": {"hip": 16}}, r"firmware\.pressure_inputs\.hip = 16: must be an analog input of the "
                                        r"Mega 2560: 0\.\.15 \(A0\.\.A15\)"),
    ({"pressure_inputs": {"knee": 1}}, r"firmware\.pressure_inputs\.knee = 1: must name a muscle whose pressure"),
    ({"valve_pins": {"knee": [30, 31]}}, r"firmware\.valve_pins\.knee .*must name a muscle of this scenario"),
    ({"log_rate": "1 kHz", "baud": 9600}, r"firmware\.log_rate = '?1000 Hz'?: lines of up to \d+ bytes at 1000 Hz "
                                          r"need \d+ bytes/s, more than 9600 baud carries"),
    ({"log_rate": "300 Hz"}, r"firmware\.log_rate = '?300 Hz'?: must divide the controller rate"),
    ({"name": "3bar"}, r"firmware\.name = '3bar': must be a C identifier"),
    ({"vref": "3.3 V"}, r"firmware\.transducer\.high_voltage = '?4\.5 V'?: must not exceed .*vref \(3\.3 V\)"),
    ({"transducer": {"low_voltage": "4.5 V", "high_voltage": "0.5 V"}}, r"high_voltage .* must exceed low_voltage"),
    ({"vref": "6 V"}, r"firmware\.vref = '6 V': must be <= 5\.5 V"),
    ({"pins": 3}, r"firmware\.pins: unknown setting"),
])
def test_bad_firmware_settings_are_refused_in_one_line(firmware, match):
    _refused(pneumatic(HOLD, firmware=firmware), match)


def test_two_signals_on_one_analog_input_are_refused():
    d = pneumatic({"a": {"kind": "bang-bang", "muscle": "m0", "setpoint": "3 bar"},
                   "b": {"kind": "bang-bang", "muscle": "m1", "setpoint": "3 bar"}}, muscles=("m0", "m1"),
                  firmware={"pressure_inputs": {"m0": 3, "m1": 3}})
    _refused(d, r"firmware\.pressure_inputs\.m1 = 3: analog input A3 is already m0 pressure's")


def test_more_analog_signals_than_inputs_are_refused_with_the_count():
    names = [f"m{i}" for i in range(17)]
    d = pneumatic({n: {"kind": "bang-bang", "muscle": n, "setpoint": "1 bar"} for n in names}, muscles=names,
                  firmware={"valve_pins": {n: [2 + 2 * i, 3 + 2 * i] for i, n in enumerate(names[:8])}})
    _refused(d, r"firmware = '17 analog signals \(17 pressures, 0 angles\)': the Mega 2560 has 16 analog inputs "
                r"\(A0-A15\): read the joint angles from quadrature encoders")


def test_sampling_that_does_not_fit_the_period_is_refused_with_the_arithmetic():
    names = [f"m{i}" for i in range(16)]
    d = pneumatic({n: {"kind": "bang-bang", "muscle": n, "setpoint": "1 bar"} for n in names}, muscles=names,
                  controller={"rate": "10 kHz"}, firmware={"log_rate": "10 Hz"})
    # 16 x 13 us (1 MHz ADC clock, the fastest recommended) = 208 us > 60 % of 100 us
    _refused(d, r"controller\.rate = '10000 Hz': the firmware's sampling does not fit: 16 conversions do not fit "
                r"the 100 us control period.*16 x 13\.0 us = 208 us")


def test_a_faster_adc_clock_that_fits_costs_two_bits():
    names = [f"m{i}" for i in range(12)]
    sc = frogsim.load_scenario(pneumatic({n: {"kind": "bang-bang", "muscle": n, "setpoint": "1 bar"}
                                          for n in names}, muscles=names))
    plan = fwm.firmware_plan(frogsim.build_model(sc))
    # 12 x 104 us = 1.25 ms does not fit 60 % of 1 ms; prescaler 32 (500 kHz, 26 us): 8 bits
    assert plan.adc.prescaler == 32 and plan.adc.bits == 8
    assert plan.channels[0].unit_per_count == pytest.approx(4 * COUNT)
    m = frogsim.build_model(sc)
    y = m.y0.copy()
    y[pressure_index(0)] = P_ATM + 10 * BAR        # 4.5 V: 921 at 10 bits, 230 in ADCH
    assert fwm.adc_counts(plan, m, y, None)[0] == 230


def test_sensor_settings_the_firmware_does_not_model_are_refused():
    ctl = dict(HOLD["hold"], sensor={"noise": "5 mbar"})
    _refused(pneumatic({"hold": ctl}), r"controllers\.hold\.sensor .*the transducer and the ADC are the sensor")


def test_a_scenario_without_firmware_has_no_plan():
    d = pneumatic(HOLD)
    del d["firmware"]
    with pytest.raises(ScenarioError, match=r"firmware: the scenario needs a \[firmware\] section"):
        fwm.firmware_plan(frogsim.build_model(frogsim.load_scenario(d)))


def _late_step(at: str) -> dict:
    """A setpoint whose table runs sample by sample up to its last step at ``at``."""
    return {"kind": "steps", "steps": [{"at": "0 s", "value": "2 bar"}, {"at": at, "value": "3 bar"}]}


def test_tables_beyond_the_flash_the_avr_reads_are_refused():
    """Three tables up to their steps at 7.9, 7.8 and 7.7 s at 1 kHz (7901, 7801 and 7701 int32
    entries: each under avr-gcc's 32767-byte object) take 4 x 23403 = 93612 bytes, and the sine
    generator's table that a bang-bang law links 1024 x 2 = 2048 more: 95660, more than the 60 KB
    the AVR's LPM reads."""
    ctl = {m: {"kind": "bang-bang", "muscle": m, "setpoint": _late_step(f"7.{9 - i} s")}
           for i, m in enumerate(("a", "b", "c"))}
    d = pneumatic(ctl, duration="8 s", muscles=("a", "b", "c"))
    with pytest.raises(ScenarioError, match=r"duration = '?8 s'?: the firmware's tables .* take 95660 bytes"):
        fwm.firmware_plan(frogsim.build_model(frogsim.load_scenario(d)))


def test_a_table_beyond_avr_gccs_largest_object_is_refused():
    """One table of 19.9 s at 1 kHz: 19901 x 4 = 79604 bytes, more than the 32767 bytes an array
    may take with avr-gcc (its size_t is 16 bits)."""
    d = pneumatic({"a": {"kind": "bang-bang", "muscle": "hip", "setpoint": _late_step("19.9 s")}}, duration="20 s")
    with pytest.raises(ScenarioError, match=r"duration = '?20 s'?: one of the firmware's tables .* takes 79604 "
                                            r"bytes, more than the 32767"):
        fwm.firmware_plan(frogsim.build_model(frogsim.load_scenario(d)))


def test_a_sine_setpoint_is_generated_on_the_board_not_tabulated():
    # 20 s of a 1 Hz sine took 80,004 bytes of table; generated, the law's table is one entry
    sine = {"kind": "sine", "mean": "3 bar", "amplitude": "1 bar", "frequency": "1 Hz", "start": "0.25 s"}
    d = pneumatic({"a": {"kind": "bang-bang", "muscle": "hip", "setpoint": sine}}, duration="20 s")
    plan = fwm.firmware_plan(frogsim.build_model(frogsim.load_scenario(d)))
    law = plan.laws[0]
    assert law.P[bang_bang.P_SINE] == 250 and law.T.size == 1          # k0: the first sample at 0.25 s
    assert plan.table_bytes == 4 + 2 * 1024


def test_the_firmware_section_is_variable_like_every_setting():
    sc = frogsim.load_scenario("hold-3bar")
    assert "firmware.transducer.high_pressure_gauge" in sc.variable_paths()
    v = sc.replace({"firmware.vref": 3.3, "firmware.transducer.high_voltage": 3.0})
    assert v.firmware.vref == 3.3
    with pytest.raises(ScenarioError, match=r"firmware\.transducer\.high_voltage"):
        sc.replace({"firmware.vref": 3.3})


def test_every_firmware_setting_is_documented():
    from pathlib import Path
    import dataclasses
    from frogsim.scenario.firmware import AngleEncoder, AnglePotentiometer, Firmware, SensorFault, Transducer
    text = (Path(__file__).resolve().parent.parent / "docs" / "control.md").read_text()
    for cls in (Firmware, Transducer, AnglePotentiometer, AngleEncoder, SensorFault):
        for f in dataclasses.fields(cls):
            assert f"`{f.name}`" in text, f"{cls.__name__}.{f.name} is not in docs/control.md"


# --- the robot: the coupled engine samples the firmware's laws too --------------------------------------
def test_the_gait_on_the_board_leaves_the_open_loop_model_as_it_was():
    raw, base = merged_raw("swim")
    assert "firmware" in raw
    without = dict(raw, base_dir=base)
    del without["firmware"]
    a = frogsim.swim(frogsim.load_robot_scenario(dict(raw, base_dir=base), cycles=1))
    b = frogsim.swim(frogsim.load_robot_scenario(without, cycles=1))
    # open-loop muscles keep their valve schedule: the same run, bit for bit
    assert np.array_equal(a.pressures, b.pressures) and np.array_equal(a.joint_angles, b.joint_angles)


def test_the_joint_angle_law_runs_on_the_angle_sensors_counts_in_the_coupled_engine():
    rs = frogsim.load_robot_scenario(with_firmware("hip-angle-in-air"))
    r = frogsim.swim(rs)
    m = r.summary()["control"]["hip"]
    assert m["tracking_error_rms_deg"] < 3.0                  # it tracks the 10 deg -> 30 deg steps
    plan = fwm.firmware_plan(rs)
    angle = plan.channels[2]
    # one count of the 0.5-4.5 V angle sensor over 180 deg at 5 V is 180 deg / 819.2
    assert math.degrees(angle.unit_per_count) == pytest.approx(180 / 819.2)


def test_tables_end_at_their_last_change_and_a_pair_shares_its_setpoint():
    rs = frogsim.load_robot_scenario(with_firmware("hip-angle-in-air"))
    plan = fwm.firmware_plan(rs)
    # steps 10 deg -> 30 deg at 1 s, 1 kHz: the setpoint's table ends at sample 1000 (1001 entries,
    # then its rate, zero, as many), read by both muscles of the pair; the ten muscles that hold
    # their valves shut have no mode change (one empty table, shared); and the sine generator's
    # table (1024 int16), which the joint-angle law links
    assert plan.table_bytes == 4 * 2 * 1001 + 4 + 2 * 1024
    assert plan.c_source.count("FS_TABLE =") == 3          # the two tables and the sine's
    ja = [law for law in plan.laws if law.module is joint_angle]
    assert len(ja) == 2 and ja[0].P[8] == 1001 and ja[0].T[1000] != ja[0].T[999]


@pytest.mark.parametrize("kind, extra", [("bang-bang", {}), ("pwm", {"frequency": "50 Hz"}), ("sliding-mode", {})])
def test_each_pressure_law_on_counts_tracks_as_its_float_law_to_within_a_count(kind, extra):
    # the twin reads the middle of the pressure's count (at most half a count, 6.1 mbar, away) and
    # rounds its setpoint and band to sixteenths of a count: the tracking error moves by less than
    # one count (12.2 mbar)
    sine = {"kind": "sine", "mean": "3 bar", "amplitude": "1 bar", "frequency": "0.5 Hz"}
    rms = []
    for fw in (None, {}):
        d = pneumatic({"c": {"kind": kind, "muscle": "hip", "setpoint": sine, **extra}}, duration="2 s")
        if fw is None:
            del d["firmware"]
        rms.append(frogsim.simulate(frogsim.load_scenario(d)).control_metrics()["c"]["tracking_error_rms_bar"])
    assert abs(rms[1] - rms[0]) * BAR < COUNT


def test_the_robots_compiled_sample_reads_the_joint_angle_through_the_angle_sensors_count():
    from frogsim.control.sampled import observe_joints
    rs = frogsim.load_robot_scenario(with_firmware("hip-angle-in-air"))
    m = frogsim.build_model(rs.pneumatic)
    plan = fwm.firmware_plan(m)
    joints = list(rs.pneumatic.joints)
    rng = np.random.default_rng(11)
    y = m.y0.copy()
    u = np.zeros(2 * m.n)
    dt = 1.0 / rs.pneumatic.controller.rate
    qpos = np.zeros(len(joints))
    qvel = np.zeros(len(joints))
    index = np.arange(len(joints), dtype=np.int64)       # joint j's angle at qpos[j] (as the engine maps it)
    cs = start_controllers(m.laws, m.mp, 0.0, y, u, dt)
    mem = fwm.firmware_memory(plan)
    rows = {int(m.laws[c, L_MUSCLE]): c for c in range(m.laws.shape[0]) if m.laws[c, L_FW] > 0}
    assert sorted(m.names[i] for i in rows) == ["hip_left", "hip_left_recovery"]
    theta = 0.0
    seen = set()
    for k in range(400):
        if k:
            theta = float(np.clip(theta + rng.normal(0.0, 0.01), -0.6, 0.6))     # a wandering hip [rad]
            qpos[joints.index("hip_left")] = theta
            for i in rows:
                y[pressure_index(i)] = P_ATM + rng.uniform(1.0, 5.0) * BAR
            observe_joints(m.laws, cs, qpos, qvel, index, index)               # what the engine does
            sample_controllers(m.laws, m.mp, k * dt, y, u, cs)
        counts = fwm.adc_counts(plan, m, y, {"hip_left": theta})
        want = fwm.firmware_modes(plan, k, counts, mem)
        seen.update((int(want[i]), int(counts[2])) for i in rows)
        for i, c in rows.items():
            b = int(CS_SIZE + c * cs[CS_BLOCK])
            assert cs[b + B_MODE] == want[i], f"sample {k}, muscle {m.names[i]}"
    assert {mode for mode, _ in seen} == {-1, 0, 1} and len({a for _, a in seen}) > 20     # not vacuous


def test_ten_seconds_of_sine_joint_setpoints_fit_the_boards_flash():
    # the swimming robot with its recovery muscles and five joints under joint-angle control with
    # 0.5 Hz sines (five: fifteen analog inputs; a sixth needs the angle from elsewhere than the
    # ADC), 10 s: tabulated, each joint's setpoint and rate took 2 x 10,001 int32 (80 KB; 400 KB
    # for five, past the 60 KB allowed); generated, a joint-angle law's table is one entry
    from frogsim.robot.params import JOINTS, SIDES
    raw, base = merged_raw("swim")
    raw = {**raw, "base_dir": base, "firmware": {}, "robot": {**raw["robot"], "recovery": "muscle"},
           "gait": {**raw["gait"], "period": "2 s", "cycles": 5}}
    rs0 = frogsim.load_robot_scenario({k: v for k, v in raw.items() if k != "firmware"})
    joints = [f"{j}_{side}" for side in SIDES for j in JOINTS][:5]
    ctls = {}
    for name in joints:
        rng = math.degrees(rs0.robot.joints[name.rsplit("_", 1)[0]].range)
        ctls[name] = {"kind": "joint-angle", "joint": name, "proportional_gain": "30 bar/rad",
                      "derivative_gain": "1 bar*s/rad", "integral_gain": "30 bar/(rad*s)",
                      "setpoint": {"kind": "sine", "mean": f"{rng / 2:.3f} deg", "amplitude": f"{rng / 4:.3f} deg",
                                   "frequency": "0.5 Hz"}}
    rs = frogsim.load_robot_scenario({**raw, "controllers": ctls})
    assert rs.duration == pytest.approx(10.0)
    plan = fwm.firmware_plan(rs)
    laws = [law for law in plan.laws if law.module is joint_angle]
    assert len(laws) == 10 and all(law.P[joint_angle.P_SINE] >= 0 and law.T.size == 1 for law in laws)
    assert 2 * 10001 * 4 * 5 > fixed.TABLE_BYTES_MAX
    assert plan.table_bytes < 4 * 1024         # the gait's programs, the one-entry tables, the sine table
    shorter = fwm.firmware_plan(frogsim.load_robot_scenario({**raw, "controllers": ctls,
                                                             "gait": {**raw["gait"], "period": "2 s", "cycles": 1}}))
    # the same laws for 2 s: the generator's parameters do not depend on the run's length
    assert [law.P for law in shorter.laws if law.module is joint_angle] == [law.P for law in laws]


@needs_gcc
@pytest.mark.parametrize("seed", [5, 6])
def test_swim_boards_staggered_and_shared_loops_in_c_equal_the_twin(seed):
    """swim-board's firmware: six joints' angle loops every 4 samples, staggered, each joint's
    second law taking the first's run (fs_joint_angle_follow) while their memories agree, against
    the twin (each law its own memory, firmware_modes) sample by sample. The pressures and angles
    wander; now and then a pressure channel reads a count outside its fault limits for a few
    samples, which stops that law (not its pair's), so the pair's memories part and each law runs
    its own loop from then on: both paths are checked."""
    plan = fwm.firmware_plan(frogsim.load_robot_scenario("swim-board", cycles=1))
    names = fwm._table_names(plan.laws)
    assert len(fwm._joint_pairs(plan.laws, names)) == 6
    assert {int(law.P[joint_angle.P_EVERY]) for law in plan.laws} == {4}
    n_ch = len(plan.channels)
    enc = [i for i, ch in enumerate(plan.channels) if ch.pins]
    analog = [i for i in range(n_ch) if i not in enc]
    state = {"counts": np.array([32768 if ch.pins else 120 for ch in plan.channels], np.int64),
             "dead": np.zeros(n_ch, np.int64)}

    def draw(rng):
        counts = state["counts"] + rng.integers(-3, 4, n_ch)
        counts[enc] = np.clip(counts[enc], 32768 - 300, 32768 + 600)
        counts[analog] = np.clip(counts[analog], 20, 235)
        state["counts"] = counts
        dead = state["dead"]
        if rng.random() < 0.01:
            dead[rng.choice(analog)] = rng.integers(1, 15)
        read = counts.copy()
        read[dead > 0] = 2                       # below every pressure channel's fault limit
        state["dead"] = np.maximum(dead - 1, 0)
        return read
    mem = _run_both(plan, 3000, seed, draw)
    lead = [j for j in fwm._joint_pairs(plan.laws, names).values()]
    follow = list(fwm._joint_pairs(plan.laws, names))
    parted = sum(1 for j, f in zip(lead, follow) if not np.array_equal(np.delete(mem[j, :8], 6), np.delete(mem[f, :8], 6)))
    assert parted > 0                            # some pair's memories parted: the unshared path ran too


def test_the_pages_largest_sine_error_over_300_random_sines():
    """docs/control.md: "the largest error seen over 300 random sines of 10 s at 1 kHz is X" (Q4
    counts, against the closed form), recomputed: 300 sines drawn with seed 0 from the ranges the
    generator holds (mean -2000..18000, amplitude 0..8191 Q4 counts, 0.01..50 Hz with a rate the
    generator can hold, start 0..3 s), every sample of 10 s at 1 kHz."""
    import re
    from pathlib import Path
    page = " ".join((Path(__file__).resolve().parents[1] / "docs" / "control.md").read_text().split())
    written = re.search(r"the largest error seen over 300 random sines of 10 s at 1 kHz is (\d+\.\d+)", page)
    assert written, "docs/control.md no longer gives the sines' largest error"
    rng = np.random.default_rng(0)
    rate, n, worst, drawn = 1000.0, 10001, 0.0, 0
    unit = 256.0 / rate
    k = np.arange(n)
    while drawn < 300:
        m, a = rng.uniform(-2000.0, 18000.0), rng.uniform(0.0, fixed.SINE_AMP_MAX)
        f, start = rng.uniform(0.01, 50.0), rng.uniform(0.0, 3.0)
        block = fixed.sine_params(m, a, f, start, rate, unit)
        if block is None:                      # a rate the generator cannot hold: tabulated instead
            continue
        drawn += 1
        P = np.array(block, float)
        sp = np.array([fw_sine(P, 0, int(i))[0] for i in k], float)
        t = k / rate
        on = t >= start
        worst = max(worst, float(np.abs(sp[on] - (m + a * np.sin(2 * np.pi * f * (t[on] - start)))).max()))
    assert f"{worst:.2f}" == written.group(1), worst
