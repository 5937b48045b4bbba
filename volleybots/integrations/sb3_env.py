"""A Stable-Baselines3 ``VecEnv`` over the batched env: one batched torch step for all worlds.

SB3's own vector envs (``DummyVecEnv``, ``SubprocVecEnv``) hold one single env per world, so each
world pays a whole torch step for itself; ``VolleySB3VecEnv`` steps every world of a single-drone
task in one call of the batched env (through ``VolleyVectorEnv``, whose checks and numbers it
shares) and speaks SB3's API: ``reset() -> obs``, ``step(actions) -> (obs, rewards, dones, infos)``
with one info dict per world.

The worlds reset within the step that ends them (SB3's convention): a done world's row of the
returned observation is its next episode's first one, its last observation is in
``infos[i]["terminal_observation"]``, ``infos[i]["TimeLimit.truncated"]`` says the episode was cut
by its length (for bootstrapping), and ``infos[i]["final_stats"]`` holds the task's statistics
(return, length, metric, reward terms). ``infos[i]["episode"]`` is left to SB3's ``VecMonitor``,
which logs ``rollout/ep_rew_mean``: wrap it as ``VecMonitor(VolleySB3VecEnv(...))``.

PPO. ``ppo_kwargs(num_envs)`` gives SB3's ``PPO`` keywords that suit many worlds (each rollout in 4
minibatches, Adam's foreach update): with SB3's small default minibatches the gradient updates cost
more than collecting (docs/integrations.md has the figures of ``benchmarks/speed/sb3_vecenv.py``).

Seeds. The worlds share one generator, so ``seed(s)`` (what ``PPO(seed=s)`` calls) seeds all of them
with ``s`` at the next ``reset()``, as ``VolleyVectorEnv.reset(seed=s)`` does.
"""

from __future__ import annotations

from typing import Any

import numpy as np

try:
    from stable_baselines3.common.vec_env import VecEnv
except ImportError:  # the message names the extra: a bare "No module named stable_baselines3" does not
    raise ImportError("volleybots.integrations.VolleySB3VecEnv needs stable-baselines3: pip install 'volleybots[sb3]'") from None

from volleybots.integrations.gym_env import VolleyVectorEnv
from volleybots.integrations.spaces import STATS_KEY, check_seed


def ppo_kwargs(num_envs: int, n_steps: int = 128, minibatches: int = 4) -> dict[str, Any]:
    """Keywords for SB3's ``PPO`` on ``num_envs`` batched worlds (docs/integrations.md, measured with
    ``benchmarks/speed/sb3_vecenv.py``): ``n_steps`` per world, each rollout of ``num_envs * n_steps`` split
    into ``minibatches`` minibatches (SB3's default 64-sample minibatches, or 256, make the gradient
    updates cost more than collecting), Adam with its foreach update and SB3's own ``eps`` (SB3 drops
    that default when ``optimizer_kwargs`` is given). SB3's other defaults stand (10 epochs, ...)."""
    for key, n in (("num_envs", num_envs), ("n_steps", n_steps), ("minibatches", minibatches)):
        if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or n < 1:  # SB3 takes 0 and -5 as given
            raise ValueError(f"{key} must be an integer >= 1, got {n!r}")
    rollout = num_envs * n_steps
    if minibatches < 1 or rollout % minibatches:
        raise ValueError(f"minibatches must divide the rollout of {num_envs} x {n_steps} = {rollout} samples, got {minibatches!r}")
    return {"n_steps": n_steps, "batch_size": rollout // minibatches,
            "policy_kwargs": {"optimizer_kwargs": {"eps": 1e-5, "foreach": True}}}


class _BatchedVecEnv(VecEnv):
    """SB3's ``VecEnv`` over one of the Gymnasium vector envs here (``self.venv``, same-step autoreset,
    with ``step32``): its rows are SB3's envs, stepped in one batched call."""

    def __init__(self, venv):
        self.venv = venv
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        # SB3's VecVideoRecorder asks for "rgb_array" and records render(), which tiles get_images()
        self.render_mode = venv.render_mode
        self._actions = None

    # ------------------------------------------------------------------ stepping
    def reset(self) -> np.ndarray:
        seed = self._seeds[0]
        obs, _ = self.venv.reset(seed=seed)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in range(self.num_envs)]
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        if self._actions is None:
            raise RuntimeError("step_wait() without step_async(actions)")
        actions, self._actions = self._actions, None
        obs, reward, term, trunc, info = self.venv.step32(actions)
        dones = term | trunc
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        if info:  # some world ended: only its rows' dicts are filled
            stats, final = info[STATS_KEY], info["final_obs"]
            for i in np.flatnonzero(dones).tolist():
                infos[i] = {
                    "terminal_observation": final[i],
                    "TimeLimit.truncated": bool(trunc[i] and not term[i]),
                    STATS_KEY: {k: float(v[i]) for k, v in stats.items()},
                }
        return obs, reward, dones, infos

    def seed(self, seed: int | None = None) -> list[int | None]:
        """Seed every world with ``seed`` at the next ``reset()`` (the worlds share one generator)."""
        if seed is None:  # as SB3 does: a fresh seed rather than none
            seed = int(np.random.randint(0, np.iinfo(np.uint32).max, dtype=np.uint32))
        self._seeds = [check_seed(seed)] * self.num_envs
        return list(self._seeds)

    def close(self) -> None:
        self.venv.close()

    # ------------------------------------------------------------------ SB3's attribute plumbing
    def _count(self, indices) -> int:
        return len(list(self._get_indices(indices)))

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        """The batched env's attribute, once per world asked for (the worlds are one env)."""
        return [getattr(self.venv, attr_name)] * self._count(indices)

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        if indices is not None and self._count(indices) != self.num_envs:
            raise ValueError(f"set_attr({attr_name!r}) sets all worlds at once (they are one env); got indices {indices!r}")
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        """Calls the batched env's method once; its result is repeated for each world asked for."""
        result = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result] * self._count(indices)

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False] * self._count(indices)  # the worlds are no gymnasium.Env: nothing wraps them

    def get_images(self) -> list[np.ndarray]:
        """The first world's video frame, as a list of one (SB3's ``render()`` tiles the list into one
        image: here that frame). One world only: a frame costs milliseconds, all worlds a frame each."""
        frames = self.venv.render()
        if frames is None:
            raise ValueError(f"{type(self).__name__} was made without render_mode='rgb_array': it has no frames to give")
        return list(frames)


class VolleySB3VecEnv(_BatchedVecEnv):
    """``num_envs`` worlds of a single-drone task as one Stable-Baselines3 ``VecEnv``.

    Args: as for ``VolleyVectorEnv`` (``task``, ``num_envs``, ``action_space``, ``physics``,
    ``device``, ``seed``, ``clip_obs``, ``render_mode`` and the task's overrides); the autoreset is SB3's
    (same step). With ``render_mode="rgb_array"``, ``render()`` gives the first world's video frame and
    SB3's ``VecVideoRecorder`` records it.
    """

    def __init__(self, task: str = "solo_bump", num_envs: int = 8, action_space: str = "prt", physics: str = "torch",
                 device="cpu", seed: int = 0, render_mode: str | None = None, **task_overrides):
        super().__init__(VolleyVectorEnv(task, num_envs, action_space=action_space, physics=physics, device=device, seed=seed,
                                         render_mode=render_mode, autoreset_mode="same_step", **task_overrides))
