"""volleybots: multi-drone volleyball testbed (TorchRL envs, batched torch / MuJoCo physics)."""

from __future__ import annotations

from volleybots.version import __version__


def make_env(
    task: str, num_envs: int = 1, action_space: str = "prt", physics: str = "torch", device="cpu", seed: int = 0, **task_overrides
):
    """Build the TorchRL env of ``task`` with ``num_envs`` worlds batched together (``volleybots.config.build_env``).

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
    from volleybots.config.envs import build_env

    return build_env(task, num_envs, action_space, physics, device, seed, **task_overrides)


__all__ = ["__version__", "make_env"]
