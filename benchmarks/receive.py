"""How well a 1v1 player receives: serves returned, against the ace serve and the scripted serve.

    python benchmarks/receive.py RECEIVER [RECEIVER ...] servers=[zoo:1v1/sp_noanchor,scripted] games=100 seed=9600 [json=OUT]

Each RECEIVER (a competitor: ``receiver``, ``scripted``, a run dir, a zoo entry, ...) receives
``games`` serves of each server (``volleybots eval crossplay``'s ``scenario=receive``: the server
serves every game, half of them from each side). A serve is **returned** when the receiver touched
the ball and the touch did not lose the point: the server touched the ball again or the receiver won
the point. Reported per pair: returned, touched (any first touch), body hits (the receiver's touch
was the body's), the receiver's W/D/L and the touches and rally length of the games.
docs/receive.md quotes these figures.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np
import torch

from volleybots.config import load
from volleybots.config.args import option, script_options
from volleybots.play.games import play_games
from volleybots.policies import resolve_competitor
from volleybots.rules import Referee


def receive_record(games) -> dict:
    """The receive figures of ``games`` played with ``scenario=receive`` (A receives every serve)."""
    touched = games.touches[:, 0] >= 1
    won = np.array([o == "W" for o in games.outcomes])
    returned = touched & ((games.touches[:, 1] >= 2) | won)
    content = games.content()
    return {
        "games": games.games, "returned": int(returned.sum()), "touched": int(touched.sum()),
        "body_hits": int(games.faults[0, Referee.FAULTS.index("body_hit")]),
        "wdl": games.total.tolist(), "touches_per_game": content["rally_touches"], "rally_steps": content["rally_steps"],
        "faults": content["faults"],
    }


def measure(receiver, server: str, games: int, seed: int, task: str = "1v1") -> dict:
    cfg = load([f"task={task}", "threads=1"])
    rec = resolve_competitor(receiver) if isinstance(receiver, str) else receiver
    g = play_games(cfg, rec, resolve_competitor(server), games, seed=seed, scenario="receive")
    return receive_record(g)


@dataclass
class Args:
    receivers: list[str] = option(help="the receiving competitors (one row each)", factory=lambda: [], positional="+")
    servers: list[str] = option(help="the serving competitors", factory=lambda: ["zoo:1v1/sp_noanchor", "scripted"])
    games: int = option(100, "games played")
    seed: int = option(9600, "the seed")
    json: Optional[Path] = option(None, "also write the results here")


def main() -> None:
    a = script_options(Args, None, __doc__)
    torch.set_num_threads(1)
    rows = []
    for r in a.receivers:
        for s in a.servers:
            t0 = time.perf_counter()
            row = {"receiver": r, "server": s, "seed": a.seed, **measure(r, s, a.games, a.seed)}
            row["wall_s"] = round(time.perf_counter() - t0, 1)
            print(json.dumps(row), flush=True)
            rows.append(row)
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps({"games": a.games, "seed": a.seed, "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
