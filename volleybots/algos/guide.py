"""A guide: another run's Gaussian actor, frozen, for a learner whose own networks cannot take its weights.

``algo=sac init=RUN`` where RUN is a ``bc``, ``ppo`` or ``mappo`` run: SAC's actor is a tanh-Gaussian
MLP with LayerNorm and its critics are Q-functions, so nothing of RUN loads into them. Instead RUN's
actor is rebuilt as PPO builds it (from RUN's network keys) with RUN's weights, exactly, and SAC
learns a residual on its mean action (algos/sac.py: the actor starts as the clone, an optional penalty).
"""

from __future__ import annotations

from types import SimpleNamespace

import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torch import nn

from volleybots.algos.base import mlp
from volleybots.algos.ppo import ObsNorm, make_actor
from volleybots.keys import OBS, OBS_NORM

# the algorithms whose actor is PPO's Gaussian over PPO's MLP (bc's is PPO's by construction)
GUIDE_SOURCES = ("bc", "ppo", "mappo")


def can_guide(source) -> bool:
    """Whether ``source`` (a built algorithm) has an actor a ``Guide`` rebuilds: PPO's continuous one."""
    return source.name in GUIDE_SOURCES and source.continuous


class Guide(nn.Module):
    """PPO's Gaussian actor (and its observation normaliser, with ``obs_norm``), frozen.

    Its parameters carry the names of a PPO-family actor's ``init_parts()["actor"]`` (``actor.*``,
    ``obs_norm.*``), so the source's weights load as they are. ``net`` is what rebuilds it on
    ``resume=`` from the checkpoint alone (plain values: checkpoints load with ``weights_only``)."""

    def __init__(self, obs_dim: int, action_dim: int, net: dict):
        super().__init__()
        self.net_keys = {"hidden": [int(h) for h in net["hidden"]], "activation": str(net["activation"]), "obs_norm": bool(net["obs_norm"])}
        # the random initial weights are overwritten at once: they must not move the run's random stream
        with torch.random.fork_rng(devices=[]):
            body = mlp(obs_dim, action_dim, self.net_keys["hidden"], self.net_keys["activation"], out_gain=0.01)
            obs_in = OBS_NORM if self.net_keys["obs_norm"] else OBS
            self.actor, _ = make_actor(body, [obs_in], action_dim, SimpleNamespace(init_log_std=0.0), True)
        self.obs_norm = TensorDictModule(ObsNorm(obs_dim), [OBS], [OBS_NORM]) if self.net_keys["obs_norm"] else None
        self.requires_grad_(False)

    @classmethod
    def of(cls, source) -> "Guide":
        """The guide holding exactly ``source``'s actor (a built and loaded ``bc``/``ppo``/``mappo``)."""
        cfg = source.cfg
        guide = cls(source.obs_dim, source.action_dim, {"hidden": cfg.hidden, "activation": cfg.activation, "obs_norm": cfg.obs_norm})
        guide.to(source.device).load_state_dict(source.init_parts()["actor"].state_dict())
        return guide

    @torch.no_grad()
    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        """The mean action for observations [..., obs], clipped to [-1, 1] (what the env executes of it)."""
        td = TensorDict({OBS: obs}, batch_size=obs.shape[:-1])
        if self.obs_norm is not None:
            self.obs_norm(td)
        return self.actor.get_dist(td).mean.clamp(-1.0, 1.0)

    def checkpoint(self) -> dict:
        """What ``from_checkpoint`` rebuilds it from: the network keys and the weights."""
        return {"net": dict(self.net_keys), "weights": self.state_dict()}

    @classmethod
    def from_checkpoint(cls, obs_dim: int, action_dim: int, saved: dict, device) -> "Guide":
        guide = cls(obs_dim, action_dim, saved["net"]).to(device)
        guide.load_state_dict(saved["weights"])
        return guide


__all__ = ["GUIDE_SOURCES", "Guide", "can_guide"]
