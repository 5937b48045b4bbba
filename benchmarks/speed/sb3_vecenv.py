"""Stable-Baselines3 PPO through ``VolleySB3VecEnv`` against the env's own batched steps/s.

Three rates on one task and world count, each the median of ``repeats=``:

- ``env``: the batched TorchRL env alone, random actions (``volleybots.bench.measure``);
- ``adapter``: ``VolleySB3VecEnv.step`` with random actions (the adapter's numpy and info cost);
- ``sb3 collect`` and ``sb3 learn``: SB3 PPO's env-steps per second of rollout collection (policy
  forward, the adapter's step, the rollout buffer) and of the whole ``learn`` (collection and the
  gradient updates), timed with SB3's rollout callbacks, with ``batch_size=`` minibatches and SB3's
  default optimiser;
- ``sb3 learn, recommended``: the same with ``volleybots.integrations.sb3_env.ppo_kwargs`` (the
  rollout in ``minibatches=`` minibatches, Adam's foreach update), what docs/integrations.md advises;
- ``dummy=N``: for comparison, SB3's ``DummyVecEnv`` over N single ``gym.make`` envs (each world a
  torch step of its own), collection only.

Each rate is given per second of wall time and per second of the process's CPU time (one torch
thread): on a shared machine the second is the steadier, the three are measured in turn each repeat.

    OMP_NUM_THREADS=1 python benchmarks/speed/sb3_vecenv.py                     # solo_bump, 64 worlds
    OMP_NUM_THREADS=1 python benchmarks/speed/sb3_vecenv.py num_envs=256 dummy=8 json=out.json

Needs ``pip install 'volleybots[sb3]'``. Quote the machine load (``uptime``) beside the figures.
"""

from __future__ import annotations

import dataclasses
import os
import statistics
import time
from dataclasses import dataclass
from typing import Optional

from volleybots.config.args import option, script_options
from volleybots.files import write_json


