"""Paired comparison of policies on the same episodes (``volleybots eval compare``).

Two policies evaluated on the same seed start their episodes from the same states (``run_episodes``
scores the first episode of every env, and a reset's random numbers do not depend on the policy).
So their per-episode metrics pair up, and the difference of each pair removes what the start
contributes: on Hover the start decides most of an episode's mean distance (the standard deviation
over episodes is 0.15 m), while the teacher and its clone differ by 0.005 m, which two unpaired means
cannot resolve and the paired differences resolve (95 % interval [-0.0070, -0.0035] m). Every target after the first is
compared with the first (the baseline); the first observations are checked to be identical, so a
pair that did not play the same episodes is refused rather than compared.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from scipy import stats

from volleybots.config.args import OVERRIDE_KEYS, split_args
from volleybots.errors import ConfigError
from volleybots.eval import play
from volleybots.files import exists
from volleybots.keys import OBS
from volleybots.overrides import split_arg
from volleybots.policies import BUILTIN as POLICY_NAMES
from volleybots.policies import EVAL_KEYS, resolve_target


@dataclass
class Paired:
    """``other`` against ``base`` on the same episodes; ``diff`` > 0 means ``other`` is better."""

    diff: float  # mean improvement (metric units, signed so that > 0 is better)
    se: float  # its standard error over episodes
    low: float  # 95 % t-interval of the mean improvement
    high: float
    wins: int  # episodes where other is better, level, worse
    ties: int
    losses: int
    rank_biserial: float  # (R+ - R-) / (R+ + R-) over the non-zero differences: the effect's direction and size
    p: float  # Wilcoxon signed-rank, two-sided (1.0 when every episode ties)

    @property
    def verdict(self) -> str:
        """About the mean, the metric's figure: better or worse when the 95 % interval excludes 0.
        The Wilcoxon test asks another question (is the typical episode better?), and on Solo Bump
        the answers differ: a clone wins 46 episodes by a bump and loses 7 by thirteen (an opening
        missed), so it is better in the typical episode (p < 1e-6) and level on the mean."""
        return "better" if self.low > 0 else "worse" if self.high < 0 else "level"

    def to_dict(self) -> dict:
        return {**self.__dict__, "verdict": self.verdict}


def paired(base, other, higher_is_better: bool = True) -> Paired:
    """Compare per-episode metrics ``other`` with ``base`` (same length, same episodes).

    Every metric must be finite: a nan difference is neither > 0 nor < 0 nor 0, so it would be
    counted as none of better, level and worse while turning the mean and its interval into nan;
    an episode whose metric is not a number is refused (``ConfigError``) rather than compared."""
    base, other = np.asarray(base, dtype=np.float64), np.asarray(other, dtype=np.float64)
    if base.shape != other.shape or base.ndim != 1 or base.size < 2:
        raise ConfigError(f"paired metrics need two vectors of the same length >= 2, got {base.shape} and {other.shape}")
    for which, m in (("baseline", base), ("other", other)):
        check_finite(m, which)
    d = (other - base) * (1.0 if higher_is_better else -1.0)
    n = d.size
    mean, se = float(d.mean()), float(d.std(ddof=1) / math.sqrt(n))
    half = float(stats.t.ppf(0.975, n - 1)) * se
    nz = d[d != 0]
    if nz.size:
        ranks = stats.rankdata(np.abs(nz))
        plus, minus = float(ranks[nz > 0].sum()), float(ranks[nz < 0].sum())
        r = (plus - minus) / (plus + minus)
        p = float(stats.wilcoxon(nz).pvalue) if nz.size > 1 else 1.0
    else:
        r, p = 0.0, 1.0
    return Paired(mean, se, mean - half, mean + half, int((d > 0).sum()), int((d == 0).sum()), int((d < 0).sum()), r, p)


def check_finite(metric: np.ndarray, who: str, name: str = "metric") -> None:
    """Refuse per-episode values that are nan or infinite, naming the episodes."""
    bad = np.flatnonzero(~np.isfinite(metric))
    if bad.size:
        shown = ", ".join(map(str, bad[:5].tolist())) + (f" and {bad.size - 5} more" if bad.size > 5 else "")
        raise ConfigError(f"{who}'s {name} is not a finite number in {bad.size} of {metric.size} episodes (episode {shown}); "
                          "a nan episode cannot be paired, so nothing is compared")


# compare's key=value words are config overrides of every target: what an evaluation may change
# (EVAL_KEYS), and for built-in players the task and env they play (task=, task.KEY=, env.KEY=)
OVERRIDES = tuple(dict.fromkeys((*EVAL_KEYS, *OVERRIDE_KEYS)))


def split(args) -> tuple[list[str], list[str]]:
    """Targets and overrides (``key=value``) of a command line, in order, read by the verbs' one
    grammar (``volleybots.config.args``)."""
    targets, _, overrides = split_args(args, None, OVERRIDES)
    for t in targets:
        key, value = split_arg(t)
        # a path whose name holds '=' (an existing run dir or checkpoint) is a target; any other key=value is a typo
        if value is not None and not exists(t):
            raise ConfigError(f"{t!r}: eval compare has no option {key!r} (and no run or checkpoint has that name); "
                              "options: " + ", ".join(k for k in OVERRIDES if "." not in k) + ", task.KEY=, env.KEY=")
    if len(targets) < 2:
        raise ConfigError(f"eval compare needs a baseline and at least one target to compare with it, got {targets or 'none'}")
    return targets, overrides


def _resolve(targets: list[str], overrides: list[str]):
    """Trained targets first; a built-in player (scripted, random) plays their task and action space
    unless the command line names them."""
    trained = {t: resolve_target(t, overrides) for t in targets if t not in POLICY_NAMES}
    named = {split_arg(o)[0] for o in overrides}
    implied = []
    if trained:
        first = next(iter(trained.values())).cfg
        implied = [f"{k}={v}" for k, v in (("task", first.task.name), ("env.action_space", first.env.action_space)) if k not in named]
    return [trained[t] if t in trained else resolve_target(t, [*implied, *overrides]) for t in targets]


def _play(target, episodes: int | None):
    """The env, the per-episode statistics of ``target`` and the first observation it saw."""
    first = []

    def watch(env, td, next_td):
        if not first:
            first.append(td[OBS].clone())

    with torch.no_grad():
        env, res = play(target, episodes, on_step=watch)
    return env, res, first[0]


def compare(args, episodes: int | None = None) -> dict:
    """``volleybots eval compare``: play every target on the same episodes; compare each with the first.

    Args:
        args: the command's words: targets (run dirs, checkpoints, ``scripted``, ``random``) and
            ``key=value`` overrides (``seed=``, ``task=``, ...) applied to every target.
        episodes: episodes per target; ``None`` uses the config's ``episodes``.

    Returns:
        A JSON-ready dict: ``task``, ``metric``, ``higher_is_better``, ``episodes``, ``seed``,
        ``baseline`` and ``targets``, one row per target (mean, std, per-episode metric, and for all
        but the first ``vs_baseline``: the paired difference, its 95 % interval and Wilcoxon's test).

    Raises:
        ConfigError: targets of different tasks, or targets that did not play the same episodes.
    """
    names, overrides = split(args)
    targets = _resolve(names, overrides)
    tasks = {t.cfg.task.name for t in targets}
    if len(tasks) > 1:
        each = ", ".join(f"{n} ({t.cfg.task.name})" for n, t in zip(names, targets))
        raise ConfigError(f"eval compare plays one task, but the targets are of {sorted(tasks)}: {each}")
    for name, t in zip(names, targets):
        n = int(episodes or t.cfg.episodes)
        if n < 2:
            # before any episode is played: the t-interval of the mean difference needs two of them
            raise ConfigError(
                f"episodes={n} for {name!r}: eval compare needs episodes >= 2 (the 95 % interval of a paired difference needs two episodes)"
            )
    rows, base, base_obs = [], None, None
    for name, t in zip(names, targets):
        env, res, obs = _play(t, episodes)
        metric = res[env.metric].double().cpu().numpy()
        check_finite(metric, repr(name), env.metric)
        if base is None:
            base, base_obs = metric, obs
        elif obs.shape != base_obs.shape or not torch.equal(obs, base_obs):
            raise ConfigError(f"{name!r} did not play the episodes {names[0]!r} played (its first observations differ: another seed, "
                              "episode count, task option or action space); compare targets on the same episodes only")
        row = {"target": name, "label": t.label, "checkpoint": str(t.checkpoint) if t.checkpoint else None, "mean": float(metric.mean()),
               "std": float(metric.std()), "per_episode": metric.tolist()}
        if len(rows):
            row["vs_baseline"] = paired(base, metric, env.metric_higher_is_better).to_dict()
        rows.append(row)
    cfg = targets[0].cfg
    return {"task": cfg.task.name, "metric": env.metric, "higher_is_better": env.metric_higher_is_better, "episodes": int(base.size),
            "seed": int(cfg.seed), "deterministic": bool(cfg.deterministic), "baseline": names[0], "targets": rows}


def format_table(result: dict):
    """A rich table: each target's metric, and its paired difference from the baseline."""
    from rich.table import Table

    way = "higher" if result["higher_is_better"] else "lower"
    table = Table(
        caption="better by: mean paired improvement +- its standard error; W/T/L: episodes better, level, worse; "
        "p: Wilcoxon signed-rank",
        title=f"{result['task']}: {result['metric']} ({way} is better), {result['episodes']} paired episodes, seed {result['seed']}",
    )
    for col in ("target", "mean", "std", "better by", "95% CI", "W/T/L", "p", "verdict"):
        table.add_column(col, justify="left" if col in ("target", "verdict") else "right")
    for row in result["targets"]:
        c = row.get("vs_baseline")
        cells = ["-"] * 4 + ["baseline"] if c is None else [f"{c['diff']:+.3g} +- {c['se']:.1g}", f"[{c['low']:+.3g}, {c['high']:+.3g}]",
                                                     f"{c['wins']}/{c['ties']}/{c['losses']}", f"{c['p']:.2g}", c["verdict"]]
        table.add_row(row["target"], f"{row['mean']:.4g}", f"{row['std']:.3g}", *cells)
    return table
