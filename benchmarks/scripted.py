"""Scripted model-based policies on the single-drone tasks, and the env's raw throughput.

For every task and action space it plays ``episodes=`` episodes (one per env of a batch) with
``volleybots.scripted.make_scripted_policy`` and reports the task metric's mean and standard
deviation; then it measures env-steps/s of Solo Bump with random actions at ``bench_envs=`` envs
(warm-up excluded, median of ``repeats=``). Targets (issue 2, item 7; paper table 1, PPO with PRT):
Solo Bump >= 10.83 bumps, Back and Forth >= 10.04 targets, Hit the Ball >= 11.40 m.

    python benchmarks/scripted.py                               # 100 episodes per task and space
    python benchmarks/scripted.py episodes=20 tasks=solo_bump spaces=prt json=out.json

Prints a Markdown table (docs/scripted.md holds the measured one).
"""

from __future__ import annotations

import json
import os
import sys
import time
from dataclasses import dataclass
from typing import Optional

import torch

import volleybots
from volleybots.bench import run_bench
from volleybots.config.args import option, script_options
from volleybots.play import run_episodes, summarize
from volleybots.scripted import make_scripted_policy

TASKS = ("hover", "back_and_forth", "hit_the_ball", "solo_bump")
# paper table 1 (PPO, PRT): what a scripted player should match; higher is better for all three
TARGETS = {"back_and_forth": 10.04, "hit_the_ball": 11.40, "solo_bump": 10.83}


def _csv(s: str) -> list[str]:
    return [x.strip() for x in s.split(",") if x.strip()]


def play(task: str, space: str, episodes: int, seed: int, device: str) -> dict:
    env = volleybots.make_env(task, num_envs=episodes, action_space=space, seed=seed, device=device)
    policy = make_scripted_policy(env)
    t0 = time.perf_counter()
    with torch.no_grad():
        res = run_episodes(env, policy)
    out = summarize(res, env.metric)
    m = out["stats"][env.metric]
    return {
        "task": task, "action_space": space, "episodes": out["episodes"], "metric": env.metric,
        "mean": m["mean"], "std": m["std"], "min": float(res[env.metric].min()), "max": float(res[env.metric].max()),
        "episode_len": out["stats"]["episode_len"]["mean"], "target": TARGETS.get(task), "wall_s": time.perf_counter() - t0,
    }


def format_table(rows: list[dict]) -> str:
    lines = [
        "| task | action space | metric | mean | std | min | max | mean episode length | target |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        target = "" if r["target"] is None else f"{r['target']:.2f}"
        lines.append(
            f"| {r['task']} | {r['action_space']} | {r['metric']} | {r['mean']:.2f} | {r['std']:.2f} | {r['min']:.2f} | "
            f"{r['max']:.2f} | {r['episode_len']:.0f} | {target} |"
        )
    return "\n".join(lines)


@dataclass
class Args:
    tasks: list[str] = option(help="comma-separated task names", factory=lambda: list(TASKS))
    spaces: list[str] = option(help="comma-separated action spaces (prt, ctbr)", factory=lambda: ["prt", "ctbr"])
    episodes: int = option(100, "episodes per task and action space")
    seed: int = option(0, "the seed")
    device: str = option("cpu", "torch device")
    bench_envs: int = option(4096, "env count of the throughput row (0: skip it)")
    repeats: int = option(5, "timed repeats of the throughput row (median reported)")
    threads: Optional[int] = option(None, "torch intra-op threads (default: torch's)")
    json: Optional[str] = option(None, "also write the rows to this JSON file")


def main(argv=None) -> int:
    args = script_options(Args, argv, __doc__)

    if args.threads:
        torch.set_num_threads(args.threads)
    print(f"# torch {torch.__version__}, {torch.get_num_threads()} threads, {os.cpu_count()} CPUs, device {args.device}", file=sys.stderr)
    rows = []
    for task in args.tasks:
        for space in args.spaces:
            r = play(task, space, args.episodes, args.seed, args.device)
            print(f"  {task} {space}: {r['metric']} {r['mean']:.2f} +- {r['std']:.2f} ({r['wall_s']:.0f} s)", file=sys.stderr, flush=True)
            rows.append(r)
    print(format_table(rows))
    bench = []
    if args.bench_envs > 0:
        bench = run_bench(["solo_bump"], ["torch"], [args.bench_envs], [args.device], repeats=args.repeats, threads=args.threads)
        for b in bench:
            print(
                f"\nSolo Bump, random PRT actions, {b['num_envs']} envs on {b['device']}: {b['env_steps_per_s']:,.0f} "
                f"env-steps/s (median of {args.repeats})"
            )
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"episodes": rows, "throughput": bench}, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
