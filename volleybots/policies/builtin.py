"""The built-in players: ``scripted``, ``receiver`` (1v1), ``random`` and ``hierarchical`` (3v3), by name in ``PLAYERS``.

Each acts for whichever agents the tensordict holds (one team of a match, or every drone), so the same
player serves ``eval scripted``, a cross-play competitor, an ``opponent=`` and a population's seed
member. Add a player by registering a ``Player`` here; ``tests/config/test_registries.py`` holds every entry
to the contract (it builds, acts with actions in the space, and is listed by ``volleybots list``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import torch
from tensordict import TensorDictBase

from volleybots.errors import ConfigError
from volleybots.files import read_yaml_text
from volleybots.keys import ACTION, AGENTS
from volleybots.runs import read_checkpoint

HIERARCHICAL_TASK = "3v3"
HIGH_LEVEL = "high_level"  # the key of a team file's learned high level, beside its drills
RECEIVER_TASK = "1v1"


def acted(policy, td: TensorDictBase) -> TensorDictBase:
    """Call ``policy`` on ``td`` and return the tensordict with ``("agents", "action")`` set (scripted
    players may return the action tensor itself)."""
    out = policy(td)
    if isinstance(out, torch.Tensor):
        td.set(ACTION, out)
        return td
    return td if out is None else out


def random_policy(env) -> Callable[[TensorDictBase], TensorDictBase]:
    """Uniform actions for whichever agents the tensordict holds (one team or all)."""
    acts = env.actions

    def act(td: TensorDictBase) -> TensorDictBase:
        n, a = td.get(AGENTS).batch_size
        if acts.continuous:
            action = torch.rand(n, a, acts.dim, device=td.device) * 2 - 1
        else:
            action = torch.randint(0, acts.n, (n, a), device=td.device)
        td.set(ACTION, action)
        return td

    return act


def scripted_policy(env, action_space: str | None = None) -> Callable[[TensorDictBase], TensorDictBase]:
    """The task's scripted model-based player (``volleybots.scripted``), as a ``td -> td`` policy."""
    from volleybots.scripted import make_scripted_policy

    action_space = action_space or env.action_space_name
    try:
        pol = make_scripted_policy(env, action_space)
    except (ValueError, KeyError) as e:
        raise ConfigError(f"no scripted policy for task {env.name!r} with env.action_space={action_space!r}: {e}") from None
    return lambda td: acted(pol, td)


def receiver_policy(env, action_space: str | None = None) -> Callable[[TensorDictBase], TensorDictBase]:
    """The 1v1 scripted player that also receives deep, flat serves (``volleybots.scripted.receive``)."""
    from volleybots.scripted.receive import OneVsOneReceiver

    action_space = action_space or env.action_space_name
    if env.name != RECEIVER_TASK:
        raise ConfigError(f"the receiver plays task {RECEIVER_TASK} only, not {env.name!r}")
    if action_space not in ("prt", "ctbr"):
        raise ConfigError(f"the receiver acts in env.action_space 'prt' or 'ctbr', not {action_space!r}")
    pol = OneVsOneReceiver(action_space, env.params)
    return lambda td: acted(pol, td)


def learned_drill(name: str, spec, env, deterministic: bool = True):
    """A trained drill policy (checkpoint file or run dir ``spec``) for the hierarchical team of ``env``,
    checked against the drill it claims to play."""
    from volleybots.config import build_env
    from volleybots.policies.store import load_learner, policy_checkpoint

    path = policy_checkpoint(str(spec), f"drill {name!r}:", builtins=())
    state = read_checkpoint(path)
    if "algo" not in state:
        raise ConfigError(f"drill {name!r}: {str(path)!r} is a built-in player, not a trained drill")
    drill_env = build_env(name, num_envs=1, action_space=env.action_space_name)
    for what, theirs, mine in (("task", state.get("task"), name), ("env.action_space", state.get("action_space"), env.action_space_name),
                               ("observation size", state.get("obs_dim"), drill_env.obs_dim)):
        if theirs != mine:
            raise ConfigError(f"drill {name!r}: {str(path)!r} was trained with {what} {theirs!r}, the drill needs {mine!r}")
    return load_learner(path, drill_env)[0].policy(deterministic=deterministic)


