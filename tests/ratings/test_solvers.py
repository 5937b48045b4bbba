"""Meta-solvers: Nash by linear programming is an equilibrium (checked against pure deviations on
random games), rock-paper-scissors gives uniform, dominated members get nothing."""

import numpy as np
import pytest

from volleybots.ratings.solvers import SOLVERS, exploitability, member_exploitability, nash, nash_with_value

RPS = np.array([[0.0, -1.0, 1.0], [1.0, 0.0, -1.0], [-1.0, 1.0, 0.0]])


def test_registry_names():
    assert {"uniform", "nash", "last", "alpharank"} <= set(SOLVERS)
    for name, solve in SOLVERS.items():
        x = solve(RPS)
        assert x.shape == (3,) and x.min() >= 0 and x.sum() == pytest.approx(1.0), name


def test_rock_paper_scissors_is_uniform():
    assert nash(RPS) == pytest.approx(np.full(3, 1 / 3), abs=1e-8)
    assert SOLVERS["alpharank"](RPS) == pytest.approx(np.full(3, 1 / 3), abs=1e-8)


def test_dominated_strategy_gets_nothing():
    # RPS plus a fourth strategy that loses to everything: strictly dominated
    a = np.zeros((4, 4))
    a[:3, :3] = RPS
    a[3, :3] = -0.5
    a[:3, 3] = 0.5
    x = nash(a)
    assert x[3] == pytest.approx(0.0, abs=1e-9)
    assert x[:3] == pytest.approx(np.full(3, 1 / 3), abs=1e-8)
    assert SOLVERS["alpharank"](a)[3] < 1e-6


def test_last_and_uniform():
    assert list(SOLVERS["last"](RPS)) == [0, 0, 1]
    assert list(SOLVERS["uniform"](np.zeros((4, 4)))) == [0.25] * 4


@pytest.mark.parametrize("seed", range(10))
def test_nash_of_random_zero_sum_games(seed):
    a = np.random.default_rng(seed).normal(size=(6, 6))
    x, v = nash_with_value(a)
    # the column player's minimax, solved from its own side, gives the same value
    y, w = nash_with_value(-a.T)
    assert v == pytest.approx(-w, abs=1e-6)
    assert x @ a @ y == pytest.approx(v, abs=1e-6)  # the mixtures' value is the LP's game value
    assert (x @ a).min() >= v - 1e-6  # no column deviation pays the column player
    assert (a @ y).max() <= v + 1e-6  # no row deviation gains against y
    assert x.min() >= 0 and x.sum() == pytest.approx(1.0)


def test_symmetric_game_exploitability():
    a = np.random.default_rng(0).normal(size=(5, 5))
    a = a - a.T  # symmetric zero-sum: value 0
    x = nash(a)
    assert exploitability(a, x) == pytest.approx(0.0, abs=1e-6)
    assert exploitability(a, SOLVERS["last"](a)) == pytest.approx(a[:, -1].max())
    ex = member_exploitability(a)
    assert ex == pytest.approx(a.max(0))  # diagonal 0: what the best other member gets against each
    assert np.all(ex >= -1e-12)


def test_bad_payoffs():
    with pytest.raises(ValueError, match="square"):
        nash(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="finite"):
        nash(np.array([[0.0, np.nan], [0.0, 0.0]]))


def test_nash_breaks_ties_by_maximum_entropy_whatever_the_order():
    """Games with many equilibria: the solver's choice is the max-entropy one, the same in any order."""
    assert nash(np.zeros((3, 3))) == pytest.approx(np.full(3, 1 / 3), abs=1e-5)  # all draws: every mixture is Nash
    # rock-paper-scissors with scissors twice: any split of 1/3 between the copies is an equilibrium
    a = np.zeros((4, 4))
    a[:3, :3] = RPS
    a[3, :3], a[:3, 3] = RPS[2], RPS[:, 2]
    x = nash(a)
    assert x == pytest.approx([1 / 3, 1 / 3, 1 / 6, 1 / 6], abs=1e-5)
    assert (x @ a).min() >= -1e-6  # still maximin: value 0
    perm = [3, 1, 0, 2]
    assert nash(a[np.ix_(perm, perm)]) == pytest.approx(x[perm], abs=1e-5)
    # a strict equilibrium is unchanged by the tie rule: one member beats all others
    b = np.array([[0.0, 0.4, 0.2], [-0.4, 0.0, 0.1], [-0.2, -0.1, 0.0]])
    assert nash(b) == pytest.approx([1.0, 0.0, 0.0], abs=1e-6)
