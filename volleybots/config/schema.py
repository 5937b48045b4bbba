"""Config schemas: the fixed keys (``Config``), the tasks' keys derived from their constructors, and
the one range check every numeric key goes through."""

from __future__ import annotations

import dataclasses
import inspect
import math
import types
import typing
from dataclasses import dataclass, field
from typing import Any, Optional

from omegaconf import MISSING, DictConfig, ListConfig, OmegaConf
from omegaconf.errors import ConfigKeyError, OmegaConfBaseException, ValidationError

from volleybots.errors import ConfigError, Range, field_range, ranged
from volleybots.paths import conf_dir

GROUPS = ("task", "algo", "population", "env")  # config groups selected by `group=option`
LOGGERS = ("csv", "wandb")
WANDB_MODES = ("offline", "online", "disabled")
# constructor arguments of a task that come from the env config (or the run), not the task's YAML
ENV_ARGS = (
    "num_envs", "action_space", "physics", "device", "seed", "substeps", "drone", "ball_drag", "downwash", "compile", "compile_physics",
)
MAX_SEED = 2**63 - 1  # torch generators take 64-bit seeds; evaluation adds an offset to the run's
MAX_THREADS = 1024  # more torch CPU threads than this is never useful, and a typo of it hangs the machine
MAX_ENVS = 2**24  # worlds of one env built by the Python API (a world takes ~300 bytes a step: past any device)
MAX_SUBSTEPS = 64  # physics sub-steps per control step: 4 is stable; 1e5 runs silent for minutes
# a numeric key without a declared upper (or lower) bound is still bounded by this: no count, budget or
# coefficient of the project comes near it, and past it int64 / float32 arithmetic overflows or a run never ends
MAX_MAGNITUDE = 10**15


# Every numeric key carries its valid range (``ranged``); ``validate`` checks them all in one place.
@dataclass
class EnvConfig:
    physics: str = "torch"
    action_space: str = "prt"
    num_envs: int = ranged(256, ge=1)
    device: str = "cpu"
    substeps: int = ranged(4, ge=1, le=MAX_SUBSTEPS)
    drone: str = "iris"
    compile: bool = False
    ball_drag: float = ranged(0.0, ge=0)
    downwash: bool = True


@dataclass
class WandbConfig:
    project: str = "volleybots"
    mode: str = "offline"
    group: Optional[str] = None
    tags: list[str] = field(default_factory=list)
    artifacts: bool = False


@dataclass
class CheckpointConfig:
    every: int = ranged(2_000_000, ge=0)
    keep: int = ranged(3, ge=1)
    best: bool = True


@dataclass
class EvaluationConfig:
    every: int = ranged(2_000_000, ge=0)
    episodes: int = ranged(16, ge=1)
    record: bool = True


@dataclass
class Config:
    task: Any = MISSING  # checked against task_schema(task.name)
    algo: Any = MISSING  # checked against the algorithm's config dataclass
    population: Any = None  # a population method's loop keys, checked against its preset's dataclass (None: one learner)
    env: EnvConfig = field(default_factory=EnvConfig)
    seed: int = ranged(0, ge=0, le=MAX_SEED)
    threads: int = ranged(1, ge=0, le=MAX_THREADS)  # 1: fast on a shared small machine; 0: torch's default (docs/training.md)
    total_frames: int = ranged(1_000_000, ge=1)
    time_limit: float = ranged(0.0, ge=0)
    resume: Optional[str] = None
    init: Optional[str] = None
    opponent: Optional[str] = None
    opponent_deterministic: bool = False
    progress: bool = True
    logger: str = "csv"
    wandb: WandbConfig = field(default_factory=WandbConfig)
    checkpoint: CheckpointConfig = field(default_factory=CheckpointConfig)
    evaluation: EvaluationConfig = field(default_factory=EvaluationConfig)
    episodes: int = ranged(100, ge=1)
    deterministic: bool = True


