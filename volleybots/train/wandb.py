"""The optional Weights & Biases mirror of metrics.csv (``logger=wandb``)."""

from __future__ import annotations

import re
from pathlib import Path

from volleybots.config import to_dict
from volleybots.errors import ConfigError


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
