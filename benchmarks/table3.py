"""Paper table 3's layout for 1 vs 1: for each competitor its average win rate, Elo and Bradley-Terry
rating (with its 95 % profile-likelihood interval), its Nash weight in the cross-play meta-game and its
exploitability within that population, plus the heatmap and the ratings plot.

    python benchmarks/table3.py scripted random                                    # what exists without training
    python benchmarks/table3.py sp=runs/sp fsp=runs/fsp psro_u=runs/psro_uniform psro_n=runs/psro_nash scripted random games=1000

Cross-play plays ``games=`` per pair (both sides equally), Elo runs ``rounds=`` rounds sampled from
the cross-play counts with ``k=`` (the paper: 2000 rounds, K = 168 for 4 policies). The paper's
exploitability column trains a best response against each competitor (``volleybots eval
exploitability``) for ``br_budget=`` frames and plays ``br_games=`` games (0: the column reads "n/a"),
from ``br_init=`` if given, stopping at the convergence criterion or, with ``br_until=budget``, training
the whole budget (equal budgets for every competitor, as the paper compares them); ``br_response=SPEC``
(repeatable) adds a fixed candidate response (``scripted``, ``hierarchical``, a run) beside the trained one,
and the figure is the best candidate's (``br_budget=0`` with a response: fixed candidates only). A
figure that no candidate's criterion holds for is marked as a lower bound. The within-population
exploitability stands beside it. ``reuse=FILE`` (an earlier table3.json or crossplay.json) copies the
pairs it played with the same settings instead of playing them again, so adding a method to a table
plays only its own pairs (``eval crossplay ... reuse=FILE``).
Writes ``table3.json``, ``table3.md``, ``table3_crossplay.png`` and ``table3_ratings.png`` into ``out=``
(default ``outputs/table3``; docs/table3.md is the written-up table, which a run never overwrites), each
naming games, rounds, seed and competitors.
"""

from __future__ import annotations

import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from volleybots.config.args import option, script_options
from volleybots.config.verbs import UNTIL  # the stopping rules eval exploitability knows

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


@dataclass
class Args:
    competitors: list[str] = option(help="run dirs, checkpoints, scripted, random; name=PATH labels one", factory=list, positional="+")
    task: str = option("1v1", "the match")
    games: int = option(1000, "games per pair (even)")
    rounds: int = option(2000, "Elo rounds, sampled from the cross-play counts")
    k: float = option(168.0, "Elo K")
    seed: int = option(0, "seeds the games, the ratings and the best responses")
    batch: int = option(256, "worlds per batch of games")
    out: Path = option(ROOT / "outputs" / "table3", "folder of table3.json, the heatmap and the ratings plot")
    br_budget: int = option(0, "frames of best-response training per competitor (0: no BR column)")
    br_games: int = option(400, "games of each best response against its target")
    br_envs: int = option(128, "envs of best-response training")
    br_init: Optional[str] = option(None, "policy every best response starts from (init=, e.g. zoo:1v1/bc)")
    br_until: str = option(UNTIL[0], "train each best response its whole budget, or until its win rate plateaus", choices=UNTIL)
    br_seeds: int = option(2, "training seeds of each best response (the figure is the best candidate's)")
    br_response: list[str] = option(help="a fixed candidate response beside the trained one (repeatable; eval exploitability's "
                                    "response=)", factory=list)
    reuse: Optional[Path] = option(None, "an earlier crossplay.json or table3.json whose pairs (same settings, same order) are "
                                   "copied, not played")
    br_root: Path = option(ROOT / "outputs" / "table3_br", "where the best responses' run dirs go")


def main(argv=None) -> int:
    a = script_options(Args, argv, __doc__)

    from volleybots.eval.crossplay import crossplay, heatmap, setup
    from volleybots.eval.ranking import plot, ratings

    comps, specs, _, cfg = setup([*a.competitors, f"task={a.task}", f"games={a.games}"])
    a.out.mkdir(parents=True, exist_ok=True)
    reuse = a.reuse
    earlier = json.loads(reuse.read_text()) if reuse is not None else {}
    if "crossplay" in earlier:  # a table3.json: its cross-play part, as the file crossplay() reads
        reuse = a.out / "reused_crossplay.json"
        reuse.write_text(json.dumps(earlier["crossplay"]))
    t0 = time.time()
    res = crossplay(cfg, comps, a.games, seed=a.seed, batch=a.batch, specs=specs, reuse=reuse,
                    progress=lambda i, j, g: print(f"  {comps[i].label} vs {comps[j].label}: W/D/L {g.total.tolist()}", flush=True))
    wall = time.time() - t0
    rep = ratings(res, a.rounds, a.k, a.seed, sample=True)
    rep["exploitability_br"] = [best_response(spec, a) for spec in specs] if a.br_budget or a.br_response else [None] * len(specs)
    heatmap(res, a.out / "table3_crossplay.png")
    plot(rep, a.out / "table3_ratings.png")
    (a.out / "table3.json").write_text(json.dumps({"crossplay": res.to_dict(), "ratings": rep, "wall_time_s": wall}, indent=1) + "\n")
    (a.out / "table3.md").write_text(table(rep, res, a, wall))
    print(table(rep, res, a, wall))
    return 0