# The ranges of the tasks' numeric constructor arguments (the task schemas are derived from the
# constructors, so their ranges live here, by argument name; a test fails for a numeric one missing).
TASK_RANGES: dict[str, Range] = {
    "episode_len": Range(low=1),  # control steps (null: the task's own)
    "hit_reward": Range(),
    "height_reward": Range(),
    "stay_reward": Range(),
    "target_reward": Range(),
    "far_starts": Range(low=0, high=1),  # Solo Bump's share of far starts (a training curriculum)
    "serve": Range(low=0, high=1),  # the serving team (null: random)
    "side": Range(low=0, high=1),  # the attack drill's target half: 0 left, 1 right (null: random)
    "deep": Range(low=0, high=1),  # the receive drill's share of deep, flat serves
    "serves": Range(low=0, high=1),  # the pass and attack drills' share of balls that are the 3v3 scripted team's serve
    "under_reward": Range(low=0),  # the receive drill's shaping coefficient (null: the task's own)
    "target": Range(length=3),  # a fixed hover target, x y z in m (null: random)
}


# ---------------------------------------------------------------------------------------- schemas
def group_options(group: str) -> list[str]:
    """The options of a config group: the YAML files of ``conf/<group>/``, and of ``<DIR>/<group>/`` for
    a user's config folder of the words being checked (``searchpath.active``: the top groups only; a
    drone file is read by the physics from ``conf/`` alone)."""
    from volleybots.config.searchpath import active_dirs

    roots = (conf_dir(), *active_dirs()) if group in GROUPS else (conf_dir(),)
    return sorted({p.stem for root in roots for p in (root / group).glob("*.yaml")})


def _omegaconf_type(tp) -> Any:
    """A constructor annotation as a type OmegaConf can check (PEP 604 unions become Optional)."""
    if tp in (int, float, bool, str):
        return tp
    args = typing.get_args(tp)
    if typing.get_origin(tp) in (typing.Union, types.UnionType) and type(None) in args:
        rest = [a for a in args if a is not type(None)]
        if len(rest) == 1 and rest[0] in (int, float, bool, str):
            return Optional[rest[0]]
    return Any


def task_schema(name: str) -> type:
    """A dataclass of the keys a task's YAML may hold: ``name`` plus the keyword arguments of the task
    class's constructor chain that are not env settings, with their annotated types and defaults."""
    from volleybots.tasks import TASKS, VolleyEnv

    cls = TASKS[name]
    fields_: dict[str, tuple] = {"name": (str, dataclasses.field(default=name))}
    for klass in (k for k in cls.__mro__ if issubclass(k, VolleyEnv)):
        init = klass.__dict__.get("__init__")
        if init is None:
            continue
        try:
            hints = typing.get_type_hints(init)
        except (NameError, TypeError):
            hints = {}
        for p in inspect.signature(init).parameters.values():
            if p.name == "self" or p.name in ENV_ARGS or p.name in fields_:
                continue
            if p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
                continue
            default = MISSING if p.default is p.empty else p.default
            tp = _omegaconf_type(hints.get(p.name, Any))
            if default is None and tp in (int, float, bool, str):
                tp = Optional[tp]
            meta = {"range": TASK_RANGES[p.name]} if p.name in TASK_RANGES else {}
            fields_[p.name] = (tp, dataclasses.field(default=default, metadata=meta))
    return dataclasses.make_dataclass(f"{cls.__name__}Config", [(k, t, f) for k, (t, f) in fields_.items()])


def _coerce_ints(schema: type, node: dict) -> dict:
    """Integral floats for int fields (``total_frames=2e6``) become ints; nested dataclasses recurse."""
    hints = typing.get_type_hints(schema)
    for f in dataclasses.fields(schema):
        if f.name not in node:
            continue
        tp, val = hints.get(f.name), node[f.name]
        if dataclasses.is_dataclass(tp) and isinstance(val, dict):
            _coerce_ints(tp, val)
        elif tp in (int, Optional[int]) and _integral(val):
            node[f.name] = int(val)
        elif tp in (list[int], Optional[list[int]]) and isinstance(val, list):
            node[f.name] = [int(v) if _integral(v) else v for v in val]
    return node


def _integral(v) -> bool:
    return isinstance(v, float) and v.is_integer()


