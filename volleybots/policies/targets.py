"""Targets: one policy playing a whole env (``eval TARGET``, ``replay TARGET``, ``eval compare``), and the
pre-flight check of the files a config names.

A target is a run directory (its final or latest checkpoint), a checkpoint file, or a built-in player
(``scripted``, ``random``, and for 3v3 ``hierarchical`` on both sides); see ``store.parse_spec``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from volleybots.algos.population import CLONE, TRAIN, method_name
from volleybots.errors import ConfigError
from volleybots.policies.builtin import BUILTIN, PLAYERS
from volleybots.policies.store import load_learner, parse_single, policy_checkpoint
from volleybots.runs import RunDir, is_population_run, read_checkpoint, refuse_interpolation

# keys of a checkpoint's config that evaluation may change; the rest fix what the policy was trained on.
# The episode limit and Solo Bump's start curriculum are in no observation, so a run trained on short
# episodes or far starts plays the task's own.
EVAL_KEYS = ("episodes", "deterministic", "seed", "progress", "threads", "env.device", "env.physics", "env.compile", "env.num_envs",
             "task.episode_len", "task.far_starts")


@dataclass
class Target:
    label: str  # what plays, for tables and file names
    cfg: object  # the validated config of the env it plays in
    checkpoint: Path | None  # the checkpoint file, for trained policies
    make_policy: Callable  # env -> (td -> td)


def resolve_target(target: str, overrides=()) -> Target:
    """Turn an eval/replay target and its overrides into a config and a policy factory."""
    from volleybots.config import load

    s = parse_single(target, "target")  # a mixture is refused as one, not as a file that does not exist
    if s.label:
        raise ConfigError(f"target {target!r}: a label (NAME=) is for competitors of a match; name the run or checkpoint alone")
    if s.kind == "builtin":
        cfg = load(list(overrides))
        return Target(s.target, cfg, None, PLAYERS[s.target].both)
    if s.kind == "drills":
        raise ConfigError(f"target {target!r} is a hierarchical team file: it plays a match (eval crossplay, replay A B)")
    if s.kind == "run" and is_population_run(s.path):
        return population_target(s.path, overrides)
    ckpt = policy_checkpoint(target, "target")
    state = read_checkpoint(ckpt)
    if "algo" not in state:
        if state.get("builtin") == "hierarchical":  # a hierarchical population member: the team on both sides
            return both_sides(str(ckpt), RunDir(Path(ckpt).parent.parent).load_config(), overrides, f"member {str(ckpt)!r}")
        raise ConfigError(f"{str(ckpt)!r} is a built-in player ({state.get('builtin')}): evaluate it by name")
    from volleybots.config import apply_overrides

    refuse_interpolation(state.get("config") or {}, f"checkpoint {str(ckpt)!r}")
    cfg = apply_overrides(state["config"], overrides, EVAL_KEYS, f"checkpoint {str(ckpt)!r}")

    def make_policy(env):
        # built for the agents it learned for (a team's learner acts for every drone alike: its actor is per drone)
        algo, _ = load_learner(ckpt, env, int(state.get("n_agents", env.n_drones)), cfg, "its config")
        return algo.policy(deterministic=cfg.deterministic)

    return Target(f"{method_name(cfg)}@{int(state['frames'])}", cfg, Path(ckpt), make_policy)


def population_target(path: Path, overrides=()) -> Target:
    """A population run as a target: its final meta-strategy on both teams (a member drawn per team and
    episode), as ``eval crossplay RUN`` plays it; a member file (``RUN/population/member_<k>.pt``) names one."""
    return both_sides(str(path), RunDir(path).load_config(), overrides, f"run {str(path)!r}")


def both_sides(spec: str, saved, overrides, what: str) -> Target:
    """The competitor ``spec`` playing both teams of the match config ``saved`` (with eval ``overrides``)."""
    import torch

    from volleybots.config import apply_overrides, to_dict
    from volleybots.policies.competitors import resolve_competitor
    from volleybots.tasks.multi import TeamPolicies

    comp = resolve_competitor(spec)
    data = saved if isinstance(saved, dict) else to_dict(saved)
    cfg = apply_overrides(data, overrides, EVAL_KEYS, what)
    parts = [f"{m.label} {w:.2f}" for m, w in zip(comp.members, comp.mixture) if w > 0]
    label = comp.label if len(comp.members) == 1 else f"{comp.label} (mixture: {', '.join(parts)})"

    def make_policy(env):
        gen = torch.Generator().manual_seed(int(cfg.seed))
        return TeamPolicies(env, tuple(comp.team_policy(env, bool(cfg.deterministic), gen) for _ in range(2)))

    return Target(label, cfg, None, make_policy)


def check_references(cfg) -> None:
    """Open and check the files a config names, before a run starts (``validate`` opens none):
    ``opponent=`` and ``population.seed_members`` must be competitors made for the run's task, action space
    and observation (``bc`` in ``seed_members`` names the clone the run makes itself),
    ``population.eval_opponent`` a built-in player of the task, and ``population.payoff_pool=ray`` (or ``oracle_pool``) needs ray
    installed. ``init=`` is checked by ``volleybots.train.check_init``, which builds the networks."""
    from volleybots.algos.base import class_attr
    from volleybots.policies.competitors import resolve_competitor, single_policy
    from volleybots.tasks import TASKS

    task_cls = TASKS[cfg.task.name]
    obs_dim = class_attr(task_cls, "obs_dim_prt") - (4 if cfg.env.action_space == "ctbr" else 0)
    if cfg.get("opponent") is not None:
        resolve_competitor(cfg.opponent).check_fits(task_cls.name, cfg.env.action_space, obs_dim)
    pop = cfg.get("population") or {}  # a population's loop keys (volleybots.algos.population_of)
    yardstick = pop.get("eval_opponent")
    if yardstick is not None:
        if yardstick not in PLAYERS:
            raise ConfigError(f"unknown population.eval_opponent {yardstick!r}; allowed: {', '.join(PLAYERS)}")
        fits = PLAYERS[yardstick].task
        if fits is not None and fits != task_cls.name:
            raise ConfigError(f"population.eval_opponent={yardstick!r} plays task {fits!r} only, not {task_cls.name!r}; allowed here: "
                              f"{', '.join(n for n, p in PLAYERS.items() if p.task in (None, task_cls.name))}")
    for key in ("payoff_pool", "oracle_pool"):
        if pop.get(key) == "ray":
            import importlib.util

            if importlib.util.find_spec("ray") is None:
                raise ConfigError(f"population.{key}=ray needs the ray package: pip install 'volleybots[cluster]' "
                                  f"(or use population.{key}=serial)")
    for spec in pop.get("seed_members") or ():
        if str(spec) in (CLONE, TRAIN):  # the run's own clone, or its stage-I drills: made by the run
            continue
        single_policy(str(spec), "population.seed_members entry").check_fits(task_cls.name, cfg.env.action_space, obs_dim)


__all__ = ["BUILTIN", "EVAL_KEYS", "Target", "check_references", "resolve_target"]
