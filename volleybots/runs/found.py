"""The runs under some folders and the state of each, for ``volleybots report``: ``complete``,
``running`` (no summary.json, written to lately), ``failed`` (stopped without a summary, an unreadable
or damaged file: config.yaml, summary.json, metrics.csv) or ``not aggregated`` (a population run).

Every file is read through ``volleybots.files.read_text`` (bounded, regular files only; YAML through
``read_yaml_text``, which refuses aliases), so a run dir received from elsewhere, with a config.yaml
that is a folder, a link to ``/dev/zero`` or an alias bomb, is listed as failed, saying why, never
read whole or mistaken for a running job.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from volleybots.errors import ConfigError
from volleybots.files import Fields, read_json, read_yaml_text
from volleybots.runs.metrics import read_metrics
from volleybots.runs.rundir import RunDir, config_problem

STALE_AFTER_S = 1800.0  # a run without summary.json untouched this long is counted as failed


@dataclass
class Run:
    """One run directory (or Hydra job folder) and what it holds."""

    path: Path
    status: str  # complete | running | failed | not aggregated
    reason: str = ""  # why it is not complete
    config: dict = field(default_factory=dict)
    summary: dict | None = None

    def final(self) -> float:
        """The final evaluation's mean of the task metric."""
        return float(self.summary["final_eval"]["stats"][self.summary["metric"]]["mean"])

    def curve(self) -> tuple[np.ndarray, np.ndarray]:
        """(frames, metric) of the run's evaluations (the periodic ones and the final one)."""
        col = f"eval_{self.summary['metric']}"
        rows = [r for r in read_metrics(RunDir(self.path).metrics_path) if r.get("phase") == "eval" and isinstance(r.get(col), float)]
        return np.array([r["frames"] for r in rows]), np.array([r[col] for r in rows])


# ------------------------------------------------------------------------------------ finding runs
def find_runs(paths, stale_after: float = STALE_AFTER_S, now: float | None = None) -> list[Run]:
    """Every run under ``paths`` (run directories or folders holding them), each with its state."""
    now = time.time() if now is None else now
    found: dict[Path, Run] = {}
    for p in map(Path, paths):
        if not p.exists():
            raise ConfigError(f"{str(p)!r} does not exist; give run directories or folders that hold them (a sweep's multirun/... folder)")
        for d in _run_dirs(p):
            found.setdefault(d.resolve(), _read_run(d, stale_after, now))
    if not found:
        raise ConfigError(f"no run directories under {', '.join(map(str, paths))} "
                          "(a run directory holds the config.yaml that `volleybots train` writes)")
    return sorted(found.values(), key=lambda r: str(r.path))


def _run_dirs(root: Path):
    """Folders with a run's config.yaml, and Hydra job folders (``.hydra/``) that have none."""
    cands = [root] if root.is_dir() else []
    cands += [p.parent for p in root.rglob("config.yaml") if p.parent.name != ".hydra"]
    cands += [p.parent.parent for p in root.rglob(".hydra/overrides.yaml")]
    for d in dict.fromkeys(cands):
        if "wandb" in d.relative_to(root).parts:
            continue  # wandb's own run folders hold a config.yaml too
        if _is_run_config(d / "config.yaml") or (d / ".hydra").is_dir():
            yield d


def _is_run_config(path: Path) -> bool:
    try:
        cfg = yaml.safe_load(read_yaml_text(path, "config.yaml"))
    except (ConfigError, yaml.YAMLError):
        return path.exists()  # an unreadable config.yaml (binary, a folder, a device) is a broken run, reported as failed
    return isinstance(cfg, dict) and {"task", "algo", "seed"} <= set(cfg)


