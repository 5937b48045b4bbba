"""Counts that pass their own check but multiply into unbounded work (issue 57, class 3) are refused
before anything starts, with the bound in the one line: exploitability's games and selection games
(the memory check cross-play already has), Elo's rounds x pairs x orders, bench's steps and repeats."""

from __future__ import annotations

import pytest
from helpers import one_line_exit_2
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.config import ConfigError
from volleybots.config.resources import ELO_MAX_GAMES, ELO_MAX_UPDATES, check_rounds
from volleybots.eval.exploitability import run_exploitability

runner = CliRunner()
FIXED = ["random", "task=1v1", "budget=0", "response=scripted"]


@pytest.mark.parametrize("key", ["games", "select_games"])
def test_exploitability_refuses_games_past_memory_before_playing(tmp_path, key):
    with pytest.raises(ConfigError, match=rf"^{key}=1000000000000 x \d pair\(s\).*needs at least .* GiB.*lower {key}$"):
        run_exploitability([*FIXED, f"{key}=1e12"], tmp_path / "ex")
    assert not (tmp_path / "ex").exists()


def test_elo_bounds_its_games_and_updates_before_playing(tmp_path):
    err = one_line_exit_2(runner.invoke(app, ["eval", "elo", "random", "scripted", "task=1v1", "orders=10000", "rounds=1e8",
                                              "--out", str(tmp_path / "elo")]), "rounds=100000000", f"{ELO_MAX_GAMES:,}")
    assert "lower rounds" in err and not (tmp_path / "elo").exists()
    with pytest.raises(ConfigError, match=f"orders=10000 is 10,000,000,000 Elo updates; the bound is {ELO_MAX_UPDATES:,}"):
        check_rounds(1_000_000, 2, orders=10_000)
    check_rounds(2000, 10, orders=100)  # the defaults with ten competitors pass


@pytest.mark.parametrize(("option", "bound"), [("steps=1e12", "[1, 100000]"), ("repeats=1000000", "[1, 20]")])
def test_bench_bounds_its_steps(option, bound):
    one_line_exit_2(runner.invoke(app, ["bench", "tasks=[hover]", "backends=[torch]", "num_envs=[2]", option]), bound)
