"""Scripted match players: registered, they play full games against random teams without the
violations a sane player never commits, and each side plays from its own mirrored view."""

import pytest
import torch

import volleybots
from volleybots.rules import Referee
from volleybots.scripted import SCRIPTED_POLICIES, make_scripted_policy
from volleybots.tasks.multi import TeamPolicies

OWN_FAULTS = [Referee.FAULTS.index(f) for f in ("cross", "net_drone", "wrong_turn", "too_soon")]


def random_policy(td):
    td.set(("agents", "action"), torch.rand(*td["agents"].batch_size, 4) * 2 - 1)
    return td


def test_players_are_registered_for_every_multi_drone_task():
    for task in ("bump_and_pass", "set_and_spike_easy", "set_and_spike_hard", "1v1", "3v3", "6v6"):
        assert task in SCRIPTED_POLICIES
        env = volleybots.make_env(task, num_envs=2)
        td = make_scripted_policy(env)(env.reset())
        act = td["agents", "action"]
        assert act.shape == (2, env.n_drones, 4) and torch.isfinite(act).all() and act.abs().max() <= 1.0


def play(task, scripted_team, steps, n=6, serve=None):
    env = volleybots.make_env(task, num_envs=n, seed=4, serve=serve)
    pols = [random_policy, random_policy]
    pols[scripted_team] = make_scripted_policy(env)
    td = env.rollout(steps, policy=TeamPolicies(env, tuple(pols)), break_when_any_done=False)
    nxt = td["next"]
    done = nxt["done"].squeeze(-1)
    return env, {k: nxt["stats", k].squeeze(-1)[done] for k in ("winner", "reason", "draw")}, td


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_scripted_1v1_team_never_loses_to_random_on_either_side():
    for team in (0, 1):
        env, st, td = play("1v1", team, 120, serve=1 - team)  # the random side serves: games get decided
        assert len(st["winner"]) >= 6
        assert not (st["winner"] == 1 - team).any()  # it commits no fault and never lets a serve drop
        assert (st["winner"] == team).any()
        # the scripted drone stays on its own half and in the air the whole time
        pos = td["next", "agents", "observation"][..., team, :3]
        assert (pos[..., 0] > 0).all() and (pos[..., 2] > 0.5).all()  # own mirrored frame: x > 0


def test_scripted_3v3_team_commits_no_drone_faults_against_random():
    env, st, td = play("3v3", 0, 100, n=4)
    lost = st["winner"] == 1
    assert not torch.isin(st["reason"][lost].long(), torch.tensor(OWN_FAULTS)).any()
    pos = td["next", "agents", "observation"][..., :3, :3]
    assert (pos[..., 0] > 0).all() and (pos[..., 2] > 0.5).all()
