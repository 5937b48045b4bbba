"""Env throughput benchmark: env-steps/s with random actions per task, backend, env count and device.

    python benchmarks/speed/bench.py                                   # solo_bump, torch + mujoco, 1/256/4096 envs
    python benchmarks/speed/bench.py --tasks solo_bump,3v3 --num-envs 4096 --compile --json out.json
    python benchmarks/speed/bench.py --tasks solo_bump,3v3 --num-envs 4096 --both --train   # + PPO / MAPPO frames/s

Prints a Markdown table (docs/performance.md holds the measured one); ``--json`` also writes the rows.
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import torch

from volleybots.bench import DEFAULT_NUM_ENVS, DEFAULT_TASKS, format_table, run_bench


def _csv(s: str) -> list[str]:
    return [x.strip() for x in s.split(",") if x.strip()]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tasks", type=_csv, default=list(DEFAULT_TASKS), help="comma-separated task names")
    ap.add_argument("--backends", type=_csv, default=["torch", "mujoco"], help="comma-separated physics backends")
    ap.add_argument(
        "--num-envs", type=lambda s: [int(x) for x in _csv(s)], default=list(DEFAULT_NUM_ENVS), help="comma-separated env counts"
    )
    ap.add_argument("--devices", type=_csv, default=None, help="comma-separated torch devices (default: cpu, and cuda if available)")
    ap.add_argument("--compile", action="store_true", help="torch.compile the torch physics sub-step")
    ap.add_argument("--both", action="store_true", help="measure the torch backend eager and compiled")
    ap.add_argument("--action-space", default="prt", choices=["prt", "ctbr", "discrete"])
    ap.add_argument("--repeats", type=int, default=3, help="timed repeats per row (median reported)")
    ap.add_argument("--steps", type=int, default=None, help="env steps per repeat (default scales with env count)")
    ap.add_argument("--threads", type=int, default=None, help="torch intra-op threads (default: torch's)")
    ap.add_argument("--train", action="store_true", help="also measure training frames/s: PPO on solo_bump, MAPPO on 3v3")
    ap.add_argument("--train-batches", type=int, default=3, help="timed training batches per training row")
    ap.add_argument("--json", default=None, help="also write the rows to this JSON file")
    args = ap.parse_args(argv)

    if args.threads:
        torch.set_num_threads(args.threads)  # before anything runs, so the banner below shows it
    print(f"# torch {torch.__version__}, {torch.get_num_threads()} threads, {os.cpu_count()} CPUs", file=sys.stderr)
    rows = run_bench(
        args.tasks,
        args.backends,
        args.num_envs,
        args.devices,
        compile=(False, True) if args.both else args.compile,
        repeats=args.repeats,
        steps=args.steps,
        action_space=args.action_space,
        threads=args.threads,
        train=args.train,
        train_batches=args.train_batches,
        progress=lambda r: print(
            f"  {r['task']} {r['kind']} {r['backend']} {r['device']} compile={r['compile']} x{r['num_envs']}: "
            f"{r['env_steps_per_s']:,.0f}/s",
            file=sys.stderr,
            flush=True,
        ),
    )
    print(format_table(rows))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
