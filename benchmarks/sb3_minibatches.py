"""What SB3 PPO's minibatch size costs in learning on Solo Bump through ``VolleySB3VecEnv``.

One PPO run per ``batch_sizes=`` entry (64 worlds, ``n_steps=128``, 10 epochs, Adam with the foreach
update and SB3's eps, as ``ppo_kwargs`` gives, so that only the minibatch differs), ``steps=`` env-steps
each. Printed per run and quarter of training: the episodes that ended, their mean return and mean
bumps (from ``infos[i]["final_stats"]``), and the run's wall and CPU seconds.

    OMP_NUM_THREADS=1 python benchmarks/sb3_minibatches.py batch_sizes=256,2048 seed=0
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Optional

import numpy as np
import torch

from volleybots.config.args import option, script_options
from volleybots.files import write_json


def run(batch_size: int, seed: int, steps: int, num_envs: int) -> dict:
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecMonitor

    from volleybots.integrations import VolleySB3VecEnv
    from volleybots.integrations.sb3_env import ppo_kwargs

    ends = []

    class Ends(BaseCallback):
        def _on_step(self):
            ends.extend((self.num_timesteps, i["final_stats"]["return"], i["final_stats"]["bumps"])
                        for i in self.locals["infos"] if "final_stats" in i)
            return True

    env = VecMonitor(VolleySB3VecEnv("solo_bump", num_envs, seed=seed))
    kw = {**ppo_kwargs(num_envs), "batch_size": batch_size}
    model = PPO("MlpPolicy", env, seed=seed, device="cpu", **kw)
    start, cpu = time.perf_counter(), time.process_time()
    model.learn(steps, callback=Ends())
    row = {"batch_size": batch_size, "seed": seed, "steps": steps, "wall_s": time.perf_counter() - start,
           "cpu_s": time.process_time() - cpu, "quarters": []}
    e = np.array(ends)
    for q in range(4):
        sel = e[(e[:, 0] > steps * q / 4) & (e[:, 0] <= steps * (q + 1) / 4)]
        row["quarters"].append({"episodes": len(sel), "return": float(sel[:, 1].mean()), "bumps": float(sel[:, 2].mean())})
    env.close()
    return row


@dataclass
class Args:
    batch_sizes: str = option("256,2048", "PPO minibatch sizes compared, comma-separated")
    steps: int = option(400_000, "env steps of each run")
    num_envs: int = option(64, "worlds stepped together")
    seed: int = option(0, "the seed")
    json: Optional[str] = option(None, "FILE: also write the results here")


def main(argv=None) -> list[dict]:
    args = script_options(Args, argv, __doc__)
    torch.set_num_threads(1)
    rows = []
    for bs in (int(b) for b in args.batch_sizes.split(",")):
        r = run(bs, args.seed, args.steps, args.num_envs)
        rows.append(r)
        last = r["quarters"][-1]
        print(f"batch {bs}, seed {args.seed}: last quarter {last['episodes']} episodes, return {last['return']:.1f}, "
              f"bumps {last['bumps']:.2f}; {r['cpu_s']:.0f} CPU-s, {r['wall_s']:.0f} s", flush=True)
    if args.json:
        write_json(args.json, rows)
    return rows


if __name__ == "__main__":
    main()
