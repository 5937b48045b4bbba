"""Payoff entries played by a Ray pool equal those played one after another: the population loop's
payoff row of a tiny PSRO run, replayed on a local Ray instance from the same member files."""

from __future__ import annotations

import json
import shutil

import pytest

from volleybots.config import ConfigError, load
from volleybots.population.loop import PopulationLoop
from volleybots.population.run import start
from volleybots.runs import RunDir

pytestmark = pytest.mark.slow

TINY = [
    "task=1v1", "algo=psro_uniform", "algo.start=scratch", "algo.iterations=1", "algo.seed_members=[random,scripted]", "env.num_envs=16",
    "algo.steps_per_batch=16", "algo.minibatches=2", "algo.epochs=1", "algo.hidden=[32,32]", "algo.min_updates=2",
    "algo.max_updates=2", "algo.payoff_games=8", "evaluation.episodes=2", "evaluation.every=0", "evaluation.record=false",
    "checkpoint.every=100000", "total_frames=100000", "progress=false", "threads=1", "seed=4",
]


@pytest.fixture(scope="module")
def serial_run(tmp_path_factory):
    run = tmp_path_factory.mktemp("pool") / "serial"
    start(load(TINY), run)
    return run


def test_a_ray_pool_plays_the_same_payoff_entries_as_serial_play(serial_run, tmp_path, monkeypatch):
    ray = pytest.importorskip("ray", reason="ray comes with the cluster extra of the test install")
    monkeypatch.setenv("RAY_AUTH_MODE", "disabled")
    serial = json.loads((serial_run / "population" / "payoffs.json").read_text())
    assert serial["members"] == ["random", "scripted", "br1"]
    assert serial["games"][2][:2] == [8, 8] and serial["games"][1][0] == 8
    # the same member files, the payoff table played again in Ray tasks
    copy = tmp_path / "ray"
    shutil.copytree(serial_run, copy)
    (copy / "population" / "payoffs.json").unlink()
    cfg = load([*TINY, "algo.payoff_pool=ray"])

    def here(*args):
        raise AssertionError("a match was played in this process, not in a Ray worker")

    monkeypatch.setattr("volleybots.play.pool.play_row_chunk", here)  # Ray's workers import their own, unpatched
    try:
        PopulationLoop(cfg, RunDir(copy))._play_payoffs()
        assert ray.is_initialized()
    finally:
        ray.shutdown()
    pooled = json.loads((copy / "population" / "payoffs.json").read_text())
    assert pooled == serial
    assert sum(w for row in serial["wdl"] for w, _, _ in row) > 0  # decisive games, not an all-draw table


def test_an_unknown_pool_is_refused():
    with pytest.raises(ConfigError, match="unknown population.payoff_pool 'dask'; allowed: serial, ray"):
        load([*TINY, "algo.payoff_pool=dask"])


def test_a_ray_pool_plays_the_same_crossplay_table_as_serial_play(tmp_path, monkeypatch):
    """``eval crossplay ... pool=ray``: every pair a Ray task, the same counts and outcomes as in turn."""
    ray = pytest.importorskip("ray", reason="ray comes with the cluster extra of the test install")
    monkeypatch.setenv("RAY_AUTH_MODE", "disabled")
    from volleybots.eval.crossplay import run_crossplay

    args = ["random", "scripted", "r2=random", "task=1v1", "games=4", "seed=3", "batch=4"]
    serial, _ = run_crossplay(args, tmp_path / "serial")
    seen = []
    try:
        pooled, _ = run_crossplay([*args, "pool=ray"], tmp_path / "ray", progress=lambda i, j, g: seen.append((i, j)))
        assert ray.is_initialized()
    finally:
        ray.shutdown()
    assert seen == [(0, 1), (0, 2), (1, 2)]  # progress still comes pair by pair, in order
    assert (pooled.wdl == serial.wdl).all() and pooled.outcomes == serial.outcomes and pooled.wdl.sum() == 24
    with pytest.raises(ConfigError, match="unknown pool 'dask'; allowed: serial, ray"):
        run_crossplay([*args, "pool=dask"], tmp_path / "never")
    assert not (tmp_path / "never").exists()


def test_best_responses_on_two_seeds_train_the_same_as_ray_tasks(tmp_path, monkeypatch):
    """``eval exploitability ... seeds=2 pool=ray``: each seed's response a Ray task, the same weights."""
    import torch

    ray = pytest.importorskip("ray", reason="ray comes with the cluster extra of the test install")
    monkeypatch.setenv("RAY_AUTH_MODE", "disabled")
    from volleybots.eval.exploitability import run_exploitability

    args = ["random", "task=1v1", "budget=512", "num_envs=8", "games=4", "select_games=4", "seeds=2", "seed=5", "progress=false",
            "threads=1"]
    serial, a = run_exploitability(args, tmp_path / "serial")
    try:
        pooled, b = run_exploitability([*args, "pool=ray"], tmp_path / "ray")
    finally:
        ray.shutdown()
    for name in ("br", "br_s1"):
        x, y = (torch.load(p / name / "checkpoints" / "final.pt", weights_only=True)["algo"]["actor"] for p in (a, b))
        assert x.keys() == y.keys() and all(torch.equal(x[k], y[k]) for k in x)
    assert pooled["selection"] == serial["selection"] and pooled["exploitability"] == serial["exploitability"]
