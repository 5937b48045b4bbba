"""Env throughput benchmark: env-steps/s with random actions per task, backend, env count and device.

    python benchmarks/speed/bench.py                                   # solo_bump, torch + mujoco, 1/256/4096 envs
    python benchmarks/speed/bench.py tasks=[solo_bump,3v3] num_envs=4096 compile=true json=out.json
    python benchmarks/speed/bench.py tasks=[solo_bump,3v3] num_envs=4096 both=true train=true   # + PPO / MAPPO frames/s

Prints a Markdown table (docs/performance.md holds the measured one); ``json=FILE`` also writes the rows.
Its options are ``volleybots bench``'s (``BenchOptions``) and two of its own; ``help`` lists them.
"""

from __future__ import annotations

import json
import os
import sys
from dataclasses import dataclass
from typing import Optional

import torch

from volleybots.bench import format_table, run_bench
from volleybots.config.args import option, script_options
from volleybots.config.verbs import BenchOptions


@dataclass
class Args(BenchOptions):
    """``volleybots bench``'s options, and the script's own."""

    both: bool = option(False, "measure the torch backend eager and compiled (compile=[false,true])")
    json: Optional[str] = option(None, "FILE: also write the rows to this JSON file")


def main(argv=None) -> int:
    args = script_options(Args, argv, __doc__)
    if args.both:
        args.compile = [False, True]
    if args.threads:
        torch.set_num_threads(args.threads)  # before anything runs, so the banner below shows it
    print(f"# torch {torch.__version__}, {torch.get_num_threads()} threads, {os.cpu_count()} CPUs", file=sys.stderr)
    rows = run_bench(
        args,
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
