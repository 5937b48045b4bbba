"""A learned 3 vs 3 team (the HCSP route): a high level trained by RL over drills, then played.

    python benchmarks/hcsp.py drills_dir=RUNS out=DIR [games=4096] [batch=256] [seed=1]
                              [opponent=scripted] [eval_games=400] [eval_seeds=9100,9101]
                              [vs=scripted,hierarchical]

1. ``drills_dir=``: the folder of a ``benchmarks/hierarchical.py learn=`` invocation (its
   ``<drill>_ppo`` runs, else ``<drill>_bc``; the drills it lacks stay scripted); ``drills=
   serve=CKPT,...`` names them one by one; neither: scripted drills.
2. The high level (``volleybots.train.high_level``) is trained against ``opponent=`` for
   ``games=`` games (``time_limit=`` seconds at most), seed ``seed=``; it is saved as
   ``DIR/high_level.pt``, the team as ``DIR/team.yaml`` (``hierarchical: {drill: run, high_level: file}``,
   a competitor like any other: ``volleybots eval crossplay hcsp=DIR/team.yaml scripted task=3v3``),
   the per-batch history as ``DIR/history.jsonl``.
3. The learned team and, as the baseline, the rules over the same drills (``DIR/rules.yaml``) play
   ``eval_games=`` games against each of ``vs=`` on each of ``eval_seeds=`` (seeds no setting was
   chosen on): W/D/L, the win rate of decisive games with its Wilson interval, touches and serve /
   receive W/D/L. Written to ``DIR/figures.json``.
"""

from __future__ import annotations

import json
import os
import platform
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Optional

import yaml

from volleybots.config import load
from volleybots.config.args import option, script_options
from volleybots.errors import ConfigError
from volleybots.play.games import play_games
from volleybots.policies import resolve_competitor
from volleybots.policies.high_level import save_high_level
from volleybots.ratings.intervals import wilson_interval
from volleybots.scripted.hierarchical import DRILLS
from volleybots.train.high_level import HighLevelConfig, train_high_level


def drills_of(args) -> dict[str, str]:
    if args.drills:
        return dict(item.split("=", 1) for item in args.drills.split(","))
    if not args.drills_dir:
        return {}
    root = Path(args.drills_dir)
    out = {}
    for name in DRILLS:
        for kind in ("ppo", "bc"):
            found = sorted(root.glob(f"*/{name}_{kind}")) + sorted(root.glob(f"{name}_{kind}"))
            if found:
                out[name] = str(found[-1].resolve())
                break
    return out


def figures(team: str, vs: str, games: int, seed: int, cfg) -> dict:
    a, b = resolve_competitor(team), resolve_competitor(vs)
    g = play_games(cfg, a, b, games, seed=seed)
    w, d, lost = (int(x) for x in g.total)
    lo, hi = wilson_interval(w, w + lost) if w + lost else (float("nan"), float("nan"))
    c = g.content()
    return {"team": team, "vs": vs, "seed": seed, "games": games, "wdl": [w, d, lost],
            "win_rate": w / (w + lost) if w + lost else None, "ci95": [float(lo), float(hi)],
            "touches": c["touches"], "rally_steps": c["rally_steps"], "serve_wdl": c["serve_wdl"], "receive_wdl": c["receive_wdl"],
            "faults": c["faults"]}


@dataclass
class Args:
    drills_dir: str = option("", "a benchmarks/hierarchical.py learn= folder whose drill runs are used")
    drills: str = option("", "drill=checkpoint,... (the others scripted)")
    out: Optional[str] = option(None, "the folder of high_level.pt, team.yaml, history.jsonl and figures.json")
    opponent: str = option("scripted", "whom the high level trains against")
    games: int = option(4096, "games the high level trains on")
    batch: int = option(256, "games (worlds) per update")
    lr: float = option(1e-3, "Adam's learning rate")
    entropy: float = option(0.01, "entropy bonus per choice")
    seed: int = option(1, "the training seed")
    receive_coming: bool = option(False, "call a receiver only for balls coming down in the own half")
    receive_attack: bool = option(False, "a front drone called to receive returns the ball at once (attack drill)")
    time_limit: float = option(0.0, "seconds of training at most (0: none)")
    eval_games: int = option(400, "games against each of vs= per evaluation seed")
    eval_seeds: str = option("9100,9101", "comma-separated held-out evaluation seeds")
    vs: str = option("scripted,hierarchical", "comma-separated opponents of the evaluation")
    skip_train: bool = option(False, "play the DIR's high level again (no training)")


def main(argv=None) -> int:
    args = script_options(Args, argv, __doc__)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cfg = load(["task=3v3"])
    drills = drills_of(args)
    team = {"hierarchical": {**drills, "high_level": "high_level.pt"}}
    rules = {"hierarchical": dict(drills)} if drills else None
    hc = HighLevelConfig(games=args.games, batch=args.batch, lr=args.lr, entropy=args.entropy, seed=args.seed, time_limit=args.time_limit,
                         receive_coming=args.receive_coming, receive_attack=args.receive_attack)
    plain = {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(hc).items()}  # JSON / YAML-friendly
    load_before = os.getloadavg()
    start = time.monotonic()
    if not args.skip_train:
        if (out / "high_level.pt").exists():
            raise SystemExit(f"{out / 'high_level.pt'} exists: choose another out=(or skip_train=true to play it)")
        with open(out / "history.jsonl", "w") as log:
            def write(row):
                log.write(json.dumps(row) + "\n")
                log.flush()
                print(json.dumps(row), file=sys.stderr, flush=True)
            net, history = train_high_level(cfg, drills, args.opponent, hc, write)
        info = {"games": history[-1]["games"], "seed": args.seed, "opponent": args.opponent, "config": plain,
                "receive_coming": args.receive_coming, "receive_attack": args.receive_attack}
        save_high_level(net, out / "high_level.pt", info)
    train_s = time.monotonic() - start
    (out / "team.yaml").write_text(yaml.safe_dump(team))
    players = {"learned": str(out / "team.yaml")}
    if rules:
        (out / "rules.yaml").write_text(yaml.safe_dump(rules))
        players["rules"] = str(out / "rules.yaml")
    else:
        players["rules"] = "hierarchical"
    rows = []
    for seed in [int(s) for s in args.eval_seeds.split(",") if s]:
        for vs in [v for v in args.vs.split(",") if v]:
            for name, spec in players.items():
                try:
                    row = {"player": name, **figures(spec, vs, args.eval_games, seed, cfg)}
                except ConfigError as e:
                    raise SystemExit(str(e)) from None
                rows.append(row)
                print(json.dumps({k: row[k] for k in ("player", "vs", "seed", "wdl", "win_rate", "ci95", "touches")}), flush=True)
    result = {"drills": drills, "config": plain,
              "opponent": args.opponent, "train_s": round(train_s, 1), "eval": rows,
              "machine": {"cpus": os.cpu_count(), "load_at_start": load_before, "load_at_end": os.getloadavg(),
                          "platform": platform.platform()}}
    (out / "figures.json").write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
