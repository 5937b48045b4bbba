"""Confidence intervals for win rates."""

from __future__ import annotations

import math

import numpy as np
import scipy  # scipy.stats loads on first use (about 1.6 s; bradley_terry.py says why that matters)

from volleybots.errors import ConfigError


def _counts(name: str, value) -> np.ndarray:
    """``value`` as an integer array, refusing what is not a count (a fraction, a negative, nan)."""
    try:
        x = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{name}={value!r} must be whole numbers of games >= 0") from None
    bad = ~np.isfinite(x) | (x < 0) | (x != np.round(x))
    if bad.any():
        raise ConfigError(f"{name}={float(x[bad].flat[0]):g} must be a whole number of games >= 0")
    return x.astype(np.int64)


def wilson_interval(wins, games, confidence: float = 0.95):
    """The Wilson score interval of a win rate ``wins / games`` (scalars or arrays of counts).

    Wilson rather than the normal approximation because cross-play rates sit near 0 and 1 (scripted
    against random wins every decisive game), where the normal interval collapses to a point or
    leaves [0, 1]. No games: (nan, nan). Counts must be whole numbers >= 0 with ``wins <= games``
    (integral floats such as 12.0 are counts too): a fraction or a negative is a damaged count, and
    rounding it would give an interval for games that were never played, so ``ConfigError`` (a
    ``ValueError``) is raised instead.

    Args:
        wins: wins (decisive games won), a count or an array of counts.
        games: games counted (decisive games), broadcast against ``wins``.
        confidence: the interval's coverage.

    Returns:
        ``(low, high)``: floats for scalar input, arrays otherwise; nan where there are no games.
    """
    if not 0.0 < confidence < 1.0:
        raise ConfigError(f"confidence={confidence!r} must be in (0, 1)")
    wins_a, games_a = np.broadcast_arrays(_counts("wins", wins), _counts("games", games))
    over = wins_a > games_a
    if over.any():
        raise ConfigError(f"wins={wins_a[over].flat[0]} exceeds games={games_a[over].flat[0]}; a win rate needs wins <= games")
    lo = np.full(wins_a.shape, math.nan)
    hi = np.full(wins_a.shape, math.nan)
    for idx in np.ndindex(wins_a.shape):
        n, k = int(games_a[idx]), int(wins_a[idx])
        if n > 0:
            ci = scipy.stats.binomtest(k, n).proportion_ci(confidence, method="wilson")
            lo[idx], hi[idx] = ci.low, ci.high
    if lo.ndim == 0:
        return float(lo), float(hi)
    return lo, hi
