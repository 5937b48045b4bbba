"""The views of a cross-play: the win-rate heatmap (PNG) and the terminal table (rich)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from volleybots.eval.plain import clean, plain
from volleybots.files import write_atomic


def heatmap(result, path: Path, title: str | None = None) -> None:
    """A PNG of the win-rate matrix (row against column), each cell with its Wilson interval, and the
    average win rate per row; the title names the task, games per pair and seed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    wr = result.win_rate()
    lo, hi = result.interval()
    n = result.n
    touches = _touch_cells(result)
    fig, ax = plt.subplots(figsize=(1.6 * n + 3, 1.2 * n + 1.5))
    im = ax.imshow(np.ma.masked_invalid(wr), cmap="RdBu", vmin=0, vmax=1)
    for i in range(n):
        for j in range(n):
            w, d, l_ = result.wdl[i, j].astype(int)
            if np.isfinite(wr[i, j]):
                colour = "white" if abs(wr[i, j] - 0.5) > 0.3 else "black"
                cell = f"{wr[i, j]:.2f}\n[{lo[i, j]:.2f}, {hi[i, j]:.2f}]\n{w}/{d}/{l_}{touches[i][j]}"
                ax.text(j, i, cell, ha="center", va="center", fontsize=8, color=colour)
            elif i != j:
                ax.text(j, i, f"no decisive\ngame{touches[i][j]}", ha="center", va="center", fontsize=7, color="grey")
    avg = result.average_win_rate()
    names = [clean(lab) for lab in result.labels]  # a label from a results file may hold control characters
    ax.set_xticks(range(n), names, rotation=30, ha="right")
    ax.set_yticks(range(n), [f"{lab}  (avg {a:.2f})" for lab, a in zip(names, avg)])
    ax.set_xlabel("opponent (column); cells: win rate [Wilson 95 %], W/D/L" + (", touches per game row/column" if result.content else ""))
    m = result.meta
    ax.set_title(title or f"{m.get('task')} cross-play: win rate of row over decisive games\n"
                 f"{m.get('games_per_pair')} games per pair, seed {m.get('seed')}, scenario {m.get('scenario')}", fontsize=9)
    fig.colorbar(im, ax=ax, fraction=0.046)
    fig.tight_layout()
    try:
        write_atomic(path, lambda fh: fig.savefig(fh, format="png", dpi=120), "the heatmap")
    finally:
        plt.close(fig)


def _touch_cells(result) -> list[list[str]]:
    """Per cell, a line "t ROW/COL": touches per game of the row and of the column ("" without content)."""
    cells = [[""] * result.n for _ in range(result.n)]
    for key, c in result.content.items():
        i, j = map(int, key.split(","))
        if c.get("games"):
            a, b = c["touches"]
            cells[i][j], cells[j][i] = f"\nt {a:.1f}/{b:.1f}", f"\nt {b:.1f}/{a:.1f}"
    return cells


def format_table(result):
    """A rich table: win rate [interval] (W/D/L) per cell, and the average win rate."""
    from rich.table import Table

    wr = result.win_rate()
    lo, hi = result.interval()
    m = result.meta
    table = Table(
        title=plain(f"cross-play on {m.get('task')} ({m.get('games_per_pair')} games per pair, seed {m.get('seed')}): "
                    "row's win rate over decisive games")
    )
    table.add_column("")
    for lab in result.labels:
        table.add_column(plain(lab), justify="right")
    table.add_column("avg win rate", justify="right")
    for i, lab in enumerate(result.labels):
        cells = []
        for j in range(result.n):
            w, d, l_ = result.wdl[i, j].astype(int)
            if i == j:
                cells.append("-")
            elif np.isfinite(wr[i, j]):
                cells.append(f"{wr[i, j]:.3f} [{lo[i, j]:.2f}, {hi[i, j]:.2f}]\n{w}/{d}/{l_}")
            else:
                cells.append(f"n/a\n{w}/{d}/{l_}")
        table.add_row(plain(lab), *cells, f"{result.average_win_rate()[i]:.3f}")
    return table


# ------------------------------------------------------------------ command line
