"""A+B / A*3+B: a mixture of competitors wherever a competitor plays (opponent=, eval crossplay)."""

from __future__ import annotations

import pytest
import torch
from helpers import TINY_1V1, one_line_exit_2
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.config import load, make_env
from volleybots.errors import ConfigError
from volleybots.policies.competitors import resolve_competitor
from volleybots.policies.store import parse_single, split_mixture


def test_split_reads_relative_weights_and_labels():
    assert split_mixture("scripted") is None
    assert split_mixture("scripted+random") == ("scripted+random", [("scripted", 0.5), ("random", 0.5)])
    label, parts = split_mixture("mix=scripted*3+random")
    assert label == "mix" and parts == [("scripted", 0.75), ("random", 0.25)]
    # a part's own label stays with the part
    assert split_mixture("scripted+b=random*1")[1] == [("scripted", 0.5), ("b=random", 0.5)]
    assert split_mixture("scripted+b=random")[0] == "scripted+b=random"


def test_an_existing_path_holding_plus_is_that_path(tmp_path):
    odd = tmp_path / "a+b*2.pt"
    odd.write_bytes(b"x")
    assert split_mixture(str(odd)) is None


@pytest.mark.parametrize("spec, words", [
    ("scripted+", ["empty part"]),
    ("scripted*0+random", ["'0'", "positive"]),
    ("scripted*x+random", ["'x'", "positive"]),
    ("scripted*inf+random", ["'inf'", "positive"]),
])
def test_bad_mixtures_are_one_line(spec, words):
    with pytest.raises(ConfigError) as e:
        split_mixture(spec)
    assert all(w in str(e.value) for w in words) and "\n" not in str(e.value)


def test_a_mixture_is_not_one_policy():
    with pytest.raises(ConfigError, match="mixture of 2 competitors, not one policy"):
        parse_single("scripted+random", "init=")


def test_members_and_weights_flatten_and_each_episode_draws_by_weight():
    comp = resolve_competitor("scripted*3+random")
    assert comp.label == "scripted*3+random"  # as written: a differently weighted mixture is another competitor
    assert [m.label for m in comp.members] == ["scripted", "random"] and comp.mixture == [0.75, 0.25]
    env = make_env(load(["task=1v1"]), num_envs=2000, seed=0)
    gen = torch.Generator().manual_seed(0)
    policy = comp.team_policy(env, generator=gen)
    policy.begin_episodes(torch.ones(2000, dtype=torch.bool))
    share = (policy.choice == 0).float().mean().item()
    assert 0.72 < share < 0.78, share  # 1,500 of 2,000 expected; 3 sigma is 0.029


def test_a_population_in_a_mixture_keeps_its_meta_strategy_scaled():
    from volleybots.policies.competitors import mixed

    comp = mixed("m", [("scripted", 0.5), ("random", 0.5)])
    assert comp.mixture == [0.5, 0.5]
    # a mixture inside a mixture (the grammar has no brackets, so only through a population or zoo
    # mixture part): its weights multiply
    inner = resolve_competitor("scripted+random")
    from unittest import mock

    with mock.patch("volleybots.policies.competitors.resolve_competitor", side_effect=[inner, resolve_competitor("receiver")]):
        comp = mixed("m", [("pop", 0.8), ("receiver", 0.2)])
    assert [m.label for m in comp.members] == ["scripted", "random", "receiver"]
    assert comp.mixture == pytest.approx([0.4, 0.4, 0.2])


def test_training_against_a_mixture_and_a_bad_one_from_the_cli(tmp_path):
    run = tmp_path / "run"
    tiny = [*TINY_1V1, "algo=mappo", "total_frames=256"]
    res = CliRunner().invoke(app, ["train", *tiny, "opponent=scripted*3+random", f"hydra.run.dir={run}"])
    assert res.exit_code == 0, res.output
    assert "opponent: scripted*3+random" in (run / "config.yaml").read_text()
    bad = tmp_path / "bad"
    res = CliRunner().invoke(app, ["train", *tiny, "opponent=scripted*0+random", f"hydra.run.dir={bad}"])
    one_line_exit_2(res, "'0'", "positive")
    assert not bad.exists()
