"""The empirical payoff table of a population: W/D/L counts per ordered pair of members.

The counts are one record ``wdl`` of shape ``[n, n, 3]`` (``volleybots.ratings.record``): those of ``(i, j)`` are
from member ``i``'s side and ``(j, i)`` holds the mirror image, so the zero-sum payoff matrix
``(wins - losses) / games`` is antisymmetric. A member against itself has payoff 0 by the symmetry of
the court and is not played. Entries are added as members join, never recomputed.

Every entry carries its uncertainty, from the counts alone (so a saved table's can be recomputed):

* ``payoff_interval``: the normal (Wald) 95 % interval of the mean game score, each game scoring
  +1 / 0 / -1, i.e. payoff +- 1.96 x the scores' standard deviation / sqrt(games); it collapses to a
  point when every game had one outcome, so it is read beside
* ``win_rate`` / ``win_rate_interval``: the share of decisive games the row won and its Wilson 95 %
  interval, which does not collapse at 0 or 1 (nan where no game was decisive).

With 60 games an entry the payoff's interval is about +-0.2 to +-0.25 wide on each side, so a
meta-solver fitted to such a table fits noise of that size; more ``payoff_games`` narrow it as
1 / sqrt(games).

``payoffs.json`` holds the counts under ``wdl`` (``[n][n][3]``, as ``crossplay.json`` does). A table
written before that held three ``[n][n]`` matrices ``wins``, ``draws`` and ``losses``; it still loads, so
that a population run resumes across the upgrade.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from volleybots.files import Fields, read_json, write_atomic
from volleybots.ratings import record  # a leaf too: numpy / scipy only

Z95 = 1.959963984540054  # the standard normal's 97.5 % quantile: two-sided 95 % intervals


def payoff_reserve(payoff_seconds: float, members: int) -> float:
    """The seconds a new member's payoff games against ``members`` others should take, at the mean
    time per pair of the ``members x (members - 1) / 2`` pairs played so far in ``payoff_seconds``
    (0 before any pair was played: the first estimate comes after the first games)."""
    played = members * (members - 1) // 2
    return payoff_seconds / played * members if played else 0.0


class PayoffTable:
    def __init__(self, labels: list[str] | None = None, wdl=None):
        self.labels = list(labels or [])
        n = len(self.labels)
        self.wdl = np.array(np.zeros((n, n, 3)) if wdl is None else wdl, dtype=np.int64).reshape(n, n, 3)

    def __len__(self) -> int:
        return len(self.labels)

    def add_member(self, label: str, results) -> None:
        """A new row and column: ``results[j]`` holds the new member's [3] W/D/L against member ``j``."""
        n = len(self)
        if len(results) != n:
            raise ValueError(f"a new member needs results against all {n} members, got {len(results)}")
        self.wdl = np.pad(self.wdl, ((0, 1), (0, 1), (0, 0)))
        for j, r in enumerate(results):
            record.put(self.wdl, n, j, np.asarray(r, dtype=np.int64))
        self.labels.append(label)

    @property
    def games(self) -> np.ndarray:
        return record.games(self.wdl)

    def matrix(self) -> np.ndarray:
        """The zero-sum payoff of the row member, (wins - losses) / games (0 where none were played)."""
        return record.payoff(self.wdl)

    def payoff_interval(self) -> np.ndarray:
        """[n, n, 2]: the normal 95 % interval of each entry's mean game score (nan where none were played)."""
        g = self.games.astype(float)
        mean = self.matrix()
        with np.errstate(invalid="ignore", divide="ignore"):
            second = record.decisive(self.wdl) / g  # E[score^2]: wins and losses score +-1, draws 0
            half = Z95 * np.sqrt(np.clip(second - mean**2, 0.0, None) / g)
        lo = np.where(g > 0, np.clip(mean - half, -1.0, 1.0), np.nan)
        hi = np.where(g > 0, np.clip(mean + half, -1.0, 1.0), np.nan)
        return np.stack([lo, hi], -1)

    def win_rate(self) -> tuple[np.ndarray, np.ndarray]:
        """The row's share of decisive games [n, n] and its Wilson 95 % interval [n, n, 2] (nan: none decisive)."""
        lo, hi = record.win_rate_interval(self.wdl)
        return record.win_rate(self.wdl), np.stack([np.asarray(lo, float), np.asarray(hi, float)], -1)

    def to_json(self) -> dict:
        rate, rate_ci = self.win_rate()
        return {
            "members": self.labels,
            "wdl": self.wdl.tolist(),  # [i][j] = [wins, draws, losses] of i against j
            "games": self.games.tolist(),
            "payoff": self.matrix().tolist(),
            "payoff_interval": _json(self.payoff_interval()),  # [i][j] = [low, high]
            "win_rate": _json(rate),
            "win_rate_interval": _json(rate_ci),  # [i][j] = [low, high]
        }

    def save(self, path: Path) -> None:
        write_atomic(path, json.dumps(self.to_json(), indent=1) + "\n")

    @classmethod
    def load(cls, path: Path) -> "PayoffTable":
        """The table saved at ``path`` (empty if there is none), in either layout (module docstring); a
        damaged file is one line naming it."""
        path = Path(path)
        if not path.is_file():
            return cls()
        data = read_json(path, "payoff table")
        f = Fields(data, f"payoff table {str(path)!r}")
        labels = f.need("members", list)
        n = len(labels)
        if "wdl" in data or not any(k in data for k in record.KEYS):
            wdl = f.counts("wdl", (n, n, 3))
        else:
            wdl = record.from_dict({k: f.counts(k, (n, n)) for k in record.KEYS}).tolist()
        f.mirrored("wdl", wdl)  # a table whose mirror disagrees would be solved as another game
        if not all(isinstance(x, str) for x in labels):
            f.fail("'members' must be a list of labels")
        return cls(labels, wdl)


def _json(a: np.ndarray) -> list:
    """Nested lists with None for nan (JSON has no nan)."""
    return np.where(np.isnan(a), None, a).tolist()


def plot(table: PayoffTable, mixture, path: Path, title: str = "") -> None:
    """The payoff matrix as a heatmap beside the meta-strategy's bars (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(table)
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(4 + 0.6 * n, 2.5 + 0.45 * n), gridspec_kw={"width_ratios": [3, 1]})
    m = table.matrix()
    im = ax.imshow(m, cmap="RdBu", vmin=-1, vmax=1)
    ax.set_xticks(range(n), table.labels, rotation=60, ha="right", fontsize=7)
    ax.set_yticks(range(n), table.labels, fontsize=7)
    for i in range(n):
        for j in range(n):
            ax.text(j, i, f"{m[i, j]:+.2f}", ha="center", va="center", fontsize=6)
    ax.set_title("payoff of row vs column\n(wins - losses) / games", fontsize=8)
    fig.colorbar(im, ax=ax, fraction=0.046)
    bx.barh(range(n), mixture)
    for i, w in enumerate(mixture):
        bx.text(min(w + 0.03, 0.7), i, f"{w:.2f}", va="center", fontsize=7)
    bx.set_yticks(range(n), [""] * n)
    bx.invert_yaxis()
    bx.set_xlim(0, 1)
    bx.set_title("meta-strategy", fontsize=8)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    try:
        write_atomic(path, lambda fh: fig.savefig(fh, format="png", dpi=110), "the payoff plot")
    finally:
        plt.close(fig)
