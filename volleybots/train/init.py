"""``init=RUN_OR_CHECKPOINT``: a new run starts from another run's networks.

The actor, and the critic where it fits, are loaded with a fresh optimiser; a resumed run restores its
own checkpoint instead. Everything is checked (``check_init``) before a run directory is written.
"""

from __future__ import annotations

from pathlib import Path

import torch

from volleybots import zoo
from volleybots.algos.base import AgentSpec
from volleybots.config import make_env
from volleybots.errors import ConfigError
from volleybots.play.seats import SelfPlay, default_seat
from volleybots.policies.store import build_learner, learner_class, policy_checkpoint, saved_config, sha256
from volleybots.runs import read_checkpoint


def init_checkpoint(spec: str) -> Path:
    """The checkpoint ``init=`` names: a checkpoint file, a run dir's final (else latest) one, or a zoo entry."""
    path = Path(spec)
    if not path.exists() and not str(spec).startswith(zoo.PREFIX):
        raise ConfigError(f"init={spec!r} is neither a run directory (with config.yaml) nor a checkpoint file")
    return policy_checkpoint(spec, "init=")


def _side(algo: str, task: str, n_drones: int, action_space: str, obs_dim: int) -> str:
    return f"algo {algo}, task {task}, {n_drones} drone(s), env.action_space={action_space}, observation {obs_dim}"


def _shapes(module) -> dict[str, tuple]:
    return {k: tuple(v.shape) for k, v in module.state_dict().items()}


def _first_difference(there: dict, here: dict) -> str | None:
    """The first parameter whose name or shape differs between two parts (None: they fit)."""
    only_there, only_here = sorted(there.keys() - here.keys()), sorted(here.keys() - there.keys())
    if only_there and only_here:
        return f"other networks: {only_there[0]!r} only there, {only_here[0]!r} only here"
    for k in sorted(there.keys() | here.keys()):
        if there.get(k) != here.get(k):
            return f"{k} is {list(there[k]) if k in there else 'absent'} there, {list(here[k]) if k in here else 'absent'} here"
    return None


def apply_init(algo, cfg, spec: AgentSpec) -> dict:
    """Load ``cfg.init``'s actor, and its critic where it fits, into ``algo`` (built for ``spec``); the
    optimiser, counters and random streams stay the new run's. Raises ``ConfigError`` naming both
    sides when the task, drone count, action space, observation or the actor's shapes differ. An
    algorithm whose networks cannot take the source's may keep them another way (``guide_from``:
    SAC from a bc / ppo / mappo run). Returns what was loaded (for summary.json)."""
    from volleybots.algos.base import class_attr
    from volleybots.tasks import TASKS, plays_as

    path = init_checkpoint(cfg.init)
    state = read_checkpoint(path, device=algo.device)
    if "algo" not in state:
        raise ConfigError(f"init={cfg.init!r} is a built-in player ({state.get('builtin')}), not a trained policy")
    src = saved_config(state, f"init={cfg.init!r}")
    here_drones = class_attr(TASKS[cfg.task.name], "n_drones")
    there_drones = class_attr(TASKS[src.task.name], "n_drones")
    here = _side(cfg.algo.name, cfg.task.name, here_drones, cfg.env.action_space, spec.obs_dim)
    there = _side(src.algo.name, src.task.name, there_drones, src.env.action_space, int(state["obs_dim"]))
    what = f"init={cfg.init!r} ({there}) does not fit this run ({here})"
    checks = [("task", plays_as(src.task.name), plays_as(cfg.task.name)), ("drone count", there_drones, here_drones),
              ("action space", src.env.action_space, cfg.env.action_space), ("observation size", int(state["obs_dim"]), spec.obs_dim)]
    if src.task.name != cfg.task.name:  # a drill and its match (tasks.plays_as): one player per drone either way
        checks.pop(1)
    for name, a, b in checks:
        if a != b:
            raise ConfigError(f"{what}: the {name} differs")
    source = build_learner(state, AgentSpec(spec.device, int(state["n_agents"]), int(state["obs_dim"]), spec.actions), f"init={cfg.init!r}")
    parts, src_parts = algo.init_parts(), source.init_parts()
    if "actor" not in parts:
        raise ConfigError(f"algo {cfg.algo.name!r} cannot start from another run (init=)")
    if algo.guide_from(source):  # networks that cannot take the source's: it guides them (sac from a clone)
        skipped = [f"{role} (algo {src.algo.name}'s networks are PPO's: its actor is the guide)" for role in parts]
        return _init_info(path, state, src, ["guide"], skipped)
    loaded, skipped = [], []
    for role, module in parts.items():
        diff = _first_difference(_shapes(src_parts[role]), _shapes(module)) if role in src_parts else f"algo {src.algo.name} has no {role}"
        if diff is None:
            module.load_state_dict(src_parts[role].state_dict())
            loaded.append(role)
        elif role == "actor":
            raise ConfigError(f"{what}: the actor's networks differ ({diff})")
        else:
            skipped.append(f"{role} ({diff})")
    algo.after_init()
    return _init_info(path, state, src, loaded, skipped)


def _init_info(path: Path, state: dict, src, loaded: list[str], skipped: list[str]) -> dict:
    """What ``init=`` loaded, for summary.json and the checkpoints."""
    return {
        "source": str(path), "sha256": sha256(path), "algo": src.algo.name, "frames": int(state["frames"]),
        "loaded": loaded, "skipped": skipped,
    }


def learner_spec(cfg, env) -> AgentSpec:
    """What the learner of ``cfg`` is built for (a population method's learner plays one team)."""
    from volleybots.algos import is_population

    if is_population(cfg):
        return SelfPlay().spec(env)
    return default_seat(cfg).spec(env)


def check_init(cfg) -> None:
    """Raise ``ConfigError`` now, before any run dir is written, when ``cfg.init`` does not fit."""
    if cfg.get("init") is None:
        return
    env = make_env(cfg, num_envs=1)
    spec = learner_spec(cfg, env)
    with torch.random.fork_rng(devices=[]):
        algo = learner_class(cfg.algo)(cfg.algo, spec, seed=cfg.seed)
    apply_init(algo, cfg, spec)


__all__ = ["apply_init", "check_init", "init_checkpoint", "learner_spec"]
