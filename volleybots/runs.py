"""The run directory: resolved config, metrics.csv, checkpoints, summary.json, recordings.

Layout of a run::

    config.yaml            the resolved, validated config (what `train resume=` and `eval` read)
    metrics.csv            one row per training batch, plus rows of the periodic evaluations
    checkpoints/           ckpt_<frames>.pt (the last `checkpoint.keep`), final.pt and best.pt (the
                           policy at the best evaluation; for `eval` and `init=`, never resumed from)
    summary.json           frames, wall time, final evaluation, checkpoints
    curves.rrd             the training curves as a rerun recording (rebuilt from metrics.csv)
    eval_<frames>.rrd      one recorded evaluation episode per periodic evaluation
    .hydra/                Hydra's own record of the overrides (when started by `volleybots train`)
    .lock                  locked (``fcntl.flock``) by the process training in the directory

A directory is used by one process at a time: the one holding the lock on ``.lock``. The operating
system drops the lock when that process ends, however it ends, so a killed run never leaves its
directory stuck. A directory whose run wrote no checkpoint (killed or crashed early) holds nothing
worth keeping: a new run or ``resume=`` starts it afresh.

Checkpoints hold tensors, numbers, strings and plain containers only, so that
``torch.load(path, weights_only=True)`` reads them.
"""

from __future__ import annotations

import contextlib
import csv
import itertools
import json
import math
import os
import re
import socket
import sys
from pathlib import Path

import torch
from omegaconf import OmegaConf

from volleybots.config import to_dict, validate
from volleybots.errors import ConfigError

try:
    import fcntl
except ImportError:  # not on Windows: run directories are then not locked
    fcntl = None

CKPT_FORMAT = 1
_CKPT = re.compile(r"ckpt_(\d+)\.pt$")
LOCK_NAME = ".lock"


