"""The robot with its closed-loop muscles driven by a Python function, sample by sample.

    result = frogsim.swim(scenario, controller=fn)      # fn(t, obs) -> {muscle: "charge" | "hold" | "vent"}

The compiled laws of the scenario's ``[controllers]`` are not used: their rows become external
ones (:data:`frogsim.control.sampled.KIND_EXTERNAL`) that keep their sensor models (pressure and,
for a joint-angle controller, the angle sensor), and the function decides instead. Its commands
go through the same dead-time queue (:func:`frogsim.control.sampled.command_valves`), so the same
law written in Python gives the same valve sequence as the compiled one. The loop is the coupled
engine's (:func:`frogsim.engine.coupled_kernel.step_kernel` per MuJoCo step); the function is
called after each step whose end is a controller sample, so the controller period must be a
whole number of MuJoCo steps.
"""
from __future__ import annotations

import time

import numpy as np

from frogsim.circuit import layout as CL
from frogsim.control.sampled import (B_A_SENSED, B_SENSED, B_W_SENSED, CS_SAMPLE,
                                     KIND_EXTERNAL, KIND_PUMP_BAND, L_DEAD_C, L_DEAD_D, L_JOINT1, L_KIND,
                                     L_MUSCLE, L_SIZE, command_from_python, law_block)
from frogsim.control.table import L_PATM
from frogsim.engine.coupled import _failure, kernel_loose_args, run_record
from frogsim.engine.coupled_kernel import step_kernel_loose
from frogsim.engine.coupled_layout import S_CTRL_DT, S_TRUNK
from frogsim.engine.integrator import start
from frogsim.errors import SimulationError
from frogsim.robot import import_mujoco


def external_laws(laws: np.ndarray, every: tuple = (), dead: tuple = (0.0, 0.0),
                  patm: float = 0.0) -> np.ndarray:
    """The table of laws with every closed-loop row turned external (sensors kept), plus an
    external row (no sensor) for each muscle index in ``every`` that has no row yet (valve dead
    times ``dead`` [s], atmospheric pressure ``patm`` [Pa])."""
    if laws.ndim == 1 and not every:
        raise ValueError("the scenario has no closed-loop [controllers]: nothing for a Python "
                         "controller to drive")
    out = (laws.reshape(-1, L_SIZE) if laws.ndim == 1 else laws).copy()
    for c in range(out.shape[0]):
        if out[c, L_KIND] != KIND_PUMP_BAND:
            out[c, L_KIND] = KIND_EXTERNAL
    have = {int(out[c, L_MUSCLE]) for c in range(out.shape[0]) if out[c, L_KIND] == KIND_EXTERNAL}
    extra = [i for i in every if i not in have]
    if extra:
        add = np.zeros((len(extra), out.shape[1]))
        for r, i in enumerate(extra):
            add[r, L_KIND] = KIND_EXTERNAL
            add[r, L_MUSCLE] = i
            add[r, L_DEAD_C], add[r, L_DEAD_D] = dead
            add[r, L_PATM] = patm
        out = np.vstack([out, add])
    return out


def body_velocity(m, d, tb: int) -> tuple:
    """(forward, sideways, yaw rate) of the hull: [m/s] along and across its heading, [rad/s]."""
    root = m.body_rootid[tb]
    w0, w1, w2, v0, v1, _ = d.cvel[tb].tolist()
    r0, r1, r2 = (d.xpos[tb] - d.subtree_com[root]).tolist()
    # v + w x r, its horizontal part written out (np.cross on 3-vectors costs more than the rest
    # of a software-in-the-loop sample's Python; the same products and differences)
    vx = v0 + (w1 * r2 - w2 * r1)
    vy = v1 + (w2 * r0 - w0 * r2)
    hx, hy = d.xmat[tb, 0], d.xmat[tb, 3]
    return (float(vx * hx + vy * hy), float(-vx * hy + vy * hx), float(w2))


