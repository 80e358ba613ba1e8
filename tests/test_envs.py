"""Step interfaces and Gymnasium environments: check_env for every registered env, determinism
under a seed, air conservation in stepped episodes, and the steppers reproducing the open-loop
engines when fed the same commands."""
from __future__ import annotations

import numpy as np
import pytest

import frogsim
from frogsim.circuit import layout as CL
from frogsim.scenario.motion import command_time
from frogsim.scenario.schema import VALVE_STATES

import gymnasium as gym  # noqa: E402  (a dependency of frogsim, never skipped)
from gymnasium.utils.env_checker import check_env  # noqa: E402

from frogsim.envs import ENVS  # noqa: E402
from frogsim.envs.plant import PneumaticPlant  # noqa: E402

V0 = sorted(e for e in ENVS if e.endswith("-v0"))         # the v1 environments: tests/test_envs_v1.py
SHORT = {"frogsim/HipPressure-v0": dict(duration=0.05), "frogsim/Swim-v0": dict(duration=0.2)}
ACTION = {"vent": 0, "hold": 1, "charge": 2}


def _programmed(steps_list, t, rate):
    """The state each program commands at time t (commands issued at controller samples)."""
    out = []
    for steps in steps_list:
        s = "hold"
        for ts, st in steps:
            if command_time(ts, rate) <= t + 1e-12:
                s = st
        out.append(s)
    return out


def test_every_env_is_registered_on_import():
    assert set(ENVS) <= set(gym.envs.registration.registry)


@pytest.mark.parametrize("env_id", V0)
def test_check_env(env_id):
    env = gym.make(env_id, **SHORT[env_id])
    check_env(env.unwrapped, skip_render_check=True)
    assert isinstance(env.action_space, gym.spaces.MultiDiscrete)


@pytest.mark.parametrize("env_id", V0)
def test_episodes_are_deterministic_under_a_seed(env_id):
    kw = dict(SHORT[env_id], noise_std=0.05)
    env = gym.make(env_id, **kw)

    def episode(seed):
        obs, _ = env.reset(seed=seed)
        env.action_space.seed(seed)
        rows, rewards, done = [obs], [], False
        while not done:
            obs, r, term, trunc, _ = env.step(env.action_space.sample())
            rows.append(obs)
            rewards.append(r)
            done = term or trunc
        return np.array(rows), np.array(rewards)

    a, ra = episode(3)
    b, rb = episode(3)
    c, _ = episode(4)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(ra, rb)
    assert not np.array_equal(a, c)          # the seed matters (noise, random actions)


def test_plant_reproduces_simulate_and_conserves_air():
    """The paper's cycle, commanded sample by sample through the step API, ends where
    frogsim.simulate ends, and no air is made or lost."""
    sc = frogsim.load_scenario("paper-cycle").replace({"duration": 1.2})
    res = frogsim.simulate(sc)
    plant = PneumaticPlant(sc)
    rate = sc.controller.rate
    progs = [sc.muscles[n].program.steps for n in plant.model.names]
    air0 = plant.total_air_mass()
    for k in range(int(round(sc.duration * rate))):
        plant.step([ACTION[s] for s in _programmed(progs, k / rate, rate)])
    n = plant.n
    want = res.y[-1, [CL.pressure_index(i) for i in range(n)] + [CL.Y_PS, CL.Y_PE]]
    obs = plant.observe()
    assert obs[-1] == pytest.approx(1.2)
    np.testing.assert_allclose(obs[:-1], want, rtol=1e-6)
    assert abs(plant.total_air_mass() / air0 - 1) < 1e-10
    assert plant.charged_mass() > 0


def test_plant_dead_time_and_switch_count():
    sc = frogsim.load_scenario("paper-cycle")
    plant = PneumaticPlant(sc, control_period=1e-3)
    p0 = plant.pressures()[0]
    plant.step([2] * plant.n)                  # charge: acts 2 ms later
    assert plant.switches == plant.n
    plant.step([2] * plant.n)
    assert plant.pressures()[0] == pytest.approx(p0, rel=1e-9)   # still the dead time
    for _ in range(5):
        plant.step([2] * plant.n)
    assert plant.pressures()[0] > p0 + 1e3
    plant.step([0] * plant.n)                  # charge -> vent: two valves each
    assert plant.switches == 3 * plant.n
    with pytest.raises(ValueError):
        plant.step([3] * plant.n)
    with pytest.raises(ValueError):
        PneumaticPlant(sc, control_period=1.5e-3)


