"""Scripted model-based policies on the single-drone tasks, and the env's raw throughput.

For every task and action space it plays ``--episodes`` episodes (one per env of a batch) with
``volleybots.scripted.make_scripted_policy`` and reports the task metric's mean and standard
deviation; then it measures env-steps/s of Solo Bump with random actions at ``--bench-envs`` envs
(warm-up excluded, median of ``--repeats``). Targets (issue 2, item 7; paper table 1, PPO with PRT):
Solo Bump >= 10.83 bumps, Back and Forth >= 10.04 targets, Hit the Ball >= 11.40 m.

    python benchmarks/scripted.py                               # 100 episodes per task and space
    python benchmarks/scripted.py --episodes 20 --tasks solo_bump --spaces prt --json out.json

Prints a Markdown table (docs/scripted.md holds the measured one).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import torch

import volleybots
from volleybots.bench import run_bench
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tasks", type=_csv, default=list(TASKS), help="comma-separated task names")
    ap.add_argument("--spaces", type=_csv, default=["prt", "ctbr"], help="comma-separated action spaces (prt, ctbr)")
    ap.add_argument("--episodes", type=int, default=100, help="episodes per task and action space")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--bench-envs", type=int, default=4096, help="env count of the throughput row (0: skip it)")
    ap.add_argument("--repeats", type=int, default=5, help="timed repeats of the throughput row (median reported)")
    ap.add_argument("--threads", type=int, default=None, help="torch intra-op threads (default: torch's)")
    ap.add_argument("--json", default=None, help="also write the rows to this JSON file")
    args = ap.parse_args(argv)

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
