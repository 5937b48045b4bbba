"""The evaluation verbs: ``evaluate`` (here), ``compare``, ``crossplay``, ``exploitability`` and ``ranking`` (docs/evaluation.md).

A *target* is what plays (``volleybots.policies.targets``): a run directory (its final or latest
checkpoint), a checkpoint file, ``scripted``, ``random`` or, for 3v3, ``hierarchical`` (both sides).
``evaluate`` plays E episodes, one per env of a batch of E worlds, and reports the task metric's mean
and standard deviation with every per-term return.
"""

from __future__ import annotations

import hashlib
import math

from volleybots.config import check_memory, make_env, to_dict
from volleybots.play.episodes import run_episodes, summarize
from volleybots.policies.targets import EVAL_KEYS, Target, resolve_target
from volleybots.runs import memory_errors_as


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


__all__ = ["EVAL_KEYS", "evaluate", "format_table", "play"]
