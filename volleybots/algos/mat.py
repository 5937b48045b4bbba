"""MAT (Wen et al. 2022, Multi-Agent Transformer) for the cooperative tasks, on MAPPO's pieces.

An encoder (``n_blocks`` self-attention blocks of width ``embed_dim`` and ``n_heads`` heads, unmasked)
turns the drones' observations into one representation per drone; its head is the value of each
drone (MAPPO's value normalisation, Huber loss and multi-agent GAE, ``ppo.py``). A decoder of as many
blocks emits the actions auto-regressively: the token of drone i is the embedding of drone i-1's
action (a start token for the first), its self-attention and its attention to the encoder's
representations are causal, so drone i's action distribution depends on the representations of drones
<= i and on the actions of drones < i only.

Acting (``policy``) runs the decoder once per drone, each time keeping the next drone's sampled (or
most likely) action. Training is teacher-forced: one decoder pass over the stored actions gives
every drone's distribution at once, and TorchRL's clipped surrogate, entropy bonus and value loss
(``HuberMAPPOLoss``) apply unchanged. Encoder and decoder are trained together (the encoder gets
the gradients of both losses): the loss runs the modules directly (``functional=False``).
Continuous actions are a Gaussian with a state-independent standard deviation, as in PPO;
``discrete`` is a Categorical over the 16 rotor patterns.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.envs.utils import ExplorationType, set_exploration_type

from volleybots.algos.ppo import MAPPO, MAPPOConfig, make_actor
from volleybots.errors import ConfigError, ranged
from volleybots.keys import ACTION, LOG_PROB, VALUE


@dataclass
class MATConfig(MAPPOConfig):
    name: str = "mat"
    actor_lr: float = 3e-5
    critic_lr: float = 3e-5
    embed_dim: int = ranged(256, ge=1)
    n_blocks: int = ranged(3, ge=1)
    n_heads: int = ranged(8, ge=1)


def _init(layer: nn.Linear, gain: float) -> nn.Linear:
    nn.init.orthogonal_(layer.weight, gain=gain)
    nn.init.zeros_(layer.bias)
    return layer


def _block(cls, cfg):
    """One post-norm transformer block of MAT's width, heads and GELU feed-forward (no dropout)."""
    layer = cls(cfg.embed_dim, cfg.n_heads, dim_feedforward=cfg.embed_dim, dropout=0.0, activation="gelu", batch_first=True)
    return layer, cfg.n_blocks


def _head(d: int, out: int, gain: float) -> nn.Sequential:
    return nn.Sequential(_init(nn.Linear(d, d), 2**0.5), nn.GELU(), nn.LayerNorm(d), _init(nn.Linear(d, out), gain))


def _flat(fn, x: torch.Tensor, *rest: torch.Tensor) -> torch.Tensor:
    """Apply a [B, A, d] -> [B, A, d] module to inputs of any leading batch shape."""
    y = fn(x.reshape(-1, *x.shape[-2:]), *(r.reshape(-1, *r.shape[-2:]) for r in rest))
    return y.reshape(*x.shape[:-1], y.shape[-1])


class Encoder(nn.Module):
    """[*, A, obs] -> [*, A, d] representations (every drone attends to every drone); its head gives
    each drone's (normalised) value."""

    def __init__(self, obs_dim: int, cfg):
        super().__init__()
        d = cfg.embed_dim
        self.embed = nn.Sequential(nn.LayerNorm(obs_dim), _init(nn.Linear(obs_dim, d), 2**0.5), nn.GELU(), nn.LayerNorm(d))
        self.blocks = nn.TransformerEncoder(*_block(nn.TransformerEncoderLayer, cfg), enable_nested_tensor=False)
        self.value_head = _head(d, 1, 1.0)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return _flat(self.blocks, self.embed(obs))


