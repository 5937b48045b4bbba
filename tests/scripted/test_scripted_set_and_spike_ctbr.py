"""Scripted Set and Spike pair flown through the CTBR action space (collective thrust and body rates)."""

import pytest
import torch
from helpers import first_episodes

pytestmark = pytest.mark.slow  # the scripted pair searches its touches on the world model: minutes on 2 cores


def test_ctbr_pair_still_plays():
    # measured: setter_hit 1.0, attacker_hit 0.63, success 0.61 (CTBR's slower attitude loop does
    # not fly the throw as well; the lookaheads model its rate controller too)
    st, _, _ = first_episodes("set_and_spike_easy", action_space="ctbr")
    assert st["setter_hit"].mean() >= 0.9
    assert st["attacker_hit"].mean() >= 0.55
    assert torch.isfinite(st["success_rate"]).all() and st["success_rate"].mean() >= 0.55
