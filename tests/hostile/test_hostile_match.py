"""The game a verb plays is the game it says it played (issue 57, classes 1 and 2): exploitability's
responses train on the match's task and physics, and a match verb refuses ``task.serve`` (who serves
is the scenario's) instead of recording a serve it did not play."""

from __future__ import annotations

import json

import pytest
import yaml
from helpers import one_line_exit_2
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.config import ConfigError
from volleybots.eval.crossplay import run_crossplay
from volleybots.eval.exploitability import run_exploitability

runner = CliRunner()


def test_exploitability_trains_its_response_on_the_match_it_plays(tmp_path):
    report, path = run_exploitability(["random", "task=1v1", "task.episode_len=30", "env.substeps=3", "budget=64", "num_envs=4",
                                       "seeds=1", "games=2", "select_games=2", "threads=1", "progress=false"], tmp_path / "ex")
    trained = yaml.safe_load((path / "br" / "config.yaml").read_text())
    assert trained["task"]["episode_len"] == 30 and trained["env"]["substeps"] == 3
    played = json.loads((path / "exploitability.json").read_text())["config"]
    assert played["task"]["episode_len"] == 30 and played["env"]["substeps"] == 3


@pytest.mark.parametrize("scenario", [[], ["scenario=serve"]])
def test_a_match_refuses_task_serve_and_points_at_scenario(tmp_path, scenario):
    with pytest.raises(ConfigError, match="task.serve=0 is not a match setting.*scenario="):
        run_crossplay(["random", "scripted", "task=1v1", "task.serve=0", "games=2", *scenario], tmp_path / "cp")
    res = runner.invoke(app, ["eval", "exploitability", "random", "task=1v1", "task.serve=1", "budget=0", "response=scripted",
                              "games=2", "select_games=2", "--out", str(tmp_path / "ex")])
    one_line_exit_2(res, "task.serve=1", "scenario=any|serve|receive")
    assert not (tmp_path / "cp").exists() and not (tmp_path / "ex").exists()
