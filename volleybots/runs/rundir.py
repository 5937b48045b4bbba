"""``RunDir``: a run's files, its checkpoints (read with ``weights_only=True``), and claiming a directory for a new run."""

from __future__ import annotations

import contextlib
import csv
import io
import itertools
import json
import re
from pathlib import Path

import torch
from omegaconf import OmegaConf

from volleybots.config import to_dict, validate
from volleybots.errors import ConfigError
from volleybots.files import Fields, read_yaml_text, write_atomic, write_json
from volleybots.runs.locks import InUseError, lock, make_dir, note, unlock
from volleybots.runs.metrics import _is_number

CKPT_FORMAT = 1
POPULATION_DIR = "population"  # a population run's members, payoffs.json and meta.jsonl
# what a run writes at its top level besides config, metrics, summary, curves and checkpoints
OWN_FILES = ("payoffs.png", "wandb_run.json", "wandb", ".lock")
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
    best_path = property(lambda self: self.ckpt_dir / "best.pt")

    def is_run(self) -> bool:
        """Whether the directory holds a run's config.yaml (a damaged one too: ``load_config`` says what is wrong)."""
        return self.config_path.exists() or self.config_path.is_symlink()

    def has_results(self) -> bool:
        """Whether a run already wrote here (starting another one would overwrite it)."""
        return any(p.exists() for p in (self.config_path, self.metrics_path, self.ckpt_dir, self.summary_path))

    def has_checkpoint(self) -> bool:
        """Whether the run holds trained work: a checkpoint, or a population member a learner trained."""
        if self.periodic_checkpoints() or self.final_path.is_file():
            return True
        members = sorted((self.path / POPULATION_DIR).glob("member_*.pt"))
        return any(_is_trained(p) for p in members)

    def checkpoint_stamp(self) -> tuple:
        """The checkpoints' names and modification times: a change means another process trained here."""
        paths = [*self.periodic_checkpoints(), *([self.final_path] if self.final_path.is_file() else [])]
        return tuple((p.name, p.stat().st_mtime_ns) for p in paths)

    @contextlib.contextmanager
    def new_run(self, cfg):
        """Hold the directory's lock while a new run writes and trains in it (``create``, then the
        body); the lock is released however the body ends. Every start goes through here."""
        self.create(cfg)
        try:
            yield self
        finally:
            unlock(self.path)

    def create(self, cfg) -> None:
        """Write the config of a new run, taking the directory's lock for the caller (``new_run``
        releases it). A run killed before its first checkpoint is cleared first; one with a checkpoint
        is refused."""
        make_dir(self.path, "the run directory")
        lock(self.path)
        try:
            self.check_contained()
        except ConfigError:
            unlock(self.path)
            raise
        if self.has_checkpoint():
            unlock(self.path)
            raise ConfigError(f"{self.path} already holds a run; choose another hydra.run.dir or continue it with resume={self.path}")
        if self.has_results():
            try:
                self.check_clearable()
            except ConfigError:
                unlock(self.path)
                raise
            self.clear_unfinished()
        self.write_config(cfg)

    def write_config(self, cfg) -> None:
        """config.yaml, replaced at once (a reader never sees half of it)."""
        write_atomic(self.config_path, OmegaConf.to_yaml(OmegaConf.create(to_dict(cfg))), "the run's config")

    def check_clearable(self) -> None:
        """Refuse to clear a run that finished (it wrote summary.json) but whose checkpoints are gone:
        its results are not those of a run killed early, and starting afresh would overwrite them."""
        if self.summary_path.exists():
            raise ConfigError(f"{self.path} holds a finished run (summary.json) whose checkpoints are gone: it cannot be continued, "
                              "and its results are never overwritten; restore its checkpoints/ or choose another directory")

    def clear_unfinished(self) -> None:
        """Remove what a run killed before its first checkpoint left (nothing of it can be resumed),
        saying so on stderr; Hydra's records and user files stay."""
        rows = max(0, sum(1 for _ in self.metrics_path.open()) - 1) if self.metrics_path.is_file() else 0
        note(f"{self.path} held a run that wrote no checkpoint ({rows} metrics rows): starting it afresh")
        stale = [self.config_path, self.metrics_path, self.summary_path, self.curves_path, self.path / "payoffs.png",
                 *self.path.glob("eval_*.rrd")]
        stale += list(self.ckpt_dir.glob("*.tmp")) if self.ckpt_dir.is_dir() else []
        pop = self.path / POPULATION_DIR
        if pop.is_dir():
            # a population killed before its first checkpoint holds only seed members and their games:
            # kept, they would silently become the new run's population whatever its seed_members say
            note(f"{self.path} held a population ({len(list(pop.glob('member_*.pt')))} member file(s)) of that run: removed")
            stale += [p for p in pop.iterdir() if p.is_file()]
        for p in stale:
            p.unlink(missing_ok=True)
        for d in (self.ckpt_dir, pop):
            if d.is_dir() and not any(d.iterdir()):
                d.rmdir()

    def check_contained(self) -> None:
        """Refuse a run directory (received from elsewhere) in which a file or folder the run writes
        is a link leading outside it: writing through it would append to, or replace, a file that is
        not the run's. Links that stay inside the directory are harmless. Writes nothing."""
        root = self.path.resolve()
        own = [self.config_path, self.metrics_path, self.summary_path, self.curves_path, *(self.path / n for n in OWN_FILES),
               self.ckpt_dir, self.path / POPULATION_DIR]
        for d in (self.ckpt_dir, self.path / POPULATION_DIR):
            if d.is_dir() and d.resolve().is_relative_to(root):
                own += sorted(d.iterdir())
        own += sorted(self.path.glob("eval_*.rrd"))
        for p in own:
            if p.is_symlink() and not p.resolve().is_relative_to(root):
                raise ConfigError(f"{p} is a link to {p.resolve()}, outside the run directory; a run writes only inside its "
                                  "own directory: replace the link with a copy of what it points to")

    def load_config(self):
        """The run's validated config; a damaged or hand-broken config.yaml is one line naming it."""
        if not self.is_run():
            raise ConfigError(f"{self.path} is not a run directory (no config.yaml)")
        text = read_yaml_text(self.config_path, "the run's config")  # bounded: a folder or /dev/zero is one line
        try:
            # not resolved: a run dir may come from someone else, and ``${oc.env:VAR}`` would fill in
            # this machine's environment (then written in clear into the resumed run's files)
            data = OmegaConf.to_container(OmegaConf.load(io.StringIO(text)), resolve=False)
        except Exception as e:  # noqa: BLE001 - YAML and OmegaConf errors alike: the file is damaged
            raise ConfigError(f"{self.config_path} is damaged ({' '.join(str(e).split())[:200]}); restore it or start a new run") from None
        if not isinstance(data, dict):
            raise ConfigError(f"{self.config_path} is damaged (not a mapping of config keys); restore it or start a new run")
        refuse_interpolation(data, str(self.config_path))
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
                    f"{self.metrics_path} is damaged (line {i}: frames {r.get('frames')!r} is not a number); "
                    "move it away to resume without the old rows"
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

    def save_checkpoint(self, state: dict, final: bool = False, keep: int = 3, best: bool = False) -> Path:
        """A periodic checkpoint, ``final.pt`` or ``best.pt``. Only periodic and final ones are resumed
        from: ``best.pt`` is written at an evaluation, mid-episode, so it is a policy, not a clean cut."""
        self.ckpt_dir.mkdir(parents=True, exist_ok=True)
        path = self.final_path if final else self.best_path if best else self.ckpt_dir / f"ckpt_{state['frames']:012d}.pt"
        # a run killed while writing leaves the previous checkpoint intact; a full disk is one line
        write_atomic(path, lambda f: torch.save(state, f), "a checkpoint")
        if not (final or best):
            for old in self.periodic_checkpoints()[:-keep]:
                old.unlink()
        return path

    def write_summary(self, summary: dict) -> None:
        write_json(self.summary_path, summary, "the run's summary", indent=2)


