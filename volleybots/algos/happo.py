"""HAPPO (Kuba et al. 2022, heterogeneous-agent PPO) for the cooperative tasks, on MAPPO's pieces.

One actor per drone, no parameter sharing (``PerAgentActors``: each drone's own MLP and Gaussian
scale or logits), and MAPPO's centralised critic, value normalisation, Huber value loss and
multi-agent GAE (``ppo.py``). Every update draws a fresh random order of the drones (from the
checkpointed generator) and trains the actors one after another in that order, each for ``epochs`` x
``minibatches`` clipped-surrogate steps (TorchRL's ``ClipPPOLoss`` on that drone's samples) whose
advantage is weighted by the product M of the policy ratios pi_new / pi_old of the drones updated
before it (M = 1 for the first). After a drone's steps its new ratio on every sample joins M. As M >=
0, M x min(r A, clip(r) A) = min(r (M A), clip(r) (M A)), so the weighting is the loss's advantage
multiplied by M. Advantages are standardised per drone over the whole batch before the weighting.
The critic then takes its own ``epochs`` x ``minibatches`` steps on the value targets.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModuleBase
from torch import nn
from torchrl.objectives import ClipPPOLoss

from volleybots.algos.base import mlp
from volleybots.algos.ppo import MAPPO, MAPPOConfig, add_logs, make_actor
from volleybots.keys import ACTION, AGENTS, LOG_PROB, leaf

ACTOR_LOGS = ("loss_objective", "loss_entropy", "entropy", "kl_approx", "clip_fraction")


@dataclass
class HAPPOConfig(MAPPOConfig):
    name: str = "happo"
    hidden: list[int] = field(default_factory=lambda: [256, 128])


class PerAgentActors(TensorDictModuleBase):
    """One policy per drone: drone ``a``'s actor reads its own observation [N, obs] and writes its
    action, log-probability and distribution parameters; the results are stacked into ``("agents", ...)``."""

    def __init__(self, actors: list, obs_key):
        super().__init__()
        self.actors = nn.ModuleList(actors)
        self.obs_key = obs_key
        self.leaf = obs_key[-1]
        self.in_keys = [obs_key]
        self.out_keys = [(AGENTS, k) for k in actors[0].out_keys]

    def agent(self, td: TensorDictBase, a: int) -> TensorDict:
        """Drone ``a``'s observations as the root-level input of its actor."""
        return TensorDict({self.leaf: td.get(self.obs_key)[:, a]}, batch_size=td.batch_size[:1])

    def forward(self, td: TensorDictBase) -> TensorDictBase:
        outs = [actor(self.agent(td, a)).exclude(self.leaf) for a, actor in enumerate(self.actors)]
        td.get(AGENTS).update(torch.stack(outs, dim=1))
        return td


class HAPPO(MAPPO):
    name = "happo"
    config_cls = HAPPOConfig
    task_kinds = ("cooperative",)

    def build_actor(self, obs_in):
        cfg = self.cfg
        actors, stds = [], []
        for _ in range(self.n_agents):
            net = mlp(self.obs_dim, self.action_dim, cfg.hidden, cfg.activation, out_gain=0.01)
            actor, std = make_actor(net, [obs_in[-1]], self.action_dim, cfg, self.continuous, group=())
            actors.append(actor)
            stds.append(std)
        self.agent_losses = []
        for actor in actors:
            loss = ClipPPOLoss(actor, None, clip_epsilon=cfg.clip_epsilon, entropy_coeff=cfg.entropy_coeff, functional=False)
            loss.set_keys(action=leaf(ACTION), sample_log_prob=leaf(LOG_PROB), advantage="advantage")
            self.agent_losses.append(loss)
        self._stds = stds
        return PerAgentActors(actors, obs_in), None

    def agent_batch(self, flat: TensorDictBase, a: int, advantage: torch.Tensor, factor: torch.Tensor) -> TensorDict:
        """Drone ``a``'s samples [B] for its surrogate: the advantage is weighted by ``factor``."""
        td = self.actor.agent(flat, a)
        td.update(
            {
                leaf(ACTION): flat.get(ACTION)[:, a],
                leaf(LOG_PROB): flat.get(LOG_PROB)[:, a],
                "factor": factor,
                "advantage": (factor * advantage).unsqueeze(-1),
            }
        )
        return td

    def train_agent(self, a: int, td: TensorDictBase) -> dict[str, float]:
        """``epochs`` x ``minibatches`` clipped-surrogate steps of drone ``a``'s actor on ``td`` (fewer under
        ``target_kl``); the means of their logs."""
        params = list(self.actor.actors[a].parameters())
        sums: dict[str, float] = {}
        steps = 0
        for idx in self.minibatches(td.numel()):
            out = self.agent_losses[a](td[idx])
            if steps and self.kl_stop(out):  # this drone's actor stops; the next drone's is weighted by where it stopped
                break
            (grad_norm,) = self.step(out["loss_objective"] + out["loss_entropy"], [params])
            add_logs(sums, {**{k: out[k] for k in ACTOR_LOGS}, "grad_norm_actor": grad_norm})
            steps += 1
        return {**{k: v / steps for k, v in sums.items()}, **self.kl_logs(steps, out)}

    def ratio(self, a: int, td: TensorDictBase) -> torch.Tensor:
        """pi_new / pi_old of drone ``a``'s actions [B]."""
        with torch.no_grad():
            dist = self.actor.actors[a].get_dist(td)
            return (dist.log_prob(td[leaf(ACTION)]) - td[leaf(LOG_PROB)]).exp()

    def update(self, batch: TensorDictBase) -> dict[str, float]:
        cfg = self.cfg
        flat = self.prepare(batch)
        n = flat.numel()
        adv = flat["advantage"].squeeze(-1)  # [B, A]
        if cfg.normalize_advantage:
            adv = (adv - adv.mean(0)) / adv.std(0).clamp_min(1e-6)
        actor: dict[str, float] = {}  # the drones' mean logs, averaged over the drones
        factor = torch.ones(n, device=self.device)
        order = torch.randperm(self.n_agents, generator=self.gen, device=self.gen.device).tolist()
        for a in order:
            td = self.agent_batch(flat, a, adv[:, a], factor)
            for k, v in self.train_agent(a, td).items():
                actor[k] = actor.get(k, 0.0) + v / self.n_agents
            factor = factor * self.ratio(a, td)
        sums: dict[str, float] = {}
        critic_params = list(self.critic.parameters())
        for idx in self.minibatches(n):
            loss, _, explained = self.loss.loss_critic(flat[idx])
            loss = loss.mean()  # the loss returns it per sample (its forward reduces)
            (grad_norm,) = self.step(loss, [critic_params])
            add_logs(sums, {"loss_critic": loss, "explained_variance": explained, "grad_norm_critic": grad_norm})
        logs = {**actor, **self.finish_update(batch, sums, cfg.epochs * cfg.minibatches)}
        logs["factor_std"] = float(factor.std())  # spread of the weights M after the last drone
        if self.continuous:
            logs["action_std"] = float(torch.stack([s.state_independent_scale.detach().exp().mean() for s in self._stds]).mean())
        return logs
