"""Your own policy in every verb: a template of a ``module:function`` competitor.

    PYTHONPATH=examples volleybots eval crossplay mine=my_policy:act zoo:1v1/bc_long scripted task=1v1 games=100
    PYTHONPATH=examples volleybots eval elo mine=my_policy:act zoo:1v1/bc zoo:1v1/dag_rally task=1v1

The verbs import this module by its name (so its folder must be on the Python path: ``PYTHONPATH``, or
install your package) and call ``act`` with a batch of observations, one row per drone of the team it
plays, ``[B, 39]`` on 1 vs 1 (mirrored to the +x side whichever side it plays), as a torch tensor; it
returns ``[B, 4]`` actions in [-1, 1]. ``act_numpy`` / ``numpy_player`` show the numpy route (what
Stable-Baselines3's ``model.predict`` takes): a module may name a competitor built with
``callable_competitor`` instead of a function.

Here the policy is the zoo's behaviour-cloned 1 vs 1 player acting on its mean, so its figures are
exactly those of ``zoo:1v1/bc`` (the test suite checks it). Replace ``act``'s body with your network.
"""

from __future__ import annotations

import torch
from tensordict import TensorDict

from volleybots import make_env
from volleybots.keys import ACTION, AGENTS, OBS, leaf
from volleybots.policies import callable_competitor, load_learner
from volleybots.zoo import lookup

# the clone's actor, loaded once when the module is imported (a policy is called every step)
_actor = load_learner(lookup("zoo:1v1/bc").checkpoint, make_env("1v1", 1), 1)[0].policy(deterministic=True)


def act(obs: torch.Tensor) -> torch.Tensor:
    """Observations [B, 39] -> actions [B, 4] (the clone's actor reads one drone per row)."""
    b = obs.shape[0]
    td = TensorDict({AGENTS: TensorDict({leaf(OBS): obs[:, None]}, batch_size=[b, 1])}, batch_size=[b])
    return _actor(td).get(ACTION)[:, 0]


def act_numpy(obs):
    """The same on numpy arrays."""
    return act(torch.as_tensor(obs)).numpy()


numpy_player = callable_competitor(act_numpy, "numpy_player", numpy=True, task="1v1")
