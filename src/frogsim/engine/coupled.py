"""The pneumatics coupled with the MuJoCo body: build the model, run the loop, read the records.

:func:`build_coupled` compiles the robot's MJCF into a MuJoCo model and maps the names the tables
use to its ids (:func:`_compile`), builds the pneumatic model and the water's tables, and
allocates every array the compiled step works on (:func:`_assemble`). :func:`run_coupled` then
runs, for each MuJoCo step of length dt,

    mj_step1 (positions, velocities, tendon lengths)  ->  step_kernel (one Numba call)  ->  mj_step2

with :func:`frogsim.engine.coupled_kernel.step_kernel` doing the muscles, palms, water and
pneumatics (its docstring says how). The loop itself runs in compiled code
(:func:`frogsim.engine.coupled_loop.run_steps`: MuJoCo's C functions and the kernel called from
one Numba function, a stretch of n_steps / 20 steps per call, back in Python between stretches for
the progress callback and at a failure); ``run_coupled(cm, compiled=False)`` runs the same calls
from Python, one step at a time, and gives the same run bit for bit. The index layouts of the
arrays are in :mod:`frogsim.engine.coupled_layout`; the record's columns R_* are part of what
:func:`run_coupled` returns and are named here too.

Every step checks the state: a non-finite position or velocity, a leg joint faster than
200 rad/s or a hull faster than 20 m/s stops the run with a SimulationError that names the
quantity and the time.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from frogsim.circuit import actuators
from frogsim.circuit import layout as CL
from frogsim.circuit.actuators.spec import FORCE_PARAMS
from frogsim.circuit.model import build_model, schedule_from_events
from frogsim.control.sampled import sampled_laws
from frogsim.engine.coupled_kernel import (CIRCUIT, GROUP_CLASSES, KERNEL_GROUPS, MuJoCo, apply_added_mass,
                                          loose_names, step_kernel_loose)
from frogsim.engine.coupled_loop import mujoco_c, run_steps
# R_* and T_PEAK*: the record's and the state's columns, read by callers of run_coupled
from frogsim.engine.coupled_layout import (  # noqa: F401
    FAIL_BODY_SPEED, FAIL_JOINT_SPEED, FAIL_PNEUMATIC, FAIL_QPOS, FAIL_QVEL, R_AIR, R_CHARGED,
    R_EXERGY, R_HULL, R_PE, R_POSITION, R_PS, R_PUMP_ON, R_PUMPED, R_THRUST, R_THRUST_AM, R_TIME,
    R_V, R_VELOCITY, R_X, R_YAW, S_CTRL_DT, S_DT, S_G, S_LAW, S_MAXSTEP, S_METHOD, S_RHO, S_RTOL, S_SIZE,
    STOP_C, STOP_DAMPING, STOP_K, STOP_LOWER, STOP_SIZE, STOP_UPPER, S_TRUNK, S_VMAX, S_WMAX,
    T_FAIL, T_FAIL_ARG, T_FAIL_VAL, T_FIRST, T_PALM_TARGET, T_PEAK, T_PEAK_TIME, T_SIZE, U_ACT, U_FITTINGS, U_SIZE,
    U_TENDON, V_SIZE, record_columns)
from frogsim.engine import methods
from frogsim.engine.integrator import D_F_VALID, D_SI, STATS_SIZE, STATUS_TEXT, start
from frogsim.engine.methods.spec import PAR_SIZE
from frogsim.errors import SimulationError
from frogsim.robot import import_mujoco
from frogsim.robot.water import E_BODY, P_SIZE, hydro_tables
from frogsim.scenario.methods import default_settings as default_method_settings

BODY_SPEED_LIMIT = 20.0       # [m/s]: ten times anything the robot can swim
JOINT_SPEED_LIMIT = 200.0     # [rad/s]: a leg joint swinging its whole range in 4 ms


@dataclass
class CoupledModel:
    """The MuJoCo model and data, the pneumatic model and every table the kernel loops over."""
    name: str
    rs: object                  # the RobotScenario (None for a bare body, see build_bare)
    mjm: object
    mjd: object
    pneumatic: object           # frogsim.circuit.model.PneumaticModel (None for a bare body)
    xml: str
    muscle_names: list
    joint_names: list
    arrays: dict
    n_steps: int
    rec_every: int
    columns: dict = field(default_factory=dict)
    # (mjm, mjd, their arrays the kernel takes): made once, as the views cost microseconds each time
    _views: tuple = field(default=(None, None, ()), repr=False, compare=False)

    @property
    def dt(self) -> float:
        return float(self.arrays["sc"][S_DT])

    def set_muscle_pressure(self, name: str, pressure_abs: float) -> None:
        """Start a muscle at a given absolute pressure [Pa] (before :func:`run_coupled`), with its
        air at ambient temperature in its present volume."""
        i = self.muscle_names.index(name)
        y, g, mp, mu = (self.arrays[k] for k in ("y", "g", "mp", "mu"))
        L = self.mjd.ten_length[int(mu[i, U_TENDON])] - mu[i, U_FITTINGS]
        V = actuators.volume(mp, i, L) + mp[i, CL.M_DEAD]
        y[CL.mass_index(i)] = pressure_abs * V / (g[CL.G_R] * g[CL.G_TAMB])
        y[CL.pressure_index(i)] = pressure_abs
        self.arrays["ds"][D_F_VALID] = 0.0          # the state changed: dy/dt is evaluated again


def _assemble(name, rs, xml, m, d, pm, circuit, mu, tables, palms_cmd, sc, joints, duration,
              output_interval, hysteresis=None, stops=None) -> CoupledModel:
    """Allocate every array the kernel needs and put the static added masses into the model.

    ``circuit`` = (g, mp, y, u, sched_t, sched_u, atol). ``hysteresis``: None (the force law
    without memory), or (anchors (n, N), stiffness (N,), slip (N,)): the muscles' slip elements
    (:func:`frogsim.physics.hysteresis.muscle_hysteresis_force`), anchors at their start.
    ``stops``: per joint of ``joints`` its end stops (STOP_* columns of
    :mod:`frogsim.engine.coupled_layout`), none for a bare body.
    """
    mujoco = import_mujoco()
    g, mp, y, u, sched_t, sched_u, atol = circuit
    el, strip_s, strip_k, pa = tables
    pal_t, pal_target = palms_cmd
    n = mu.shape[0]
    # no elements (N = 0) when the law has no memory: the kernel then skips the hysteresis
    hyst = hysteresis if hysteresis is not None else (np.zeros((n, 0)), np.zeros(0), np.zeros(0))
    ids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in joints]
    leg_qpos = np.array([m.jnt_qposadr[i] for i in ids], np.int64)
    leg_dof = np.array([m.jnt_dofadr[i] for i in ids], np.int64)
    st = np.zeros(T_SIZE)
    st[T_FIRST] = 1.0
    st[T_PEAK] = -np.inf
    # the pump's band and the scenario's closed-loop controllers (joint-angle laws read the joint
    # angles that step_kernel writes into cs before each step; the sample at t = 0 reads the
    # initial observation, zero: the robot starts at rest at its flexed stops)
    laws = pm.laws if pm is not None else sampled_laws(g)
    ds, cs = start(0.0, 1e-4, y, u, mp, (sched_t, sched_u, laws, sc[S_CTRL_DT]))
    dt = sc[S_DT]
    n_steps = int(round(duration / dt))
    rec_every = max(1, int(round(output_interval / dt)))
    cols = record_columns(n, pa.shape[0], len(joints), m.nq)
    frac = np.zeros(pa.shape[0])
    arrays = dict(
        sc=sc, st=st, el=el, strip_s=np.ascontiguousarray(strip_s),
        strip_k=np.ascontiguousarray(strip_k), pa=pa.reshape(-1, P_SIZE), pal_t=pal_t,
        pal_target=pal_target, frac=frac, frac_new=frac.copy(), mu=mu, mp=mp, g=g, y=y, u=u,
        ds=ds, cs=cs, mot_t=np.zeros((n, 4)), mot_L=np.zeros((n, 4)), mot_d=np.zeros((n, 4)),
        mot_n=np.full(n, 4, np.int64), sched_t=sched_t, sched_u=sched_u, laws=laws, atol=atol,
        stats=np.zeros(STATS_SIZE, np.int64), vprev=np.zeros((el.shape[0], V_SIZE)), tension=np.zeros(n),
        anchors=hyst[0], slip_k=hyst[1], slip_f=hyst[2],
        rec=np.full((record_rows(n_steps, rec_every), cols["size"]), np.nan), leg_qpos=leg_qpos,
        leg_dof=leg_dof, stops=(np.zeros((len(joints), STOP_SIZE)) if stops is None
                                else np.ascontiguousarray(stops, float)))
    apply_added_mass(el, arrays["pa"], frac, False, m.body_mass, m.body_ipos, m.body_inertia,
                     m.body_subtreemass, m.body_parentid)
    # MuJoCo keeps the mass-matrix entries of "simple" dofs (a body whose dofs do not couple)
    # as constants computed at compile time (dof_M0): recompute them for the new masses, and
    # refuse a palm (whose mass changes every step) on such a dof
    mujoco.mj_setConst(m, mujoco.MjData(m))
    for p in range(pa.shape[0]):
        b = int(el[int(pa[p, 0]), E_BODY])
        dofs = np.nonzero(m.dof_bodyid == b)[0]
        if np.any(m.dof_simplenum[dofs] > 0):
            raise AssertionError(f"body {b}: its mass changes at run time but MuJoCo treats it as simple")
    return CoupledModel(name=name, rs=rs, mjm=m, mjd=d, pneumatic=pm, xml=xml,
                        muscle_names=list(rs.muscles) if rs is not None else [],
                        joint_names=list(joints), arrays=arrays, n_steps=n_steps,
                        rec_every=rec_every, columns=cols)


def _constants(dt, rho, gravity, trunk, ctrl_rate=1000.0, rtol=1e-7, max_step=1e-3, law=None, method=None,
               types=()):
    """The kernel's constants sc[:] (columns S_* of :mod:`frogsim.engine.coupled_layout`);
    ``method`` the integration method's settings (None: the default method's); ``law`` the force
    law ([muscle_force]) of the muscles of settings ``types``, its block written by their actuator
    type (:func:`frogsim.circuit.actuators.force_block`)."""
    sc = np.zeros(S_SIZE)
    sc[S_METHOD:S_METHOD + PAR_SIZE] = methods.parameter_block(method if method is not None
                                                               else default_method_settings())
    sc[S_DT], sc[S_RHO], sc[S_G] = dt, rho, gravity
    sc[S_CTRL_DT], sc[S_RTOL], sc[S_MAXSTEP] = 1.0 / ctrl_rate, rtol, max_step
    if law is not None:
        sc[S_LAW:S_LAW + FORCE_PARAMS] = actuators.force_block(types, law)
    sc[S_TRUNK] = trunk
    sc[S_VMAX] = BODY_SPEED_LIMIT
    sc[S_WMAX] = JOINT_SPEED_LIMIT
    return sc


# --- MJCF compile and id maps ----------------------------------------------------------------------
def _compile(xml: str):
    """(MuJoCo model, data after a forward pass, id lookup) of an MJCF document.

    The lookup ``oid(kind, name)`` maps a name of the tables (muscle tendon and actuator, part
    body) to MuJoCo's id and refuses a name the MJCF lacks.
    """
    mujoco = import_mujoco()
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)

    def oid(kind, name):
        i = mujoco.mj_name2id(m, kind, name)
        if i < 0:
            raise AssertionError(f"MJCF has no {name!r}")
        return i

    return m, d, oid


def build_coupled(rs) -> CoupledModel:
    """MuJoCo model (from the generated MJCF), pneumatic model and tables for a robot scenario."""
    mujoco = import_mujoco()

    from frogsim.control.gait import palm_commands
    from frogsim.robot.mjcf import build_mjcf

    xml = build_mjcf(rs)
    m, d, oid = _compile(xml)
    pm = build_model(rs.pneumatic)
    names = list(rs.muscles)
    if pm.names != names:
        raise AssertionError("pneumatic muscles and robot muscles out of order")
    mu = np.zeros((len(names), U_SIZE))
    for i, name in enumerate(names):
        mu[i, U_TENDON] = oid(mujoco.mjtObj.mjOBJ_TENDON, name)
        mu[i, U_ACT] = oid(mujoco.mjtObj.mjOBJ_ACTUATOR, name)
        mu[i, U_FITTINGS] = rs.layout.cranks[rs.muscles[name][0]].fittings
    tables = hydro_tables(rs, lambda b: oid(mujoco.mjtObj.mjOBJ_BODY, b))
    sc = _constants(rs.options.timestep, rs.medium_density, rs.robot.water.gravity,
                    oid(mujoco.mjtObj.mjOBJ_BODY, "body"), rs.pneumatic.controller.rate,
                    rs.pneumatic.solver.rtol, rs.pneumatic.solver.max_step, rs.robot.muscle_force,
                    rs.pneumatic.solver.method,
                    tuple(rs.pneumatic.muscle_types[rs.pneumatic.muscles[n].type] for n in names))
    # the muscles' air at ambient temperature in their actual initial volumes
    y = pm.y0.copy()
    contraction = np.zeros(len(names))
    for i in range(len(names)):
        L = d.ten_length[int(mu[i, U_TENDON])] - mu[i, U_FITTINGS]
        V = actuators.volume(pm.mp, i, L) + pm.mp[i, CL.M_DEAD]
        y[CL.mass_index(i)] = y[CL.pressure_index(i)] * V / (pm.g[CL.G_R] * pm.g[CL.G_TAMB])
        contraction[i] = 1.0 - L / pm.mp[i, CL.M_L0]
    circuit = (pm.g, pm.mp, y, pm.u0.copy(), pm.sched_t, pm.sched_u, pm.atol)
    joints = [f"{j}_{s}" for s in ("left", "right") for j in ("hip", "knee", "ankle")]
    return _assemble(rs.name, rs, xml, m, d, pm, circuit, mu, tables,
                     palm_commands(rs.gait, rs.pneumatic.controller.rate), sc, joints,
                     rs.duration, rs.pneumatic.output_interval,
                     _hysteresis(rs.robot.muscle_force, contraction), stop_table(rs, joints))


def _hysteresis(law, contraction):
    """The muscles' slip elements for the kernel (see :func:`_assemble`), or None for a law without
    memory. Every element's anchor starts at its muscle's contraction at t = 0: the muscle starts
    relaxed, without a hysteresis force, whatever path it took to its start."""
    if law.hysteresis == "none":
        return None
    from frogsim.physics.hysteresis import element_table
    k, f = element_table(law.slip_elements, law.slip_per_pressure, law.slip_strain)
    return np.repeat(contraction[:, None], k.size, axis=1), k, f


def stop_table(rs, joints) -> np.ndarray:
    """The end stops of the named leg joints ("hip_left", ...): per row the range's two ends
    [rad], the pads' stiffness [N m/rad] and damping [N m s/rad] (:mod:`frogsim.physics.stop`)
    and the joint's own damping [N m s/rad]."""
    out = np.zeros((len(joints), STOP_SIZE))
    for i, name in enumerate(joints):
        jp = rs.robot.joints[name.split("_")[0]]
        out[i, STOP_LOWER], out[i, STOP_UPPER] = 0.0, jp.range
        out[i, STOP_K], out[i, STOP_C] = jp.stop_stiffness, jp.stop_damping
        out[i, STOP_DAMPING] = jp.damping
    return out


