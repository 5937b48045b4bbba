"""volleybots: multi-drone volleyball testbed (TorchRL envs, batched torch / MuJoCo physics)."""

from __future__ import annotations

from volleybots.version import __version__


def make_env(task: str, num_envs: int = 1, action_space: str = "prt", physics: str = "torch", device="cpu", seed: int = 0, **task_overrides):
    """Build the TorchRL env of ``task`` with ``num_envs`` worlds batched together (``volleybots.config.build_env``).

    ``action_space``: "prt" (per-rotor thrust), "ctbr" (collective thrust + body rates) or
    "discrete" (16 rotor on/off actions). ``physics``: a backend of ``volleybots.physics.BACKENDS``.
    Further keywords go to the task (``reward_shaping``, ``substeps``, ``drone``, ``episode_len``, ...);
    ``compile=True`` compiles the whole env step and reset with ``torch.compile`` (static shapes, torch backend).
    """
    from volleybots.config.envs import build_env

    return build_env(task, num_envs, action_space, physics, device, seed, **task_overrides)


__all__ = ["__version__", "make_env"]
