"""QMIX (Rashid et al. 2018) on TorchRL's ``QMixer`` / ``QMixerLoss``, for the cooperative tasks in
the discrete action space (each rotor -1 or +1: 16 actions per drone, the paper's 2 bins).

Every drone has the same Q network over its own observation (the id one-hot in the observation tells
the drones apart); the mixer turns the drones' chosen Q values into the team's Q with weights that
hyper-networks compute from the global state (the concatenated observations, as MAPPO's critic sees
them, first encoded by an MLP) and that are made non-negative, so the team's Q is monotonic in every
drone's Q and each drone's greedy action is the team's greedy joint action. The TD(0) target is the
team reward (the drones' rewards summed) plus the discounted target mixer over the target networks'
greedy Q of the next observations; ``terminated`` alone cuts it. Collection is epsilon-greedy per
drone, annealed by env steps, as DQN's.

Replay items are chunks: one env's ``steps_per_batch`` consecutive joint steps, as in the reference
(buffer 1024 chunks, batches of 128 chunks); a sampled batch is flattened into its steps.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.modules import QValueModule
from torchrl.modules.models.multiagent import QMixer
from torchrl.objectives.multiagent import QMixerLoss

from volleybots.algos.dqn import DQN, DQNConfig
from volleybots.algos.offpolicy import joint_transitions, net
from volleybots.errors import ConfigError, ranged
from volleybots.keys import ACTION, ACTION_VALUE, CHOSEN_VALUE, NEXT, OBS, REWARD, nxt


@dataclass
class QMIXConfig(DQNConfig):
    name: str = "qmix"
    hidden: list[int] = field(default_factory=lambda: [256, 128])
    buffer_size: int = 1024
    batch_size: int = 128
    gamma: float = 0.99
    critic_loss: str = "l2"
    mixing_embed_dim: int = ranged(32, ge=1)


class StateMixer(nn.Module):
    """TorchRL's ``QMixer`` over an MLP encoding of the global state (all observations concatenated):
    [*, A, 1] chosen Q values and [*, A, obs] observations -> [*, 1] team Q."""

    def __init__(self, obs_dim: int, n_agents: int, cfg, device):
        super().__init__()
        width = cfg.hidden[-1]
        self.encoder = net(obs_dim * n_agents, width, cfg).to(device)
        self.mixer = QMixer(state_shape=(width,), mixing_embed_dim=cfg.mixing_embed_dim, n_agents=n_agents, device=device)

    def forward(self, chosen: torch.Tensor, obs: torch.Tensor) -> torch.Tensor:
        return self.mixer(chosen, self.encoder(obs.flatten(-2)))


class QMIX(DQN):
    name = "qmix"
    config_cls = QMIXConfig
    multi_agent = True
    task_kinds = ("cooperative",)

    @classmethod
    def check(cls, cfg, task_cls, env_cfg):
        super().check(cfg, task_cls, env_cfg)
        if cfg.double_q:
            raise ConfigError("bad value for 'algo.double_q': true (qmix has no double-Q variant; allowed: false)")

    def build(self) -> None:
        cfg, dev = self.cfg, self.device
        self.qnet = net(self.obs_dim, self.action_dim, cfg).to(dev)
        local = TensorDictSequential(
            TensorDictModule(self.qnet, [OBS], [ACTION_VALUE]),
            QValueModule(action_value_key=ACTION_VALUE, out_keys=[ACTION, ACTION_VALUE, CHOSEN_VALUE], action_space="categorical"),
        )
        self.mixer = StateMixer(self.obs_dim, self.n_agents, cfg, dev)
        # the team's value and reward sit at the root under QMixerLoss's default names
        mixer = TensorDictModule(self.mixer, [CHOSEN_VALUE, OBS], ["chosen_action_value"])
        self.loss = QMixerLoss(local, mixer, loss_function=cfg.critic_loss, delay_value=True, action_space="categorical")
        params = [*self.loss.local_value_network_params.values(True, True), *self.loss.mixer_network_params.values(True, True)]
        self.optims = {"q": self.adam(params)}

    def replay_items(self, batch: TensorDictBase):
        """Chunks [N] of [T] joint steps, with the team reward (the drones' rewards summed)."""
        data = joint_transitions(batch)
        data[NEXT, "reward"] = data[nxt(REWARD)].sum(-2)
        return data

    def losses(self, td):
        td = td.reshape(-1)  # chunks of steps -> steps
        out = self.loss(td)
        with torch.no_grad():
            q_max = self.qnet(td[OBS]).max(-1).values
        return {"q": out["loss"]}, {"q_max": q_max}