def best_response(spec: str, a) -> dict:
    """Exploitability of one competitor: a best response of ``br_budget=`` frames, ``br_games=`` games."""
    from volleybots.eval.exploitability import run_exploitability

    label = spec.partition("=")[0] if "=" in spec else Path(spec).name
    out = a.br_root / f"{label}_{time.strftime('%Y%m%d-%H%M%S')}"
    args = [
        spec,
        f"task={a.task}",
        f"budget={a.br_budget}",
        f"games={a.br_games}",
        f"num_envs={a.br_envs}",
        f"seed={a.seed}",
        f"until={a.br_until}",
        f"seeds={getattr(a, 'br_seeds', 2)}",
        "progress=false",
    ]
    if a.br_init:
        args.append(f"init={a.br_init}")
    args += [f"response={r}" for r in a.br_response]
    report, _ = run_exploitability(args, out)
    print(f"  exploitability of {label}: {report['exploitability']:.1f} {report['exploitability_interval']}", flush=True)
    keys = ("exploitability", "exploitability_interval", "lower_bound", "budget_frames", "games", "wdl", "best", "seeds", "trained")
    return {k: report[k] for k in keys if k in report}


def table(rep: dict, res, a, wall: float) -> str:
    bt, elo = rep["bradley_terry"], rep["elo"]
    lines = [
        f"# Competitive policies on {a.task} (paper table 3)",
        "",
        f"Task {a.task}: {a.games} games per pair (both sides equally), cross-play seed {a.seed}; Elo K={a.k:g} over "
        f"{a.rounds} rounds sampled from the counts; BT with 95 % profile-likelihood intervals; {wall:.0f} s of games"
        + (f" ({len(res.meta['reused'])} of {res.n * (res.n - 1) // 2} pairs copied from {a.reuse})" if res.meta.get("reused") else "")
        + "; "
        + (f"best responses: {a.br_budget:,} frames ({'the whole budget' if a.br_until == 'budget' else 'or until a plateau'}"
           f"{f', from {a.br_init}' if a.br_init else ''}), {a.br_games} games each" if a.br_budget else "no best responses trained")
        + (f"; fixed candidate responses: {', '.join(a.br_response)}." if a.br_response else "."),
        "",
        "| competitor | exploitability (BR) | exploitability in population (pp) | avg win rate | Elo | Bradley-Terry "
        "[95 %] | Nash weight |",
        "|---|---|---|---|---|---|---|",
    ]
    for i, lab in enumerate(rep["labels"]):
        avg = rep["average_win_rate"][i]
        lines.append(
            f"| {lab} | {_br(rep['exploitability_br'][i])} | {rep['exploitability_in_population'][i]:.1f} | "
            f"{'n/a' if avg is None else f'{avg:.3f}'} | "
            f"{elo['ratings'][i]:.0f} | {bt['ratings'][i]:.0f} [{bt['low'][i]:.0f}, {bt['high'][i]:.0f}] | {rep['nash'][i]:.3f} |"
        )
    return "\n".join(lines) + "\n"


def _br(r) -> str:
    """A lower bound (every figure is), the candidate that gave it and the training seeds' spread."""
    if r is None:
        return "n/a"
    lo, hi = r["exploitability_interval"]
    by = f", by {r['best']}" if r.get("best") else ""
    seeds = (r.get("seeds") or {}).get("points") or {}
    spread = f"; seeds {min(seeds.values()):.1f} to {max(seeds.values()):.1f}" if len(seeds) > 1 else ""
    return f">= {r['exploitability']:.1f} [{lo:.1f}, {hi:.1f}]{by}{spread}"


if __name__ == "__main__":
    sys.exit(main())
