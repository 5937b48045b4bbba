"""Evaluation of single-agent and cooperative policies (spec: evaluation.md, last section).

A *target* is what plays: a run directory (its final or latest checkpoint), a checkpoint file,
``scripted`` (``volleybots.scripted.make_scripted_policy``), ``random`` (uniform actions) or, for 3v3,
``hierarchical`` (the hierarchical team on both sides).
``evaluate`` plays E episodes, one per env of a batch of E worlds, and reports the task metric's mean
and standard deviation with every per-term return.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import torch
from torchrl.envs.utils import step_mdp

from volleybots.competitors import scripted_policy
from volleybots.config import apply_overrides, check_memory, load, make_env, to_dict
from volleybots.errors import ConfigError
from volleybots.runs import RunDir, load_algo_state, memory_errors_as, read_checkpoint

POLICY_NAMES = ("scripted", "random", "hierarchical")  # hierarchical: 3v3, the hierarchical team on both sides
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


def stat_keys(env) -> list[str]:
    return list(env.observation_spec["stats"].keys())


def run_episodes(env, policy, on_step=None) -> dict[str, torch.Tensor]:
    """Play until every env of the batch has finished one episode; return the statistics of those
    first episodes ([num_envs] per statistic). ``on_step(env, td, next_td)`` sees every step before
    the finished envs are reset (the recorder uses it)."""
    keys = stat_keys(env)
    n = env.num_envs
    finished = torch.zeros(n, dtype=torch.bool, device=env.device)
    out = {k: torch.zeros(n, device=env.device) for k in keys}
    td = env.reset()
    # a task may end episodes by itself, but never later than its time limit
    for _ in range(env.episode_len + 1):
        td = policy(td)
        td = env.step(td)
        nxt = td["next"]
        if on_step is not None:
            on_step(env, td, nxt)
        new = nxt["done"].reshape(n) & ~finished
        for k in keys:
            out[k] = torch.where(new, nxt["stats", k].reshape(n), out[k])
        finished |= new
        if bool(finished.all()):
            break
        td = env.maybe_reset(step_mdp(td, keep_other=True, exclude_action=True))
    return out


def summarize(results: dict[str, torch.Tensor], metric: str) -> dict:
    """Mean and standard deviation of every statistic; the task metric first."""
    table = {}
    for k in [metric, *[k for k in results if k != metric]]:
        v = results[k].double()
        table[k] = {"mean": float(v.mean()), "std": float(v.std(unbiased=False)) if v.numel() > 1 else 0.0}
    return {"metric": metric, "episodes": int(next(iter(results.values())).numel()), "stats": table}


def resolve_target(target: str, overrides=()) -> Target:
    """Turn an eval/replay target and its overrides into a config and a policy factory."""
    if target in POLICY_NAMES:
        cfg = load(list(overrides))
        if target == "random":
            return Target("random", cfg, None, lambda env: (lambda td: env.rand_action(td)))
        if target == "hierarchical":
            return Target("hierarchical", cfg, None, lambda env: hierarchical_both_sides(env))
        return Target("scripted", cfg, None, lambda env: scripted_policy(env, cfg.env.action_space))
    path = Path(target)
    if path.is_dir():
        run = RunDir(path)
        if not run.is_run():
            raise ConfigError(f"{target!r} is not a run directory (no config.yaml) nor a checkpoint file")
        ckpt = run.policy_checkpoint(f"run {target!r}")
    elif path.is_file():
        ckpt = path
    else:
        raise ConfigError(f"unknown target {target!r}; expected a run directory, a checkpoint file, or one of: {', '.join(POLICY_NAMES)}")
    state = read_checkpoint(ckpt)
    cfg = apply_overrides(state["config"], overrides, EVAL_KEYS, f"checkpoint {str(ckpt)!r}")

    def make_policy(env):
        from volleybots.algos import ALGOS
        from volleybots.algos.base import AgentSpec

        algo_cls = ALGOS[cfg.algo.name]
        algo_cls = getattr(algo_cls, "learner_cls", algo_cls)  # a population method's learner
        # built for the agents it learned for (a team's learner acts for every drone alike: its actor is per drone)
        algo = algo_cls(cfg.algo, AgentSpec.of(env, int(state.get("n_agents", env.n_drones))), seed=cfg.seed)
        load_algo_state(algo, state, f"checkpoint {str(ckpt)!r}", cfg, side="its config")
        return algo.policy(deterministic=cfg.deterministic)

    return Target(f"{cfg.algo.name}@{int(state['frames'])}", cfg, Path(ckpt), make_policy)


def hierarchical_both_sides(env):
    """The hierarchical team (``competitors.hierarchical_policy``) playing both teams of a 3v3 env."""
    from volleybots.competitors import hierarchical_policy
    from volleybots.tasks.multi import TeamPolicies

    if env.name != "3v3":
        raise ConfigError(f"the hierarchical policy plays task 3v3 only, not {env.name!r}")
    return TeamPolicies(env, (hierarchical_policy(env), hierarchical_policy(env)))


def play(t: Target, episodes: int | None = None, on_step=None):
    """The env and the per-episode statistics of ``episodes`` (default: the config's) played by ``t``."""
    n = int(episodes or t.cfg.episodes)
    check_memory(t.cfg, worlds=n)
    with memory_errors_as(f"episodes={n}"):
        env = make_env(t.cfg, num_envs=n, seed=t.cfg.seed)
        return env, run_episodes(env, t.make_policy(env), on_step)


def evaluate(target: str, overrides=(), episodes: int | None = None) -> dict:
    """Play ``episodes`` (default: the config's ``episodes``) and summarise them."""
    t = resolve_target(target, overrides)
    env, res = play(t, episodes)
    out = summarize(res, env.metric)
    out.update(
        target=t.label,
        task=t.cfg.task.name,
        action_space=t.cfg.env.action_space,
        checkpoint=str(t.checkpoint) if t.checkpoint else None,
        checkpoint_sha256=hashlib.sha256(t.checkpoint.read_bytes()).hexdigest() if t.checkpoint else None,
        deterministic=bool(t.cfg.deterministic),
        seed=int(t.cfg.seed),
        config=to_dict(t.cfg),
    )
    return out


def format_table(result: dict):
    """A rich table of an ``evaluate`` result: the metric first, then the other statistics."""
    from rich.table import Table

    title = f"{result['target']} on {result['task']} ({result['action_space']}), {result['episodes']} episodes"
    table = Table(title=title)
    table.add_column("statistic")
    table.add_column("mean", justify="right")
    table.add_column("std", justify="right")
    for k, v in result["stats"].items():
        name = f"{k} (metric)" if k == result["metric"] else k
        table.add_row(name, _num(v["mean"]), _num(v["std"]))
    return table


def _num(x: float) -> str:
    return "nan" if math.isnan(x) else f"{x:.4g}"


__all__ = ["Target", "evaluate", "format_table", "play", "resolve_target", "run_episodes", "summarize"]