def refuse_interpolation(data, where: str, prefix: str = "") -> None:
    """Refuse any ``${...}`` in a saved config (``data``: plain containers), naming the first key: a
    saved config holds resolved values only, so one there was planted."""
    items = data.items() if isinstance(data, dict) else enumerate(data) if isinstance(data, list) else ()
    for k, v in items:
        key = f"{prefix}[{k}]" if isinstance(data, list) else f"{prefix}{'.' if prefix else ''}{k}"
        if isinstance(v, str) and "${" in v:
            raise ConfigError(f"{where}: {key} holds an interpolation {v[:60]!r}; a saved config holds plain values only, "
                              "so it was edited: restore the value or start a new run")
        refuse_interpolation(v, where, key)


def config_problem(config) -> str:
    """What is wrong with the keys that identify a run in its config.yaml (``config``: as YAML read
    it), for ``volleybots report``: types only, so that a run of an older version whose keys were
    renamed still aggregates; "" when nothing."""
    if not isinstance(config, dict):
        return "not a mapping of config keys"
    for group in ("task", "algo"):
        if not isinstance(config.get(group), dict) or not isinstance(config[group].get("name"), str):
            return f"{group}.name is not a name"
    number = (int, float)
    for key, kinds, optional in (("seed", (int,), False), ("total_frames", number, True), ("time_limit", number, True)):
        v = config.get(key)
        if (v is None and not optional) or (v is not None and (isinstance(v, bool) or not isinstance(v, kinds))):
            return f"{key} is {v!r}, not a number"
    for key in ("evaluation", "env", "checkpoint", "wandb"):
        if key in config and not isinstance(config[key], (dict, type(None))):
            return f"{key} is {type(config[key]).__name__}, not a group of keys"
    if "${" in json.dumps(config, default=str):
        return "it holds an interpolation ${...}; a saved config holds plain values only"
    return ""


def _is_trained(path: Path) -> bool:
    try:
        return "oracle" in read_checkpoint(path)  # a learner's member; seed members are copies or records
    except ConfigError:
        return True  # a damaged member is not cleared away silently: the run is refused instead


def read_checkpoint(path, device="cpu") -> dict:
    """Load a checkpoint written by ``RunDir.save_checkpoint`` (``weights_only=True``)."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"checkpoint {str(path)!r} does not exist")
    try:
        state = torch.load(path, map_location=device, weights_only=True)
    except Exception as e:  # noqa: BLE001 - any unreadable file is the same user error
        raise ConfigError(f"{str(path)!r} is damaged or not a volleybots checkpoint ({type(e).__name__}: "
                          f"{' '.join(str(e).split())[:120]})") from None
    if not isinstance(state, dict) or state.get("format") != CKPT_FORMAT:
        raise ConfigError(f"{str(path)!r} is not a volleybots checkpoint (format {CKPT_FORMAT} expected)")
    fields = Fields(state, f"checkpoint {str(path)!r}")
    for key in COUNTS:  # read as int() by every verb: a tampered NaN or text would be a traceback there
        fields.count(key, optional=True)
    return state


COUNTS = ("frames", "iteration", "obs_dim", "n_agents")  # a checkpoint's counters


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
    from volleybots.algos.population import upgrade_saved

    saved = upgrade_saved(state.get("config") or {})  # an old population member's config names its learner so
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


