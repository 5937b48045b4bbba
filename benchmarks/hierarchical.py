"""The hierarchical 3v3 policy's figures (not a test: it takes minutes). docs/hierarchical.md.

    python benchmarks/hierarchical.py [episodes=100] [seeds=0,1] [games=200] [vs=random,scripted,sp=RUN]
                                      [drills=serve=CKPT,...] [out=results/hierarchical/hierarchical.json]
    python benchmarks/hierarchical.py learn=serve,pass,set,attack bc_minutes=4 [ft_minutes=0]
                                      seeds=1000,1001 [sp_frames=300000] vs=random,scripted,hierarchical

1. Each drill (serve, pass, set, attack) played by its scripted player (or the checkpoint given in
   ``drills=``): ``episodes=`` episodes per seed (one per env), the success rate (the metric) with
   its Wilson 95 % interval, the mean error and the touches.
2. The hierarchical team (scripted drills, or ``drills=``) against each competitor of ``vs=``:
   ``games=`` games (``volleybots.play.games.play_games``: each side half of the games, serves
   drawn at random), W/D/L from the hierarchical side and the win rate of decisive games with its
   Wilson 95 % interval (spec: win rate = wins / (wins + losses)).
Writes the results (with the seeds, budget and machine) as JSON to ``out=`` (keys ``drills``, ``matches``;
the others of that file are kept).

``learn=`` first makes the learned drills: per drill, ``algo=bc`` (imitation of the scripted drill,
docs/imitation.md) for ``bc_minutes=`` of wall time, then, with ``ft_minutes=``, PPO from the clone
with benchmarks/imitation.py's fine-tuning recipe; training uses ``train_seed=`` (its periodic
evaluations that seed + 10000), so ``seeds=`` should be held out. Step 1 then plays each drill both
scripted and learned (bc, and fine-tuned) on the same seeds, and step 2's team uses the learned drills
(the fine-tuned one unless its final evaluation on the training's evaluation seed is below the
clone's); ``baseline=true`` also plays the all-scripted hierarchical team. ``sp_frames=`` first trains
the SP run (``task=3v3 algo=sp``, ``sp_envs=`` envs) and adds it to ``vs=`` as ``sp``. ``reuse=
DIR`` takes the finished runs of an earlier invocation's folder instead of training them. These
results go under the key ``learned`` of ``out=``; its other keys are kept.
"""

from __future__ import annotations

import json
import os
import platform
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

import volleybots
from volleybots.config import load
from volleybots.config.args import option, script_options
from volleybots.play import run_episodes
from volleybots.play.games import play_games
from volleybots.policies import Competitor, hierarchical_member, resolve_competitor
from volleybots.policies.builtin import learned_drill
from volleybots.ratings import record
from volleybots.ratings.intervals import wilson_interval
from volleybots.scripted.policies import SCRIPTED_POLICIES
from volleybots.tasks.match import Referee
from volleybots.train import train

sys.path.insert(0, str(Path(__file__).parent))
from imitation import common, curve, fine_tune  # noqa: E402  (the same runs as the imitation benchmark)

DRILLS = ("serve", "pass", "set", "attack")


def wilson(k: int, n: int) -> tuple[float | None, float | None]:
    """The library's Wilson interval (``volleybots.ratings.intervals``), None for no games (JSON null)."""
    if n == 0:
        return None, None
    lo, hi = wilson_interval(k, n)
    return float(lo), float(hi)


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
    """W/D/L of ``hier`` against ``opponent``, with the faults that ended the decisive games."""
    cfg = load(["task=3v3"])
    t0 = time.time()
    g = play_games(cfg, hier, resolve_competitor(opponent), games, seed)
    w, d, l_ = (int(x) for x in g.total)
    rate = record.win_rate(g.total)
    faults = lambda k: {f: int(n) for f, n in zip(Referee.FAULTS, g.faults[k], strict=True) if n}  # noqa: E731
    return {"team": hier.label, "opponent": opponent, "games": games, "seed": seed, "wins": w, "draws": d, "losses": l_,
            "win_rate": None if np.isnan(rate) else float(rate), "ci95": wilson(w, w + l_), "served": int(g.served),
            "lost_by": faults(0), "won_by_opponent_fault": faults(1), "seconds": round(time.time() - t0)}


