"""Table 3's ratings on two evaluation seeds, side by side, and which claims hold on both.

    python benchmarks/table3_seeds.py A/ratings.json B/ratings.json out=results/table3/two_seeds.md

Each file is what ``volleybots eval elo`` wrote (the same competitors, two cross-play seeds). For
every competitor: Bradley-Terry on decisive games with its 95 % interval, the paper's Elo with its
95 % range over game orders, the draw rate, the Nash weight with the share of resampled payoff tables
in which it carries weight, and the win rate against ``scripted`` with its Wilson interval. A pair is
called ordered only where the Bradley-Terry intervals do not overlap on both seeds; otherwise a tie.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from volleybots.config.args import option, script_options

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def vs(report: dict, name: str, other: str):
    """(win rate, low, high, W/D/L) of ``name`` against ``other`` from the report's cross-play file."""
    from volleybots.eval.crossplay import CrossPlay

    cp = CrossPlay.load(report["source"])
    i, j = cp.labels.index(name), cp.labels.index(other)
    lo, hi = cp.interval()
    return float(cp.win_rate()[i, j]), float(lo[i, j]), float(hi[i, j]), [int(x) for x in cp.wdl[i, j]]


@dataclass
class Args:
    reports: list[Path] = option(help="the two seeds' table3.json reports", factory=list, positional="+")
    out: Path = option(ROOT / "results" / "table3" / "two_seeds.md", "where the results go")


def main(argv=None) -> int:
    a = script_options(Args, argv, __doc__)
    reps = [json.loads(r.read_text()) for r in a.reports]
    labels = reps[0]["labels"]
    if reps[1]["labels"] != labels:
        raise SystemExit(f"the two reports rate different competitors: {labels} / {reps[1]['labels']}")
    seeds = [r["crossplay"]["seed"] for r in reps]
    lines = [f"# Table 3 (1v1) on cross-play seeds {seeds[0]} and {seeds[1]}", "",
             "| competitor | " + " | ".join(f"{h} (seed {s})" for s in seeds for h in ("BT [95 %]", "Elo; over orders", "draws",
                                                                                        "Nash (carries)", "vs scripted")) + " |",
             "|---|" + "---|" * 10]
    for i, lab in enumerate(labels):
        cells = []
        for r in reps:
            bt, e, s = r["bradley_terry"], r["elo"], r["nash_sensitivity"]
            w = vs(r, lab, "scripted") if lab != "scripted" else None
            cells += [f"{bt['ratings'][i]:.0f} [{bt['low'][i]:.0f}, {bt['high'][i]:.0f}]",
                      f"{e['ratings'][i]:.0f}; {e['order_mean'][i]:.0f} [{e['order_low'][i]:.0f}, {e['order_high'][i]:.0f}]",
                      f"{r['draw_rate'][i]:.2f}", f"{r['nash'][i]:.2f} ({s['carries_weight'][i]:.2f})",
                      "-" if w is None else f"{w[0]:.3f} [{w[1]:.2f}, {w[2]:.2f}]"]
        lines.append(f"| {lab} | " + " | ".join(cells) + " |")
    ordered, ties = [], []
    for i in range(len(labels)):
        for j in range(len(labels)):
            if i == j:
                continue
            sep = [r["bradley_terry"]["low"][i] > r["bradley_terry"]["high"][j] for r in reps]
            if all(sep):
                ordered.append(f"{labels[i]} > {labels[j]}")
            elif i < j and not any(r["bradley_terry"]["low"][j] > r["bradley_terry"]["high"][i] for r in reps):
                ties.append(f"{labels[i]} ~ {labels[j]}")
    lines += ["", f"Ordered on both seeds (Bradley-Terry intervals apart on each): {', '.join(ordered) or 'none'}.", "",
              f"Ties (intervals overlap on at least one seed): {', '.join(ties) or 'none'}.", ""]
    rho = np.corrcoef(np.argsort(np.argsort(reps[0]["elo"]["ratings"])), np.argsort(np.argsort(reps[1]["elo"]["ratings"])))[0, 1]
    rho_bt = np.corrcoef(np.argsort(np.argsort(reps[0]["bradley_terry"]["ratings"])),
                         np.argsort(np.argsort(reps[1]["bradley_terry"]["ratings"])))[0, 1]
    lines.append(f"Rank correlation between the seeds: paper Elo {rho:.2f}, Bradley-Terry {rho_bt:.2f}.")
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
