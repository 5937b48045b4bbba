"""An error inside a policy that non-finite numbers explain is one line naming them (issue 57, class
10): a response's training once ended with tensordict's "Failed while executing module '0'." as the
last line of a traceback. ``play.episodes.act`` is where every training batch and evaluation acts."""

from __future__ import annotations

import pytest
import torch
from tensordict.nn import TensorDictModule, TensorDictSequential

from volleybots import make_env
from volleybots.config import ConfigError
from volleybots.keys import ACTION, OBS
from volleybots.play.episodes import act, collect


class Sampler(torch.nn.Module):
    """Draws an action index from softmax(logits): torch.multinomial raises on NaN probabilities."""

    def __init__(self, n: int = 4):
        super().__init__()
        self.logits = torch.nn.Parameter(torch.zeros(n))

    def forward(self, obs):
        probs = torch.softmax(self.logits + 0 * obs.sum(-1, keepdim=True), -1)
        return torch.multinomial(probs.reshape(-1, probs.shape[-1]), 1).reshape(*obs.shape[:-1], 1).float().expand(*obs.shape[:-1], 4)


def _policy():
    return TensorDictSequential(TensorDictModule(Sampler(), [OBS], [ACTION]))


def test_weights_that_went_nan_are_named(tmp_path):
    env = make_env("solo_bump", num_envs=2)
    policy = _policy()
    collect(env, policy, env.reset(), 2)  # finite weights: it acts
    with torch.no_grad():
        policy[0].module.logits.fill_(float("nan"))
    named = r"failed while acting \(RuntimeError: .*\) because its weight module\.0\.module\.logits holds NaN.*algo\.lr"
    with pytest.raises(ConfigError, match=named):
        collect(env, policy, env.reset(), 2)


def test_a_nan_observation_is_named():
    env = make_env("solo_bump", num_envs=2)
    td = env.reset()
    td.set(OBS, torch.full_like(td.get(OBS), float("nan")))

    def strict(td):
        if not bool(torch.isfinite(td.get(OBS)).all()):
            raise ValueError("Expected parameter loc to satisfy the constraint Real()")
        return td

    with pytest.raises(ConfigError, match=r"ValueError: Expected parameter loc.*because its observation holds NaN or infinity"):
        act(strict, td)


def test_an_error_that_numbers_do_not_explain_is_left_as_it_is():
    env = make_env("solo_bump", num_envs=2)

    def broken(td):
        raise KeyError("a bug")

    with pytest.raises(KeyError, match="a bug"):
        act(broken, env.reset())
