"""The v1 environments: Gymnasium's and stable-baselines3's checkers, registration, seeded starts
(also through a vector env), the valves observed, bounds that hold, the reward terms, the
constant policies against the paper's gait, offscreen rendering, and the PPO example."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import frogsim
from frogsim.envs.policies import CONSTANT_POLICIES, constant_action, gait_actions, run_episode

ROOT = Path(__file__).resolve().parents[1]
V1 = ("frogsim/HipPressure-v1", "frogsim/Swim-v1")
SHORT = {"frogsim/HipPressure-v1": 50, "frogsim/Swim-v1": 30}      # max_episode_steps for quick tests


def _make(env_id, **kw):
    return gym.make(env_id, max_episode_steps=SHORT[env_id], **kw)


def test_registration_as_gymnasium_envs():
    swim = gym.spec("frogsim/Swim-v1")
    assert swim.max_episode_steps == 2000            # 20 s of 10 ms steps
    assert swim.reward_threshold is not None and swim.reward_threshold > 0
    assert gym.spec("frogsim/HipPressure-v1").max_episode_steps == 500      # 0.5 s of 1 ms
    env = gym.make("frogsim/Swim-v1")
    assert env.unwrapped.stepper.period * swim.max_episode_steps == pytest.approx(20.0)
    assert env.metadata["render_modes"] == ["rgb_array"]


@pytest.mark.parametrize("env_id", V1)
@pytest.mark.parametrize("normalize", [False, True])
def test_check_env(env_id, normalize):
    check_env(_make(env_id, normalize=normalize).unwrapped, skip_render_check=True)


@pytest.mark.parametrize("env_id", V1)
def test_stable_baselines3_check_env(env_id):
    from stable_baselines3.common.env_checker import check_env as sb3_check
    import warnings
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sb3_check(_make(env_id, normalize=True).unwrapped, warn=True)
    # SB3 warns about what would make learning harder (unbounded or unnormalised boxes, ...)
    assert not [w for w in caught if "stable_baselines3" in str(w.filename)], [str(w.message) for w in caught]


def _episode(env, seed, actions_seed=0):
    obs, info = env.reset(seed=seed)
    env.action_space.seed(actions_seed)
    rows, done = [obs], False
    while not done:
        obs, r, term, trunc, _ = env.step(env.action_space.sample())
        rows.append(np.append(obs, r))
        done = term or trunc
    return rows[0], np.array(rows[1:]), info


@pytest.mark.parametrize("env_id", V1)
def test_the_seed_sets_the_start(env_id):
    """Same seed and actions: the same episode; another seed: another start and episode. With
    reset_noise_scale = 0 and a fixed setpoint the seed no longer matters."""
    env = _make(env_id)
    a0, a, ia = _episode(env, 3)
    b0, b, _ = _episode(env, 3)
    c0, c, ic = _episode(env, 4)
    np.testing.assert_array_equal(a0, b0)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a0, c0) and not np.array_equal(a, c)
    assert ia["start_source_bar_gauge"] != ic["start_source_bar_gauge"]
    kw = {"setpoint": 2.0} if "Hip" in env_id else {}
    quiet = _make(env_id, reset_noise_scale=0.0, **kw)
    q3, x3, _ = _episode(quiet, 3)
    q4, x4, _ = _episode(quiet, 4)
    np.testing.assert_array_equal(q3, q4)
    np.testing.assert_array_equal(x3, x4)


def test_the_start_noise_stays_within_its_documented_ranges():
    s = 0.05
    env = _make("frogsim/Swim-v1", reset_noise_scale=s)
    u = env.unwrapped
    for seed in range(5):
        _, info = env.reset(seed=seed)
        q = info["start_joint_angles_rad"]
        assert np.all(q >= u.stop_low) and np.all(q <= u.stop_low + s)       # the robot starts at its flexed stops
        assert np.all(np.abs(info["start_joint_velocities_rad_s"]) <= s)
        p = info["start_muscle_pressures_bar_gauge"]
        assert np.all((p >= 0) & (p <= s))
        np.testing.assert_allclose(u.stepper.pressures(), u.patm + p * 1e5)
        assert 6.0 * (1 - s) <= info["start_source_bar_gauge"] <= 6.0 * (1 + s)   # the paper's 6 bar source


def test_seeds_reach_every_copy_of_a_vector_env():
    envs = gym.vector.SyncVectorEnv([lambda: _make("frogsim/Swim-v1") for _ in range(2)])
    o12, _ = envs.reset(seed=[1, 2])
    assert not np.array_equal(o12[0], o12[1])
    o11, _ = envs.reset(seed=[1, 1])
    np.testing.assert_array_equal(o11[0], o11[1])
    np.testing.assert_array_equal(o11[0], o12[0])
    single, _ = _make("frogsim/Swim-v1").reset(seed=2)
    np.testing.assert_array_equal(o12[1], single)
    envs.close()


def test_hip_v1_observes_a_command_inside_the_dead_time():
    """The issue's case: after "vent" and after "charge" v0 observes the same; v1 sees the
    command pending (2 ms dead time, 1 ms steps) and the valve acting one step later."""
    env = gym.make("frogsim/HipPressure-v1", setpoint=2.0, reset_noise_scale=0.0).unwrapped
    n = env.plant.n
    now, cmd = slice(n + 3, 3 * n + 3), slice(3 * n + 3, 5 * n + 3)
    env.reset(seed=0)
    o_vent, *_ = env.step([0])
    env.reset(seed=0)
    o_charge, *_ = env.step([2])
    np.testing.assert_array_equal(o_charge[now], [0, 0])           # still shut: inside the dead time
    np.testing.assert_array_equal(o_charge[cmd], [1, 0])           # charge valve commanded open
    np.testing.assert_array_equal(o_vent[cmd], [0, 1])
    assert not np.array_equal(o_vent, o_charge)
    o, *_ = env.step([1])                                          # hold: the charge acts now
    np.testing.assert_array_equal(o[now], [1, 0])
    np.testing.assert_array_equal(o[cmd], [0, 0])


def test_swim_v1_observes_valves_palms_heading_and_phase():
    env = gym.make("frogsim/Swim-v1", reset_noise_scale=0.0, steps_per_action=1).unwrapped
    names = env.obs_names
    col = {nm: j for j, nm in enumerate(names)}
    n = env.n
    env.reset(seed=0)
    o, *_ = env.step(np.array([2] * n + [1]))
    # 1 ms steps, 2 ms dead time: commanded but not yet open
    assert o[col["charge valve hip_left open now [0/1]"]] == 0
    assert o[col["charge valve hip_left open commanded [0/1]"]] == 1
    assert o[col["palms target [0/1]"]] == 1
    o, *_ = env.step(np.array([2] * n + [1]))
    assert o[col["charge valve hip_left open now [0/1]"]] == 1
    for _ in range(500):                                           # 0.5 s more: palms open
        o, *_ = env.step(np.array([2] * n + [1]))
    assert o[col["palm left opening [0-1]"]] == pytest.approx(1.0)
    t = env.stepper.t
    assert o[col["gait phase sin [-]"]] == pytest.approx(np.sin(2 * np.pi * t / 2.0), abs=1e-6)
    assert o[col["heading sin [-]"]] ** 2 + o[col["heading cos [-]"]] ** 2 == pytest.approx(1.0, abs=1e-6)


def _within(space, rows):
    rows = np.atleast_2d(rows)
    return np.all(rows >= space.low) and np.all(rows <= space.high)


def test_bounds_are_physical_and_hold_over_an_episode():
    """The paper's gait for 4 s and random actions: every observation inside the bounds, the
    pressures within vacuum .. the source's highest pressure, the angles within the stops."""
    env = gym.make("frogsim/Swim-v1", max_episode_steps=400)
    u = env.unwrapped
    sp = env.observation_space
    names = u.obs_names
    p = [j for j, nm in enumerate(names) if nm.startswith("pressure")]
    assert np.all(sp.low[p] == pytest.approx(-1.01325))             # vacuum [bar gauge]
    assert np.all(sp.high[p] == pytest.approx(6.0 * 1.05 + 0.5))     # the 6 bar source, + 5 % noise + margin
    acts = gait_actions(frogsim.load_robot_scenario("swim"), u.muscle_names, u.stepper.period, 400)
    obs, _ = env.reset(seed=0)
    rows, done, k = [obs], False, 0
    while not done:
        obs, _, term, trunc, _ = env.step(acts[k])
        rows.append(obs)
        k += 1
        done = term or trunc
    rows = np.array(rows)
    assert _within(sp, rows)
    assert rows[:, p].max() <= 6.0 * 1.05 + 1e-6                      # no muscle above the source's start
    _, random_rows, _ = _episode(env, 1)
    assert _within(sp, random_rows[:, :-1])
    normed = gym.make("frogsim/Swim-v1", normalize=True).unwrapped
    normed.reset(seed=0)
    off, sc = normed.obs_offset, normed.obs_scale
    np.testing.assert_allclose(normed.observation_space.low, ((sp.low - off) / sc).astype(np.float32))
    ang = [j for j, nm in enumerate(names) if nm.startswith("angle")]
    np.testing.assert_allclose((u.stop_low - off[ang]) / sc[ang], -1.0)     # the stops map to -1, +1
    np.testing.assert_allclose((u.stop_high - off[ang]) / sc[ang], 1.0)


