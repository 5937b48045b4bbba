"""Gymnasium views of the single-drone tasks: a ``VectorEnv`` over the batched TorchRL env and a
single ``Env`` (one world) for code and checkers that want one.

Both drive the env through its TorchRL API (``reset``, ``step``, ``step_and_maybe_reset``), so the
physics, rewards and resets are the env's own; these classes only move numbers between numpy and
the env's tensordicts, and check what comes in (``spaces``: exact action shapes and dtypes, seeds,
switches). Observations are float32 arrays of the env's observation size, actions the env's action
(a Box in [-1, 1] of 4 for ``prt`` / ``ctbr``, a Discrete(16) for ``discrete``).

Autoreset. By default the vector env resets a finished world within the step that ends it
(Gymnasium's ``AutoresetMode.SAME_STEP``, what the batched env does): a done world's row of the
returned observation is already its next episode's first one and its last observation is in
``info["final_obs"]`` (rows where ``info["_final_obs"]`` is set). ``autoreset_mode="next_step"``
gives Gymnasium's default instead: the ending step returns the last observation, and the next
``step`` resets that world (its action is ignored, its reward is 0) while the others step. The
episode statistics (return, length, the task metric, every reward term) come in
``info["final_stats"]`` (rows where ``info["_final_stats"]`` is set): ``info["episode"]`` is left
to the standard wrappers (``RecordEpisodeStatistics``, SB3's ``Monitor``). The single env does not
reset by itself: it reports ``info["final_stats"]`` at the end, and refuses ``step`` until ``reset()``.

Seeding. ``reset(seed=s)`` reseeds the env's generator with ``s`` before the reset, exactly as
``make_env(task, seed=s)`` does at construction: the same seed gives the same starts, the same
observations and (for the same actions) the same episodes as the batched env itself.
"""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
import torch
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from tensordict import TensorDict

from volleybots.integrations import spaces as sp
from volleybots.integrations.render import RENDER_MODES, Trail, check_render_mode
from volleybots.integrations.spaces import SINGLE_TASKS, STATS_KEY, Actions, check_seed, episode_stats, to_numpy
from volleybots.keys import ACTION, NEXT, OBS, REWARD, TERMINATED, TRUNCATED
from volleybots.tasks import TASKS

NAMESPACE = "volleybots"
VERSION = 0
# Gymnasium id -> task: volleybots/SoloBump-v0 -> solo_bump (the task's class name)
IDS = {f"{NAMESPACE}/{TASKS[name].__name__}-v{VERSION}": name for name in SINGLE_TASKS}
AUTORESET_MODES = {"same_step": AutoresetMode.SAME_STEP, "next_step": AutoresetMode.NEXT_STEP}


def _make(task: str, num_envs: int, **kw):
    if task not in SINGLE_TASKS:
        others = "; use volleybots.integrations.VolleyParallelEnv (PettingZoo) for it" if task in TASKS else ""
        raise ValueError(f"task {task!r} is not a single-drone task{others}; allowed: {list(SINGLE_TASKS)}")
    return sp.build(task, num_envs, **kw)


def _autoreset_mode(mode) -> AutoresetMode:
    if isinstance(mode, AutoresetMode) and mode in AUTORESET_MODES.values():
        return mode
    if isinstance(mode, str) and mode in AUTORESET_MODES:
        return AUTORESET_MODES[mode]
    raise ValueError(f"autoreset_mode must be one of {list(AUTORESET_MODES)} (or the AutoresetMode), got {mode!r}")


class _Closable:
    """Refuses use after ``close()``, as a closed Gymnasium or PettingZoo env should."""

    _closed = False

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError(f"this {type(self).__name__} is closed: make a new one")


