"""Valid input taken as given and refusals that give the right advice (issue 57, class 8): a run dir
whose name holds '=' or ',' is the target and the init= of exploitability's responses, a bad init=
or algo.name= is refused before any response trains, a folder a killed exploitability left says how
to finish its run, and eval of a mixture says it is one."""

from __future__ import annotations

import shutil

import pytest
import yaml
from helpers import one_line_exit_2
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.config import ConfigError
from volleybots.eval.exploitability import run_exploitability

runner = CliRunner()


def test_exploitability_trains_against_a_run_whose_name_holds_equals_and_comma(tiny_1v1_run, tmp_path):
    odd = tmp_path / "run=1,x"
    shutil.copytree(tiny_1v1_run, odd, ignore=shutil.ignore_patterns(".lock"))
    report, path = run_exploitability([str(odd), f"init={odd}", "algo.hidden=[16]", "budget=32", "num_envs=4", "seeds=1", "games=2",
                                       "select_games=2", "threads=1", "progress=false"], tmp_path / "ex")
    cfg = yaml.safe_load((path / "br" / "config.yaml").read_text())
    assert cfg["opponent"] == str(odd) and cfg["init"] == str(odd)
    assert report["target"]["label"] == "run=1,x"


@pytest.mark.parametrize(("arg", "words"), [
    ("init=random", ["init='random'", "neither a run directory"]),
    ("algo.name=sac", ["algo.name=sac", "trained by MAPPO"]),
])
def test_exploitability_refuses_before_training(tmp_path, arg, words):
    res = runner.invoke(app, ["eval", "exploitability", "random", "task=1v1", arg, "budget=64", "games=2", "select_games=2",
                              "--out", str(tmp_path / "ex")])
    one_line_exit_2(res, *words)
    assert "training response" not in res.output and not (tmp_path / "ex").exists()


def test_a_folder_with_a_stopped_response_run_says_how_to_finish_it(tmp_path):
    (tmp_path / "ex" / "br").mkdir(parents=True)
    (tmp_path / "ex" / "br" / "config.yaml").write_text("task: {name: 1v1}\n")
    with pytest.raises(ConfigError, match=r"exists and is not an empty folder.*stopped before.*train resume=.*ex/br"):
        run_exploitability(["random", "task=1v1", "budget=0", "response=scripted", "games=2", "select_games=2"], tmp_path / "ex")


@pytest.mark.parametrize("verb", [["eval"], ["eval", "compare", "random"]])
def test_eval_of_a_mixture_says_it_is_one(verb):
    one_line_exit_2(runner.invoke(app, [*verb, "random+scripted", "task=1v1", "episodes=2"]),
                    "'random+scripted' is a mixture of 2 competitors, not one policy")