def build_bare(xml: str, tables, density: float, gravity: float, duration: float,
               output_interval: float, trunk: str = "body") -> CoupledModel:
    """A body in water without muscles or pneumatics (e.g. a hull coasting): the MJCF's timestep,
    the parts' tables as made by :mod:`frogsim.robot.water` (body ids of this model)."""
    mujoco = import_mujoco()
    m, d, oid = _compile(xml)
    g = np.zeros(CL.G_SIZE)
    g[CL.G_K], g[CL.G_R], g[CL.G_PATM] = 1.4, 287.0, 101325.0
    g[CL.G_RHOREF], g[CL.G_TREF], g[CL.G_TAMB] = 1e5 / (287.0 * 293.15), 293.15, 293.15
    g[CL.G_VS] = g[CL.G_VE] = 1e-3
    m_air = g[CL.G_PATM] * 1e-3 / (287.0 * 293.15)
    y = np.array([m_air, g[CL.G_PATM], m_air, g[CL.G_PATM], 0.0])
    circuit = (g, np.zeros((0, CL.M_SIZE)), y, np.zeros(0), np.zeros(0), np.zeros((0, 0)),
               np.full(5, 1e-9))
    sc = _constants(float(m.opt.timestep), density, gravity, oid(mujoco.mjtObj.mjOBJ_BODY, trunk))
    return _assemble("bare", None, xml, m, d, None, circuit, np.zeros((0, U_SIZE)), tables,
                     (np.zeros(0), np.zeros(0)), sc, [], duration, output_interval)


