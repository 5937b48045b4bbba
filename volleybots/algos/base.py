"""What the run loop (``volleybots.train``) needs from an algorithm.

An algorithm is one class with a small dataclass config beside it (BenchMARL style), registered by
name in ``volleybots.algos.ALGOS``. The loop collects ``steps_per_batch`` steps of every env with
``policy()``, hands the batch to ``update()``, logs what it returns, and checkpoints ``state_dict()``.
"""

from __future__ import annotations

import inspect
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, Callable, ClassVar

from tensordict import TensorDictBase
from torch import nn

from volleybots.errors import ConfigError
from volleybots.physics import ACTION_SPACES

ACTIVATIONS = {"elu": nn.ELU, "relu": nn.ReLU, "tanh": nn.Tanh, "leaky_relu": nn.LeakyReLU}
TASK_KINDS = ("single", "cooperative", "competitive")  # one drone; several drones in one team; two teams


@dataclass(frozen=True)
class AgentSpec:
    """What an algorithm learns for: how many agents, what each sees and how it acts, on which device.

    An env is one (all its drones: single-drone and cooperative tasks); a match's team is another
    (``AgentSpec.of(env, team_size)``): a learner of one team sizes its centralised critic for that
    team, and a frozen policy is rebuilt for the agent count it was trained with."""

    device: Any
    n_drones: int
    obs_dim: int
    actions: Any  # the env's action space (``continuous``, ``dim`` or ``n``)

    @classmethod
    def of(cls, env, n_agents: int | None = None) -> "AgentSpec":
        return cls(env.device, int(env.n_drones if n_agents is None else n_agents), int(env.obs_dim), env.actions)


class Algorithm(ABC):
    name: ClassVar[str]
    config_cls: ClassVar[type]
    action_spaces: ClassVar[tuple[str, ...]] = ACTION_SPACES  # action spaces it can act in
    multi_agent: ClassVar[bool] = False  # whether it trains tasks with several drones
    # the kinds of task (TASK_KINDS) it trains; None: "single", and every kind when ``multi_agent``
    task_kinds: ClassVar[tuple[str, ...] | None] = None

    def __init__(self, cfg, env):
        """``env`` is the env it trains on or an ``AgentSpec`` (a team of a match)."""
        self.cfg = cfg
        self.device = env.device
        self.n_agents = env.n_drones
        self.obs_dim = env.obs_dim
        self.continuous = env.actions.continuous
        self.action_dim = env.actions.dim if self.continuous else env.actions.n

    @classmethod
    def check(cls, cfg, task_cls, env_cfg) -> None:
        """Raise ``ConfigError`` when the algorithm's config ``cfg`` is bad or it cannot train
        ``task_cls`` in the env of ``env_cfg`` (action space, batch size)."""
        action_space = env_cfg.action_space
        if hasattr(cfg, "activation") and cfg.activation not in ACTIVATIONS:
            raise ConfigError(f"unknown algo.activation {cfg.activation!r}; allowed: {', '.join(ACTIVATIONS)}")
        if action_space not in cls.action_spaces:
            raise ConfigError(
                f"algo {cls.name!r} does not support env.action_space={action_space!r}; allowed: {', '.join(cls.action_spaces)}"
            )
        n_drones = class_attr(task_cls, "n_drones")
        if n_drones > 1 and not cls.multi_agent:
            multi = sorted({a.name for a in _subclasses(Algorithm) if a.multi_agent})
            raise ConfigError(
                f"algo {cls.name!r} trains one drone but task {task_cls.name!r} has {n_drones}; use one of: {', '.join(multi)}"
            )
        kind, kinds = task_kind(task_cls), cls.supported_kinds()
        if kind not in kinds:
            from volleybots.tasks import TASKS

            allowed = [n for n, t in TASKS.items() if task_kind(t) in kinds]
            raise ConfigError(
                f"algo {cls.name!r} trains {' or '.join(kinds)} tasks but task {task_cls.name!r} is {kind}; "
                f"allowed tasks: {', '.join(allowed)}"
            )

    @classmethod
    def supported_kinds(cls) -> tuple[str, ...]:
        """The kinds of task (``TASK_KINDS``) this algorithm trains."""
        if cls.task_kinds is not None:
            return cls.task_kinds
        return TASK_KINDS if cls.multi_agent else ("single",)

    @property
    def steps_per_batch(self) -> int:
        return int(self.cfg.steps_per_batch)

    @abstractmethod
    def policy(self, deterministic: bool = False) -> Callable[[TensorDictBase], TensorDictBase]:
        """A function writing ``("agents", "action")`` into an env tensordict (no gradients)."""

    @abstractmethod
    def update(self, batch: TensorDictBase) -> dict[str, float]:
        """Learn from a batch [num_envs, steps] of transitions; return scalars to log (losses, ...)."""

    @abstractmethod
    def state_dict(self) -> dict:
        """Everything needed to continue training: networks, optimisers, normalisers (tensors only)."""

    @abstractmethod
    def load_state_dict(self, state: dict) -> None:
        ...

    def init_parts(self) -> dict[str, nn.Module]:
        """The networks another run may start this one from (``init=``), by role: ``actor`` (what acts,
        required) and ``critic`` (loaded where it fits); a part loads from the source's part of the
        same role when every parameter has the same name and shape."""
        return {}

    def guide_from(self, source: "Algorithm") -> bool:
        """``init=`` from ``source`` (built and loaded) whose networks this algorithm's cannot take:
        return True if it keeps them another way (SAC: a PPO-family actor as a frozen guide). Only
        asked when the task, drone count, action space and observation size fit."""
        return False

    def after_init(self) -> None:
        """Called once ``init=`` has loaded parts (an off-policy method copies them to its targets)."""


def task_kind(task_cls) -> str:
    """``single`` (one drone), ``cooperative`` (several drones, one team) or ``competitive`` (two teams)."""
    if class_attr(task_cls, "n_drones") == 1:
        return "single"
    return "competitive" if class_attr(task_cls, "competitive") else "cooperative"


def class_attr(cls, name: str):
    """A class attribute that a task may define as a property of other class attributes
    (the matches derive ``n_drones`` from ``team_size``)."""
    value = inspect.getattr_static(cls, name)
    return value.fget(cls) if isinstance(value, property) else value


def mlp(in_dim: int, out_dim: int, hidden, activation: str, out_gain: float) -> nn.Sequential:
    """An MLP with orthogonal init (gain sqrt(2) on hidden layers, ``out_gain`` on the output layer)."""
    layers: list[nn.Module] = []
    dims = [in_dim, *hidden]
    for a, b in zip(dims[:-1], dims[1:]):
        layers += [nn.Linear(a, b), ACTIVATIONS[activation]()]
    layers.append(nn.Linear(dims[-1], out_dim))
    for m in layers:
        if isinstance(m, nn.Linear):
            nn.init.orthogonal_(m.weight, gain=out_gain if m is layers[-1] else 2**0.5)
            nn.init.zeros_(m.bias)
    return nn.Sequential(*layers)


def _subclasses(cls) -> list[type]:
    """Every subclass of ``cls``, recursively (the registry in ``volleybots.algos`` imports this module,
    so the alternatives an error names are found here without importing it back)."""
    out = []
    for sub in cls.__subclasses__():
        out += [sub, *_subclasses(sub)]
    return out
