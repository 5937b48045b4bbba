"""Stable-Baselines3 PPO on the batched match (``VolleyMatchSB3VecEnv``) against the env's own agent-steps.

One process, each figure the median of ``repeats=``, the rows measured in turn each repeat so that a
shared machine's load falls on all alike:

- ``env``: the batched TorchRL match alone with random actions for every drone
  (``volleybots.bench.measure``), as agent-steps (world-steps x drones) per second;
- ``self-play``: SB3 PPO learning with ``opponent="self"`` (every drone of every world is one of SB3's
  envs): its env-steps are agent-steps of the learner;
- ``vs OPPONENT``: SB3 PPO learning one team against ``opponent=`` (default ``zoo:1v1/bc``): SB3's
  env-steps are the learner's agent-steps; the opponent's forward pass is part of the cost.

Rates per second of wall time and per second of this process's CPU time (``threads=`` torch threads;
the steadier figure on a shared machine). The PPO keywords are ``sb3_env.ppo_kwargs`` (the rollout in
``minibatches=`` minibatches, Adam's foreach update) with ``n_epochs=`` epochs.

    OMP_NUM_THREADS=1 python benchmarks/speed/sb3_match.py                  # 1v1, 64 worlds
    OMP_NUM_THREADS=1 python benchmarks/speed/sb3_match.py json=out.json

Needs ``pip install 'volleybots[sb3]'``. Quote the machine load (``uptime``) beside the figures.
"""

from __future__ import annotations

import os
import statistics
from dataclasses import dataclass
from typing import Optional

from sb3_vecenv import sb3_rates  # the same SB3 timing as the single-drone benchmark (benchmarks/speed/)

from volleybots.config.args import option, script_options
from volleybots.files import write_json


@dataclass
class Args:
    task: str = option("1v1", "the match")
    num_envs: int = option(64, "worlds stepped together")
    opponent: str = option("zoo:1v1/bc", "the competitor of the one-team row")
    steps: int = option(200, "batched steps per timed repeat of the env")
    n_steps: int = option(128, "PPO's rollout length per SB3 env")
    minibatches: int = option(4, "minibatches per rollout (ppo_kwargs)", ge=1)
    n_epochs: int = option(10, "PPO's epochs per rollout (SB3's default)")
    rollouts: int = option(2, "rollouts per SB3 measurement")
    repeats: int = option(3, "repeats, each figure their median", ge=1)
    threads: int = option(1, "torch threads", ge=1)
    seed: int = option(0, "seeds the envs and PPO", ge=0)
    json: Optional[str] = option(None, "also write the figures here")


def main(argv=None) -> dict:
    args = script_options(Args, argv, __doc__)

    import torch

    from volleybots.bench import measure
    from volleybots.integrations import VolleyMatchSB3VecEnv
    from volleybots.integrations.sb3_env import ppo_kwargs

    torch.set_num_threads(args.threads)
    learners = {"self": "self-play (both teams learn)", args.opponent: f"vs {args.opponent} (one team learns)"}
    rows, load = [], [os.getloadavg()[0]]
    for _ in range(args.repeats):
        m = measure(args.task, "torch", args.num_envs, steps=args.steps, repeats=1, seed=args.seed)
        row = {"env_agent_steps_per_s": m["env_steps_per_s"] * m["n_drones"],
               "env_agent_steps_per_cpu_s": m["env_steps_per_cpu_s"] * m["n_drones"]}
        for opp in learners:
            make = lambda opp=opp: VolleyMatchSB3VecEnv(args.task, args.num_envs, opponent=opp, seed=args.seed)  # noqa: E731
            rows_per_world = make().num_envs // args.num_envs
            ppo = ppo_kwargs(args.num_envs * rows_per_world, args.n_steps, args.minibatches)
            r = sb3_rates(make, args, learn=True, ppo=ppo)
            row[f"{opp}_steps_per_s"], row[f"{opp}_steps_per_cpu_s"] = r["sb3_learn_steps_per_s"], r["sb3_learn_steps_per_cpu_s"]
        rows.append(row)
        load.append(os.getloadavg()[0])
    out = {"task": args.task, "num_envs": args.num_envs, "threads": args.threads, "load_1min": load, "repeats": rows,
           "ppo": {"n_steps": args.n_steps, "minibatches": args.minibatches, "n_epochs": args.n_epochs, "rollouts": args.rollouts}}
    for k in rows[0]:
        out[k] = statistics.median(r[k] for r in rows)
    print("| what | agent-steps/s (wall) | x env | agent-steps per CPU-s | x env |\n|---|---:|---:|---:|---:|")
    env_wall, env_cpu = out["env_agent_steps_per_s"], out["env_agent_steps_per_cpu_s"]
    print(f"| env (batched, random actions, every drone) | {env_wall:,.0f} | 1.00 | {env_cpu:,.0f} | 1.00 |")
    for opp, label in learners.items():
        wall, cpu = out[f"{opp}_steps_per_s"], out[f"{opp}_steps_per_cpu_s"]
        out[f"{opp}_vs_env"], out[f"{opp}_cpu_vs_env"] = wall / env_wall, cpu / env_cpu
        print(f"| SB3 PPO learn, {label} | {wall:,.0f} | {wall / env_wall:.2f} | {cpu:,.0f} | {cpu / env_cpu:.2f} |")
    print(f"{args.task}, {args.num_envs} worlds, {args.threads} thread(s), 1-min load over the repeats {load}")
    if args.json:
        write_json(args.json, out)
    return out


if __name__ == "__main__":
    main()
