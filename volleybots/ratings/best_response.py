"""The statistics of approximate exploitability, apart from how responses are trained or games played.

Exploitability(pi) = max over responses pi' of U(pi', pi) - U(pi, pi). Every response anyone can try
gives a lower bound on that max, and the estimate is only as good as the best response found, so the
estimator here follows three rules (docs/evaluation.md, "Approximate exploitability"):

- **Best of everything tried.** The candidates are the trained responses (several seeds, each with
  its checkpoints), fixed responses, the target's own members, and the target itself, which scores
  exactly 0 in a symmetric zero-sum game. So the figure is never below 0.
- **Chosen on other games.** Each candidate plays ``select_games`` games on a selection seed; the one
  with the highest win rate over decisive games is then played ``games`` games on another seed, and
  only those give the figure and its interval (picking the maximum of noisy estimates on the games
  that report it would bias the figure upwards).
- **A lower bound, with both noises shown.** The games' Wilson interval says how well the chosen
  response was measured; the spread of the trained responses across seeds says how much training
  noise there is (often the larger of the two).

``plateau`` is the convergence test of a trained response: its training win rate has stopped rising
(a level, such as the 0.9 an oracle stops at, cannot tell a response that is done from one that
stopped early, and censors every figure near the level).

This module imports no torch: ``play`` functions do the games.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from volleybots.ratings.record import win_rate, win_rate_interval

SELF = "self"  # the target as its own response: exactly 0 points in a symmetric zero-sum game
PLATEAU_TOLERANCE = 0.05  # a response has plateaued when another window of training would gain less win rate than this (95 %)


def points(rate: float) -> float:
    """Percentage points a win rate over decisive games lies above an even game's: 100 x (rate - 0.5)."""
    return 100.0 * (rate - 0.5)


def figure(wdl) -> dict:
    """W/D/L as the report's win rate and exploitability, with Wilson intervals. Games without a decisive
    one have no win rate: they count as even (0 points) with the widest interval."""
    wdl = [int(x) for x in wdl]
    if wdl[0] + wdl[2] == 0:
        return {"wdl": wdl, "br_win_rate": 0.5, "br_win_rate_interval": [0.0, 1.0], "exploitability": 0.0,
                "exploitability_interval": [-50.0, 50.0]}
    rate = float(win_rate(wdl))
    lo, hi = (float(x) for x in win_rate_interval(wdl))
    return {"wdl": wdl, "br_win_rate": rate, "br_win_rate_interval": [lo, hi], "exploitability": points(rate),
            "exploitability_interval": [points(lo), points(hi)]}


def plateau(win_rates, window: int, tolerance: float = PLATEAU_TOLERANCE) -> dict:
    """Whether a response's training win rate has stopped rising: an OLS line through the last
    ``2 x window`` batches' win rates, extrapolated over one more window, gains less than ``tolerance``
    at its 95 % upper bound. Fewer than ``2 x window`` batches: not judged (False).

    Returns:
        ``{"plateau": bool, "gain": the fitted gain over a window, "gain_upper": its 95 % upper bound,
        "batches": how many win rates were seen}``.
    """
    from scipy import stats

    r = np.asarray([w for w in win_rates if w is not None and not math.isnan(w)], dtype=float)
    n = 2 * window
    if len(r) < n or window < 2:
        return {"plateau": False, "gain": None, "gain_upper": None, "batches": len(r)}
    y = r[-n:]
    fit = stats.linregress(np.arange(n, dtype=float), y)
    se = 0.0 if math.isnan(fit.stderr) else fit.stderr
    t = stats.t.ppf(0.975, n - 2)
    gain, upper = fit.slope * window, (fit.slope + t * se) * window
    return {"plateau": bool(upper < tolerance), "gain": float(gain), "gain_upper": float(upper), "batches": len(r)}


@dataclass
class Candidate:
    """One response to the target: ``play(games, seed)`` returns its W/D/L against the target.
    ``kind``: ``trained`` (a checkpoint of a trained response; ``group`` names its training seed),
    ``fixed`` (a response= competitor) or ``member`` (one of the target's own members)."""

    name: str
    play: Callable[[int, int], list]
    kind: str = "fixed"
    group: str | None = None
    info: dict = field(default_factory=dict)


def estimate(candidates: list[Candidate], games: int, select_games: int, seed: int, select_seed: int) -> dict:
    """The approximate exploitability over ``candidates`` (rules in the module's docstring).

    Args:
        candidates: the responses tried (the target itself is added here, at 0 points).
        games: games that give the figure (the chosen response's only).
        select_games: games each candidate plays to be chosen (on ``select_seed``, not ``seed``).

    Returns:
        The figure's fields (``figure``), ``best`` (a candidate's name or ``self``), ``selection`` (each
        candidate's selection W/D/L and points), ``seeds`` (each training seed's best selection points,
        and their spread) and ``lower_bound: True``.
    """
    if select_games < 1 or games < 1:
        raise ValueError(f"games={games} and select_games={select_games} must be >= 1")
    names = [c.name for c in candidates]
    if SELF in names or len(set(names)) != len(names):
        raise ValueError(f"candidate names must be unique and not {SELF!r}: {names}")
    selection = {}
    for c in candidates:
        f = figure(c.play(select_games, select_seed))
        selection[c.name] = {"kind": c.kind, **({"group": c.group} if c.group else {}), "wdl": f["wdl"],
                             "exploitability": f["exploitability"], **c.info}
    # the highest selection score; the target itself (0) wins ties and every negative score
    best = max(selection, key=lambda k: selection[k]["exploitability"], default=None)
    if best is None or selection[best]["exploitability"] <= 0.0:
        best, fig = SELF, {"wdl": [0, 0, 0], "br_win_rate": 0.5, "br_win_rate_interval": [0.5, 0.5], "exploitability": 0.0,
                           "exploitability_interval": [0.0, 0.0]}
    else:
        fig = figure(next(c for c in candidates if c.name == best).play(games, seed))
        raw = fig["exploitability"]
        # the target itself is a response too: a chosen response that scores below it on the report's
        # games is replaced by it (0), and the interval cannot reach below what the target scores
        fig["exploitability"] = max(raw, 0.0)
        fig["exploitability_interval"] = [max(x, 0.0) for x in fig["exploitability_interval"]]
        fig["chosen_points"] = raw
    groups: dict[str, float] = {}
    for s in selection.values():
        if s["kind"] == "trained":
            groups[s["group"]] = max(groups.get(s["group"], -math.inf), s["exploitability"])
    spread = {"points": groups}
    if groups:
        v = np.asarray(list(groups.values()), dtype=float)
        spread.update(mean=float(v.mean()), min=float(v.min()), max=float(v.max()), std=float(v.std(ddof=1)) if len(v) > 1 else None)
    return {**fig, "best": best, "selection": selection, "seeds": spread, "select_games": select_games, "lower_bound": True}


__all__ = ["PLATEAU_TOLERANCE", "SELF", "Candidate", "estimate", "figure", "plateau", "points"]
