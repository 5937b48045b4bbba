"""metrics.csv of a match run logs the learner's team: its ``return`` and ``r_*`` (the all-drone
means, which cancel between the teams, move to ``*_all``)."""

from __future__ import annotations

import pytest

from volleybots.config import load
from volleybots.runs import read_metrics
from volleybots.train import train


def test_a_versus_run_logs_its_own_teams_win_or_lose(tmp_path):
    cfg = load(["task=1v1", "opponent=random", "env.num_envs=16", "algo.steps_per_batch=64", "total_frames=2048", "threads=1",
                "progress=false", "evaluation.every=0", "evaluation.episodes=2", "evaluation.record=false", "checkpoint.every=0",
                "algo.epochs=1", "algo.minibatches=1"])
    train(cfg, tmp_path / "run")
    rows = [r for r in read_metrics(tmp_path / "run" / "metrics.csv") if r["phase"] == "train" and r["episodes"]]
    decided = [r for r in rows if r["win"] + r["loss"] > 0]
    assert decided, "no decided game in the run: the test needs some"
    for r in rows:
        # 1 vs 1: the learner's one drone gets +100 for a won game and -100 for a lost one
        assert r["r_win_or_lose"] == pytest.approx(100.0 * (r["win"] - r["loss"]), abs=1e-3)
        assert r["r_win_or_lose_all"] == pytest.approx(0.0, abs=1e-3)  # both drones together: one's win is the other's loss
        terms = sum(v for k, v in r.items() if k.startswith("r_") and not k.endswith("_all"))
        assert r["return"] == pytest.approx(terms, abs=1e-2)
    assert any(r["r_win_or_lose"] != 0 for r in decided)
    assert "return_team0" not in rows[0]
