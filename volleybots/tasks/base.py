"""The one TorchRL env base every task derives from.

It owns the batch of worlds (physics backend + action space + referee), the TorchRL specs, partial
resets, truncation and per-episode statistics; a task only says how to reset, what each drone sees,
and what the referee's events are worth (``reset_task``, ``observe``, ``evaluate``).

Keys: ``("agents", "observation")`` [N, A, obs], ``("agents", "action")`` [N, A, 4] (or [N, A] int for
the discrete space), ``("agents", "reward")`` [N, A, 1]; ``done``/``terminated``/``truncated`` [N, 1]
shared by all agents; ``("stats", name)`` [N, 1] running episode statistics (return, length, the task
metric and every reward term), final when ``done`` is set.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from volleybots.physics import WorldParams, make_action_space, make_physics
from volleybots.physics.math import quat_axes, quat_rotate
from volleybots.physics.params import BallParams, DroneParams
from volleybots.rules import Referee

PARKED_BALL = (-100.0, 0.0, 0.1)  # where tasks without a ball keep it, resting on the ground far away


@dataclass
class StepResult:
    """What a task's ``evaluate`` returns for one control step."""

    terms: dict[str, torch.Tensor]  # reward term -> [N, A]
    terminated: torch.Tensor  # [N] bool
    stats: dict[str, torch.Tensor] = field(default_factory=dict)  # stat -> [N] value *after* this step