def run_coupled_python(cm, fn, progress=None, every_muscle: bool = False) -> dict:
    """Run a built coupled model (:func:`frogsim.engine.coupled.build_coupled`) with ``fn``
    deciding the valves of the muscles under ``[controllers]``; returns what
    :func:`frogsim.engine.coupled.run_coupled` returns.

    ``fn(t, obs)`` is called at every controller sample t (from 0) with ``obs``: {muscle: its
    pressure [Pa abs] as its controller's sensor reads it, "source": p_s, "exhaust": p_e [Pa abs],
    "angle": {joint: [rad]}, "velocity": {joint: [rad/s]}, "body_velocity": (forward [m/s],
    sideways [m/s], yaw rate [rad/s])}. The joint angles and velocities are the state at the
    start of the MuJoCo step that ends at t, as the compiled joint-angle law reads them; a joint
    under a joint-angle controller is read through that controller's angle sensor. It returns
    {muscle: "charge" | "hold" | "vent"} (or +1, 0, -1); a muscle left out keeps its mode.
    ``obs["state"]`` is a copy of the pneumatic state y at t, ``obs["qpos"]`` and ``obs["qvel"]``
    copies of MuJoCo's whole qpos and qvel as the compiled laws read them (the step's start).
    A function with an attribute ``observes`` (a subset of {"state", "qpos", "qvel"}) is given
    just those three (a cheaper sample: software in the loop reads no more).

    With ``every_muscle`` the function drives every muscle, those with a gait program too (the
    gait's valve commands are not run; its palm commands are): the firmware in the loop runs the
    programs (:mod:`frogsim.export.sil`).
    """
    mujoco = import_mujoco()
    m, d = cm.mjm, cm.mjd
    a = cm.arrays
    dt_ctrl = float(a["sc"][S_CTRL_DT])
    ratio = dt_ctrl / cm.dt
    if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
        raise SimulationError(f"scenario {cm.name!r}: a Python controller needs the controller "
                              f"period ({dt_ctrl * 1e3:g} ms) to be a whole number of MuJoCo steps "
                              f"(robot.timestep = {cm.dt * 1e3:g} ms)")
    pn = cm.pneumatic
    every = tuple(range(len(cm.muscle_names))) if every_muscle else ()
    laws = external_laws(a["laws"], every, (pn.scenario.valves.charge.dead_time,
                                            pn.scenario.valves.discharge.dead_time),
                         float(pn.g[CL.G_PATM]))
    a["laws"] = laws
    if every_muscle:
        a["sched_t"], a["sched_u"] = np.zeros(0), np.zeros((0, a["u"].size))
    a["u"][:] = 0.0 if every_muscle else cm.pneumatic.u0
    ds, cs = start(0.0, 1e-4, a["y"], a["u"], a["mp"], (a["sched_t"], a["sched_u"], laws, dt_ctrl))
    a["ds"], a["cs"] = ds, cs
    rows = {cm.muscle_names[int(laws[c, L_MUSCLE])]: c for c in range(laws.shape[0])
            if laws[c, L_KIND] == KIND_EXTERNAL}
    sensed_joint = {}
    for c in rows.values():
        j = int(laws[c, L_JOINT1]) - 1
        if j >= 0:
            sensed_joint[cm.joint_names[j]] = law_block(cs, c)
    leg_qpos, leg_dof = a["leg_qpos"], a["leg_dof"]
    y, u = a["y"], a["u"]
    tb = int(a["sc"][S_TRUNK])

    # a function that names the observations it reads (``fn.observes``) gets only those: software
    # in the loop reads the state and MuJoCo's qpos and qvel, and the rest would cost it a third
    # of its Python time
    only = getattr(fn, "observes", None)
    if only is not None:
        only = frozenset(only)
        known = {"state", "qpos", "qvel"}
        if not only <= known:
            raise ValueError(f"controller function: observes {sorted(only - known)}; a function that "
                             f"names what it reads may name {sorted(known)}, or leave observes unset")

    def decide():
        t_k = cs[CS_SAMPLE] * dt_ctrl
        if only is not None:
            obs = {"state": y.copy(), "qpos": d.qpos.copy(), "qvel": d.qvel.copy()}
            command_from_python(laws, rows, cs, fn(t_k, obs), t_k, u, t_k)
            return
        obs = {n: float(cs[law_block(cs, c) + B_SENSED]) for n, c in rows.items()}
        obs["source"], obs["exhaust"] = float(y[CL.Y_PS]), float(y[CL.Y_PE])
        angle = {n: float(d.qpos[leg_qpos[j]]) for j, n in enumerate(cm.joint_names)}
        vel = {n: float(d.qvel[leg_dof[j]]) for j, n in enumerate(cm.joint_names)}
        for n, b in sensed_joint.items():
            angle[n], vel[n] = float(cs[b + B_A_SENSED]), float(cs[b + B_W_SENSED])
        obs["angle"], obs["velocity"] = angle, vel
        obs["body_velocity"] = body_velocity(m, d, tb)
        obs["state"], obs["qpos"], obs["qvel"] = y.copy(), d.qpos.copy(), d.qvel.copy()
        command_from_python(laws, rows, cs, fn(t_k, obs), t_k, u, t_k)

    args = kernel_loose_args(cm)
    step1, step2 = mujoco.mj_step1, mujoco.mj_step2
    n_steps, every = cm.n_steps, cm.rec_every
    chunk = max(1, n_steps // 20)
    t0 = time.perf_counter()
    for k in range(n_steps + 1):
        step1(m, d)
        if k == 0:
            decide()                            # the sample at t = 0 (taken by start)
        stepping = 1 if k < n_steps else 0
        row = k // every if k % every == 0 else (-1 if stepping else k // every + 1)
        before = cs[CS_SAMPLE]
        if step_kernel_loose(k, stepping, row, *args):
            raise SimulationError(f"scenario {cm.name!r}: unstable at t = {k * cm.dt:.4f} s: "
                                  f"{_failure(cm)}")
        if stepping:
            if cs[CS_SAMPLE] != before:
                decide()
            step2(m, d)
        if progress is not None and k % chunk == 0:
            progress(k / n_steps)
    return run_record(cm, time.perf_counter() - t0)
