"""Matches: specs, observation sizes, episode limits, agent grouping and long random rollouts."""

import pytest
import torch
from torchrl.envs.utils import check_env_specs

import volleybots
from volleybots.tasks import TASKS
from volleybots.tasks.multi import TeamPolicies

MATCHES = {"1v1": (39, 800, 1), "3v3": (57, 500, 3), "6v6": (78, 500, 6)}


@pytest.mark.parametrize("action_space", ["prt", "ctbr", "discrete"])
@pytest.mark.parametrize("name", list(MATCHES))
def test_specs_and_observation_sizes(name, action_space):
    env = volleybots.make_env(name, num_envs=2, action_space=action_space)
    check_env_specs(env)
    obs, limit, size = MATCHES[name]
    td = env.reset()
    expect = obs - 4 if action_space == "ctbr" else obs
    assert td["agents", "observation"].shape == (2, 2 * size, expect)
    assert env.episode_len == limit
    assert env.teams == (0,) * size + (1,) * size


def test_registry_names():
    assert {"1v1", "3v3", "6v6"} <= set(TASKS)


def test_team_helpers_split_and_merge_the_agents():
    env = volleybots.make_env("3v3", num_envs=3, seed=0)
    td = env.reset()
    assert env.team_index(0).tolist() == [0, 1, 2] and env.team_index(1).tolist() == [3, 4, 5]
    assert env.team_ids.tolist() == [0, 0, 0, 1, 1, 1]
    sub = env.select_team(td, 1)
    assert sub.batch_size == (3, 3)
    assert torch.equal(sub["observation"], td["agents", "observation"][:, 3:])
    act = torch.full((3, 3, 4), 0.25)
    env.write_team(td, 1, sub.set("action", act))
    env.write_team(td, 0, env.select_team(td, 0).set("action", -act))
    assert (td["agents", "action"][:, 3:] == 0.25).all() and (td["agents", "action"][:, :3] == -0.25).all()


def test_team_policies_drive_each_team_with_its_own_policy():
    env = volleybots.make_env("1v1", num_envs=4, seed=0)
    seen = {}

    def const(value, team):
        def policy(td):
            seen[team] = td["agents", "observation"].shape
            return td.set(("agents", "action"), torch.full((*td["agents"].batch_size, 4), value))
        return policy

    td = env.rollout(3, policy=TeamPolicies(env, (const(0.5, 0), const(-0.5, 1))), break_when_any_done=False)
    assert seen == {0: (4, 1, 39), 1: (4, 1, 39)}
    assert (td["agents", "action"][:, :, 0] == 0.5).all() and (td["agents", "action"][:, :, 1] == -0.5).all()


def test_team_one_starts_as_the_image_of_team_zero():
    env = volleybots.make_env("6v6", num_envs=1, seed=0)
    env.reset()
    a = env.anchors
    assert torch.allclose(a[6:], a[:6] * torch.tensor([-1.0, -1.0, 1.0]))
    obs = env.observe()[0]
    # each side sees itself near its own-frame anchor, in front of the net (x > 0), upright
    k = env.team_size
    assert (obs[:, 23:26].abs() <= 0.1 + 1e-6).all() and (obs[:, 0] > 0).all()
    assert torch.allclose(obs[:k, 3:7], obs[k:, 3:7], atol=1e-6)


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
@pytest.mark.parametrize("name", list(MATCHES))
def test_ten_thousand_random_steps_stay_finite_and_stats_add_up(name):
    env = volleybots.make_env(name, num_envs=64, seed=3)
    td = env.rollout(160, break_when_any_done=False)  # 10k env-steps, auto-reset
    nxt = td["next"]
    assert torch.isfinite(nxt["agents", "observation"]).all() and torch.isfinite(nxt["agents", "reward"]).all()
    for v in env.physics.state.tensors().values():
        assert torch.isfinite(v).all()
    done = nxt["done"].squeeze(-1)
    assert done.sum() > 64  # random drones crash quickly
    st = {k: nxt["stats", k].squeeze(-1)[done] for k in ("win", "loss", "draw", "winner", "reason")}
    assert torch.equal(st["win"] + st["loss"] + st["draw"], torch.ones_like(st["win"]))
    assert torch.equal(st["winner"] == 0, st["win"] == 1) and torch.equal(st["winner"] == -1, st["draw"] == 1)
    assert ((st["reason"] >= 0) == (st["draw"] == 0)).all()
