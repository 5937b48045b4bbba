"""What the off-policy single-agent algorithms (``dqn``, ``ddpg``, ``td3``, ``sac``) share.

Each collection of ``steps_per_batch`` steps per env is flattened into per-drone transitions and
written to a TorchRL replay buffer (``LazyTensorStorage`` on ``buffer_device``); once the buffer holds
``warmup_batches`` sampling batches (a few, not the reference's full 1e6) every collection is followed
by ``replay_ratio x frames / batch_size`` gradient steps on uniformly sampled batches. The losses are
TorchRL's; targets follow the online networks by Polyak averaging (``SoftUpdate``) every
``target_update_interval`` gradient steps.

The buffer uses TorchRL's default flat keys (``observation``, ``action``, ``("next", "reward")``,
``("next", "terminated")``, ...), so the losses run unchanged. ``("next", "terminated")`` alone cuts
the bootstrap (TorchRL's TD(0) target), so an episode cut by the time limit still bootstraps from its
last observation.

A subclass builds its networks and loss (``build``), says which losses feed which optimiser on a
gradient step (``losses``), and how it acts (``greedy`` for evaluation, ``explore`` for collection).
"""

from __future__ import annotations

import math
import warnings
from abc import abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import torch
from tensordict import TensorDict, TensorDictBase
from torch import nn
from torchrl.data import LazyTensorStorage, TensorDictReplayBuffer
from torchrl.modules import MLP
from torchrl.objectives import LossModule, SoftUpdate

from volleybots.algos.base import ACTIVATIONS, Algorithm
from volleybots.errors import ConfigError, check_device, ranged
from volleybots.keys import ACTION, AGENT_DONE, AGENT_TERMINATED, AGENTS, DONE, NEXT, OBS, REWARD, TERMINATED, leaf, nxt

CRITIC_LOSSES = ("smooth_l1", "l2", "l1")  # TorchRL's distance losses; smooth_l1 is Huber with delta 1


@dataclass
class OffPolicyConfig:
    name: str = ""
    steps_per_batch: int = ranged(64, ge=1)
    lr: float = ranged(5e-4, gt=0)
    max_grad_norm: float = ranged(10.0, gt=0)
    buffer_size: int = ranged(1_000_000, ge=1)
    buffer_device: str | None = None
    batch_size: int = ranged(4096, ge=1)
    warmup_batches: int = ranged(4, ge=1)
    random_warmup: bool = True
    replay_ratio: float = ranged(8.0, gt=0)
    gamma: float = ranged(0.95, gt=0, le=1)
    critic_loss: str = "smooth_l1"
    reward_scale: float = ranged(1.0, gt=0)
    tau: float = ranged(0.005, gt=0, le=1)
    target_update_interval: int = ranged(4, ge=1)
    hidden: list[int] = ranged(factory=lambda: [256, 128, 128], ge=1)
    activation: str = "elu"
    layer_norm: bool = True
    checkpoint_buffer: bool = False


def net_kwargs(cfg) -> dict:
    """TorchRL ``MLP`` / ``MultiAgentMLP`` keywords of every actor and critic here: ``cfg.hidden``
    cells, optional LayerNorm after each hidden layer (the reference's choice for these methods)."""
    return {
        "num_cells": list(cfg.hidden),
        "activation_class": ACTIVATIONS[cfg.activation],
        "norm_class": nn.LayerNorm if cfg.layer_norm else None,
        "norm_kwargs": [{"normalized_shape": h} for h in cfg.hidden] if cfg.layer_norm else None,
    }


def net(in_dim: int, out_dim: int, cfg) -> MLP:
    """The MLP of every single-agent actor and critic here (``net_kwargs``)."""
    return MLP(in_features=in_dim, out_features=out_dim, **net_kwargs(cfg))


class QNet(nn.Module):
    """Q(s, a) of a continuous action: one MLP over the observation and the action concatenated."""

    def __init__(self, obs_dim: int, action_dim: int, cfg):
        super().__init__()
        self.net = net(obs_dim + action_dim, 1, cfg)

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        return self.net(torch.cat((obs, action), -1))