def hierarchical_policy(env, drills: dict | None = None) -> Callable[[TensorDictBase], TensorDictBase]:
    """The hierarchical 3v3 team (``volleybots.scripted.hierarchical``): scripted drills, or the
    trained checkpoints of ``drills`` (drill name -> checkpoint file or run dir), under the rules or,
    where ``drills`` names a ``high_level`` file, a learned high level (volleybots/policies/high_level.py),
    which samples its choices as the rules draw the attack's side. **Decision:** trained drills act on
    their mean, also where the competitor is asked for sampled play: a drill is a skill under the
    high level, whose own randomness is the choices (a Pass clone, seed 0, 100 episodes: 0.41 success
    on its mean, 0.24 sampling its Gaussian); the scripted drills are deterministic too."""
    from volleybots.policies.high_level import chooser_from_file
    from volleybots.scripted.hierarchical import DRILLS, make_hierarchical

    drills = dict(drills or {})
    high = drills.pop(HIGH_LEVEL, None)
    unknown = set(drills) - set(DRILLS)
    if unknown:
        raise ConfigError(f"competitor 'hierarchical': unknown drills {sorted(unknown)}; allowed: {', '.join((*DRILLS, HIGH_LEVEL))}")
    chooser = chooser_from_file(high) if high else None
    try:
        return make_hierarchical(env, {k: learned_drill(k, v, env, True) for k, v in drills.items()}, chooser=chooser)
    except ValueError as e:
        raise ConfigError(f"competitor 'hierarchical': {e}") from None


def hierarchical_both_sides(env):
    """The hierarchical team playing both teams of a 3v3 env."""
    from volleybots.tasks.multi import TeamPolicies

    if env.name != HIERARCHICAL_TASK:
        raise ConfigError(f"the hierarchical policy plays task {HIERARCHICAL_TASK} only, not {env.name!r}")
    return TeamPolicies(env, (hierarchical_policy(env), hierarchical_policy(env)))


def read_drills_file(path: Path) -> dict:
    """A hierarchical team's drill checkpoints (and learned high level, key ``high_level``) from a YAML
    file ``hierarchical: {drill: path}`` (relative paths are relative to the file)."""
    import io

    from omegaconf import OmegaConf

    text = read_yaml_text(path, "hierarchical team file")  # bounded: a huge file or a device is one line
    try:
        data = OmegaConf.to_container(OmegaConf.load(io.StringIO(text)), resolve=False)
    except Exception as e:  # noqa: BLE001 - YAML and OmegaConf errors alike: the file is damaged
        raise ConfigError(f"{str(path)!r} is no hierarchical team file ({' '.join(str(e).split())[:160]})") from None
    drills = data.get("hierarchical") if isinstance(data, dict) else None
    if not isinstance(drills, dict) or not all(isinstance(v, str) and v for v in drills.values()):
        raise ConfigError(f"{str(path)!r} is no hierarchical team: expected a mapping 'hierarchical: {{drill: checkpoint}}'")
    from volleybots.scripted.hierarchical import DRILLS

    unknown = sorted(str(k) for k in drills if str(k) not in (*DRILLS, HIGH_LEVEL))
    if unknown:
        raise ConfigError(f"{str(path)!r}: unknown drills {unknown}; allowed: {', '.join((*DRILLS, HIGH_LEVEL))}")
    return {str(k): str((Path(path).parent / v) if not Path(v).is_absolute() else v) for k, v in drills.items()}


@dataclass(frozen=True)
class Player:
    """A built-in player: ``team(env)`` acts for one team (or every drone); ``both(env)`` plays the
    whole env (``eval NAME``); ``task`` None fits every task."""

    name: str
    description: str
    team: Callable
    both: Callable
    task: str | None = None


PLAYERS: dict[str, Player] = {
    p.name: p
    for p in (
        Player("scripted", "the task's scripted model-based player (plans on an exact model of the simulator)",
               lambda env: scripted_policy(env), lambda env: scripted_policy(env)),
        Player("receiver", "1v1 only: the scripted player that also receives deep, flat serves (a teacher for algo=bc)",
               lambda env: receiver_policy(env), lambda env: receiver_policy(env), RECEIVER_TASK),
        Player("random", "uniform random actions", random_policy, random_policy),
        Player("hierarchical", "3v3 only: drills under an event-driven high level (scripted drills, or trained ones from a YAML file)",
               hierarchical_policy, hierarchical_both_sides, HIERARCHICAL_TASK),
    )
}
BUILTIN = tuple(PLAYERS)

__all__ = [
    "BUILTIN", "HIERARCHICAL_TASK", "HIGH_LEVEL", "RECEIVER_TASK", "Player", "acted", "hierarchical_both_sides",
    "hierarchical_policy", "learned_drill", "random_policy", "read_drills_file", "receiver_policy", "scripted_policy",
]
