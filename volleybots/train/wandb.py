"""The optional Weights & Biases mirror of a run (``logger=wandb``).

What a W&B run holds: the config, every row of metrics.csv as history (the step is the frame count),
summary.json and the final evaluation in its summary, and with ``wandb.artifacts=true`` the
checkpoints (final.pt, best.pt) and the rerun recordings as artifacts.

Identity: the run id is a hash of the run directory's absolute path and the moment the run started,
kept in ``<run dir>/wandb_run.json``. Runs of different sweeps (whose job folders are both ``0``,
``1``, ...) therefore never share an id, while ``train resume=DIR`` reads the file back and continues
the same W&B run. The group is ``wandb.group``, else the sweep directory's name for a job of a ``-m``
sweep (kept in the same file, as a resume runs outside the sweep); the name is ``<task>_<algo>_s<seed>``.
"""

from __future__ import annotations

import hashlib
import re
import time
from pathlib import Path

from volleybots.config import to_dict
from volleybots.errors import ConfigError
from volleybots.files import read_json, write_json
from volleybots.runs import RunDir, note

IDENTITY_FILE = "wandb_run.json"
_DATE = re.compile(r"\d{4}-\d{2}-\d{2}")  # the date folder of Hydra's default sweep dir
_RUN_ID = re.compile(r"[A-Za-z0-9_-]{1,64}")  # what W&B accepts as a run id


def sweep_group(run_dir: Path) -> str | None:
    """The group of ``run_dir`` when it is the job of a ``-m`` sweep running now: the sweep directory's
    name (with the date folder in front for the time-stamped default, so sweeps started at the same
    time on two days stay apart); None otherwise. Hydra keeps its state after a sweep ends, so a later
    run in the same process (the Python API) counts only if it is the sweep's job directory."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    if not HydraConfig.initialized():
        return None
    hc = HydraConfig.get()
    if hc.mode != RunMode.MULTIRUN or Path(str(hc.runtime.output_dir)).resolve() != Path(run_dir).resolve():
        return None
    sweep = Path(str(hc.sweep.dir))
    return f"{sweep.parent.name}_{sweep.name}" if _DATE.fullmatch(sweep.parent.name) else sweep.name


def run_identity(run_dir: Path, resume: bool) -> dict:
    """The id and derived group of the W&B run of ``run_dir``: read back when the run continues, made
    afresh (and saved) when it starts."""
    path = Path(run_dir) / IDENTITY_FILE
    if resume and path.is_file():
        try:
            saved = read_json(path, "W&B identity file")
        except ConfigError:
            saved = None
        # the id names W&B's folders under the run dir: only W&B's own characters, never a path ("../x")
        if isinstance(saved, dict) and isinstance(saved.get("id"), str) and _RUN_ID.fullmatch(saved["id"]) \
                and isinstance(saved.get("group"), (str, type(None))):
            return saved
        note(f"{path} is damaged (its id is not a W&B run id of letters, digits, '-' and '_'): the resumed run starts a new W&B run")
    created = time.time_ns()
    identity = {
        "id": hashlib.sha256(f"{Path(run_dir).resolve()}\n{created}".encode()).hexdigest()[:16],
        "group": sweep_group(run_dir),
        "created_ns": created,
    }
    write_json(path, identity, "the W&B identity")
    return identity


def run_name(cfg) -> str:
    from volleybots.algos import method_name

    return f"{cfg.task.name}_{method_name(cfg)}_s{cfg.seed}"


def run_tags(cfg) -> list[str]:
    """The task, method (a population's, else the algorithm), action space and physics backend, then
    ``wandb.tags`` (each once, in order)."""
    from volleybots.algos import method_name

    tags = [cfg.task.name, method_name(cfg), cfg.env.action_space, cfg.env.physics, *cfg.wandb.tags]
    return list(dict.fromkeys(str(t) for t in tags))


def summary_fields(summary: dict) -> dict:
    """summary.json for the W&B summary, its final evaluation flattened to ``final_eval_<stat>`` and
    ``final_eval_<stat>_std`` (the task metric and the return among them) so that runs compare by them."""
    out = {k: v for k, v in summary.items() if k != "final_eval"}
    final = summary.get("final_eval")
    if final:
        out["final_eval_episodes"] = final["episodes"]
        for stat, v in final["stats"].items():
            out[f"final_eval_{stat}"] = v["mean"]
            out[f"final_eval_{stat}_std"] = v["std"]
    return out


class WandbLogger:
    """The W&B run of one run directory; offline unless ``wandb.mode=online``. ``resume``: the run
    continues (a resume, or a population's later iteration), so it keeps its saved identity."""

    def __init__(self, cfg, run_dir: Path, resume: bool):
        try:
            import wandb
        except ImportError:
            raise ConfigError("logger=wandb needs the wandb package: pip install 'volleybots[wandb]'") from None
        identity = run_identity(run_dir, resume)
        self.cfg, self.id = cfg, identity["id"]
        try:
            self.run = self._init(wandb, cfg, run_dir, identity, resume)
        except wandb.errors.Error as e:  # a refused key, an unreachable server, a setting W&B will not take
            raise ConfigError(f"W&B could not start the run ({type(e).__name__}: {' '.join(str(e).split())[:200]}); "
                              "check wandb.* and the WANDB_* environment, or use wandb.mode=offline") from None

    def _init(self, wandb, cfg, run_dir, identity, resume):
        return wandb.init(
            project=cfg.wandb.project,
            mode=cfg.wandb.mode,
            dir=str(run_dir),
            config=to_dict(cfg),
            id=self.id,
            name=run_name(cfg),
            group=cfg.wandb.group or identity.get("group"),
            tags=run_tags(cfg),
            job_type="train",
            resume="allow" if resume else None,
        )

    def log(self, row: dict) -> None:
        self.run.log({k: v for k, v in row.items() if isinstance(v, (int, float))}, step=int(row["frames"]))

    def finish(self, summary: dict, run: RunDir) -> None:
        """End the W&B run: summary.json into its summary, then (``wandb.artifacts``) the artifacts."""
        self.run.summary.update(summary_fields(summary))
        if self.cfg.wandb.artifacts:
            self._log_artifacts(summary, run)
        self.close()

    def _log_artifacts(self, summary: dict, run: RunDir) -> None:
        """``model-<id>`` (final.pt, best.pt) and ``recordings-<id>`` (the run's .rrd files); a resumed
        run that ends again adds a new version of each."""
        import wandb

        meta = {k: summary[k] for k in ("task", "algo", "action_space", "seed", "frames") if k in summary}
        aliases = ["latest", f"frames_{summary.get('frames', 0)}"]
        for name, kind, files in (
            (f"model-{self.id}", "model", [p for p in (run.final_path, run.best_path) if p.is_file()]),
            (f"recordings-{self.id}", "recording", sorted(run.path.glob("*.rrd"))),
        ):
            if not files:
                continue
            artifact = wandb.Artifact(name, type=kind, metadata=meta)
            for p in files:
                artifact.add_file(str(p), name=p.name)
            self.run.log_artifact(artifact, aliases=aliases)

    def close(self) -> None:
        self.run.finish()
