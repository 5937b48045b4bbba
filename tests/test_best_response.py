"""The statistics of approximate exploitability on a game whose exploitability is known exactly.

A symmetric zero-sum matrix game without draws: response i beats member j with probability P[i, j]
(P[j, i] = 1 - P[i, j]). Against a target mixing its members with weights x, pure response i wins with
probability (P x)_i, so the exact exploitability of the target is 100 x (max_i (P x)_i - 0.5): the
reference OpenSpiel computes exactly on small games, which the approximation must approach."""

import numpy as np
import pytest

from volleybots.ratings.best_response import SELF, Candidate, estimate, figure, plateau

# rock-paper-scissors with a fourth strategy that loses to everything (the deliberately exploitable member)
P = np.array([[0.5, 0.2, 0.8, 0.9],
              [0.8, 0.5, 0.2, 0.9],
              [0.2, 0.8, 0.5, 0.9],
              [0.1, 0.1, 0.1, 0.5]])


def candidates(x, calls=None):
    p = P @ np.asarray(x)

    def play(i):
        def f(n, seed):
            if calls is not None:
                calls.append((i, n, seed))
            wins = np.random.default_rng([seed, i]).binomial(n, p[i])
            return [int(wins), 0, int(n - wins)]
        return f

    return [Candidate(f"pure{i}", play(i), "trained" if i < 2 else "fixed", group=f"s{i}" if i < 2 else None) for i in range(4)]


def exact(x) -> float:
    return 100 * (max(P @ np.asarray(x)) - 0.5)


def test_a_known_exploitability_is_recovered_within_its_interval():
    """A target mixing rock-paper-scissors with the exploitable member (weight 0.4): exact 25.0 points,
    the best response is pure 1; response 0 scores 16.0, so a wrong choice would miss the interval."""
    x = [0.4, 0.1, 0.1, 0.4]
    truth = exact(x)
    assert truth == pytest.approx(25.0)
    covered = chosen = 0
    for seed in range(40):
        r = estimate(candidates(x), games=1000, select_games=400, seed=seed, select_seed=10_000 + seed)
        lo, hi = r["exploitability_interval"]
        covered += lo <= truth <= hi
        chosen += r["best"] == "pure1"
        assert r["lower_bound"] is True
    assert chosen >= 38  # the selection games tell 0.75 from 0.66 (2.6 standard deviations of their difference)
    assert covered >= 34  # a 95 % interval: 38 expected of 40; 34 is 2 standard deviations of coverage below


def test_the_uniform_rock_paper_scissors_is_not_exploitable_and_the_figure_never_goes_below_zero():
    x = [1 / 3, 1 / 3, 1 / 3, 0.0]
    assert exact(x) == pytest.approx(0.0)
    for seed in range(20):
        r = estimate(candidates(x), games=400, select_games=100, seed=seed, select_seed=99 + seed)
        assert r["exploitability"] >= 0 and r["exploitability_interval"][0] >= 0
        assert r["exploitability_interval"][0] <= 0.0 + 1e-9 or r["best"] != SELF
    # responses that all lose: the target itself (0 points) is the best response found
    losers = [Candidate("bad", lambda n, s: [0, 0, n])]
    r = estimate(losers, games=10, select_games=10, seed=0, select_seed=1)
    assert r["best"] == SELF and r["exploitability"] == 0.0 and r["exploitability_interval"] == [0.0, 0.0]


def test_the_best_is_chosen_on_selection_games_and_only_it_plays_the_reported_games():
    calls = []
    r = estimate(candidates([0.3, 0.2, 0.2, 0.3], calls), games=300, select_games=50, seed=7, select_seed=8)
    chosen = int(r["best"].removeprefix("pure"))
    assert sorted(i for i, n, s in calls if s == 8 and n == 50) == [0, 1, 2, 3]  # every candidate: selection games
    assert [(i, n, s) for i, n, s in calls if s == 7] == [(chosen, 300, 7)]  # only the chosen one: the report's games
    assert sum(r["wdl"]) == 300 and set(r["selection"]) == {"pure0", "pure1", "pure2", "pure3"}
    # the trained responses' seeds are reported with their spread
    assert set(r["seeds"]["points"]) == {"s0", "s1"} and r["seeds"]["min"] <= r["seeds"]["mean"] <= r["seeds"]["max"]


def test_draws_only_count_as_an_even_game_and_plateau_needs_two_windows():
    f = figure([0, 10, 0])
    assert f["exploitability"] == 0.0 and f["exploitability_interval"] == [-50.0, 50.0]
    assert not plateau([0.5] * 19, window=10)["plateau"] and plateau([0.5] * 20, window=10)["plateau"]
    assert not plateau([0.02 * k for k in range(20)], window=10)["plateau"]  # still rising by 0.2 a window
    with pytest.raises(ValueError, match="unique"):
        estimate([Candidate("a", None), Candidate("a", None)], 2, 2, 0, 1)
