"""The one TorchRL env base every task derives from.

It owns the batch of worlds (physics backend + action space + referee), the TorchRL specs, partial
resets, truncation and per-episode statistics; a task only says how to reset, what each drone sees,
and what the referee's events are worth (``reset_task``, ``observe``, ``evaluate``).

Keys (named once in ``volleybots/keys.py``): ``("agents", "observation")`` [N, A, obs],
``("agents", "action")`` [N, A, 4] (or [N, A] int for the discrete space), ``("agents", "reward")``
[N, A, 1]; ``done``/``terminated``/``truncated`` [N, 1] shared by all agents; ``("stats", name)``
[N, 1] running episode statistics (return, length, the task metric and every reward term), final
when ``done`` is set.

Static shapes. The step (physics sub-steps, referee, rewards, statistics, observations) and the reset
are two pure batched functions of fixed shapes, ``_step_core(action)`` and ``_reset_core(mask,
noise)``: a reset touches the envs of ``mask`` by masked selects over all envs (never boolean indexing
or a shape that depends on how many envs reset), and its random numbers come pre-drawn from the env's
generator (``noise`` [N, K], read through ``uniform``). So ``compile=True`` on the torch backend
compiles each of them once per (task, env count) with ``torch.compile`` and never recompiles during a
run (docs/performance.md). ``step_and_maybe_reset`` (what collectors and the trainer call) runs both
and builds the two tensordicts itself, skipping TorchRL's generic partial-reset plumbing.

Bad actions (docs/physics.md). A non-finite continuous action is a crash of its drone: the drone's
commands are replaced by zeros for that step, the referee's ``drone_low`` event is set for it (so each
task scores it as its own crash: a match ends in a draw), its env terminates, ``("stats", "nonfinite_action")``
is 1 for that episode and a warning is issued once per env object; both backends do the same. A
discrete action outside the integers 0..15 raises a ``ValueError`` naming it.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from volleybots.keys import ACTION, AGENTS, DONE, NEXT, OBS, REWARD, STATS, TERMINATED, TRUNCATED, leaf, stat
from volleybots.physics import WorldParams, make_action_space, make_physics
from volleybots.physics.math import quat_axes, quat_rotate
from volleybots.physics.params import BallParams, DroneParams
from volleybots.physics.torch_backend import compile_options
from volleybots.rules import Referee
from volleybots.tasks.layout import ObsLayout, for_action_space, root_layout

PARKED_BALL = (-100.0, 0.0, 0.1)  # where tasks without a ball keep it, resting on the ground far away
COMPILE_BACKEND = "inductor"  # torch.compile backend of compile=True (tests use "eager": same guards, no codegen)


@dataclass
class StepResult:
    """What a task's ``evaluate`` returns for one control step."""

    terms: dict[str, torch.Tensor]  # reward term -> [N, A]
    terminated: torch.Tensor  # [N] bool
    stats: dict[str, torch.Tensor] = field(default_factory=dict)  # stat -> [N] value *after* this step


class NoiseTape:
    """The random numbers of one reset, handed out in order to ``VolleyEnv.uniform``.

    With ``noise`` [N, K] given, ``take(k)`` returns its next k columns; without, it hands out 0.5
    and only counts: how the env learns K, once, without touching its generator (so that every reset,
    the first included, draws its numbers the same way: a resumed run repeats the uninterrupted one).
    """

    def __init__(self, noise: torch.Tensor | None, num_envs: int = 0, device=None):
        self.noise, self.num_envs, self.device = noise, num_envs, device
        self.used = 0
        self.widths: list[int] = []  # columns of each take, in order

    def take(self, k: int) -> torch.Tensor:
        if self.noise is None:
            out = torch.full((self.num_envs, k), 0.5, device=self.device)
        else:
            out = self.noise[:, self.used : self.used + k]
        self.used += k
        self.widths.append(k)
        return out