def test_reward_terms_sum_to_the_reward_and_mean_what_they_say():
    env = gym.make("frogsim/Swim-v1", max_episode_steps=150, air_cost_weight=0.1)
    u = env.unwrapped
    env.reset(seed=0)
    dist = 0.0
    for k in range(150):
        _, r, _, _, info = env.step(np.array([2] * u.n + [1]))
        assert r == pytest.approx(info["reward_forward"] + info["reward_air"])
        assert info["reward_forward"] == pytest.approx(info["x_velocity"])       # weight 1
        assert info["reward_air"] == pytest.approx(-0.1 * info["air_L_std"] / 0.01)
        dist += info["x_velocity"] * 0.01
    assert dist == pytest.approx(info["distance_m"])
    assert dist > 0.5                                                # one stroke from 6 bar: about 1 m/s


def test_constant_policies_score_below_the_paper_gait():
    """Every constant policy (all muscles charging or holding, palms open or folded) returns less
    over the 20 s episode than the paper's 1 s / 1 s gait: one stroke and a glide do not pay."""
    env = gym.make("frogsim/Swim-v1")
    u = env.unwrapped
    acts = gait_actions(frogsim.load_robot_scenario("swim"), u.muscle_names, u.stepper.period, 2000)
    paper = run_episode(env, lambda o, k: acts[k], seed=0)
    assert paper["steps"] == 2000 and not paper["terminated"]
    for name, (m, p) in CONSTANT_POLICIES.items():
        a = constant_action(u.n, m, p)
        got = run_episode(env, lambda o, k: a, seed=0)
        assert got["return"] < 0.9 * paper["return"], (name, got["return"], paper["return"])


