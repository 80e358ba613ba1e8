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

gym = pytest.importorskip("gymnasium")
from gymnasium.utils.env_checker import check_env  # noqa: E402

from frogsim.envs import ENVS  # noqa: E402
from frogsim.envs.plant import PneumaticPlant  # noqa: E402

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


@pytest.mark.parametrize("env_id", sorted(ENVS))
def test_check_env(env_id):
    env = gym.make(env_id, **SHORT[env_id])
    check_env(env.unwrapped, skip_render_check=True)
    assert isinstance(env.action_space, gym.spaces.MultiDiscrete)


@pytest.mark.parametrize("env_id", sorted(ENVS))
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
