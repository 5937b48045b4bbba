"""The cost of one rendered frame (``render_mode="rgb_array"``): the video frame drawn into pixels
(``volleybots.replay.raster``, what ``render()`` gives now) against the replay's matplotlib still
(``Trail.still``, what ``render()`` gave before), on the same episode so far, in one process.

Each repeat times ``--frames`` frames of each kind in turn (so a shared machine's load falls on both
alike); the figures are the medians over ``--repeats`` of the mean milliseconds per frame.

    OMP_NUM_THREADS=1 python benchmarks/speed/render_frame.py                   # Solo Bump, 200 steps in
    OMP_NUM_THREADS=1 python benchmarks/speed/render_frame.py --task 1v1 --json results/integrations/render_frame.json

Quote the machine load (``uptime``, printed with the figures) beside them.
"""

from __future__ import annotations

import os
import statistics
import time
from dataclasses import dataclass
from typing import Optional

import numpy as np
import torch

from volleybots.config.args import option, script_options
from volleybots.files import write_json
from volleybots.integrations import VolleyParallelEnv
from volleybots.integrations.gym_env import VolleyGymEnv
from volleybots.integrations.match_env import MATCHES


def _episode(task: str, steps: int, seed: int):
    """An env with ``render_mode="rgb_array"`` after ``steps`` random steps (fewer if the episode ends)."""
    rng = np.random.default_rng(seed)
    if task in MATCHES:
        env = VolleyParallelEnv(task, render_mode="rgb_array", seed=seed)
        env.reset(seed=seed)
        for _ in range(steps):
            if not env.agents:
                break
            env.step({a: rng.uniform(-1, 1, 4).astype(np.float32) for a in env.agents})
        return env
    env = VolleyGymEnv(task, render_mode="rgb_array", seed=seed)
    env.reset(seed=seed)
    for _ in range(steps):
        if env.step(rng.uniform(-1, 1, 4).astype(np.float32))[2:4] != (False, False):
            break
    return env


def _ms(fn, n: int) -> float:
    start = time.perf_counter()
    for _ in range(n):
        fn()
    return (time.perf_counter() - start) / n * 1e3


@dataclass
class Args:
    task: str = option("solo_bump", "the task whose frames are drawn")
    steps: int = option(200, "random steps before the frames (the paths drawn)")
    frames: int = option(20, "frames of each kind per repeat")
    repeats: int = option(3, "repeats (the figure is their median)")
    seed: int = option(0, "the seed")
    json: Optional[str] = option(None, "write the figures here")


def main(argv=None) -> dict:
    args = script_options(Args, argv, __doc__)
    torch.set_num_threads(1)
    env = _episode(args.task, args.steps, args.seed)
    trail = env._trail
    frame, still = env.render(), trail.still(args.task)  # warm both (the font, matplotlib's imports)
    new, old = [], []
    for _ in range(args.repeats):
        new.append(_ms(env.render, args.frames))
        old.append(_ms(lambda: trail.still(args.task), max(1, args.frames // 4)))  # 4x fewer: each costs ~70 ms
    out = {
        "task": args.task, "steps_drawn": len(trail.ball), "frame_shape": list(frame.shape), "still_shape": list(still.shape),
        "raster_ms": statistics.median(new), "matplotlib_still_ms": statistics.median(old), "repeats": args.repeats,
        "speedup": statistics.median(old) / statistics.median(new), "load_average": list(os.getloadavg()),
    }
    print(f"{args.task}, {out['steps_drawn']} steps drawn: raster {out['raster_ms']:.2f} ms/frame, matplotlib still "
          f"{out['matplotlib_still_ms']:.1f} ms/frame ({out['speedup']:.0f}x); load average {os.getloadavg()[0]:.1f}")
    if args.json:
        write_json(args.json, out)
    return out


if __name__ == "__main__":
    main()
