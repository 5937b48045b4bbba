"""Algorithms by name. Each is one module with one class and its dataclass config beside it;
``conf/algo/<name>.yaml`` holds its defaults. Add one by registering its class here."""

from __future__ import annotations

from volleybots.algos.base import Algorithm
from volleybots.algos.ppo import MAPPO, PPO

ALGOS: dict[str, type[Algorithm]] = {cls.name: cls for cls in (PPO, MAPPO)}

__all__ = ["ALGOS", "Algorithm", "MAPPO", "PPO"]
