"""Scripted Set and Spike pair (Easy, Hard): the setter always sets, the attacker spikes most sets
down over the net, on Easy a good share of them into the target, on Hard a tip the defence racket
never touches."""

import functools

import torch

import volleybots
from volleybots.scripted import make_scripted_policy

STEPS = 170  # every first episode is over by then (a spiked ball lands about 2.8 s in)


@functools.cache  # several tests read the same episodes (nothing mutates them)
def first_episodes(task, n=32, seed=2, action_space="prt"):
    """Stats of each env's first episode, and the rollout."""
    env = volleybots.make_env(task, num_envs=n, seed=seed, action_space=action_space)
    td = env.rollout(STEPS, policy=make_scripted_policy(env), break_when_any_done=False)
    nxt = td["next"]
    done = nxt["done"].squeeze(-1)
    first = done & (done.long().cumsum(1) == 1)
    assert bool(first.any(1).all()), "an env did not finish its first episode"
    return {k: nxt["stats", k].squeeze(-1)[first] for k in env._stats_keys}, td, first


def test_setter_always_sets_and_stays_home():
    for task in ("set_and_spike_easy", "set_and_spike_hard"):
        st, td, first = first_episodes(task)
        assert (st["setter_hit"] == 1).all()
        # until its episode ends the setter never leaves its own half or drops low
        alive = (first.long().cumsum(1) - first.long()) == 0
        setter = td["next", "agents", "observation"][..., 0, :3][alive]
        assert (setter[:, 0] > 0.2).all() and (setter[:, 2] > 1.0).all()


def test_spikes_go_down_over_the_net():
    # measured on these 32 episodes: Easy attacker_hit, downward, in_target and success all 1.0
    # (the benchmark's 100 episodes: 0.993 on seeds 0-2; without the lookaheads 0.45 here)
    floors = {"attacker_hit": 0.95, "downward_spike": 0.95, "in_target": 0.9, "success_rate": 0.97}
    st, _, _ = first_episodes("set_and_spike_easy")
    got = {k: st[k].mean().item() for k in floors}
    assert all(got[k] >= v for k, v in floors.items()), got
    # a spike that counts nearly always goes down
    assert st["downward_spike"].sum() >= 0.85 * st["attacker_hit"].sum()


def test_hard_tip_is_never_defended():
    # measured on these 32 episodes: attacker_hit 0.97, downward 0.91, success_spike 0.91,
    # success 0.945 (the benchmark's 100 episodes: 0.945 seed 0); the tip is slower than the
    # defence racket's trigger, so it never touches the ball
    floors = {"attacker_hit": 0.9, "downward_spike": 0.84, "success_spike": 0.84, "success_rate": 0.9}
    st, _, _ = first_episodes("set_and_spike_hard")
    got = {k: st[k].mean().item() for k in floors}
    assert all(got[k] >= v for k, v in floors.items()), got
    assert (st["intercepted"] == 0).all()


def test_ctbr_pair_still_plays():
    # measured: setter_hit 1.0, attacker_hit 0.63, success 0.61 (CTBR's slower attitude loop does
    # not fly the throw as well; the lookaheads model its rate controller too)
    st, _, _ = first_episodes("set_and_spike_easy", n=16, action_space="ctbr")
    assert st["setter_hit"].mean() >= 0.9
    assert st["attacker_hit"].mean() >= 0.55
    assert torch.isfinite(st["success_rate"]).all() and st["success_rate"].mean() >= 0.55


def test_low_set_is_wanted_nearer_the_net():
    # a set that peaks low falls slowly and is spiked slower, so the setter's cost wants it to come
    # down nearer the net (``set_low_near`` m per metre under ``set_apex``); a full-height set is
    # wanted on the attack spot itself
    from types import SimpleNamespace

    from volleybots.scripted.ballistics import launch_for_apex
    from volleybots.scripted.set_and_spike import SetAndSpikePlayer

    pol = SetAndSpikePlayer()
    c = pol.cfg
    a = pol.attack_ball(torch.zeros(3))
    start = torch.tensor([2.0, -2.5, 2.9])
    # two sets, one down on the spot and one 0.3 m's worth of ``set_low_near`` nearer the net
    targets = torch.stack((a[:2], a[:2] - torch.tensor([c.set_low_near * 0.3, 0.0])))
    for shortfall in (0.3, 0.0):
        vel = launch_for_apex(start.expand(2, 3), targets, c.set_apex - shortfall, a[2], pol.params.gravity)
        o = SimpleNamespace(
            ball_pos=start.expand(2, 3), ball_vel=vel, hit=torch.ones(2, dtype=torch.bool), body=torch.zeros(2, dtype=torch.bool)
        )
        cost = pol.set_cost(o)
        assert int(cost.argmin()) == (1 if shortfall > 0 else 0), (shortfall, cost)
        # what it costs beyond the landing is the apex's shortfall, at ``set_low_cost`` per metre
        assert torch.allclose(cost.min(), torch.tensor(c.set_low_cost * shortfall), atol=1e-4), cost
