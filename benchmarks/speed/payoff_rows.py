"""Payoff rows in one batch against pair by pair: a population run's payoff table replayed from its
member files, every row timed as the population loop plays it now (``volleybots.play.pool.payoff_row``),
then the last row again pair by pair (``play_games``), as the loop played it before.

    python benchmarks/speed/payoff_rows.py RUN [games=100] [out=payoff_rows.json]

Prints and writes each row's seconds with the load average at its start. One torch thread.
"""

from __future__ import annotations

import json
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from volleybots.config.args import option, script_options  # noqa: E402


@dataclass
class Args:
    run: Optional[Path] = option(None, "a population run dir (its population/member_*.pt)", positional=True)
    games: int = option(100, "games per entry (the run's algo.payoff_games)", ge=2)
    out: Optional[Path] = option(None, "FILE: also write the rows here (JSON)")


def main(argv=None) -> int:
    a = script_options(Args, argv, __doc__)
    if a.run is None:
        raise SystemExit("error: name the population run: payoff_rows.py RUN")

    import torch

    from volleybots.play.games import play_games
    from volleybots.play.pool import payoff_row
    from volleybots.policies.competitors import Competitor, checkpoint_member
    from volleybots.runs import RunDir
    from volleybots.runs.contents import population_members

    torch.set_num_threads(1)
    cfg = RunDir(a.run).load_config()
    paths = population_members(a.run)
    comp = [Competitor(f"m{k}", [checkpoint_member(path)]) for k, path in enumerate(paths)]
    out = {"run": str(a.run), "task": cfg.task.name, "games": a.games, "rows": []}
    for k in range(1, len(comp)):
        load, t = os.getloadavg()[0], time.time()
        payoff_row(cfg, comp[k], comp[:k], a.games, 1000 + k)
        out["rows"].append({"entries": k, "seconds": time.time() - t, "load": load})
        print(out["rows"][-1], flush=True)
    load, t = os.getloadavg()[0], time.time()
    for j in range(len(comp) - 1):
        play_games(cfg, comp[-1], comp[j], a.games, seed=2000 + j)
    out["last_row_pair_by_pair"] = {"entries": len(comp) - 1, "seconds": time.time() - t, "load": load}
    out["table_seconds"] = sum(r["seconds"] for r in out["rows"])
    print(out["last_row_pair_by_pair"], "table in chunks:", round(out["table_seconds"], 1), "s", flush=True)
    if a.out is not None:
        a.out.write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
