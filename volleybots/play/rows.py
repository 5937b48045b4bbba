"""Payoff rows: one competitor against many, every opponent in the same batch of worlds.

A population run adds a row to its payoff table per new member: ``games`` games against each member
before it. Played pair by pair, each pair's batch is small (50 worlds a side for 100 games) and lasts
as long as its longest game, and at that size stepping is overhead-bound: a row of ten pairs cost
about ten times one pair (3v3, CPU). A row is therefore played in chunks of opponents: a chunk's
worlds are split among its opponents (``AssignedPolicy``: each world plays one of them, fixed for its
game; a trained opponent's network acts on its own worlds only) and the chunk is one batch per side.
A chunk holds as many opponents as fit in ``batch`` worlds a side, and its games draw from ``seed +
its first opponent's index`` alone, so the counts do not depend on where or in which order the chunks
are played (``volleybots.play.pool`` plays them here or as Ray tasks).
"""

from __future__ import annotations

import numpy as np
import torch

from volleybots.errors import ConfigError
from volleybots.play.episodes import run_episodes
from volleybots.play.games import DEFAULT_BATCH, outcome, side_env
from volleybots.policies.competitors import AssignedPolicy
from volleybots.ratings import record
from volleybots.tasks.multi import TeamPolicies


def row_chunks(opponents: int, games: int, batch: int = DEFAULT_BATCH) -> list[range]:
    """Consecutive opponents whose games of one side (``games - games // 2`` each) fit in ``batch`` worlds."""
    per = max(1, batch // max(1, games - games // 2))
    return [range(i, min(i + per, opponents)) for i in range(0, opponents, per)]


def play_row_chunk(cfg, a, opponents: list, games: int, seed: int) -> list[np.ndarray]:
    """[3] wins, draws, losses from ``a``'s side against each of ``opponents`` (single policies), ``games``
    each, half with ``a`` on team 0 (an odd one more there); one batch of worlds per side for them all."""
    if any(len(o.members) != 1 for o in opponents):
        raise ConfigError("a payoff row plays single policies; a population opponent is a mixture of several")
    out = np.zeros((len(opponents), 3), dtype=int)
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        gen = torch.Generator().manual_seed(seed)
        for side, per in enumerate((games - games // 2, games // 2)):
            if per == 0:
                continue
            env = side_env(cfg, side, "any", per * len(opponents), seed)
            pa = a.team_policy(env, False, gen)
            members = [o.members[0] for o in opponents]
            pb = AssignedPolicy([m.make(env, False) for m in members], per, [m.source["kind"] == "checkpoint" for m in members])
            winner = run_episodes(env, TeamPolicies(env, (pa, pb) if side == 0 else (pb, pa)))["winner"].round().long().tolist()
            for j in range(len(opponents)):
                out[j] += record.tally("".join(outcome(w, side) for w in winner[j * per:(j + 1) * per]))
    return list(out)


__all__ = ["play_row_chunk", "row_chunks"]