#: where kernel_args finds the MuJoCo group's members (coupled_kernel.KERNEL_GROUPS): (mjData "d" or
#: mjModel "m", its attribute)
_MUJOCO_ARRAYS = {"ten_length": ("d", "ten_length"), "ten_velocity": ("d", "ten_velocity"), "xpos": ("d", "xpos"),
                  "xmat": ("d", "xmat"), "xipos": ("d", "xipos"), "cvel": ("d", "cvel"),
                  "subtree_com": ("d", "subtree_com"), "body_rootid": ("m", "body_rootid"),
                  "body_parentid": ("m", "body_parentid"), "body_mass": ("m", "body_mass"),
                  "body_ipos": ("m", "body_ipos"), "body_inertia": ("m", "body_inertia"),
                  "body_subtreemass": ("m", "body_subtreemass"), "ctrl": ("d", "ctrl"),
                  "xfrc": ("d", "xfrc_applied"), "qpos": ("d", "qpos"), "qvel": ("d", "qvel"),
                  "qfrc": ("d", "qfrc_applied"), "dof_damping": ("m", "dof_damping")}


def _mujoco_views(cm: CoupledModel):
    """The MuJoCo group (:class:`frogsim.engine.coupled_kernel.MuJoCo`) of the model's MuJoCo
    arrays, made again only when the model or data changed."""
    m, d = cm.mjm, cm.mjd
    if cm._views[0] is not m or cm._views[1] is not d:
        src = {"m": m, "d": d}
        cm._views = (m, d, MuJoCo(**{name: getattr(src[which], attr)
                                     for name, (which, attr) in _MUJOCO_ARRAYS.items()}))
    return cm._views[2]


