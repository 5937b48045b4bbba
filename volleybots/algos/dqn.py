"""DQN (Mnih et al. 2015) on TorchRL's ``DQNLoss``, for the discrete action space (each rotor -1 or
+1: 16 joint actions). Collection is epsilon-greedy on the online Q of the *current* observation (the
reference evaluated it on the next one); the bootstrap uses the target network, or with ``double_q``
the online network's argmax valued by the target network."""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torchrl.modules import QValueActor
from torchrl.objectives import DQNLoss

from volleybots.algos.offpolicy import OffPolicy, OffPolicyConfig, net
from volleybots.errors import ranged


@dataclass
class DQNConfig(OffPolicyConfig):
    name: str = "dqn"
    hidden: list[int] = ranged(factory=lambda: [256, 128], ge=1)
    double_q: bool = False
    eps_start: float = ranged(1.0, ge=0, le=1)
    eps_end: float = ranged(0.05, ge=0, le=1)
    eps_anneal_frames: int = ranged(200_000, ge=0)


class DQN(OffPolicy):
    name = "dqn"
    config_cls = DQNConfig
    actor_attr = "qnet"
    action_spaces = ("discrete",)
    info_keys = ("q_max",)

    def build(self) -> None:
        self.qnet = net(self.obs_dim, self.action_dim, self.cfg).to(self.device)
        actor = QValueActor(self.qnet, in_keys=["observation"], action_space="categorical")
        self.loss = DQNLoss(
            actor, loss_function=self.cfg.critic_loss, delay_value=True, double_dqn=self.cfg.double_q, action_space="categorical"
        )
        self.optims = {"q": self.adam(self.loss.value_network_params.values(True, True))}

    @property
    def epsilon(self) -> float:
        cfg = self.cfg
        frac = min(1.0, self.frames / cfg.eps_anneal_frames) if cfg.eps_anneal_frames else 1.0
        return cfg.eps_start + (cfg.eps_end - cfg.eps_start) * frac

    def extra_logs(self):
        return {"epsilon": self.epsilon}

    def log_keys(self):
        return [*super().log_keys(), "epsilon"]

    def losses(self, td):
        out = self.loss(td)
        with torch.no_grad():
            q_max = self.qnet(td["observation"]).max(-1).values
        return {"q": out["loss"]}, {"q_max": q_max}

    def greedy(self, obs):
        return self.qnet(obs).argmax(-1)

    def explore(self, obs):
        greedy = self.greedy(obs)
        explore = torch.rand(greedy.shape, generator=self.gen, device=greedy.device) < self.epsilon
        return torch.where(explore, self.random_action(greedy.shape), greedy)