def transitions(batch: TensorDictBase) -> TensorDict:
    """A collected batch [N, T] with agents nested under ``"agents"`` as flat per-drone transitions
    [N * T * A] in TorchRL's default keys; the root ``done``/``terminated`` [N, T, 1] are shared by
    the drones of an env."""
    obs = batch.get(OBS)
    shape = obs.shape[:-1]  # N, T, A

    def per_agent(key):
        return batch.get(nxt(key)).unsqueeze(-2).expand(*shape, 1)

    return TensorDict(
        {
            "observation": obs,
            "action": batch.get(ACTION),
            NEXT: {
                "observation": batch.get(nxt(OBS)),
                "reward": batch.get(nxt(REWARD)),
                "done": per_agent(DONE),
                "terminated": per_agent(TERMINATED),
            },
        },
        batch_size=shape,
    ).reshape(-1)


def joint_transitions(batch: TensorDictBase) -> TensorDict:
    """A collected batch [N, T] as joint transitions [N, T] that keep all drones of a step together
    under ``("agents", ...)`` (what a centralised critic or a mixer needs). ``done``/``terminated``
    stay shared at the root and are also given per drone, for TorchRL's per-agent TD targets."""
    obs = batch.get(OBS)
    shape = obs.shape[:-1]  # N, T, A

    def per_agent(key):
        return batch.get(nxt(key)).unsqueeze(-2).expand(*shape, 1)

    after = batch.get(NEXT)
    return TensorDict(
        {
            AGENTS: TensorDict({leaf(OBS): obs, leaf(ACTION): batch.get(ACTION)}, batch_size=shape),
            NEXT: {
                AGENTS: TensorDict(
                    {
                        leaf(OBS): batch.get(nxt(OBS)),
                        leaf(REWARD): batch.get(nxt(REWARD)),
                        leaf(AGENT_DONE): per_agent(DONE),
                        leaf(AGENT_TERMINATED): per_agent(TERMINATED),
                    },
                    batch_size=shape,
                ),
                DONE: after.get(DONE),
                TERMINATED: after.get(TERMINATED),
            },
        },
        batch_size=shape[:-1],
    )