def kernel_args(cm: CoupledModel) -> tuple:
    """The groups step_kernel takes after (k, stepping, row), as named tuples
    (:data:`frogsim.engine.coupled_kernel.KERNEL_GROUPS`): the model's arrays by their names, the
    circuit as advance's model tuple, MuJoCo's views; for the compiled loop."""
    a = cm.arrays
    circuit = tuple(a[k] for k in CIRCUIT)
    groups = tuple(cls(**{m: (circuit if m == "circuit" else a[m]) for m in members})
                   for cls, (_, _, members) in zip(GROUP_CLASSES[:-1], KERNEL_GROUPS[:-1]))
    return groups + (_mujoco_views(cm),)


def kernel_loose_args(cm: CoupledModel) -> tuple:
    """The same arrays loose, in the same order (:func:`frogsim.engine.coupled_kernel.loose_names`),
    for :func:`step_kernel_loose` (Python's calls)."""
    a = cm.arrays
    return tuple(a[k] for k in _LOOSE_OWN) + tuple(_mujoco_views(cm))


#: step_kernel_loose's parameters that are the model's arrays (the MuJoCo group's follow)
_LOOSE_OWN = loose_names()[:-len(KERNEL_GROUPS[-1][2])]


def forces_now(cm: CoupledModel) -> np.ndarray:
    """The forces the kernel would apply in the present state, without advancing anything:
    ``xfrc_applied`` (per body: force [N] and torque about its centre of mass [N m], world frame)
    after MuJoCo's forward pass and the kernel's force computation (muscles and water)."""
    mujoco = import_mujoco()
    mujoco.mj_forward(cm.mjm, cm.mjd)
    status = step_kernel_loose(0, 0, -1, *kernel_loose_args(cm))
    if status:
        raise SimulationError(f"{cm.name!r}: {_failure(cm)}")
    return cm.mjd.xfrc_applied.copy()


