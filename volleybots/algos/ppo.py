"""(MA)PPO on TorchRL: ``ppo`` for one drone, ``mappo`` for several; one code path.

The actor is shared by all drones (it sees one drone's observation); the critic values each drone's
own observation (``ppo``) or, centralised, all drones' observations concatenated (``mappo``), with one
output per drone. Losses are TorchRL's ``MAPPOLoss`` (clipped surrogate, entropy bonus, value loss on
PopArt-normalised targets) and the advantage is TorchRL's multi-agent GAE, which bootstraps the value
of the last observation on time-limit truncation (``truncated``) and not on ``terminated``.

Continuous actions are a Gaussian with a state-independent standard deviation whose samples the env
clips to [-1, 1] (the log-probability is that of the unclipped sample); ``discrete`` is Categorical.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import torch
from tensordict import TensorDictBase
from tensordict.nn import AddStateIndependentNormalScale, TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.modules import IndependentNormal, PopArtValueNorm, ProbabilisticActor, RunningValueNorm
from torchrl.objectives.multiagent import MAPPOLoss
from torchrl.objectives.utils import ValueEstimators

from volleybots.algos.base import Algorithm, mlp
from volleybots.errors import ConfigError, ranged
from volleybots.keys import ACTION, AGENTS, DONE, LOG_PROB, NEXT, OBS, OBS_NORM, REWARD, STATS, TERMINATED, VALUE, leaf, nxt

# what a minibatch's loss output adds to the logs (when the loss computed it)
# fine-tuning from a clone (docs/imitation.md; init=): the critic learns the clone's values for 10 batches
# first, then a slow, tightly clipped actor without an entropy bonus keeps what imitation taught
FINE_TUNE = ("algo.actor_freeze_updates=10", "algo.actor_lr=5e-5", "algo.clip_epsilon=0.1", "algo.entropy_coeff=0.0")
LOSS_LOGS = ("loss_objective", "loss_critic", "loss_entropy", "entropy", "kl_approx", "clip_fraction", "explained_variance")


@dataclass
class PPONetConfig:
    """The keys that shape PPO's networks and fit its critic, shared with ``bc`` (algos/bc.py): a
    clone is PPO's network, so a PPO run can start from it (``init=``)."""

    steps_per_batch: int = ranged(64, ge=1)
    actor_lr: float = ranged(5e-4, gt=0)
    critic_lr: float = ranged(5e-4, gt=0)
    max_grad_norm: float = ranged(10.0, gt=0)
    huber_delta: float = ranged(10.0, gt=0)
    gamma: float = ranged(0.995, gt=0, le=1)
    gae_lambda: float = ranged(0.95, ge=0, le=1)
    value_norm: bool = True
    obs_norm: bool = False
    hidden: list[int] = ranged(factory=lambda: [256, 128, 128], ge=1)
    activation: str = "elu"
    init_log_std: float = ranged(0.0, ge=-20, le=20)  # beyond, exp() of it under/overflows in float32
    centralised_critic: bool = False


@dataclass
class PPOConfig(PPONetConfig):
    name: str = "ppo"
    epochs: int = ranged(4, ge=1)
    minibatches: int = ranged(16, ge=1)
    clip_epsilon: float = ranged(0.1, gt=0, lt=1)
    entropy_coeff: float = ranged(0.001, ge=0)
    critic_coeff: float = ranged(1.0, ge=0)
    normalize_advantage: bool = True
    actor_freeze_updates: int = ranged(0, ge=0)
    anchor_coeff: float = ranged(0.0, ge=0)
    anchor_updates: int = ranged(0, ge=0)
    target_kl: float | None = ranged(None, gt=0)


@dataclass
class MAPPOConfig(PPOConfig):
    name: str = "mappo"
    centralised_critic: bool = True


