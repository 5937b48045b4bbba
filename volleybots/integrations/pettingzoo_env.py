"""A PettingZoo ``ParallelEnv`` over one world of any task (the multi-drone ones above all).

Agents. A match names its drones after their team's colour, ``blue_0 ... blue_2, red_0 ... red_2``
(blue: team 0 on +x, red: team 1 on -x; each team's agents in the env's agent order), the
``<type>_<n>`` form of SuperSuit's ``agent_indicator_v0(type_only=True)``, where the type is the team.
``groups`` maps ``team0`` and ``team1`` to them: the group map of TorchRL's and BenchMARL's
multi-agent code, one policy per group. A cooperative task (and a single-drone one) has one team:
``drone_0, drone_1, ...`` in one group named ``agents``, as TorchRL names the group of agents that
share everything. ``legacy_names=True`` gives a match's earlier names (``team0_drone0`` ...).
The -x team's observations are mirrored by the task itself, so one policy can play either side.

All agents start and end together (the env's ``done`` is shared): a step that ends the episode gives
every agent ``terminated`` or ``truncated``, the episode statistics in each agent's
``info["final_stats"]``, and leaves ``agents`` empty until ``reset()``; a later ``step`` is refused.
``reset(seed=s)`` reseeds the env's generator as ``make_env(task, seed=s)`` does (and refuses what
the Gymnasium envs refuse). ``state()`` is the global state a centralised critic sees (MAPPO's:
every agent's observation, in ``possible_agents`` order, concatenated), ``state_space`` its box.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

try:
    from pettingzoo import ParallelEnv
except ImportError:  # the message names the extra: a bare "No module named pettingzoo" does not
    raise ImportError("volleybots.integrations.VolleyParallelEnv needs pettingzoo: pip install 'volleybots[pettingzoo]'") from None

from gymnasium import spaces

from volleybots.integrations import spaces as sp
from volleybots.integrations.render import RENDER_MODES, Trail, check_render_mode
from volleybots.integrations.spaces import STATS_KEY, Actions, check_seed, episode_stats, to_numpy
from volleybots.keys import ACTION, AGENTS, NEXT, OBS, REWARD, TERMINATED, TRUNCATED
from volleybots.tasks.groups import agent_names


class VolleyParallelEnv(ParallelEnv):
    """One world of ``task`` as a PettingZoo parallel env: dicts of numpy arrays keyed by agent.

    Args:
        task: any task (``bump_and_pass``, ``set_and_spike_easy``, ``3v3``, ...).
        action_space: ``prt``, ``ctbr`` or ``discrete``.
        physics: ``torch`` or ``mujoco``.
        device: where the env's tensors live (arrays always come back on the CPU).
        seed: the generator's seed until ``reset(seed=...)`` gives another.
        render_mode: None or ``rgb_array`` (``render()``: the video frame of the episode so far, with the score).
        legacy_names: a match's agents named ``team0_drone0`` ... as they were first.
        clip_obs: declare finite bounds for the positions and velocities and clip observations into
            them (for SuperSuit's ``normalize_obs_v0``); ``obs_clip`` counts the clipped values.
        **task_overrides: as for ``volleybots.make_env`` (``episode_len``, ``serve``, ...).
    """

    metadata: ClassVar[dict] = {"name": "volleybots_v0", "render_modes": list(RENDER_MODES), "render_fps": 50, "is_parallelizable": True}

    def __init__(self, task: str = "3v3", action_space: str = "prt", physics: str = "torch", device="cpu", seed: int = 0,
                 render_mode: str | None = None, legacy_names: bool = False, clip_obs: bool = False, **task_overrides):
        if not isinstance(legacy_names, (bool, np.bool_)):
            raise ValueError(f"legacy_names must be True or False, got {legacy_names!r}")
        self.render_mode = check_render_mode(render_mode)
        self.env = sp.build(task, 1, action_space=action_space, physics=physics, device=device, seed=seed, **task_overrides)
        self._trail = Trail(self.env) if self.render_mode else None
        self._observe = sp.Observations(self.env, clip_obs)
        self.obs_clip = self._observe.clip
        self.task = task
        teams = tuple(self.env.teams)
        self.possible_agents = agent_names(teams, self.env.competitive, bool(legacy_names))
        self.n_agents = len(self.possible_agents)
        self.team_of = dict(zip(self.possible_agents, teams))  # agent -> its team (0 or 1)
        if self.env.competitive:
            self.groups = {f"team{t}": [a for a in self.possible_agents if self.team_of[a] == t] for t in sorted(set(teams))}
        else:
            self.groups = {AGENTS: list(self.possible_agents)}
        # one space object per agent, the same on every call (the API test asks for it; seeding one agent's
        # action space must not seed the others')
        self.observation_spaces = {a: sp.observation_space(self.env, self._observe.clip_obs) for a in self.possible_agents}
        self.action_spaces = {a: sp.action_space(self.env) for a in self.possible_agents}
        one = self.observation_spaces[self.possible_agents[0]]
        self.state_space = spaces.Box(np.tile(one.low, self.n_agents), np.tile(one.high, self.n_agents), dtype=np.float32)
        self._actions = Actions(self.env, (1, self.n_agents))
        self._shape = self._actions.shape()
        self.agents: list[str] = []
        self._td = None
        self._closed = False

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("this VolleyParallelEnv is closed: make a new one")

    def observation_space(self, agent: str):
        return self.observation_spaces[self._agent(agent)]

    def action_space(self, agent: str):
        return self.action_spaces[self._agent(agent)]

    def _agent(self, agent: str) -> str:
        if agent not in self.possible_agents:  # a bare KeyError would not say which names there are
            raise ValueError(f"unknown agent {agent!r}; agents: {', '.join(self.possible_agents)}")
        return agent

    def _obs(self, td) -> dict[str, np.ndarray]:
        obs = self._observe(td.get(OBS)[0])
        return {a: obs[i] for i, a in enumerate(self.possible_agents)}

    def reset(self, seed: int | None = None, options: dict | None = None):
        """Start an episode with every agent; ``seed`` reseeds the env's generator first."""
        self._check_open()
        seed = check_seed(seed)
        if seed is not None:
            self.env.set_seed(seed)
        self._td = self.env.reset()
        self.agents = list(self.possible_agents)
        if self._trail is not None:
            self._trail.clear()
            self._trail.record(after_step=False)
        return self._obs(self._td), {a: {} for a in self.agents}

    def step(self, actions: dict[str, Any]):
        """One step of every agent: ``actions`` holds one action per agent of ``agents``."""
        self._check_open()
        if not self.agents:
            raise RuntimeError("the episode is over (or never began): call reset() first")
        if set(actions) != set(self.agents):
            missing, unknown = sorted(set(self.agents) - set(actions)), sorted(set(actions) - set(self.agents))
            raise ValueError(f"actions must name every agent once: missing {missing}, unknown {unknown}; agents: {self.agents}")
        stacked = np.stack([self._actions.array(actions[a], self._shape, a) for a in self.possible_agents])
        self._td.set(ACTION, self._actions.tensor(stacked))
        nxt = self.env.step(self._td).get(NEXT)
        self._td = nxt
        reward = to_numpy(nxt.get(REWARD)[0, :, 0])
        terminated, truncated = bool(nxt.get(TERMINATED)), bool(nxt.get(TRUNCATED))
        if self._trail is not None:
            self._trail.record(after_step=True, stats=episode_stats(self.env, nxt, 0))
            if terminated or truncated:  # a match's winner takes the point the frames' header shows
                self._trail.end(episode_stats(self.env, nxt, 0))
        agents = self.agents
        info = {STATS_KEY: episode_stats(self.env, nxt, 0)} if terminated or truncated else {}
        if terminated or truncated:
            self.agents = []
        return (
            self._obs(nxt),
            {a: float(reward[i]) for i, a in enumerate(self.possible_agents)},
            dict.fromkeys(agents, terminated),
            dict.fromkeys(agents, truncated),
            {a: dict(info) for a in agents},
        )

    def render(self):
        """The video frame of the episode so far ([H, W, 3] uint8), or None without a render mode."""
        self._check_open()
        return None if self._trail is None else self._trail.frame(title=self.task)

    def state(self) -> np.ndarray:
        """The global state [n_agents * obs]: every agent's current observation, in ``possible_agents``
        order, concatenated (what MAPPO's centralised critic sees)."""
        self._check_open()
        if self._td is None:
            raise RuntimeError("call reset() before state()")
        return self._observe(self._td.get(OBS)[0]).reshape(-1)

    def close(self):
        self._closed = True
        self.env.close(raise_if_closed=False)


def parallel_env(task: str = "3v3", **kwargs) -> VolleyParallelEnv:
    """``VolleyParallelEnv(task, **kwargs)``, under the name PettingZoo's environments use."""
    return VolleyParallelEnv(task, **kwargs)
