"""SAC (Haarnoja et al. 2018, the version without a state-value network) on TorchRL's ``SACLoss``:
a tanh-squashed Gaussian actor, twin critics with targets, and a learned temperature that drives the
policy's entropy toward ``target_entropy_scale x action_dim``.

Started from a ``bc``, ``ppo`` or ``mappo`` run (``init=``), whose Gaussian actor over PPO's MLP none
of SAC's networks can take, SAC keeps that actor frozen as a guide (algos/guide.py) and uses it to
start where the clone is instead of from random play (docs/imitation.md):

1. the warm-up collection plays the guide's mean action plus noise (``guide_noise``), not uniform noise;
2. at the first gradient step SAC's actor is distilled from the guide (``distill_steps``);
3. the next ``actor_freeze_updates`` gradient steps fit only the critics, on the distilled actor's play;
4. optionally a penalty ``guide_coeff x (tanh(loc) - guide)^2`` keeps the actor near the guide (TD3+BC).

Without a guide nothing of this runs: the same random draws, the same run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torch import nn
from torchrl.modules import ProbabilisticActor, TanhNormal, ValueOperator
from torchrl.objectives import SACLoss

from volleybots.algos.guide import Guide, can_guide
from volleybots.algos.offpolicy import OffPolicy, OffPolicyConfig, QNet, net
from volleybots.errors import ConfigError, ranged


@dataclass
class SACConfig(OffPolicyConfig):
    name: str = "sac"
    alpha_init: float = ranged(0.1, gt=0)
    alpha_lr: float = ranged(5e-4, gt=0)
    target_entropy_scale: float = ranged(-0.5, ge=-10, le=10)  # x action_dim: the entropy the temperature aims at
    # with a guide only (init= from a bc / ppo / mappo run)
    guide_noise: float = ranged(0.1, ge=0)  # std of the noise on the guide's warm-up actions
    distill_steps: int = ranged(500, ge=0)  # Adam steps fitting the actor to the guide at the first gradient step
    actor_freeze_updates: int = ranged(1000, ge=0)  # then: gradient steps that fit only the critics
    guide_coeff: float = ranged(0.0, ge=0)  # weight of the squared gap to the guide's action in the actor loss
    guide_warmup: int = ranged(409_600, ge=1)  # buffer transitions of the guide's play before the first gradient step


DISTILL_LIMIT = 1.0 - 1e-3  # distillation targets stay inside the tanh's open range: atanh(+-1) is infinite
GUIDE_LOGS = ("distill_loss", "guide_mse", "actor_frozen")  # logged from the first batch when there is a guide


class SAC(OffPolicy):
    name = "sac"
    config_cls = SACConfig
    actor_attr = "head"
    info_keys = ("alpha", "entropy")

    def __init__(self, cfg, env, seed: int = 0):
        super().__init__(cfg, env, seed)
        self.guide: Guide | None = None  # a frozen bc / ppo / mappo actor (init=), checkpointed
        self.distilled = False  # whether the actor has been fitted to the guide (once, at the first gradient step)

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
        info = {"alpha": out["alpha"], "entropy": out["entropy"]}
        if self.guide is None:
            return {"critic": out["loss_qvalue"], "actor": out["loss_actor"], "alpha": out["loss_alpha"]}, info
        frozen = self.actor_frozen
        penalised = not frozen and self.cfg.guide_coeff > 0
        gap = self.guide_gap(td["observation"], grad=penalised)
        info.update(guide_mse=gap.detach(), actor_frozen=torch.tensor(float(frozen)))
        losses = {"critic": out["loss_qvalue"]}
        if not frozen:
            actor = out["loss_actor"] + self.cfg.guide_coeff * gap if penalised else out["loss_actor"]
            losses.update(actor=actor, alpha=out["loss_alpha"])
        return losses, info

    def greedy(self, obs):
        loc, _ = self.head(obs)
        return torch.tanh(loc)

    def explore(self, obs):
        loc, scale = self.head(obs)
        return torch.tanh(loc + scale * torch.randn(loc.shape, generator=self.gen, device=loc.device))

    # ------------------------------------------------------------ a guide (init= from a bc / ppo / mappo run)
    def guide_from(self, source) -> bool:
        """``init=`` from a run whose actor is PPO's Gaussian: SAC's networks cannot take its weights,
        so they become the frozen guide (exactly the source's). False for any other source."""
        if not can_guide(source):
            return False
        self.guide = Guide.of(source).to(self.device)
        return True

    @classmethod
    def check(cls, cfg, task_cls, env_cfg):
        super().check(cfg, task_cls, env_cfg)
        if cfg.guide_warmup > cfg.buffer_size:
            raise ConfigError(f"bad value for 'algo.guide_warmup': {cfg.guide_warmup} must fit in algo.buffer_size = {cfg.buffer_size}")

    @property
    def warmup_frames(self) -> int:
        """With a guide the warm-up lasts ``guide_warmup`` transitions at least: whole episodes of the
        clone's play (800 steps x 256 envs = 204,800 on Solo Bump), so the distillation sees the
        states of a whole rally; SAC's own warm-up (4 batches of 4096) holds only their openings."""
        own = super().warmup_frames
        return own if self.guide is None else max(own, self.cfg.guide_warmup)

    def warmup_action(self, obs):
        """With a guide the buffer starts with its play: its mean action plus Gaussian noise of
        ``guide_noise``, clipped to [-1, 1] (as bc collects), so the critics first see the clone's states."""
        if self.guide is None:
            return super().warmup_action(obs)
        action = self.guide(obs)
        noise = torch.randn(action.shape, generator=self.gen, device=self.gen.device).to(action.device)
        return (action + self.cfg.guide_noise * noise).clamp(-1.0, 1.0)

    def before_gradient_steps(self) -> dict[str, float]:
        if self.guide is None or self.distilled:
            return {}
        return {"distill_loss": self.distill()}

    def distill(self) -> float:
        """Fit SAC's actor to the guide before SAC learns: ``distill_steps`` Adam steps (an optimiser
        of its own, so SAC's starts fresh) of the TanhNormal's negative log-likelihood of the guide's
        mean action, on observations sampled from the buffer. A random actor would otherwise steer
        the critics' targets (the next action) and the first actor steps away from the clone.
        Returns the last step's loss."""
        params = list(self.head.parameters())
        opt = torch.optim.Adam(params, lr=self.cfg.lr)
        loss = torch.tensor(math.nan)
        for _ in range(self.cfg.distill_steps):
            obs = self.buffer.sample().get("observation").to(self.device)
            target = self.guide(obs).clamp(-DISTILL_LIMIT, DISTILL_LIMIT)
            loc, scale = self.head(obs)
            loss = -TanhNormal(loc, scale, low=-1.0, high=1.0).log_prob(target).mean()
            opt.zero_grad(set_to_none=True)
            loss.backward()
            nn.utils.clip_grad_norm_(params, self.cfg.max_grad_norm)
            opt.step()
        self.distilled = True
        return float(loss.detach())

    @property
    def actor_frozen(self) -> bool:
        """With a guide, the first ``actor_freeze_updates`` gradient steps (the distillation comes
        before them) fit only the critics: the actor's first steps then climb Q-values of the
        distilled actor's play, not those of freshly initialised critics."""
        return self.guide is not None and self.grad_steps < self.cfg.actor_freeze_updates

    def guide_gap(self, obs: torch.Tensor, grad: bool) -> torch.Tensor:
        """Mean squared difference between SAC's deterministic action tanh(loc) and the guide's mean
        action (over samples and action dimensions): logged, and with ``guide_coeff`` the penalty."""
        with torch.set_grad_enabled(grad):
            loc, _ = self.head(obs)
            return (torch.tanh(loc) - self.guide(obs)).pow(2).mean()

    def log_keys(self) -> list[str]:
        keys = super().log_keys()
        return [*keys, *GUIDE_LOGS] if self.guide is not None else keys

    def state_dict(self) -> dict:
        state = super().state_dict()
        if self.guide is not None:
            state["guide"] = {**self.guide.checkpoint(), "distilled": torch.tensor(self.distilled)}
        return state

    def load_state_dict(self, state: dict) -> None:
        super().load_state_dict(state)
        saved = state.get("guide")  # a resumed run keeps its guide and whether it has distilled it
        self.guide = Guide.from_checkpoint(self.obs_dim, self.action_dim, saved, self.device) if saved else None
        self.distilled = bool(saved["distilled"]) if saved else False