class HuberMAPPOLoss(MAPPOLoss):
    """MAPPOLoss with the paper's Huber value loss of any delta.

    TorchRL's ``smooth_l1`` is Huber with delta 1, and Huber_d(e) = d^2 * Huber_1(e / d): so the
    (normalised) target and prediction are divided by d and the critic weight multiplied by d^2."""

    def __init__(self, *args, huber_delta: float, critic_coeff: float, **kw):
        super().__init__(*args, loss_critic_type="smooth_l1", critic_coeff=critic_coeff * huber_delta**2, **kw)
        self.huber_delta = huber_delta

    def _critic_loss_inputs(self, target_return, state_value, old_state_value):
        t, v, o = super()._critic_loss_inputs(target_return, state_value, old_state_value)
        d = self.huber_delta
        return t / d, v / d, None if o is None else o / d


class ObsNorm(nn.Module):
    """Running mean / std of the observations (TorchRL's Welford normaliser), clipped to +-10.
    Identity until it has seen a batch."""

    def __init__(self, obs_dim: int):
        super().__init__()
        self.stats = RunningValueNorm(shape=obs_dim)

    def forward(self, obs):
        return torch.where(self.stats.count > 0, self.stats.normalize(obs).clamp(-10.0, 10.0), obs)


class Critic(nn.Module):
    """[*, A, obs] -> [*, A, 1] values in the returns' scale (the head learns normalised values)."""

    def __init__(self, obs_dim: int, n_agents: int, cfg, value_norm: PopArtValueNorm | None):
        super().__init__()
        self.centralised = bool(cfg.centralised_critic)
        in_dim, out_dim = (obs_dim * n_agents, n_agents) if self.centralised else (obs_dim, 1)
        self.net = mlp(in_dim, out_dim, cfg.hidden, cfg.activation, out_gain=1.0)
        self.value_norm = value_norm

    def forward(self, obs):
        v = self.net(obs.flatten(-2)).unsqueeze(-1) if self.centralised else self.net(obs)
        return v if self.value_norm is None else self.value_norm.denormalize(v)


class Scaled(nn.Sequential):
    """``net`` followed by a state-independent Gaussian scale, for a ``net`` of any number of inputs."""

    def forward(self, *inputs):
        return self[1](self[0](*inputs))


def make_actor(net: nn.Module, in_keys, action_dim: int, cfg, continuous: bool, group: tuple[str, ...] = (AGENTS,)):
    """The policy over ``net``'s output (reading ``in_keys``): a Gaussian with a state-independent
    standard deviation (continuous) or a Categorical over logits (discrete). Writes the action and
    its log-probability under ``group``. Returns the actor and the scale module (None if discrete)."""

    def key(name):
        return (*group, name) if group else name

    if continuous:
        std = AddStateIndependentNormalScale(action_dim, init_value=cfg.init_log_std)
        head = TensorDictModule(Scaled(net, std), in_keys, [key("loc"), key("scale")])
        dist_keys, dist_cls = [key("loc"), key("scale")], IndependentNormal
    else:
        std = None
        head = TensorDictModule(net, in_keys, [key("logits")])
        dist_keys, dist_cls = [key("logits")], torch.distributions.Categorical
    actor = ProbabilisticActor(
        head,
        in_keys=dist_keys,
        out_keys=[key(leaf(ACTION))],
        distribution_class=dist_cls,
        return_log_prob=True,
        log_prob_key=key(leaf(LOG_PROB)),
    )
    return actor, std


def add_logs(sums: dict[str, float], logs: dict) -> None:
    """Add a step's scalars (tensors or numbers) to running sums."""
    for k, v in logs.items():
        sums[k] = sums.get(k, 0.0) + float(v.detach().mean() if isinstance(v, torch.Tensor) else v)