def sb3_rates(make_env, args, learn: bool, ppo: dict | None = None) -> dict:
    """SB3 PPO's collection (and with ``learn`` whole-run) env-steps/s on ``make_env()``, with the
    PPO keywords ``ppo`` (default: ``n_steps=`` and ``batch_size=``, SB3's optimiser)."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback

    class Clock(BaseCallback):
        def __init__(self):
            super().__init__()
            self.collect_s = self.collect_cpu_s = self.t0 = self.c0 = 0.0

        def _on_rollout_start(self):
            self.t0, self.c0 = time.perf_counter(), time.process_time()

        def _on_rollout_end(self):
            self.collect_s += time.perf_counter() - self.t0
            self.collect_cpu_s += time.process_time() - self.c0

        def _on_step(self):
            return True

    env = make_env()
    n = env.num_envs
    rollout = args.n_steps * n
    ppo = ppo or {"n_steps": args.n_steps, "batch_size": min(args.batch_size, rollout)}
    model = PPO("MlpPolicy", env, seed=args.seed, device="cpu", n_epochs=args.n_epochs, **ppo)
    total = rollout * args.rollouts
    clock = Clock()
    start, cpu_start = time.perf_counter(), time.process_time()
    if learn:
        model.learn(total, callback=clock)
    else:  # collection only: one rollout per repeat, no update
        model._setup_learn(total, callback=None)
        cb = model._init_callback(clock)
        for _ in range(args.rollouts):
            model.collect_rollouts(model.env, cb, model.rollout_buffer, args.n_steps)
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu_start
    env.close()
    out = {"sb3_collect_steps_per_s": total / clock.collect_s, "sb3_collect_steps_per_cpu_s": total / clock.collect_cpu_s}
    if learn:
        out["sb3_learn_steps_per_s"], out["sb3_learn_steps_per_cpu_s"] = total / wall, total / cpu
    return out


def adapter_rate(args) -> tuple[float, float]:
    import numpy as np

    from volleybots.integrations import VolleySB3VecEnv

    env = VolleySB3VecEnv(args.task, args.num_envs, seed=args.seed)
    rng = np.random.default_rng(args.seed)
    actions = [rng.uniform(-1, 1, (args.num_envs, 4)).astype(np.float32) for _ in range(8)]
    env.reset()
    for i in range(5):
        env.step(actions[i % 8])
    start, cpu_start = time.perf_counter(), time.process_time()
    for i in range(args.steps):
        env.step(actions[i % 8])
    n = args.num_envs * args.steps
    rates = n / (time.perf_counter() - start), n / (time.process_time() - cpu_start)
    env.close()
    return rates


@dataclass
class Args:
    task: str = option("solo_bump", "the task")
    num_envs: int = option(64, "worlds stepped together", ge=1)
    steps: int = option(200, "batched steps per timed repeat of the env and the adapter")
    n_steps: int = option(128, "PPO's rollout length per world")
    batch_size: int = option(256, "PPO's minibatch of the first learn row")
    minibatches: int = option(4, "minibatches per rollout of the recommended row")
    n_epochs: int = option(10, "PPO's epochs per rollout (SB3's default)")
    rollouts: int = option(3, "rollouts per SB3 measurement")
    repeats: int = option(3, "repeats, each rate their median", ge=1)
    dummy: int = option(0, "also SB3's DummyVecEnv over this many single envs (0: skip)")
    threads: int = option(1, "torch threads", ge=1)
    seed: int = option(0, "seeds the env and PPO", ge=0)
    json: Optional[str] = option(None, "also write the figures here")


def main(argv=None) -> dict:
    args = script_options(Args, argv, __doc__)

    import torch

    from volleybots.bench import measure
    from volleybots.integrations import VolleySB3VecEnv
    from volleybots.integrations.sb3_env import ppo_kwargs

    torch.set_num_threads(args.threads)
    # the three measured in turn, repeat by repeat, so that a shared machine's load falls on all alike; per
    # second of wall time and per second of this process's CPU time (one thread: what it would reach on a core
    # of its own, the steadier figure on a loaded machine)
    rows, load = [], [os.getloadavg()[0]]
    for _ in range(args.repeats):
        m = measure(args.task, "torch", args.num_envs, steps=args.steps, repeats=1, seed=args.seed)
        a = adapter_rate(args)
        make = lambda: VolleySB3VecEnv(args.task, args.num_envs, seed=args.seed)  # noqa: E731
        r = sb3_rates(make, args, learn=True)
        rec = sb3_rates(make, args, learn=True, ppo=ppo_kwargs(args.num_envs, args.n_steps, args.minibatches))
        rows.append({"env_steps_per_s": m["env_steps_per_s"], "env_steps_per_cpu_s": m["env_steps_per_cpu_s"],
                     "adapter_steps_per_s": a[0], "adapter_steps_per_cpu_s": a[1], **r,
                     "sb3_rec_learn_steps_per_s": rec["sb3_learn_steps_per_s"],
                     "sb3_rec_learn_steps_per_cpu_s": rec["sb3_learn_steps_per_cpu_s"]})
        load.append(os.getloadavg()[0])
    row = {"task": args.task, "num_envs": args.num_envs, "threads": args.threads, "load_1min": load, "repeats": rows,
           "ppo": {"n_steps": args.n_steps, "batch_size": args.batch_size, "n_epochs": args.n_epochs, "rollouts": args.rollouts},
           "ppo_recommended": {**ppo_kwargs(args.num_envs, args.n_steps, args.minibatches), "n_epochs": args.n_epochs}}
    for k in rows[0]:
        row[k] = statistics.median(r[k] for r in rows)
    if args.dummy:
        import gymnasium as gym
        from stable_baselines3.common.vec_env import DummyVecEnv

        import volleybots.integrations  # noqa: F401  (registers the ids)

        env_id = f"volleybots/{''.join(w.capitalize() for w in args.task.split('_'))}-v0"
        one = dataclasses.replace(args, rollouts=1)
        dummy = sb3_rates(lambda: DummyVecEnv([lambda: gym.make(env_id)] * args.dummy), one, learn=False)
        row["dummy_num_envs"], row["dummy_collect_steps_per_s"] = args.dummy, dummy["sb3_collect_steps_per_s"]
        row["dummy_collect_steps_per_cpu_s"] = dummy["sb3_collect_steps_per_cpu_s"]
    print("| what | env-steps/s (wall) | x env | env-steps per CPU-s | x env |\n|---|---:|---:|---:|---:|")
    for label, k in (("env (batched, random actions)", "env"), ("adapter step", "adapter"), ("SB3 PPO collection", "sb3_collect"),
                     (f"SB3 PPO learn, batch {args.batch_size}", "sb3_learn"),
                     (f"SB3 PPO learn, recommended (batch {args.num_envs * args.n_steps // args.minibatches}, foreach)", "sb3_rec_learn")):
        wall, cpu = row[k + "_steps_per_s"], row[k + "_steps_per_cpu_s"]
        row[k + "_vs_env"], row[k + "_cpu_vs_env"] = wall / row["env_steps_per_s"], cpu / row["env_steps_per_cpu_s"]
        print(f"| {label} | {wall:,.0f} | {row[k + '_vs_env']:.2f} | {cpu:,.0f} | {row[k + '_cpu_vs_env']:.2f} |")
    if args.dummy:
        d = row["dummy_collect_steps_per_cpu_s"]
        print(f"| SB3 PPO collection, DummyVecEnv of {args.dummy} single envs | {row['dummy_collect_steps_per_s']:,.0f} | "
              f"{row['dummy_collect_steps_per_s'] / row['env_steps_per_s']:.2f} | {d:,.0f} | {d / row['env_steps_per_cpu_s']:.2f} |")
    print(f"{args.task}, {args.num_envs} worlds, {args.threads} thread(s), 1-min load over the repeats {load}")
    if args.json:
        write_json(args.json, row)
    return row


if __name__ == "__main__":
    main()
