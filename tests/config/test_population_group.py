"""``population=`` is a config group and ``algo=`` the learner alone (issue 56): a population's learner
composes from its own file with all its defaults, a match task's default population takes its keys, a
``-m`` sweep over a learner's own key composes every job, and the spellings of before keep working."""

from __future__ import annotations

import pytest
import yaml
from omegaconf import OmegaConf
from typer.testing import CliRunner

from volleybots.algos import LEARNERS
from volleybots.algos.population import FINE_TUNING
from volleybots.cli import app
from volleybots.config import ConfigError, compose, load, validate
from volleybots.config.spelling import respell

runner = CliRunner()
SPELLINGS = {  # the same run, as typed before population= and as typed now (flat members: a learner's own networks)
    "before": ["task=3v3", "algo=psro_nash", "algo.learner={learner}", "algo.start=scratch", "algo.members=flat"],
    "now": ["task=3v3", "population=psro_nash", "algo={learner}", "population.start=scratch", "population.members=flat"],
}


def _own_defaults(learner: str) -> dict:
    return OmegaConf.to_container(OmegaConf.structured(LEARNERS[learner].config_cls))


@pytest.mark.parametrize("spelling", sorted(SPELLINGS))
@pytest.mark.parametrize("learner", ["mat", "happo"])
def test_a_population_learner_takes_its_own_defaults_for_every_shared_key(learner, spelling):
    """``algo=psro_nash algo.learner=mat`` composed MAPPO's actor_lr 5e-4 (MAT's own: 3e-5) and HAPPO
    oracles MAPPO's hidden sizes: the preset's file inherited MAPPO's. Now every key of the learner is
    its own default, but for the population's fine-tuning recipe (``FINE_TUNING``, documented)."""
    cfg = load([w.format(learner=learner) for w in SPELLINGS[spelling]])
    own, got = _own_defaults(learner), OmegaConf.to_container(cfg.algo)
    assert set(got) == set(own)
    differ = {k: (got[k], own[k]) for k in own if got[k] != own[k]}
    assert differ == {k: (v, own[k]) for k, v in FINE_TUNING.items()}, differ
    assert cfg.population.name == "psro_nash" and cfg.population.start == "scratch"
    if learner == "mat":
        assert cfg.algo.actor_lr == cfg.algo.critic_lr == 3.0e-5
    else:
        assert list(cfg.algo.hidden) == [256, 128]


def test_cfg_job_of_a_mat_population_shows_mats_own_learning_rates():
    res = runner.invoke(app, ["train", "task=3v3", "algo=psro_nash", "algo.learner=mat", "algo.start=scratch", "--cfg", "job"])
    assert res.exit_code == 0, res.output
    shown = yaml.safe_load(res.stdout)
    assert (shown["algo"]["name"], shown["algo"]["actor_lr"], shown["algo"]["critic_lr"]) == ("mat", 3.0e-5, 3.0e-5)
    assert shown["population"]["name"] == "psro_nash"
    # the old spelling is read, with one note line naming the new one
    assert "algo.learner=mat is read as algo=mat" in res.stderr and len(res.stderr.strip().splitlines()) == 2


@pytest.mark.parametrize("words", [
    ["algo.iterations=3", "algo.start=scratch"],  # as typed before: the loop's keys under algo
    ["population.iterations=3", "population.start=scratch"],
])
def test_a_match_task_with_no_algo_accepts_the_default_populations_keys(words):
    """``train task=3v3 algo.iterations=3`` was refused ("unknown config key 'algo.iterations'") although
    ``--cfg job`` showed the task's default population: the default was pinned after the keys were checked."""
    cfg = load(["task=3v3", *words])
    assert (cfg.population.name, cfg.population.iterations, cfg.population.start, cfg.algo.name) == ("sp", 3, "scratch", "mappo")
    res = runner.invoke(app, ["train", "task=3v3", *words, "--cfg", "job"])
    assert res.exit_code == 0 and yaml.safe_load(res.stdout)["population"]["iterations"] == 3, res.output