class Decoder(nn.Module):
    """Teacher-forced action parameters [*, A, action_dim] (Gaussian means or logits) from the
    representations and the drones' actions: position i reads the actions of drones < i (token i is
    drone i-1's action, token 0 a start flag) and the representations of drones <= i."""

    def __init__(self, action_dim: int, n_agents: int, continuous: bool, cfg):
        super().__init__()
        d = cfg.embed_dim
        self.action_dim, self.continuous = action_dim, continuous
        self.embed = nn.Sequential(_init(nn.Linear(action_dim + 1, d), 2**0.5), nn.GELU(), nn.LayerNorm(d))
        self.blocks = nn.TransformerDecoder(*_block(nn.TransformerDecoderLayer, cfg))
        self.action_head = _head(d, action_dim, 0.01)
        self.register_buffer("causal", torch.triu(torch.ones(n_agents, n_agents, dtype=torch.bool), diagonal=1), persistent=False)

    def tokens(self, action: torch.Tensor) -> torch.Tensor:
        """[*, A, action_dim + 1]: the previous drone's action (one-hot if discrete) and a start flag."""
        a = action.float() if self.continuous else nn.functional.one_hot(action.long(), self.action_dim).float()
        prev = torch.cat((torch.zeros_like(a[..., :1, :]), a[..., :-1, :]), -2)
        start = torch.zeros_like(prev[..., :1])
        start[..., 0, :] = 1.0
        return torch.cat((prev, start), -1)

    def forward(self, rep: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        def blocks(x, mem):
            return self.blocks(x, mem, tgt_mask=self.causal, memory_mask=self.causal)

        return self.action_head(_flat(blocks, self.embed(self.tokens(action)), rep))


class Policy(nn.Module):
    """(observations, actions) -> every drone's action parameters, through encoder and decoder."""

    def __init__(self, encoder: Encoder, decoder: Decoder):
        super().__init__()
        self.encoder, self.decoder = encoder, decoder

    def forward(self, obs, action):
        return self.decoder(self.encoder(obs), action)


class Value(nn.Module):
    """observations -> every drone's value (the encoder's head), in the returns' scale."""

    def __init__(self, encoder: Encoder, value_norm):
        super().__init__()
        self.encoder, self.value_norm = encoder, value_norm

    def forward(self, obs):
        v = self.encoder.value_head(self.encoder(obs))
        return v if self.value_norm is None else self.value_norm.denormalize(v)


class MAT(MAPPO):
    name = "mat"
    config_cls = MATConfig
    task_kinds = ("cooperative",)
    loss_options = {"functional": False}  # actor and critic share the encoder
    value_options = {"deactivate_vmap": True}  # attention has no vmap rule: value the steps without vmap

    @classmethod
    def check(cls, cfg, task_cls, env_cfg):
        super().check(cfg, task_cls, env_cfg)
        if cfg.embed_dim % cfg.n_heads:
            raise ConfigError(f"bad value for 'algo.embed_dim': {cfg.embed_dim} (must be a multiple of algo.n_heads={cfg.n_heads})")

    def build_actor(self, obs_in):
        self.encoder = Encoder(self.obs_dim, self.cfg)
        self.decoder = Decoder(self.action_dim, self.n_agents, self.continuous, self.cfg)
        return make_actor(Policy(self.encoder, self.decoder), [obs_in, ACTION], self.action_dim, self.cfg, self.continuous)

    def build_critic(self, obs_in):
        return TensorDictModule(Value(self.encoder, self.value_norm), [obs_in], [VALUE])

    def param_groups(self) -> list[dict]:
        """The decoder side at ``actor_lr``, the encoder and its value head at ``critic_lr``."""
        critic = {id(p) for p in self.critic.parameters()}
        actor = [p for p in self.actor.parameters() if id(p) not in critic]
        return [{"params": actor, "lr": self.cfg.actor_lr}, {"params": list(self.critic.parameters()), "lr": self.cfg.critic_lr}]

    def policy(self, deterministic: bool = False):
        mode = ExplorationType.DETERMINISTIC if deterministic else ExplorationType.RANDOM

        def act(td: TensorDictBase) -> TensorDictBase:
            with torch.no_grad(), set_exploration_type(mode):
                if self.obs_norm is not None:
                    self.obs_norm(td)
                return self.autoregressive(td)

        return act

    def autoregressive(self, td: TensorDictBase) -> TensorDictBase:
        """Drone after drone: decode with the actions chosen so far and keep drone i's action (the
        later drones' placeholder actions are invisible to it: the decoder is causal)."""
        obs = td.get(self._obs_in)
        shape = obs.shape[:-1]
        if self.continuous:
            action = torch.zeros(*shape, self.action_dim, device=obs.device)
        else:
            action = torch.zeros(shape, dtype=torch.long, device=obs.device)
        log_prob = torch.zeros(shape, device=obs.device)
        work = td.select(self._obs_in)
        for i in range(self.n_agents):
            work.set(ACTION, action)
            out = self.actor(work.clone(False))
            action = action.clone()
            action[:, i] = out.get(ACTION)[:, i]
            log_prob[:, i] = out.get(LOG_PROB)[:, i]
        td.set(ACTION, action)
        td.set(LOG_PROB, log_prob)
        return td
