"""The zoo: trained policies shipped inside the package, named ``zoo:<task>/<method>`` wherever a
competitor or a target is (``eval crossplay``, ``opponent=``, ``algo.seed_members``, ``replay``).

Each entry is a weights-only checkpoint ``<task>/<method>.pt`` (``torch.load(..., weights_only=True)``
reads it) beside its card ``<task>/<method>.yaml``: the command that trained it, its frames, seed and
wall time, and the figures measured on held-out evaluation seeds. A leaf module: it only finds files.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import yaml

ZOO_DIR = Path(__file__).resolve().parent
PREFIX = "zoo:"


@dataclass(frozen=True)
class Entry:
    name: str  # "<task>/<method>"
    checkpoint: Path
    card: dict

    @property
    def task(self) -> str:
        return self.name.split("/", 1)[0]


def entries() -> dict[str, Entry]:
    """Every shipped policy by name, in name order (an entry without its card is not listed)."""
    out = {}
    for ckpt in sorted(ZOO_DIR.glob("*/*.pt")):
        card_path = ckpt.with_suffix(".yaml")
        if not card_path.is_file():
            continue
        card = yaml.safe_load(card_path.read_text()) or {}
        name = f"{ckpt.parent.name}/{ckpt.stem}"
        out[name] = Entry(name, ckpt, card if isinstance(card, dict) else {})
    return out


def lookup(spec: str) -> Entry | None:
    """The entry ``zoo:<task>/<method>`` names, or None when it names none (the caller says what exists)."""
    return entries().get(spec[len(PREFIX):]) if spec.startswith(PREFIX) else None


__all__ = ["Entry", "PREFIX", "ZOO_DIR", "entries", "lookup"]