class RunDir:
    def __init__(self, path):
        self.path = Path(path)

    config_path = property(lambda self: self.path / "config.yaml")
    metrics_path = property(lambda self: self.path / "metrics.csv")
    summary_path = property(lambda self: self.path / "summary.json")
    curves_path = property(lambda self: self.path / "curves.rrd")
    ckpt_dir = property(lambda self: self.path / "checkpoints")
    final_path = property(lambda self: self.ckpt_dir / "final.pt")
    best_path = property(lambda self: self.ckpt_dir / "best.pt")

    def is_run(self) -> bool:
        return self.config_path.is_file()

    def has_results(self) -> bool:
        """Whether a run already wrote here (starting another one would overwrite it)."""
        return any(p.exists() for p in (self.config_path, self.metrics_path, self.ckpt_dir, self.summary_path))

    def has_checkpoint(self) -> bool:
        return bool(self.periodic_checkpoints()) or self.final_path.is_file()

    def checkpoint_stamp(self) -> tuple:
        """The checkpoints' names and modification times: a change means another process trained here."""
        paths = [*self.periodic_checkpoints(), *([self.final_path] if self.final_path.is_file() else [])]
        return tuple((p.name, p.stat().st_mtime_ns) for p in paths)

    def create(self, cfg) -> None:
        """Write the config of a new run, holding the directory's lock (``train`` releases it). A run
        killed before its first checkpoint is cleared first; one with a checkpoint is refused."""
        make_dir(self.path, "the run directory")
        lock(self.path)
        if self.has_checkpoint():
            unlock(self.path)
            raise ConfigError(f"{self.path} already holds a run; choose another hydra.run.dir or continue it with resume={self.path}")
        if self.has_results():
            self.clear_unfinished()
        self.write_config(cfg)

    def write_config(self, cfg) -> None:
        """config.yaml, replaced at once (a reader never sees half of it)."""
        tmp = self.config_path.with_suffix(".yaml.tmp")
        tmp.write_text(OmegaConf.to_yaml(OmegaConf.create(to_dict(cfg))))
        os.replace(tmp, self.config_path)

    def clear_unfinished(self) -> None:
        """Remove what a run killed before its first checkpoint left (nothing of it can be resumed),
        saying so on stderr; Hydra's records and user files stay."""
        rows = max(0, sum(1 for _ in self.metrics_path.open()) - 1) if self.metrics_path.is_file() else 0
        note(f"{self.path} held a run that wrote no checkpoint ({rows} metrics rows): starting it afresh")
        stale = [self.config_path, self.metrics_path, self.summary_path, self.curves_path, *self.path.glob("eval_*.rrd")]
        stale += list(self.ckpt_dir.glob("*.tmp")) if self.ckpt_dir.is_dir() else []
        for p in stale:
            p.unlink(missing_ok=True)
        if self.ckpt_dir.is_dir() and not any(self.ckpt_dir.iterdir()):
            self.ckpt_dir.rmdir()

    def load_config(self):
        """The run's validated config; a damaged or hand-broken config.yaml is one line naming it."""
        if not self.is_run():
            raise ConfigError(f"{self.path} is not a run directory (no config.yaml)")
        try:
            data = OmegaConf.to_container(OmegaConf.load(self.config_path), resolve=True)
        except Exception as e:  # noqa: BLE001 - YAML and OmegaConf errors alike: the file is damaged
            raise ConfigError(f"{self.config_path} is damaged ({' '.join(str(e).split())[:200]}); restore it or start a new run") from None
        if not isinstance(data, dict):
            raise ConfigError(f"{self.config_path} is damaged (not a mapping of config keys); restore it or start a new run")
        try:
            return validate(data)
        except ConfigError as e:
            raise ConfigError(f"{self.config_path}: {e}") from None

    def check_metrics(self) -> None:
        """Refuse a damaged metrics.csv before a resume rewrites it. Its last row may be cut short
        (a kill while writing): the resume drops it anyway, with every row after the checkpoint."""
        if not self.metrics_path.is_file():
            return
        try:
            with self.metrics_path.open(newline="") as f:
                reader = csv.DictReader(f)
                if "frames" not in (reader.fieldnames or []):
                    raise ValueError("no 'frames' column in the header")
                rows = list(reader)
        except (ValueError, csv.Error, UnicodeDecodeError) as e:
            raise ConfigError(f"{self.metrics_path} is damaged ({e}); move it away to resume without the old rows") from None
        for i, r in enumerate(rows[:-1], start=2):
            if not _is_number(r.get("frames")):
                raise ConfigError(
                    f"{self.metrics_path} is damaged (line {i}: frames {r.get('frames')!r} is not a number); move it away to resume without the old rows"
                )

    # ---------------------------------------------------------------------------- checkpoints
    def periodic_checkpoints(self) -> list[Path]:
        found = [(int(m.group(1)), p) for p in self.ckpt_dir.glob("ckpt_*.pt") if (m := _CKPT.search(p.name))]
        return [p for _, p in sorted(found)]

    def latest_checkpoint(self) -> Path | None:
        """The checkpoint with the most frames (final.pt included); a damaged one is a ConfigError naming it."""
        cands = self.periodic_checkpoints()
        if self.final_path.is_file():
            cands.append(self.final_path)
        if not cands:
            return None
        return max(cands, key=self._frames_of)

    def _frames_of(self, path: Path) -> int:
        try:
            return int(read_checkpoint(path)["frames"])
        except ConfigError as e:
            raise ConfigError(f"{e}; move it out of {self.ckpt_dir} to use the run's other checkpoints") from None

    def policy_checkpoint(self, what: str) -> Path:
        """The checkpoint that stands for the run's policy: final.pt, else the latest; ``what`` names
        the run in the error when there is none."""
        ckpt = self.final_path if self.final_path.is_file() else self.latest_checkpoint()
        if ckpt is None:
            raise ConfigError(f"{what} has no checkpoint yet (checkpoints/ is empty)")
        return ckpt

    def save_checkpoint(self, state: dict, final: bool = False, keep: int = 3, best: bool = False) -> Path:
        """A periodic checkpoint, ``final.pt`` or ``best.pt``. Only periodic and final ones are resumed
        from: ``best.pt`` is written at an evaluation, mid-episode, so it is a policy, not a clean cut."""
        self.ckpt_dir.mkdir(parents=True, exist_ok=True)
        path = self.final_path if final else self.best_path if best else self.ckpt_dir / f"ckpt_{state['frames']:012d}.pt"
        tmp = path.with_suffix(".tmp")
        torch.save(state, tmp)
        os.replace(tmp, path)  # a run killed while writing leaves the previous checkpoint intact
        if not (final or best):
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


