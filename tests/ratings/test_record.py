"""The one layout of game records (wins, draws, losses on the last axis) and its arithmetic."""

from __future__ import annotations

import math

import numpy as np
import pytest

from volleybots.ratings import record

TABLE = np.array([[[0, 0, 0], [6, 2, 2], [0, 4, 0]],
                  [[2, 2, 6], [0, 0, 0], [0, 0, 0]],
                  [[0, 4, 0], [0, 0, 0], [0, 0, 0]]])


def test_counts_of_a_record():
    assert record.games([6, 2, 2]) == 10 and record.decisive([6, 2, 2]) == 8
    assert record.games(TABLE).tolist() == [[0, 10, 4], [10, 0, 0], [4, 0, 0]]
    assert record.decisive(TABLE).tolist() == [[0, 8, 0], [8, 0, 0], [0, 0, 0]]
    assert record.tally("WWDLW").tolist() == [3, 1, 1] and record.tally("").tolist() == [0, 0, 0]


def test_win_rate_is_over_decisive_games_and_nan_without_one():
    assert record.win_rate([6, 2, 2]) == pytest.approx(0.75)
    assert math.isnan(record.win_rate([0, 4, 0]))
    rate = record.win_rate(TABLE)
    assert rate[0, 1] == pytest.approx(0.75) and rate[1, 0] == pytest.approx(0.25)
    assert np.isnan(rate[0, 2]) and np.isnan(rate[0, 0])


def test_win_rate_interval_is_wilsons():
    lo, hi = record.win_rate_interval([6, 2, 2])
    # Wilson 95 % for 6 of 8: (p + z^2/2n -+ z sqrt(p q / n + z^2/4n^2)) / (1 + z^2/n)
    z, n, p = 1.959963984540054, 8, 0.75
    mid, half = p + z * z / (2 * n), z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    assert (lo, hi) == pytest.approx(((mid - half) / (1 + z * z / n), (mid + half) / (1 + z * z / n)))
    lo, hi = record.win_rate_interval(TABLE)
    assert np.isnan(lo[0, 2]) and lo[0, 1] == pytest.approx(1 - hi[1, 0])


def test_payoff_is_the_mean_game_score_and_zero_without_games():
    assert record.payoff([6, 2, 2]) == pytest.approx(0.4)
    pay = record.payoff(TABLE)
    assert np.allclose(pay, [[0.0, 0.4, 0.0], [-0.4, 0.0, 0.0], [0.0, 0.0, 0.0]])
    assert np.allclose(pay, -pay.T)
    assert record.points([6, 2, 2]) == 7.0 and record.points(TABLE)[1].tolist() == [3.0, 0.0, 0.0]


def test_flip_is_the_other_sides_view_and_put_mirrors():
    assert record.flip([6, 2, 1]).tolist() == [1, 2, 6]
    assert record.flip([[1, 0, 3], [5, 4, 2]]).tolist() == [[3, 0, 1], [2, 4, 5]]
    t = np.zeros((3, 3, 3), dtype=int)
    record.put(t, 0, 1, np.array([6, 2, 2]))
    record.put(t, 2, 0, np.array([0, 4, 0]))
    record.put(t, 1, 0, np.array([2, 2, 6]))
    assert t.tolist() == TABLE.tolist()
    assert (record.flip(TABLE) == TABLE.transpose(1, 0, 2)).all()


def test_from_dict_reads_three_matrices_into_one_record():
    wdl = record.from_dict({"wins": [[0, 6], [2, 0]], "draws": [[0, 2], [2, 0]], "losses": [[0, 2], [6, 0]]})
    assert wdl.shape == (2, 2, 3) and wdl.tolist() == TABLE[:2, :2].tolist()
    assert record.from_dict({"wins": 3, "draws": 1, "losses": 0}).tolist() == [3, 1, 0]
