"""The benchmark helper returns well-formed rows and a table with the torch/MuJoCo ratio (no timing asserts)."""

import pytest

from volleybots.bench import format_table, run_bench, speed_ratios
from volleybots.config import BenchOptions

pytestmark = pytest.mark.mujoco


def test_run_bench_rows_and_table():
    rows = run_bench(BenchOptions(tasks=["hover"], backends=["torch", "mujoco"], num_envs=[2], devices=["cpu"], repeats=2, steps=3,
                                  threads=1))
    assert [(r["backend"], r["num_envs"], r["device"]) for r in rows] == [("torch", 2, "cpu"), ("mujoco", 2, "cpu")]
    for r in rows:
        assert r["env_steps_per_s"] > 0 and len(r["all_env_steps_per_s"]) == 2
        assert r["step_ms"] == 1e3 * 2 / r["env_steps_per_s"]
        assert r["n_drones"] == 1 and r["steps"] == 3 and r["threads"] == 1 and r["env_steps_per_cpu_s"] > 0
    ratio = speed_ratios(rows)[("hover", 2, "cpu", False)]
    assert ratio == rows[0]["env_steps_per_s"] / rows[1]["env_steps_per_s"]
    table = format_table(rows).splitlines()
    assert len(table) == 4 and table[2].startswith("| hover | env | 1 | torch | cpu | no | 1 | 2 |")
    assert table[2].endswith(f"| {ratio:.1f}x |") and table[3].endswith("|  |")


def test_mujoco_rows_use_the_threads_for_the_pool_and_restore_torch():
    """Equal cores: a MuJoCo row's threads size its rollout pool; torch's own count comes back after."""
    import torch

    before = torch.get_num_threads()
    rows = run_bench(BenchOptions(tasks=["hover"], backends=["mujoco"], num_envs=[2], devices=["cpu"], repeats=1, steps=2, threads=2))
    assert rows[0]["threads"] == 2 and torch.get_num_threads() == before
