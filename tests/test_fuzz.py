"""Every bad input is refused by frogsim's own errors, and every accepted one runs physically.

Hypothesis mutates shipped and small scenarios (keys deleted or misspelt, values replaced by text,
numbers, units, NaN, inf, huge or negative numbers, booleans, nested lists and tables) and checks:
the loader and the engine raise nothing but :class:`frogsim.FrogsimError` subclasses, and an
accepted scenario, run for at most 20 ms, gives finite air masses, pressures, volumes and
temperatures that are all positive (an ideal gas in a real chamber: m > 0, p > 0, V > 0, T > 0).
Deterministic (derandomize=True) so CI sees the same 1,000 scenarios on every run.
"""
from __future__ import annotations

import copy
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import frogsim
from frogsim.io.results import run_summary
from conftest import one_muscle_scenario, paper_cycle_dict, steps

_DIR = Path(tempfile.mkdtemp(prefix="frogsim-fuzz-"))
(_DIR / "angles.csv").write_text("time_s,hip\n0,0\n0.005,5\n0.01,10\n0.02,20\n")
(_DIR / "bad.csv").write_text("time_s,hip\n0,0\n0.01,nan\n")

UNIT_TEXTS = ["6 bar", "-0.5 bar", "1e3 bar", "4 L", "-4 L", "0 L", "1e-9 m^3", "1e9 L", "45 L/min",
              "0.4 L/(s*bar)", "1e6 L/(s*bar)", "1 kHz", "0 Hz", "2 ms", "0 s", "1e-9 s", "20 ms",
              "25 deg", "1e-8 deg", "90 deg", "38 %", "38 %%", "120 %", "nan bar", "inf L", "1e999 bar",
              "293.15 K", "-5 K", "287 J/(kg*K)", "343 m/s", "180 mm", "10**10**10 bar", "3 apples",
              "charge", "vent", "hold", "stroke", "constant", "table", "volume_constant", "joint_angles",
              "hip", "knee", "stroke", "paper", "physical", "none", "fan2017", "/dev/zero", "/dev/null",
              ".", "angles.csv", "bad.csv", "missing.csv", "x" * 300, "\x00", "é\u202e"]
NUMBERS = st.one_of(st.integers(-10, 10), st.integers(-2**63, 2**63 - 1), st.just(10**400),
                    st.floats(allow_nan=True, allow_infinity=True),
                    st.sampled_from([0.0, -1.0, 1e-300, 1e300, float("nan"), float("inf"), -float("inf")]))
LEAVES = st.one_of(st.sampled_from(UNIT_TEXTS), st.text(max_size=12), NUMBERS, st.booleans())


def _nested(depth: int):
    v: object = 1
    for _ in range(depth):
        v = [v]
    return v


VALUES = st.one_of(
    LEAVES,
    st.recursive(LEAVES, lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=6), c, max_size=3),
                 max_leaves=6),
    st.integers(30, 200).map(_nested),
    st.just({}), st.just([]),
)


def _slots(node, out):
    """Every (container, key) in a nested dict/list."""
    if isinstance(node, dict):
        for k, v in node.items():
            out.append((node, k))
            _slots(v, out)
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out.append((node, i))
            _slots(v, out)
    return out


def _misspell(key: str, data) -> str:
    if not key:
        return "x"
    i = data.draw(st.integers(0, len(key) - 1))
    how = data.draw(st.sampled_from(["drop", "double", "swap", "case", "suffix"]))
    if how == "drop":
        return key[:i] + key[i + 1:] or "x"
    if how == "double":
        return key[:i] + key[i] + key[i:]
    if how == "swap" and len(key) > 1:
        j = min(i + 1, len(key) - 1)
        return key[:i] + key[j] + key[i] + key[j + 1:] if j > i else key + "_"
    if how == "case":
        return key.upper()
    return key + data.draw(st.sampled_from(["_abs", "_gauge", "s", "_"]))


