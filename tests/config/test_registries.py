"""Contract tests over every registry: algorithms, population presets, built-in players,
meta-solvers and rating methods. A new entry is held to the same contract without a new test."""

from __future__ import annotations

import dataclasses
import shutil

import numpy as np
import pytest
import torch
from omegaconf import OmegaConf

from volleybots.algos import ALGOS, is_population
from volleybots.algos.population import PRESETS
from volleybots.config import compose, load, make_env, validate
from volleybots.policies import PLAYERS, check_references, resolve_target
from volleybots.ratings.solvers import SOLVERS


def _plain(x):
    return OmegaConf.to_container(x) if OmegaConf.is_config(x) else x


@pytest.mark.parametrize("name", sorted(ALGOS))
def test_the_yaml_of_every_algorithm_equals_its_dataclass_defaults(name):
    """One source of defaults: conf/algo/<name>.yaml repeats the dataclass (it exists for Hydra's
    ``--cfg`` and the comments); a value changed in one and not the other fails here."""
    cls = ALGOS[name]
    yaml = OmegaConf.to_container(compose([f"algo={name}", f"env.action_space={cls.action_spaces[0]}"]).algo)
    defaults = OmegaConf.to_container(OmegaConf.structured(cls.config_cls))
    assert set(yaml) <= set(defaults), f"keys only in the YAML: {sorted(set(yaml) - set(defaults))}"
    differ = {k: (yaml[k], defaults[k]) for k in yaml if _plain(yaml[k]) != _plain(defaults[k])}
    assert differ == {}, f"conf/algo/{name}.yaml differs from {cls.config_cls.__name__}: {differ}"
    missing = set(defaults) - set(yaml)
    assert missing == set(), f"{cls.config_cls.__name__} keys missing from conf/algo/{name}.yaml: {sorted(missing)}"


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_the_yaml_of_every_population_equals_its_dataclass_defaults(name):
    """conf/population/<name>.yaml repeats its preset's loop dataclass (the name and solver are the preset's),
    and sets under algo the fine-tuning recipe (``FINE_TUNING``) and nothing else of the learner's."""
    from volleybots.algos.population import FINE_TUNING

    preset = PRESETS[name]
    cfg = compose(["task=1v1", f"population={name}"])
    yaml = OmegaConf.to_container(cfg.population)
    defaults = {**OmegaConf.to_container(OmegaConf.structured(preset.config_cls)), "name": name, "solver": preset.solver}
    assert yaml == defaults, f"conf/population/{name}.yaml differs from {preset.config_cls.__name__}"
    assert cfg.algo.name == preset.learner  # the file's default learner is the preset's
    learner = OmegaConf.to_container(OmegaConf.structured(preset.learner_cls.config_cls))
    assert {k: v for k, v in OmegaConf.to_container(cfg.algo).items() if _plain(learner.get(k)) != _plain(v)} == FINE_TUNING


def test_the_top_level_yaml_equals_the_config_dataclass():
    from volleybots.config.schema import CheckpointConfig, Config, EvaluationConfig, WandbConfig

    cfg = OmegaConf.to_container(compose([]))
    for f in dataclasses.fields(Config):
        if f.name in ("task", "algo", "population", "env"):  # the groups: compared with their own dataclasses
            continue
        default = f.default if f.default is not dataclasses.MISSING else dataclasses.asdict(f.default_factory())
        assert cfg[f.name] == default, f"conf/config.yaml {f.name}: {cfg[f.name]!r}, Config: {default!r}"
    for sub in (CheckpointConfig, EvaluationConfig, WandbConfig):
        assert sub.__name__  # the nested ones were compared as dicts above


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
@pytest.mark.parametrize("name", sorted(ALGOS))
def test_every_algorithm_composes_validates_and_builds_on_a_task_it_accepts(name):
    """The registry contract: a class with a name, a config dataclass, action spaces and ``check``; on a
    task it accepts, the validated config builds its learner and the learner acts in the action space."""
    from volleybots.algos.base import AgentSpec
    from volleybots.policies.store import learner_class
    from volleybots.tasks import TASKS

    cls = ALGOS[name]
    assert cls.name == name and dataclasses.is_dataclass(cls.config_cls) and cls.action_spaces
    task = next(t for t in ("solo_bump", "bump_and_pass", "1v1") if _accepts(cls, t))
    cfg = load([f"task={task}", f"algo={name}", f"env.action_space={cls.action_spaces[0]}", "env.num_envs=2", "threads=1"])
    assert validate(OmegaConf.to_container(cfg)).algo == cfg.algo  # validation is idempotent
    env = make_env(cfg, num_envs=2)
    n = len(env.team_index(0)) if is_population(cfg) else env.n_drones
    learner = learner_class(cfg.algo)(cfg.algo, AgentSpec.of(env, n), seed=0)
    if hasattr(learner, "attach"):
        learner.attach(env)
    td = env.reset()
    if n != env.n_drones:
        td = td.exclude("agents").set("agents", td.get("agents")[:, :n])
    act = learner.policy(deterministic=True)(td).get(("agents", "action"))
    assert act.shape[:2] == (2, n)
    if env.actions.continuous:
        assert torch.isfinite(act).all() and act.abs().max() <= 1.0 + 1e-5
    assert TASKS[task].name == task


