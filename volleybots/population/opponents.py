"""The population loop's opponent seam: whom each oracle trains against, and whom the final mixture is.

The opponent is the meta-solver's mixture over the population's members (those of weight zero are
never drawn), with ``population.fixed_opponents`` beside it at ``population.fixed_share`` (a league's
anchors). Flat and hierarchical oracles are handed the same opponent: it is the loop's choice, not
the oracle's.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from volleybots.policies import Competitor, checkpoint_member, population_members, resolve_competitor
from volleybots.runs import read_checkpoint


def member_label(path: Path) -> str:
    """A member file's label (its file name where it names none)."""
    return read_checkpoint(path).get("label", path.stem)


def population_competitor(run_path, mixture) -> Competitor:
    """The members of the run in ``run_path`` with positive weight in ``mixture`` (the others are never drawn)."""
    paths = population_members(run_path)
    keep = [j for j, w in enumerate(mixture) if w > 0]
    weights = np.asarray([mixture[j] for j in keep], dtype=float)
    return Competitor("population", [checkpoint_member(paths[j], member_label(paths[j])) for j in keep], list(weights / weights.sum()))


def fixed_mixture(population: Competitor, fixed: list[str], share: float) -> Competitor:
    """The oracle's opponent: the population's mixture with weight 1 - ``share`` and the ``fixed``
    competitors, equally, with ``share`` (a league's anchors; none: the mixture alone)."""
    if not fixed or share <= 0:
        return population
    comps = [resolve_competitor(s) for s in fixed]
    members = list(population.members) + [mm for c in comps for mm in c.members]
    weights = [(1 - share) * float(w) for w in population.mixture]
    weights += [share / len(comps) * float(w) for c in comps for w in c.mixture]
    return Competitor(population.label, members, weights)


def oracle_opponent(run_path, mixture, pop) -> Competitor:
    """What an oracle of the population node ``pop`` trains against, the population's ``mixture`` being solved."""
    return fixed_mixture(population_competitor(run_path, mixture), pop.fixed_opponents, pop.fixed_share)


__all__ = ["fixed_mixture", "member_label", "oracle_opponent", "population_competitor"]
