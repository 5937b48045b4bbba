"""Nothing unbounded (issue 49): files are read with a size bound and only if they are files, a Ray
address nothing answers at is refused at once, and every numeric config key has an upper bound."""

from __future__ import annotations

import os

import pytest
from conftest import one_line_exit_2, snapshot
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.config import ConfigError, build_env, load
from volleybots.files import MAX_READ_BYTES, read_json

runner = CliRunner()


def _huge(path):
    with open(path, "wb") as f:  # sparse: no disk is used, but its size is past the bound
        f.truncate(MAX_READ_BYTES + 1)
    return path


def test_a_config_yaml_that_is_a_device_is_one_line(tiny_1v1_run, copy_run):
    run = copy_run(tiny_1v1_run)
    (run / "config.yaml").unlink()
    (run / "config.yaml").symlink_to("/dev/zero")
    before = snapshot(run)
    one_line_exit_2(runner.invoke(app, ["train", f"resume={run}", "total_frames=256"]), "config.yaml", "device")
    res = runner.invoke(app, ["report", str(run)])
    assert res.exit_code == 0 and "failed" in res.output and "device" in res.output, res.output
    assert snapshot(run) == before


def test_huge_files_are_refused_unread(tmp_path):
    with pytest.raises(ConfigError, match="larger than"):
        read_json(_huge(tmp_path / "crossplay.json"), "cross-play results file")
    drills = _huge(tmp_path / "team.yaml")
    one_line_exit_2(runner.invoke(app, ["eval", "crossplay", f"t={drills}", "random", "task=3v3", "games=2",
                                        "--out", str(tmp_path / "o")]), "team.yaml", "larger than")
    reuse = _huge(tmp_path / "old.json")
    one_line_exit_2(runner.invoke(app, ["eval", "crossplay", "random", "scripted", "task=1v1", "games=2", f"reuse={reuse}",
                                        "--out", str(tmp_path / "o")]), "old.json", "larger than")
    assert not (tmp_path / "o").exists()


def test_a_ray_address_nothing_answers_at_is_refused_at_once(monkeypatch):
    pytest.importorskip("ray")
    from volleybots.play.pool import check_pool

    monkeypatch.setenv("RAY_ADDRESS", "127.0.0.1:9")  # the discard port: refused at once
    with pytest.raises(ConfigError, match="no Ray cluster answers"):
        check_pool("ray", "algo.payoff_pool")
    monkeypatch.setenv("RAY_ADDRESS", "nonsense")
    with pytest.raises(ConfigError, match="not host:port"):
        check_pool("ray", "algo.payoff_pool")


@pytest.mark.parametrize("override", [
    "env.substeps=100000", "env.num_envs=1e18", "total_frames=1e30", "evaluation.every=9223372036854775808",
    "algo.actor_lr=1e30", "algo.entropy_coeff=-1e30", "time_limit=1e30", "task.hit_reward=1e30",
])
def test_numeric_keys_have_upper_bounds(override):
    key = override.partition("=")[0]
    with pytest.raises(ConfigError, match=f"bad value for '{key}'"):
        load(["task=solo_bump", "algo=mappo", override] if key.startswith("task.") else [override])


@pytest.mark.parametrize("kw, words", [({"num_envs": 2.5}, "must be an integer"), ({"num_envs": 2**40}, "num_envs"),
                                       ({"substeps": 10**5}, "substeps")])
def test_make_env_refuses_absurd_counts_with_one_error(kw, words):
    with pytest.raises(ConfigError, match=words):
        build_env("hover", **kw)


def test_absurd_payoff_games_are_refused_before_the_run_dir(tmp_path):
    run = tmp_path / "pop"
    one_line_exit_2(runner.invoke(app, ["train", "task=1v1", "algo=psro_uniform", "algo.payoff_games=1e12", "threads=1",
                                        "progress=false", f"hydra.run.dir={run}"]), "games=1000000000000", "lower games")
    assert not run.exists() or not [p for p in run.iterdir() if p.name not in (".hydra", ".lock")]


def test_reasonable_values_still_pass():
    cfg = load(["env.num_envs=65536", "env.substeps=8", "total_frames=1e10", f"seed={2**63 - 1}"])
    assert cfg.env.num_envs == 65536 and cfg.total_frames == 10**10 and os.cpu_count()
