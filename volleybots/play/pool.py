"""Many head-to-head matches at once: here one after another, or as tasks of a Ray pool.

A match's games draw their random numbers from the match's own seed (``volleybots.play.games``), so
its W/D/L counts do not depend on where or in which order it is played: the pool changes the wall
time, never the results. ``ray`` connects to the cluster named by ``RAY_ADDRESS`` (``ray start
--head`` prints it), joins the cluster of the Ray task it runs in (a sweep job of
``hydra/launcher=ray``), or else starts a local Ray instance for the rest of the process.
"""

from __future__ import annotations

import importlib.util
import os

from volleybots.algos.population import POOLS
from volleybots.config import to_dict, validate
from volleybots.errors import ConfigError
from volleybots.play.games import head_to_head

EXTRA = "cluster"  # pip install 'volleybots[cluster]' installs ray


def check_pool(pool: str, key: str) -> None:
    """Raise ``ConfigError`` for an unknown pool, or ``ray`` where ray is not installed."""
    if pool not in POOLS:
        raise ConfigError(f"unknown {key} {pool!r}; allowed: {', '.join(POOLS)}")
    if pool == "ray" and importlib.util.find_spec("ray") is None:
        raise ConfigError(f"{key}=ray needs the ray package: pip install 'volleybots[{EXTRA}]' (or use {key}=serial)")


def head_to_heads(cfg, matches: list[tuple], pool: str = "serial") -> list:
    """``head_to_head(cfg, a, b, games, seed)`` for each ``(a, b, games, seed)`` of ``matches``, in
    order: one [3] record of wins, draws and losses each."""
    if pool == "serial" or not matches:
        return [head_to_head(cfg, *m) for m in matches]
    check_pool(pool, "pool")
    import ray

    if not ray.is_initialized():
        ray.init(address=os.environ.get("RAY_ADDRESS"), include_dashboard=False, log_to_driver=False)
    task = ray.remote(num_cpus=1)(_match)
    data = ray.put(to_dict(cfg))
    return ray.get([task.remote(data, *m) for m in matches])


def _match(cfg: dict, a, b, games: int, seed: int):
    """One match in a Ray worker (one torch thread, as Ray's workers run with OMP_NUM_THREADS=1)."""
    import torch

    torch.set_num_threads(1)
    return head_to_head(validate(cfg), a, b, games, seed)
