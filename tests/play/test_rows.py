"""Payoff rows (``volleybots.play.rows``): one competitor against many in one batch of worlds, each world
assigned to one opponent for its game, chunked so that a chunk's seed alone decides its games."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from tensordict import TensorDict

from volleybots.config import load
from volleybots.keys import ACTION, AGENTS
from volleybots.play.pool import payoff_row
from volleybots.play.rows import play_row_chunk, row_chunks
from volleybots.policies import resolve_competitor
from volleybots.policies.competitors import AssignedPolicy


def test_an_assigned_policy_gives_each_block_of_envs_its_own_member_stateless_or_not():
    def const(k):
        return lambda td: td.set(ACTION, torch.full((*td.get(AGENTS).batch_size, 2), float(k)))

    td = TensorDict({AGENTS: TensorDict({"observation": torch.zeros(6, 3, 5)}, [6, 3])}, [6])
    out = AssignedPolicy([const(0), const(1), const(2)], 2, [True, False, True])(td)
    assert out.get(ACTION)[:, 0, 0].tolist() == [0, 0, 1, 1, 2, 2]


def test_row_chunks_fill_a_batch_a_side_and_keep_the_order():
    assert row_chunks(10, 100, 256) == [range(0, 5), range(5, 10)]  # 50 worlds a side per opponent
    assert row_chunks(3, 101, 50) == [range(0, 1), range(1, 2), range(2, 3)]  # 51 a side: one per chunk
    assert row_chunks(0, 100) == []


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_a_payoff_row_plays_every_opponent_its_games_and_a_chunk_is_its_own_seed():
    cfg = load(["task=1v1", "task.episode_len=30"])  # short games: the bookkeeping is the point
    a = resolve_competitor("zoo:1v1/bc")
    opps = [resolve_competitor(s) for s in ("random", "c=zoo:1v1/bc", "r=random")]
    rows = payoff_row(cfg, a, opps, 8, seed=3)  # one chunk: 12 worlds a side
    assert [int(r.sum()) for r in rows] == [8, 8, 8]
    assert np.array_equal(np.stack(rows), np.stack(payoff_row(cfg, a, opps, 8, seed=3)))
    # chunks of one opponent each (4 worlds a side) are the chunk of that opponent alone, on seed + its index
    alone = payoff_row(cfg, a, opps, 8, seed=3, batch=4)
    assert [r.tolist() for r in alone] == [play_row_chunk(cfg, a, [o], 8, 3 + j)[0].tolist() for j, o in enumerate(opps)]
    assert sum(int(r[0]) for r in rows + alone) > 0  # the clone wins games: decisive games, not an all-draw table
