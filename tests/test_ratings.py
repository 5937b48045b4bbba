"""Ratings on synthetic games whose true strengths are known: Elo and Bradley-Terry recover the order
and the gaps, BT's profile-likelihood intervals cover the truth at their nominal rate (unbeaten
records included) and shrink with more games, Wilson intervals match their closed form and refuse
what is not a count."""

import math
from itertools import combinations

import numpy as np
import pytest

from volleybots.ratings import (
    bradley_terry,
    bradley_terry_intervals,
    elo,
    expected_score,
    round_robin,
    sample_round_robin,
    wilson_interval,
)
from volleybots.ratings.bradley_terry import ELO_SCALE

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


def test_bradley_terry_counts_a_draw_as_half_a_win_only_when_asked():
    wdl = np.zeros((2, 2, 3))
    wdl[0, 1] = (30, 40, 10)  # half-wins 50 to 30: odds 5/3
    wdl[1, 0] = wdl[0, 1, ::-1]
    r = bradley_terry(wdl, firth=False, draws="half")
    assert r[0] - r[1] == pytest.approx(400 * math.log10(50 / 30), abs=1.0)
    r = bradley_terry(wdl, draws="half")  # Firth's estimate: half a win more for each side, (50 + 1/2) / (30 + 1/2)
    assert r[0] - r[1] == pytest.approx(400 * math.log10(50.5 / 30.5), abs=1.0)
    r = bradley_terry(wdl)  # the default: decisive games only, 30 to 10, Firth (30.5 / 10.5)
    assert r[0] - r[1] == pytest.approx(400 * math.log10(30.5 / 10.5), abs=1.0)
    with pytest.raises(ValueError, match="draws='third'; allowed: decisive, half"):
        bradley_terry(wdl, draws="third")


def test_a_drawing_player_that_never_wins_cannot_outrank_the_players_that_beat_it():
    """The 3v3 inversion: random drew 70-80 % of its games and won none, yet counted as half wins its
    draws rated it above two learned teams that won every decisive game against it."""
    labels = ["scripted", "fsp", "sp", "random"]
    games = {(0, 1): (98, 1, 1), (0, 2): (99, 1, 0), (0, 3): (10, 90, 0), (1, 2): (50, 0, 50),
             (1, 3): (25, 75, 0), (2, 3): (20, 80, 0)}
    wdl = np.zeros((4, 4, 3))
    for (a, b), rec in games.items():
        wdl[a, b], wdl[b, a] = rec, rec[::-1]
    half = bradley_terry(wdl, draws="half")
    assert half[3] > half[1] and half[3] > half[2]  # the inversion the half-win rule makes
    r, lo, hi = bradley_terry_intervals(wdl)
    for beaten_by in (0, 1, 2):
        assert r[3] < r[beaten_by], dict(zip(labels, r, strict=False))


def test_bradley_terry_is_finite_when_one_side_wins_everything():
    wdl = np.zeros((2, 2, 3))
    wdl[0, 1] = (100, 0, 0)
    wdl[1, 0] = (0, 0, 100)
    r = bradley_terry(wdl)
    assert np.isfinite(r).all() and r[0] - r[1] > 800


def test_bradley_terry_intervals_cover_the_truth_and_shrink_with_more_games():
    widths = []
    truth = TRUE - TRUE.mean() + 1000.0  # the ratings are reported with mean 1000
    for games in (100, 1600):
        rng = np.random.default_rng(4)
        # no draws: draws taken evenly, as half wins, pull every strength towards the mean
        r, lo, hi = bradley_terry_intervals(synthetic_wdl(TRUE, games, rng))
        assert np.all(lo < r) and np.all(r < hi)
        assert np.all(np.abs(r - truth) < hi - lo), (lo, truth, hi)  # coverage is tested below
        widths.append(np.mean(hi - lo))
    assert widths[1] < 0.3 * widths[0], widths  # 16 x the games: about a quarter of the width


def record(wins, draws, losses):
    """Two competitors' counts [2, 2, 3] from the first one's wins, draws and losses."""
    wdl = np.zeros((2, 2, 3))
    wdl[0, 1] = (wins, draws, losses)
    wdl[1, 0] = (losses, draws, wins)
    return wdl


def test_firth_estimate_of_two_players_has_its_closed_form():
    # for one pair the Firth estimate of the gap is the logit of (wins + 1/2) / (games + 1); a huge
    # prior_sd leaves the penalty alone
    for w, n in ((10, 10), (7, 10), (0, 4)):
        r = bradley_terry(record(w, 0, n - w), prior_sd=1e4)
        assert r[0] - r[1] == pytest.approx(ELO_SCALE * math.log((w + 0.5) / (n - w + 0.5)), abs=0.5)
    r = bradley_terry(record(10, 0, 0))  # the default weak prior moves it by a few points only
    assert r[0] - r[1] == pytest.approx(ELO_SCALE * math.log(21), abs=10)


