"""The hierarchical 3v3 policy's figures (not a test: it takes minutes). docs/hierarchical.md.

    python benchmarks/hierarchical.py [--episodes 100] [--seeds 0,1] [--games 200] [--vs random,scripted,sp=RUN]
                                      [--drills serve=CKPT,...] [--out docs/hierarchical.json]

1. Each drill (serve, pass, set, attack) played by its scripted player (or the checkpoint given in
   ``--drills``): ``--episodes`` episodes per seed (one per env), the success rate (the metric) with
   its Wilson 95 % interval, the mean error and the touches.
2. The hierarchical team (scripted drills, or ``--drills``) against each competitor of ``--vs``:
   ``--games`` games (``volleybots.eval.games.head_to_head``: each side half of the games, serves
   drawn at random), W/D/L from the hierarchical side and the win rate of decisive games with its
   Wilson 95 % interval (spec: win rate = wins / (wins + losses)).
Writes the results (with the seeds, budget and machine) as JSON to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import torch
from scipy.stats import binomtest

import volleybots
from volleybots.competitors import hierarchical_member, resolve_competitor, Competitor
from volleybots.config import load
from volleybots.eval import run_episodes
from volleybots.eval.games import head_to_head
from volleybots.scripted.hierarchical import learned_drill
from volleybots.scripted.policies import SCRIPTED_POLICIES

DRILLS = ("serve", "pass", "set", "attack")


def wilson(k: int, n: int) -> tuple[float, float]:
    if n == 0:
        return float("nan"), float("nan")
    ci = binomtest(k, n).proportion_ci(0.95, method="wilson")
    return float(ci.low), float(ci.high)


def drill_figures(name: str, episodes: int, seeds: list[int], checkpoint: str | None) -> dict:
    rows = []
    for seed in seeds:
        env = volleybots.make_env(name, num_envs=episodes, seed=seed)
        policy = learned_drill(name, checkpoint, env, True) if checkpoint else SCRIPTED_POLICIES[name](env.action_space_name, env.params)
        res = run_episodes(env, policy)
        ok = int(res["success"].sum())
        rows.append({"seed": seed, "episodes": episodes, "success": ok / episodes, "ci95": wilson(ok, episodes),
                     "error_m": float(res["error"][res["success"] > 0].mean()) if ok else None, "hits": float(res["hits"].mean())})
    return {"drill": name, "policy": checkpoint or "scripted", "per_seed": rows}


def match_figures(hier: Competitor, opponent: str, games: int, seed: int) -> dict:
    cfg = load(["task=3v3"])
    t0 = time.time()
    c = head_to_head(cfg, hier, resolve_competitor(opponent), games, seed)
    decisive = c["wins"] + c["losses"]
    return {"opponent": opponent, "games": games, "seed": seed, **c, "win_rate": c["wins"] / decisive if decisive else None,
            "ci95": wilson(c["wins"], decisive), "seconds": round(time.time() - t0)}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--episodes", type=int, default=100)
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument("--games", type=int, default=200)
    ap.add_argument("--vs", default="random,scripted")
    ap.add_argument("--drills", default="", help="drill=checkpoint,... (trained drills; the others scripted)")
    ap.add_argument("--skip-drills", action="store_true")
    ap.add_argument("--out", default="docs/hierarchical.json")
    a = ap.parse_args()
    torch.set_num_threads(1)
    drills = dict(kv.split("=", 1) for kv in a.drills.split(",") if kv)
    seeds = [int(s) for s in a.seeds.split(",")]
    out = {"machine": f"{platform.machine()}, {os.cpu_count()} cores, torch {torch.__version__}", "drills": [], "matches": []}
    if not a.skip_drills:
        for name in DRILLS:
            row = drill_figures(name, a.episodes, seeds, drills.get(name))
            out["drills"].append(row)
            print(json.dumps(row))
    hier = Competitor("hierarchical", [hierarchical_member(drills)])
    for opp in (s for s in a.vs.split(",") if s):
        row = match_figures(hier, opp, a.games, seeds[0])
        out["matches"].append(row)
        print(json.dumps(row))
    with open(a.out, "w") as f:
        json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
