"""A user's own presets through Hydra's config search path (issue 55): ``train --config-dir DIR`` and
``hydra.searchpath=[file://DIR]`` make ``algo=myppo`` (a file that starts from the packaged PPO) an
option, with the checks made before composition knowing it and the keys it declares."""

from __future__ import annotations

import subprocess
import sys

import pytest
from helpers import CLI_ENV, one_line_exit_2
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.config import compose, group_options, validate
from volleybots.config.compose import check_group_args
from volleybots.config.searchpath import active, with_config_dir
from volleybots.errors import ConfigError

runner = CliRunner()


@pytest.fixture
def user_conf(tmp_path):
    """A user's config folder: ``algo/myppo.yaml`` (the packaged PPO with another actor learning rate
    and epochs) and ``task/myhover.yaml`` (Hover with a fixed target)."""
    (tmp_path / "algo").mkdir()
    (tmp_path / "algo" / "myppo.yaml").write_text(
        "defaults:\n  - ppo  # the packaged PPO\n  - _self_\nactor_lr: 1.0e-4  # slower actor\nepochs: 2  # fewer passes\n")
    (tmp_path / "task").mkdir()
    (tmp_path / "task" / "myhover.yaml").write_text("defaults:\n  - hover\n  - _self_\ntarget: [0.5, -0.5, 2.0]  # a fixed target\n")
    (tmp_path / "task" / "my1v1.yaml").write_text("defaults:\n  - 1v1\n  - _self_\nserve: 0  # team 0 always serves\n")
    return tmp_path


def test_a_user_task_preset_trains_with_its_tasks_default_method(user_conf):
    cfg = validate(compose([f"hydra.searchpath=[file://{user_conf}]", "task=my1v1"]))
    assert cfg.task.name == "1v1" and cfg.task.serve == 0
    assert cfg.population.name == "sp" and cfg.algo.name == "mappo"  # as task=1v1 itself: self-play with MAPPO


def test_searchpath_composes_a_user_preset_that_inherits_the_packaged_one(user_conf):
    cfg = validate(compose([f"hydra.searchpath=[file://{user_conf}]", "algo=myppo", "task=myhover", "algo.critic_lr=2e-4"]))
    assert cfg.algo.name == "ppo" and cfg.algo.actor_lr == pytest.approx(1e-4) and cfg.algo.epochs == 2
    assert cfg.algo.critic_lr == pytest.approx(2e-4) and cfg.algo.minibatches == 16  # the packaged value it inherits
    assert cfg.task.name == "hover" and list(cfg.task.target) == [0.5, -0.5, 2.0]
    with pytest.raises(ConfigError, match="unknown algo 'myppo'"):  # without the search path it is no option
        compose(["algo=myppo"])


def test_the_early_checks_know_the_user_presets(user_conf):
    path = f"hydra.searchpath=[file://{user_conf}]"
    check_group_args([path, "algo=myppo", "task=myhover"])  # accepted: no error
    with pytest.raises(ConfigError, match="unknown algo 'myppo'"):
        check_group_args(["algo=myppo"])
    with active([path]):
        assert {"myppo", "ppo"} <= set(group_options("algo")) and "myhover" in group_options("task")
        assert group_options("env/drone") == sorted(group_options("env/drone"))
    assert "myppo" not in group_options("algo")  # the folders are the words', not the process's
    with pytest.raises(ConfigError, match="unknown config key 'algo.bogus'; allowed under 'algo': .*actor_lr"):
        compose([path, "algo=myppo", "algo.bogus=1"])
    with pytest.raises(ConfigError, match="is not a directory"):
        compose([f"hydra.searchpath=[file://{user_conf / 'nope'}]", "algo=myppo"])


def test_config_dir_is_the_first_searchpath_entry(user_conf, tmp_path_factory):
    other = tmp_path_factory.mktemp("other")
    words = with_config_dir(["algo=myppo", f"hydra.searchpath=[file://{other}]"], str(user_conf))
    assert words == ["algo=myppo", f"hydra.searchpath=['file://{user_conf.resolve()}','file://{other.resolve()}']"]
    assert with_config_dir(["algo=ppo"], None) == ["algo=ppo"]


def test_train_config_dir_prints_the_user_preset(user_conf):
    res = runner.invoke(app, ["train", "--config-dir", str(user_conf), "algo=myppo", "task=myhover", "--cfg", "job"])
    assert res.exit_code == 0, res.output
    assert "actor_lr: 0.0001" in res.stdout and "epochs: 2" in res.stdout and "- 0.5" in res.stdout
    one_line_exit_2(runner.invoke(app, ["train", "--config-dir", str(user_conf / "nope"), "algo=myppo"]), "--config-dir", "not a directory")
    one_line_exit_2(runner.invoke(app, ["train", "algo=myppo"]), "unknown algo 'myppo'", "allowed")


def test_train_config_dir_trains_and_records_the_search_path(user_conf, tmp_path):
    run = tmp_path / "run"
    res = runner.invoke(app, [
        "train", "-cd", str(user_conf), "algo=myppo", "task=myhover", "env.num_envs=4", "algo.steps_per_batch=8", "algo.minibatches=2",
        "algo.hidden=[16]", "task.episode_len=40", "threads=1", "progress=false", "evaluation.episodes=1", "evaluation.record=false",
        "evaluation.every=0", "total_frames=32", f"hydra.run.dir={run}",
    ])
    assert res.exit_code == 0, res.output
    saved = (run / ".hydra" / "config.yaml").read_text()
    assert "actor_lr: 0.0001" in saved and "epochs: 2" in saved
    assert f"file://{user_conf.resolve()}" in (run / ".hydra" / "overrides.yaml").read_text()  # a rerun composes the same


def test_a_bad_key_of_a_user_preset_comes_before_torch_loads(user_conf):
    argv = ["train", "--config-dir", str(user_conf), "algo=myppo", "algo.nonsense=1"]
    code = ("import sys\nfrom volleybots.cli import app\ntry:\n    app(%r)\nexcept SystemExit as e:\n"
            "    print('exit', e.code, 'torch loaded' if 'torch' in sys.modules else 'torch not loaded')" % (argv,))
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=CLI_ENV, timeout=120)
    assert res.stdout.strip().splitlines()[-1] == "exit 2 torch not loaded", res.stdout + res.stderr
    assert res.stderr.strip().startswith("error: unknown config key 'algo.nonsense'"), res.stderr


def test_a_sweep_with_config_dir_gives_every_job_the_user_preset(user_conf, tmp_path):
    """``-m`` goes through ``hydra.main``: the search path reaches it as the override ``--config-dir`` became."""
    sweep = tmp_path / "sweep"
    res = runner.invoke(app, [
        "train", "-m", "--config-dir", str(user_conf), "algo=myppo", "task=myhover", "seed=0,1", "env.num_envs=4", "algo.steps_per_batch=8",
        "algo.minibatches=2", "algo.hidden=[16]", "task.episode_len=40", "threads=1", "progress=false", "evaluation.episodes=1",
        "evaluation.record=false", "evaluation.every=0", "total_frames=32", f"hydra.sweep.dir={sweep}",
    ])
    assert res.exit_code == 0, res.output
    for job in ("0", "1"):
        saved = (sweep / job / ".hydra" / "config.yaml").read_text()
        assert "actor_lr: 0.0001" in saved and "- 0.5" in saved, job
