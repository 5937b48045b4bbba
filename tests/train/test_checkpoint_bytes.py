"""Checkpoints whose bytes depend only on the training (issue 55): two identical runs (same seed, CPU) in
two folders write files of equal sha256: no wall time in them, and the paths inside the run (a population
learner's ``init=`` clone) written relative to it. A resume still continues the run's clock, from metrics.csv,
and a checkpoint written before (with its ``wall_time``) still loads and keeps its own."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest
import torch
from helpers import HOVER_FPB, tiny_hover_run

from volleybots.runs import read_metrics, wall_at


def _digests(run: Path) -> dict[str, str]:
    return {str(p.relative_to(run)): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(run.rglob("*.pt"))}


def test_two_identical_runs_in_two_folders_write_checkpoints_of_equal_bytes(tmp_path):
    extra = (f"total_frames={2 * HOVER_FPB}", f"checkpoint.every={HOVER_FPB}")
    a = tiny_hover_run(tmp_path / "a", *extra)
    b = tiny_hover_run(tmp_path / "elsewhere" / "b", *extra)
    da, db = _digests(a), _digests(b)
    assert sorted(da) == ["checkpoints/best.pt", "checkpoints/ckpt_000000000032.pt", "checkpoints/final.pt"]
    assert da == db
    state = torch.load(a / "checkpoints" / "final.pt", weights_only=True)
    assert "wall_time" not in state and str(tmp_path) not in repr(state)
    # the wall time lives in the run's metrics.csv (and summary.json), where a resume reads it back
    rows = [r for r in read_metrics(a / "metrics.csv") if r["phase"] == "train"]
    assert wall_at(a / "metrics.csv", HOVER_FPB) == rows[0]["wall_time"] > 0
    assert wall_at(a / "metrics.csv", 2 * HOVER_FPB) == max(r["wall_time"] for r in read_metrics(a / "metrics.csv"))
    assert wall_at(a / "metrics.csv", 0) == 0.0 and wall_at(tmp_path / "none.csv", 10) == 0.0


def test_a_resume_continues_the_clock_from_metrics_and_an_old_checkpoint_keeps_its_own(tmp_path):
    from volleybots.runs import RunDir
    from volleybots.train import Trainer

    run = tiny_hover_run(tmp_path / "run", f"total_frames={2 * HOVER_FPB}", f"checkpoint.every={HOVER_FPB}")
    cfg = RunDir(run).load_config()
    ckpt = run / "checkpoints" / "ckpt_000000000032.pt"
    first = [r for r in read_metrics(run / "metrics.csv") if r["phase"] == "train"][0]["wall_time"]
    assert Trainer(cfg, RunDir(run), checkpoint=ckpt).wall_offset == first
    old = torch.load(ckpt, weights_only=True)
    old["wall_time"] = 123.5  # as every checkpoint held it before
    torch.save(old, tmp_path / "old.pt")
    assert Trainer(cfg, RunDir(run), checkpoint=tmp_path / "old.pt").wall_offset == 123.5


@pytest.mark.slow  # two population runs with a clone each (a bc run of 256 frames): 20-40 s on the shared cores
def test_two_identical_population_runs_from_a_clone_write_members_of_equal_bytes(tmp_path):
    from volleybots.config import load
    from volleybots.population.run import start

    args = ["task=1v1", "env.num_envs=8", "algo.steps_per_batch=16", "algo.minibatches=1", "algo.epochs=1", "algo.hidden=[16]",
            "algo=psro_nash", "algo.learner_init=bc", "algo.seed_members=[random]", "algo.bc_frames=256", "algo.iterations=1",
            "algo.min_updates=1", "algo.max_updates=1", "algo.payoff_games=2", "total_frames=128", "evaluation.episodes=2",
            "evaluation.every=0", "evaluation.record=false", "checkpoint.every=0", "progress=false", "threads=1"]
    a, b = tmp_path / "a", tmp_path / "elsewhere" / "b"
    start(load(args), a)
    start(load(args), b)
    da, db = _digests(a), _digests(b)
    assert "population/member_001.pt" in da and "population/bc/checkpoints/final.pt" in da
    assert da == db
    br1 = torch.load(a / "population" / "member_001.pt", weights_only=True)
    assert br1["init"]["source"].startswith("population/bc/checkpoints/") and br1["config"]["init"] == br1["init"]["source"]