def _read_run(d: Path, stale_after: float, now: float) -> Run:
    run = RunDir(d)
    if not run.config_path.exists():
        overrides = _hydra_overrides(d)
        return _unfinished(Run(d, "running"), d, stale_after, now,
                           f"no config.yaml: the job stopped before training began (overrides: {overrides})")
    try:
        config = yaml.safe_load(read_yaml_text(run.config_path, "config.yaml"))
    except ConfigError as e:
        return Run(d, "failed", f"config.yaml unreadable ({' '.join(str(e).split())[:160]})")
    except yaml.YAMLError as e:
        return Run(d, "failed", f"config.yaml unreadable ({type(e).__name__})")
    bad = config_problem(config)
    if bad:  # a hand-edited config.yaml: listed as failed, never grouped with the runs it would break
        return Run(d, "failed", f"config.yaml invalid ({bad})")
    if not run.summary_path.is_file():
        total = config.get("total_frames", "?")
        hint = f"; `volleybots train resume={d}` continues it" if any(run.ckpt_dir.glob("*.pt")) else ""
        return _unfinished(Run(d, "running", config=config), d, stale_after, now,
                           f"no summary.json: stopped (killed or crashed) at {_frames_reached(run)} of {total} frames{hint}")
    try:
        summary = read_json(run.summary_path, "run summary")
        if "final_eval" not in summary and "population" in summary:
            return Run(d, "not aggregated", "a population run: no final evaluation to average (its payoffs: population/payoffs.json)",
                       config, summary)
        value = float(summary["final_eval"]["stats"][summary["metric"]]["mean"])
        Fields(summary, "summary.json").count("frames", optional=True)  # compared with total_frames below
    except (ValueError, KeyError, TypeError, AttributeError) as e:  # a ConfigError is a ValueError
        return Run(d, "failed", f"summary.json unreadable ({type(e).__name__}: {' '.join(str(e).split())[:160]})", config)
    if not config.get("time_limit") and summary.get("frames", 0) < config.get("total_frames", 0):
        # `train resume=DIR total_frames=N` rewrote config.yaml; summary.json is that of the earlier budget
        return _unfinished(Run(d, "running", config=config), d, stale_after, now,
                           f"resumed to {config['total_frames']} frames but stopped (killed or crashed) at {_frames_reached(run)}; "
                           f"summary.json is of the first {summary['frames']}")
    if not math.isfinite(value):
        return Run(d, "failed", f"final {summary['metric']} is {value} (training diverged)", config, summary)
    try:
        Run(d, "complete", "", config, summary).curve()  # its learning curve is read too: a damaged metrics.csv is listed
    except ConfigError as e:
        return Run(d, "failed", f"metrics.csv unreadable ({' '.join(str(e).split())[:160]})", config, summary)
    return Run(d, "complete", "", config, summary)


def _unfinished(run: Run, d: Path, stale_after: float, now: float, failed_reason: str) -> Run:
    """A run with no result: still running if written to lately, else failed."""
    age = now - max(p.stat().st_mtime for p in [d, *d.rglob("*")])
    if age < stale_after:
        run.status, run.reason = "running", f"in progress at {_frames_reached(RunDir(d))} frames (last written {age:.0f} s ago)"
    else:
        run.status, run.reason = "failed", f"{failed_reason}; last written {_age(age)} ago"
    return run


def _frames_reached(run: RunDir) -> int:
    if not run.metrics_path.is_file():
        return 0
    try:
        rows = read_metrics(run.metrics_path)
        return int(rows[-1]["frames"]) if rows else 0
    except (ConfigError, ValueError, TypeError):  # damaged: how far it got is unknown
        return 0


def _hydra_overrides(d: Path) -> str:
    try:
        return " ".join(map(str, yaml.safe_load(read_yaml_text(d / ".hydra" / "overrides.yaml", "overrides.yaml")) or [])) or "none"
    except (ConfigError, yaml.YAMLError, TypeError):
        return "unknown"


def _age(seconds: float) -> str:
    for unit, size in (("d", 86400), ("h", 3600), ("min", 60)):
        if seconds >= size:
            return f"{seconds / size:.1f} {unit}"
    return f"{seconds:.0f} s"


__all__ = ["STALE_AFTER_S", "Run", "find_runs"]