def run_summary(run: Path, summary: dict, metric: str = "success") -> dict:
    return {"run_dir": str(run), "frames": summary["frames"], "wall_s": round(summary["wall_time_s"]),
            "final_eval": summary["final_eval"]["stats"][metric]["mean"], "curve": curve(run, metric)}


def trained(run: Path) -> dict | None:
    """The summary of a finished run at ``run`` (``root=`` of an earlier invocation), else None."""
    path = run / "summary.json"
    return json.loads(path.read_text()) if path.is_file() else None


def learn_drill(name: str, a, root: Path) -> dict:
    """bc on drill ``name`` for ``a.bc_minutes``, then (``a.ft_minutes`` > 0) PPO fine-tuning from it."""
    bc_dir, ft_dir = root / f"{name}_bc", root / f"{name}_ppo"
    bc = trained(bc_dir) or train(load([*common(a, name, a.bc_minutes), "algo=bc", *a.bc_overrides]), bc_dir)
    row = {"drill": name, "bc": run_summary(bc_dir, bc), "fine_tune": None, "policy": str(bc_dir)}
    if a.ft_minutes > 0:
        ft = trained(ft_dir) or train(
            load([*common(a, name, a.ft_minutes), "algo=ppo", f"init={bc_dir}", *fine_tune("ppo"), *a.ft_overrides]), ft_dir
        )
        row["fine_tune"] = run_summary(ft_dir, ft)
        # the team's drill: the fine-tuned policy unless its final evaluation (the training seed's
        # evaluation seed, not the held-out ones) is below the clone's
        if row["fine_tune"]["final_eval"] >= row["bc"]["final_eval"]:
            row["policy"] = str(ft_dir)
    print(json.dumps(row))
    return row


def train_sp(a, root: Path) -> dict:
    run = root / "3v3_sp"
    overrides = [
        "task=3v3",
        "algo=sp",
        "algo.start=scratch",  # the run the hierarchical page measured: self-play from scratch
        f"total_frames={a.sp_frames}",
        f"env.num_envs={a.sp_envs}",
        f"seed={a.train_seed}",
        f"threads={a.threads}",
        "evaluation.record=false",
        "progress=false",
    ]
    summary = trained(run) or train(load(overrides), run)
    return {
        "command": "volleybots train " + " ".join(overrides),
        "run_dir": str(run),
        "frames": summary["frames"],
        "seconds": round(summary["wall_time_s"]),
    }


def learned(a, seeds: list[int], save) -> dict:
    """The ``learn=`` path: train the drills (and the SP run), play them, play the team with them;
    ``save(out)`` after every step, so that a partial result survives."""
    root = Path(a.reuse) if a.reuse else Path(a.root) / time.strftime("%Y%m%d-%H%M%S")
    t0 = time.time()
    out = {
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, torch {torch.__version__}",
        "command": " ".join(sys.argv),
        "train_seed": a.train_seed,
        "eval_seeds": seeds,
        "root": str(root),
        "training": [],
        "drills": [],
        "matches": [],
    }
    names = [n for n in a.learn.split(",") if n]
    for name in names:
        out["training"].append(learn_drill(name, a, root))
        save(out)
    policies = {r["drill"]: r["policy"] for r in out["training"]}
    for name in names:
        t = next(r for r in out["training"] if r["drill"] == name)
        row = {
            "drill": name,
            "policy": policies[name],
            "scripted": drill_figures(name, a.episodes, seeds, None)["per_seed"],
            "bc": drill_figures(name, a.episodes, seeds, t["bc"]["run_dir"])["per_seed"],
        }
        if t["fine_tune"]:
            row["fine_tuned"] = drill_figures(name, a.episodes, seeds, t["fine_tune"]["run_dir"])["per_seed"]
        out["drills"].append(row)
        print(json.dumps(row))
        save(out)
    vs = [s for s in a.vs.split(",") if s]
    if a.sp_frames:
        out["sp_run"] = train_sp(a, root)
        vs.append(f"sp={out['sp_run']['run_dir']}")
        save(out)
    teams = [Competitor("hierarchical_learned", [hierarchical_member(policies, "hierarchical_learned")])]
    if a.baseline:  # the all-scripted hierarchical team against the same opponents, on the same seed
        teams.append(resolve_competitor("hierarchical"))
    for hier in teams:
        for opp in vs:
            if hier.label == opp:
                continue
            row = match_figures(hier, opp, a.games, seeds[0])
            out["matches"].append(row)
            print(json.dumps(row))
            save(out)
    out["wall_s"] = round(time.time() - t0)
    save(out)
    return out


