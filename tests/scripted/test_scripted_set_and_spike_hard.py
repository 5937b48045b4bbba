"""Scripted Set and Spike pair, Hard: the setter always sets and stays home, and the attacker's tip
is one the defence racket never touches."""

import pytest
from helpers import first_episodes, setter_sets_and_stays_home

pytestmark = pytest.mark.slow  # the scripted pair searches its touches on the world model: minutes on 2 cores


def test_setter_always_sets_and_stays_home_on_hard():
    setter_sets_and_stays_home("set_and_spike_hard")


def test_hard_tip_is_never_defended():
    # measured on these 16 episodes: attacker_hit 1.0, downward 1.0, success_spike 0.94, success
    # 0.98 (on 32: 0.97, 0.91, 0.91, 0.945; the benchmark's 100 episodes: 0.945 seed 0); the tip is slower than the
    # defence racket's trigger, so it never touches the ball
    floors = {"attacker_hit": 0.9, "downward_spike": 0.84, "success_spike": 0.84, "success_rate": 0.9}
    st, _, _ = first_episodes("set_and_spike_hard")
    got = {k: st[k].mean().item() for k in floors}
    assert all(got[k] >= v for k, v in floors.items()), got
    assert (st["intercepted"] == 0).all()
