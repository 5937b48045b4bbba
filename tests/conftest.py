"""Session-scoped tiny runs shared by the tests of damaged runs and of the evaluation verbs' input checks:
each is trained once (seconds) and copied by a test that damages it."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

TINY_1V1 = [
    "task=1v1", "env.num_envs=8", "algo.steps_per_batch=16", "algo.minibatches=1", "algo.epochs=1", "algo.hidden=[16]",
    "evaluation.episodes=2", "evaluation.every=0", "evaluation.record=false", "progress=false", "threads=1",
]


def _train(path: Path, *args) -> Path:
    from typer.testing import CliRunner

    from volleybots.cli import app

    res = CliRunner().invoke(app, ["train", *TINY_1V1, *args, f"hydra.run.dir={path}"])
    assert res.exit_code == 0, res.output
    return path


@pytest.fixture(scope="session")
def tiny_run(tmp_path_factory) -> Path:
    """A finished 1v1 MAPPO run of 128 frames (final.pt, summary.json listing it)."""
    return _train(tmp_path_factory.mktemp("shared") / "run", "algo=mappo", "total_frames=128")


@pytest.fixture(scope="session")
def tiny_population(tmp_path_factory) -> Path:
    """A finished PSRO run of one iteration over a random seed member: members random and br1."""
    return _train(tmp_path_factory.mktemp("shared") / "pop", "algo=psro_uniform", "algo.seed_members=[random]", "algo.iterations=1",
                  "total_frames=256", "algo.min_updates=1", "algo.max_updates=1", "algo.payoff_games=2")


@pytest.fixture
def copy_run(tmp_path):
    """``copy_run(src, name)``: a copy of a shared run in this test's folder, free to damage."""

    def copy(src: Path, name: str = "copy") -> Path:
        return Path(shutil.copytree(src, tmp_path / name, ignore=shutil.ignore_patterns(".lock")))

    return copy
