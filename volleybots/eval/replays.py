"""The ``volleybots replay`` verb: one policy's episode (``replay TARGET``) or one match between two
competitors (``replay A B``) recorded to rerun, the outputs checked before anything plays, and the file
a replay writes reserved so that two replays never write one file. (``volleybots.replay`` is the
recorder it drives; the CLI only parses the command line.)"""

from __future__ import annotations

from pathlib import Path

from volleybots.config.args import split_args
from volleybots.config.verbs import ReplayOptions
from volleybots.errors import ConfigError
from volleybots.eval.crossplay import setup
from volleybots.overrides import split_arg


def is_competitor_spec(arg: str) -> bool:
    """A replay argument names a competitor (rather than a config override) when it has no ``=`` or
    labels a built-in player or an existing path: ``replay A B`` records a match, ``replay A k=v`` one policy."""
    from volleybots.files import exists
    from volleybots.policies import BUILTIN

    value = split_arg(arg)[1]
    return value is None or value in BUILTIN or (bool(value) and exists(value)) or exists(arg)


def check_outputs(out: Path | None, still: Path | None) -> None:
    """``--out FILE.rrd`` and ``--still FILE.png``: the right suffix, a file name the file system takes, a
    file that does not exist yet (replays never overwrite) in a folder this process can write."""
    from volleybots.runs import check_writable

    for opt, path, suffix in (("--out", out, ".rrd"), ("--still", still, ".png")):
        if path is None:
            continue
        if path.suffix != suffix:
            raise ConfigError(f"{opt} {str(path)!r} must end in {suffix}")
        if len(path.name.encode()) > 255:  # the limit of most file systems (NAME_MAX)
            raise ConfigError(f"{opt} {path.name[:40]!r}... is too long for a file name ({len(path.name.encode())} bytes, at most 255)")
        if path.exists() or path.is_symlink():
            raise ConfigError(f"{opt} {str(path)!r} exists; choose another file (replays never overwrite)")
        check_writable(path.parent, f"the folder of {opt}")


def replay_verb(args: list[str], out: Path | None, viewer: bool, still: Path | None = None) -> str:
    """``volleybots replay ARGS``: record a match when two arguments name competitors, else one episode
    of the policy the first names; returns the line saying what was recorded where."""
    check_outputs(out, still)
    if sum(map(is_competitor_spec, args)) >= 2:
        if still is not None:
            raise ConfigError("--still draws one policy's episode (replay TARGET ...); a match replay takes --out and --no-viewer only")
        stats, out, labels = replay_match(args, out, viewer)
        where = str(out) if out is not None else "the viewer"
        who = {0: f"{labels[0]} (blue) won", 1: f"{labels[1]} (red) won", -1: "a draw"}[int(stats["winner"])]
        return f"recorded one match of {labels[0]} (blue) against {labels[1]} (red) to {where}: {who}"
    return replay_one(args[0], args[1:], out, viewer, still)


def replay_one(target: str, overrides: list[str], out: Path | None, viewer: bool, still: Path | None = None) -> str:
    """One episode of the policy ``target`` names (with config ``overrides``) recorded to rerun."""
    import time

    from volleybots.config import make_env
    from volleybots.policies import resolve_target
    from volleybots.replay import record_episode
    from volleybots.runs import make_dir, reserve_file

    t = resolve_target(target, overrides)
    default = None
    if out is None and not viewer:
        base = Path(target) if Path(target).is_dir() else Path("outputs") / "replays"
        default = base / replay_name(t.cfg.task.name, [t.label], time.strftime("%Y%m%d-%H%M%S"))
    env = make_env(t.cfg, num_envs=1, seed=t.cfg.seed)
    policy = t.make_policy(env)
    out = replay_file(out, default)
    try:
        if still is not None:  # reserved before the episode: a second replay to the same picture is refused, not mixed in
            still = reserve_file(make_dir(still.parent, "the folder of --still") / still.name, explicit=True, what="--still")
        stats = record_episode(env, policy, out, viewer=viewer, still=still)
    except BaseException:
        for path in (out, still):
            if path is not None and path.is_file() and path.stat().st_size == 0:
                path.unlink()
        raise
    where = str(out) if out is not None else "the viewer"
    where += f" and {still}" if still is not None else ""
    return (f"recorded one episode of {t.label} on {t.cfg.task.name} to {where}: "
            f"{env.metric} {stats[env.metric]:.4g}, return {stats['return']:.4g}")


def replay_match(args, out: Path | None, viewer: bool) -> tuple[dict, Path | None, list[str]]:
    """``volleybots replay A B task=3v3``: one match between two competitors recorded to rerun (team
    colours, touches, the point and its fault); returns (env 0's statistics, the file, the labels)."""
    import time

    from volleybots.play.games import side_env
    from volleybots.replay import record_match
    from volleybots.tasks.multi import TeamPolicies

    specs = split_args(args, ReplayOptions)[0]
    if len(specs) != 2:
        raise ConfigError(f"a match replay takes two competitors; got {len(specs)}: {' '.join(specs)}")
    comps, specs, opts, cfg = setup(args, ReplayOptions)
    labels = [c.label for c in comps]
    default = None
    if out is None and not viewer:
        default = Path("outputs") / "replays" / replay_name(cfg.task.name, labels, time.strftime("%Y%m%d-%H%M%S"))
    seed = opts.seed
    env = side_env(cfg, 0, opts.scenario, 1, seed)  # A is team 0 (blue)
    gen = torch_generator(seed)
    policy = TeamPolicies(env, tuple(c.team_policy(env, opts.deterministic, gen) for c in comps))
    out = replay_file(out, default)
    try:
        return record_match(env, policy, tuple(labels), out, viewer=viewer), out, labels
    except BaseException:
        if out is not None and out.is_file() and out.stat().st_size == 0:
            out.unlink()
        raise


def replay_file(out: Path | None, default: Path | None):
    """The file a replay writes, reserved at once (``reserve_file``: two replays never pick one
    name), or None for the viewer alone; the caller removes it if the recording fails."""
    from volleybots.runs import check_writable, make_dir, reserve_file

    if out is None and default is None:
        return None
    path = out if out is not None else default
    if out is None:
        check_writable(path.parent, "the replay folder (choose another with --out)")
    make_dir(path.parent, "the folder of --out")
    return reserve_file(path, explicit=out is not None)


NAME_MAX = 200  # bytes of a file name the replay's labels may take (most file systems allow 255)


def replay_name(task: str, labels, stamp: str) -> str:
    """A replay's default file name from its labels: characters a path cannot hold replaced, and
    labels too long for a file name shortened, with a hash so that different ones stay apart."""
    import hashlib
    import re

    name = "_vs_".join(re.sub(r"[^\w.+-]", "_", lab) for lab in labels)
    if len(f"replay_{task}_{name}_{stamp}.rrd".encode()) > NAME_MAX:
        digest = hashlib.sha256(name.encode()).hexdigest()[:10]
        name = name.encode()[: NAME_MAX - 60].decode(errors="ignore") + f"~{digest}"
    return f"replay_{task}_{name}_{stamp}.rrd"


def torch_generator(seed: int):
    import torch

    torch.manual_seed(seed)
    return torch.Generator().manual_seed(seed)