def _typed(schema: type, node, prefix: str) -> DictConfig:
    """Merge ``node`` onto ``schema``; an unknown key or a bad value raises one ConfigError line."""
    data = node if isinstance(node, dict) else OmegaConf.to_container(node, resolve=True)
    data = _coerce_ints(schema, dict(data))
    try:
        return OmegaConf.merge(OmegaConf.structured(schema), data)
    except ConfigKeyError as e:
        allowed = ", ".join(f.name for f in dataclasses.fields(schema))
        key = str(e.key) if getattr(e, "key", None) is not None else str(e.full_key)
        raise ConfigError(f"unknown config key {prefix + key!r}; allowed: {allowed}") from None
    except ValidationError as e:
        msg = str(e.msg).splitlines()[0] if getattr(e, "msg", None) else str(e).splitlines()[0]
        raise ConfigError(f"bad value for {prefix + str(e.full_key)!r}: {msg}") from None
    except OmegaConfBaseException as e:
        raise ConfigError(f"bad config under {prefix.rstrip('.') or 'top level'!r}: {str(e).splitlines()[0]}") from None



def check_values(schema: type, node, prefix: str) -> None:
    """The one range check: every numeric field of ``schema`` (nested dataclasses included) against
    the range in its metadata (``volleybots.errors.ranged``), and no string field empty. Floats
    without a declared range must still be finite. Raises ``ConfigError`` naming the key."""
    hints = typing.get_type_hints(schema)
    for f in dataclasses.fields(schema):
        if f.name not in node:
            continue
        value, key = node[f.name], prefix + f.name
        if dataclasses.is_dataclass(hints.get(f.name)):
            check_values(hints[f.name], value, key + ".")
            continue
        value = OmegaConf.to_container(value) if isinstance(value, (DictConfig, ListConfig)) else value
        rng = field_range(schema, f.name)
        check_range(key, value, rng or (Range() if isinstance(value, float) else None))
        check_magnitude(key, value, rng)
        if isinstance(value, str) and not value.strip():
            raise ConfigError(f"bad value for {key!r}: it is empty")


def check_magnitude(key: str, value, rng: Range | None = None) -> None:
    """Refuse a number (or a list's) beyond ``MAX_MAGNITUDE`` on a side the key's range ``rng`` leaves
    open: 1e30 and 2**63 are no one's setting."""
    open_high, open_low = rng is None or rng.high is None, rng is None or rng.low is None
    for v in value if isinstance(value, list) else [value]:
        if isinstance(v, (int, float)) and not isinstance(v, bool) and (v > MAX_MAGNITUDE and open_high or v < -MAX_MAGNITUDE and open_low):
            raise ConfigError(f"bad value for {key!r}: {value!r} (must be within +-{MAX_MAGNITUDE:.0e}: no setting comes near it)")


def check_range(key: str, value, rng: Range | None) -> None:
    """Raise ``ConfigError`` naming ``key`` unless ``value`` (None: unset) is in ``rng`` (None: any)."""
    if rng is None or value is None or rng.holds(value):
        return
    each = " each" if isinstance(value, list) and rng.length is None else ""
    finite = "finite and " if isinstance(value, float) and not math.isfinite(value) and rng.length is None else ""
    raise ConfigError(f"bad value for {key!r}: {value!r} (must be {finite}{rng}{each})")


def check_env_args(**kwargs) -> None:
    """``volleybots.make_env``'s keywords against the ranges of the config's env and task keys (and
    ``seed``), so that ``make_env(..., substeps=0)`` is a clear error rather than a ZeroDivisionError."""
    ranges = {f.name: field_range(s, f.name) for s in (EnvConfig, Config) for f in dataclasses.fields(s)}
    ranges.update(TASK_RANGES)
    ints = {f.name for s in (EnvConfig, Config) for f in dataclasses.fields(s) if f.type in (int, "int")}
    for key, value in kwargs.items():
        value = value.tolist() if hasattr(value, "tolist") else list(value) if isinstance(value, tuple) else value
        if key in ints and (isinstance(value, bool) or not isinstance(value, int)):
            raise ConfigError(f"bad value for {key!r}: {value!r} (must be an integer)")
        check_range(key, value, ranges.get(key))
        check_magnitude(key, value, ranges.get(key))
        if key == "num_envs" and value > MAX_ENVS:  # the config's num_envs is held by the memory check instead
            raise ConfigError(f"bad value for 'num_envs': {value} (at most {MAX_ENVS:,} worlds: past any device's memory)")



def to_dict(cfg) -> dict:
    return cfg if isinstance(cfg, dict) else OmegaConf.to_container(cfg, resolve=True)

