"""The headline's figures: a competitor (a population run, a zoo entry) against the issue's yardsticks,
on held-out seeds, under the paper's rule (a fall ends the match drawn) and the volleyball rule (a fall
is its team's fault, ``task.fall_fault=true``).

    python benchmarks/headline.py COMPETITOR task=3v3 seeds=9200,9201 games=200 \\
        vs=scripted,hierarchical,zoo:3v3/hcsp_return,zoo:3v3/sp_noanchor out=results/headline/3v3.json

Per seed, rule and opponent: W/D/L, the win rate of decisive games with its Wilson interval, serving
and receiving W/D/L (the receiving win rate of decisive games too), touches and faults; then the
average win rate over the opponents. Written to ``out=`` with the machine's load before and after.
"""

from __future__ import annotations

import json
import os
import platform
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from volleybots.config import load
from volleybots.config.args import option, script_options
from volleybots.play.games import play_games
from volleybots.policies import resolve_competitor
from volleybots.ratings.intervals import wilson_interval

RULES = {"paper": "false", "volleyball": "true"}


def rate(w: int, lost: int) -> tuple[float | None, list[float]]:
    if w + lost == 0:
        return None, [float("nan"), float("nan")]
    lo, hi = wilson_interval(w, w + lost)
    return w / (w + lost), [round(float(lo), 3), round(float(hi), 3)]


def row(team, opponent: str, cfg, games: int, seed: int) -> dict:
    g = play_games(cfg, team, resolve_competitor(opponent), games, seed=seed)
    w, d, lost = (int(x) for x in g.total)
    c = g.content()
    win, ci = rate(w, lost)
    rw, _, rl = c["receive_wdl"]
    return {"vs": opponent, "seed": seed, "games": games, "wdl": [w, d, lost], "win_rate": win, "ci95": ci,
            "serve_wdl": c["serve_wdl"], "receive_wdl": c["receive_wdl"], "receive_win_rate": rate(rw, rl)[0],
            "touches": c["touches"], "faults": c["faults"]}


@dataclass
class Args:
    competitor: Optional[str] = option(None, "", positional=True)
    task: str = option("3v3", "the match task")
    seeds: str = option("9200,9201", "comma-separated held-out cross-play seeds")
    games: int = option(200, "games a pair on each seed")
    vs: str = option("scripted,hierarchical,zoo:3v3/hcsp_return,zoo:3v3/sp_noanchor", "comma-separated opponents")
    rules: str = option("paper,volleyball", "the fall rules played: paper (a fall is a draw), volleyball (a fault)")
    out: Optional[str] = option(None, "where the figures are written (JSON)")


def main(argv=None) -> int:
    args = script_options(Args, argv, __doc__)
    out = Path(args.out)
    if out.exists():
        raise SystemExit(f"{out} exists: choose another out=")
    team = resolve_competitor(args.competitor)
    load0, t0 = os.getloadavg(), time.monotonic()
    rows = []
    for rule in [r for r in args.rules.split(",") if r]:
        cfg = load([f"task={args.task}", f"task.fall_fault={RULES[rule]}"])
        for seed in [int(s) for s in args.seeds.split(",") if s]:
            for vs in [v for v in args.vs.split(",") if v]:
                r = {"rule": rule, **row(team, vs, cfg, args.games, seed)}
                rows.append(r)
                print(json.dumps({k: r[k] for k in ("rule", "vs", "seed", "wdl", "win_rate", "ci95", "receive_wdl")}), flush=True)
    summary = {}
    for rule in {r["rule"] for r in rows}:
        for seed in {r["seed"] for r in rows}:
            rates = [r["win_rate"] for r in rows if r["rule"] == rule and r["seed"] == seed and r["win_rate"] is not None]
            summary[f"{rule}/{seed}"] = round(sum(rates) / len(rates), 4) if rates else None
    result = {"competitor": args.competitor, "task": args.task, "members": [m.label for m in team.members],
              "mixture": [float(w) for w in team.mixture], "rows": rows, "average_win_rate": summary,
              "wall_s": round(time.monotonic() - t0, 1),
              "machine": {"cpus": os.cpu_count(), "load_at_start": load0, "load_at_end": os.getloadavg(), "platform": platform.platform()}}
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
