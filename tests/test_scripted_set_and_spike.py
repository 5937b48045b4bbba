"""Scripted Set and Spike pair (Easy, Hard): the setter always sets and nobody leaves its half."""

import volleybots
from volleybots.scripted import make_scripted_policy


def episodes(task, steps, n=8):
    env = volleybots.make_env(task, num_envs=n, seed=2)
    td = env.rollout(steps, policy=make_scripted_policy(env), break_when_any_done=False)
    nxt = td["next"]
    done = nxt["done"].squeeze(-1)
    return {k: nxt["stats", k].squeeze(-1)[done] for k in env._stats_keys}, td


def test_setter_always_sets_to_the_attacker():
    for task in ("set_and_spike_easy", "set_and_spike_hard"):
        st, td = episodes(task, 150)
        assert len(st["setter_hit"]) >= 6
        assert (st["setter_hit"] == 1).all()
        assert ((st["success_rate"] >= 0.25) & (st["success_rate"] <= 1.0)).all()
        # the setter never leaves its own half or drops low
        setter = td["next", "agents", "observation"][..., 0, :3]
        assert (setter[..., 0] > 0.2).all() and (setter[..., 2] > 1.0).all()