def _bases():
    return {
        "paper-cycle": paper_cycle_dict(),
        "one-table": one_muscle_scenario(steps((0, "charge"), (0.01, "vent")), 0.02,
                                         motion={"kind": "table", "time_s": [0, 0.005, 0.01],
                                                 "contraction_percent": [0, 5, 8]},
                                         source={"initial_pressure_gauge": "6 bar"}),
        "one-joint": one_muscle_scenario(steps((0, "charge"), (0.015, "vent")), 0.02,
                                         motion={"kind": "joint_angles", "file": "angles.csv", "column": "hip"},
                                         n_muscles=2, exhaust={"initial_pressure_gauge": "0 bar"}),
    }


def _scaled(value, data):
    """A "number unit" text scaled by a drawn factor (a plausible edit a user makes)."""
    text = value.get("value") if isinstance(value, dict) else value
    if not isinstance(text, str) or " " not in text:
        return data.draw(VALUES, label="value")
    number, unit = text.split(" ", 1)
    try:
        x = float(number)
    except ValueError:
        return data.draw(VALUES, label="value")
    factor = data.draw(st.sampled_from([0.5, 0.9, 1.1, 2.0] * 3 + [0.0, 0.1, 10.0, 1e3, 1e-3, 1e-6, -1.0]), label="factor")
    return f"{x * factor!r} {unit}"


def _mutate(d: dict, data) -> None:
    for _ in range(data.draw(st.sampled_from([1, 1, 1, 2, 3]), label="mutations")):
        op = data.draw(st.sampled_from(["delete", "replace", "replace", "scale", "scale", "scale", "misspell",
                                        "add"]), label="op")
        slots = _slots(d, [])
        if op == "scale":      # a setting written "number unit"
            slots = [(p, k) for p, k in slots if isinstance(p[k], str) and " " in p[k]] or slots
        if not slots:
            return
        parent, key = slots[data.draw(st.integers(0, len(slots) - 1), label="slot")]
        if op == "scale":
            parent[key] = _scaled(parent[key], data)
        elif op == "delete":
            del parent[key]
        elif op == "replace":
            parent[key] = data.draw(VALUES, label="value")
        elif op == "misspell" and isinstance(parent, dict):
            parent[_misspell(str(key), data)] = parent.pop(key)
        elif op == "add" and isinstance(parent, dict):
            parent[data.draw(st.sampled_from(["volum", "initial_pressure_abs", "on_below_abs", "max_wall_time",
                                              "extra", "value", "source", "kind"]), label="key")] = \
                data.draw(VALUES, label="value")
        elif isinstance(parent, list):
            parent[key] = data.draw(VALUES, label="value")


def _check_physical(result) -> None:
    y = result.y
    assert np.all(np.isfinite(y)), "non-finite state"
    assert np.all(result.total_air_mass > 0)
    for who in ["source", "exhaust", *result.names]:
        T = result.temperature(who)
        assert np.all(np.isfinite(T)) and np.all(T > 0), (who, T.min())
    for name in result.names:
        assert np.all(result.muscle_mass(name) > 0), name
        assert np.all(result.muscle_pressure(name) > 0), name
    assert np.all(result.source_pressure > 0) and np.all(result.exhaust_pressure > 0)
    assert np.all(np.isfinite(result.volumes)) and np.all(result.volumes > 0)


ACCEPTED = []


@settings(max_examples=1000, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(base=st.sampled_from(["paper-cycle", "one-table", "one-joint"]), data=st.data())
def test_mutated_scenarios_are_refused_or_run_physically(base, data):
    d = copy.deepcopy(_bases()[base])
    d["base_dir"] = str(_DIR)
    _mutate(d, data)
    try:
        sc = frogsim.load_scenario(d)
        dur = min(sc.duration, 0.02)
        sc = sc.replace({"duration": dur, "output_interval": min(max(sc.output_interval, 1e-3), dur)})
        result = frogsim.simulate(sc, max_wall_s=5.0, progress=False)
    except frogsim.FrogsimError as exc:
        msg = str(exc)
        assert "\n" not in msg and len(msg) < 2000, msg
        return
    ACCEPTED.append(base)
    _check_physical(result)
    run_summary(result)        # the measures of a run whose valves may never open


def test_the_fuzzer_reaches_runs():
    """Guards the fuzz test above from refusing everything (it then checks no physics)."""
    if not ACCEPTED:       # run alone: nothing to count
        return
    assert len(ACCEPTED) >= 100, len(ACCEPTED)
