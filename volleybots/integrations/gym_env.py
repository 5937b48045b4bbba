"""Gymnasium views of the single-drone tasks: a ``VectorEnv`` over the batched TorchRL env and a
single ``Env`` (one world) for code and checkers that want one.

Both drive the env through its TorchRL API (``reset``, ``step``, ``step_and_maybe_reset``), so the
physics, rewards and resets are the env's own; these classes only move numbers between numpy and
the env's tensordicts. Observations are float32 arrays of the env's observation size, actions the
env's action (a Box in [-1, 1] of 4 for ``prt`` / ``ctbr``, a Discrete(16) for ``discrete``).

Autoreset. The batched env resets a finished world within the step that ends it, so the vector env
declares Gymnasium's ``AutoresetMode.SAME_STEP``: a done world's row of the returned observation is
already its next episode's first one; its last observation is in ``info["final_obs"]`` (rows where
``info["_final_obs"]`` is set) and its episode statistics (return, length, the task metric, every
reward term) in ``info["episode"]`` (rows where ``info["_episode"]`` is set). The single env does
not reset by itself: it reports ``info["episode"]`` at the end and waits for ``reset()``.

Seeding. ``reset(seed=s)`` reseeds the env's generator with ``s`` before the reset, exactly as
``make_env(task, seed=s)`` does at construction: the same seed gives the same starts, the same
observations and (for the same actions) the same episodes as the batched env itself.
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from tensordict import TensorDict

from volleybots.config import build_env
from volleybots.integrations import spaces as sp
from volleybots.integrations.spaces import (
    SINGLE_TASKS,
    action_tensor,
    episode_stats,
    to_numpy,
)
from volleybots.keys import ACTION, DONE, NEXT, OBS, REWARD, TERMINATED, TRUNCATED
from volleybots.tasks import TASKS

NAMESPACE = "volleybots"
VERSION = 0
# Gymnasium id -> task: volleybots/SoloBump-v0 -> solo_bump (the task's class name)
IDS = {f"{NAMESPACE}/{TASKS[name].__name__}-v{VERSION}": name for name in SINGLE_TASKS}


def _make(task: str, num_envs: int, **kw):
    if task not in SINGLE_TASKS:
        others = "; use volleybots.integrations.VolleyParallelEnv (PettingZoo) for it" if task in TASKS else ""
        raise ValueError(f"task {task!r} is not a single-drone task{others}; allowed: {list(SINGLE_TASKS)}")
    return build_env(task, num_envs=num_envs, **kw)


class VolleyVectorEnv(VectorEnv):
    """``num_envs`` worlds of a single-drone task as one Gymnasium vector env (numpy in and out).

    Args:
        task: a single-drone task (``hover``, ``back_and_forth``, ``hit_the_ball``, ``solo_bump``, a drill).
        num_envs: worlds stepped together.
        action_space: ``prt``, ``ctbr`` or ``discrete``.
        physics: ``torch`` or ``mujoco``.
        device: where the env's tensors live (arrays always come back on the CPU).
        seed: the generator's seed until ``reset(seed=...)`` gives another.
        **task_overrides: as for ``volleybots.make_env`` (``episode_len``, ``reward_shaping``, ...).
    """

    metadata: ClassVar[dict] = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": []}

    def __init__(self, task: str = "solo_bump", num_envs: int = 1, action_space: str = "prt", physics: str = "torch",
                 device="cpu", seed: int = 0, render_mode: str | None = None, **task_overrides):
        # a render_mode is accepted and ignored (tools such as SB3's make_vec_env pass one): nothing
        # renders here; a replay of the task comes from `volleybots replay`
        self.render_mode = None
        self.env = _make(task, num_envs, action_space=action_space, physics=physics, device=device, seed=seed, **task_overrides)
        self.task, self.num_envs = task, num_envs
        self.single_observation_space = sp.observation_space(self.env)
        self.single_action_space = sp.action_space(self.env)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._td = None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Reset every world; ``seed`` (one int for the whole batch) reseeds the env's generator first."""
        if seed is not None and not isinstance(seed, (int, np.integer)):
            raise ValueError(f"seed must be one int for the whole batch (the worlds share one generator), got {seed!r}")
        super().reset(seed=None if seed is None else int(seed))
        if seed is not None:
            self.env.set_seed(int(seed))
        self._td = self.env.reset()
        return to_numpy(self._td.get(OBS)[:, 0]), {}

    def step(self, actions):
        if self._td is None:
            raise RuntimeError("call reset() before step()")
        self._td.set(ACTION, action_tensor(self.env, actions, (self.num_envs, 1)))
        cur, self._td = self.env.step_and_maybe_reset(self._td)
        nxt = cur.get(NEXT)
        done = to_numpy(nxt.get(DONE).reshape(-1))
        info: dict[str, Any] = {}
        if done.any():
            info["final_obs"] = to_numpy(nxt.get(OBS)[:, 0])
            info["_final_obs"] = done
            info["episode"] = episode_stats(self.env, nxt)
            info["_episode"] = done.copy()
        return (
            to_numpy(self._td.get(OBS)[:, 0]),
            to_numpy(nxt.get(REWARD)[:, 0, 0]).astype(np.float64),
            to_numpy(nxt.get(TERMINATED).reshape(-1)),
            to_numpy(nxt.get(TRUNCATED).reshape(-1)),
            info,
        )

    def close_extras(self, **kwargs):
        self.env.close(raise_if_closed=False)


