"""volleybots: multi-drone volleyball testbed (TorchRL envs, batched torch / MuJoCo physics)."""

from __future__ import annotations

__version__ = "0.1.0"


def make_env(task: str, num_envs: int = 1, action_space: str = "prt", physics: str = "torch", device="cpu", seed: int = 0, **task_overrides):
    """Build the TorchRL env of ``task`` with ``num_envs`` worlds batched together.

    Args:
        task: a registered task name (``volleybots.tasks.TASKS``), e.g. "hover", "solo_bump", "3v3".
        num_envs: worlds stepped together in one batch.
        action_space: "prt" (per-rotor thrust), "ctbr" (collective thrust + body rates) or
            "discrete" (16 rotor on/off actions).
        physics: a backend of ``volleybots.physics.BACKENDS`` ("torch" or "mujoco").
        device: the torch device of the state and of every tensor the env returns.
        seed: seeds the env's random numbers (resets, noise); the same seed replays the same episodes.
        **task_overrides: keywords of the task's constructor (``reward_shaping``, ``substeps``, ``drone``,
            ``episode_len``, ...); ``compile=True`` compiles the whole env step and reset with
            ``torch.compile`` (static shapes, torch backend).

    Returns:
        The task's env (a TorchRL ``EnvBase``): per-drone data under ``("agents", ...)`` with batch
        ``(num_envs, n_agents)``, ``done`` / ``terminated`` / ``truncated`` shared, per-episode
        statistics under ``("stats", name)``.

    Raises:
        ValueError: an unknown task, action space or backend, or a task keyword out of its range,
            named with the allowed values.
    """
    from volleybots.config import check_env_args
    from volleybots.physics import ACTION_SPACES, BACKENDS
    from volleybots.tasks import TASKS

    check_env_args(num_envs=num_envs, seed=seed, **task_overrides)  # a ValueError naming the key
    if task not in TASKS:
        raise ValueError(f"unknown task {task!r}; allowed: {sorted(TASKS)}")
    if action_space not in ACTION_SPACES:
        raise ValueError(f"unknown action_space {action_space!r}; allowed: {list(ACTION_SPACES)}")
    if physics not in BACKENDS:
        raise ValueError(f"unknown physics {physics!r}; allowed: {list(BACKENDS)}")
    # TorchRL's EnvBase metaclass consumes a ``compile`` keyword itself (compiling the whole step,
    # generically): route ours to the env's own static-shape step and reset instead.
    if "compile" in task_overrides:
        task_overrides["compile_physics"] = task_overrides.pop("compile")
    return TASKS[task](num_envs=num_envs, action_space=action_space, physics=physics, device=device, seed=seed, **task_overrides)


__all__ = ["__version__", "make_env"]
