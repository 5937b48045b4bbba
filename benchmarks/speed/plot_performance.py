"""Bar chart of docs/performance.md's "Current figures": env-steps/s of torch eager, torch compiled and
MuJoCo per task and core count (4096 envs, random actions, median of 3 repeats).

    python benchmarks/speed/plot_performance.py out=outputs/performance/performance.png
    python benchmarks/speed/plot_performance.py json=bench.json out=...   # rows of bench.py json=FILE instead

The figures below are the page's table (measured with `bench.py both=true threads=2`, then `threads=1`,
on the 2-core machine with nothing else running); the PNG the page shows is this script's output copied
to docs/img/results/performance.png. With `json=FILE`, the rows of one `bench.py json=FILE` file are drawn
instead (one group per task and thread count found in it).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from volleybots.config.args import option, script_options

# (task, threads) -> env-steps/s: torch eager, torch compiled, MuJoCo, and the table's compiled / MuJoCo
# ratio (from the unrounded rates, so it can differ from the rounded figures' in the last digit)
# (docs/performance.md, "Current figures")
FIGURES = {
    ("solo_bump", 2): (365.3e3, 1.56e6, 105.6e3, 14.7),
    ("3v3", 2): (94.6e3, 390.7e3, 28.9e3, 13.5),
    ("solo_bump", 1): (404.8e3, 1.25e6, 66.6e3, 18.8),
    ("3v3", 1): (85.1e3, 215.5e3, 18.2e3, 11.9),
}
SERIES = ("torch eager", "torch compiled", "MuJoCo")


def figures_from_json(path: Path) -> dict[tuple[str, int], tuple[float, ...]]:
    """(task, threads) -> (eager, compiled, mujoco, compiled / mujoco) from the rows `bench.py json=FILE`
    writes (a missing rate: 0)."""
    rows = json.loads(path.read_text())
    out: dict[tuple[str, int], list[float]] = {}
    for r in rows:
        if r.get("kind", "env") != "env":  # the training rows of train=true
            continue
        key = (r["task"], int(r.get("threads", 1)))
        col = 2 if r.get("backend") == "mujoco" else (1 if r.get("compile") else 0)
        out.setdefault(key, [0.0, 0.0, 0.0])[col] = float(r["env_steps_per_s"])
    return {k: (*v, v[1] / v[2] if v[2] else 0.0) for k, v in out.items()}


def plot(figures: dict, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    keys = list(figures)
    x = np.arange(len(keys))
    width = 0.27
    fig, ax = plt.subplots(figsize=(7.5, 3.6), dpi=110)
    colors = ("#9ecae1", "#2171b5", "#fd8d3c")
    for i, (name, color) in enumerate(zip(SERIES, colors, strict=True)):
        values = [figures[k][i] for k in keys]
        bars = ax.bar(x + (i - 1) * width, values, width, label=name, color=color)
        for bar, v in zip(bars, values, strict=True):
            label = f"{v / 1e6:.2f}M" if v >= 1e6 else f"{v / 1e3:.0f}k"
            ax.annotate(label, (bar.get_x() + bar.get_width() / 2, v), ha="center", va="bottom", fontsize=7,
                        xytext=(0, 1), textcoords="offset points")
    def tick(task: str, threads: int) -> str:
        ratio = figures[(task, threads)][3]
        ratio = f"\ncompiled {ratio:.1f}x MuJoCo" if ratio else ""
        return f"{task}, {threads} core{'s' if threads > 1 else ''}{ratio}"

    ax.set_xticks(x, [tick(*k) for k in keys], fontsize=8)
    ax.set_yscale("log")
    ax.set_ylabel("env-steps per second")
    ax.set_title("4096 envs, random actions, median of 3 repeats (equal cores)", fontsize=9)
    ax.legend(fontsize=8, loc="upper right", ncols=3)
    ax.set_ylim(top=max(max(v[:3]) for v in figures.values()) * 4)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)


@dataclass
class Args:
    out: Path = option(Path("outputs/performance/performance.png"), "the PNG to write")
    json: Optional[Path] = option(None, "rows of `bench.py json=FILE` to draw instead of the page's figures")


def main(argv=None) -> int:
    args = script_options(Args, argv, __doc__)
    plot(figures_from_json(args.json) if args.json else FIGURES, args.out)
    print(args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