class _BatchedVectorEnv(_Closable, VectorEnv):
    """What the vector envs over one batched env share (``self.env``; rows of the learner's agents
    through ``_rows``): the seeded reset, ``step`` over ``step32``, the ending rows' info and closing."""

    def _rows(self, x: torch.Tensor) -> torch.Tensor:
        """The vector env's rows of a per-agent tensor [N, A, ...]: one agent per world here."""
        return x[:, 0]

    def _per_row(self, x: np.ndarray) -> np.ndarray:
        """A per-world array [N] as the rows (one a world here)."""
        return x

    def _reseed(self, seed: int) -> None:
        self.env.set_seed(seed)

    def _after_reset(self) -> None:
        """What a subclass clears when every world resets."""

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Reset every world; ``seed`` (one int for the whole batch) reseeds the env's generator first."""
        self._check_open()
        seed = check_seed(seed)
        super().reset(seed=seed)
        if seed is not None:
            self._reseed(seed)
        self._td = self.env.reset()
        self._after_reset()
        self._trail_restart()
        return self._observe(self._rows(self._td.get(OBS))), {}

    def step(self, actions):
        obs, reward, term, trunc, info = self.step32(actions)
        return obs, reward.astype(np.float64), term, trunc, info

    def _flags(self, nxt) -> tuple[np.ndarray, np.ndarray]:
        """(terminated, truncated) of a step's output as the rows."""
        return tuple(self._per_row(to_numpy(nxt.get(k).reshape(-1))) for k in (TERMINATED, TRUNCATED))

    def _ended_info(self, nxt, done: np.ndarray) -> dict[str, Any]:
        """The info of a same-step autoreset: the ended rows' last observation and episode statistics."""
        if not done.any():
            return {}
        stats = {k: self._per_row(v) for k, v in episode_stats(self.env, nxt).items()}
        return {"final_obs": self._observe(self._rows(nxt.get(OBS))), "_final_obs": done, STATS_KEY: stats, "_" + STATS_KEY: done.copy()}

    # ------------------------------------------------------------------ rendering (the first world)
    _trail: Trail | None = None

    def _init_render(self, render_mode) -> None:
        self.render_mode = check_render_mode(render_mode)
        self._trail = Trail(self.env, 0) if self.render_mode else None

    def _trail_restart(self) -> None:
        """World 0 began an episode: its trail starts again from the state now."""
        if self._trail is not None:
            self._trail.clear()
            self._trail.record(after_step=False)

    def _trail_step(self, nxt, ended: bool) -> None:
        """After a same-step-autoreset step: world 0's trail goes on, or gives its point and starts again."""
        if self._trail is not None:
            self._trail.after_batched_step(episode_stats(self.env, nxt, 0), ended)

    def render(self):
        """The first world's video frame ([H, W, 3] uint8: ``volleybots.integrations.render``) as a tuple
        of one, as Gymnasium's vector envs return one frame per env; None without a render mode. One
        world only: the frames of all of them would cost a frame each and show the same picture."""
        self._check_open()
        if self._trail is None:
            return None
        return (self._trail.frame(title=f"{self.task} (world 0)"),)

    def close_extras(self, **kwargs):
        self._closed = True
        self.env.close(raise_if_closed=False)


class VolleyVectorEnv(_BatchedVectorEnv):
    """``num_envs`` worlds of a single-drone task as one Gymnasium vector env (numpy in and out).

    Args:
        task: a single-drone task (``hover``, ``back_and_forth``, ``hit_the_ball``, ``solo_bump``, a drill).
        num_envs: worlds stepped together.
        action_space: ``prt``, ``ctbr`` or ``discrete``.
        physics: ``torch`` or ``mujoco``.
        device: where the env's tensors live (arrays always come back on the CPU).
        seed: the generator's seed until ``reset(seed=...)`` gives another.
        autoreset_mode: ``"same_step"`` (the batched env's own) or ``"next_step"`` (Gymnasium's default).
        clip_obs: declare finite bounds for the positions and velocities and clip observations into
            them (``bounds``; for wrappers that scale by the bounds); ``obs_clip`` counts the clipped values.
        render_mode: None, or ``"rgb_array"``: ``render()`` gives the first world's video frame (a
            tuple of one frame), for Gymnasium's and SB3's video recorders.
        **task_overrides: as for ``volleybots.make_env`` (``episode_len``, ``reward_shaping``, ...).
    """

    metadata: ClassVar[dict] = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": list(RENDER_MODES), "render_fps": 50}

    def __init__(self, task: str = "solo_bump", num_envs: int = 1, action_space: str = "prt", physics: str = "torch",
                 device="cpu", seed: int = 0, render_mode: str | None = None, autoreset_mode="same_step", clip_obs: bool = False,
                 **task_overrides):
        check_render_mode(render_mode)  # before the env is built: a bad mode is one line
        mode = _autoreset_mode(autoreset_mode)
        self.env = _make(task, num_envs, action_space=action_space, physics=physics, device=device, seed=seed, **task_overrides)
        self._init_render(render_mode)
        self._observe = sp.Observations(self.env, clip_obs)
        self.obs_clip = self._observe.clip
        self.metadata = {**type(self).metadata, "autoreset_mode": mode}
        self.next_step = mode == AutoresetMode.NEXT_STEP
        self.task, self.num_envs = task, int(num_envs)
        # the task's headline statistic, a key of info["final_stats"], and its direction (a script plots it by name)
        self.metric, self.metric_higher_is_better = self.env.metric, bool(self.env.metric_higher_is_better)
        self.single_observation_space = self._observe.space
        self.single_action_space = sp.action_space(self.env)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._actions = Actions(self.env, (self.num_envs, 1))
        self._shape = self._actions.shape((self.num_envs,))
        self._td = None
        self._pending = np.zeros(self.num_envs, bool)  # next_step: worlds whose episode ended last step

    def _after_reset(self) -> None:
        self._pending[:] = False

    def step32(self, actions):
        """``step`` with the reward as the env's float32 (what SB3's buffers hold: ``VolleySB3VecEnv``
        takes it as it is; Gymnasium's ``step`` gives float64)."""
        self._check_open()
        if self._td is None:
            raise RuntimeError("call reset() before step()")
        arr = self._actions.array(actions, self._shape)
        if self.next_step:
            return self._step_next(arr)
        self._td.set(ACTION, self._actions.tensor(arr))
        cur, self._td = self.env.step_and_maybe_reset(self._td)
        nxt = cur.get(NEXT)
        term, trunc = self._flags(nxt)
        self._trail_step(nxt, bool(term[0] or trunc[0]))
        return self._observe(self._td.get(OBS)[:, 0]), to_numpy(nxt.get(REWARD)[:, 0, 0]), term, trunc, self._ended_info(nxt, term | trunc)

    def _step_next(self, arr: np.ndarray):
        """Gymnasium's next-step autoreset: the worlds whose episode ended last step are stepped with a
        zero action (one batched step for all), then reset; their rows report the reset, reward 0."""
        pending = self._pending.copy()
        if pending.any():  # their actions are ignored, as Gymnasium's next-step mode says: nothing of them reaches the env
            arr = arr.copy()
            arr[pending] = 0
        self._td.set(ACTION, self._actions.tensor(arr))
        nxt = self.env.step(self._td).get(NEXT)
        obs = self._observe(nxt.get(OBS)[:, 0])
        reward = to_numpy(nxt.get(REWARD)[:, 0, 0])
        term, trunc = to_numpy(nxt.get(TERMINATED).reshape(-1)), to_numpy(nxt.get(TRUNCATED).reshape(-1))
        if pending.any():
            mask = torch.as_tensor(pending, device=self.env.device).unsqueeze(-1)
            fresh = self.env.reset(TensorDict({"_reset": mask}, batch_size=[self.num_envs], device=self.env.device))
            obs[pending] = self._observe(fresh.get(OBS)[:, 0][mask[:, 0]])
            reward[pending], term[pending], trunc[pending] = 0.0, False, False
        self._td = nxt
        done = term | trunc
        if pending[0]:  # world 0 was reset after this step: its trail starts again
            self._trail_restart()
        elif self._trail is not None:
            self._trail.record(after_step=True, stats=episode_stats(self.env, nxt, 0))
            if done[0]:
                self._trail.end(episode_stats(self.env, nxt, 0))
        info: dict[str, Any] = {}
        if done.any():
            info[STATS_KEY] = episode_stats(self.env, nxt)
            info["_" + STATS_KEY] = done.copy()
        self._pending = done
        return obs, reward, term, trunc, info


