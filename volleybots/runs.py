"""The run directory: resolved config, metrics.csv, checkpoints, summary.json, recordings.

Layout of a run::

    config.yaml            the resolved, validated config (what `train resume=` and `eval` read)
    metrics.csv            one row per training batch, plus rows of the periodic evaluations
    checkpoints/           ckpt_<frames>.pt (the last `checkpoint.keep`) and final.pt
    summary.json           frames, wall time, final evaluation, checkpoints
    curves.rrd             the training curves as a rerun recording (rebuilt from metrics.csv)
    eval_<frames>.rrd      one recorded evaluation episode per periodic evaluation
    .hydra/                Hydra's own record of the overrides (when started by `volleybots train`)

Checkpoints hold tensors, numbers, strings and plain containers only, so that
``torch.load(path, weights_only=True)`` reads them.
"""

from __future__ import annotations

import csv
import json
import math
import os
import re
from pathlib import Path

import torch
from omegaconf import OmegaConf

from volleybots.config import ConfigError, to_dict, validate

CKPT_FORMAT = 1
_CKPT = re.compile(r"ckpt_(\d+)\.pt$")


class RunDir:
    def __init__(self, path):
        self.path = Path(path)

    config_path = property(lambda self: self.path / "config.yaml")
    metrics_path = property(lambda self: self.path / "metrics.csv")
    summary_path = property(lambda self: self.path / "summary.json")
    curves_path = property(lambda self: self.path / "curves.rrd")
    ckpt_dir = property(lambda self: self.path / "checkpoints")
    final_path = property(lambda self: self.ckpt_dir / "final.pt")

    def is_run(self) -> bool:
        return self.config_path.is_file()

    def has_results(self) -> bool:
        """Whether a run already wrote here (starting another one would overwrite it)."""
        return any(p.exists() for p in (self.config_path, self.metrics_path, self.ckpt_dir, self.summary_path))

    def create(self, cfg) -> None:
        if self.has_results():
            raise ConfigError(f"{self.path} already holds a run; choose another hydra.run.dir or continue it with resume={self.path}")
        self.path.mkdir(parents=True, exist_ok=True)
        self.config_path.write_text(OmegaConf.to_yaml(OmegaConf.create(to_dict(cfg))))

    def load_config(self):
        if not self.is_run():
            raise ConfigError(f"{self.path} is not a run directory (no config.yaml)")
        return validate(OmegaConf.to_container(OmegaConf.load(self.config_path), resolve=True))

    # ---------------------------------------------------------------------------- checkpoints
    def periodic_checkpoints(self) -> list[Path]:
        found = [(int(m.group(1)), p) for p in self.ckpt_dir.glob("ckpt_*.pt") if (m := _CKPT.search(p.name))]
        return [p for _, p in sorted(found)]

    def latest_checkpoint(self) -> Path | None:
        """The checkpoint with the most frames (final.pt included)."""
        cands = self.periodic_checkpoints()
        if self.final_path.is_file():
            cands.append(self.final_path)
        if not cands:
            return None
        return max(cands, key=lambda p: read_checkpoint(p)["frames"])

    def policy_checkpoint(self, what: str) -> Path:
        """The checkpoint that stands for the run's policy: final.pt, else the latest; ``what`` names
        the run in the error when there is none."""
        ckpt = self.final_path if self.final_path.is_file() else self.latest_checkpoint()
        if ckpt is None:
            raise ConfigError(f"{what} has no checkpoint yet (checkpoints/ is empty)")
        return ckpt

    def save_checkpoint(self, state: dict, final: bool = False, keep: int = 3) -> Path:
        self.ckpt_dir.mkdir(parents=True, exist_ok=True)
        path = self.final_path if final else self.ckpt_dir / f"ckpt_{state['frames']:012d}.pt"
        tmp = path.with_suffix(".tmp")
        torch.save(state, tmp)
        os.replace(tmp, path)  # a run killed while writing leaves the previous checkpoint intact
        if not final:
            for old in self.periodic_checkpoints()[:-keep]:
                old.unlink()
        return path

    def write_summary(self, summary: dict) -> None:
        self.summary_path.write_text(json.dumps(summary, indent=2, default=float) + "\n")


