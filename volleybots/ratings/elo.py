"""The paper's Elo: every competitor starts at 1000, games are played in rounds in which every pair
meets once, and each game moves both ratings by K x (score - expected score), a draw scoring 0.5.

Sequential Elo depends on the order of the games; the schedules here fix it (rounds, with the order
of the pairs within a round shuffled by a seeded generator) so that a seed gives one answer.
"""

from __future__ import annotations

import math
from itertools import combinations
from typing import Callable, Iterable

import numpy as np

from volleybots.ratings.record import OUTCOMES, SCORES

ELO_START = 1000.0
ELO_K = 168.0  # the paper's K for its 4 policies; a parameter everywhere


def expected_score(ra, rb):
    """The expected score of a player rated ``ra`` against one rated ``rb``.

    Args:
        ra: the player's rating (a scalar or an array).
        rb: the opponent's rating, broadcast against ``ra``.

    Returns:
        ``1 / (1 + 10^((rb - ra) / 400))``: 0.5 between equals, toward 1 as ``ra`` leads.
    """
    return 1.0 / (1.0 + 10.0 ** ((np.asarray(rb, float) - np.asarray(ra, float)) / 400.0))


def elo(games: Iterable, n: int, k: float = ELO_K, start: float = ELO_START) -> np.ndarray:
    """Final Elo ratings after a sequence of games.

    Args:
        games: ``(a, b, score_a)`` rows in the order played; score 1 a win of a, 0.5 a draw, 0 a loss.
        n: the number of players (indices ``0 .. n-1``).
        k: the update step (the paper's 168 for 4 policies).
        start: everyone's rating before the first game.

    Returns:
        Ratings [n] after the last game.
    """
    return elo_history(games, n, k, start)[-1]


def elo_history(games: Iterable, n: int, k: float = ELO_K, start: float = ELO_START) -> np.ndarray:
    """Elo ratings at the start and after every game.

    Args:
        games: ``(a, b, score_a)`` rows in the order played, as for ``elo``.
        n: the number of players.
        k: the update step.
        start: everyone's rating before the first game.

    Returns:
        Ratings [1 + games, n]; row 0 is the start, row i after game i.
    """
    if not (math.isfinite(k) and k > 0):
        raise ValueError(f"k={k} must be a finite number > 0 (Elo's step)")
    r = np.full(n, float(start))
    out = [r.copy()]
    for a, b, score in games:
        a, b = int(a), int(b)
        delta = k * (float(score) - expected_score(r[a], r[b]))
        r[a] += delta
        r[b] -= delta
        out.append(r.copy())
    return np.asarray(out)


def round_robin(n: int, rounds: int, play: Callable[[int, int, int], float], rng: np.random.Generator) -> np.ndarray:
    """Games of ``rounds`` rounds in which every pair (a < b) meets once, in a shuffled order per round.

    Args:
        n: the number of players.
        rounds: how many rounds.
        play: ``play(a, b, r)`` gives a's score (1, 0.5, 0) against b in round r.
        rng: the generator that shuffles each round.

    Returns:
        Games [rounds x n(n-1)/2, 3] of ``(a, b, score_a)``, ready for ``elo``.
    """
    pairs = list(combinations(range(n), 2))
    games = []
    for r in range(rounds):
        for p in rng.permutation(len(pairs)):
            a, b = pairs[p]
            games.append((a, b, play(a, b, r)))
    return np.asarray(games, dtype=float).reshape(-1, 3)


def sample_round_robin(wdl, rounds: int, rng: np.random.Generator) -> np.ndarray:
    """Round-robin games whose results are drawn from each pair's cross-play frequencies, as the
    paper's Elo was.

    Args:
        wdl: counts [n, n, 3]: wins, draws and losses of the row against the column.
        rounds: how many rounds (every pair meets once a round).
        rng: the generator of the order and the drawn results.

    Returns:
        Games [rounds x n(n-1)/2, 3] of ``(a, b, score_a)``.

    Raises:
        ValueError: a pair that played no game.
    """
    wdl = np.asarray(wdl, float)
    n = wdl.shape[0]
    for a, b in combinations(range(n), 2):
        if wdl[a, b].sum() <= 0:
            raise ValueError(f"competitors {a} and {b} have played no games; cannot sample their results")
    scores = np.array(SCORES)

    def play(a, b, r):
        p = wdl[a, b] / wdl[a, b].sum()
        return scores[rng.choice(3, p=p)]

    return round_robin(n, rounds, play, rng)