class VolleyGymEnv(gym.Env):
    """One world of a single-drone task as a ``gymnasium.Env`` (the batched env with ``num_envs=1``).

    Arguments as for ``VolleyVectorEnv`` (without ``num_envs``). The episode's statistics come in
    ``info["episode"]`` on its last step; step again only after ``reset()``.
    """

    metadata: ClassVar[dict] = {"render_modes": []}

    def __init__(self, task: str = "solo_bump", action_space: str = "prt", physics: str = "torch", device="cpu",
                 seed: int = 0, render_mode: str | None = None, **task_overrides):
        # a render_mode is accepted and ignored (tools such as SB3's make_vec_env pass one): nothing
        # renders here; a replay of the task comes from `volleybots replay`
        self.render_mode = None
        self.env = _make(task, 1, action_space=action_space, physics=physics, device=device, seed=seed, **task_overrides)
        self.task = task
        self.observation_space = sp.observation_space(self.env)
        self.action_space = sp.action_space(self.env)
        self._td: TensorDict | None = None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start an episode; ``seed`` reseeds the env's generator first."""
        super().reset(seed=seed)
        if seed is not None:
            self.env.set_seed(int(seed))
        self._td = self.env.reset()
        return to_numpy(self._td.get(OBS)[0, 0]), {}

    def step(self, action):
        if self._td is None:
            raise RuntimeError("call reset() before step()")
        self._td.set(ACTION, action_tensor(self.env, action, (1, 1)))
        nxt = self.env.step(self._td).get(NEXT)
        self._td = nxt
        terminated, truncated = bool(nxt.get(TERMINATED)), bool(nxt.get(TRUNCATED))
        info = {"episode": episode_stats(self.env, nxt, 0)} if terminated or truncated else {}
        return to_numpy(nxt.get(OBS)[0, 0]), float(nxt.get(REWARD)), terminated, truncated, info

    def close(self):
        self.env.close(raise_if_closed=False)


def register() -> None:
    """Register ``volleybots/<Task>-v0`` for every single-drone task (``gymnasium.make`` gives the
    single env, ``gymnasium.make_vec`` the batched one); registering again changes nothing."""
    for env_id, task in IDS.items():
        if env_id in gym.registry:
            continue
        gym.register(
            id=env_id,
            entry_point=f"{__name__}:VolleyGymEnv",
            vector_entry_point=f"{__name__}:VolleyVectorEnv",
            # the task ends its own episodes (truncation at its episode length): no TimeLimit wrapper
            max_episode_steps=None,
            kwargs={"task": task},
        )
