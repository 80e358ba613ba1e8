"""The coupled loop run in compiled code (frogsim.engine.coupled_loop) against the Python loop it
replaces: the same calls in the same order, so the same run bit for bit; failures stop at the same
step with the same message (quantity, time, MuJoCo's own warning)."""
from __future__ import annotations

import math

import numpy as np
import pytest

import frogsim
from frogsim.engine import coupled as C
from frogsim.engine.coupled_loop import mujoco_c
from frogsim.errors import SimulationError


@pytest.fixture(scope="module")
def full_robot():
    """The full robot (12 muscles, 24 valves) in water, one swim cycle."""
    raw = frogsim.load_robot_scenario("swim").raw
    raw = frogsim.with_overrides(raw, {"robot.recovery": "muscle"})
    return frogsim.load_robot_scenario(raw, cycles=1)


def test_the_mujoco_library_found_steps_the_bindings_data():
    """The two addresses the compiled loop calls are MuJoCo's mj_step1 and mj_step2 in the copy the
    bindings use: called on a model and data made through the bindings, one step of a free ball
    (no contact, default semi-implicit Euler) gives v = -g dt and z = -g dt^2, the same bits as the
    bindings' own mj_step1 + mj_step2."""
    import ctypes

    import mujoco
    addresses = mujoco_c(mujoco)
    assert addresses is not None
    xml = ('<mujoco><option timestep="0.01" gravity="0 0 -9.81"/><worldbody><body pos="0 0 1"><freejoint/>'
           '<geom size="0.1"/></body></worldbody></mujoco>')
    m = mujoco.MjModel.from_xml_string(xml)
    ours, theirs = mujoco.MjData(m), mujoco.MjData(m)
    step = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p)
    for address in addresses:
        step(address)(m._address, ours._address)
    mujoco.mj_step1(m, theirs)
    mujoco.mj_step2(m, theirs)
    g, dt = 9.81, 0.01
    assert ours.time == pytest.approx(dt)
    assert ours.qvel[2] == pytest.approx(-g * dt, rel=1e-12)
    assert ours.qpos[2] == pytest.approx(1.0 - g * dt ** 2, rel=1e-12)
    np.testing.assert_array_equal(ours.qpos, theirs.qpos)
    np.testing.assert_array_equal(ours.qvel, theirs.qvel)


def _run(rs, compiled, progress=None):
    cm = C.build_coupled(rs)
    out = C.run_coupled(cm, progress=progress, compiled=compiled)
    return cm, out


def test_run_coupled_compiled_equals_the_python_loop_bit_for_bit(full_robot):
    seen = {True: [], False: []}
    (cm_p, out_p), (cm_c, out_c) = (_run(full_robot, c, seen[c].append) for c in (False, True))
    # a run that actually moved and pumped: the comparison is not between two idle states
    assert out_c["rec"][-1, C.R_X] != out_c["rec"][0, C.R_X]
    assert out_c["stats"]["rhs_evaluations"] > cm_c.n_steps
    np.testing.assert_array_equal(out_c["rec"], out_p["rec"])
    assert out_c["stats"] == out_p["stats"]
    for name in ("qpos", "qvel", "qacc", "xfrc_applied", "ctrl", "act"):
        np.testing.assert_array_equal(getattr(cm_c.mjd, name), getattr(cm_p.mjd, name), err_msg=name)
    for name in ("body_mass", "body_inertia", "body_ipos"):
        np.testing.assert_array_equal(getattr(cm_c.mjm, name), getattr(cm_p.mjm, name), err_msg=name)
    for key in ("y", "u", "ds", "cs", "st", "frac", "vprev", "tension"):
        np.testing.assert_array_equal(cm_c.arrays[key], cm_p.arrays[key], err_msg=key)
    # progress reported at the same fractions, 0 to 1
    assert seen[True] == seen[False] and seen[True][0] == 0.0 and seen[True][-1] == 1.0


