"""Game records: the one layout of win / draw / loss counts and the arithmetic on it.

A record is a count array whose last axis is (wins, draws, losses) from one side's view: ``[3]`` for
one match, ``[2, 3]`` per side of the court, ``[n, n, 3]`` for every ordered pair of a population or a
cross-play (row against column, so ``table[j, i] == flip(table[i, j])``). Every figure read off
such counts (decisive games, win rates, zero-sum payoffs, the other side's view) is computed here
and nowhere else, so that a population's payoff table, a cross-play and an exploitability report
cannot drift apart in what they call a win rate.
"""

from __future__ import annotations

import numpy as np

from volleybots.ratings.intervals import wilson_interval

OUTCOMES = "WDL"  # the letter of each outcome, in the order of the last axis
KEYS = ("wins", "draws", "losses")  # the same outcomes spelled out, as dict keys
SCORES = (1.0, 0.5, 0.0)  # a game's score for each outcome: a draw is half a win


def tally(outcomes: str) -> np.ndarray:
    """[3] counts of a string of outcome letters ("W", "D", "L")."""
    return np.array([outcomes.count(c) for c in OUTCOMES], dtype=np.int64)


def games(wdl) -> np.ndarray:
    """Games played: wins + draws + losses."""
    return np.asarray(wdl).sum(-1)


def decisive(wdl) -> np.ndarray:
    """Games that were not drawn: wins + losses."""
    wdl = np.asarray(wdl)
    return wdl[..., 0] + wdl[..., 2]


def win_rate(wdl) -> np.ndarray:
    """Wins / decisive games (nan where no game was decisive)."""
    wdl = np.asarray(wdl)
    dec = decisive(wdl)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(dec > 0, wdl[..., 0] / np.maximum(dec, 1), np.nan)


def win_rate_interval(wdl, confidence: float = 0.95):
    """(low, high): the Wilson interval of ``win_rate`` (nan where no game was decisive)."""
    wdl = np.asarray(wdl)
    return wilson_interval(wdl[..., 0], decisive(wdl), confidence)


def average_win_rate(wdl) -> np.ndarray:
    """[n]: each competitor's mean win rate against the others of a table [n, n, 3] (pairs without a
    decisive game left out; nan where it has none)."""
    wr = win_rate(wdl).astype(float)
    np.fill_diagonal(wr, np.nan)
    with np.errstate(invalid="ignore"):
        return np.array([np.nanmean(r) if np.isfinite(r).any() else np.nan for r in wr])


def draw_rate(wdl) -> list:
    """Each competitor's share of drawn games over all its games in a table [n, n, 3] (None: it played none)."""
    wdl = np.asarray(wdl, float)
    played, draws = wdl.sum((1, 2)), wdl[..., 1].sum(1)
    return [None if g == 0 else float(d / g) for d, g in zip(draws, played, strict=True)]


def points(wdl) -> np.ndarray:
    """Games' scores summed: wins + draws / 2."""
    return np.asarray(wdl, float) @ np.array(SCORES)


def payoff(wdl) -> np.ndarray:
    """The zero-sum payoff, the mean game score of +1 / 0 / -1: (wins - losses) / games (0 where none
    was played, a competitor's value against itself in a symmetric game)."""
    wdl = np.asarray(wdl)
    g = games(wdl)
    return np.divide(wdl[..., 0] - wdl[..., 2], g, out=np.zeros(g.shape), where=g > 0)


def flip(wdl) -> np.ndarray:
    """The same games from the other side: its wins are these losses."""
    return np.asarray(wdl)[..., ::-1]


def put(table: np.ndarray, i: int, j: int, wdl) -> None:
    """Write the record of ``i`` against ``j`` into ``table`` [n, n, 3], and its mirror into ``(j, i)``."""
    table[i, j], table[j, i] = wdl, flip(wdl)


def from_dict(counts: dict) -> np.ndarray:
    """The record held as ``{"wins": .., "draws": .., "losses": ..}`` (counts or arrays of counts of one
    shape, as payoffs.json held them before it held one ``wdl``): that shape with a last axis of 3."""
    return np.stack([np.asarray(counts[k], dtype=np.int64) for k in KEYS], -1)
