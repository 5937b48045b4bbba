"""SAC (Haarnoja et al. 2018, the version without a state-value network) on TorchRL's ``SACLoss``:
a tanh-squashed Gaussian actor, twin critics with targets, and a learned temperature that drives the
policy's entropy toward ``target_entropy_scale x action_dim``."""

from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torch import nn
from torchrl.modules import ProbabilisticActor, TanhNormal, ValueOperator
from torchrl.objectives import SACLoss

from volleybots.algos.offpolicy import OffPolicy, OffPolicyConfig, QNet, net
from volleybots.errors import ranged


@dataclass
class SACConfig(OffPolicyConfig):
    name: str = "sac"
    alpha_init: float = ranged(0.1, gt=0)
    alpha_lr: float = ranged(5e-4, gt=0)
    target_entropy_scale: float = ranged(-0.5, ge=-10, le=10)  # x action_dim: the entropy the temperature aims at


class SAC(OffPolicy):
    name = "sac"
    config_cls = SACConfig
    info_keys = ("alpha", "entropy")

    def build(self) -> None:
        cfg = self.cfg
        # loc and a softplus-mapped scale of the Gaussian before the tanh
        self.head = nn.Sequential(net(self.obs_dim, 2 * self.action_dim, cfg), NormalParamExtractor()).to(self.device)
        actor = ProbabilisticActor(
            TensorDictModule(self.head, ["observation"], ["loc", "scale"]),
            in_keys=["loc", "scale"],
            distribution_class=TanhNormal,
            distribution_kwargs={"low": -1.0, "high": 1.0},
        )
        critic = ValueOperator(QNet(self.obs_dim, self.action_dim, cfg), in_keys=["observation", "action"]).to(self.device)
        self.loss = SACLoss(
            actor,
            critic,
            num_qvalue_nets=2,
            loss_function=self.cfg.critic_loss,
            alpha_init=cfg.alpha_init,
            target_entropy=cfg.target_entropy_scale * self.action_dim,
        )
        self.optims = {
            "actor": self.adam(self.loss.actor_network_params.values(True, True)),
            "critic": self.adam(self.loss.qvalue_network_params.values(True, True)),
            "alpha": self.adam([self.loss.log_alpha], lr=cfg.alpha_lr),
        }

    def losses(self, td):
        out = self.loss(td)
        losses = {"critic": out["loss_qvalue"], "actor": out["loss_actor"], "alpha": out["loss_alpha"]}
        return losses, {"alpha": out["alpha"], "entropy": out["entropy"]}

    def greedy(self, obs):
        loc, _ = self.head(obs)
        return torch.tanh(loc)

    def explore(self, obs):
        loc, scale = self.head(obs)
        return torch.tanh(loc + scale * torch.randn(loc.shape, generator=self.gen, device=loc.device))
