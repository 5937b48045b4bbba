"""A match with one TorchRL group per team: ``make_env("3v3", group_map="teams")``.

The env's own layout keeps every drone in one ``("agents", ...)`` group [N, A] with ``done`` only at
the root. TorchRL's multi-agent envs (VMAS, PettingZoo with a group map) and BenchMARL lay a
competitive game out by team instead, with each agent's own flags, so their loops read
``(group, "observation")`` and ``(group, "done")`` for every group of ``env.group_map``.
``TeamGroups`` gives a match that layout over the same env (the same physics, rewards and resets):

- ``("team0", ...)`` / ``("team1", ...)``, batch [N, A_t]: ``observation`` [N, A_t, obs] (team 1's
  mirrored to the +x side, as the task gives it), ``action`` [N, A_t, 4] (or [N, A_t] discrete),
  ``reward`` [N, A_t, 1] and the agent-level ``done`` / ``terminated`` / ``truncated`` [N, A_t, 1]
  (all a world's drones end together: each is the world's flag);
- ``done`` / ``terminated`` / ``truncated`` [N, 1] at the root and ``("stats", name)`` as before;
- ``group_map``: ``{"team0": ["blue_0", ...], "team1": ["red_0", ...]}``, the agents' names of the
  PettingZoo env (``agent_names``).

A partial reset takes ``_reset`` at the root or in either group (any agent of a world resets the world).
"""

from __future__ import annotations

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Categorical, Composite
from torchrl.envs import EnvBase

from volleybots.keys import ACTION, AGENTS, DONE, OBS, REWARD, STATS, TEAM_NAMES, TERMINATED, TRUNCATED, leaf
from volleybots.tasks.base import VolleyEnv

GROUP_MAPS = (AGENTS, "teams")  # make_env's group_map: one group of every drone (the env's own), or one per team
FLAGS = (DONE, TERMINATED, TRUNCATED)


def agent_names(teams: tuple[int, ...], competitive: bool, legacy: bool = False) -> list[str]:
    """One name per drone of a task whose drones play on ``teams`` (in agent order): ``blue_0``,
    ``red_0`` ... in a match (``team0_drone0`` ... with ``legacy``), ``drone_0`` ... otherwise."""
    if not competitive:
        return [f"drone_{i}" for i in range(len(teams))]
    rank = {0: 0, 1: 0}
    names = []
    for t in teams:
        names.append(f"team{t}_drone{rank[t]}" if legacy else f"{TEAM_NAMES[t]}_{rank[t]}")
        rank[t] += 1
    return names


class TeamGroups(EnvBase):
    """A match env (``VolleyEnv`` with two teams) laid out with one group per team (module docstring)."""

    def __init__(self, env: VolleyEnv):
        if not env.competitive:
            raise ValueError(f"group_map='teams' needs a match (two teams); task {env.name!r} has one team")
        super().__init__(device=env.device, batch_size=env.batch_size)
        self.base = env
        self.name, self.num_envs, self.n_drones = env.name, env.num_envs, env.n_drones
        self.groups = {f"team{t}": env.team_index(t) for t in (0, 1)}
        names = agent_names(tuple(env.teams), True)
        self.group_map = {g: [names[i] for i in idx.tolist()] for g, idx in self.groups.items()}
        n, dev = env.num_envs, env.device

        def grouped(spec: Composite, key: tuple) -> dict:
            """The env's per-drone spec of ``key`` split into one group per team."""
            one = spec[AGENTS][leaf(key)]
            out = {}
            for g, idx in self.groups.items():
                a = len(idx)
                sub = one[:, :a].clone()  # the same kind of spec (bounds, categories) for A_t drones
                out[g] = Composite({leaf(key): sub}, shape=(n, a), device=dev)
            return out

        obs = grouped(env.observation_spec, OBS)
        obs[STATS] = env.observation_spec[STATS].clone()
        self.observation_spec = Composite(obs, shape=(n,), device=dev)
        self.action_spec = Composite(grouped(env.action_spec, ACTION), shape=(n,), device=dev)
        self.reward_spec = Composite(grouped(env.reward_spec, REWARD), shape=(n,), device=dev)
        flags = {f: Categorical(2, (n, 1), dtype=torch.bool, device=dev) for f in FLAGS}
        for g, idx in self.groups.items():
            a = len(idx)
            flags[g] = Composite({f: Categorical(2, (n, a, 1), dtype=torch.bool, device=dev) for f in FLAGS}, shape=(n, a), device=dev)
        self.done_spec = Composite(flags, shape=(n,), device=dev)

    # ------------------------------------------------------------------ moving between the layouts
    def _split(self, out: TensorDictBase) -> TensorDictBase:
        """The env's output (agents [N, A], root flags) in the per-team layout."""
        agents = out.get(AGENTS)
        res = TensorDict({STATS: out.get(STATS)}, batch_size=self.batch_size, device=self.device)
        flags = {f: out.get(f) for f in FLAGS}
        for g, idx in self.groups.items():
            sub = agents[:, idx]
            a = len(idx)
            for f, v in flags.items():
                sub.set(f, v.unsqueeze(1).expand(self.num_envs, a, 1).clone())
            res.set(g, sub)
        res.update(flags)
        return res

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        parts = [tensordict.get((g, leaf(ACTION))) for g in self.groups]
        first = parts[0]
        action = torch.empty((self.num_envs, self.n_drones, *first.shape[2:]), dtype=first.dtype, device=self.device)
        for idx, part in zip(self.groups.values(), parts):
            action[:, idx] = part
        inner = TensorDict({ACTION: action}, batch_size=self.batch_size, device=self.device)
        return self._split(self.base._step(inner))

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        inner = None
        if tensordict is not None:
            masks = [tensordict.get(k).reshape(self.num_envs, -1).any(-1) for k in ("_reset", *((g, "_reset") for g in self.groups))
                     if k in tensordict.keys(include_nested=True)]
            if masks:
                mask = torch.stack(masks).any(0)
                inner = TensorDict({"_reset": mask.unsqueeze(-1)}, batch_size=self.batch_size, device=self.device)
        return self._split(self.base._reset(inner))

    def _set_seed(self, seed: int | None):
        return self.base._set_seed(seed)


__all__ = ["GROUP_MAPS", "TeamGroups", "agent_names"]