@dataclass
class Args:
    episodes: int = option(100, "episodes each drill is evaluated on")
    seeds: str = option("0,1", "comma-separated evaluation seeds")
    games: int = option(200, "games the team plays against each of vs=")
    vs: str = option("random,scripted", "comma-separated opponents of the team")
    drills: str = option("", "drill=checkpoint,... (trained drills; the others scripted)")
    skip_drills: bool = option(False, "skip the drills' own evaluation (play the team only)")
    out: str = option("results/hierarchical/hierarchical.json", "where the figures are written")
    learn: str = option("", "drills to train (bc, then PPO with ft_minutes=) and play, e.g. serve,pass,set,attack")
    bc_minutes: float = option(4.0, "wall-clock minutes of each drill's bc run")
    ft_minutes: float = option(0.0, "wall-clock minutes of each drill's PPO fine-tuning (0: none)")
    bc_overrides: list[str] = option(help="extra overrides of the bc runs", factory=lambda: [])
    ft_overrides: list[str] = option(help="extra overrides of the fine-tuning runs", factory=lambda: [])
    train_seed: int = option(0, "seed of the training runs (periodic evaluations: + 10000)")
    action_space: str = option("prt", "the drills' action space")
    num_envs: int = option(256, "envs of the drills' training runs")
    threads: int = option(1, "torch threads of the training runs")
    eval_every: int = option(200_000, "frames between the training runs' periodic evaluations")
    eval_episodes: int = option(32, "episodes of each periodic evaluation")
    sp_frames: int = option(0, "train an SP run of this many frames first and play it (0: none)")
    sp_envs: int = option(128, "envs of the SP run")
    root: str = option("outputs/hierarchical", "where the training runs go (a new folder per invocation)")
    reuse: str = option("", "a folder of an earlier learn= invocation: its finished runs are used, not trained again")
    baseline: bool = option(False, "also play the all-scripted hierarchical team against vs=")


def main() -> None:
    a = script_options(Args, None, __doc__)
    torch.set_num_threads(a.threads)
    a.seed = a.train_seed  # imitation.common's name
    drills = dict(kv.split("=", 1) for kv in a.drills.split(",") if kv)
    seeds = [int(s) for s in a.seeds.split(",")]
    bad = sorted(set(n for n in a.learn.split(",") if n) - set(DRILLS))
    if bad or (a.reuse and not Path(a.reuse).is_dir()):
        print(
            f"error: learn={','.join(bad)}: not a drill; allowed: {', '.join(DRILLS)}"
            if bad
            else f"error: reuse={a.reuse!r} is no folder of an earlier learn=invocation",
            file=sys.stderr,
        )
        sys.exit(2)
    doc = json.loads(Path(a.out).read_text()) if Path(a.out).is_file() else {}

    def save(key: str, part) -> None:  # the other keys of out=(the other path's figures) are kept
        doc[key] = part
        Path(a.out).write_text(json.dumps(doc, indent=1) + "\n")

    if a.learn:
        learned(a, seeds, lambda part: save("learned", part))
        return
    save("machine", f"{platform.machine()}, {os.cpu_count()} cores, torch {torch.__version__}")
    save("command", " ".join(sys.argv))
    if not a.skip_drills:
        save("drills", [])
        for name in DRILLS:
            row = drill_figures(name, a.episodes, seeds, drills.get(name))
            save("drills", [*doc["drills"], row])
            print(json.dumps(row))
    vs = [s for s in a.vs.split(",") if s]
    if vs:
        save("matches", [])
    hier = Competitor("hierarchical", [hierarchical_member(drills)])
    for opp in vs:
        row = match_figures(hier, opp, a.games, seeds[0])
        save("matches", [*doc["matches"], row])
        print(json.dumps(row))


if __name__ == "__main__":
    main()
