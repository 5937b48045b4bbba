"""Paired statistics of ``volleybots eval compare`` (the CLI is tested in test_cli.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from volleybots.eval.compare import paired


def test_a_constant_improvement_is_better_in_every_episode():
    base = np.array([1.0, 5.0, 2.0, 9.0, 4.0, 7.0, 3.0, 6.0])
    c = paired(base, base + 0.5)
    assert (c.wins, c.ties, c.losses) == (8, 0, 0)
    assert c.diff == pytest.approx(0.5) and c.se == pytest.approx(0.0) and c.low == pytest.approx(0.5) == pytest.approx(c.high)
    assert c.rank_biserial == 1.0 and c.p == pytest.approx(2 / 2**8) and c.verdict == "better"


def test_lower_is_better_flips_the_sign():
    base = np.array([1.0, 5.0, 2.0, 9.0, 4.0, 7.0, 3.0, 6.0])
    c = paired(base, base + 0.5, higher_is_better=False)
    assert c.diff == pytest.approx(-0.5) and (c.wins, c.losses) == (0, 8) and c.verdict == "worse"


def test_pairing_finds_a_small_shift_that_the_spread_of_the_starts_hides():
    rng = np.random.default_rng(0)
    start = rng.normal(10.0, 3.0, 100)  # what the episode's start contributes: the same for both
    a, b = start + rng.normal(0, 0.05, 100), start + 0.1 + rng.normal(0, 0.05, 100)
    assert stats.ttest_ind(b, a).pvalue > 0.5  # unpaired: nothing to see
    c = paired(a, b)
    assert c.verdict == "better" and c.p < 1e-6 and c.low > 0.05 and c.wins > 80
    t = stats.ttest_rel(b, a)
    assert c.diff / c.se == pytest.approx(t.statistic)  # the interval is the paired t-test's


def test_ties_and_mixed_results_are_level():
    base = np.arange(10.0)
    c = paired(base, base.copy())
    assert (c.wins, c.ties, c.losses) == (0, 10, 0) and c.p == 1.0 and c.verdict == "level" and c.diff == 0.0
    c = paired(base, base + np.array([1, -1] * 5))
    assert c.verdict == "level" and c.rank_biserial == 0.0
    with pytest.raises(ValueError, match="same length"):
        paired(base, base[:5])


def test_the_verdict_is_about_the_mean_not_the_typical_episode():
    # many episodes a little better, a few much worse: Solo Bump's clone against its teacher
    base = np.zeros(100)
    other = np.array([1.0] * 90 + [-13.0] * 10)
    c = paired(base, other)
    assert c.diff == pytest.approx(-0.4) and c.low < 0 < c.high and c.verdict == "level"
    assert c.rank_biserial > 0.5 and c.p < 1e-6  # yet the typical episode is better
