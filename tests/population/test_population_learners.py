"""A population's learner is the one ``algo=`` names (``algo.learner=`` before), and saved configs of before
there was a choice still load as MAPPO populations."""

from pathlib import Path

import pytest
import torch
from omegaconf import OmegaConf

from volleybots.algos import HAPPO, MAPPO, PRESETS, is_population
from volleybots.config import ConfigError, load, validate
from volleybots.policies.store import learner_class, load_learner
from volleybots.population.run import start

SAVED = Path(__file__).resolve().parents[1] / "data" / "saved_configs"  # written by the code of before algo.learner (d5bf0eb)

TINY_3V3 = [
    "task=3v3", "env.num_envs=8", "algo.steps_per_batch=16", "algo.minibatches=2", "algo.epochs=1", "algo.hidden=[16,16]",
    "algo.min_updates=1", "algo.max_updates=2", "algo.payoff_games=2", "algo.iterations=1", "evaluation.episodes=1",
    "evaluation.every=0", "evaluation.record=false", "checkpoint.every=0", "progress=false", "threads=1", "total_frames=100000",
    "algo.start=scratch", "algo.members=flat",  # a flat learner (members=auto is hierarchical on 3v3)
]


@pytest.mark.parametrize("path", sorted(SAVED.glob("*.yaml")), ids=lambda p: p.stem)
def test_a_saved_population_config_of_before_algo_learner_loads_as_mappo(path):
    data = OmegaConf.to_container(OmegaConf.load(path))
    assert "learner" not in data["algo"]
    cfg = validate(data)
    assert is_population(cfg) and cfg.algo.name == "mappo" and cfg.population.name == data["algo"]["name"]
    assert learner_class(cfg.algo) is MAPPO
    # the values saved are the values loaded (the loop's now under population): nothing the run did is re-read
    # from today's defaults, and the keys added since read as what the run did then (flat members, no fixed opponents)
    loaded = {**OmegaConf.to_container(cfg.algo), **OmegaConf.to_container(cfg.population)}
    assert {k: loaded[k] for k in data["algo"]} == data["algo"]
    assert (loaded["members"], loaded["fixed_opponents"], loaded["fixed_share"]) == ("flat", [], 0.0)


def test_one_question_tells_populations_from_learners():
    assert all(is_population(n) and is_population(p) for n, p in PRESETS.items())
    assert not any(is_population(n) for n in ("mappo", "happo", "bc", "ppo", "nope"))
    assert is_population({"name": "fsp"}) and not is_population({"name": "mappo"}) and not is_population({})
    assert is_population(load(["task=1v1", "algo=fsp"])) and not is_population(load(["task=1v1", "algo=mappo"]))


def test_the_learner_and_loop_keys_are_separate_dataclasses():
    import dataclasses

    from volleybots.algos import LEARNERS
    from volleybots.algos.population import LoopConfig

    assert PRESETS["psro_nash"].config_cls is LoopConfig and PRESETS["sp"].config_cls().self_play is True
    loop = {f.name for f in dataclasses.fields(LoopConfig)}
    for cls in LEARNERS.values():  # no key is both: algo.K and population.K never shadow each other
        assert loop & {f.name for f in dataclasses.fields(cls.config_cls)} == {"name"}
    cfg = load(["task=3v3", "population=psro_nash", "algo=happo", "population.start=scratch"])
    assert (cfg.population.name, cfg.population.solver, cfg.algo.name) == ("psro_nash", "nash", "happo")


@pytest.mark.parametrize("overrides, match", [
    (["task=1v1", "algo.learner=happo"], "cannot learn a team of 1 drone"),
    (["task=3v3", "algo.learner=qmix"], "cannot train algo=qmix as its learner; allowed: mappo, happo, mat"),
    (["task=3v3", "algo.learner=mat", "algo.start=clone", "algo.members=flat"], "cannot start from the clone"),
    (["task=3v3", "algo.learner=mat", "algo.members=hierarchical"], "algo=mat trains flat members; .* give population.members=flat"),
])
def test_a_learner_that_cannot_play_one_team_is_one_line(overrides, match):
    with pytest.raises(ConfigError, match=match):
        load(["algo=psro_nash", "algo.start=scratch", *overrides])


def test_a_learners_own_keys_are_given_as_algo_keys():
    cfg = load(["task=3v3", "algo=psro_nash", "algo.learner=mat", "algo.start=scratch", "algo.embed_dim=32", "algo.n_heads=4"])
    assert cfg.algo.embed_dim == 32 and cfg.algo.n_heads == 4 and cfg.population.iterations == 5


@pytest.mark.slow
def test_a_happo_population_member_trains_saves_and_reloads_through_the_store(tmp_path):
    cfg = load([*TINY_3V3, "algo=psro_nash", "algo.learner=happo"])
    summary = start(cfg, tmp_path / "run")
    assert summary["population"]["members"] == ["random", "br1"]
    member = tmp_path / "run" / "population" / "member_001.pt"
    state = torch.load(member, weights_only=True)
    assert state["config"]["algo"]["name"] == "happo"
    assert any(k.startswith("actors.2.") for k in state["algo"]["actor"])  # one actor per drone of the team: HAPPO's
    from volleybots.config import make_env

    env = make_env(cfg, num_envs=2)
    algo, _ = load_learner(member, env, n_agents=3)
    assert isinstance(algo, HAPPO)
    mine, saved = algo.actor.state_dict(), state["algo"]["actor"]
    assert mine.keys() == saved.keys() and all(torch.equal(mine[k].cpu(), saved[k]) for k in mine)
    td = env.reset()
    td["agents"] = td["agents"][:, :3]
    out = algo.policy(deterministic=True)(td)
    assert out["agents", "action"].shape[:2] == (2, 3) and torch.isfinite(out["agents", "action"]).all()
