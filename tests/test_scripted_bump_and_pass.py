"""Scripted Bump and Pass pair: plays full episodes with legal bumps and stays airborne."""

import torch

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


def test_bump_and_pass_pair_keeps_passing_for_the_whole_episode():
    _, td = episodes("bump_and_pass", 800)
    done = td["next", "done"].squeeze(-1)
    first = done.float().argmax(-1)  # the step each env's first episode ends
    envs = torch.arange(done.shape[0])
    bumps = td["next", "stats", "bumps"].squeeze(-1)[envs, first]
    # seed 2 gives 13 bumps in every env, each episode running the full 800 steps (16 s)
    assert (first == 799).float().mean() >= 0.875
    assert bumps.mean() >= 12.5
