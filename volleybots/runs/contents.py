"""What a run holds, checked against what the run says it holds: the one loader of a run's policies.

A finished run lists its checkpoints in summary.json; a population run lists, per iteration, its
members and meta-strategy in ``population/meta.jsonl`` (written after the member's file). Every verb
that plays a run (``eval``, ``replay``, ``eval crossplay``, ``opponent=``, ``init=``) and every
population resume reads it through ``run_policy_checkpoint`` or ``read_population``, which refuse
with one line naming what is missing or damaged rather than play something else:

- a checkpoint that summary.json lists but that is gone, or a run with no checkpoint left;
- a checkpoint or member file that does not read back (truncated, overwritten);
- a meta.jsonl line that is not JSON, lacks a key, or whose mixture is not weights >= 0 summing to 1;
- a member file that meta.jsonl lists but that is gone, or whose label is not the one listed.

A population run killed between writing a member and its meta.jsonl line holds a member that no
meta-strategy includes yet: it plays as its last complete iteration, saying so (``train resume=``
completes the iteration).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import yaml

from volleybots.errors import ConfigError
from volleybots.files import Fields, read_json, read_jsonl, read_yaml_text, sha256
from volleybots.runs.locks import note
from volleybots.runs.rundir import POPULATION_DIR, RunDir, read_checkpoint

META_FILE = "meta.jsonl"


def member_path(run_path, k: int) -> Path:
    return Path(run_path) / POPULATION_DIR / f"member_{k:03d}.pt"


def population_members(run_path) -> list[Path]:
    """The member files on disk, in order (complete or not: see ``read_population``)."""
    return sorted((Path(run_path) / POPULATION_DIR).glob("member_*.pt"))


def is_population_run(run_path) -> bool:
    """Whether the run's config names a population preset (``population.name``, or ``algo.name`` as saved
    before ``population=`` was a group: ``sp``, ``fsp``, ``psro_*``) or it holds a population."""
    from volleybots.algos.population import is_population

    path = Path(run_path)
    if (path / POPULATION_DIR).is_dir():
        return True
    try:
        cfg = yaml.safe_load(read_yaml_text(path / "config.yaml", "the run's config")) or {}
        algo = cfg.get("algo") or {}
    except (ConfigError, yaml.YAMLError, AttributeError):
        return False
    return is_population(cfg) or (isinstance(algo, dict) and is_population(algo))


def read_metas(run_path) -> list[dict]:
    """Every line of a population run's meta.jsonl, each checked: iteration numbers rising from 0 or 1,
    member labels, a mixture over them of weights >= 0 summing to 1, frame and update counts."""
    path = Path(run_path) / POPULATION_DIR / META_FILE
    metas = read_jsonl(path, "population file")
    last = -1
    for n, line in enumerate(metas, start=1):
        f = Fields(line, f"population file {str(path)!r} (line {n})")
        it = f.need("iteration", int)
        labels = f.need("members", list)
        if not all(isinstance(x, str) for x in labels):
            f.fail("'members' must be a list of labels")
        f.mixture("mixture", len(labels))
        shas = f.need("sha256", list, optional=True)  # absent in runs written before it was recorded
        if shas is not None and (len(shas) != len(labels) or not all(isinstance(x, str) for x in shas)):
            f.fail(f"'sha256' must list one checksum per member ({len(labels)})")
        for key in ("frames", "updates"):
            if f.need(key, int) < 0:
                f.fail(f"{key!r} is negative")
        if it <= last or it < 0:
            f.fail(f"iteration {it} follows iteration {last}")
        last = it
    return metas


@dataclass
class Population:
    """A population run's last complete iteration: its member files, labels and meta-strategy."""

    path: Path
    iteration: int
    members: list[Path]
    labels: list[str]
    mixture: list[float]
    metas: list[dict] = field(default_factory=list)
    pending: list[Path] = field(default_factory=list)  # member files no meta-strategy includes yet


def read_population(run_path, what: str, quiet: bool = False) -> Population:
    """The population a run holds, every member file read back and matched with meta.jsonl. A run
    stopped after writing a member but before its meta line plays its last complete iteration (a
    note says so unless ``quiet``); one with no complete iteration is refused."""
    path = Path(run_path)
    metas = read_metas(path)
    files = population_members(path)
    if not metas:
        raise ConfigError(f"{what} is a population run with no complete iteration yet ({POPULATION_DIR}/{META_FILE} "
                          f"{'is empty' if (path / POPULATION_DIR / META_FILE).is_file() else 'is missing'}, "
                          f"{len(files)} member file(s)); nothing of it can play: resume it with train resume={path}")
    last = metas[-1]
    labels = list(last["members"])
    members = [member_path(path, k) for k in range(len(labels))]
    for k, (p, label) in enumerate(zip(members, labels)):
        if not p.is_file():
            raise ConfigError(f"{what}: member file {POPULATION_DIR}/{p.name} is missing (iteration {last['iteration']} of "
                              f"{META_FILE} lists {len(labels)} members); restore it")
        state = read_checkpoint(p)
        found = state.get("label", p.stem)
        if found != label:
            raise ConfigError(f"{what}: member file {POPULATION_DIR}/{p.name} holds {found!r}, but {META_FILE} lists {label!r} "
                              f"as member {k}; restore the run's own file")
        if last.get("sha256") and sha256(p) != last["sha256"][k]:
            raise ConfigError(f"{what}: member file {POPULATION_DIR}/{p.name} is not the file this run wrote (its sha256 differs "
                              f"from the one {META_FILE} recorded for {label!r}); restore the run's own file")
    pending = [p for p in files if p not in members]
    if pending and not quiet:
        note(f"{what} was stopped during iteration {last['iteration'] + 1} ({', '.join(p.name for p in pending)} has no "
             f"meta-strategy yet): playing iteration {last['iteration']}, its last complete one, of {len(labels)} members")
    return Population(path, int(last["iteration"]), members, labels, list(last["mixture"]), metas, pending)


def run_policy_checkpoint(run_path, what: str) -> Path:
    """The checkpoint that stands for a run's policy (final.pt, else the latest), read back and
    matched with what the run says it holds: a finished run's summary.json lists its checkpoints;
    a population run's policy is the last learned member of its last complete iteration."""
    run = RunDir(run_path)
    if is_population_run(run.path):
        learned = [p for p in read_population(run.path, what, quiet=True).members if "algo" in read_checkpoint(p)]
        if not learned:
            raise ConfigError(f"{what} is a population run without a trained member yet; name it as a competitor of a match instead")
        return learned[-1]
    listed = []
    if run.summary_path.is_file():
        summary = Fields(read_json(run.summary_path, "run summary"), f"run summary {str(run.summary_path)!r}")
        listed = [str(x) for x in (summary.need("checkpoints", list, optional=True) or [])]
    gone = [x for x in listed if not (run.path / x).is_file()]
    if listed and len(gone) == len(listed):
        raise ConfigError(f"{what}: its checkpoints are gone (summary.json lists {', '.join(listed)}); restore them")
    if "checkpoints/final.pt" in gone:
        raise ConfigError(f"{what}: checkpoints/final.pt is gone (summary.json lists it); restore it to play the run's final policy")
    ckpt = run.final_path if run.final_path.is_file() else run.latest_checkpoint()
    if ckpt is None:
        raise ConfigError(f"{what} has no checkpoint yet (checkpoints/ is empty)")
    read_checkpoint(ckpt)  # a truncated or overwritten file is one line naming it
    return ckpt


__all__ = ["META_FILE", "Population", "is_population_run", "member_path", "population_members", "read_metas", "read_population",
           "run_policy_checkpoint"]