def read_checkpoint(path, device="cpu") -> dict:
    """Load a checkpoint written by ``RunDir.save_checkpoint`` (``weights_only=True``)."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"checkpoint {str(path)!r} does not exist")
    try:
        state = torch.load(path, map_location=device, weights_only=True)
    except Exception as e:  # noqa: BLE001 - any unreadable file is the same user error
        raise ConfigError(f"{str(path)!r} is not a volleybots checkpoint ({type(e).__name__})") from None
    if not isinstance(state, dict) or state.get("format") != CKPT_FORMAT:
        raise ConfigError(f"{str(path)!r} is not a volleybots checkpoint (format {CKPT_FORMAT} expected)")
    return state


def _to_device(state, device):
    if isinstance(state, torch.Tensor):
        # random generator states (uint8) stay on the CPU
        return state if state.dtype == torch.uint8 else state.to(device)
    if isinstance(state, dict):
        return {k: _to_device(v, device) for k, v in state.items()}
    if isinstance(state, list):
        return [_to_device(v, device) for v in state]
    return state


def load_algo_state(algo, state: dict, what: str, cfg) -> None:
    """Load a checkpoint's algorithm state into ``algo``; a mismatch is a user error naming ``what``."""
    try:
        algo.load_state_dict(_to_device(state["algo"], algo.device))
    except (RuntimeError, KeyError, ValueError) as e:
        raise ConfigError(f"{what} does not match algo {cfg.algo.name!r} on task {cfg.task.name!r}: {str(e).splitlines()[0]}") from None


class MetricsLog:
    """metrics.csv: the header is the first row's keys; a resumed run drops the rows after its checkpoint."""

    def __init__(self, path: Path, keep_until_frames: int | None = None):
        self.path = Path(path)
        self.fields: list[str] | None = None
        if keep_until_frames is not None and self.path.is_file():
            with self.path.open(newline="") as f:
                reader = csv.DictReader(f)
                self.fields = list(reader.fieldnames or [])
                rows = [r for r in reader if float(r["frames"]) <= keep_until_frames]
            with self.path.open("w", newline="") as f:
                w = csv.DictWriter(f, self.fields)
                w.writeheader()
                w.writerows(rows)

    def write(self, row: dict) -> None:
        new = self.fields is None
        if new:
            self.fields = list(row)
        with self.path.open("a" if not new else "x", newline="") as f:
            w = csv.DictWriter(f, self.fields, extrasaction="ignore")
            if new:
                w.writeheader()
            w.writerow({k: _fmt(row.get(k)) for k in self.fields})


def _fmt(v):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    if isinstance(v, float):
        return f"{v:.6g}"
    return v


def read_metrics(path) -> list[dict[str, float | str]]:
    out = []
    with Path(path).open(newline="") as f:
        for r in csv.DictReader(f):
            out.append({k: (float(v) if _is_number(v) else v) for k, v in r.items()})
    return out


def _is_number(v: str) -> bool:
    try:
        float(v)
    except (TypeError, ValueError):
        return False
    return True


def write_curves(metrics_csv, out_path) -> None:
    """The training curves of metrics.csv as a rerun recording: one time series per numeric column,
    on a ``frames`` timeline (rebuilt whole, so it is always complete and a resumed run needs no merge)."""
    import rerun as rr

    from volleybots.replay import recording

    rows = read_metrics(metrics_csv)
    with recording(Path(out_path), "volleybots_curves") as rec:
        for r in rows:
            rec.set_time("frames", sequence=int(r["frames"]))
            phase = r.get("phase", "train") or "train"
            for k, v in r.items():
                if k in ("frames", "phase") or not isinstance(v, float) or math.isnan(v):
                    continue
                rec.log(f"{phase}/{k}", rr.Scalars(v))


class WandbLogger:
    """Optional Weights & Biases mirror of metrics.csv; offline unless ``wandb.mode=online``."""

    def __init__(self, cfg, run_dir: Path, resume: bool):
        try:
            import wandb
        except ImportError:
            raise ConfigError("logger=wandb needs the wandb package: pip install 'volleybots[wandb]'") from None
        self.run = wandb.init(
            project=cfg.wandb.project,
            mode=cfg.wandb.mode,
            dir=str(run_dir),
            config=to_dict(cfg),
            name=run_dir.name,
            id=re.sub(r"[^A-Za-z0-9_-]", "_", run_dir.name),
            resume="allow" if resume else None,
        )

    def log(self, row: dict) -> None:
        self.run.log({k: v for k, v in row.items() if isinstance(v, (int, float))}, step=int(row["frames"]))

    def close(self) -> None:
        self.run.finish()
