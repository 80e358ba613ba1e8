"""Reference returns of ``frogsim/Swim-v1``: random, constant, paper-gait, tuned-gait and trained policies.

Run:  python benchmarks/bench_rl.py [--gait DIR/best-gait.toml] [--model ppo-swim.zip] [--seeds 1000 1001 1002]

Policies (each over the registered 2,000 steps, 20 s, from ``reset(seed=s)`` for every seed given)
    ``random``: uniform actions (the action space seeded with the reset seed); the four constant
    policies (every muscle charging or holding, palms open or folded); the paper's 1 s / 1 s gait
    (the shipped ``swim`` scenario's gait, sampled at the 10 ms steps,
    :func:`frogsim.envs.policies.gait_actions`); the tuned gait (``--gait``: the ``best-gait.toml``
    of ``frogsim optimize-gait swim --objective speed``; without it the search is run here with
    50 trials, seed 0, 2 workers, as docs/control.md's gait-search table); and, with
    ``--model``, a PPO policy saved by examples/rl/train_ppo.py, acting deterministically on the
    normalised observation.

What is printed
    A table (markdown) of the mean return, its range over the seeds, the mean distance [m] and
    the reward terms; then the ordering the task is built for: every constant policy below the
    paper's gait, the paper's gait below the tuned one. Exit status 0 when that ordering holds.
    No time is measured: the numbers are returns, the same on any machine for the same seeds.
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--gait", help="best-gait.toml of optimize-gait (else the search is run here)")
    ap.add_argument("--model", help="a PPO model saved by examples/rl/train_ppo.py")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1000, 1001, 1002])
    args = ap.parse_args(argv)
    import gymnasium as gym
    import numpy as np

    import frogsim
    from frogsim.envs.policies import CONSTANT_POLICIES, constant_action, gait_actions, run_episode

    env = gym.make("frogsim/Swim-v1")
    u = env.unwrapped
    steps = env.spec.max_episode_steps
    gait_path = args.gait
    if gait_path is None:
        out = Path(tempfile.mkdtemp(prefix="frogsim-gait-"))
        print(f"running the gait search (50 trials, seed 0, 2 workers) into {out} ...", flush=True)
        subprocess.run([sys.executable, "-m", "frogsim", "optimize-gait", "swim", "--trials", "50",
                        "--objective", "speed", "--seed", "0", "--workers", "2", "--out", str(out)],
                       check=True, stdout=subprocess.DEVNULL)
        gait_path = str(out / "best-gait.toml")

    policies = {}

    def random_policy(obs, k, _space=env.action_space):
        return _space.sample()
    policies["random"] = random_policy
    for name, (m, p) in CONSTANT_POLICIES.items():
        a = constant_action(u.n, m, p)
        policies[name] = lambda obs, k, a=a: a
    for name, source in (("paper gait (1 s / 1 s)", "swim"), ("tuned gait (optimize-gait, speed)", gait_path)):
        acts = gait_actions(frogsim.load_robot_scenario(source), u.muscle_names, u.stepper.period, steps)
        policies[name] = lambda obs, k, acts=acts: acts[k]
    envs = {name: env for name in policies}
    if args.model:
        from stable_baselines3 import PPO
        model = PPO.load(args.model, device="cpu")
        policies["PPO (examples/rl/train_ppo.py)"] = lambda obs, k: model.predict(obs, deterministic=True)[0]
        envs["PPO (examples/rl/train_ppo.py)"] = gym.make("frogsim/Swim-v1", normalize=True)

    results = {}
    print(f"frogsim/Swim-v1, {steps} steps, reset seeds {args.seeds}\n")
    print("| policy | mean return | range | distance [m] | reward_forward | reward_air |")
    print("|---|---|---|---|---|---|")
    for name, policy in policies.items():
        runs = []
        for seed in args.seeds:
            envs[name].action_space.seed(seed)
            runs.append(run_episode(envs[name], policy, seed=seed))
        ret = np.array([r["return"] for r in runs])
        results[name] = ret.mean()
        fwd = np.mean([r["terms"].get("reward_forward", 0.0) for r in runs])
        air = np.mean([r["terms"].get("reward_air", 0.0) for r in runs])
        dist = np.mean([r["distance_m"] for r in runs])
        print(f"| {name} | {ret.mean():.1f} | {ret.min():.1f} .. {ret.max():.1f} | {dist:.2f} | {fwd:.1f} | {air:.1f} |",
              flush=True)
    paper = results["paper gait (1 s / 1 s)"]
    tuned = results["tuned gait (optimize-gait, speed)"]
    best_constant = max(results[k] for k in CONSTANT_POLICIES)
    ok = best_constant < paper < tuned
    print(f"\nbest constant {best_constant:.1f} < paper gait {paper:.1f} < tuned gait {tuned:.1f}: "
          f"{'HOLDS' if ok else 'DOES NOT HOLD'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
