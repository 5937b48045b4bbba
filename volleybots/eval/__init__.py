"""The evaluation verbs: ``evaluate`` (here), ``compare``, ``crossplay``, ``exploitability`` and ``ranking`` (docs/evaluation.md).

A *target* is what plays (``volleybots.policies.targets``): a run directory (its final or latest
checkpoint), a checkpoint file, ``scripted``, ``random`` or, for 3v3, ``hierarchical`` (both sides).
``evaluate`` plays E episodes, one per env of a batch of E worlds, and reports the task metric's mean
and standard deviation with every per-term return.
"""

from __future__ import annotations

import hashlib
import math
from collections import Counter

from volleybots.config import check_memory, make_env, to_dict
from volleybots.play.episodes import run_episodes, summarize
from volleybots.policies.targets import EVAL_KEYS, Target, resolve_target
from volleybots.rules import Referee
from volleybots.runs import memory_errors_as

# a match's per-episode codes: names, not quantities (a mean winner of -0.25 says nothing), so they are
# counted by name; -1 is "none": no winner (a draw) / no fault (a crash, teammates too close, the time limit)
CODES = {
    "winner": ("won by", {0: "team0", 1: "team1", -1: "draw"}),
    "reason": ("ended by", {**dict(enumerate(Referee.FAULTS)), -1: "none"}),
    "serve_team": ("served by", {0: "team0", 1: "team1"}),
}
NONE_TEXT = "no fault: a draw (a crash, teammates too close, or the episode's time limit)"


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
    out["outcomes"] = outcome_counts(res)
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


def outcome_counts(res: dict) -> dict[str, dict[str, int]]:
    """How many episodes each named code counts (``{"winner": {"team0": 3, "draw": 1}, "reason": {"landed": 3,
    "none": 1}, ...}``), in the order of ``CODES``; empty for a task that is no match. An unknown code
    (a task of another version) is named ``code N``, not dropped."""
    out = {}
    for key, (_, names) in CODES.items():
        if key in res:
            counts = Counter(int(c) for c in res[key].round().long().tolist())
            order = [c for c in names if counts[c]] + sorted(c for c in counts if c not in names)
            out[key] = {names.get(c, f"code {c}"): counts[c] for c in order}
    return out


def format_table(result: dict):
    """A rich table of an ``evaluate`` result: the metric first, then the other statistics; a match's
    codes (``CODES``) as named counts below it, with a legend of the faults that ended its rallies."""
    from rich.console import Group
    from rich.table import Table

    title = f"{result['target']} on {result['task']} ({result['action_space']}), {result['episodes']} episodes"
    table = Table(title=title)
    table.add_column("statistic")
    table.add_column("mean", justify="right")
    table.add_column("std", justify="right")
    outcomes = result.get("outcomes") or {}
    for k, v in result["stats"].items():
        if k in outcomes:  # counted by name below
            continue
        name = f"{k} (metric)" if k == result["metric"] else k
        table.add_row(name, _num(v["mean"]), _num(v["std"]))
    if not outcomes:
        return table
    counts = Table(title=f"outcomes (episodes of {result['episodes']})", show_header=False)
    counts.add_column("")
    counts.add_column("")
    for key, named in outcomes.items():
        counts.add_row(CODES[key][0], ", ".join(f"{name} {n}" for name, n in named.items()))
    return Group(table, counts, *legend(outcomes.get("reason", {})))


def legend(reasons: dict) -> list[str]:
    """One line per fault named in ``reasons`` (the "ended by" counts): what it means."""
    text = {**Referee.FAULT_TEXT, "none": NONE_TEXT}
    return [f"  {name}: {text[name]}" for name in reasons if name in text]


def _num(x: float) -> str:
    return "nan" if math.isnan(x) else f"{x:.4g}"


__all__ = ["CODES", "EVAL_KEYS", "evaluate", "format_table", "legend", "outcome_counts", "play"]
