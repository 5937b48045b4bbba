"""Ratings on synthetic games whose true strengths are known: Elo and Bradley-Terry recover the order
and the gaps, BT's bootstrap intervals cover the truth and shrink with more games, Wilson intervals
match their closed form."""

import math
from itertools import combinations

import numpy as np
import pytest

from volleybots.ratings import (
    bradley_terry,
    bradley_terry_bootstrap,
    elo,
    expected_score,
    round_robin,
    sample_round_robin,
    wilson_interval,
)

TRUE = np.array([1000.0, 1200.0, 1400.0, 1600.0])  # Elo-scale strengths: 200 points apart


def synthetic_wdl(true, games, rng, draw=0.0):
    """Counts [n, n, 3] of games whose outcomes follow the Elo/BT model (draws taken evenly)."""
    n = len(true)
    wdl = np.zeros((n, n, 3))
    for a, b in combinations(range(n), 2):
        p = float(expected_score(true[a], true[b]))
        g = rng.multinomial(games, [p * (1 - draw), draw, (1 - p) * (1 - draw)])
        wdl[a, b], wdl[b, a] = g, g[::-1]
    return wdl


def test_elo_update_is_the_papers():
    r = elo([(0, 1, 1.0)], 2, k=168)
    assert r == pytest.approx([1084.0, 916.0])  # equal ratings: expected 0.5, K x 0.5 = 84
    r = elo([(0, 1, 0.5)], 2, k=32, start=1000)
    assert r == pytest.approx([1000.0, 1000.0])  # a draw between equals changes nothing
    r = elo([(0, 1, 0.0), (0, 1, 0.5)], 2, k=10)
    e = 1 / (1 + 10 ** ((995 - 1005) / 400))  # second game: b leads 1005 to 995
    assert r[1] == pytest.approx(1005 + 10 * (0.5 - e))
    assert r.sum() == pytest.approx(2000)  # zero-sum updates


def test_round_robin_meets_every_pair_once_per_round():
    rng = np.random.default_rng(0)
    games = round_robin(4, 5, lambda a, b, r: 1.0, rng)
    assert games.shape == (5 * 6, 3)
    for r in range(5):
        pairs = {tuple(g[:2].astype(int)) for g in games[6 * r : 6 * r + 6]}
        assert pairs == set(combinations(range(4), 2))


def test_elo_on_sampled_rounds_recovers_order_and_gaps():
    rng = np.random.default_rng(1)
    wdl = synthetic_wdl(TRUE, 2000, rng)
    r = elo(sample_round_robin(wdl, 2000, rng), 4, k=8)
    assert list(np.argsort(r)) == [0, 1, 2, 3]
    assert r.mean() == pytest.approx(1000.0)  # all start at 1000 and updates are zero-sum
    gaps = np.diff(r)
    assert np.all(np.abs(gaps - 200) < 90), gaps  # sequential Elo is noisy: gaps within 90 points
    assert abs((r[3] - r[0]) - 600) < 90


def test_sampled_games_follow_the_cross_play_frequencies():
    rng = np.random.default_rng(2)
    wdl = np.zeros((2, 2, 3))
    wdl[0, 1] = (70, 20, 10)
    wdl[1, 0] = (10, 20, 70)
    games = sample_round_robin(wdl, 4000, rng)
    freq = [np.mean(games[:, 2] == s) for s in (1.0, 0.5, 0.0)]
    assert freq == pytest.approx([0.7, 0.2, 0.1], abs=0.025)
    wdl[0, 1] = wdl[1, 0] = 0
    with pytest.raises(ValueError, match="no games"):
        sample_round_robin(wdl, 1, rng)


def test_bradley_terry_recovers_strengths():
    rng = np.random.default_rng(3)
    r = bradley_terry(synthetic_wdl(TRUE, 2000, rng))
    assert r.mean() == pytest.approx(1000.0)
    assert np.abs((r - r[0]) - (TRUE - TRUE[0])).max() < 30  # ML on 12000 games: within 30 points


def test_bradley_terry_counts_a_draw_as_half_a_win():
    wdl = np.zeros((2, 2, 3))
    wdl[0, 1] = (30, 40, 10)  # half-wins 50 to 30: odds 5/3
    wdl[1, 0] = wdl[0, 1, ::-1]
    r = bradley_terry(wdl)
    assert r[0] - r[1] == pytest.approx(400 * math.log10(50 / 30), abs=1.0)


def test_bradley_terry_is_finite_when_one_side_wins_everything():
    wdl = np.zeros((2, 2, 3))
    wdl[0, 1] = (100, 0, 0)
    wdl[1, 0] = (0, 0, 100)
    r = bradley_terry(wdl)
    assert np.isfinite(r).all() and r[0] - r[1] > 800


def test_bradley_terry_intervals_cover_the_truth_and_shrink_with_more_games():
    widths = []
    for games in (100, 1600):
        rng = np.random.default_rng(4)
        r, lo, hi = bradley_terry_bootstrap(synthetic_wdl(TRUE, games, rng, draw=0.1), samples=200, rng=rng)
        assert np.all(lo <= r) and np.all(r <= hi)
        widths.append(np.mean(hi - lo))
    assert widths[1] < 0.4 * widths[0], widths  # 16 x the games: about a quarter of the width


def test_wilson_interval():
    lo, hi = wilson_interval(95, 100)
    z = 1.959963984540054
    p, n = 0.95, 100
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    assert (lo, hi) == pytest.approx((centre - half, centre + half))
    lo, hi = wilson_interval(np.array([10, 0, 0]), np.array([10, 10, 0]))
    assert hi[0] == pytest.approx(1.0) and lo[0] > 0.65  # all won: the interval still has width
    assert lo[1] == pytest.approx(0.0) and hi[1] < 0.35
    assert math.isnan(lo[2]) and math.isnan(hi[2])  # no games, no interval