def load_algo_state(algo, state: dict, what: str, cfg, side: str = "run") -> None:
    """Load a checkpoint's algorithm state into ``algo``; a mismatch is a user error naming ``what``
    and both sides: "checkpoint is solo_bump (obs 32, prt, ppo), run is hover (obs 26, prt, ppo)"."""
    saved = state.get("config") or {}
    theirs = (state.get("task"), state.get("obs_dim"), state.get("action_space"), (saved.get("algo") or {}).get("name"))
    mine = (cfg.task.name, algo.obs_dim, cfg.env.action_space, cfg.algo.name)
    # what the checkpoint does not record (an older or a population member's) is not compared
    mine = tuple(m if t is not None else None for m, t in zip(mine, theirs))
    theirs, mine = _describe(*theirs), _describe(*mine)
    if theirs != mine:
        raise ConfigError(f"{what} does not match: checkpoint is {theirs}, {side} is {mine}")
    try:
        algo.load_state_dict(_to_device(state["algo"], algo.device))
    except (RuntimeError, KeyError, ValueError) as e:
        lines = [" ".join(line.split()) for line in str(e).splitlines() if line.strip()]
        detail = (lines[1] if len(lines) > 1 else lines[0] if lines else type(e).__name__).rstrip(".")
        raise ConfigError(f"{what} does not match the networks of the {side} ({theirs}): {detail}") from None


def _describe(task, obs_dim, action_space, algo) -> str:
    detail = ", ".join(str(x) for x in (f"obs {obs_dim}" if obs_dim is not None else None, action_space, algo) if x is not None)
    return f"{task or '?'} ({detail})"


class MetricsLog:
    """metrics.csv: the header is the first row's keys; a resumed run drops the rows after its checkpoint."""

    def __init__(self, path: Path, keep_until_frames: int | None = None):
        self.path = Path(path)
        self.fields: list[str] | None = None
        if keep_until_frames is not None and self.path.is_file():
            with self.path.open(newline="") as f:
                reader = csv.DictReader(f)
                self.fields = list(reader.fieldnames or [])
                # a row cut short by a kill has no number in frames (RunDir.check_metrics allows it last)
                rows = [r for r in reader if _is_number(r["frames"]) and float(r["frames"]) <= keep_until_frames]
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


def _is_number(v) -> bool:
    try:
        float(v)
    except (TypeError, ValueError):
        return False
    return True


# ------------------------------------------------------------------------------ locks and directories
_HELD: dict[str, list] = {}  # resolved path -> [lock file descriptor, times locked by this process]


class InUseError(ConfigError):
    """The directory is locked by another process."""


def lock(path) -> None:
    """Take the exclusive lock of the directory ``path`` for this process (again: counted), or raise
    ``ConfigError`` naming the process that holds it. ``fcntl.flock`` locks die with their process."""
    key = str(Path(path).resolve())
    if key in _HELD:
        _HELD[key][1] += 1
        return
    if fcntl is None:
        return
    lock_path = Path(key) / LOCK_NAME
    try:
        fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as e:
        raise ConfigError(f"cannot lock {str(path)!r}: {e.strerror} ({lock_path})") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        holder = os.read(fd, 200).decode(errors="replace").strip() or "another process"
        os.close(fd)
        raise InUseError(f"{path} is in use by {holder}; wait for it to finish or choose another directory") from None
    os.ftruncate(fd, 0)
    os.write(fd, f"process {os.getpid()} on {socket.gethostname()}\n".encode())
    _HELD[key] = [fd, 1]


def unlock(path) -> None:
    key = str(Path(path).resolve())
    held = _HELD.get(key)
    if held is None:
        return
    held[1] -= 1
    if held[1] == 0:
        del _HELD[key]
        os.close(held[0])  # closing the descriptor drops the flock


