"""Behaviour cloning of the task's scripted player, with DAgger relabelling (``algo=bc``).

The teacher is ``volleybots.scripted.make_scripted_policy(env)``: it reads observations and writes
actions for the whole batch of envs, so it is queried once per env step for every env, whoever
drives. Collection (the run loop's, through ``policy()``):

* for the first ``expert_frames`` frames the teacher drives every env;
* after that a fixed share of the envs (``learner_envs``) is driven by the learner's mean action, the
  rest by the teacher (DAgger: the learner visits its own states, the teacher says what it would do);
* Gaussian noise (``action_noise``) is added to every executed action, so that even the teacher's
  envs leave its path and show the states a learner's small errors lead to.

The dataset keeps the TEACHER's action for every visited state (never the executed, noisy or learner
action): a ring buffer of the last ``buffer_size`` per-drone samples, checkpointed with the run.
Each batch is followed by ``replay_ratio x samples / batch_size`` gradient steps, each fitting the
actor by maximum likelihood on a uniform sample of the dataset (mean and the state-independent
standard deviation of PPO's Gaussian) and the critic on the batch's own returns (TorchRL's GAE
targets, truncation bootstrapped, with PPO's value normalisation and Huber loss).

The networks are PPO's (this class is PPO's with another update), so ``init=`` from a bc run starts
``ppo`` / ``mappo`` with the cloned actor and the fitted critic (docs/imitation.md).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import torch
from tensordict import TensorDict, TensorDictBase
from torch import nn

from volleybots.algos.ppo import PPO, PPOConfig, PPONetConfig
from volleybots.errors import ConfigError, ranged
from volleybots.keys import ACTION, AGENTS, NEXT, OBS, STATS, TEACHER, leaf, nxt


@dataclass
class BCConfig(PPONetConfig):
    name: str = "bc"
    expert_frames: int = ranged(200_000, ge=0)
    learner_envs: float = ranged(0.5, ge=0, le=1)
    action_noise: float = ranged(0.1, ge=0)
    buffer_size: int = ranged(500_000, ge=1)
    batch_size: int = ranged(4096, ge=1)
    replay_ratio: float = ranged(8.0, gt=0)
    min_std: float = ranged(0.02, gt=0)
    teacher_replan: int = ranged(1, ge=1)
    teacher: str = "scripted"  # scripted: the task's scripted player; receiver: 1v1's deep-serve receiver (docs/receive.md)
    actor_lr: float = 1e-3
    centralised_critic: bool = True


TEACHERS = ("scripted", "receiver")
TEACHER_TASKS = ("1v1", "receive")  # the receiver reads the 1 vs 1 observation, which the receive drill shares


def ppo_config(cfg) -> PPOConfig:
    """PPO's config with bc's network and critic keys: the networks PPO would build for them."""
    return PPOConfig(**{f.name: getattr(cfg, f.name) for f in dataclasses.fields(PPONetConfig)})


class BC(PPO):
    name = "bc"
    config_cls = BCConfig
    action_spaces = ("prt", "ctbr")  # the scripted players fly continuous actions only
    multi_agent = True
    # on a match the learner is seated on team 0 against ``opponent=`` (the ``Versus`` seat) and clones
    # the scripted player of its own team, which reads that team's (mirrored) observations
    task_kinds = ("single", "cooperative", "competitive")
    needs_seat_on_matches = True

    @classmethod
    def check(cls, cfg, task_cls, env_cfg):
        from volleybots.algos.base import task_kind
        from volleybots.scripted import SCRIPTED_POLICIES
        from volleybots.tasks import TASKS

        super(PPO, cls).check(cfg, task_cls, env_cfg)  # the shared checks; PPO's own are about minibatches
        if task_cls.name not in SCRIPTED_POLICIES:
            allowed = sorted(t for t in SCRIPTED_POLICIES if t in TASKS and task_kind(TASKS[t]) in cls.task_kinds)
            raise ConfigError(f"algo 'bc' imitates a scripted player; task {task_cls.name!r} has none; allowed: {', '.join(allowed)}")
        teacher = getattr(cfg, "teacher", "scripted")  # (a population's config, whose clone's teacher is the scripted player, has none)
        if teacher not in TEACHERS:
            raise ConfigError(f"unknown algo.teacher {teacher!r}; allowed: {', '.join(TEACHERS)}")
        if teacher == "receiver" and task_cls.name not in TEACHER_TASKS:
            raise ConfigError(f"algo.teacher=receiver plays task {' or '.join(TEACHER_TASKS)}, not {task_cls.name!r}")

    def __init__(self, cfg, env, seed: int = 0):
        super().__init__(ppo_config(cfg), env, seed)
        self.cfg = cfg
        dev = self.device
        # the dataset: observations and the teacher's actions, one row per drone and step
        self.data_obs = torch.zeros(cfg.buffer_size, self.obs_dim, device=dev)
        self.data_act = torch.zeros(cfg.buffer_size, self.action_dim, device=dev)
        self.size = self.cursor = self.frames = 0
        self.teacher = None  # attached by the run loop (``attach``); evaluation needs none
        self.teacher_s = 0.0  # seconds in the teacher since the last update
        self._residual: torch.Tensor | None = None  # squared errors of the mean over an update's steps

    # ---------------------------------------------------------------------------- collection
    def attach(self, env) -> None:
        """The run loop hands over its env: the teacher is built for its task, action space and physics."""
        from volleybots.scripted import make_scripted_policy
        from volleybots.scripted.receive import OneVsOneReceiver

        if getattr(self.cfg, "teacher", "scripted") == "receiver":
            teacher = OneVsOneReceiver(env.action_space_name, env.params)
        else:
            teacher = make_scripted_policy(env, env.action_space_name)
        self.teacher = teacher.replan_every(self.cfg.teacher_replan)
        n = env.num_envs
        self.learner_mask = (torch.arange(n, device=self.device) < round(self.cfg.learner_envs * n)).view(n, 1, 1)

    @property
    def dagger(self) -> bool:
        return self.frames >= self.cfg.expert_frames

    def teach(self, td: TensorDictBase) -> torch.Tensor:
        """The teacher's action for the states of ``td`` (left as it was), timed."""
        t0 = time.perf_counter()
        out = self.teacher(_view(td))
        action = out if isinstance(out, torch.Tensor) else out.get(ACTION)
        self.teacher_s += time.perf_counter() - t0
        return action.clamp(-1.0, 1.0)

    def policy(self, deterministic: bool = False):
        """Evaluation (and any use without the run loop's env): the learner, as PPO's. Collection:
        the teacher or, in DAgger's envs, the learner's mean, plus noise; the teacher labels all."""
        if deterministic or self.teacher is None:
            return super().policy(deterministic)
        learner = super().policy(deterministic=True)

        def act(td: TensorDictBase) -> TensorDictBase:
            teacher = self.teach(td)
            drive = teacher
            if self.dagger and self.cfg.learner_envs > 0:
                own = learner(_view(td)).get(ACTION)
                drive = torch.where(self.learner_mask, own, teacher)
            noise = torch.randn(drive.shape, generator=self.gen, device=self.gen.device).to(drive.device) * self.cfg.action_noise
            td.set(TEACHER, teacher)
            td.set(ACTION, (drive + noise).clamp(-1.0, 1.0))
            return td

        return act

    # ---------------------------------------------------------------------------- learning
    def store(self, obs: torch.Tensor, action: torch.Tensor) -> None:
        """Append rows to the ring buffer (the oldest go when it is full)."""
        cap = self.cfg.buffer_size
        obs, action = obs[-cap:], action[-cap:]
        idx = (self.cursor + torch.arange(len(obs), device=self.device)) % cap
        self.data_obs[idx], self.data_act[idx] = obs, action
        self.cursor = (self.cursor + len(obs)) % cap
        self.size = min(cap, self.size + len(obs))

    def update(self, batch: TensorDictBase) -> dict[str, float]:
        cfg = self.cfg
        batch = batch.exclude(STATS, nxt(STATS))
        if TEACHER not in batch.keys(True):
            raise RuntimeError("bc learns from batches its own collection policy labelled (attach the env first)")
        self.store(batch.get(OBS).reshape(-1, self.obs_dim), batch.get(TEACHER).reshape(-1, self.action_dim))
        self.frames += batch.numel()
        with torch.no_grad():
            if self.obs_norm is not None:  # the teacher's collection did not run it
                self.obs_norm.module.stats.update(batch.get(OBS))
                self.obs_norm(batch)
                self.obs_norm(batch[NEXT])
            self.loss.value_estimator(batch)
        flat = batch.select(self._obs_in, "value_target").reshape(-1)
        steps = max(1, round(cfg.replay_ratio * batch.numel() * self.n_agents / cfg.batch_size))
        critic_batch = max(1, cfg.batch_size // self.n_agents)
        sums: dict[str, float] = {}
        self._residual = None
        for _ in range(steps):
            for k, v in self.gradient_step(flat, critic_batch).items():
                sums[k] = sums.get(k, 0.0) + v
        with torch.no_grad():  # the maximum-likelihood deviation of the fitted mean: its RMS error per dimension
            self._std.state_independent_scale.copy_((self._residual / steps).sqrt().clamp_min(cfg.min_std).log())
        logs = {k: v / steps for k, v in sums.items()}
        logs.update(
            dataset=float(self.size),
            dagger=float(self.dagger),
            action_std=float(self._std.state_independent_scale.detach().exp().mean()),
            teacher_s=self.teacher_s,
            teacher_steps_per_s=batch.numel() / max(self.teacher_s, 1e-9),
        )
        self.teacher_s = 0.0
        return logs

    def gradient_step(self, flat: TensorDictBase, critic_batch: int) -> dict[str, float]:
        """One Adam step: the actor's negative log-likelihood of the teacher's actions on a dataset
        sample, plus the critic's loss on a sample of the batch's steps."""
        cfg = self.cfg
        idx = torch.randint(self.size, (min(cfg.batch_size, self.size),), generator=self.gen, device=self.gen.device).to(self.device)
        td = TensorDict({AGENTS: TensorDict({leaf(OBS): self.data_obs[idx]}, batch_size=[len(idx)])}, batch_size=[len(idx)])
        if self.obs_norm is not None:
            self.obs_norm(td)
        target = self.data_act[idx]
        loc = self.actor.get_dist(td).mean
        # the Gaussian's negative log-likelihood with its standard deviation held: the mean's fit,
        # each action dimension weighted by its residual; the deviation's own maximum is set in closed form
        log_std = self._std.state_independent_scale.detach()
        err = target - loc
        nll = (0.5 * (err / log_std.exp()).pow(2) + log_std).sum(-1).mean() + 0.5 * self.action_dim * math.log(2 * math.pi)
        cidx = torch.randint(flat.numel(), (critic_batch,), generator=self.gen, device=self.gen.device).to(flat.device)
        loss_critic, _, explained = self.loss.loss_critic(flat[cidx])
        loss_critic = loss_critic.mean()  # per sample: the loss's forward would reduce it
        self.optim.zero_grad(set_to_none=True)
        (nll + loss_critic).backward()
        gn_a = nn.utils.clip_grad_norm_(list(self.actor.parameters()), cfg.max_grad_norm)
        gn_c = nn.utils.clip_grad_norm_(list(self.critic.parameters()), cfg.max_grad_norm)
        self.optim.step()
        sq = err.detach().pow(2).mean(0)
        self._residual = sq if self._residual is None else self._residual + sq
        return {
            "loss_bc": float(nll.detach()), "action_mse": float(sq.mean()), "loss_critic": float(loss_critic.detach()),
            "explained_variance": float(explained.mean()) if explained is not None else float("nan"),
            "grad_norm_actor": float(gn_a), "grad_norm_critic": float(gn_c),
        }

    # ---------------------------------------------------------------------------- checkpoints
    def state_dict(self) -> dict:
        return {
            **super().state_dict(),
            "data": {"obs": self.data_obs[: self.size].clone(), "action": self.data_act[: self.size].clone()},
            "counters": torch.tensor([self.frames, self.size, self.cursor]),
        }

    def load_state_dict(self, state: dict) -> None:
        super().load_state_dict(state)
        self.frames, self.size, self.cursor = (int(x) for x in state["counters"])
        self.data_obs[: self.size] = state["data"]["obs"]
        self.data_act[: self.size] = state["data"]["action"]


def _view(td: TensorDictBase) -> TensorDictBase:
    """A shallow copy whose ``agents`` entries a policy may write without touching ``td``'s."""
    return td.clone(recurse=False).set(AGENTS, td.get(AGENTS).clone(recurse=False))
