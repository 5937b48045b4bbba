"""A learned 3 vs 3 team (the HCSP route): a high level trained by RL over drills, then played.

    python benchmarks/hcsp.py --drills-dir RUNS --out DIR [--games 4096] [--batch 256] [--seed 1]
                              [--opponent scripted] [--eval-games 400] [--eval-seeds 9100,9101]
                              [--vs scripted,hierarchical]

1. ``--drills-dir``: the folder of a ``benchmarks/hierarchical.py --learn`` invocation (its
   ``<drill>_ppo`` runs, else ``<drill>_bc``; the drills it lacks stay scripted); ``--drills
   serve=CKPT,...`` names them one by one; neither: scripted drills.
2. The high level (``volleybots.train.high_level``) is trained against ``--opponent`` for
   ``--games`` games (``--time-limit`` seconds at most), seed ``--seed``; it is saved as
   ``DIR/high_level.pt``, the team as ``DIR/team.yaml`` (``hierarchical: {drill: run, high_level: file}``,
   a competitor like any other: ``volleybots eval crossplay hcsp=DIR/team.yaml scripted task=3v3``),
   the per-batch history as ``DIR/history.jsonl``.
3. The learned team and, as the baseline, the rules over the same drills (``DIR/rules.yaml``) play
   ``--eval-games`` games against each of ``--vs`` on each of ``--eval-seeds`` (seeds no setting was
   chosen on): W/D/L, the win rate of decisive games with its Wilson interval, touches and serve /
   receive W/D/L. Written to ``DIR/figures.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from dataclasses import asdict
from pathlib import Path

import yaml

from volleybots.config import load
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--drills-dir", default="")
    ap.add_argument("--drills", default="", help="drill=checkpoint,... (the others scripted)")
    ap.add_argument("--out", required=True)
    ap.add_argument("--opponent", default="scripted")
    ap.add_argument("--games", type=int, default=4096)
    ap.add_argument("--batch", type=int, default=256)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--entropy", type=float, default=0.01)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--receive-coming", action="store_true", help="call a receiver only for balls coming down in the own half")
    ap.add_argument("--receive-attack", action="store_true", help="a front drone called to receive returns the ball at once (attack drill)")
    ap.add_argument("--time-limit", type=float, default=0.0)
    ap.add_argument("--eval-games", type=int, default=400)
    ap.add_argument("--eval-seeds", default="9100,9101")
    ap.add_argument("--vs", default="scripted,hierarchical")
    ap.add_argument("--skip-train", action="store_true", help="play the DIR's high level again (no training)")
    args = ap.parse_args(argv)
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
            raise SystemExit(f"{out / 'high_level.pt'} exists: choose another --out (or --skip-train to play it)")
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
