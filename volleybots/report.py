"""Aggregate run directories across seeds: one row per task x algorithm (x variant), learning curves.

``volleybots report DIR...`` finds every run under the given folders (a run directory holds the
``config.yaml`` that ``volleybots train`` writes; a Hydra job folder without one is a job that stopped
before training began) and groups the runs whose configs differ only in their seed and in how they
were run (threads, logging, checkpoints, device). For each group it reports the final evaluation's
task metric across seeds as rliable recommends (Agarwal et al., "Deep RL at the edge of the
statistical precipice", 2021): the mean, the interquartile mean (the mean of the middle 50 %, robust
to one odd seed) and 95 % percentile-bootstrap intervals of both. With fewer than ``FEW_SEEDS`` seeds
a percentile bootstrap can only reach the seeds' own extremes (with 2 or 3 seeds the interval of the
mean is exactly [min, max]), so such a cell carries a warning saying so, with its seed count; every
table says whether its metric improves upwards or downwards (the task's ``metric_higher_is_better``).

The statistics are scipy's (``scipy.stats.trim_mean``, ``scipy.stats.bootstrap``), computed exactly as
rliable computes them for one task; rliable itself pins ``arch<8``, whose releases for Python 3.11 do
not import with pandas 3, so it cannot be a dependency here.

Runs without a result are listed with their state, never dropped: ``running`` (no summary.json and
written to within ``stale_after`` seconds), ``failed`` (a run that stopped without a summary, an
unreadable summary, a final metric that is not finite, or a job that stopped before training) or
``not aggregated`` (a population run, whose result is a payoff table, not one final evaluation).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from volleybots.errors import ConfigError, Range
from volleybots.files import write_atomic, write_json
from volleybots.runs import InUseError, check_writable, lock, make_dir, unlock
from volleybots.runs.found import STALE_AFTER_S, Run, find_runs  # noqa: F401 (also importable from here)

CONFIDENCE = 0.95
RESAMPLES = 10_000  # bootstrap resamples (seeds are few: this costs milliseconds)
BOOTSTRAP_SEED = 0  # the intervals of the same runs are the same every time
FEW_SEEDS = 5  # below this many seeds a bootstrap interval is about the seeds' [min, max]: warned

# config keys that say how a run was executed, not what it trained: runs differing only here are seeds
# of one experiment
RUN_KEYS = ("seed", "threads", "resume", "progress", "logger", "time_limit", "episodes", "deterministic",
            "env.device", "env.compile", "evaluation.every", "evaluation.record")
RUN_SECTIONS = ("wandb.", "checkpoint.")
OUTPUT_FILES = ("report.md", "report.json")


# ------------------------------------------------------------------------------------------ groups
def _flat(d: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flat(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def _experiment(config: dict) -> tuple:
    """What a run trained: its config without the keys of ``RUN_KEYS`` and ``RUN_SECTIONS``."""
    flat = _flat(config)
    return tuple(sorted((k, repr(v)) for k, v in flat.items() if k not in RUN_KEYS and not k.startswith(RUN_SECTIONS)))


def group_runs(runs: list[Run]) -> list[dict]:
    """Complete runs grouped by experiment; each group is labelled by task, algorithm and the config
    keys (its *variant*) that set it apart from the other groups of the same task and algorithm."""
    from volleybots.algos.population import method_name  # a population run is labelled by its method

    groups: dict[tuple, list[Run]] = {}
    for r in runs:
        if r.status == "complete":
            groups.setdefault(_experiment(r.config), []).append(r)
    by_cell: dict[tuple, list[tuple]] = {}
    for key, members in groups.items():
        by_cell.setdefault((members[0].config["task"]["name"], method_name(members[0].config)), []).append(key)
    cells = []
    for (task, algo), keys in sorted(by_cell.items()):
        differ = sorted({k for key in keys for k, v in key if any(dict(other).get(k) != v for other in keys)})
        for key in keys:
            d = dict(key)
            variant = ", ".join(f"{k}={d[k]}" if k in d else f"{k} unset" for k in differ)
            cells.append({"task": task, "algo": algo, "variant": variant, "runs": sorted(groups[key], key=lambda r: r.config["seed"])})
    return sorted(cells, key=lambda c: (c["task"], c["algo"], c["variant"]))


# ------------------------------------------------------------------------------------- statistics
def iqm(x, axis=None):
    """Interquartile mean: the mean of the middle 50 % (rliable's ``aggregate_iqm``)."""
    from scipy.stats import trim_mean

    return trim_mean(x, proportiontocut=0.25, axis=axis)


def interval(values: np.ndarray, statistic) -> tuple[float, float] | None:
    """95 % percentile-bootstrap interval of ``statistic`` over the first axis (seeds), as rliable
    computes it; None for a single seed, which has no spread to resample."""
    from scipy.stats import bootstrap

    values = np.asarray(values, dtype=float)
    if values.shape[0] < 2:
        return None
    res = bootstrap((values,), statistic, n_resamples=RESAMPLES, confidence_level=CONFIDENCE, method="percentile",
                    axis=0, rng=np.random.default_rng(BOOTSTRAP_SEED))
    return res.confidence_interval.low, res.confidence_interval.high


def higher_is_better(task: str, metric: str) -> bool | None:
    """Whether ``task``'s ``metric`` improves upwards (the task's own ``metric_higher_is_better``);
    None for a task or metric this version does not know (a run of an older or newer volleybots)."""
    from volleybots.tasks import TASKS

    cls = TASKS.get(task)
    return cls.metric_higher_is_better if cls is not None and cls.metric == metric else None


def few_seeds_warning(cell: dict) -> str | None:
    """The warning of a cell whose intervals rest on too few seeds to mean much (None: enough, or one
    seed, which has no interval at all)."""
    n = len(cell["seeds"])
    if not 2 <= n < FEW_SEEDS:
        return None
    label = cell["algo"] + (f" ({cell['variant']})" if cell["variant"] else "")
    return (f"{cell['task']} / {label}: only {n} seeds; with fewer than {FEW_SEEDS} the {CONFIDENCE:.0%} bootstrap interval "
            f"is about the seeds' [min, max] ({'exactly' if n <= 3 else 'close to'} it here), not a reliable interval")


def cell_stats(cell: dict) -> dict:
    runs = cell["runs"]
    x = np.array([r.final() for r in runs])
    mean_ci, iqm_ci = interval(x, np.mean), interval(x, iqm)
    metric = runs[0].summary["metric"]
    row = {
        "task": cell["task"], "algo": cell["algo"], "variant": cell["variant"],
        "metric": metric, "higher_is_better": higher_is_better(cell["task"], metric),
        "total_frames": runs[0].config.get("total_frames"),
        "seeds": [r.config["seed"] for r in runs],
        "values": x.tolist(),
        "mean": float(x.mean()), "mean_ci": None if mean_ci is None else [float(v) for v in mean_ci],
        "iqm": float(iqm(x)), "iqm_ci": None if iqm_ci is None else [float(v) for v in iqm_ci],
        "runs": [str(r.path) for r in runs],
    }
    row["warning"] = few_seeds_warning(row)
    return row


def curve_band(runs: list[Run]) -> dict:
    """The evaluation curves of ``runs`` on their common frames (each run interpolated onto the union
    of their evaluation points, within the range all of them cover): mean and bootstrap band."""
    curves = [r.curve() for r in runs]
    curves = [(f, v) for f, v in curves if len(f)]
    if not curves:
        return {"frames": [], "mean": [], "low": [], "high": []}
    lo, hi = max(f[0] for f, _ in curves), min(f[-1] for f, _ in curves)
    grid = np.unique(np.concatenate([f for f, _ in curves]))
    grid = grid[(grid >= lo) & (grid <= hi)]
    if not len(grid):  # no frames that every run evaluated at
        return {"frames": [], "mean": [], "low": [], "high": []}
    y = np.stack([np.interp(grid, f, v) for f, v in curves])
    band = interval(y, np.mean)
    low, high = (y.mean(0), y.mean(0)) if band is None else band
    return {"frames": grid.tolist(), "mean": y.mean(0).tolist(), "low": np.asarray(low).tolist(), "high": np.asarray(high).tolist()}


# ---------------------------------------------------------------------------------------- the report
def build_report(paths, stale_after: float = STALE_AFTER_S, now: float | None = None) -> dict:
    """The report of the runs under ``paths``: per-group statistics and curves, and every run's state."""
    if stale_after not in Range(low=0):  # a NaN age compares false with everything: no run would ever be failed
        raise ConfigError(f"stale_after (--stale-after) is {stale_after!r}; it must be a finite number of seconds >= 0")
    runs = find_runs(paths, stale_after, now)
    cells = group_runs(runs)
    rows = []
    for c in cells:
        row = cell_stats(c)
        row["curve"] = curve_band(c["runs"])
        rows.append(row)
    return {
        "statistics": {"confidence": CONFIDENCE, "bootstrap": "percentile", "resamples": RESAMPLES, "bootstrap_seed": BOOTSTRAP_SEED,
                       "iqm": "mean of the middle 50 % of seeds (scipy.stats.trim_mean, 0.25 cut each side)"},
        "cells": rows,
        "runs": [{"path": str(r.path), "status": r.status, "reason": r.reason, "task": r.config.get("task", {}).get("name"),
                  "algo": r.config.get("algo", {}).get("name"), "seed": r.config.get("seed")} for r in runs],
    }


def _fmt(v: float) -> str:
    return f"{v:.4g}"


def _frames(n: int) -> str:
    """2000000 -> 2M, 1024 -> 1,024: budgets as a sweep names them."""
    return f"{n / 1e6:g}M" if n >= 1e6 and n % 100_000 == 0 else f"{n:,}"


def _direction(higher: bool | None) -> str:
    return "direction unknown" if higher is None else "higher is better" if higher else "lower is better"


def _ci(ci) -> str:
    return "n/a (1 seed)" if ci is None else f"[{_fmt(ci[0])}, {_fmt(ci[1])}]"


def format_markdown(report: dict) -> str:
    """The report as Markdown: one table per task, then the runs that are not counted."""
    lines = ["# Sweep report", ""]
    for task in dict.fromkeys(c["task"] for c in report["cells"]):
        cells = [c for c in report["cells"] if c["task"] == task]
        lines += [f"## {task}: final `{cells[0]['metric']}` across seeds ({_direction(cells[0]['higher_is_better'])})", "",
                  "| algorithm | variant | frames | seeds | mean | 95% CI | IQM | 95% CI |", "|---|---|---|---|---|---|---|---|"]
        for c in cells:
            seeds = ",".join(map(str, c["seeds"]))
            lines.append(f"| {c['algo']} | {c['variant'] or '-'} | {_frames(c['total_frames'])} | {seeds} | {_fmt(c['mean'])} | "
                         f"{_ci(c['mean_ci'])} | {_fmt(c['iqm'])} | {_ci(c['iqm_ci'])} |")
        lines.append("")
        lines += [f"Warning: {c['warning']}." for c in cells if c["warning"]]
        lines += [""] if any(c["warning"] for c in cells) else []
    if not report["cells"]:
        lines += ["No complete run: nothing to aggregate yet.", ""]
    stats = report["statistics"]
    lines += [f"Intervals: {stats['confidence']:.0%} {stats['bootstrap']} bootstrap over seeds ({stats['resamples']} resamples); "
              f"IQM: {stats['iqm']}. Each value is a run's final evaluation (`summary.json`).", ""]
    others = [r for r in report["runs"] if r["status"] != "complete"]
    if others:
        lines += [f"## Runs not counted ({len(others)})", "", "| status | run | why |", "|---|---|---|"]
        lines += [f"| {r['status']} | `{r['path']}` | {r['reason']} |" for r in others]
        lines.append("")
    return "\n".join(lines)


def plot_curves(report: dict, out: Path) -> list[Path]:
    """One PNG per task: each group's evaluation curve (mean over seeds) with its 95 % band."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise ConfigError("report figures need matplotlib: pip install 'volleybots[plot]'") from None
    files = []
    for task in dict.fromkeys(c["task"] for c in report["cells"]):
        cells = [c for c in report["cells"] if c["task"] == task]
        fig, ax = plt.subplots(figsize=(7, 4.2))
        for c in cells:
            cv = c["curve"]
            label = (f"{c['algo']}{' (' + c['variant'] + ')' if c['variant'] else ''}: seeds {','.join(map(str, c['seeds']))}, "
                     f"{_frames(c['total_frames'])} frames")
            (line,) = ax.plot(cv["frames"], cv["mean"], marker="o", ms=3, label=label)
            ax.fill_between(cv["frames"], cv["low"], cv["high"], color=line.get_color(), alpha=0.25, lw=0)
            if len(cv["frames"]) == 1:  # a single evaluation has no band to fill: draw its interval
                m = cv["mean"][0]
                ax.errorbar(cv["frames"], cv["mean"], yerr=[[m - cv["low"][0]], [cv["high"][0] - m]], color=line.get_color(), capsize=4)
        ax.set_xlabel("frames")
        ax.set_ylabel(f"evaluation {cells[0]['metric']}")
        ax.set_title(f"{task}: mean over seeds, {CONFIDENCE:.0%} bootstrap band", fontsize=10)
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
        fig.tight_layout()
        path = out / f"curves_{task}.png"
        try:
            write_atomic(path, lambda fh, fig=fig: fig.savefig(fh, format="png", dpi=120), "the report's curves")
        finally:
            plt.close(fig)
        files.append(path)
    return files


def check_out(out: Path) -> None:
    """Refuse an output folder that already holds a report (reports are never overwritten)."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {str(out)!r} is a file; give a folder")
    check_writable(out, "--out")
    taken = []
    if out.is_dir():
        taken = [p.name for p in out.glob("*") if p.name in OUTPUT_FILES or (p.name.startswith("curves_") and p.suffix == ".png")]
    if taken:
        raise ConfigError(f"--out {str(out)!r} already holds a report ({', '.join(sorted(taken))}); choose another folder")


def write_report(report: dict, out: Path) -> list[Path]:
    """report.md, report.json and curves_<task>.png in ``out``, holding the folder's lock: two
    reports to one folder end with one report and one refusal, never a mix of both."""
    out = Path(out)
    make_dir(out, "--out")
    try:
        lock(out)
    except InUseError:
        raise ConfigError(f"--out {str(out)!r} is being written by another report; choose another folder") from None
    try:
        check_out(out)  # again under the lock: another report may have been first
        files = plot_curves(report, out)
        md = format_markdown(report) + "\n" + "".join(f"![{p.stem}]({p.name})\n" for p in files)
        write_atomic(out / "report.md", md, "the report")
        write_json(out / "report.json", report, "the report", indent=2)
    finally:
        unlock(out)
    return [out / "report.md", out / "report.json", *files]