def test_an_unbeaten_record_has_an_interval_of_positive_width():
    r, lo, hi = bradley_terry_intervals(record(10, 0, 0))
    assert np.all(hi - lo > 300), (lo, hi)  # a resampling bootstrap gave zero width here
    assert lo[0] > 1000 > hi[1]  # 10-0 is significant (binomial p = 0.002): the winner is the stronger
    assert np.all(lo < r) and np.all(r < hi)
    assert hi[0] - r[0] > r[0] - lo[0]  # open-ended above: nothing in 10-0 bounds how much stronger
    assert r[0] - 1000 == pytest.approx(1000 - r[1]) and hi[0] - 1000 == pytest.approx(1000 - lo[1])


def test_profile_interval_ends_are_where_the_penalised_deviance_reaches_the_chi2_quantile():
    # for two players the profile is one-dimensional: the penalised log-likelihood of the gap g is
    # w log p + l log q + log(n p q) / 2 (Firth) - the weak prior on s = +-g/2
    from scipy.special import log_expit
    from scipy.stats import chi2

    w, l_ = 8.0, 2.0

    def pll(g):
        return w * log_expit(g) + l_ * log_expit(-g) + 0.5 * (math.log(w + l_) + log_expit(g) + log_expit(-g)) - (g / 2) ** 2 / 100.0

    r, lo, hi = bradley_terry_intervals(record(w, 0, l_))
    g_hat = 2 * (r[0] - 1000) / ELO_SCALE
    for end in (lo[0], hi[0]):
        g = 2 * (end - 1000) / ELO_SCALE
        assert 2 * (pll(g_hat) - pll(g)) == pytest.approx(chi2.ppf(0.95, 1), abs=1e-3)


def test_bradley_terry_intervals_cover_a_400_point_gap_at_ten_games_at_their_nominal_rate():
    # 200 records of 10 games between players 400 Elo points apart (the winner's true rating is 1200
    # on the mean-1000 scale). A 10-game record is one of 11, so each distinct record is fitted once.
    rng = np.random.default_rng(7)
    wins = rng.binomial(10, float(expected_score(1400, 1000)), 200)
    fits = {w: bradley_terry_intervals(record(w, 0, 10 - w)) for w in np.unique(wins)}
    covered = np.array([fits[w][1][0] <= 1200 <= fits[w][2][0] for w in wins])
    assert 10 in fits  # unbeaten records were drawn (about 39 % of them): they are the hard case
    assert 0.88 <= covered.mean() <= 0.995, covered.mean()


def test_plain_fit_agrees_with_choix():
    choix = pytest.importorskip("choix")
    rng = np.random.default_rng(8)
    wdl = synthetic_wdl(TRUE, 30, rng)
    wdl[0, 3], wdl[3, 0] = (0, 0, 30), (30, 0, 0)  # a separated pair: only the prior keeps it finite
    data = [(a, b) for a in range(4) for b in range(4) for _ in range(int(wdl[a, b, 0]))]
    theirs = choix.opt_pairwise(4, data, alpha=1 / (2 * 10.0**2))  # alpha |s|^2 is our N(0, 10^2) prior
    mine = bradley_terry(wdl, firth=False)
    assert mine == pytest.approx(1000 + ELO_SCALE * (theirs - theirs.mean()), abs=0.05)


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
    assert wilson_interval(np.array([3.0]), np.array([10.0]))[0] == pytest.approx(wilson_interval(3, 10)[0])  # integral floats are counts


@pytest.mark.parametrize(("wins", "games", "words"), [
    (2.5, 10, ["wins=2.5", "whole number"]),
    (3, 9.9, ["games=9.9", "whole number"]),
    (-1, 10, ["wins=-1", ">= 0"]),
    (11, 10, ["wins=11", "games=10"]),
    (float("nan"), 10, ["wins=nan"]),
    (np.array([1, 2]), np.array([5, 1]), ["wins=2", "games=1"]),
])
def test_wilson_interval_refuses_what_is_not_a_count(wins, games, words):
    with pytest.raises(ValueError) as e:
        wilson_interval(wins, games)
    for w in words:
        assert w in str(e.value)


@pytest.mark.parametrize("k", [math.nan, math.inf, 0.0, -8.0])
def test_elo_refuses_a_step_that_is_not_finite_and_positive(k):
    with pytest.raises(ValueError, match=f"k={k}"):
        elo([(0, 1, 1.0)], 2, k=k)


def test_draws_narrow_the_interval_to_the_variance_of_a_score():
    # 25 wins, 50 draws, 25 losses: a game's score (1, 1/2, 0) has variance 1/4 - 1/8 = 1/8, half the
    # 1/4 of a win-or-loss game, so the gap's 95 % half-width is 1.96 sqrt(1/8 / 100) / (1/4) logits
    from volleybots.ratings.bradley_terry import draw_dispersion

    half = 1.959964 * math.sqrt(0.125 / 100) / 0.25 * ELO_SCALE
    _, lo, hi = bradley_terry_intervals(record(25, 50, 25), draws="half")
    assert draw_dispersion(record(25, 50, 25), np.zeros(2)) == pytest.approx(0.5)
    assert hi[0] - lo[0] == pytest.approx(half, rel=0.05)  # a competitor's rating moves by half the gap
    _, lo, hi = bradley_terry_intervals(record(50, 0, 50), draws="half")  # no draws: the binomial width, sqrt(2) wider
    assert draw_dispersion(record(50, 0, 50), np.zeros(2)) == 1.0
    assert hi[0] - lo[0] == pytest.approx(math.sqrt(2) * half, rel=0.05)