def elo_games(wdl, outcomes, rounds: int, rng: np.random.Generator, sample: bool = False) -> tuple[np.ndarray, str]:
    """The round-robin games [rounds x pairs, 3] for Elo and how they were obtained ("played" or "sampled").

    When every pair played at least ``rounds`` games (``outcomes``: "a,b" -> a string of W/D/L letters
    from a's side) and ``sample`` is off, round r is every pair's r-th game after a seeded shuffle of
    that pair's games; otherwise each round's results are drawn from the pairs' W/D/L frequencies, as
    the paper sampled them.

    Why the shuffle: a cross-play plays each pair in batches, half its games with one competitor on team
    0 and then half on team 1, and records them in that order. Sequential Elo weighs the latest games
    most (with K = 168 a rating forgets within a few dozen games), so in play order the last side's batch
    would decide the rating, and a side advantage would pass for a difference in strength. The games of
    a pair are put in a canonical order (sorted) and then permuted by the seeded generator, so the games
    used depend on the pair's results and the seed only, never on the order in which they were played.
    """
    n = np.asarray(wdl).shape[0]
    outcomes = outcomes or {}
    played = min((len(s) for s in outcomes.values()), default=0)
    if not sample and played >= rounds and len(outcomes) == n * (n - 1) // 2:
        score = dict(zip(OUTCOMES, SCORES, strict=True))
        shuffled = {key: rng.permutation(sorted(seq)) for key, seq in sorted(outcomes.items())}
        return round_robin(n, rounds, lambda a, b, r: score[shuffled[f"{a},{b}"][r]], rng), "played"
    return sample_round_robin(wdl, rounds, rng), "sampled"


def elo_orders(wdl, rounds: int, orders: int, seed: int, k: float = ELO_K, start: float = ELO_START, outcomes=None) -> np.ndarray:
    """Final Elo ratings [orders, n] over ``orders`` seeded game orders: the order dependence of the
    paper's sequential Elo made visible (its mean and spread are what a reader can compare).

    Each order is a round-robin schedule of ``rounds`` rounds with the pairs of a round in a random
    order; a pair's results in it are its played games in a random order (``outcomes``: "a,b" -> a
    string of W/D/L letters from a's side, when every pair played at least ``rounds`` games) or drawn
    from its W/D/L frequencies. All orders are updated together, one game at a time.
    """
    if not (math.isfinite(k) and k > 0):
        raise ValueError(f"k={k} must be a finite number > 0 (Elo's step)")
    wdl = np.asarray(wdl, float)
    n = wdl.shape[0]
    pairs = list(combinations(range(n), 2))
    if not pairs or orders < 1 or rounds < 1:
        return np.full((max(orders, 1), n), float(start))
    letters = {"W": 1.0, "D": 0.5, "L": 0.0}
    played = outcomes is not None and all(len(outcomes.get(f"{a},{b}", "")) >= rounds for a, b in pairs)
    scores = np.array(SCORES)
    a_idx = np.array([p[0] for p in pairs])
    b_idx = np.array([p[1] for p in pairs])
    A, B, S = (np.empty((orders, rounds * len(pairs))) for _ in range(3))
    for o in range(orders):
        rng = np.random.default_rng([seed, o])
        cols = []
        for a, b in pairs:
            if played:
                seq = np.array([letters[c] for c in sorted(outcomes[f"{a},{b}"])])
                cols.append(rng.permutation(seq)[:rounds])
            else:
                if wdl[a, b].sum() <= 0:
                    raise ValueError(f"competitors {a} and {b} have played no games; cannot sample their results")
                cols.append(scores[rng.choice(3, size=rounds, p=wdl[a, b] / wdl[a, b].sum())])
        score = np.stack(cols, 1)  # [rounds, pairs]
        perm = np.argsort(rng.random((rounds, len(pairs))), axis=1)
        A[o] = a_idx[perm].ravel()
        B[o] = b_idx[perm].ravel()
        S[o] = np.take_along_axis(score, perm, 1).ravel()
    A, B = A.astype(int), B.astype(int)
    r = np.full((orders, n), float(start))
    rows = np.arange(orders)
    for g in range(A.shape[1]):
        a, b = A[:, g], B[:, g]
        delta = k * (S[:, g] - expected_score(r[rows, a], r[rows, b]))
        r[rows, a] += delta
        r[rows, b] -= delta
    return r
