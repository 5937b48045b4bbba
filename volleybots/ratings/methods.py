"""The rating methods of ``volleybots eval elo``, registered by name in ``RATINGS`` as the meta-solvers are
in ``SOLVERS`` (docs/evaluation.md says what each one answers and where it misleads).

A method is a ``Rating``: it rates a record of games (``Games``) into the report keys it owns, names its
columns of the table and fills them for each competitor, says its part of the table's title, and may
draw. The verb (``volleybots.eval.ranking``) loops over ``RATINGS`` in its order and knows no method by
name, so a method added here (or registered by a test or a plug-in) is computed, tabled and plotted
with no edit elsewhere.

Built in, in table order:

* ``elo``: the paper's sequential Elo over rounds in which every pair meets once, with its spread over
  seeded game orders (``volleybots.ratings.elo``);
* ``bradley_terry``: Firth-penalised Bradley-Terry on decisive games with 95 % profile-likelihood
  intervals, each competitor's draw rate beside (``volleybots.ratings.bradley_terry``);
* ``win_rate``: each competitor's mean win rate against the others (``volleybots.ratings.record``);
* ``nash``: the maximum-entropy Nash mixture of the zero-sum meta-game, how often each competitor
  carries weight in it on resampled tables, and each one's exploitability within the population
  (``volleybots.ratings.solvers``).

Like the rest of ``volleybots.ratings`` this is a leaf of numpy and scipy: plotting methods are handed
matplotlib axes and never import it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import numpy as np

from volleybots.ratings import record
from volleybots.ratings.bradley_terry import bradley_terry_intervals
from volleybots.ratings.elo import ELO_K, ELO_START, elo_games, elo_history, elo_orders
from volleybots.ratings.solvers import exploitability, member_exploitability, nash, nash_sensitivity

ROUNDS = 2000  # Elo rounds, every pair meeting once a round
ORDERS = 100  # seeded game orders over which Elo's spread is reported
RESAMPLES = 200  # resampled payoff tables over which the Nash weights' sensitivity is reported
TRAJECTORY_POINTS = 200  # rounds of Elo's trajectory kept in the report (all of them when fewer)


@dataclass(frozen=True)
class Games:
    """What a method rates: the competitors' labels, their counts ``wdl`` [n, n, 3] (wins, draws and
    losses of the row against the column), the game-by-game ``outcomes`` when they were kept ("a,b" ->
    W/D/L letters from a's side, a < b; empty when only counts are known), the ``seed`` of any random
    draw, and the verb's ``settings`` (``rounds``, ``k``, ``sample``, ``orders``, ``resamples``): each
    method reads those it uses, with its own default."""

    labels: list[str]
    wdl: np.ndarray
    outcomes: Mapping[str, str] = field(default_factory=dict)
    seed: int = 0
    settings: Mapping[str, Any] = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.labels)


def _no_title(report: dict) -> str:
    return ""


@dataclass(frozen=True)
class Rating:
    """One rating method.

    Attributes:
        rate: ``rate(games) -> dict``: the report keys the method owns, JSON-ready (lists, not arrays).
        columns: the names of its table columns.
        cells: ``cells(report, i)``: competitor i's cells under ``columns``, as text, read off the report
            (so a report loaded from ``ratings.json`` tables as well as a fresh one).
        title: ``title(report)``: its part of the table's title ("" for none).
        plot: ``plot(report, ax, x)`` draws its ratings on the shared panel of ratings on the Elo scale,
            competitor i at ``x[i]`` (each method keeps its own small offset beside it); None: it draws none.
        panel: ``panel(report, ax)`` draws a panel of its own (Elo's trajectory); None: it has none.
    """

    rate: Callable[[Games], dict]
    columns: tuple[str, ...]
    cells: Callable[[dict, int], tuple[str, ...]]
    title: Callable[[dict], str] = _no_title
    plot: Callable[[dict, Any, np.ndarray], None] | None = None
    panel: Callable[[dict, Any], None] | None = None


# ------------------------------------------------------------------ Elo
def _trajectory_rounds(rounds: int) -> list[int]:
    return sorted({int(r) for r in np.linspace(0, rounds - 1, min(TRAJECTORY_POINTS, rounds))})


def _rate_elo(g: Games) -> dict:
    rounds, k, orders = g.settings.get("rounds", ROUNDS), g.settings.get("k", ELO_K), g.settings.get("orders", ORDERS)
    sample = g.settings.get("sample", False)
    games, how = elo_games(g.wdl, g.outcomes, rounds, np.random.default_rng(g.seed), sample)
    pairs = g.n * (g.n - 1) // 2
    history = elo_history(games, g.n, k)
    points = _trajectory_rounds(rounds)
    spread = elo_orders(g.wdl, rounds, orders, g.seed, k, outcomes=None if sample else g.outcomes)
    return {"elo": {
        "k": k, "start": ELO_START, "rounds": rounds, "games": how, "seed": g.seed, "ratings": history[-1].tolist(),
        "trajectory_rounds": [r + 1 for r in points], "trajectory": history[[(r + 1) * pairs for r in points]].tolist(),
        # the same Elo over `orders` other seeded orders: what the order alone moves it by
        "orders": orders, "order_mean": spread.mean(0).tolist(), "order_low": np.percentile(spread, 2.5, 0).tolist(),
        "order_high": np.percentile(spread, 97.5, 0).tolist()}}


def _elo_cells(report: dict, i: int) -> tuple[str, ...]:
    e = report["elo"]
    spread = f"{e['order_mean'][i]:.0f} [{e['order_low'][i]:.0f}, {e['order_high'][i]:.0f}]" if e.get("orders") else "-"
    return f"{e['ratings'][i]:.0f}", spread


def _elo_title(report: dict) -> str:
    e = report["elo"]
    orders = e.get("orders")
    return f"Elo K={e['k']:g} over {e['rounds']} rounds ({e['games']} games)" + (
        f", with its mean [95 %] over {orders} game orders" if orders else "")


def _elo_plot(report: dict, ax, x: np.ndarray) -> None:
    e = report["elo"]
    ax.plot(x - 0.1, e["ratings"], "s", label="Elo (final)")
    if e.get("orders"):  # the order's own spread of Elo: what a reader must not read as a difference in strength
        m, lo, hi = (np.asarray(e[k]) for k in ("order_mean", "order_low", "order_high"))
        ax.errorbar(x - 0.2, m, yerr=[m - lo, hi - m], fmt="s", mfc="none", capsize=3, label=f"Elo over {e['orders']} orders (95 %)")


def _elo_panel(report: dict, ax) -> None:
    e = report["elo"]
    traj = np.asarray(e["trajectory"])
    for i, lab in enumerate(report["labels"]):
        ax.plot(e["trajectory_rounds"], traj[:, i], label=lab)
    ax.set_xlabel("round (every pair meets once)")
    ax.set_ylabel("Elo")
    ax.set_title(f"Elo, K={e['k']:g}, {e['rounds']} rounds of {e['games']} games, seed {e['seed']}", fontsize=9)
    ax.legend(fontsize=8)


# ------------------------------------------------------------------ Bradley-Terry
def _rate_bradley_terry(g: Games) -> dict:
    bt, lo, hi = bradley_terry_intervals(g.wdl)  # decisive games only: draws are reported beside
    return {"bradley_terry": {"ratings": bt.tolist(), "low": lo.tolist(), "high": hi.tolist(),
                              "interval": "95 % Firth-penalised profile likelihood", "draws": "left out (decisive games only)"},
            "draw_rate": record.draw_rate(g.wdl)}


def _bradley_terry_cells(report: dict, i: int) -> tuple[str, ...]:
    bt = report["bradley_terry"]
    draws = (report.get("draw_rate") or [None] * len(report["labels"]))[i]
    return f"{bt['ratings'][i]:.0f} [{bt['low'][i]:.0f}, {bt['high'][i]:.0f}]", "-" if draws is None else f"{draws:.2f}"


def _bradley_terry_plot(report: dict, ax, x: np.ndarray) -> None:
    r, lo, hi = (np.asarray(report["bradley_terry"][k]) for k in ("ratings", "low", "high"))
    ax.errorbar(x + 0.1, r, yerr=[r - lo, hi - r], fmt="o", capsize=4, label="Bradley-Terry (95 % profile likelihood)")


# ------------------------------------------------------------------ average win rate
def _rate_win_rate(g: Games) -> dict:
    return {"average_win_rate": [None if np.isnan(x) else float(x) for x in record.average_win_rate(g.wdl)]}


def _win_rate_cells(report: dict, i: int) -> tuple[str, ...]:
    avg = report["average_win_rate"][i]
    return ("n/a" if avg is None else f"{avg:.3f}",)


# ------------------------------------------------------------------ Nash
def _rate_nash(g: Games) -> dict:
    pay = record.payoff(g.wdl)
    mix = nash(pay)
    return {
        "payoffs": pay.tolist(),
        "nash": mix.tolist(),
        "nash_sensitivity": nash_sensitivity(g.wdl, g.settings.get("resamples", RESAMPLES), g.seed),
        # percentage points of score, 100 x (score - 0.5), score = (wins + draws / 2) / games
        "nash_exploitability": 50.0 * exploitability(pay, mix),
        "exploitability_in_population": (50.0 * member_exploitability(pay)).tolist(),
    }


def _nash_cells(report: dict, i: int) -> tuple[str, ...]:
    sens = report.get("nash_sensitivity")
    return (f"{report['nash'][i]:.3f}" + (f" ({sens['carries_weight'][i]:.2f})" if sens else ""),
            f"{report['exploitability_in_population'][i]:.1f}")


def _nash_title(report: dict) -> str:
    return "Nash weight (share of resampled tables where it carries weight)"


RATINGS: dict[str, Rating] = {
    "elo": Rating(_rate_elo, ("Elo", "Elo over orders"), _elo_cells, _elo_title, _elo_plot, _elo_panel),
    "bradley_terry": Rating(_rate_bradley_terry, ("Bradley-Terry [95 %]", "draws"), _bradley_terry_cells,
                            lambda report: "BT on decisive games with 95 % profile-likelihood intervals", _bradley_terry_plot),
    "win_rate": Rating(_rate_win_rate, ("avg win rate",), _win_rate_cells),
    "nash": Rating(_rate_nash, ("Nash weight", "exploitability in population (pp)"), _nash_cells, _nash_title),
}


def rate(games: Games) -> dict:
    """Every registered method's report keys, in ``RATINGS`` order; a method claiming a key another one
    already wrote is a programming error, refused rather than silently overwriting it."""
    out: dict = {}
    for name, method in RATINGS.items():
        part = method.rate(games)
        clash = set(part) & set(out)
        if clash:
            raise ValueError(f"rating {name!r} writes {sorted(clash)}, which an earlier rating already wrote")
        out.update(part)
    return out


__all__ = ["Games", "ORDERS", "RATINGS", "RESAMPLES", "ROUNDS", "Rating", "rate"]
