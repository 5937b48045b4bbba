"""Environments from keywords (``volleybots.make_env``) and from a validated config."""

from __future__ import annotations

from volleybots.config.schema import check_env_args, to_dict
from volleybots.errors import ConfigError


def build_env(
    task: str, num_envs: int = 1, action_space: str = "prt", physics: str = "torch", device="cpu", seed: int = 0, **task_overrides
):
    """Build the TorchRL env of ``task`` with ``num_envs`` worlds batched together.

    Args:
        task: a name of ``volleybots.tasks.TASKS``.
        num_envs: worlds simulated together.
        action_space: "prt" (per-rotor thrust), "ctbr" (collective thrust + body rates) or "discrete"
            (16 rotor on/off actions).
        physics: a backend of ``volleybots.physics.BACKENDS``.
        device: the torch device of the env's tensors.
        seed: the env's random stream.
        **task_overrides: further task keywords (``reward_shaping``, ``substeps``, ``drone``,
            ``episode_len``, ...); ``compile=True`` compiles the whole env step and reset with
            ``torch.compile`` (static shapes, torch backend); ``group_map="teams"`` lays a match out
            with one TorchRL group per team and agent-level flags (``volleybots.tasks.groups``).

    Returns:
        The task's ``VolleyEnv`` (with ``group_map="teams"``, a ``TeamGroups`` over it). Raises ``ValueError`` naming a bad name or value.
    """
    from volleybots.physics import ACTION_SPACES, BACKENDS
    from volleybots.tasks import TASKS
    from volleybots.tasks.groups import GROUP_MAPS, TeamGroups

    check_env_args(num_envs=num_envs, seed=seed, **task_overrides)  # a ValueError naming the key
    if task not in TASKS:
        raise ValueError(f"unknown task {task!r}; allowed: {sorted(TASKS)}")
    if action_space not in ACTION_SPACES:
        raise ValueError(f"unknown action_space {action_space!r}; allowed: {list(ACTION_SPACES)}")
    if physics not in BACKENDS:
        raise ValueError(f"unknown physics {physics!r}; allowed: {list(BACKENDS)}")
    _check_switches(TASKS[task], task_overrides)
    # TorchRL's EnvBase metaclass consumes a ``compile`` keyword itself (compiling the whole step,
    # generically): route ours to the env's own static-shape step and reset instead.
    if "compile" in task_overrides:
        task_overrides["compile_physics"] = task_overrides.pop("compile")
    group_map = task_overrides.pop("group_map", GROUP_MAPS[0])  # the env's own layout unless asked
    if group_map not in GROUP_MAPS:
        raise ValueError(f"unknown group_map {group_map!r}; allowed: {list(GROUP_MAPS)}")
    if group_map == "teams" and not TASKS[task].competitive:
        raise ValueError(f"group_map='teams' needs a match; task {task!r} has one team (allowed: "
                         f"{[n for n, c in TASKS.items() if c.competitive]})")
    env = TASKS[task](num_envs=num_envs, action_space=action_space, physics=physics, device=device, seed=seed, **task_overrides)
    return TeamGroups(env) if group_map == "teams" else env


def _check_switches(task_cls, overrides: dict) -> None:
    """Refuse a non-bool for a keyword whose default is a bool in the task's constructors (``opening``,
    ``compile``): the task would read ``bool("no")``, which is True."""
    import inspect

    for klass in task_cls.__mro__:
        init = klass.__dict__.get("__init__")
        if init is None:
            continue
        for p in inspect.signature(init).parameters.values():
            v = overrides.get(p.name)
            if isinstance(p.default, bool) and p.name in overrides and not isinstance(v, bool):
                raise ConfigError(f"bad value for {p.name!r}: {v!r} (must be True or False)")


def task_kwargs(cfg) -> dict:
    """The task's constructor keywords of a validated config (everything of ``task`` but its name)."""
    return {k: v for k, v in to_dict(cfg.task).items() if k != "name"}


def make_env(cfg, num_envs: int | None = None, seed: int | None = None):
    """Build the env a validated config describes (``num_envs`` / ``seed`` override the config's).

    Also applies ``threads`` (torch's CPU threads), which must be set before any work."""
    import torch


    if cfg.threads and torch.get_num_threads() != cfg.threads:
        torch.set_num_threads(cfg.threads)

    e = cfg.env
    return build_env(
        cfg.task.name,
        num_envs=e.num_envs if num_envs is None else num_envs,
        action_space=e.action_space,
        physics=e.physics,
        device=e.device,
        seed=cfg.seed if seed is None else seed,
        substeps=e.substeps,
        drone=e.drone,
        ball_drag=e.ball_drag,
        downwash=e.downwash,
        compile=e.compile,
        **task_kwargs(cfg),
    )


