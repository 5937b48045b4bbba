"""Scripted cooperative players play full episodes: the opening touch is a legal racket hit, the
setter always sets, and nobody falls out of the air."""

import volleybots
from volleybots.scripted import make_scripted_policy


def episodes(task, steps, n=8):
    env = volleybots.make_env(task, num_envs=n, seed=2)
    td = env.rollout(steps, policy=make_scripted_policy(env), break_when_any_done=False)
    nxt = td["next"]
    done = nxt["done"].squeeze(-1)
    return {k: nxt["stats", k].squeeze(-1)[done] for k in env._stats_keys}, td


def test_bump_and_pass_pair_opens_with_a_legal_bump_and_stays_airborne():
    st, td = episodes("bump_and_pass", 150)
    # every env makes its opening touch (a legal racket hit by drone 1) within the 3 s, and every
    # episode that ended had it
    assert (td["next", "stats", "hits"].squeeze(-1).amax(-1) >= 1).all()
    assert (st["hits"] >= 1).all()
    assert (st["r_drone_misbehave"] == 0).all()
    assert (td["next", "agents", "observation"][..., 2] > 1.0).all()  # nobody sinks


def test_setter_always_sets_to_the_attacker():
    for task in ("set_and_spike_easy", "set_and_spike_hard"):
        st, td = episodes(task, 150)
        assert len(st["setter_hit"]) >= 6
        assert (st["setter_hit"] == 1).all()
        assert ((st["success_rate"] >= 0.25) & (st["success_rate"] <= 1.0)).all()
        # the setter never leaves its own half or drops low
        setter = td["next", "agents", "observation"][..., 0, :3]
        assert (setter[..., 0] > 0.2).all() and (setter[..., 2] > 1.0).all()
