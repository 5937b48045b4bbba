"""The scripted 3 vs 3 team rallies against itself: the serve is passed and attacked at an
opponent, who receives it (at least 3 touches in a game), from either side's serve."""

import pytest
import torch

import volleybots
from volleybots.scripted import make_scripted_policy
from volleybots.tasks.multi import TeamPolicies


def first_games(task, serve, n=4, steps=200):
    """Touches of both teams in each env's first game, up to its end or the last step (a long rally)."""
    env = volleybots.make_env(task, num_envs=n, seed=7, serve=serve)
    player = make_scripted_policy(env)
    td = env.rollout(steps, policy=TeamPolicies(env, (player, player)), break_when_any_done=False)
    nxt = td["next"]
    done = nxt["done"].squeeze(-1)  # [N, T]
    first = torch.where(done.any(1), done.float().argmax(1), done.shape[1] - 1)
    envs = torch.arange(n)
    return nxt["stats", "hits_team0"].squeeze(-1)[envs, first] + nxt["stats", "hits_team1"].squeeze(-1)[envs, first]


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_scripted_3v3_team_rallies_against_itself():
    touches = torch.cat([first_games("3v3", serve) for serve in (0, 1)])
    assert (touches >= 3).float().mean() >= 0.75, touches
