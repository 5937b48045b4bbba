"""Put a trained run into the zoo: ``volleybots/zoo/<task>/<method>.pt`` and its card ``<method>.yaml``.

    python benchmarks/zoo.py RUN_DIR METHOD --games 400 --seed 9000

The checkpoint keeps what acting needs and what ``load_algo_state`` reads (networks, observation
statistics, counters) with a fresh optimiser state: a few hundred KB instead of the run's megabytes.
The card records the command, frames, seed and wall time from the run's files, and the figures of
``--games`` games per pair against ``random`` and ``scripted`` on the evaluation seed ``--seed`` (a seed
no setting was chosen on), both sides equally.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import torch
import yaml

from volleybots.config import make_env, to_dict
from volleybots.eval.crossplay import crossplay, match_config, resolve_all
from volleybots.policies.store import load_learner, saved_config
from volleybots.runs import RunDir, read_checkpoint, run_policy_checkpoint
from volleybots.zoo import PREFIX, ZOO_DIR


def slim_checkpoint(src: Path) -> dict:
    """The checkpoint ``src`` with a fresh optimiser and no training-only state (rng, evals, anchor)."""
    state = read_checkpoint(src)
    env = make_env(saved_config(state, f"checkpoint {str(src)!r}"), num_envs=1)
    learner, _ = load_learner(src, env, int(state["n_agents"]))
    algo = learner.state_dict()
    algo.pop("anchor", None)
    if "optim" in algo:  # the moments are training state: an empty state with the same parameter groups loads as fresh
        algo["optim"] = {"state": {}, "param_groups": algo["optim"]["param_groups"]}
    if "data" in algo:  # a clone's imitation dataset is what it learned from, not what it acts with
        algo["data"] = {k: v[:0].clone() for k, v in algo["data"].items()}
        algo["counters"] = torch.tensor([int(algo["counters"][0]), 0, 0])
    keep = ("format", "version", "config", "task", "action_space", "obs_dim", "n_agents", "frames", "iteration", "wall_time", "label")
    return {**{k: state[k] for k in keep if k in state}, "algo": algo}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path)
    p.add_argument("method")
    p.add_argument("--games", type=int, default=400)
    p.add_argument("--seed", type=int, default=9000)
    p.add_argument("--command", default="", help="the command that trained the run, for the card")
    a = p.parse_args(argv)
    run = RunDir(a.run)
    ckpt = run_policy_checkpoint(run.path, f"run {str(a.run)!r}")
    summary = json.loads(run.summary_path.read_text()) if run.summary_path.is_file() else {}
    slim = slim_checkpoint(ckpt)
    task = slim["task"]
    out = ZOO_DIR / task / f"{a.method}.pt"
    out.parent.mkdir(parents=True, exist_ok=True)
    torch.save(slim, out)
    torch.load(out, weights_only=True)  # what every user does
    comps = resolve_all([f"{a.method}={out}", "random", "scripted"])
    cfg = match_config(comps, ["threads=1"])
    res = crossplay(cfg, comps, a.games, seed=a.seed)
    wr, lo_hi = res.win_rate(), res.interval()
    figures = {}
    for j, name in ((1, "random"), (2, "scripted")):
        w, d, l_ = res.wdl[0, j].astype(int).tolist()
        figures[f"vs_{name}"] = f"{wr[0, j]:.3f} of decisive games [{lo_hi[0][0, j]:.2f}, {lo_hi[1][0, j]:.2f}], W/D/L {w}/{d}/{l_}"
    card = {
        "name": PREFIX + f"{task}/{a.method}",
        "task": task,
        "algo": slim["config"]["algo"]["name"],
        "command": a.command or f"volleybots train task={task} algo={slim['config']['algo']['name']} seed={slim['config']['seed']}",
        "frames": int(slim["frames"]),
        "seed": int(slim["config"]["seed"]),
        "wall_time_s": round(float(summary.get("wall_time_s", slim.get("wall_time", 0.0))), 1),
        "evaluation": {
            "games_per_pair": a.games,
            "seed": a.seed,
            "note": "both sides equally; the seed was never used to choose a setting",
        },
        "figures": figures,
        "config": to_dict(slim["config"]),
    }
    out.with_suffix(".yaml").write_text(yaml.safe_dump(card, sort_keys=False))
    print(f"wrote {out} ({out.stat().st_size / 1024:.0f} KB) and its card: {figures}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