def test_the_headline_command_is_the_population_with_its_default_learner():
    cfg = load(["task=3v3", "algo=psro_nash"])
    assert (cfg.population.name, cfg.algo.name, cfg.population.solver) == ("psro_nash", "mappo", "nash")
    assert respell(["task=3v3", "algo=psro_nash"]) == (["task=3v3", "population=psro_nash"], [])  # no note: a spelling of its own
    assert load(["task=3v3"]).population.name == "sp" and load(["task=bump_and_pass"]).population is None
    assert load(["task=1v1", "opponent=scripted"]).population is None  # one team's learner against a competitor


def test_a_sweep_over_a_learners_own_key_composes_every_job(monkeypatch, tmp_path):
    """``train -m task=3v3 algo=psro_nash algo.learner=mat algo.embed_dim=64 seed=0,1`` passed the pre-check
    and failed inside the job: the ``+algo.embed_dim`` rewrite happened in composition, which ``-m`` bypasses.
    The jobs run here through Hydra's own multirun, with the trainer replaced by a recorder."""
    import volleybots.population.run as run

    seen = []

    def fake_start(cfg, run_dir, checked=False):
        seen.append(cfg)
        return {"final_eval": {"stats": {"win": {"mean": 0.0, "std": 0.0}}}, "metric": "win", "frames": 0, "wall_time_s": 0.0,
                "frames_per_s": 0.0}

    monkeypatch.setattr(run, "start", fake_start)
    monkeypatch.setattr("volleybots.cli.train._sweep_report", lambda sweep_dir: None)
    res = runner.invoke(app, ["train", "-m", "task=3v3", "algo=psro_nash", "algo.learner=mat", "algo.embed_dim=64", "algo.start=scratch",
                              "algo.members=flat", "seed=0,1", f"hydra.sweep.dir={tmp_path / 'sweep'}"])
    assert res.exit_code == 0, res.output
    assert sorted(c.seed for c in seen) == [0, 1]
    for c in seen:
        assert (c.population.name, c.algo.name, c.algo.embed_dim, c.algo.actor_lr) == ("psro_nash", "mat", 64, 3.0e-5)


def test_the_jobs_of_a_sweep_compose_with_hydra_alone():
    """What Hydra's sweeper hands each job are the words ``respell`` wrote: they compose without it."""
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir

    from volleybots.cli.train import _jobs
    from volleybots.paths import conf_dir

    words, _ = respell(["task=3v3", "algo=psro_nash", "algo.learner=mat", "algo.embed_dim=64,128", "algo.iterations=2", "seed=0,1"])
    with initialize_config_dir(config_dir=str(conf_dir()), version_base="1.3"):
        cfgs = [validate(hydra_compose("config", overrides=[*job, "population.start=scratch"])) for job in _jobs(words, True)]
    assert sorted((c.algo.embed_dim, c.seed) for c in cfgs) == [(64, 0), (64, 1), (128, 0), (128, 1)]
    assert {(c.algo.name, c.population.iterations) for c in cfgs} == {("mat", 2)}


@pytest.mark.parametrize("words, match", [
    (["task=3v3", "algo=ppo,psro_nash"], "^algo=ppo,psro_nash mixes learners and population methods"),
    (["task=hover", "algo.learner=mat"], "^algo.learner=mat names a population's learner, now spelt algo=mat, and this run trains no"),
    (["task=3v3", "algo=psro_nash", "algo=mat", "algo.learner=happo"], "^algo.learner=happo names .* algo=mat names it too"),
    (["task=3v3", "population=psro_nash", "algo=qmix"],
     "^population=psro_nash cannot train algo=qmix as its learner; allowed: mappo, happo, mat$"),
    (["task=3v3", "population=nope"], "^unknown population 'nope'; allowed: fsp, psro_nash, psro_uniform, sp$"),
])
def test_a_bad_population_word_is_one_line(words, match):
    with pytest.raises(ConfigError, match=match):
        load(words)


def test_a_saved_population_config_keeps_its_loop_keys_under_population_when_saved_again():
    old = {**OmegaConf.to_container(compose(["task=1v1", "population=fsp"]))}
    flat = {**old.pop("algo"), **old.pop("population"), "learner": "mappo"}  # as a run of before saved it
    cfg = validate({**old, "algo": flat})
    again = validate(OmegaConf.to_container(cfg))
    assert again == cfg and cfg.population.name == "fsp" and cfg.algo.name == "mappo" and "iterations" not in cfg.algo