class PPO(Algorithm):
    name = "ppo"
    config_cls = PPOConfig

    @classmethod
    def check(cls, cfg, task_cls, env_cfg):
        super().check(cfg, task_cls, env_cfg)
        for key in ("actor_freeze_updates", "anchor_coeff"):
            if getattr(cfg, key) and cls.update is not PPO.update:
                raise ConfigError(f"algo {cls.name!r} updates its actors its own way: algo.{key} must be 0 (it is for ppo, mappo, mat)")
        frames = env_cfg.num_envs * cfg.steps_per_batch
        if frames < cfg.minibatches:
            raise ConfigError(
                f"a batch of {frames} frames (env.num_envs x algo.steps_per_batch) cannot make "
                f"algo.minibatches={cfg.minibatches} minibatches"
            )

    def __init__(self, cfg, env, seed: int = 0):
        super().__init__(cfg, env)
        dev = self.device
        self.obs_norm = TensorDictModule(ObsNorm(self.obs_dim), [OBS], [OBS_NORM]).to(dev) if cfg.obs_norm else None
        obs_in = self._obs_in = OBS_NORM if cfg.obs_norm else OBS
        self.actor, self._std = self.build_actor(obs_in)
        self.actor.to(dev)
        self.value_norm = PopArtValueNorm(shape=1, device=dev) if cfg.value_norm else None
        self.critic = self.build_critic(obs_in).to(dev)
        self.loss = HuberMAPPOLoss(
            self.actor,
            self.critic,
            value_norm=self.value_norm,
            clip_epsilon=cfg.clip_epsilon,
            entropy_coeff=cfg.entropy_coeff,
            huber_delta=cfg.huber_delta,
            critic_coeff=cfg.critic_coeff,
            normalize_advantage=cfg.normalize_advantage,
            **self.loss_options,
        )
        self.loss.set_keys(
            action=ACTION, sample_log_prob=LOG_PROB, value=VALUE, reward=REWARD, done=DONE, terminated=TERMINATED
        )
        self.loss.make_value_estimator(ValueEstimators.MAGAE, gamma=cfg.gamma, lmbda=cfg.gae_lambda, **self.value_options)
        self.optim = torch.optim.Adam(self.param_groups())
        self.gen = torch.Generator(device=dev)  # minibatch shuffling, checkpointed with the rest
        self.gen.manual_seed(seed)
        self.updates = 0  # batches learned from (the actor stays frozen for the first actor_freeze_updates)
        self.anchor = None  # the actor as it started (anchor_coeff > 0): a frozen copy made at the first update
        self._policy = TensorDictSequential(self.obs_norm, self.actor) if self.obs_norm is not None else self.actor

    # ------------------------------------------------------------ what a variant (happo, mat) replaces
    loss_options: dict = {}  # extra keywords of the loss (a network shared by actor and critic: functional=False)
    value_options: dict = {}  # extra keywords of TorchRL's multi-agent GAE

    def build_actor(self, obs_in):
        """One actor shared by all drones: (policy module, Gaussian scale module or None)."""
        net = mlp(self.obs_dim, self.action_dim, self.cfg.hidden, self.cfg.activation, out_gain=0.01)
        return make_actor(net, [obs_in], self.action_dim, self.cfg, self.continuous)

    def build_critic(self, obs_in):
        return TensorDictModule(Critic(self.obs_dim, self.n_agents, self.cfg, self.value_norm), [obs_in], [VALUE])

    def param_groups(self) -> list[dict]:
        """Adam's parameter groups; each is also gradient-clipped on its own."""
        return [
            {"params": list(self.actor.parameters()), "lr": self.cfg.actor_lr},
            {"params": list(self.critic.parameters()), "lr": self.cfg.critic_lr},
        ]

    # ------------------------------------------------------------------------------------ shared
    def policy(self, deterministic: bool = False):
        mode = ExplorationType.DETERMINISTIC if deterministic else ExplorationType.RANDOM

        def act(td: TensorDictBase) -> TensorDictBase:
            with torch.no_grad(), set_exploration_type(mode):
                return self._policy(td)

        return act

    def prepare(self, batch: TensorDictBase) -> TensorDictBase:
        """GAE advantages and value targets of a collected batch [N, T], flattened to [N * T] with
        only what the losses read (so that minibatch indexing copies no more than it must)."""
        batch = batch.exclude(STATS, nxt(STATS))
        with torch.no_grad():
            if self.obs_norm is not None:
                self.obs_norm(batch[NEXT])  # the same statistics the rollout used
            self.loss.value_estimator(batch)
        return batch.select(self._obs_in, ACTION, LOG_PROB, VALUE, "advantage", "value_target").reshape(-1)

    def minibatches(self, n: int):
        """Index tensors of ``epochs`` x ``minibatches`` shuffled minibatches of ``n`` samples."""
        size = n // self.cfg.minibatches
        for _ in range(self.cfg.epochs):
            perm = torch.randperm(n, generator=self.gen, device=self.gen.device).to(self.device)
            for i in range(self.cfg.minibatches):
                yield perm[i * size : (i + 1) * size]

    def step(self, loss: torch.Tensor, groups) -> list[torch.Tensor]:
        """One Adam step on ``loss``; each parameter list of ``groups`` is clipped to ``max_grad_norm``
        on its own. Returns the gradient norms before clipping."""
        self.optim.zero_grad(set_to_none=True)
        loss.backward()
        norms = [nn.utils.clip_grad_norm_(params, self.cfg.max_grad_norm) for params in groups]
        self.optim.step()
        return norms

    def finish_update(self, batch: TensorDictBase, sums: dict[str, float], steps: int) -> dict[str, float]:
        """Update the observation statistics after learning; the mean of the summed logs."""
        if self.obs_norm is not None:
            self.obs_norm.module.stats.update(batch[NEXT][OBS])
        logs = {k: v / steps for k, v in sums.items()}
        if self._std is not None:
            logs["action_std"] = float(self._std.state_independent_scale.detach().exp().mean())
        return logs

    def update(self, batch: TensorDictBase) -> dict[str, float]:
        cfg = self.cfg
        flat = self.prepare(batch)
        sums: dict[str, float] = {}
        groups = [g["params"] for g in self.optim.param_groups]  # actor, critic
        # a critic warm-up: an actor started from another run (init=) keeps what it knows until the
        # critic's advantages mean something
        frozen = self.updates < cfg.actor_freeze_updates
        anchor = 0.0 if frozen else self.anchor_weight()
        steps = 0
        for idx in self.minibatches(flat.numel()):
            mb = flat[idx]
            out = self.loss(mb)
            if steps and self.kl_stop(out, frozen):
                break
            loss = out["loss_critic"] if frozen else out["loss_objective"] + out["loss_critic"] + out.get("loss_entropy", 0.0)
            # logged from the first batch whenever the anchor is on: metrics.csv's columns are its first row's
            logs = {"anchor_kl": 0.0} if cfg.anchor_coeff > 0 else {}
            if anchor > 0:
                kl = self.anchor_kl(mb)
                loss = loss + anchor * kl
                logs["anchor_kl"] = kl.detach()
            gn_a, gn_c = self.step(loss, groups)
            logs.update({k: out[k] for k in LOSS_LOGS if k in out.keys()})
            logs.update(grad_norm_actor=gn_a, grad_norm_critic=gn_c)
            add_logs(sums, logs)
            steps += 1
        self.updates += 1
        return {**self.finish_update(batch, sums, steps), "actor_frozen": float(frozen), "anchor_weight": anchor,
                **self.kl_logs(steps, out)}

    def kl_stop(self, out, frozen: bool = False) -> bool:
        """``target_kl``'s early stop (as in Stable-Baselines3 and CleanRL): the update ends before a
        minibatch on which the actor has already moved more than 1.5 x ``target_kl`` from the policy that
        collected the batch, by TorchRL's ``kl_approx`` (the minibatch's mean log-probability drop). Asked
        from the second minibatch on: before the first, nothing has moved."""
        limit = self.cfg.target_kl
        return limit is not None and not frozen and "kl_approx" in out and float(out["kl_approx"]) > 1.5 * limit

    def kl_logs(self, steps: int, out) -> dict[str, float]:
        """With ``target_kl``: ``kl_steps``, the share of the update's planned minibatch steps taken (the
        early stop cuts it below 1), and ``kl_last``, the approximate KL on the last minibatch looked at
        (the one that stopped the update, if one did); ``kl_approx`` stays the mean before each step taken."""
        if self.cfg.target_kl is None:
            return {}
        last = float(out["kl_approx"]) if "kl_approx" in out else 0.0
        return {"kl_steps": steps / (self.cfg.epochs * self.cfg.minibatches), "kl_last": last}

    # ----------------------------------------------------------------- the anchor (fine-tuning a clone)
    def anchor_weight(self) -> float:
        """The weight of the KL penalty toward the actor as the run started: ``anchor_coeff`` from the
        first update the actor makes, decaying linearly to 0 over ``anchor_updates`` batches (0: it
        stays). Fine-tuning a clone: PPO's first updates, on a critic that has only seen the clone's
        noisy play, can walk the actor off what it imitated faster than the returns can show it; the
        penalty lets it move where the advantages agree over many batches, and the decay lets it go."""
        cfg = self.cfg
        if cfg.anchor_coeff == 0:
            return 0.0
        if self.anchor is None:
            self.anchor = copy.deepcopy(self.actor).requires_grad_(False)
        if cfg.anchor_updates == 0:
            return cfg.anchor_coeff
        done = self.updates - cfg.actor_freeze_updates
        return cfg.anchor_coeff * max(0.0, 1.0 - done / cfg.anchor_updates)

    def anchor_kl(self, td: TensorDictBase) -> torch.Tensor:
        """Mean KL(anchor || actor) over a minibatch's drones: the actor pays for giving up actions the
        anchor chose (the mass-covering direction), not for being surer than it."""
        with torch.no_grad():
            ref = self.anchor.get_dist(td)
        return torch.distributions.kl_divergence(ref, self.actor.get_dist(td)).mean()

    def state_dict(self) -> dict:
        return {
            "actor": self.actor.state_dict(),
            "critic": self.critic.state_dict(),
            "obs_norm": self.obs_norm.state_dict() if self.obs_norm is not None else {},
            "optim": self.optim.state_dict(),
            "gen": self.gen.get_state(),
            "updates": torch.tensor(self.updates),
            **({"anchor": self.anchor.state_dict()} if self.anchor is not None else {}),
        }

    def init_parts(self) -> dict[str, nn.Module]:
        # the observation normaliser belongs to the actor: its weights expect normalised inputs
        actor = nn.ModuleDict({"actor": self.actor, **({"obs_norm": self.obs_norm} if self.obs_norm is not None else {})})
        return {"actor": actor, "critic": self.critic}

    def load_networks(self, state: dict) -> None:
        """The actor, critic and observation statistics of ``state`` (a PPO-family learner's or a
        clone's), leaving this learner's optimiser, counters and random stream its own: another
        run's optimiser would bring its learning rates (a clone's actor learns at 1e-3, PPO's at 5e-4)."""
        self.actor.load_state_dict(state["actor"])
        self.critic.load_state_dict(state["critic"])
        if self.obs_norm is not None:
            self.obs_norm.load_state_dict(state["obs_norm"])

    def load_state_dict(self, state: dict) -> None:
        self.updates = int(state.get("updates", 0))
        self.load_networks(state)
        self.optim.load_state_dict(state["optim"])
        self.gen.set_state(state["gen"])
        if "anchor" in state:  # a resumed run keeps the anchor it started from, not the actor it resumes with
            self.anchor = copy.deepcopy(self.actor).requires_grad_(False)
            self.anchor.load_state_dict(state["anchor"])


class MAPPO(PPO):
    """PPO with a centralised critic, for any number of drones (one drone: the same as ``ppo``)."""

    name = "mappo"
    config_cls = MAPPOConfig
    multi_agent = True
