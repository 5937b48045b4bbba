"""Inputs that ended in a traceback (issue 57, class 7) are one line: ``RAY_ADDRESS=auto`` with no
cluster, mixture weights whose sum overflows, tampered counters of a checkpoint or a summary, and Elo
from a results file with a pair that never played."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from helpers import one_line_exit_2, snapshot
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.config import ConfigError
from volleybots.eval.crossplay import CrossPlay
from volleybots.policies.store import split_mixture

runner = CliRunner()


def test_ray_address_auto_with_no_cluster_is_refused_at_once(monkeypatch, tmp_path):
    pytest.importorskip("ray")
    from volleybots.play.pool import check_pool

    monkeypatch.setenv("RAY_ADDRESS", "auto")
    monkeypatch.setenv("RAY_TMPDIR", str(tmp_path))  # where Ray looks for a running cluster: none here
    with pytest.raises(ConfigError, match="RAY_ADDRESS=auto but no Ray cluster runs on this machine.*pool=serial"):
        check_pool("ray", "pool")


def test_mixture_weights_whose_sum_overflows_are_still_relative():
    assert split_mixture("random*1e308+scripted*1e308")[1] == [("random", 0.5), ("scripted", 0.5)]
    assert [w for _, w in split_mixture("random*1.5e308+scripted*1e308")[1]] == pytest.approx([0.6, 0.4])
    with pytest.raises(ConfigError, match="weight of 'scripted' is too small"):
        split_mixture("random*1e308+scripted*1e-308")


@pytest.mark.parametrize("value", [float("nan"), "lots", -5])
def test_a_tampered_checkpoint_count_is_one_line(tiny_1v1_run, copy_run, tmp_path, value):
    run = copy_run(tiny_1v1_run)
    for ckpt in (run / "checkpoints").glob("*.pt"):
        state = torch.load(ckpt, weights_only=True)
        state["frames"] = value
        torch.save(state, ckpt)
    before = snapshot(run)
    one_line_exit_2(runner.invoke(app, ["eval", str(run), "episodes=2", "threads=1"]), "final.pt", "damaged", "frames")
    one_line_exit_2(runner.invoke(app, ["replay", str(run), "--no-viewer", "--out", str(tmp_path / "r.rrd")]), "frames")
    assert snapshot(run) == before and not (tmp_path / "r.rrd").exists()


@pytest.mark.parametrize("value", ["lots", None, float("inf")])
def test_report_lists_a_summary_with_tampered_frames_as_failed(tiny_1v1_run, copy_run, value):
    run = copy_run(tiny_1v1_run)
    summary = json.loads((run / "summary.json").read_text())
    summary["frames"] = value
    (run / "summary.json").write_text(json.dumps(summary))
    res = runner.invoke(app, ["report", str(run)])
    assert res.exit_code == 0 and "Traceback" not in res.output, res.output
    assert "failed" in res.output and "summary.json" in res.output and "frames" in res.output, res.output


def test_elo_from_a_file_with_an_unplayed_pair_is_one_line(tmp_path):
    wdl = np.zeros((3, 3, 3))
    wdl[0, 1], wdl[1, 0] = [2, 0, 0], [0, 0, 2]
    wdl[1, 2], wdl[2, 1] = [1, 1, 0], [0, 1, 1]
    CrossPlay(["a", "b", "c"], wdl, {"0,1": "WW", "1,2": "WD"}).save(tmp_path / "cp.json")
    err = one_line_exit_2(runner.invoke(app, ["eval", "elo", f"from={tmp_path / 'cp.json'}", "--out", str(tmp_path / "elo")]),
                          "'a' and 'c' played no game")
    assert "crossplay" in err and not (tmp_path / "elo").exists()