def _accepts(cls, task: str) -> bool:
    from volleybots.config import ConfigError

    try:
        load([f"task={task}", f"algo={cls.name}", f"env.action_space={cls.action_spaces[0]}"])
    except ConfigError:
        return False
    return True


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
@pytest.mark.parametrize("name", sorted(PRESETS))
def test_every_population_preset_accepts_its_own_default_start_and_refuses_the_others_by_name(name):
    """A preset that is defined by its learners' start (FSP: each continues the newest member) refuses
    every other ``population.learner_init`` with one line naming the value; the rest take every start."""
    from volleybots.algos.population import INITS
    from volleybots.config import ConfigError

    preset = PRESETS[name]
    assert set(preset.learner_inits) <= set(INITS) and bool(preset.learner_inits) == bool(preset.otherwise)
    defaults = {init for _, init, _ in preset.starts}  # what each population.start gives learner_init
    base = OmegaConf.to_container(compose(["task=1v1", f"algo={name}", "env.num_envs=2", "threads=1"]))
    for init in INITS:
        raw = {**base, "population": {**base["population"], "learner_init": init}}
        if not preset.learner_inits or init in preset.learner_inits:
            assert validate(raw).population.learner_init == init
        else:
            with pytest.raises(ConfigError, match=f"^population={name} .*'{init}'"):
                validate(raw)
    assert not preset.learner_inits or defaults <= set(preset.learner_inits)


def test_the_names_a_spec_may_give_are_the_built_in_players():
    from volleybots.policies.store import BUILTIN_NAMES

    assert BUILTIN_NAMES == tuple(PLAYERS)


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
@pytest.mark.parametrize("name", sorted(PLAYERS))
def test_every_built_in_player_acts_in_the_space_of_the_tasks_it_fits(name):
    player = PLAYERS[name]
    task = player.task or "1v1"
    env = make_env(load([f"task={task}", "threads=1"]), num_envs=2)
    td = player.both(env)(env.reset())
    act = td.get(("agents", "action"))
    assert act.shape[:2] == (2, env.n_drones) and torch.isfinite(act.float()).all()
    assert resolve_target(name, [f"task={task}"]).label == name
    if player.task is not None:  # a player of one task is refused elsewhere, before any run starts
        elsewhere = "3v3" if player.task == "1v1" else "1v1"
        other = load([f"task={elsewhere}", "algo=sp", f"algo.eval_opponent={name}"])
        with pytest.raises(Exception, match=f"plays task '{player.task}' only"):
            check_references(other)


@pytest.mark.parametrize("name", sorted(SOLVERS))
def test_every_meta_solver_returns_a_mixture_that_a_dominant_strategy_wins(name):
    # row 0 beats everything: every solver but "last" must put most weight on it; "last" picks the newest
    payoffs = np.array([[0.0, 0.6, 0.8], [-0.6, 0.0, 0.2], [-0.8, -0.2, 0.0]])
    mix = np.asarray(SOLVERS[name](payoffs), dtype=float)
    assert mix.shape == (3,) and np.all(mix >= -1e-12) and mix.sum() == pytest.approx(1.0)
    assert (mix[2] == pytest.approx(1.0)) if name == "last" else (mix[0] >= max(mix[1], mix[2]))


def test_every_rating_method_orders_a_clear_hierarchy():
    """Elo (the paper's rounds) and Bradley-Terry both rank a stronger player first."""
    from volleybots.ratings import bradley_terry, elo, round_robin

    rng = np.random.default_rng(0)
    strength = np.array([400.0, 200.0, 0.0])  # Elo points
    p_win = lambda a, b: 1 / (1 + 10 ** ((strength[b] - strength[a]) / 400))  # noqa: E731
    games = round_robin(3, 300, lambda a, b, r: float(rng.random() < p_win(a, b)), rng)
    assert list(np.argsort(-elo(games, 3, k=16))) == [0, 1, 2]
    wdl = np.zeros((3, 3, 3))
    for a, b, score in games:
        a, b = int(a), int(b)
        wdl[a, b, 0 if score == 1 else 2] += 1
        wdl[b, a, 2 if score == 1 else 0] += 1
    bt = bradley_terry(wdl)
    assert list(np.argsort(-bt)) == [0, 1, 2]
    assert bt[0] - bt[2] == pytest.approx(400, abs=120)  # the true gap, within sampling noise of 600 games


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_a_run_dir_evaluates_after_the_files_it_was_trained_against_have_moved(tmp_path):
    """Validating a saved config never opens the files it names: a run trained with
    ``opponent=CHECKPOINT`` still evaluates once that checkpoint has moved away."""
    from volleybots.eval import evaluate
    from volleybots.train import train

    tiny = ["task=1v1", "env.num_envs=4", "algo.steps_per_batch=8", "total_frames=32", "threads=1", "progress=false",
            "evaluation.every=0", "evaluation.episodes=2", "evaluation.record=false", "checkpoint.every=0"]
    train(load([*tiny, "algo=mappo", "opponent=random"]), tmp_path / "first")
    opp = tmp_path / "opponent.pt"
    shutil.copy(tmp_path / "first" / "checkpoints" / "final.pt", opp)
    train(load([*tiny, "algo=mappo", f"opponent={opp}"]), tmp_path / "second")
    opp.rename(tmp_path / "moved.pt")
    out = evaluate(str(tmp_path / "second"), ["episodes=2", "threads=1"])
    assert out["episodes"] == 2 and out["task"] == "1v1"
    # what needs the file still says so, in one line
    from volleybots.config import ConfigError
    from volleybots.train import resume

    with pytest.raises(ConfigError, match="does not exist"):
        resume(tmp_path / "second", ["total_frames=64"])
