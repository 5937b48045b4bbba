"""Confidence intervals for win rates."""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import binomtest


def wilson_interval(wins, games, confidence: float = 0.95):
    """The Wilson score interval of a win rate ``wins / games`` (scalars or arrays of counts).

    Wilson rather than the normal approximation because cross-play rates sit near 0 and 1 (scripted
    against random wins every decisive game), where the normal interval collapses to a point or
    leaves [0, 1].

    Args:
        wins: wins (decisive games won), a count or an array of counts.
        games: games counted (decisive games), broadcast against ``wins``.
        confidence: the interval's coverage.

    Returns:
        ``(low, high)``: floats for scalar input, arrays otherwise; nan where there are no games.
    """
    wins_a, games_a = np.broadcast_arrays(np.asarray(wins), np.asarray(games))
    lo = np.full(wins_a.shape, math.nan)
    hi = np.full(wins_a.shape, math.nan)
    for idx in np.ndindex(wins_a.shape):
        n, k = int(games_a[idx]), int(wins_a[idx])
        if n > 0:
            ci = binomtest(k, n).proportion_ci(confidence, method="wilson")
            lo[idx], hi[idx] = ci.low, ci.high
    if lo.ndim == 0:
        return float(lo), float(hi)
    return lo, hi
