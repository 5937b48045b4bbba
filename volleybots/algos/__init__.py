"""Algorithms by name. Each is one module with one class and its dataclass config beside it;
``conf/algo/<name>.yaml`` holds its defaults. Add one by registering its class here."""

from __future__ import annotations

from volleybots.algos.base import Algorithm
from volleybots.algos.ddpg import DDPG
from volleybots.algos.dqn import DQN
from volleybots.algos.happo import HAPPO
from volleybots.algos.maddpg import MADDPG
from volleybots.algos.mat import MAT
from volleybots.algos.population import FSP, SP, PSRONash, PSROUniform
from volleybots.algos.ppo import MAPPO, PPO
from volleybots.algos.qmix import QMIX
from volleybots.algos.sac import SAC
from volleybots.algos.td3 import TD3

ALGOS: dict[str, type[Algorithm]] = {
    cls.name: cls for cls in (PPO, MAPPO, DQN, DDPG, TD3, SAC, QMIX, MADDPG, HAPPO, MAT, SP, FSP, PSROUniform, PSRONash)
}

__all__ = [
    "ALGOS", "Algorithm", "DDPG", "DQN", "FSP", "HAPPO", "MADDPG", "MAPPO", "MAT", "PPO", "PSRONash", "PSROUniform", "QMIX", "SAC", "SP", "TD3",
]