RENDER = """
import sys, numpy as np, gymnasium as gym, frogsim
env = gym.make("frogsim/Swim-v1", render_mode="rgb_array", width=160, height=120)
env.reset(seed=0)
a = env.render()
for _ in range(60):
    env.step(np.array([2] * env.unwrapped.n + [1]))
b = env.render()
np.save(sys.argv[1], np.stack([a, b]))
"""


def test_rgb_array_rendering_offscreen(tmp_path):
    """Drawn in a child process with MUJOCO_GL set (MuJoCo reads it at import): EGL, else OSMesa."""
    out = tmp_path / "frames.npy"
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    errors = []
    for backend in ("egl", "osmesa"):
        env["MUJOCO_GL"] = backend
        p = subprocess.run([sys.executable, "-c", RENDER, str(out)], env=env, capture_output=True, text=True,
                           timeout=600)
        if p.returncode == 0:
            break
        errors.append(f"{backend}: {p.stderr.strip().splitlines()[-1:]}")
    assert out.exists(), errors
    a, b = np.load(out)
    assert a.shape == (120, 160, 3) and a.dtype == np.uint8
    assert a.std() > 5                                   # a scene, not a blank frame
    assert np.abs(a.astype(int) - b).mean() > 1          # the legs moved and the muscles changed colour


