"""Stable-Baselines3 PPO on a single-drone task through the batched ``VolleySB3VecEnv``, with its
learning curve (the task's metric and the return against env-steps) written as CSV.

    pip install -e ".[sb3]"
    python examples/sb3_ppo_hover.py                                  # Hover, 1M steps: a few minutes on a CPU core
    python examples/sb3_ppo_hover.py --seed 1 --curve outputs/sb3_hover_seed1.csv
    python examples/sb3_ppo_hover.py --task solo_bump --total-timesteps 400000

Hover is the task whose metric moves within minutes: the mean distance to the target falls from
about 3.5 m (random flight, crashing within ~30 steps) to about 1 m in 1M steps (docs/integrations.md
shows the curves of two seeds, ``benchmarks/curves_rise.py``). Solo Bump's bumps take hours.

The callback reads what the env reports when an episode ends: ``infos[i]["final_stats"]`` (the
task's statistics; its metric is ``env.get_attr("metric")[0]``) and ``infos[i]["episode"]`` from
SB3's ``VecMonitor``. The PPO keywords are ``ppo_kwargs`` (docs/integrations.md: 4 minibatches per
rollout keep SB3 at the batched env's pace), with the learning rate and epochs given here.
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecMonitor

from volleybots.integrations import VolleySB3VecEnv
from volleybots.integrations.sb3_env import ppo_kwargs


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--task", default="hover", help="a single-drone task (hover, back_and_forth, hit_the_ball, solo_bump, ...)")
    p.add_argument("--total-timesteps", type=int, default=1_000_000)
    p.add_argument("--num-envs", type=int, default=64, help="worlds stepped together (one SB3 env each)")
    p.add_argument("--n-steps", type=int, default=64, help="steps per world per rollout")
    p.add_argument("--minibatches", type=int, default=4, help="minibatches per rollout")
    p.add_argument("--epochs", type=int, default=10, help="passes over each rollout")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--curve", default=None, help="CSV file for the learning curve (one row per rollout)")
    return p.parse_args(argv)


class Curve(BaseCallback):
    """One row per rollout: env-steps, wall seconds, episodes finished so far, and the mean return and
    task metric of the last 20 finished episodes."""

    def __init__(self, metric: str):
        super().__init__()
        self.metric, self.returns, self.values, self.rows = metric, [], [], []
        self.start = time.time()

    def _on_step(self) -> bool:
        for info in self.locals["infos"]:
            if "final_stats" in info:  # this world's episode just ended
                self.values.append(info["final_stats"][self.metric])
                self.returns.append(info["episode"]["r"])  # VecMonitor's return of the same episode
        return True

    def _on_rollout_end(self) -> None:
        ret, met = (float(np.mean(x[-20:])) if x else float("nan") for x in (self.returns, self.values))
        self.rows.append((self.num_timesteps, time.time() - self.start, len(self.returns), ret, met))
        print(f"{self.num_timesteps:>9,} steps, {self.rows[-1][1]:6.0f} s, {len(self.returns)} episodes: "
              f"mean return of the last 20 {ret:.1f}, {self.metric} {met:.3f}")

    def write(self, path) -> None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        with open(path, "w", newline="") as fh:
            out = csv.writer(fh)
            out.writerow(["steps", "seconds", "episodes", "return", self.metric])
            out.writerows(self.rows)


def main(argv=None) -> list[tuple]:
    """Train; returns the curve's rows."""
    args = parse_args(argv)
    torch.set_num_threads(1)  # small tensors: one thread is the fastest on a shared CPU (docs/integrations.md)
    env = VecMonitor(VolleySB3VecEnv(args.task, num_envs=args.num_envs, seed=args.seed))
    metric = env.get_attr("metric")[0]  # the task's headline statistic, a key of infos[i]["final_stats"]
    kwargs = ppo_kwargs(env.num_envs, n_steps=args.n_steps, minibatches=args.minibatches)
    model = PPO("MlpPolicy", env, seed=args.seed, device="cpu", n_epochs=args.epochs, **kwargs)
    curve = Curve(metric)
    model.learn(total_timesteps=args.total_timesteps, callback=curve)
    if args.curve:
        curve.write(args.curve)
    env.close()
    return curve.rows


if __name__ == "__main__":
    main()
