"""Train stable-baselines3's PPO on a frogsim environment and report the trained policy's return.

Run:  python examples/rl/train_ppo.py [--env frogsim/Swim-v1] [--timesteps 200000] [--n-envs 1]
                                      [--seed 0] [--out ppo-swim.zip]

Needs the optional extra ``rl`` (``python3 -m pip install -e ".[rl]"``: stable-baselines3 and a
CPU build of PyTorch). Trains PPO with its default hyperparameters (an MLP policy over the
``MultiDiscrete`` action), the observation normalised by the environment (``normalize=True``),
saves the model to ``--out`` and prints the return of one deterministic episode from
``reset(seed=1000)``, the start benchmarks/bench_rl.py scores every policy from.

Vector environments: ``--n-envs N`` steps N copies in this process (``DummyVecEnv``), which
multiplies the samples per update, not the speed. A ``SubprocVecEnv`` pays a pickle and a pipe
round trip per step that costs more than a 10 ms step of ``Swim-v1`` (benchmarks/bench_envs.py
measures both): use it only with as many free cores as processes.
"""
from __future__ import annotations

import argparse
import sys
import time


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--env", default="frogsim/Swim-v1")
    ap.add_argument("--timesteps", type=int, default=200_000, help="environment steps to train on")
    ap.add_argument("--n-envs", type=int, default=1, help="copies stepped in this process")
    ap.add_argument("--n-steps", type=int, default=2048, help="PPO's steps per copy and update")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="ppo-swim.zip", help="where the model is saved")
    args = ap.parse_args(argv)
    for name in ("timesteps", "n_envs", "n_steps"):
        if getattr(args, name) < 1:
            print(f"--{name.replace('_', '-')} = {getattr(args, name)}: must be a whole number >= 1", file=sys.stderr)
            return 2
    try:
        import torch
        from stable_baselines3 import PPO
        from stable_baselines3.common.env_util import make_vec_env
    except ImportError as exc:
        print(f"this example needs the extra 'rl' (pip install -e \".[rl]\"): {exc}", file=sys.stderr)
        return 2
    import gymnasium as gym

    import frogsim  # noqa: F401  (registers the environments)

    torch.set_num_threads(1)
    vec = make_vec_env(args.env, n_envs=args.n_envs, seed=args.seed, env_kwargs={"normalize": True})
    model = PPO("MlpPolicy", vec, n_steps=args.n_steps, batch_size=min(64, args.n_steps * args.n_envs),
                seed=args.seed, device="cpu", verbose=0)
    t0 = time.perf_counter()
    model.learn(total_timesteps=args.timesteps)
    wall = time.perf_counter() - t0
    model.save(args.out)
    env = gym.make(args.env, normalize=True)
    obs, _ = env.reset(seed=1000)
    total, done, steps = 0.0, False, 0
    while not done:
        action, _ = model.predict(obs, deterministic=True)
        obs, r, term, trunc, info = env.step(action)
        total += r
        steps += 1
        done = term or trunc
    print(f"{args.env}: trained {args.timesteps} steps in {wall:.0f} s; deterministic return from "
          f"reset(seed=1000): {total:.1f} over {steps} steps; model saved to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
