"""One line instead of a traceback (issue 49): W&B settings W&B would refuse, a binary metrics.csv in a
report, a full disk while training or drawing a still."""

from __future__ import annotations

import errno

import pytest
from conftest import TINY_1V1, one_line_exit_2
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.config import ConfigError, load

runner = CliRunner()


@pytest.mark.parametrize("override, env, words", [
    ("wandb.project=team/project", {}, ["wandb.project", "team/project"]),
    ("wandb.project=a:b", {}, ["wandb.project"]),
    ("wandb.mode=offline", {"WANDB_MODE": "bogus"}, ["WANDB_MODE='bogus'"]),
    ("wandb.mode=online", {"WANDB_API_KEY": None, "WANDB_IDENTITY_TOKEN_FILE": None, "NETRC": "/nonexistent/netrc"},
     ["wandb.mode=online", "API key"]),
])
def test_wandb_settings_wandb_refuses_are_one_line(override, env, words, monkeypatch):
    pytest.importorskip("wandb")
    for k, v in env.items():
        if v is None:
            monkeypatch.delenv(k, raising=False)
        else:
            monkeypatch.setenv(k, v)
    with pytest.raises(ConfigError) as e:
        load(["logger=wandb", override])
    assert all(w in str(e.value) for w in words), str(e.value)


def test_a_binary_metrics_csv_is_reported_not_a_traceback(tiny_1v1_run, copy_run):
    run = copy_run(tiny_1v1_run)
    (run / "metrics.csv").write_bytes(bytes(range(256)) * 4)
    res = runner.invoke(app, ["report", str(run)])
    assert res.exit_code == 0, res.output
    assert "failed" in res.output and "metrics.csv" in res.output


def _full_disk(*a, **k):
    raise OSError(errno.ENOSPC, "No space left on device")


def test_a_full_disk_while_training_is_one_line(tmp_path, monkeypatch):
    monkeypatch.setattr("volleybots.runs.metrics.MetricsLog.write", _full_disk)
    one_line_exit_2(runner.invoke(app, ["train", *TINY_1V1, "algo=mappo", "total_frames=128", f"hydra.run.dir={tmp_path / 'r'}"]),
                    "No space left on device", "free space")


def test_a_full_disk_while_drawing_a_still_is_one_line(tiny_1v1_run, tmp_path, monkeypatch):
    monkeypatch.setattr("volleybots.files._write", _full_disk)
    still = tmp_path / "a.png"
    one_line_exit_2(runner.invoke(app, ["replay", str(tiny_1v1_run), "--no-viewer", "--out", str(tmp_path / "a.rrd"), "--still",
                                        str(still)]), "a.png", "free space")
    assert not still.exists() and not list(tmp_path.glob("*.tmp"))