def test_hip_env_tracks_a_setpoint_with_bang_bang():
    env = gym.make("frogsim/HipPressure-v0", duration=0.4, setpoint=2.0, switch_price=0.0)
    obs, info = env.reset(seed=0)
    assert info["setpoint_bar_gauge"] == 2.0
    done, errs = False, []
    while not done:
        obs, r, term, trunc, info = env.step([2] if obs[0] < 2.0 else [1])
        errs.append(info["error_bar"])
        done = term or trunc
    assert abs(errs[-1]) < 0.3                 # settled near the setpoint
    assert r == pytest.approx(-abs(errs[-1]))


def test_coupled_stepper_reproduces_run_coupled():
    """The swim gait fed through CoupledStepper.step (one MuJoCo step per period) is the
    open-loop run; reset gives the same run again; the air in the circuit is conserved."""
    from frogsim.control.gait import palm_commands
    from frogsim.engine.coupled import R_X, CoupledStepper, build_coupled, run_coupled
    rs = frogsim.load_robot_scenario("swim", cycles=1)
    cm = build_coupled(rs)
    rec = run_coupled(cm)["rec"]
    st = CoupledStepper(rs, steps_per_action=1)
    rate = rs.pneumatic.controller.rate
    progs = [rs.pneumatic.muscles[n].program.steps for n in cm.muscle_names]
    pal_t, pal_v = palm_commands(rs.gait, rate)

    def run(n_steps):
        for k in range(n_steps):
            t = k * cm.dt
            u = [v for s in _programmed(progs, t, rate) for v in VALVE_STATES[s]]
            palm = pal_v[pal_t <= t + 1e-12][-1] if (pal_t <= t + 1e-12).any() else 0.0
            st.step(np.array(u, float), palm)
        return st.position()

    air0 = st.total_air_mass()
    end = run(cm.n_steps)
    np.testing.assert_allclose(end, rec[-1, R_X:R_X + 3], rtol=1e-9, atol=1e-12)
    assert abs(st.total_air_mass() / air0 - 1) < 1e-10
    st.reset()
    assert st.t == 0 and st.charged_mass() == 0
    first = run(300)
    st.reset()
    np.testing.assert_array_equal(run(300), first)


def test_swim_env_episode_conserves_air_and_pays_for_it():
    env = gym.make("frogsim/Swim-v0", duration=1.2, air_price=0.1)
    env.reset(seed=0)
    stepper = env.unwrapped.stepper
    air0 = stepper.total_air_mass()
    done, total_air, total_prog, total_r = False, 0.0, 0.0, 0.0
    k = 0
    while not done:
        a = [2] * env.unwrapped.n + [1] if k < 60 else [0] * env.unwrapped.n + [0]
        _, r, term, trunc, info = env.step(a)
        total_air += info["air_L_std"]
        total_prog += info["progress_m"]
        total_r += r
        done = term or trunc
        k += 1
    assert not term and k == 120
    assert total_air > 0.5 and total_prog > 0.05
    assert total_r == pytest.approx(total_prog - 0.1 * total_air)
    assert abs(stepper.total_air_mass() / air0 - 1) < 1e-10


# --- every bad argument, option and action is refused with a clear ValueError -----------------------
#: argument -> values that are not allowed (NaN, infinities, negatives, wrong types)
NOT_A_NUMBER = [float("nan"), float("inf"), float("-inf"), "1", True, 1 + 0j, None, [1.0]]
BAD_ARGS = {
    "frogsim/HipPressure-v0": {
        "duration": NOT_A_NUMBER + [-1, 0, 0.0005, 2e6],     # 0.0005 s: less than the 1 ms period
        "control_period": [float("nan"), float("inf"), -1e-3, 0, "1 ms", True, 1j],
        "switch_price": NOT_A_NUMBER + [-0.01],
        "noise_std": NOT_A_NUMBER + [-0.1],
        "setpoint": [float("nan"), float("inf"), -1.0, 101.0, "2 bar", True, 2j],
        "setpoint_range": [(float("nan"), 2.0), (1.0, float("inf")), (-1.0, 2.0), (3.0, 2.0), (1.0,),
                           "1-5", (True, 2.0), (1.0, 2j)],
    },
    "frogsim/Swim-v0": {
        "duration": NOT_A_NUMBER + [-1, 0, 0.005, 2e6],       # 0.005 s: less than the 10 ms period
        "steps_per_action": [float("nan"), 0, -1, 1.5, 10.0, "10", True, 10j, None, 10**9],
        "air_price": NOT_A_NUMBER + [-0.05],
        "noise_std": NOT_A_NUMBER + [-0.1],
    },
}
BAD_CASES = [(env_id, arg, v) for env_id, args in BAD_ARGS.items() for arg, vals in args.items() for v in vals]


