"""Stable-Baselines3 PPO on the batched match (``VolleyMatchSB3VecEnv``) against the env's own agent-steps.

One process, each figure the median of ``--repeats``, the rows measured in turn each repeat so that a
shared machine's load falls on all alike:

- ``env``: the batched TorchRL match alone with random actions for every drone
  (``volleybots.bench.measure``), as agent-steps (world-steps x drones) per second;
- ``self-play``: SB3 PPO learning with ``opponent="self"`` (every drone of every world is one of SB3's
  envs): its env-steps are agent-steps of the learner;
- ``vs OPPONENT``: SB3 PPO learning one team against ``--opponent`` (default ``zoo:1v1/bc``): SB3's
  env-steps are the learner's agent-steps; the opponent's forward pass is part of the cost.

Rates per second of wall time and per second of this process's CPU time (``--threads`` torch threads;
the steadier figure on a shared machine). The PPO keywords are ``sb3_env.ppo_kwargs`` (the rollout in
``--minibatches`` minibatches, Adam's foreach update) with ``--n-epochs`` epochs.

    OMP_NUM_THREADS=1 python benchmarks/speed/sb3_match.py                  # 1v1, 64 worlds
    OMP_NUM_THREADS=1 python benchmarks/speed/sb3_match.py --json out.json

Needs ``pip install 'volleybots[sb3]'``. Quote the machine load (``uptime``) beside the figures.
"""

from __future__ import annotations

import argparse
import os
import statistics

from sb3_vecenv import sb3_rates  # the same SB3 timing as the single-drone benchmark (benchmarks/speed/)

from volleybots.files import write_json


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--task", default="1v1")
    ap.add_argument("--num-envs", type=int, default=64, help="worlds stepped together")
    ap.add_argument("--opponent", default="zoo:1v1/bc", help="the competitor of the one-team row")
    ap.add_argument("--steps", type=int, default=200, help="batched steps per timed repeat of the env")
    ap.add_argument("--n-steps", type=int, default=128, help="PPO's rollout length per SB3 env")
    ap.add_argument("--minibatches", type=int, default=4)
    ap.add_argument("--n-epochs", type=int, default=10, help="PPO's epochs per rollout (SB3's default)")
    ap.add_argument("--rollouts", type=int, default=2, help="rollouts per SB3 measurement")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default=None, help="also write the figures here")
    args = ap.parse_args(argv)

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
