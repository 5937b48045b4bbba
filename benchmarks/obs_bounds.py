"""How often the adapters' declared observation bounds (``clip_obs=True``) bind.

For each task, scripted play (every drone driven by the task's scripted policy, where it has one) and
random play (uniform actions): ``num_envs=`` worlds for ``steps=`` control steps of the batched env
(worlds reset as they finish), every agent's observation checked against the bounds the adapters
declare with ``clip_obs=True`` (``volleybots.integrations.spaces.observation_bounds``). Reported per
task and play: the share of observation values the clip would change, the parts where it did, and the
largest |value| / bound of the declared parts (the headroom left).

    OMP_NUM_THREADS=1 python benchmarks/obs_bounds.py json=results/integrations/obs_bounds.json
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np
import torch

from volleybots.config import build_env
from volleybots.config.args import option, script_options
from volleybots.files import write_json
from volleybots.integrations.bounds import ObsClip
from volleybots.integrations.spaces import observation_bounds
from volleybots.keys import OBS
from volleybots.scripted import SCRIPTED_POLICIES, make_scripted_policy
from volleybots.tasks import TASKS
from volleybots.tasks.layout import ROOT, root_layout

DECLARED = ("pos", "positions", "anchor", "ball", "other", "target", "vel", "ball_vel", "omega")


def part_names(env) -> list[str]:
    """The part name of every observation value (the root's own parts by name)."""
    names = []
    for name, size in env.layout.parts:
        for sub, k in root_layout(env.with_throttle).parts if name == ROOT else ((name, size),):
            names += [sub] * k
    return names


def play(task: str, mode: str, num_envs: int, steps: int, seed: int) -> dict:
    env = build_env(task, num_envs=num_envs, seed=seed)
    low, high = observation_bounds(env, clip_obs=True)
    names = np.array(part_names(env))
    clip = ObsClip(low, high)
    policy = make_scripted_policy(env) if mode == "scripted" else None
    clipped = np.zeros(len(names), np.int64)
    peak = np.zeros(len(names))
    torch.manual_seed(seed)
    td = env.reset()
    with torch.no_grad():
        for _ in range(steps):
            td = policy(td) if policy is not None else td.update(env.full_action_spec.rand())
            _, td = env.step_and_maybe_reset(td)
            obs = td.get(OBS).reshape(-1, len(names)).cpu().numpy()
            clipped += ((obs < low) | (obs > high)).sum(0)
            peak = np.maximum(peak, np.abs(obs).max(0) / np.maximum(np.abs(low), np.abs(high)))
            clip(obs.copy())
    declared = np.isin(names, DECLARED)
    return {
        "task": task, "play": mode, "num_envs": num_envs, "steps": steps, "seed": seed,
        "agent_steps": clip.seen // len(names), "values": clip.seen, "clipped": clip.clipped, "clipped_share": clip.clipped / clip.seen,
        "clipped_parts": sorted({str(n) for n in names[clipped > 0]}),
        "peak_of_bound": {str(n): round(float(peak[names == n].max()), 3) for n in DECLARED if (names == n).any()},
        "peak_of_bound_max": round(float(peak[declared].max()), 3),
    }


@dataclass
class Args:
    tasks: str = option(",".join(TASKS), "comma-separated tasks (default: all)")
    num_envs: int = option(16, "worlds stepped together")
    steps: int = option(300, "control steps of the batched env per task and play")
    seed: int = option(0, "the seed")
    json: Optional[str] = option(None, "also write the rows here")


def main(argv=None) -> list[dict]:
    args = script_options(Args, argv, __doc__)
    torch.set_num_threads(1)
    rows = []
    print("| task | play | agent-steps | values clipped | parts clipped | largest |value| / bound |\n|---|---|---:|---:|---|---:|")
    for task in args.tasks.split(","):
        for mode in ("scripted", "random"):
            if mode == "scripted" and task not in SCRIPTED_POLICIES:
                continue
            r = play(task, mode, args.num_envs, args.steps, args.seed)
            rows.append(r)
            print(f"| {task} | {mode} | {r['agent_steps']:,} | {r['clipped']} ({100 * r['clipped_share']:.3f} %) | "
                  f"{', '.join(r['clipped_parts']) or '-'} | {r['peak_of_bound_max']:.2f} |", flush=True)
    if args.json:
        write_json(args.json, rows)
    return rows


if __name__ == "__main__":
    main()
