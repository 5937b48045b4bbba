"""The package version, and a fingerprint of the code that plays a game: a leaf module, so that
whatever records them (checkpoints, results files) need not import the package's top level."""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path

__version__ = "0.1.0"

# The floors whose code decides how a game goes: the physics, the referee, the tasks' observations and
# rewards, the scripted players, the networks that act, the policy store and the game loop, and the
# config that builds the match. Eval, training, ratings, reports and the CLI only record or read games.
PLAY_CODE = ("physics", "rules", "tasks", "scripted", "algos", "policies", "play", "config", "keys.py")
_ROOT = Path(__file__).resolve().parent


def play_sources() -> list[Path]:
    """The source files ``play_code`` reads, in a fixed order: the play floors' code and the config
    tree's YAML files (a drone's mass in ``conf/env/drone/`` changes a game as much as code does)."""
    from volleybots.paths import conf_dir  # a leaf too

    out = []
    for part in PLAY_CODE:
        path = _ROOT / part
        out += [path] if path.is_file() else sorted(path.rglob("*.py"))
    return out + sorted(conf_dir().rglob("*.yaml"))


def _name(path: Path) -> str:
    """A source's name as hashed: relative to the package, or ``conf/...`` for the config tree."""
    from volleybots.paths import conf_dir

    if path.is_relative_to(_ROOT):
        return path.relative_to(_ROOT).as_posix()
    return "conf/" + path.relative_to(conf_dir()).as_posix()


@functools.cache
def play_code() -> str:
    """A short sha256 of the play floors' source (names and bytes). The version string stays 0.1.0
    across commits, so a results file records this too: an earlier file's games are reused only
    when the code that played them is this one (``eval.reuse``)."""
    h = hashlib.sha256()
    for path in play_sources():
        h.update(_name(path).encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:16]
