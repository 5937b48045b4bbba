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


def test_a_nan_episode_is_refused_not_counted_as_level():
    from volleybots.errors import ConfigError

    base = np.arange(6.0)
    other = base + 1.0
    other[3] = np.nan  # a nan difference is neither > 0, < 0 nor == 0: it used to vanish from W/T/L
    with pytest.raises(ConfigError, match=r"other's metric is not a finite number in 1 of 6 episodes \(episode 3\)"):
        paired(base, other)
    base[[0, 5]] = np.inf
    with pytest.raises(ConfigError, match=r"baseline's .* 2 of 6 episodes \(episode 0, 5\)"):
        paired(base, base + 1.0)


def test_one_episode_is_refused():
    from volleybots.errors import ConfigError

    with pytest.raises(ConfigError, match="length >= 2"):
        paired(np.array([1.0]), np.array([2.0]))


# ------------------------------------------------------------------ the command line
class _Env:
    metric, metric_higher_is_better = "distance", False


def _fake_play(metrics: dict):
    """A stand-in for compare's ``_play``: per target label, its per-episode metric (same first observation)."""
    import torch

    def play(target, episodes):
        return _Env(), {"distance": torch.tensor(metrics[target.label], dtype=torch.float64)}, torch.zeros(4, 1, 3)

    return play


def _cli(args):
    from typer.testing import CliRunner

    from volleybots.cli import app

    return CliRunner().invoke(app, ["eval", "compare", *args, "task=hover", "--json"])


def test_cli_refuses_a_nan_episode_with_one_line(monkeypatch):
    import volleybots.eval.compare as compare_mod

    monkeypatch.setattr(compare_mod, "_play", _fake_play({"random": [3.0, 2.0, 4.0, 1.0], "scripted": [1.0, float("nan"), 2.0, 0.5]}))
    res = _cli(["random", "scripted", "episodes=4"])
    assert res.exit_code == 2, res.output
    err = res.stderr.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in res.output
    assert "'scripted'" in err and "distance" in err and "episode 1" in err
    # without the nan the same fake comparison goes through: the refusal is the nan's
    monkeypatch.setattr(compare_mod, "_play", _fake_play({"random": [3.0, 2.0, 4.0, 1.0], "scripted": [2.0, 1.0, 3.0, 0.0]}))
    res = _cli(["random", "scripted", "episodes=4"])
    assert res.exit_code == 0, res.output
    assert '"verdict": "better"' in res.stdout


def test_cli_refuses_one_episode_before_playing(monkeypatch):
    import volleybots.eval.compare as compare_mod

    def never(*a, **k):
        raise AssertionError("an episode was played")

    monkeypatch.setattr(compare_mod, "_play", never)
    res = _cli(["random", "scripted", "episodes=1"])
    assert res.exit_code == 2, res.output
    err = res.stderr.strip()
    assert len(err.splitlines()) == 1 and "episodes=1" in err and "episodes >= 2" in err
