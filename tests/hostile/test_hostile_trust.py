"""What was trusted is checked (issue 57, class 9): a learned high level's weights and switches, the
task switches of ``make_env``, SB3's counts, PettingZoo's agent names and ragged actions, and
``report --stale-after``. Each is a ``ValueError`` (or one CLI line) naming the value."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from helpers import one_line_exit_2
from typer.testing import CliRunner

import volleybots
from volleybots.cli import app
from volleybots.config import ConfigError
from volleybots.policies.high_level import HighLevelNet, chooser_from_file, read_high_level, save_high_level

runner = CliRunner()


def test_a_high_level_with_nan_weights_is_refused(tmp_path):
    net = HighLevelNet((8,))
    with torch.no_grad():
        for p in net.parameters():
            p.fill_(float("nan"))
    save_high_level(net, tmp_path / "hl.pt")
    with pytest.raises(ConfigError, match=r"hl.pt'.*weights hold a NaN or an infinity \(heads\."):
        read_high_level(tmp_path / "hl.pt")


@pytest.mark.parametrize("value", ["false", 0, None])
def test_a_high_level_switch_that_is_not_a_bool_is_refused(tmp_path, value):
    save_high_level(HighLevelNet((8,)), tmp_path / "hl.pt", {"receive_attack": value})
    with pytest.raises(ConfigError, match=f"'receive_attack' is {value!r}, not true or false"):
        chooser_from_file(tmp_path / "hl.pt")
    save_high_level(HighLevelNet((8,)), tmp_path / "ok.pt", {"receive_attack": False})
    assert chooser_from_file(tmp_path / "ok.pt").receive_attack is False


def test_make_env_refuses_a_switch_that_is_not_a_bool():
    with pytest.raises(ValueError, match="bad value for 'opening': 'no' \\(must be True or False\\)"):
        volleybots.make_env("receive", opening="no")
    assert volleybots.make_env("receive", opening=True).opening is True


@pytest.mark.parametrize(("args", "words"), [((0,), "num_envs must be an integer >= 1, got 0"),
                                              ((4, -5), "n_steps must be an integer >= 1, got -5"),
                                              ((4, 8, True), "minibatches must be an integer >= 1, got True")])
def test_ppo_kwargs_refuses_counts_below_one(args, words):
    pytest.importorskip("stable_baselines3")
    from volleybots.integrations.sb3_env import ppo_kwargs

    with pytest.raises(ValueError, match=words):
        ppo_kwargs(*args)


def test_pettingzoo_names_the_agent_and_the_agents():
    pytest.importorskip("pettingzoo")
    from volleybots.integrations.pettingzoo_env import VolleyParallelEnv

    env = VolleyParallelEnv("1v1")
    with pytest.raises(ValueError, match="unknown agent 'bogus'; agents: blue_0, red_0"):
        env.observation_space("bogus")
    with pytest.raises(ValueError, match="unknown agent 'bogus'"):
        env.action_space("bogus")
    env.reset(seed=0)
    actions = {a: np.zeros(4, dtype=np.float32) for a in env.agents}
    actions["red_0"] = [0.1, [0.2, 0.3], 0.3, 0.4]
    with pytest.raises(ValueError, match=r"agent 'red_0': got a ragged action .*expected shape \(4,\)"):
        env.step(actions)
    env.close()


@pytest.mark.parametrize("value", ["nan", "inf", "-1"])
def test_report_refuses_a_stale_after_that_is_not_a_finite_age(tmp_path, value):
    one_line_exit_2(runner.invoke(app, ["report", str(tmp_path), "--stale-after", value]), "--stale-after", "finite number of seconds")
