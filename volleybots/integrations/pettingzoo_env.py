"""A PettingZoo ``ParallelEnv`` over one world of any task (the multi-drone ones above all).

Agents. A match names its drones per team, ``team0_drone0 ... team1_drone2`` (team 0 plays on +x, 1
on -x; each team's agents in the env's agent order), and ``groups`` maps ``team0`` and ``team1`` to
them: the group map of TorchRL's and BenchMARL's multi-agent code, one policy per group. A
cooperative task (and a single-drone one) has one team: ``drone_0, drone_1, ...`` in one group named
``agents``, as TorchRL names the group of agents that share everything. The -x team's observations
are mirrored by the task itself, so one policy can play either side.

All agents start and end together (the env's ``done`` is shared): a step that ends the episode gives
every agent ``terminated`` or ``truncated``, the episode statistics in each agent's
``info["episode"]``, and leaves ``agents`` empty until ``reset()``. ``reset(seed=s)`` reseeds the
env's generator as ``make_env(task, seed=s)`` does.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

try:
    from pettingzoo import ParallelEnv
except ImportError:  # the message names the extra: a bare "No module named pettingzoo" does not
    raise ImportError("volleybots.integrations.VolleyParallelEnv needs pettingzoo: pip install 'volleybots[pettingzoo]'") from None

from volleybots.config import build_env
from volleybots.integrations import spaces as sp
from volleybots.integrations.spaces import action_tensor, episode_stats, to_numpy
from volleybots.keys import ACTION, AGENTS, NEXT, OBS, REWARD, TERMINATED, TRUNCATED


def agent_names(teams: tuple[int, ...], competitive: bool) -> list[str]:
    """One name per drone of a task whose drones play on ``teams`` (in agent order)."""
    if not competitive:
        return [f"drone_{i}" for i in range(len(teams))]
    rank = {0: 0, 1: 0}
    names = []
    for t in teams:
        names.append(f"team{t}_drone{rank[t]}")
        rank[t] += 1
    return names


class VolleyParallelEnv(ParallelEnv):
    """One world of ``task`` as a PettingZoo parallel env: dicts of numpy arrays keyed by agent.

    Args:
        task: any task (``bump_and_pass``, ``set_and_spike_easy``, ``3v3``, ...).
        action_space: ``prt``, ``ctbr`` or ``discrete``.
        physics: ``torch`` or ``mujoco``.
        device: where the env's tensors live (arrays always come back on the CPU).
        seed: the generator's seed until ``reset(seed=...)`` gives another.
        **task_overrides: as for ``volleybots.make_env`` (``episode_len``, ``serve``, ...).
    """

    metadata: ClassVar[dict] = {"name": "volleybots_v0", "render_modes": [], "is_parallelizable": True}

    def __init__(self, task: str = "3v3", action_space: str = "prt", physics: str = "torch", device="cpu", seed: int = 0,
                 render_mode: str | None = None, **task_overrides):
        # a render_mode is accepted and ignored (tools such as SB3's make_vec_env pass one): nothing
        # renders here; a replay of the task comes from `volleybots replay`
        self.render_mode = None
        self.env = build_env(task, num_envs=1, action_space=action_space, physics=physics, device=device, seed=seed,
                                       **task_overrides)
        self.task = task
        teams = tuple(self.env.teams)
        self.possible_agents = agent_names(teams, self.env.competitive)
        self.n_agents = len(self.possible_agents)
        self.team_of = dict(zip(self.possible_agents, teams))  # agent -> its team (0 or 1)
        if self.env.competitive:
            self.groups = {f"team{t}": [a for a in self.possible_agents if self.team_of[a] == t] for t in sorted(set(teams))}
        else:
            self.groups = {AGENTS: list(self.possible_agents)}
        # one space object per agent, the same on every call (the API test asks for it; seeding one agent's
        # action space must not seed the others')
        self.observation_spaces = {a: sp.observation_space(self.env) for a in self.possible_agents}
        self.action_spaces = {a: sp.action_space(self.env) for a in self.possible_agents}
        self.agents: list[str] = []
        self._td = None

    def observation_space(self, agent: str):
        return self.observation_spaces[agent]

    def action_space(self, agent: str):
        return self.action_spaces[agent]

    def _obs(self, td) -> dict[str, np.ndarray]:
        obs = to_numpy(td.get(OBS)[0])
        return {a: obs[i] for i, a in enumerate(self.possible_agents)}

    def reset(self, seed: int | None = None, options: dict | None = None):
        """Start an episode with every agent; ``seed`` reseeds the env's generator first."""
        if seed is not None:
            self.env.set_seed(int(seed))
        self._td = self.env.reset()
        self.agents = list(self.possible_agents)
        return self._obs(self._td), {a: {} for a in self.agents}

    def step(self, actions: dict[str, Any]):
        """One step of every agent: ``actions`` holds one action per agent of ``agents``."""
        if not self.agents:
            raise RuntimeError("the episode is over (or never began): call reset() first")
        if set(actions) != set(self.agents):
            missing, unknown = sorted(set(self.agents) - set(actions)), sorted(set(actions) - set(self.agents))
            raise ValueError(f"actions must name every agent once: missing {missing}, unknown {unknown}; agents: {self.agents}")
        stacked = np.stack([np.asarray(actions[a]) for a in self.possible_agents])
        self._td.set(ACTION, action_tensor(self.env, stacked, (1, self.n_agents)))
        nxt = self.env.step(self._td).get(NEXT)
        self._td = nxt
        reward = to_numpy(nxt.get(REWARD)[0, :, 0])
        terminated, truncated = bool(nxt.get(TERMINATED)), bool(nxt.get(TRUNCATED))
        agents = self.agents
        info = {"episode": episode_stats(self.env, nxt, 0)} if terminated or truncated else {}
        if terminated or truncated:
            self.agents = []
        return (
            self._obs(nxt),
            {a: float(reward[i]) for i, a in enumerate(self.possible_agents)},
            dict.fromkeys(agents, terminated),
            dict.fromkeys(agents, truncated),
            {a: dict(info) for a in agents},
        )

    def close(self):
        self.env.close(raise_if_closed=False)


def parallel_env(task: str = "3v3", **kwargs) -> VolleyParallelEnv:
    """``VolleyParallelEnv(task, **kwargs)``, under the name PettingZoo's environments use."""
    return VolleyParallelEnv(task, **kwargs)
