"""The zoo: trained policies shipped inside the package, named ``zoo:<task>/<method>`` wherever a
competitor is (``eval crossplay``, ``opponent=``, ``replay A B``); a single policy also wherever one
policy goes (``eval``, ``replay TARGET``, ``init=``, ``population.seed_members``).

An entry is its card ``<task>/<method>.yaml`` (the command that trained it, its frames, seed and wall
time, and the figures measured on held-out evaluation seeds) with either of:

- **a single policy:** the weights-only checkpoint ``<task>/<method>.pt`` beside the card
  (``torch.load(..., weights_only=True)`` reads it);
- **a mixture** (a population's final meta-strategy, e.g. PSRO-Nash): the card's ``mixture:`` lists
  ``{file: <method>/<member>.pt, weight: w}``, files relative to the task folder, members of nonzero
  weight only. It plays as one competitor that draws a member per game with those weights.
- **a hierarchical team** (3v3): the card's ``hierarchical:`` maps drills (and ``high_level``) to files
  relative to the task folder; the card is then also the team's file (``hierarchical: {drill: file}``,
  volleybots/policies/builtin.py) and plays as the ``hierarchical`` competitor with those files.

A leaf module: it only finds files and checks that a mixture's files exist and its weights sum to 1.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import yaml

from volleybots.errors import ConfigError
from volleybots.files import Fields

ZOO_DIR = Path(__file__).resolve().parent
PREFIX = "zoo:"


@dataclass(frozen=True)
class Entry:
    name: str  # "<task>/<method>"
    card: dict
    members: tuple[Path, ...]  # the checkpoint files: the one of a single policy, or a mixture's members
    weights: tuple[float, ...]  # the chance each member plays a game; (1.0,) for a single policy
    is_mixture: bool  # whether the card lists a mixture (even one of a single member)
    is_team: bool = False  # whether the card is a hierarchical team's (its members: the drills' and high level's files)
    card_file: Path | None = None  # the card itself (a team's file)

    @property
    def task(self) -> str:
        return self.name.split("/", 1)[0]

    @property
    def checkpoint(self) -> Path | None:
        """The file of a single policy; None for a mixture or a team (their files are ``members``)."""
        return None if self.is_mixture or self.is_team else self.members[0]


def _mixture(card_path: Path, listed) -> tuple[tuple[Path, ...], tuple[float, ...]]:
    """A card's ``mixture:`` as member files and weights; a damaged list is one ``ConfigError`` line
    (the weights are checked as a population's meta-strategy is: ``files.Fields.mixture``)."""
    what = f"zoo card {str(card_path)!r}"
    if not isinstance(listed, list) or not listed:
        raise ConfigError(f"{what}: 'mixture' must be a non-empty list of {{file: <method>/<member>.pt, weight: w}}")
    files = []
    for item in listed:
        file = item.get("file") if isinstance(item, dict) else None
        if not isinstance(file, str) or not isinstance(item.get("weight"), (int, float)) or not item["weight"] > 0:
            raise ConfigError(f"{what}: mixture item {item!r} is not {{file: <method>/<member>.pt, weight: w > 0}}")
        path = card_path.parent / file
        if not path.is_file():
            raise ConfigError(f"{what}: member file {file!r} is missing")
        files.append(path)
    weights = Fields({"mixture": [item["weight"] for item in listed]}, what).mixture("mixture", len(files))
    return tuple(files), tuple(weights)


def _team(card_path: Path, listed) -> tuple[Path, ...]:
    """A team card's ``hierarchical:`` files; a damaged mapping is one ``ConfigError`` line."""
    what = f"zoo card {str(card_path)!r}"
    if not isinstance(listed, dict) or not listed or not all(isinstance(v, str) and v for v in listed.values()):
        raise ConfigError(f"{what}: 'hierarchical' must map drills (and high_level) to files, e.g. {{pass: <method>/pass.pt}}")
    files = tuple(card_path.parent / v for v in listed.values())
    for f in files:
        if not f.is_file():
            raise ConfigError(f"{what}: file {str(f.relative_to(card_path.parent))!r} is missing")
    return files


def entries() -> dict[str, Entry]:
    """Every shipped policy by name, in name order (a checkpoint without its card is not listed)."""
    out = {}
    for card_path in sorted(ZOO_DIR.glob("*/*.yaml")):
        card = yaml.safe_load(card_path.read_text()) or {}
        card = card if isinstance(card, dict) else {}
        name = f"{card_path.parent.name}/{card_path.stem}"
        if "mixture" in card:
            out[name] = Entry(name, card, *_mixture(card_path, card["mixture"]), is_mixture=True)
        elif "hierarchical" in card:
            out[name] = Entry(name, card, _team(card_path, card["hierarchical"]), (1.0,), False, True, card_path)
        elif card_path.with_suffix(".pt").is_file():
            out[name] = Entry(name, card, (card_path.with_suffix(".pt"),), (1.0,), is_mixture=False)
    return out


def lookup(spec: str) -> Entry | None:
    """The entry ``zoo:<task>/<method>`` names, or None when it names none (the caller says what exists)."""
    return entries().get(spec[len(PREFIX):]) if spec.startswith(PREFIX) else None


__all__ = ["Entry", "PREFIX", "ZOO_DIR", "entries", "lookup"]
