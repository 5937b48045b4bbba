"""TD3 (Fujimoto et al. 2018) on TorchRL's ``TD3Loss``: DDPG's networks with twin critics (the
smaller target of the two), target policy smoothing (clipped Gaussian noise on the target action)
and an actor updated every ``policy_delay`` critic updates."""

from __future__ import annotations

from dataclasses import dataclass

from torchrl.objectives import TD3Loss

from volleybots.algos.ddpg import DDPG, DDPGConfig
from volleybots.errors import ranged


@dataclass
class TD3Config(DDPGConfig):
    name: str = "td3"
    policy_delay: int = ranged(2, ge=1)
    target_noise: float = ranged(0.1, ge=0)
    noise_clip: float = ranged(0.2, ge=0)


class TD3(DDPG):
    name = "td3"
    config_cls = TD3Config

    def make_loss(self, actor, critic):
        return TD3Loss(
            actor,
            critic,
            bounds=(-1.0, 1.0),
            num_qvalue_nets=2,
            policy_noise=self.cfg.target_noise,
            noise_clip=self.cfg.noise_clip,
            loss_function=self.cfg.critic_loss,
        )

    def critic_params(self):
        return self.loss.qvalue_network_params.values(True, True)

    def losses(self, td):
        loss_critic, info = self.loss.value_loss(td)
        out = {"critic": loss_critic}
        # the step about to be taken is number grad_steps + 1
        if (self.grad_steps + 1) % self.cfg.policy_delay == 0:
            out["actor"], _ = self.loss.actor_loss(td)
        return out, {"q_pred": info["pred_value"], "q_target": info["target_value"]}