def _failure(cm: CoupledModel) -> str:
    st = cm.arrays["st"]
    code, arg, val = int(st[T_FAIL]), int(st[T_FAIL_ARG]), float(st[T_FAIL_VAL])
    m = cm.mjm
    mujoco = import_mujoco()
    if code == FAIL_PNEUMATIC:
        return f"the pneumatic integration stopped: {STATUS_TEXT.get(arg, arg)}"
    if code in (FAIL_QPOS, FAIL_QVEL):
        what = "position" if code == FAIL_QPOS else "velocity"
        jid = (np.searchsorted(m.jnt_qposadr, arg, side="right") - 1 if code == FAIL_QPOS
               else np.searchsorted(m.jnt_dofadr, arg, side="right") - 1)
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, int(jid)) or f"dof {arg}"
        return f"joint {name!r} {what} = {val:g} (not finite)"
    if code == FAIL_BODY_SPEED:
        return f"hull speed = {val:.4g} m/s exceeds {BODY_SPEED_LIMIT:g} m/s"
    if code == FAIL_JOINT_SPEED:
        return (f"joint {cm.joint_names[arg]!r} angular velocity = {val:.4g} rad/s exceeds "
                f"{JOINT_SPEED_LIMIT:g} rad/s")
    return f"failure code {code}"


def record_rows(n_steps: int, every: int) -> int:
    """The number of record rows of a run of ``n_steps`` MuJoCo steps recorded every ``every``
    steps: steps 0, every, 2 every, ... and the last step n_steps (its own row if it is not a
    multiple of ``every``)."""
    return n_steps // every + 1 + (1 if n_steps % every else 0)


