"""MADDPG (Lowe et al. 2017) on TorchRL's ``DDPGLoss``, for the cooperative tasks.

Decentralised deterministic actors (each drone's tanh actor sees its own observation; one network
per drone unless ``share_actor``) and a centralised critic per drone that sees every drone's
observation and action (TorchRL ``MultiAgentMLP(centralized=True)`` over the drones' observation and
action concatenated; one network per drone unless ``share_critic``). Each drone's critic learns its
own reward by TD(0) with target actors and critics; the actors climb the sum of the critics with
all drones' actions from the current actors (TorchRL's multi-agent DDPG). Gaussian noise on the
actions while collecting, and the replay buffer, warm-up and soft target updates of the off-policy
single-agent methods (``offpolicy.py``) with one replay item per joint step.
"""

from __future__ import annotations

from dataclasses import dataclass

from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.modules.models.multiagent import MultiAgentMLP
from torchrl.objectives import DDPGLoss

from volleybots.algos.ddpg import DDPG, DDPGConfig
from volleybots.algos.offpolicy import QNet, joint_transitions, net_kwargs
from volleybots.keys import ACTION, AGENT_DONE, AGENT_TERMINATED, OBS, Q_VALUE, REWARD, nxt


@dataclass
class MADDPGConfig(DDPGConfig):
    name: str = "maddpg"
    share_actor: bool = False
    share_critic: bool = False


class CentralisedQ(QNet):
    """Q_i(all observations, all actions) for every drone i: [*, A, obs] and [*, A, action] -> [*, A, 1]."""

    def __init__(self, obs_dim: int, action_dim: int, n_agents: int, cfg, device):
        nn.Module.__init__(self)
        self.net = MultiAgentMLP(
            obs_dim + action_dim, 1, n_agents, centralized=True, share_params=cfg.share_critic, device=device, **net_kwargs(cfg)
        )


class MADDPG(DDPG):
    name = "maddpg"
    config_cls = MADDPGConfig
    multi_agent = True
    task_kinds = ("cooperative",)
    reward_key = nxt(REWARD)

    def build(self) -> None:
        cfg, dev, a = self.cfg, self.device, self.n_agents
        policy = MultiAgentMLP(
            self.obs_dim, self.action_dim, a, centralized=False, share_params=cfg.share_actor, device=dev, **net_kwargs(cfg)
        )
        self.actor_net = nn.Sequential(policy, nn.Tanh())
        actor = TensorDictModule(self.actor_net, [OBS], [ACTION])
        critic = TensorDictModule(CentralisedQ(self.obs_dim, self.action_dim, a, cfg, dev), [OBS, ACTION], [Q_VALUE])
        self.loss = DDPGLoss(actor, critic, loss_function=cfg.critic_loss, delay_actor=True, delay_value=True)
        self.loss.set_keys(state_action_value=Q_VALUE, reward=REWARD, done=AGENT_DONE, terminated=AGENT_TERMINATED)
        self.optims = {
            "actor": self.adam(self.loss.actor_network_params.values(True, True)),
            "critic": self.adam(self.critic_params()),
        }

    def replay_items(self, batch: TensorDictBase):
        return joint_transitions(batch).reshape(-1)
