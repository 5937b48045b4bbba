"""Stable-Baselines3 PPO on batched 1 vs 1 matches against the zoo's clone, then ranked against the zoo.

    pip install -e ".[sb3]"
    python examples/sb3_match_1v1.py                         # 16,384 steps and 3 x 16 games: about a minute on a CPU
    python examples/sb3_match_1v1.py --total-timesteps 2000000 --worlds 128 --games 200

Three steps, each one call of the public API:

1. train: ``VolleyMatchSB3VecEnv("1v1", worlds, opponent="zoo:1v1/bc")`` is an SB3 ``VecEnv`` whose
   envs are the learning drone of each world; every world steps in one batched call and the other
   drone is the zoo's behaviour-cloned player (any competitor spec works: ``scripted``, a run
   directory, a mixture ``scripted+zoo:1v1/bc``; ``opponent="self"`` for self-play, or
   ``SnapshotOpponent`` for self-play against a frozen copy refreshed every few rollouts);
2. export: ``export_torchscript`` writes the policy's mean action as a TorchScript file, which every
   verb of the CLI takes as ``torchscript:PATH``;
3. rank: ``sb3_competitor(model)`` plays a cross-play against zoo entries (win rates over decisive
   games, both sides equally), and the script prints the CLI line that ranks the exported file by Elo.

A short run does not beat the clone; it shows the plumbing, and the cross-play tells where it stands.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecMonitor

from volleybots.eval.crossplay import crossplay, format_table, match_config
from volleybots.integrations import VolleyMatchSB3VecEnv, export_torchscript, sb3_competitor
from volleybots.integrations.sb3_env import ppo_kwargs
from volleybots.policies import resolve_competitor


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--total-timesteps", type=int, default=16_384)
    p.add_argument("--worlds", type=int, default=32, help="1v1 matches stepped together (one SB3 env each)")
    p.add_argument("--opponent", default="zoo:1v1/bc", help="who plays the other drone while it trains")
    p.add_argument("--rivals", nargs="+", default=["zoo:1v1/bc", "zoo:1v1/bc_long"], help="what it is ranked against")
    p.add_argument("--games", type=int, default=16, help="games per pair of the ranking")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="outputs/sb3_match_1v1", help="folder for the SB3 model and its TorchScript export")
    return p.parse_args(argv)


def main(argv=None) -> dict:
    args = parse_args(argv)
    torch.set_num_threads(1)  # small tensors: one thread is the fastest on a shared CPU (docs/integrations.md)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    env = VecMonitor(VolleyMatchSB3VecEnv("1v1", args.worlds, opponent=args.opponent, seed=args.seed))
    model = PPO("MlpPolicy", env, seed=args.seed, device="cpu", **ppo_kwargs(env.num_envs, n_steps=128))
    model.learn(total_timesteps=args.total_timesteps)
    returns = [e["r"] for e in model.ep_info_buffer]
    print(f"trained {model.num_timesteps:,} steps against {args.opponent}; mean return of the last "
          f"{len(returns)} episodes: {np.mean(returns) if returns else float('nan'):.1f}")
    model.save(out / "ppo_1v1")
    export_torchscript(model, out / "policy.pt")

    mine = sb3_competitor(model, "sb3_ppo", task="1v1")
    rivals = [resolve_competitor(s) for s in args.rivals]
    cfg = match_config([mine, *rivals], ["task=1v1"])
    result = crossplay(cfg, [mine, *rivals], games=args.games, seed=args.seed, batch=args.games, specs=["sb3_ppo", *args.rivals])
    from rich.console import Console

    Console(width=120).print(format_table(result))
    rank = sorted(zip(result.average_win_rate(), result.labels, strict=True), key=lambda x: -np.nan_to_num(x[0], nan=-1.0))
    print("average win rate over decisive games: " + ", ".join(f"{lab} {wr:.2f}" for wr, lab in rank))
    print(f"wrote {out / 'ppo_1v1.zip'} and {out / 'policy.pt'}; rank the export by Elo with:\n"
          f"  volleybots eval elo mine=torchscript:{out / 'policy.pt'} {' '.join(args.rivals)} task=1v1 games=100")
    return {"timesteps": int(model.num_timesteps), "labels": result.labels, "average_win_rate": result.average_win_rate().tolist()}


if __name__ == "__main__":
    main()