@pytest.mark.parametrize("env_id,arg,value", BAD_CASES, ids=[f"{e[8:]}-{a}-{v!r}" for e, a, v in BAD_CASES])
def test_every_bad_constructor_argument_raises_a_value_error_naming_it(env_id, arg, value):
    with pytest.raises(ValueError) as err:
        gym.make(env_id, **{arg: value})
    msg = str(err.value)
    assert msg.startswith(arg) and "\n" not in msg
    assert any(w in msg for w in ("must", "expected"))


@pytest.fixture(scope="module")
def made():
    envs = {env_id: gym.make(env_id, **SHORT[env_id]).unwrapped for env_id in V0}
    yield envs
    for env in envs.values():
        env.close()


@pytest.mark.parametrize("value", [float("nan"), float("inf"), -0.5, 100.5, "2", True, 2j, None])
def test_every_bad_setpoint_option_raises(made, value):
    env = made["frogsim/HipPressure-v0"]
    with pytest.raises(ValueError, match=r"^options\['setpoint'\] = .*must|^options\['setpoint'\] = .*expected"):
        env.reset(options={"setpoint": value})


@pytest.mark.parametrize("env_id,opts", [("frogsim/HipPressure-v0", {"setpont": 2.0}),
                                         ("frogsim/HipPressure-v0", [("setpoint", 2.0)]),
                                         ("frogsim/Swim-v0", {"setpoint": 2.0})])
def test_unknown_reset_options_raise(made, env_id, opts):
    with pytest.raises(ValueError, match="options"):
        made[env_id].reset(options=opts)


def _outside(space):
    """Actions outside a MultiDiscrete space: each entry one past its range or below 0, floats
    (even whole ones), bools, complex numbers, the wrong length, the wrong shape, text, None."""
    n = space.shape[0]
    good = [0] * n
    out = []
    for j, k in enumerate(space.nvec):
        out += [good[:j] + [int(k)] + good[j + 1:], good[:j] + [-1] + good[j + 1:],
                good[:j] + [1.7] + good[j + 1:], good[:j] + [True] + good[j + 1:],
                good[:j] + [1 + 0j] + good[j + 1:]]
    out += [np.zeros(n, float), np.zeros(n, bool), np.zeros(n, complex), good[:-1], good + [0],
            np.zeros((1, n), int), "0" * n, None, 1]
    return out


@pytest.mark.parametrize("env_id", V0)
def test_every_action_outside_the_space_raises(made, env_id):
    env = made[env_id]
    env.reset(seed=0)
    bad = _outside(env.action_space)
    assert len(bad) > 10
    for a in bad:
        with pytest.raises(ValueError, match="^action = .*action space"):
            env.step(a)
    env.step(np.zeros(env.action_space.shape, np.int64))       # the refusals changed nothing
    assert env.steps == 1


@pytest.mark.parametrize("env_id", V0)
def test_stepping_before_reset_or_after_the_episode_ended_raises(env_id):
    from gymnasium.error import ResetNeeded
    env = gym.make(env_id, **SHORT[env_id]).unwrapped
    hold = np.ones(env.action_space.shape, np.int64)
    with pytest.raises(ResetNeeded, match="reset"):
        env.step(hold)
    env.reset(seed=0)
    k, done = 0, False
    while not done:
        _, _, term, trunc, _ = env.step(hold)
        done = term or trunc
        k += 1
    assert trunc and k == env.max_steps
    with pytest.raises(ResetNeeded, match="ended"):
        env.step(hold)
    env.reset(seed=0)
    env.step(hold)                              # a reset starts another episode


@pytest.mark.parametrize("env_id", V0)
def test_stepping_or_resetting_after_close_raises(env_id):
    from gymnasium.error import ClosedEnvironmentError
    env = gym.make(env_id, **SHORT[env_id]).unwrapped
    hold = np.ones(env.action_space.shape, np.int64)
    env.reset(seed=0)
    env.step(hold)
    env.close()
    env.close()                                 # twice is allowed, as gymnasium asks
    with pytest.raises(ClosedEnvironmentError, match=r"step\(\) after close\(\)"):
        env.step(hold)
    with pytest.raises(ClosedEnvironmentError, match=r"reset\(\) after close\(\)"):
        env.reset(seed=0)
    # through gymnasium.make's wrappers too
    wrapped = gym.make(env_id, **SHORT[env_id])
    wrapped.reset(seed=0)
    wrapped.close()
    with pytest.raises(ClosedEnvironmentError):
        wrapped.step(hold)