def test_render_without_a_mode_and_bad_render_arguments():
    env = _make("frogsim/Swim-v1").unwrapped
    env.reset(seed=0)
    assert env.render() is None
    for kw in ({"render_mode": "ansi"}, {"width": 8}, {"camera": "side"}, {"normalize": 1},
               {"reset_noise_scale": -0.1}, {"reset_noise_scale": 0.6}, {"phase_period": 0},
               {"air_cost_weight": float("nan")}, {"forward_reward_weight": -1}):
        with pytest.raises(ValueError) as err:
            gym.make("frogsim/Swim-v1", **kw)
        assert str(err.value).startswith(next(iter(kw)))
    for kw in ({"reset_noise_scale": float("inf")}, {"normalize": "yes"}):
        with pytest.raises(ValueError, match=f"^{next(iter(kw))}"):
            gym.make("frogsim/HipPressure-v1", **kw)


def test_ppo_example_trains_on_a_tiny_budget(tmp_path):
    """The example runs (256 steps, not to learn: the docs give the budget of a real run)."""
    model = tmp_path / "ppo.zip"
    p = subprocess.run([sys.executable, "examples/rl/train_ppo.py", "--timesteps", "256", "--n-steps", "128",
                        "--out", str(model)], cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT / "src")),
                       capture_output=True, text=True, timeout=900)
    assert p.returncode == 0, p.stderr
    assert model.exists() and "deterministic return" in p.stdout
    bad = subprocess.run([sys.executable, "examples/rl/train_ppo.py", "--timesteps", "0"], cwd=ROOT,
                         env=dict(os.environ, PYTHONPATH=str(ROOT / "src")), capture_output=True, text=True)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "--timesteps = 0" in bad.stderr


@pytest.mark.parametrize("env_id", V1)
def test_a_pickled_env_gives_the_same_episodes(env_id):
    import pickle
    env = _make(env_id)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    copy = pickle.loads(pickle.dumps(env))
    a0, a, _ = _episode(env, 7)
    b0, b, _ = _episode(copy, 7)
    np.testing.assert_array_equal(a0, b0)
    np.testing.assert_array_equal(a, b)


def test_the_pages_paper_gait_return_is_the_codes():
    """docs/control.md's reference return of the paper's gait (benchmarks/bench_rl.py's seeds) is
    what the environment gives, at the page's precision, and reaches the registered threshold."""
    import re
    text = (ROOT / "docs" / "control.md").read_text()
    row = re.search(r"^\| paper gait \(1 s / 1 s\) \| ([\d.]+) \|", text, re.M)
    assert row, "the reference table has no paper-gait row"
    env = gym.make("frogsim/Swim-v1")
    u = env.unwrapped
    acts = gait_actions(frogsim.load_robot_scenario("swim"), u.muscle_names, u.stepper.period, 2000)
    mean = np.mean([run_episode(env, lambda o, k: acts[k], seed=s)["return"] for s in (1000, 1001, 1002)])
    assert f"{mean:.1f}" == row.group(1)
    assert mean >= gym.spec("frogsim/Swim-v1").reward_threshold
