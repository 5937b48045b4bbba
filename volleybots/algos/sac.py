"""SAC (Haarnoja et al. 2018, the version without a state-value network) on TorchRL's ``SACLoss``:
a tanh-squashed Gaussian actor, twin critics with targets, and a learned temperature that drives the
policy's entropy toward ``target_entropy_scale x action_dim``.

Started from a ``bc``, ``ppo`` or ``mappo`` run (``init=``), whose Gaussian actor over PPO's MLP none
of SAC's networks can take, SAC keeps that actor frozen as a guide (algos/guide.py) and learns a
residual on it (residual policy learning, Silver et al. 2018; docs/imitation.md):

1. the actor's pre-tanh mean is atanh(guide's action) + the MLP's output, whose last layer starts at
   zero (and its scale at ``guide_noise``): the actor starts exactly as the clone, with a little noise;
2. the warm-up (``guide_warmup`` transitions, whole episodes) plays that actor, not uniform noise;
3. the first ``actor_freeze_updates`` gradient steps fit only the critics, on the clone's play;
4. optionally a penalty ``guide_coeff x (tanh(loc) - guide)^2`` keeps the actor near the guide (TD3+BC).

Without a guide nothing of this runs: the same random draws, the same run.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torch import nn
from torchrl.modules import ProbabilisticActor, TanhNormal, ValueOperator
from torchrl.objectives import SACLoss

from volleybots.algos.guide import Guide, can_guide
from volleybots.algos.offpolicy import OffPolicy, OffPolicyConfig, QNet, net
from volleybots.errors import ranged


@dataclass
class SACConfig(OffPolicyConfig):
    name: str = "sac"
    alpha_init: float = ranged(0.1, gt=0)
    alpha_lr: float = ranged(5e-4, gt=0)
    target_entropy_scale: float = ranged(-0.5, ge=-10, le=10)  # x action_dim: the entropy the temperature aims at
    actor_lr: float | None = ranged(None, gt=0)  # the actor's Adam learning rate (None: lr); small steps from a clone
    # with a guide only (init= from a bc / ppo / mappo run)
    guide_noise: float = ranged(0.1, ge=0.01)  # the residual actor's initial std (before the tanh; 0.01 is the extractor's floor)
    actor_freeze_updates: int = ranged(1000, ge=0)  # the first gradient steps, which fit only the critics
    guide_coeff: float = ranged(0.0, ge=0)  # weight of the squared gap to the guide's action in the actor loss
    guide_warmup: int = ranged(409_600, ge=1)  # buffer transitions of the clone's play before the first gradient step


GUIDE_LIMIT = 1.0 - 1e-3  # the guide's action stays inside the tanh's open range: atanh(+-1) is infinite
GUIDE_LOGS = ("guide_mse", "actor_frozen")  # logged from the first batch when there is a guide


class Head(nn.Sequential):
    """SAC's actor head: an MLP, then loc and a softplus-mapped scale of the Gaussian before the tanh.

    With a guide the loc is a residual: atanh(guide's action) + the MLP's. A Sequential of the same
    two children as before, so checkpoints keep their parameter names; the guide is not a submodule
    (a tuple), so its frozen weights stay out of SAC's parameters, optimisers and loss."""

    def __init__(self, mlp: nn.Module, action_dim: int):
        super().__init__(mlp, NormalParamExtractor())
        self.action_dim = action_dim
        self.guide: tuple = ()

    def forward(self, obs):
        loc, scale = super().forward(obs)
        if self.guide:
            loc = loc + torch.atanh(self.guide[0](obs).clamp(-GUIDE_LIMIT, GUIDE_LIMIT))
        return loc, scale

    @torch.no_grad()
    def start_at_guide(self, std: float) -> None:
        """Zero the MLP's last layer but for a bias that maps to ``std``: the residual is 0 and the
        actor the guide, with that much noise before the tanh."""
        last = [m for m in self[0].modules() if isinstance(m, nn.Linear)][-1]
        last.weight.zero_()
        last.bias.zero_()
        lo, hi = -20.0, 20.0  # the extractor's scale is increasing in its input: bisect for ``std``
        for _ in range(60):
            mid = (lo + hi) / 2
            _, scale = self[1](torch.tensor([0.0, mid], device=last.bias.device))
            lo, hi = (mid, hi) if float(scale) < std else (lo, mid)
        last.bias[self.action_dim:] = lo


class SAC(OffPolicy):
    name = "sac"
    config_cls = SACConfig
    actor_attr = "head"
    info_keys = ("alpha", "entropy")

    def __init__(self, cfg, env, seed: int = 0):
        super().__init__(cfg, env, seed)
        self.guide: Guide | None = None  # a frozen bc / ppo / mappo actor (init=), checkpointed

    def build(self) -> None:
        cfg = self.cfg
        # loc and a softplus-mapped scale of the Gaussian before the tanh
        self.head = Head(net(self.obs_dim, 2 * self.action_dim, cfg), self.action_dim).to(self.device)
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
            "actor": self.adam(self.loss.actor_network_params.values(True, True), lr=cfg.actor_lr),
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
        so they become the frozen guide (exactly the source's). False for any other source; a guided
        SAC run passes its guide on first, since its actor is only the residual on it."""
        if isinstance(source, SAC) and source.guide is not None:
            self.use_guide(Guide.from_checkpoint(self.obs_dim, self.action_dim, source.guide.checkpoint(), self.device))
        if not can_guide(source):
            return False
        self.use_guide(Guide.of(source).to(self.device))
        self.head.start_at_guide(self.cfg.guide_noise)
        return True

    def use_guide(self, guide: Guide) -> None:
        """Keep ``guide`` (checkpointed) and make the actor a residual on it."""
        self.guide = guide
        self.head.guide = (guide,)

    @property
    def warmup_frames(self) -> int:
        """With a guide the warm-up lasts ``guide_warmup`` transitions at least: whole episodes of the
        clone's play (800 steps x 256 envs = 204,800 on Solo Bump), so the critics' first data hold
        whole rallies; SAC's own warm-up (4 batches of 4096) holds only their openings. At most the
        buffer's size (the key is read only with a guide, so it is not checked against it)."""
        own = super().warmup_frames
        return own if self.guide is None else max(own, min(self.cfg.guide_warmup, self.cfg.buffer_size))

    def warmup_action(self, obs):
        """With a guide the warm-up plays the actor (the clone plus ``guide_noise``), not uniform
        noise, so the buffer starts with the clone's states."""
        return super().warmup_action(obs) if self.guide is None else self.explore(obs)

    @property
    def actor_frozen(self) -> bool:
        """With a guide, the first ``actor_freeze_updates`` gradient steps fit only the critics: the
        actor's first steps then climb Q-values of the clone's play, not freshly initialised critics'."""
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
            state["guide"] = self.guide.checkpoint()
        return state

    def load_state_dict(self, state: dict) -> None:
        super().load_state_dict(state)
        saved = state.get("guide")  # a resumed run keeps its guide (the residual is in the loaded weights)
        if saved:
            self.use_guide(Guide.from_checkpoint(self.obs_dim, self.action_dim, saved, self.device))