class VolleyGymEnv(_Closable, gym.Env):
    """One world of a single-drone task as a ``gymnasium.Env`` (the batched env with ``num_envs=1``).

    Arguments as for ``VolleyVectorEnv`` (without ``num_envs`` and ``autoreset_mode``);
    ``render_mode="rgb_array"`` makes ``render()`` return the video frame of the episode so far
    ([H, W, 3] uint8: ``volleybots.integrations.render``). The episode's statistics come in ``info["final_stats"]`` on its last step;
    ``step`` is refused after that until ``reset()``.
    """

    metadata: ClassVar[dict] = {"render_modes": list(RENDER_MODES), "render_fps": 50}  # 50 control steps per second

    def __init__(self, task: str = "solo_bump", action_space: str = "prt", physics: str = "torch", device="cpu",
                 seed: int = 0, render_mode: str | None = None, clip_obs: bool = False, **task_overrides):
        self.render_mode = check_render_mode(render_mode)
        self.env = _make(task, 1, action_space=action_space, physics=physics, device=device, seed=seed, **task_overrides)
        self._observe = sp.Observations(self.env, clip_obs)
        self.obs_clip = self._observe.clip
        self.task = task
        self.observation_space = self._observe.space
        self.action_space = sp.action_space(self.env)
        self._actions = Actions(self.env, (1, 1))
        self._shape = self._actions.shape()
        self._td: TensorDict | None = None
        self._ended = False
        self._trail = Trail(self.env) if self.render_mode else None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start an episode; ``seed`` reseeds the env's generator first."""
        self._check_open()
        seed = check_seed(seed)
        super().reset(seed=seed)
        if seed is not None:
            self.env.set_seed(seed)
        self._td = self.env.reset()
        self._ended = False
        if self._trail is not None:
            self._trail.clear()
            self._trail.record(after_step=False)
        return self._observe(self._td.get(OBS)[0, 0]), {}

    def step(self, action):
        self._check_open()
        if self._td is None:
            raise RuntimeError("call reset() before step()")
        if self._ended:
            raise RuntimeError("the episode has ended (terminated or truncated): call reset() before step()")
        self._td.set(ACTION, self._actions.tensor(self._actions.array(action, self._shape)))
        nxt = self.env.step(self._td).get(NEXT)
        self._td = nxt
        terminated, truncated = bool(nxt.get(TERMINATED)), bool(nxt.get(TRUNCATED))
        self._ended = terminated or truncated
        if self._trail is not None:
            self._trail.record(after_step=True, stats=episode_stats(self.env, nxt, 0))
            if self._ended:
                self._trail.end(episode_stats(self.env, nxt, 0))
        info = {STATS_KEY: episode_stats(self.env, nxt, 0)} if self._ended else {}
        return self._observe(nxt.get(OBS)[0, 0]), float(nxt.get(REWARD)), terminated, truncated, info

    def render(self):
        """The video frame of the episode so far ([H, W, 3] uint8), or None without a render mode."""
        self._check_open()
        if self._trail is None:
            return None
        return self._trail.frame(title=self.task)

    def close(self):
        self._closed = True
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
