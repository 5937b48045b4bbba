"""Algorithms by name. Each is one module with one class and its dataclass config beside it;
``conf/algo/<name>.yaml`` holds its defaults. Add one by registering its class here. The population
presets (``sp``, ``fsp``, ``psro_*``: ``population=NAME``, ``conf/population/``) are a registry of their own,
``PRESETS``: configs of the population loop, which trains one of ``LEARNERS`` (``algo=``)."""

from __future__ import annotations

from volleybots.algos.base import Algorithm
from volleybots.algos.bc import BC
from volleybots.algos.ddpg import DDPG
from volleybots.algos.dqn import DQN
from volleybots.algos.happo import HAPPO
from volleybots.algos.maddpg import MADDPG
from volleybots.algos.mat import MAT
from volleybots.algos.population import (
    FSP,
    LEARNERS,
    PRESETS,
    SP,
    Preset,
    PSRONash,
    PSROUniform,
    is_population,
    method_name,
    population_of,
    upgrade_saved,
)
from volleybots.algos.ppo import MAPPO, PPO
from volleybots.algos.qmix import QMIX
from volleybots.algos.sac import SAC
from volleybots.algos.td3 import TD3

# the learners (algo=NAME); the population presets are PRESETS (population=NAME)
ALGOS: dict[str, type[Algorithm]] = {
    **{cls.name: cls for cls in (PPO, MAPPO, DQN, DDPG, TD3, SAC, QMIX, MADDPG, HAPPO, MAT)},
    BC.name: BC,
}

__all__ = [
    "ALGOS", "Algorithm", "BC", "LEARNERS", "PRESETS", "Preset", "DDPG", "DQN", "FSP", "HAPPO", "MADDPG", "MAPPO", "MAT", "PPO",
    "PSRONash", "PSROUniform", "QMIX", "SAC", "SP", "TD3", "is_population", "method_name", "population_of", "upgrade_saved",
]
