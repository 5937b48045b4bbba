"""DDPG, TD3 and SAC clearly improve on Hover within a small budget.

Budget (20-75 s each on two busy cores): CTBR actions, 32 envs, 40960 frames, batch 256, networks
[64, 64], targets updated every gradient step with tau 0.05. The paper's tau 0.005 every 4 steps
assumes ~1e6 gradient steps; with the ~1300 of this budget its targets hardly move and nothing is
learnt (measured: no gain after 50k frames), so the budget's targets move faster.

Random flight falls within ~50 steps (evaluation return ~4.6 over 32 episodes); each method must at
least triple that in its final deterministic evaluation (64 episodes) and lengthen its training
episodes by a tenth. Measured with seeds 0, 1, 2 (seed 0 is the test's): final evaluation returns
DDPG 21.1 / 18.2 / 27.2, TD3 21.6 / 24.4 / 25.5, SAC 43.9 / 36.2 / 32.3; training episodes from
~50 steps to 59-95. Measured again on seed 0 with today's code (2026-11-28): DDPG 19.65, TD3 23.1,
SAC 35.8 (floor 13.8), so the thinnest margin is DDPG's 1.42x and the budget cannot be cut.
"""

from __future__ import annotations

import pytest
import torch

from volleybots.config import load
from volleybots.eval import evaluate
from volleybots.runs import read_metrics
from volleybots.train import train

pytestmark = pytest.mark.learning

BUDGET = [
    "task=hover", "env.action_space=ctbr", "env.num_envs=32", "total_frames=40960", "seed=0", "threads=1",
    "algo.batch_size=256", "algo.buffer_size=100000", "algo.hidden=[64,64]", "algo.tau=0.05", "algo.target_update_interval=1",
    "progress=false", "checkpoint.every=0", "evaluation.every=0", "evaluation.episodes=64", "evaluation.record=false",
]


@pytest.fixture(scope="module")
def random_return():
    n = torch.get_num_threads()
    res = evaluate("random", ["task=hover", "env.action_space=ctbr", "episodes=32", "threads=1"])
    torch.set_num_threads(n)
    return res["stats"]["return"]["mean"]


@pytest.mark.parametrize("name", ["ddpg", "td3", "sac"])
def test_improves_hover_over_random_flight(name, tmp_path, random_return):
    n = torch.get_num_threads()
    try:
        summary = train(load([f"algo={name}", *BUDGET]), tmp_path / "run")
    finally:
        torch.set_num_threads(n)
    final = summary["final_eval"]["stats"]["return"]["mean"]
    assert final > 3 * max(random_return, 1.0), (final, random_return)
    rows = [r for r in read_metrics(tmp_path / "run" / "metrics.csv") if r["phase"] == "train"]
    first = sum(r["episode_len"] for r in rows[:3]) / 3
    last = sum(r["episode_len"] for r in rows[-3:]) / 3
    assert last > 1.1 * first, (first, last)