class OffPolicy(Algorithm):
    """Replay buffer, warm-up, gradient steps, target updates and checkpoints of the four methods."""

    action_spaces = ("prt", "ctbr")
    # the TorchRL loss module, and one (optimiser, parameters) per group a loss of ``losses`` names
    loss: LossModule
    optims: dict[str, tuple[torch.optim.Optimizer, list[nn.Parameter]]]
    info_keys: tuple[str, ...] = ()  # the diagnostics ``losses`` returns besides the losses
    actor_attr: ClassVar[str]  # the attribute holding the network that acts (init= loads it as the actor)
    reward_key: ClassVar[tuple[str, ...]] = (NEXT, "reward")  # the reward of a replay item (``reward_scale``)


    @classmethod
    def check(cls, cfg, task_cls, action_space):
        super().check(cfg, task_cls, action_space)
        if cfg.critic_loss not in CRITIC_LOSSES:
            raise ConfigError(f"unknown algo.critic_loss {cfg.critic_loss!r}; allowed: {', '.join(CRITIC_LOSSES)}")
        if cfg.warmup_batches * cfg.batch_size > cfg.buffer_size:
            raise ConfigError(
                f"bad value for 'algo.warmup_batches': {cfg.warmup_batches} x algo.batch_size {cfg.batch_size} "
                f"must fit in algo.buffer_size = {cfg.buffer_size}"
            )
        if cfg.buffer_device is not None:
            check_device("algo.buffer_device", cfg.buffer_device)

    def __init__(self, cfg, env, seed: int = 0):
        super().__init__(cfg, env)
        self.gen = torch.Generator(device=self.device)  # exploration noise and epsilon draws
        self.gen.manual_seed(seed)
        self.build()
        self.loss.make_value_estimator(gamma=cfg.gamma)
        self.target_updater = SoftUpdate(self.loss, tau=cfg.tau)
        buffer_device = torch.device(cfg.buffer_device) if cfg.buffer_device is not None else self.device
        self.rb_gen = torch.Generator(device=buffer_device)  # replay sampling: indices are drawn on the storage's device
        self.rb_gen.manual_seed(seed + 1)
        self.buffer = TensorDictReplayBuffer(
            storage=LazyTensorStorage(cfg.buffer_size, device=buffer_device), batch_size=cfg.batch_size, generator=self.rb_gen
        )
        self.frames = 0  # env steps collected so far (summed over envs)
        self.grad_steps = 0

    # ------------------------------------------------------------------ to be written by a method
    @abstractmethod
    def build(self) -> None:
        """Create the networks, ``self.loss`` and ``self.optims``."""

    @abstractmethod
    def losses(self, td: TensorDictBase) -> tuple[dict[str, torch.Tensor], dict[str, torch.Tensor]]:
        """One gradient step's losses by optimiser group (only the groups to step now) and what to log."""

    @abstractmethod
    def greedy(self, obs: torch.Tensor) -> torch.Tensor:
        """The evaluation action for observations [..., obs]."""

    @abstractmethod
    def explore(self, obs: torch.Tensor) -> torch.Tensor:
        """The collection action (with exploration) for observations [..., obs]."""

    # ------------------------------------------------------------------ shared
    def init_parts(self) -> dict[str, nn.Module]:
        # the critic role is the whole loss module (critics, targets, temperature): it fits a run of the same method
        return {"actor": getattr(self, self.actor_attr), "critic": self.loss}

    def after_init(self) -> None:
        with warnings.catch_warnings():  # init_ says it ran already (at construction): this copy is the point
            warnings.simplefilter("ignore", UserWarning)
            self.target_updater.init_()  # the targets start from the loaded networks, not the random ones

    def adam(self, params, lr: float | None = None) -> tuple[torch.optim.Optimizer, list]:
        params = list(params)
        return torch.optim.Adam(params, lr=self.cfg.lr if lr is None else lr), params

    @property
    def warmup_frames(self) -> int:
        return int(self.cfg.warmup_batches * self.cfg.batch_size)

    @property
    def warming_up(self) -> bool:
        return len(self.buffer) < self.warmup_frames

    def random_action(self, shape: torch.Size) -> torch.Tensor:
        if self.continuous:
            return torch.rand(*shape, self.action_dim, generator=self.gen, device=self.device) * 2.0 - 1.0
        return torch.randint(self.action_dim, tuple(shape), generator=self.gen, device=self.device)

    def warmup_action(self, obs: torch.Tensor) -> torch.Tensor:
        """The action while the buffer warms up (``random_warmup``): uniformly random; SAC with a
        guide plays its actor instead (the clone plus noise)."""
        return self.random_action(obs.shape[:-1])

    def policy(self, deterministic: bool = False):
        def act(td: TensorDictBase) -> TensorDictBase:
            obs = td.get(OBS)
            with torch.no_grad():
                if deterministic:
                    action = self.greedy(obs)
                elif self.cfg.random_warmup and self.warming_up:
                    action = self.warmup_action(obs)
                else:
                    action = self.explore(obs)
            td.set(ACTION, action)
            return td

        return act

    def gradient_steps(self, frames: int) -> int:
        return max(1, round(self.cfg.replay_ratio * frames / self.cfg.batch_size))

    def log_keys(self) -> list[str]:
        """Every column ``update`` reports, from the first batch on (the metrics file's header is
        the first row's keys): NaN while the buffer warms up."""
        groups = [f"{k}_{g}" for g in self.optims for k in ("loss", "grad_norm")]
        return ["buffer_size", "grad_steps", *groups, *self.info_keys]

    def replay_items(self, batch: TensorDictBase) -> TensorDict:
        """What one collection [N, T] writes to the replay buffer, one item per first index: per-drone
        transitions here; a multi-agent method keeps a step's drones (or a whole chunk) together."""
        return transitions(batch)

    def update(self, batch: TensorDictBase) -> dict[str, float]:
        data = self.replay_items(batch)
        if self.cfg.reward_scale != 1.0:
            data[self.reward_key] = data[self.reward_key] * self.cfg.reward_scale
        self.buffer.extend(data.to(self.buffer.storage.device))
        self.frames += batch.numel()  # env steps (epsilon schedules anneal over these)
        logs = dict.fromkeys(self.log_keys(), math.nan)
        if not self.warming_up:
            sums: dict[str, float] = {}
            counts: dict[str, int] = {}
            for _ in range(self.gradient_steps(len(data))):
                for k, v in self.train_step(self.buffer.sample().to(self.device)).items():
                    sums[k] = sums.get(k, 0.0) + v
                    counts[k] = counts.get(k, 0) + 1
            logs.update({k: v / counts[k] for k, v in sums.items()})  # a delayed actor: over its own steps
        logs.update(self.extra_logs())
        logs.update(buffer_size=float(len(self.buffer)), grad_steps=float(self.grad_steps))
        return logs

    def extra_logs(self) -> dict[str, float]:
        """Scalars a method reports once per batch (exploration schedules, ...)."""
        return {}

    def train_step(self, td: TensorDictBase) -> dict[str, float]:
        """One gradient step on a sampled batch: every returned loss's group is stepped (each
        clipped to ``max_grad_norm``), then the targets move every ``target_update_interval`` steps.
        TorchRL's losses detach the parameters one loss must not move (the critic in the actor loss,
        log-alpha in the actor loss), so one backward of the sum gives each group its own gradient."""
        losses, info = self.losses(td)
        groups = [self.optims[g] for g in losses]
        for opt, _ in groups:
            opt.zero_grad(set_to_none=True)
        sum(losses.values()).backward()
        logs = {f"loss_{g}": float(v.detach()) for g, v in losses.items()}
        for g, (opt, params) in zip(losses, groups):
            logs[f"grad_norm_{g}"] = float(nn.utils.clip_grad_norm_(params, self.cfg.max_grad_norm))
            opt.step()
        self.grad_steps += 1
        if self.grad_steps % self.cfg.target_update_interval == 0:
            self.target_updater.step()
        logs.update({k: float(v.detach().float().mean()) for k, v in info.items()})
        return logs

    def state_dict(self) -> dict:
        state = {
            "loss": self.loss.state_dict(),
            "optims": {g: opt.state_dict() for g, (opt, _) in self.optims.items()},
            "gen": self.gen.get_state(),
            "rb_gen": self.rb_gen.get_state(),
            "counters": torch.tensor([self.frames, self.grad_steps]),
        }
        if self.cfg.checkpoint_buffer:
            n = len(self.buffer)
            data = self.buffer.storage[:n]
            state["buffer"] = {
                "data": data.to("cpu").to_dict() if n else {},
                "cursor": torch.tensor(self.buffer._writer._cursor),
                "batch_dims": torch.tensor(data.batch_dims if n else 1),  # items of QMIX's chunks are [T]
            }
        return state

    def load_state_dict(self, state: dict) -> None:
        self.loss.load_state_dict(state["loss"])
        for g, (opt, _) in self.optims.items():
            opt.load_state_dict(state["optims"][g])
        self.gen.set_state(state["gen"])
        self.rb_gen.set_state(state["rb_gen"])
        self.frames, self.grad_steps = (int(x) for x in state["counters"])
        self.buffer.empty()
        saved = state.get("buffer")
        if saved and saved["data"]:
            data = TensorDict(saved["data"]).auto_batch_size_(batch_dims=int(saved.get("batch_dims", 1)))
            self.buffer.extend(data.to(self.buffer.storage.device))
            self.buffer._writer._cursor = int(saved["cursor"])


__all__ = ["OffPolicy", "OffPolicyConfig", "QNet", "joint_transitions", "net", "net_kwargs", "transitions"]
