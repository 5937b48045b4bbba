"""``volleybots bench train=true`` on a match: the competitive seats' training rows beside MAPPO's."""

from __future__ import annotations

from volleybots.bench import SEATS, format_table, run_bench
from volleybots.config import BenchOptions


def test_competitive_seats_are_measured_beside_mappo_on_the_same_batch():
    quick = ["algo.steps_per_batch=8", "algo.minibatches=1", "algo.epochs=1", "algo.hidden=[16]"]
    rows = run_bench(BenchOptions(tasks=["3v3"], backends=["torch"], num_envs=[4], devices=["cpu"], repeats=1, steps=2, threads=1,
                                  train=True, train_batches=1, train_overrides=quick))
    train = [r for r in rows if r["kind"].startswith("train")]
    assert [r["kind"] for r in train] == ["train mappo", *(f"train {s}" for s in SEATS)]
    base = train[0]["env_steps_per_s"]
    for r in train:
        assert r["env_steps_per_s"] > 0 and r["num_envs"] == 4 and r["steps"] == 8 and r["task"] == "3v3"
    for r in train[1:]:
        assert r["vs_mappo"] == r["env_steps_per_s"] / base
    table = format_table(rows)
    assert "| train psro oracle |" in table and f"{train[2]['vs_mappo']:.2f}x" in table