class VolleyEnv(EnvBase):
    # subclasses set these
    name: str = ""
    n_drones: int = 1
    teams: tuple[int, ...] = (0,)
    episode_len: int = 800
    obs_parts: tuple[tuple[str, int], ...] = ()  # the observation's named parts in order, root (23) first (layout.py)
    obs_dim_prt: int = 0  # observation size with rotor throttles (the parts' sum); CTBR drops 4
    reward_terms: tuple[str, ...] = ()
    shaping_terms: tuple[str, ...] = ()  # zeroed by reward_shaping=False
    metric: str = ""  # the task's headline metric, a key of the stats
    metric_higher_is_better: bool = True  # which way the metric improves (the run's best.pt follows it)
    extra_stats: tuple[str, ...] = ()  # further per-episode statistics besides the metric
    competitive: bool = False  # two teams play against each other (the matches)
    default_algo: str = "ppo"  # what `volleybots train task=...` trains when no algo is named

    def __init_subclass__(cls, **kw):
        super().__init_subclass__(**kw)
        if "obs_parts" in cls.__dict__:  # declared once: the size follows from the parts
            cls.obs_dim_prt = for_action_space(cls.obs_parts, True).size

    @classmethod
    def obs_layout(cls, with_throttle: bool = True) -> ObsLayout:
        """The named layout of this task's observation (``with_throttle``: PRT and discrete; CTBR not)."""
        return for_action_space(cls.obs_parts, with_throttle)

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
        self._hover_throttle = torch.tensor(drone_params.hover_throttle, device=self.device)  # solved once, not per reset
        self.reward_shaping = reward_shaping
        # compile=True compiles the whole env step below, physics included
        self.physics = make_physics(physics, self.params, num_envs, self.n_drones, device=self.device)
        self.actions = make_action_space(action_space, self.params, num_envs, self.n_drones, self.device)
        self.action_space_name = action_space
        self.with_throttle = action_space != "ctbr"
        self.layout = self.obs_layout(self.with_throttle)
        self._root_layout = root_layout(self.with_throttle)
        self.referee = Referee(self.referee_config(), num_envs, list(self.teams), self.device)
        self.rng = torch.Generator(device=self.device)
        self.t = torch.zeros(num_envs, dtype=torch.long, device=self.device)
        # a competitive task's all-drone means cancel out (team 0's +100 for a win is team 1's -100), so
        # it also keeps team 0's: what a learner on team 0 (a Versus or self-play seat) is paid
        self._team0 = torch.tensor([i for i, t in enumerate(self.teams) if t == 0], device=self.device) if self.competitive else None
        team0 = ("return_team0", *(f"r_{k}_team0" for k in self.reward_terms)) if self.competitive else ()
        terms = (f"r_{k}" for k in self.reward_terms)
        # nonfinite_action stays last: the step reads it as the stats tensor's last column
        self._stats_keys = ("return", "episode_len", self.metric, *self.extra_stats, *terms, *team0, "nonfinite_action")
        self._stats = {k: torch.zeros(num_envs, device=self.device) for k in self._stats_keys}
        self._warned_nonfinite = False
        self._make_specs()
        self.rng.manual_seed(seed)
        self._noise_widths = None  # random numbers per env of each draw of a reset: counted by the first
        self.compiled = bool(compile_physics) and physics == "torch"  # MuJoCo steps in its own native code
        self._step_fn, self._reset_fn = self._step_core, self._reset_core
        if self.compiled:
            opts = compile_options(COMPILE_BACKEND)
            self._step_fn = torch.compile(self._step_core, **opts)
            self._reset_fn = torch.compile(self._reset_core, **opts)

    # ------------------------------------------------------------------ to be written by a task
    def referee_config(self):
        raise TypeError(f"{type(self).__name__} must define referee_config()")

    def reset_task(self, mask: torch.Tensor) -> None:
        """Place drones and ball for the envs in ``mask`` (physics state, referee, task buffers).

        Everything is computed for all envs and written by masked selects (``place_drones``,
        ``place_ball``, ``masked_select``); random numbers come from ``uniform``."""
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
        parts = dict(pos=s.pos, quat=s.quat, vel=s.vel, omega=quat_rotate(s.quat, s.omega), heading=heading, up=up)
        if self.with_throttle:
            parts["throttle"] = s.throttle * 2.0 - 1.0
        return self._root_layout.build(**parts)

    def uniform(self, low, high, shape) -> torch.Tensor:
        """Uniform in [low, high] (per component of the last dimension), ``shape`` (num_envs, ...),
        from the current reset's random numbers."""
        low = torch.as_tensor(low, device=self.device, dtype=torch.float32)
        high = torch.as_tensor(high, device=self.device, dtype=torch.float32)
        dims = low.shape[-1] if low.dim() else 1
        count = dims
        for x in shape[1:]:
            count *= x
        u = self._tape.take(count).reshape(*shape, dims)
        out = low + (high - low) * u
        return out if low.dim() else out.squeeze(-1)

    def place_drones(self, mask: torch.Tensor, pos: torch.Tensor, quat: torch.Tensor | None = None) -> None:
        """Put the drones of the masked envs at rest at ``pos`` [N, D, 3] with rotors at hover."""
        if quat is None:
            quat = torch.tensor((1.0, 0.0, 0.0, 0.0), device=self.device)
        zeros = torch.zeros(3, device=self.device)
        self.physics.set_state(mask, pos=pos, quat=quat, vel=zeros, omega=zeros, throttle=self._hover_throttle)

    def place_ball(self, mask: torch.Tensor, pos, vel=None) -> None:
        pos = torch.as_tensor(pos, device=self.device, dtype=torch.float32)
        vel = torch.zeros(3, device=self.device) if vel is None else torch.as_tensor(vel, device=self.device, dtype=torch.float32)
        self.physics.set_state(mask, ball_pos=pos, ball_vel=vel)

    # ------------------------------------------------------------------ TorchRL plumbing
    def _make_specs(self) -> None:
        n, a = self.num_envs, self.n_drones
        dev = self.device
        self.observation_spec = Composite(
            {
                AGENTS: Composite({leaf(OBS): Unbounded((n, a, self.obs_dim), device=dev)}, shape=(n, a), device=dev),
                STATS: Composite({k: Unbounded((n, 1), device=dev) for k in self._stats_keys}, shape=(n,), device=dev),
            },
            shape=(n,),
            device=dev,
        )
        if self.actions.continuous:
            act = Bounded(-1.0, 1.0, (n, a, self.actions.dim), device=dev)
        else:
            act = Categorical(self.actions.n, (n, a), device=dev, dtype=torch.long)
        self.action_spec = Composite({AGENTS: Composite({leaf(ACTION): act}, shape=(n, a), device=dev)}, shape=(n,), device=dev)
        self.reward_spec = Composite(
            {AGENTS: Composite({leaf(REWARD): Unbounded((n, a, 1), device=dev)}, shape=(n, a), device=dev)}, shape=(n,), device=dev
        )
        self.done_spec = Composite(
            {flag: Categorical(2, (n, 1), dtype=torch.bool, device=dev) for flag in (DONE, TERMINATED, TRUNCATED)},
            shape=(n,),
            device=dev,
        )

    def _set_seed(self, seed: int | None):
        if seed is not None:
            self.rng.manual_seed(seed)
        return seed

    def _stats_tensor(self) -> torch.Tensor:
        """[N, S] the running statistics in ``_stats_keys`` order (one tensor out of the compiled step)."""
        return torch.stack([self._stats[k] for k in self._stats_keys], -1)

    def _obs_td(self, obs: torch.Tensor, stats: torch.Tensor) -> TensorDict:
        n, dev = self.num_envs, self.device
        return TensorDict(
            {
                AGENTS: TensorDict({leaf(OBS): obs}, batch_size=(n, self.n_drones), device=dev),
                STATS: TensorDict({k: stats[:, i : i + 1] for i, k in enumerate(self._stats_keys)}, batch_size=(n,), device=dev),
            },
            batch_size=self.batch_size,
            device=dev,
        )

    # ------------------------------------------------------------------ reset
    def _reset_core(self, mask: torch.Tensor, noise: torch.Tensor | None) -> tuple[torch.Tensor, torch.Tensor]:
        """Reset the envs of ``mask`` [N] from the random numbers ``noise`` [N, K]; returns the
        observations [N, A, obs] and statistics [N, S] of all envs. Fixed shapes: compiled as is."""
        if noise is not None:
            self._tape = NoiseTape(noise)
        self.t = torch.where(mask, 0, self.t)
        for k, v in self._stats.items():
            self._stats[k] = torch.where(mask, 0.0, v)
        self.actions.reset(mask)
        self.reset_task(mask)
        return self.observe(), self._stats_tensor()

    def _reset_envs(self, mask: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        if self._noise_widths is None:  # a dry run of the first reset counts its random numbers
            self._tape = NoiseTape(None, self.num_envs, self.device)
            self._reset_core(mask, None)
            self._noise_widths = tuple(self._tape.widths)
        # one [N, k] block per draw, in order: a full reset draws exactly what drawing as it goes would
        noise = torch.cat([torch.rand(self.num_envs, k, generator=self.rng, device=self.device) for k in self._noise_widths], -1)
        return self._reset_fn(mask, noise)

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        mask = None
        if tensordict is not None and "_reset" in tensordict.keys():
            mask = tensordict.get("_reset").reshape(self.num_envs).bool()
        if mask is None:
            mask = torch.ones(self.num_envs, dtype=torch.bool, device=self.device)
        out = self._obs_td(*self._reset_envs(mask))
        false = torch.zeros(self.num_envs, 1, dtype=torch.bool, device=self.device)
        out.update({DONE: false, TERMINATED: false.clone(), TRUNCATED: false.clone()})
        return out

    # ------------------------------------------------------------------ step
    def _step_core(self, action: torch.Tensor):
        """One control step of all envs: physics, referee, rewards, statistics, observations.
        Returns (observation [N, A, obs], reward [N, A], terminated [N], truncated [N], stats [N, S])."""
        action, bad = self.actions.sanitize(action)
        contacts = self.physics.step(self.actions.command_fn(action))
        self.t = self.t + 1
        s = self.physics.state
        self.last_contacts = contacts
        ev = self.referee.update(s.pos, s.ball_pos, contacts.racket, contacts.body)
        # a non-finite action is a crash of its drone, judged by the task's own rules (a match: a draw)
        ev.drone_low = ev.drone_low | bad
        self.last_events = ev
        res = self.evaluate(ev)
        reward = torch.zeros(self.num_envs, self.n_drones, device=self.device)
        for name, val in res.terms.items():
            if not self.reward_shaping and name in self.shaping_terms:
                val = torch.zeros_like(val)
            reward = reward + val
            self._stats[f"r_{name}"] = self._stats[f"r_{name}"] + val.mean(1)
            if self._team0 is not None:
                self._stats[f"r_{name}_team0"] = self._stats[f"r_{name}_team0"] + val[:, self._team0].mean(1)
        self._stats["return"] = self._stats["return"] + reward.mean(1)
        if self._team0 is not None:
            self._stats["return_team0"] = self._stats["return_team0"] + reward[:, self._team0].mean(1)
        self._stats["episode_len"] = self._stats["episode_len"] + 1.0
        for k, v in res.stats.items():
            # a copy, never the task's own buffer: aliased inputs would recompile the reset graph
            self._stats[k] = v.to(torch.float32, copy=True)
        bad = bad.any(1)
        self._stats["nonfinite_action"] = torch.maximum(self._stats["nonfinite_action"], bad.float())
        terminated = res.terminated | bad
        truncated = (self.t >= self.episode_len) & ~terminated
        return self.observe(), reward, terminated, truncated, self._stats_tensor()

    def _run_step(self, tensordict: TensorDictBase):
        action = tensordict.get(ACTION)
        self.actions.check(action)
        obs, reward, terminated, truncated, stats = self._step_fn(action)
        if not self._warned_nonfinite and self.actions.continuous and bool(stats[:, -1].any()):
            self._warned_nonfinite = True
            warnings.warn(
                f"{self.name}: a non-finite action ended its episode as a crash (counted in stats 'nonfinite_action')",
                RuntimeWarning, stacklevel=3,
            )
        out = self._obs_td(obs, stats)
        out.set(REWARD, reward.unsqueeze(-1))
        out.set(TERMINATED, terminated.unsqueeze(-1))
        out.set(TRUNCATED, truncated.unsqueeze(-1))
        out.set(DONE, (terminated | truncated).unsqueeze(-1))
        return out

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        return self._run_step(tensordict)

    def _step_and_maybe_reset(self, tensordict: TensorDictBase) -> tuple[TensorDictBase, TensorDictBase]:
        """TorchRL's step + partial reset, with the same result, without its generic plumbing: one
        step, then (if any env is done) one masked reset of the done envs; the reset's observations
        and statistics are those of every env (unchanged where nothing reset)."""
        if tensordict.device != self.device:
            tensordict = tensordict.to(self.device)
        nxt = self._run_step(tensordict)
        tensordict.set(NEXT, nxt)
        following = self._step_mdp(tensordict)
        done = nxt.get(DONE).reshape(self.num_envs)
        if bool(done.any()):
            obs, stats = self._reset_envs(done)
            following.update(self._obs_td(obs, stats))
            false = torch.zeros(self.num_envs, 1, dtype=torch.bool, device=self.device)
            following.update({DONE: false, TERMINATED: false.clone(), TRUNCATED: false.clone()})
        return tensordict, following

    def episode_stats(self, td: TensorDictBase) -> dict[str, torch.Tensor]:
        """The statistics of the episodes that ended in a step's output ``td`` (its ``next``)."""
        done = td.get(DONE).reshape(-1)
        return {k: td.get(stat(k)).reshape(-1)[done] for k in self._stats_keys}