@contextlib.contextmanager
def locked(path):
    lock(path)
    try:
        yield
    finally:
        unlock(path)


def check_writable(path, what: str) -> None:
    """Raise ``ConfigError`` unless the directory ``path`` exists and is writable or can be created:
    no file in the way and permission to write in its nearest existing ancestor. Writes nothing."""
    path = Path(path).absolute()
    probe = path
    while not probe.exists() and probe != probe.parent:
        if probe.is_symlink():  # a dangling link: mkdir would fail on it
            raise ConfigError(f"{what} {str(path)!r} cannot be created: {probe} is a broken link")
        probe = probe.parent
    if not probe.is_dir():
        raise ConfigError(f"{what} {str(path)!r} cannot be created: {probe} is a file, not a directory")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise ConfigError(f"{what} {str(path)!r} cannot be written: no permission to write in {probe}")


def make_dir(path, what: str) -> Path:
    """Create the directory ``path`` (with its parents) or raise ``ConfigError`` naming it."""
    check_writable(path, what)
    try:
        Path(path).mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ConfigError(f"{what} {str(path)!r} cannot be created: {e.strerror}") from None
    return Path(path)


def claim_run_dir(path, unique: bool, sweep: bool = False) -> Path:
    """Lock a directory for a new run (or, with ``sweep``, a ``-m`` sweep's parent) and return it.

    With ``unique`` (Hydra's time-stamped default) the first free one of ``path``, ``path_2``,
    ``path_3``, ... is taken, so runs started in the same second never share one. Otherwise ``path``
    itself, refused while another process uses it or while it holds a run with a checkpoint (a run
    killed before its first checkpoint is cleared by ``RunDir.create``)."""
    path = Path(path)
    for n in itertools.count(1):
        cand = path if n == 1 else path.with_name(f"{path.name}_{n}")
        if _taken(cand, unique, sweep):  # checked before locking too: a refusal writes nothing
            continue
        make_dir(cand, "hydra.sweep.dir" if sweep else "the run directory")
        try:
            lock(cand)
        except InUseError:
            if unique:
                continue
            raise
        try:
            free = not _taken(cand, unique, sweep)  # again under the lock: another process may have been first
        except ConfigError:
            unlock(cand)
            raise
        if free:
            return cand
        unlock(cand)
    raise AssertionError("unreachable")


def _taken(path: Path, unique: bool, sweep: bool) -> bool:
    """Whether a new run may not use ``path``: it holds a run with a checkpoint (refused unless
    ``unique``, which moves on to the next name), or with ``unique`` anything of a run at all."""
    if not path.is_dir():
        return False
    runs = [RunDir(c) for c in path.iterdir() if c.is_dir()] if sweep else [RunDir(path)]
    done = [r.path for r in runs if r.has_checkpoint()]
    if unique:
        return bool(done) or any(r.has_results() for r in runs)
    if done and sweep:
        raise ConfigError(f"{path} already holds runs ({done[0]}); choose another hydra.sweep.dir")
    if done:
        raise ConfigError(f"{path} already holds a run; choose another hydra.run.dir or continue it with resume={path}")
    return False


@contextlib.contextmanager
def memory_errors_as(what: str):
    """Turn an out-of-memory error of torch (CPU or CUDA) or Python into one ``ConfigError`` line
    naming ``what`` (the counts that asked for the memory): ``check_memory`` only knows a lower bound."""
    try:
        yield
    except (MemoryError, RuntimeError) as e:
        oom = isinstance(e, (MemoryError, torch.OutOfMemoryError)) or any(s in str(e) for s in ("can't allocate memory", "out of memory"))
        if not oom:
            raise
        raise ConfigError(f"ran out of memory with {what}; lower them ({' '.join(str(e).split())[:160]})") from None


def note(msg: str) -> None:
    """A line on stderr for what the user should know but that is no error (a run started afresh)."""
    print(f"note: {msg}", file=sys.stderr, flush=True)


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