@pytest.mark.parametrize("when", [0, 1])
def test_failure_stops_at_the_same_step_with_the_same_message(when):
    """A non-finite velocity planted at t = 0, or between two stretches of the loop (from the
    progress callback after step k = n/20): both loops stop at the next kernel call, at the time
    of that step, naming the joint, and quote MuJoCo's own warning about the bad velocity."""
    rs = frogsim.load_robot_scenario("leg-in-air")
    msgs = []
    for compiled in (False, True):
        cm = C.build_coupled(rs)
        knee = cm.arrays["leg_dof"][1]                                   # knee_left
        calls = []

        def plant(frac, cm=cm, knee=knee, calls=calls):
            calls.append(frac)
            if len(calls) == 2:                                          # after k = n / 20
                cm.mjd.qvel[knee] = math.nan

        if when == 0:
            cm.mjd.qvel[knee] = math.nan
        with pytest.raises(SimulationError) as exc:
            C.run_coupled(cm, progress=plant, compiled=compiled)
        msgs.append(str(exc.value))
    chunk = max(1, C.build_coupled(rs).n_steps // 20)
    t = 0.0 if when == 0 else (chunk + 1) * rs.options.timestep
    assert msgs[0] == msgs[1]
    assert f"unstable at t = {t:.4f} s" in msgs[1] and "knee_left" in msgs[1]
    assert "velocity = nan (not finite)" in msgs[1] and "(MuJoCo: " in msgs[1]


def _actions(n, K, seed=1):
    """A reproducible sequence of valve states and palm targets (a bang-bang controller's)."""
    rng = np.random.default_rng(seed)
    return [(rng.integers(0, 2, 2 * n).astype(float), float(rng.integers(0, 2))) for _ in range(K)]


def _observe(st):
    return np.concatenate([st.joint_angles(), st.joint_velocities(), st.body_velocity(),
                           st.position(), [st.heading()], st.pressures(), [st.source_pressure()],
                           [st.charged_mass()], st.palm_opening(), st.cm.mjd.xfrc_applied.ravel()])


def test_coupled_stepper_compiled_equals_the_python_loop_bit_for_bit(full_robot):
    obs = {}
    for compiled in (False, True):
        st = C.CoupledStepper(full_robot, steps_per_action=10, compiled=compiled)
        acts = _actions(st.n, 60)
        seq = []
        for episode in range(2):                       # and again after a reset
            st.reset()
            for u, palm in acts:
                st.step(u, palm)
                seq.append(_observe(st))
        obs[compiled] = np.array(seq)
        assert st.k == 600 and st.t == pytest.approx(0.6)
    np.testing.assert_array_equal(obs[True], obs[False])
    half = obs[True].shape[0] // 2
    np.testing.assert_array_equal(obs[True][:half], obs[True][half:])
    # the robot moved and the valves charged air: a comparison of non-trivial states
    assert not np.array_equal(obs[True][0], obs[True][half - 1])


def test_coupled_stepper_failure_message_is_the_same(full_robot):
    msgs = []
    for compiled in (False, True):
        st = C.CoupledStepper(full_robot, steps_per_action=10, compiled=compiled)
        for u, palm in _actions(st.n, 3):
            st.step(u, palm)
        st.cm.mjd.qvel[st.cm.arrays["leg_dof"][4]] = math.inf          # knee_right
        with pytest.raises(SimulationError) as exc:
            st.step(np.zeros(2 * st.n), 0.0)
        msgs.append(str(exc.value))
        assert st.k == 30
    assert msgs[0] == msgs[1]
    assert "unstable at t = 0.0300 s" in msgs[1] and "knee_right" in msgs[1] and "inf" in msgs[1]


def test_without_the_c_library_the_python_loop_runs_after_one_warning(monkeypatch):
    import frogsim.engine.coupled_loop as loop
    monkeypatch.setattr(loop, "_LIB", "no MuJoCo shared library next to the bindings")
    monkeypatch.setattr(loop, "_WARNED", False)
    rs = frogsim.load_robot_scenario("leg-in-air")
    with pytest.warns(RuntimeWarning, match="no MuJoCo shared library.*running the loop from Python"):
        cm, out = _run(rs, True)
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")                       # once per process, not per run
        cm2, out2 = _run(rs, True)
    monkeypatch.undo()
    cm3, out3 = _run(rs, True)
    np.testing.assert_array_equal(out["rec"], out3["rec"])
    np.testing.assert_array_equal(out2["rec"], out3["rec"])


def test_the_run_rate_excludes_compilation(monkeypatch):
    """Compiling (or loading) the loop happens in a call of zero steps before the timed steps:
    a compilation that takes 0.5 s shows in compile_s, not in wall_s."""
    import time as _time
    from frogsim.engine import coupled
    real = coupled.run_steps

    def slow_first(*a):
        if a[4] == a[5]:                  # k0 == k1: the call that only compiles
            _time.sleep(0.5)
        return real(*a)
    monkeypatch.setattr(coupled, "run_steps", slow_first)
    t0 = _time.perf_counter()
    res = frogsim.swim("leg-in-air", cycles=1)
    total = _time.perf_counter() - t0
    assert res.compile_s >= 0.5 and res.wall_s <= total - 0.5
    solver = res.summary()["solver"]
    assert solver["compile_time_s"] >= 0.5
    assert solver["real_time_factor"] == pytest.approx(res.t[-1] / res.wall_s)


def test_the_kernels_groups_and_its_loose_form_come_from_one_list(full_robot):
    """step_kernel_loose's parameters, the named groups step_kernel reads and the arguments the
    engine hands either are made from KERNEL_GROUPS: each group member is the model's array of that
    name (the circuit: advance's model tuple), the loose arguments the same arrays in the same order."""
    import inspect
    from frogsim.circuit import layout as CL
    from frogsim.engine import coupled_kernel as K
    params = tuple(inspect.signature(K.step_kernel_loose.py_func).parameters)
    assert params == ("k", "stepping", "row") + K.loose_names()
    cm = C.build_coupled(full_robot)
    groups = C.kernel_args(cm)
    assert [type(gr) for gr in groups] == list(K.GROUP_CLASSES)
    flat = []
    for gr, (_, _, members) in zip(groups, K.KERNEL_GROUPS):
        assert gr._fields == members
        for m in members:
            v = getattr(gr, m)
            if m == "circuit":
                assert all(a is cm.arrays[k] for a, k in zip(v, CL.MODEL_GROUP)) and len(v) == 6
                flat.extend(v)
            else:
                if gr is not groups[-1]:
                    assert v is cm.arrays[m]
                flat.append(v)
    assert np.shares_memory(groups[-1].xfrc, cm.mjd.xfrc_applied)
    assert np.shares_memory(groups[-1].body_mass, cm.mjm.body_mass)
    loose = C.kernel_loose_args(cm)
    assert len(loose) == len(flat) and all(a is b for a, b in zip(loose, flat))