def run_record(cm: CoupledModel, wall: float, compile_s: float = 0.0) -> dict:
    """What a finished coupled run returns: its record rows, wall time of the steps
    (``wall_s``), time spent compiling or loading the compiled loop before them (``compile_s``)
    and step statistics.

    Raises SimulationError if a row of the output grid was not written (a run is never returned
    with a row nobody wrote)."""
    a = cm.arrays
    rec = a["rec"]
    want = record_rows(cm.n_steps, cm.rec_every)
    written = ~np.isnan(rec[:, R_TIME])
    if int(written[:want].sum()) != want or written[want:].any():
        raise SimulationError(f"scenario {cm.name!r}: the run ended with {int(written.sum())} of its {want} "
                              f"output rows written")
    rec = rec[:want]
    return {"rec": rec, "wall_s": wall, "compile_s": compile_s, "stats": {"mujoco_steps": cm.n_steps,
                                                  "pneumatic_steps": int(a["stats"][0]),
                                                  "pneumatic_rejected": int(a["stats"][1]),
                                                  "rhs_evaluations": int(a["stats"][2]),
                                                  "stiff_steps": int(a["stats"][3])}}


def run_coupled(cm: CoupledModel, progress=None, compiled: bool = True) -> dict:
    """Run the loop to the end of the scenario; returns {"rec", "wall_s", "compile_s", "stats", ...}.

    ``wall_s`` times the steps only: the compiled loop is compiled (or loaded from the cache)
    first, by a call that runs no step, and that time is ``compile_s``.

    Raises SimulationError with the quantity and the time when the run goes unstable.
    ``compiled`` runs the loop in compiled code, in stretches of n_steps / 20 steps
    (:mod:`frogsim.engine.coupled_loop`); False runs it from Python, one step per iteration (the
    reference the compiled loop is tested against; also the fallback when MuJoCo's C library
    cannot be used). Both make the same calls in the same order: the same run bit for bit.
    """
    mujoco = import_mujoco()
    m, d = cm.mjm, cm.mjd
    lib = mujoco_c(mujoco) if compiled else None
    args = kernel_args(cm) if lib is not None else kernel_loose_args(cm)
    n_steps, every = cm.n_steps, cm.rec_every
    chunk = max(1, n_steps // 20)
    warnings = []            # MuJoCo's own warnings, kept instead of written to MUJOCO_LOG.TXT
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda msg: warnings.append(str(msg).strip()))

    def unstable(k):
        t = k * cm.dt
        said = f" (MuJoCo: {warnings[0]})" if warnings else ""
        return SimulationError(f"scenario {cm.name!r}: unstable at t = {t:.4f} s: "
                               f"{_failure(cm)}{said}; try a smaller robot.timestep "
                               f"(now {cm.dt * 1e3:g} ms)")

    t0 = time.perf_counter()
    if lib is not None:      # compile or load run_steps (and the kernel) by a call of zero steps
        run_steps(lib[0], lib[1], m._address, d._address, 0, 0, n_steps, every, False, False, args)
    compile_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    try:
        if lib is not None:
            # stretches ending at the steps where the Python loop reports progress (k % chunk == 0)
            k = 0
            while k <= n_steps:
                last = k if k % chunk == 0 else (k // chunk + 1) * chunk
                k1 = min(n_steps, last) + 1
                k_end, status = run_steps(lib[0], lib[1], m._address, d._address, k, k1,
                                          n_steps, every, False, False, args)
                if status:
                    raise unstable(k_end)
                if progress is not None and (k1 - 1) % chunk == 0:
                    progress((k1 - 1) / n_steps)
                k = k1
        else:
            step1, step2 = mujoco.mj_step1, mujoco.mj_step2
            kernel = step_kernel_loose
            for k in range(n_steps + 1):
                step1(m, d)
                stepping = 1 if k < n_steps else 0
                row = k // every if k % every == 0 else (-1 if stepping else k // every + 1)
                if kernel(k, stepping, row, *args):
                    raise unstable(k)
                if stepping:
                    step2(m, d)
                if progress is not None and k % chunk == 0:
                    progress(k / n_steps)
    finally:
        mujoco.set_mju_user_warning(previous)
    return run_record(cm, time.perf_counter() - t0, compile_s)


# --- stepping one controller period at a time ----------------------------------------------------
class CoupledStepper:
    """The coupled engine driven from outside, one controller period per :meth:`step`.

    Built once from a robot scenario (the MJCF compiled, the tables allocated); the scenario's
    gait is not used: the valve states and the palms' target are set by each call of
    :meth:`step` and held for ``steps_per_action`` MuJoCo steps (one controller period). A valve
    command acts after the valve's dead time (``valves.charge.dead_time``,
    ``valves.discharge.dead_time``), exactly as a gait's command does; the palms' steering motors
    take their new target at once and move at their travel rate. The pump's pressure band and the
    scenario's other sampled rules run as in :func:`run_coupled`.

    :meth:`reset` restores the MuJoCo state, the model's masses (the palms' added mass changes
    them), the pneumatic state and the kernel's memory as they were after the build, so that
    every episode from a reset is the same run bit for bit. :func:`run_coupled` is not affected
    (this class works on a model of its own).

    Each :meth:`step` runs its steps_per_action MuJoCo steps in one compiled call
    (:func:`frogsim.engine.coupled_loop.run_steps`); ``compiled=False`` runs them from Python
    (the same run bit for bit; the reference the compiled loop is tested against). With one
    MuJoCo step per period the Python loop runs anyway: its direct calls cost less than one
    compiled call's dispatch (a tuple of about 50 arrays to unbox), about 8 us per step less.
    """

    def __init__(self, rs, steps_per_action: int = 10, compiled: bool = True):
        if int(steps_per_action) < 1:
            raise ValueError(f"steps_per_action = {steps_per_action}: must be >= 1")
        mujoco = import_mujoco()
        if any(c.kind != "program" for c in rs.pneumatic.controllers.values()):
            raise ValueError("CoupledStepper sets every valve itself: remove the scenario's closed-loop "
                             "[controllers] (or run it with frogsim.swim)")
        cm = build_coupled(rs)
        a = cm.arrays
        n = len(cm.muscle_names)
        self.cm = cm
        self.n = n
        self.steps_per_action = int(steps_per_action)
        self.dead = CL.per_valve(n, rs.pneumatic.valves.charge.dead_time, rs.pneumatic.valves.discharge.dead_time)
        self.rate = rs.pneumatic.controller.rate
        # no open-loop commands: an empty schedule and no palm commands; the valves start shut
        a["pal_t"], a["pal_target"] = np.zeros(0), np.zeros(0)
        a["sched_t"], a["sched_u"] = np.zeros(0), np.zeros((0, CL.valve_size(n)))
        a["u"][:] = 0.0
        ds, cs = start(0.0, 1e-4, a["y"], a["u"], a["mp"], (a["sched_t"], a["sched_u"], a["laws"],
                                                             a["sc"][S_CTRL_DT]))
        a["ds"], a["cs"] = ds, cs
        a["st"][T_PALM_TARGET] = 0.0
        self._keys = ("st", "y", "u", "ds", "cs", "frac", "frac_new", "vprev", "mot_t", "mot_L",
                      "mot_d", "mot_n", "stats", "tension", "anchors")
        self._saved = {k: a[k].copy() for k in self._keys}
        m = cm.mjm
        self._model_saved = {k: getattr(m, k).copy() for k in
                             ("body_mass", "body_ipos", "body_inertia", "body_subtreemass",
                              "dof_damping")}
        self._d0 = mujoco.MjData(m)
        mujoco.mj_copyData(self._d0, m, cm.mjd)
        self._copy = mujoco.mj_copyData
        self._lib = mujoco_c(mujoco) if compiled else None
        self._step1, self._step2 = mujoco.mj_step1, mujoco.mj_step2
        self.trunk = int(a["sc"][S_TRUNK])
        self.reset()

    # -- state ----------------------------------------------------------------------------------
    def reset(self) -> None:
        """Back to the state after the build: t = 0, valves shut, palms folded, no commands due."""
        cm, a, m = self.cm, self.cm.arrays, self.cm.mjm
        for k in self._keys:
            np.copyto(a[k], self._saved[k])
        for k, v in self._model_saved.items():
            np.copyto(getattr(m, k), v)
        self._copy(cm.mjd, m, self._d0)
        self.k = 0
        self.u_cmd = np.zeros(2 * self.n)      # the valve states last commanded
        self.u_due = np.zeros(2 * self.n)      # the valve states once every due command has acted
        self.pending: list = []                # (time, valve, state) of commands not yet acted
        self.switches = 0                      # valve state changes commanded since the reset
        # MuJoCo's derived quantities (positions, velocities, com) for the restored state and the
        # model's masses as they are now (the build changed them after its forward pass)
        self._step1(m, cm.mjd)
        self._fresh = True

    @property
    def t(self) -> float:
        return self.k * self.cm.dt

    @property
    def period(self) -> float:
        """The controller period: steps_per_action MuJoCo steps [s]."""
        return self.steps_per_action * self.cm.dt

    def step(self, u, palm: float) -> int:
        """Command the valve states ``u`` (charge, discharge per muscle; 1 open, 0 shut) and the
        palms' target (1 open, 0 folded), then run one controller period. ``u`` is an (n, 2) array,
        a row (charge, discharge) per muscle in the order of ``cm.muscle_names``, or the same
        flattened, (2 n,). Returns the number of valve state changes commanded. SimulationError
        (with the quantity and the time) if the run goes unstable; the stepper then needs a
        :meth:`reset`."""
        cm, a = self.cm, self.cm.arrays
        u = np.asarray(u, float)
        if u.shape == (self.n, CL.VALVE_WIDTH):
            u = u.reshape(-1)                    # rows (charge, discharge): the valve vector's order
        if u.shape != (CL.valve_size(self.n),):
            raise ValueError(f"u has shape {u.shape}, expected ({self.n}, 2): (charge, discharge) per muscle, "
                             f"or ({CL.valve_size(self.n)},) flattened")
        t = self.t
        changed = np.nonzero(u != self.u_cmd)[0]
        for j in changed:
            self.pending.append((t + self.dead[j], int(j), float(u[j])))
        self.u_cmd = u.copy()
        self.switches += changed.size
        K = self.steps_per_action
        t_end = (self.k + K) * cm.dt
        self.pending.sort()
        due = [e for e in self.pending if e[0] <= t_end + 1e-12]
        self.pending = self.pending[len(due):]
        a["sched_t"], a["sched_u"] = schedule_from_events(due, self.u_due)
        if due:
            self.u_due = a["sched_u"][-1].copy()
        a["ds"][D_SI] = 0.0
        a["st"][T_PALM_TARGET] = float(palm)
        m, d = cm.mjm, cm.mjd
        if self._lib is not None and K > 1:
            args = kernel_args(cm)
            k_end, status = run_steps(self._lib[0], self._lib[1], m._address, d._address, self.k,
                                      self.k + K, self.k + K + 1, 0, self._fresh, True, args)
            self._fresh = status == 0
            self.k = k_end
            if status:
                raise SimulationError(f"scenario {cm.name!r}: unstable at t = {self.t:.4f} s: "
                                      f"{_failure(cm)}")
            return int(changed.size)
        step1, step2, kernel = self._step1, self._step2, step_kernel_loose
        args = kernel_loose_args(cm)
        for _ in range(K):
            if not self._fresh:
                step1(m, d)
            self._fresh = False
            if kernel(self.k, 1, -1, *args):
                raise SimulationError(f"scenario {cm.name!r}: unstable at t = {self.t:.4f} s: "
                                      f"{_failure(cm)}")
            step2(m, d)
            self.k += 1
        step1(m, d)              # positions and velocities' derived quantities at the new time
        self._fresh = True
        return int(changed.size)

    # -- what a controller can read --------------------------------------------------------------
    def joint_angles(self) -> np.ndarray:
        """Leg joint angles [rad] (order of ``cm.joint_names``)."""
        return self.cm.mjd.qpos[self.cm.arrays["leg_qpos"]].copy()

    def joint_velocities(self) -> np.ndarray:
        return self.cm.mjd.qvel[self.cm.arrays["leg_dof"]].copy()

    def body_velocity(self) -> np.ndarray:
        """(forward, sideways, yaw rate) of the hull: [m/s] along and across its heading, [rad/s]."""
        m, d, tb = self.cm.mjm, self.cm.mjd, self.trunk
        root = m.body_rootid[tb]
        w = d.cvel[tb, :3]
        v = d.cvel[tb, 3:] + np.cross(w, d.xpos[tb] - d.subtree_com[root])
        hx, hy = d.xmat[tb, 0], d.xmat[tb, 3]
        return np.array([v[0] * hx + v[1] * hy, -v[0] * hy + v[1] * hx, w[2]])

    def position(self) -> np.ndarray:
        """Hull centre in the world [m]."""
        return self.cm.mjd.xpos[self.trunk].copy()

    def heading(self) -> float:
        d = self.cm.mjd
        return float(math.atan2(d.xmat[self.trunk, 3], d.xmat[self.trunk, 0]))

    def pressures(self) -> np.ndarray:
        """Muscle pressures [Pa abs]."""
        y = self.cm.arrays["y"]
        return y[CL.pressure_slice(self.n)].copy()

    def source_pressure(self) -> float:
        return float(self.cm.arrays["y"][CL.Y_PS])

    def charged_mass(self) -> float:
        """Air charged into all muscles since the reset [kg]."""
        return float(self.cm.arrays["y"][CL.charged_slice(self.n)].sum())

    def total_air_mass(self) -> float:
        """Air in source, exhaust and muscles [kg] (constant in the closed circuit)."""
        y, n = self.cm.arrays["y"], self.n
        return float(y[CL.Y_MS] + y[CL.Y_ME] + y[CL.mass_slice(n)].sum())

    def palm_opening(self) -> np.ndarray:
        return self.cm.arrays["frac"].copy()
