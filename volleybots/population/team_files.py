"""Where a hierarchical population keeps its members' files (population/hierarchical.py): drills by name
and content under ``population/drills/``, each member's high level as ``population/high_level_<k>.pt``.
Stage III's tuned drills go the same way (population/tune_drills.py)."""

from __future__ import annotations

from pathlib import Path

from volleybots.files import sha256, write_atomic
from volleybots.policies.builtin import HIGH_LEVEL
from volleybots.runs import POPULATION_DIR

DRILLS_DIR = "drills"


def high_level_path(run_path, k: int) -> Path:
    return Path(run_path) / POPULATION_DIR / f"high_level_{k:03d}.pt"


def copy_team(run_path, files: dict[str, str], k: int) -> dict[str, str]:
    """Copy a team's files into the run's population folder (drills by name and content, the high level
    as member ``k``'s); returns them relative to that folder, as a member record names them."""
    root = Path(run_path) / POPULATION_DIR
    out = {}
    for name, src in files.items():
        if name == HIGH_LEVEL:
            dst = high_level_path(run_path, k)
        else:
            dst = root / DRILLS_DIR / f"{name}-{sha256(src)[:12]}.pt"
        if not dst.is_file():
            dst.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(dst, Path(src).read_bytes(), "a population member's file")
        out[name] = str(dst.relative_to(root))
    return out


__all__ = ["DRILLS_DIR", "copy_team", "high_level_path"]
