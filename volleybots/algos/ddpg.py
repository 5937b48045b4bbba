"""DDPG (Lillicrap et al. 2015) on TorchRL's ``DDPGLoss``: a deterministic tanh actor, one Q critic
with smooth-L1 TD(0) loss, target actor and critic, Gaussian exploration noise on the actions."""

from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.modules import ValueOperator
from torchrl.objectives import DDPGLoss

from volleybots.algos.offpolicy import OffPolicy, OffPolicyConfig, QNet, net
from volleybots.errors import ranged


@dataclass
class DDPGConfig(OffPolicyConfig):
    name: str = "ddpg"
    exploration_noise: float = ranged(0.1, ge=0)


class DDPG(OffPolicy):
    name = "ddpg"
    config_cls = DDPGConfig
    info_keys = ("q_pred", "q_target")

    def build(self) -> None:
        cfg = self.cfg
        self.actor_net = nn.Sequential(net(self.obs_dim, self.action_dim, cfg), nn.Tanh()).to(self.device)
        actor = TensorDictModule(self.actor_net, ["observation"], ["action"])
        critic = ValueOperator(QNet(self.obs_dim, self.action_dim, cfg), in_keys=["observation", "action"]).to(self.device)
        self.loss = self.make_loss(actor, critic)
        self.optims = {
            "actor": self.adam(self.loss.actor_network_params.values(True, True)),
            "critic": self.adam(self.critic_params()),
        }

    def make_loss(self, actor, critic):
        return DDPGLoss(actor, critic, loss_function=self.cfg.critic_loss, delay_actor=True, delay_value=True)

    def critic_params(self):
        return self.loss.value_network_params.values(True, True)

    def losses(self, td):
        loss_critic, info = self.loss.loss_value(td)
        loss_actor, _ = self.loss.loss_actor(td)
        return {"critic": loss_critic, "actor": loss_actor}, {"q_pred": info["pred_value"], "q_target": info["target_value"]}

    def greedy(self, obs):
        return self.actor_net(obs)

    def explore(self, obs):
        a = self.actor_net(obs)
        return (a + self.cfg.exploration_noise * torch.randn(a.shape, generator=self.gen, device=a.device)).clamp(-1.0, 1.0)