class VolleyEnv(EnvBase):
    # subclasses set these
    name: str = ""
    n_drones: int = 1
    teams: tuple[int, ...] = (0,)
    episode_len: int = 800
    obs_dim_prt: int = 0  # observation size with rotor throttles; CTBR drops 4
    reward_terms: tuple[str, ...] = ()
    shaping_terms: tuple[str, ...] = ()  # zeroed by reward_shaping=False
    metric: str = ""  # the task's headline metric, a key of the stats
    extra_stats: tuple[str, ...] = ()  # further per-episode statistics besides the metric
    competitive: bool = False  # two teams play against each other (the matches)
    default_algo: str = "ppo"  # what `volleybots train task=...` trains when no algo is named

    def __init__(
        self,
        num_envs: int = 1,
        action_space: str = "prt",
        physics: str = "torch",
        device="cpu",
        seed: int = 0,
        reward_shaping: bool = True,
        substeps: int = 4,
        drone: str | DroneParams = "iris",
        ball_drag: float = 0.0,
        downwash: bool = True,
        compile_physics: bool = False,
        episode_len: int | None = None,
    ):
        super().__init__(device=device, batch_size=torch.Size([num_envs]))
        if num_envs < 1:
            raise ValueError(f"num_envs must be >= 1, got {num_envs}")
        if episode_len is not None:
            self.episode_len = int(episode_len)
        drone_params = drone if isinstance(drone, DroneParams) else DroneParams.named(drone)
        self.params = WorldParams(substeps=substeps, downwash=downwash, drone=drone_params, ball=BallParams(drag=ball_drag))
        self.num_envs = num_envs
        self.reward_shaping = reward_shaping
        self.physics = make_physics(physics, self.params, num_envs, self.n_drones, device=self.device, compile=compile_physics)
        self.actions = make_action_space(action_space, self.params, num_envs, self.n_drones, self.device)
        self.action_space_name = action_space
        self.with_throttle = action_space != "ctbr"
        self.referee = Referee(self.referee_config(), num_envs, list(self.teams), self.device)
        self.rng = torch.Generator(device=self.device)
        self.rng.manual_seed(seed)
        self.t = torch.zeros(num_envs, dtype=torch.long, device=self.device)
        self._stats_keys = ("return", "episode_len", self.metric, *self.extra_stats, *(f"r_{k}" for k in self.reward_terms))
        self._stats = {k: torch.zeros(num_envs, device=self.device) for k in self._stats_keys}
        self._make_specs()

    # ------------------------------------------------------------------ to be written by a task
    def referee_config(self):
        raise TypeError(f"{type(self).__name__} must define referee_config()")

    def reset_task(self, mask: torch.Tensor) -> None:
        """Place drones and ball for the envs in ``mask`` (physics state, referee, task buffers)."""
        raise TypeError(f"{type(self).__name__} must define reset_task()")

    def observe(self) -> torch.Tensor:
        """[N, A, obs_dim] observations of the current state."""
        raise TypeError(f"{type(self).__name__} must define observe()")

    def evaluate(self, events) -> StepResult:
        """Rewards, termination and statistics after one control step, given the referee's events."""
        raise TypeError(f"{type(self).__name__} must define evaluate()")

    # ------------------------------------------------------------------ helpers for tasks
    @property
    def obs_dim(self) -> int:
        return self.obs_dim_prt - (0 if self.with_throttle else 4)

    def root_state(self) -> torch.Tensor:
        """[N, D, 23] (19 without throttles): pos, quat, vel, world angular vel, heading, up, throttle."""
        s = self.physics.state
        heading, up = quat_axes(s.quat)
        parts = [s.pos, s.quat, s.vel, quat_rotate(s.quat, s.omega), heading, up]
        if self.with_throttle:
            parts.append(s.throttle * 2.0 - 1.0)
        return torch.cat(parts, -1)

    def uniform(self, low, high, shape) -> torch.Tensor:
        low = torch.as_tensor(low, device=self.device, dtype=torch.float32)
        high = torch.as_tensor(high, device=self.device, dtype=torch.float32)
        u = torch.rand(*shape, low.shape[-1] if low.dim() else 1, generator=self.rng, device=self.device)
        out = low + (high - low) * u
        return out if low.dim() else out.squeeze(-1)

    def place_drones(self, mask: torch.Tensor, pos: torch.Tensor, quat: torch.Tensor | None = None) -> None:
        """Put the drones of the masked envs at rest at ``pos`` [M, D, 3] with rotors at hover."""
        m = int(mask.sum())
        if quat is None:
            quat = torch.zeros(m, self.n_drones, 4, device=self.device)
            quat[..., 0] = 1.0
        zeros = torch.zeros(m, self.n_drones, 3, device=self.device)
        throttle = torch.tensor(self.params.drone.hover_throttle, device=self.device).expand(m, self.n_drones, 4)
        self.physics.set_state(mask, pos=pos, quat=quat, vel=zeros, omega=zeros, throttle=throttle)

    def place_ball(self, mask: torch.Tensor, pos, vel=None) -> None:
        m = int(mask.sum())
        pos = torch.as_tensor(pos, device=self.device, dtype=torch.float32).expand(m, 3)
        vel = torch.zeros(m, 3, device=self.device) if vel is None else torch.as_tensor(vel, device=self.device, dtype=torch.float32).expand(m, 3)
        self.physics.set_state(mask, ball_pos=pos, ball_vel=vel)

    # ------------------------------------------------------------------ TorchRL plumbing
    def _make_specs(self) -> None:
        n, a = self.num_envs, self.n_drones
        dev = self.device
        self.observation_spec = Composite(
            agents=Composite(observation=Unbounded((n, a, self.obs_dim), device=dev), shape=(n, a), device=dev),
            stats=Composite({k: Unbounded((n, 1), device=dev) for k in self._stats_keys}, shape=(n,), device=dev),
            shape=(n,),
            device=dev,
        )
        if self.actions.continuous:
            act = Bounded(-1.0, 1.0, (n, a, self.actions.dim), device=dev)
        else:
            act = Categorical(self.actions.n, (n, a), device=dev, dtype=torch.long)
        self.action_spec = Composite(agents=Composite(action=act, shape=(n, a), device=dev), shape=(n,), device=dev)
        self.reward_spec = Composite(
            agents=Composite(reward=Unbounded((n, a, 1), device=dev), shape=(n, a), device=dev), shape=(n,), device=dev
        )
        self.done_spec = Composite(
            done=Categorical(2, (n, 1), dtype=torch.bool, device=dev),
            terminated=Categorical(2, (n, 1), dtype=torch.bool, device=dev),
            truncated=Categorical(2, (n, 1), dtype=torch.bool, device=dev),
            shape=(n,),
            device=dev,
        )

    def _set_seed(self, seed: int | None):
        if seed is not None:
            self.rng.manual_seed(seed)
        return seed

    def _stats_td(self) -> TensorDict:
        return TensorDict({k: v.unsqueeze(-1).clone() for k, v in self._stats.items()}, batch_size=self.batch_size, device=self.device)

    def _obs_td(self) -> TensorDict:
        return TensorDict(
            {
                "agents": TensorDict({"observation": self.observe()}, batch_size=(self.num_envs, self.n_drones), device=self.device),
                "stats": self._stats_td(),
            },
            batch_size=self.batch_size,
            device=self.device,
        )

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        mask = None
        if tensordict is not None and "_reset" in tensordict.keys():
            mask = tensordict.get("_reset").reshape(self.num_envs).bool()
        if mask is None:
            mask = torch.ones(self.num_envs, dtype=torch.bool, device=self.device)
        self.t[mask] = 0
        for v in self._stats.values():
            v[mask] = 0.0
        self.actions.reset(mask)
        self.reset_task(mask)
        out = self._obs_td()
        false = torch.zeros(self.num_envs, 1, dtype=torch.bool, device=self.device)
        out.update({"done": false, "terminated": false.clone(), "truncated": false.clone()})
        return out

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict.get(("agents", "action"))
        contacts = self.physics.step(self.actions.command_fn(action))
        self.t += 1
        s = self.physics.state
        self.last_contacts = contacts
        self.last_events = self.referee.update(s.pos, s.ball_pos, contacts.racket, contacts.body)
        res = self.evaluate(self.last_events)
        reward = torch.zeros(self.num_envs, self.n_drones, device=self.device)
        for name, val in res.terms.items():
            if not self.reward_shaping and name in self.shaping_terms:
                val = torch.zeros_like(val)
            reward = reward + val
            self._stats[f"r_{name}"] += val.mean(1)
        self._stats["return"] += reward.mean(1)
        self._stats["episode_len"] += 1.0
        for k, v in res.stats.items():
            self._stats[k] = v.to(torch.float32)
        terminated = res.terminated
        truncated = (self.t >= self.episode_len) & ~terminated
        out = self._obs_td()
        out.set(("agents", "reward"), reward.unsqueeze(-1))
        out.set("terminated", terminated.unsqueeze(-1))
        out.set("truncated", truncated.unsqueeze(-1))
        out.set("done", (terminated | truncated).unsqueeze(-1))
        return out

    def episode_stats(self, td: TensorDictBase) -> dict[str, torch.Tensor]:
        """The statistics of the episodes that ended in a step's output ``td`` (its ``next``)."""
        done = td.get("done").reshape(-1)
        return {k: td.get(("stats", k)).reshape(-1)[done] for k in self._stats_keys}
