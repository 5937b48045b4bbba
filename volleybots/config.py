"""Config schemas, composition and validation for the ``volleybots`` CLI.

The YAML tree lives in ``conf/`` (found by ``volleybots.paths.conf_dir()`` wherever the package is
installed). Hydra composes it; this module then checks the result against dataclass schemas so that a
misspelt key or a value of the wrong type is rejected with one line naming the key:

* the fixed part (env, logging, checkpoints, ...) is ``Config`` below;
* a task's keys are derived from its class's constructor signature (``task_schema``), so a new task
  needs only its YAML file;
* an algorithm's keys are its own dataclass config (``volleybots.algos.ALGOS[name].config_cls``).
"""

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

from volleybots.errors import ConfigError, Range, check_device, field_range, ranged
from volleybots.paths import conf_dir

GROUPS = ("task", "algo", "env")  # config groups selected by `group=option`
LOGGERS = ("csv", "wandb")
WANDB_MODES = ("offline", "online", "disabled")
# constructor arguments of a task that come from the env config (or the run), not the task's YAML
ENV_ARGS = ("num_envs", "action_space", "physics", "device", "seed", "substeps", "drone", "ball_drag", "downwash", "compile", "compile_physics")
MAX_SEED = 2**63 - 1  # torch generators take 64-bit seeds; evaluation adds an offset to the run's
MAX_THREADS = 1024  # more torch CPU threads than this is never useful, and a typo of it hangs the machine


# Every numeric key carries its valid range (``ranged``); ``validate`` checks them all in one place.
@dataclass
class EnvConfig:
    physics: str = "torch"
    action_space: str = "prt"
    num_envs: int = ranged(256, ge=1)
    device: str = "cpu"
    substeps: int = ranged(4, ge=1)
    drone: str = "iris"
    compile: bool = False
    ball_drag: float = ranged(0.0, ge=0)
    downwash: bool = True


@dataclass
class WandbConfig:
    project: str = "volleybots"
    mode: str = "offline"


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
    env: EnvConfig = field(default_factory=EnvConfig)
    seed: int = ranged(0, ge=0, le=MAX_SEED)
    threads: int = ranged(0, ge=0, le=MAX_THREADS)
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
    "target": Range(length=3),  # a fixed hover target, x y z in m (null: random)
}


# ---------------------------------------------------------------------------------------- schemas
def group_options(group: str) -> list[str]:
    """The options of a config group: the YAML files of ``conf/<group>/``."""
    return sorted(p.stem for p in (conf_dir() / group).glob("*.yaml"))


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


def validate(cfg) -> DictConfig:
    """Check a composed config (DictConfig or dict) against the schemas and the registries.

    Returns a typed, resolved DictConfig without the ``hydra`` node. Raises ``ConfigError``."""
    from volleybots.algos import ALGOS
    from volleybots.algos.base import class_attr
    from volleybots.physics import ACTION_SPACES, BACKENDS
    from volleybots.tasks import TASKS

    data = cfg if isinstance(cfg, dict) else OmegaConf.to_container(cfg, resolve=True)
    data = {k: v for k, v in data.items() if k != "hydra"}
    task, algo = data.get("task"), data.get("algo")
    if isinstance(task, dict) and "compile_physics" in task:
        # saved by versions whose task constructor took compile_physics (now env.compile): the
        # runs and checkpoints they wrote still load; the value only ever mirrored env.compile
        task = {k: v for k, v in task.items() if k != "compile_physics"}
    if not isinstance(task, dict) or "name" not in task:
        raise ConfigError(f"the config has no task; choose one with task=NAME, allowed: {', '.join(sorted(TASKS))}")
    if task["name"] not in TASKS:
        raise ConfigError(f"unknown task {task['name']!r}; allowed: {', '.join(sorted(TASKS))}")
    if not isinstance(algo, dict) or "name" not in algo:
        raise ConfigError(f"the config has no algo; choose one with algo=NAME, allowed: {', '.join(ALGOS)}")
    if algo["name"] not in ALGOS:
        raise ConfigError(f"unknown algo {algo['name']!r}; allowed: {', '.join(ALGOS)}")
    task_cls_schema = task_schema(task["name"])
    typed_task = _typed(task_cls_schema, task, "task.")
    algo_cls = ALGOS[algo["name"]]
    typed_algo = _typed(algo_cls.config_cls, algo, "algo.")
    rest = _typed(Config, {k: v for k, v in data.items() if k not in ("task", "algo")}, "")
    rest.task, rest.algo = typed_task, typed_algo

    check_values(Config, rest, "")
    check_values(task_cls_schema, typed_task, "task.")
    check_values(algo_cls.config_cls, typed_algo, "algo.")
    env = rest.env
    for value, allowed, what in (
        (env.action_space, ACTION_SPACES, "env.action_space"),
        (env.physics, BACKENDS, "env.physics"),
        (rest.logger, LOGGERS, "logger"),
        (rest.wandb.mode, WANDB_MODES, "wandb.mode"),
        (env.drone, group_options("env/drone"), "env.drone"),
    ):
        if value not in allowed:
            raise ConfigError(f"unknown {what} {value!r}; allowed: {', '.join(allowed)}")
    check_device("env.device", env.device)
    if rest.logger == "wandb":
        import importlib.util

        if importlib.util.find_spec("wandb") is None:
            raise ConfigError("logger=wandb needs the wandb package: pip install 'volleybots[wandb]' (or use logger=csv)")
    algo_cls.check(typed_algo, TASKS[typed_task.name], env)
    if rest.opponent is not None:
        _check_opponent(rest, TASKS[typed_task.name], algo_cls)
    elif getattr(algo_cls, "needs_seat_on_matches", False) and class_attr(TASKS[typed_task.name], "competitive"):
        raise ConfigError(
            f"algo {algo_cls.name!r} on a match learns one team: give it opponent=COMPETITOR (scripted, random, a run dir, ...)"
        )
    return rest


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
        check_range(key, value, field_range(schema, f.name) or (Range() if isinstance(value, float) else None))
        if isinstance(value, str) and not value.strip():
            raise ConfigError(f"bad value for {key!r}: it is empty")


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
    for key, value in kwargs.items():
        value = value.tolist() if hasattr(value, "tolist") else list(value) if isinstance(value, tuple) else value
        check_range(key, value, ranges.get(key))


OPPONENT_LEARNERS = ("mappo", "bc")  # learners that can play one team (MAPPO over one drone is PPO; bc clones the team's scripted player)


def _check_opponent(cfg, task_cls, algo_cls) -> None:
    """``opponent=``: a match, a learner that plays one team, and a competitor made for this task."""
    from volleybots.algos.base import class_attr
    from volleybots.competitors import resolve_competitor

    if not class_attr(task_cls, "competitive"):
        raise ConfigError(f"opponent={cfg.opponent!r} is for matches (1v1, 3v3, 6v6), not task {task_cls.name!r}")
    if getattr(algo_cls, "population", False):
        raise ConfigError(f"algo {algo_cls.name!r} chooses its own opponents; give it algo.seed_members=[...] instead of opponent=")
    if algo_cls.name not in OPPONENT_LEARNERS:
        raise ConfigError(f"algo {algo_cls.name!r} cannot learn one team against opponent=; allowed: {', '.join(OPPONENT_LEARNERS)}")
    obs_dim = class_attr(task_cls, "obs_dim_prt") - (4 if cfg.env.action_space == "ctbr" else 0)
    resolve_competitor(cfg.opponent).check_fits(task_cls.name, cfg.env.action_space, obs_dim)


# ------------------------------------------------------------------------------------ composition
def _check_overrides(overrides: list[str]) -> None:
    """Name the bad value of a group override before Hydra does (with the allowed options)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import OverrideParseException

    try:
        parsed = OverridesParser.create().parse_overrides(overrides)
    except OverrideParseException as e:
        raise ConfigError(f"bad override: {str(e).splitlines()[0]}") from None
    for o in parsed:
        key = o.get_key_element()
        if key in GROUPS and not o.is_delete():
            values = list(o.sweep_string_iterator()) if o.is_sweep_override() else [o.value()]
            for v in values:
                if str(v) not in group_options(key):
                    raise ConfigError(f"unknown {key} {v!r}; allowed: {', '.join(group_options(key))}")


def compose(overrides: list[str] | tuple[str, ...] = (), hydra_node: bool = False) -> DictConfig:
    """Compose ``conf/config.yaml`` with Hydra overrides (no sweeps). Raises ``ConfigError``.

    A misspelt key is reported with the keys allowed beside it."""
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir
    from hydra.errors import HydraException

    overrides = list(overrides)
    _check_overrides(overrides)
    with initialize_config_dir(config_dir=str(conf_dir()), version_base="1.3"):
        try:
            cfg = hydra_compose("config", overrides=overrides, return_hydra_config=hydra_node)
            default = _task_default_algo(cfg, overrides)
            if default is not None:
                cfg = hydra_compose("config", overrides=[*overrides, f"algo={default}"], return_hydra_config=hydra_node)
            return algo_action_space(cfg, overrides)
        except HydraException as e:
            _explain_unknown_key(overrides, hydra_compose)
            raise ConfigError(f"bad override: {_one_line(e)}") from None


def _explain_unknown_key(overrides: list[str], hydra_compose) -> None:
    """After a failed composition: raise a ConfigError naming an override's key that does not exist,
    with the keys allowed beside it (Hydra's own message lists none)."""
    from hydra.errors import HydraException

    try:
        base = hydra_compose("config", overrides=[o for o in overrides if o.split("=", 1)[0].lstrip("~+") in GROUPS])
    except HydraException:
        return
    for o in overrides:
        key = o.split("=", 1)[0]
        if "=" not in o or key.startswith(("+", "~", "hydra.")) or key in GROUPS:
            continue
        if OmegaConf.select(base, key, default=_ABSENT) is _ABSENT:
            parent = key.rpartition(".")[0]
            node = OmegaConf.select(base, parent) if parent else base
            allowed = ", ".join(str(k) for k in node.keys()) if isinstance(node, DictConfig) else "(none: not a section)"
            raise ConfigError(f"unknown config key {key!r}; allowed{' under ' + repr(parent) if parent else ''}: {allowed}")


_ABSENT = object()


def _task_default_algo(cfg: DictConfig, overrides) -> str | None:
    """The algorithm a task trains with when the command line names none (the task's
    ``default_algo``: MAPPO for the cooperative tasks, SP for the matches, MAPPO against an
    ``opponent=``), if it is not the config's
    default already. ``eval scripted task=3v3`` needs no algo at all, and ``train task=3v3`` then does
    what one expects. A named algo that cannot train the task is still an error."""
    from volleybots.algos.base import class_attr
    from volleybots.tasks import TASKS

    if any(o.split("=", 1)[0].lstrip("+~") == "algo" for o in overrides):
        return None
    task_cls = TASKS.get(OmegaConf.select(cfg, "task.name", default=None))
    if task_cls is None:
        return None
    default = OPPONENT_LEARNERS[0] if OmegaConf.select(cfg, "opponent", default=None) is not None else class_attr(task_cls, "default_algo")
    return None if default == OmegaConf.select(cfg, "algo.name", default=None) else default


def algo_action_space(cfg: DictConfig, overrides) -> DictConfig:
    """An algorithm that cannot act in the default action space (``dqn``: discrete only) gets its own
    first one, unless the command line names ``env.action_space`` (then ``validate`` rejects a bad one)."""
    from volleybots.algos import ALGOS

    if any(o.split("=", 1)[0].lstrip("+~") == "env.action_space" for o in overrides):
        return cfg
    algo_cls = ALGOS.get(OmegaConf.select(cfg, "algo.name", default=None))
    if algo_cls is not None and cfg.env.action_space not in algo_cls.action_spaces:
        cfg.env.action_space = algo_cls.action_spaces[0]
    return cfg


def _one_line(e: BaseException) -> str:
    """The innermost message of an exception chain, on one line."""
    while e.__cause__ is not None:
        e = e.__cause__
    return " ".join(str(e).split())


def load(overrides=()) -> DictConfig:
    """Compose and validate: the typed config for ``overrides``."""
    return validate(compose(overrides))


def to_dict(cfg) -> dict:
    return cfg if isinstance(cfg, dict) else OmegaConf.to_container(cfg, resolve=True)


def parse_value(value: str):
    """A command-line value as Hydra reads it (numbers, booleans, null, lists, strings)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import HydraException

    try:
        return OverridesParser.create().parse_override(f"k={value}").value()
    except HydraException as e:
        raise ConfigError(f"bad value {value!r}: {_one_line(e)}") from None


def apply_overrides(base: dict, overrides, allowed: tuple[str, ...], what: str) -> DictConfig:
    """Validate a saved config ``base`` with ``key=value`` overrides restricted to the keys (or
    sections) in ``allowed``: a run or checkpoint keeps the task, algorithm and env it was made with."""
    data = OmegaConf.create(base)
    for o in overrides:
        key, eq, value = o.partition("=")
        if not eq:
            raise ConfigError(f"bad override {o!r}: expected key=value")
        if not any(key == a or key.startswith(a + ".") for a in allowed):
            raise ConfigError(f"cannot change {key!r} of {what}; allowed: {', '.join(allowed)}")
        OmegaConf.update(data, key, parse_value(value), merge=True)
    return validate(to_dict(data))


def task_kwargs(cfg) -> dict:
    """The task's constructor keywords of a validated config (everything of ``task`` but its name)."""
    return {k: v for k, v in to_dict(cfg.task).items() if k != "name"}


def make_env(cfg, num_envs: int | None = None, seed: int | None = None):
    """Build the env a validated config describes (``num_envs`` / ``seed`` override the config's).

    Also applies ``threads`` (torch's CPU threads), which must be set before any work."""
    import torch

    import volleybots

    if cfg.threads and torch.get_num_threads() != cfg.threads:
        torch.set_num_threads(cfg.threads)

    e = cfg.env
    return volleybots.make_env(
        cfg.task.name,
        num_envs=e.num_envs if num_envs is None else num_envs,
        action_space=e.action_space,
        physics=e.physics,
        device=e.device,
        seed=cfg.seed if seed is None else seed,
        substeps=e.substeps,
        drone=e.drone,
        ball_drag=e.ball_drag,
        downwash=e.downwash,
        compile=e.compile,
        **task_kwargs(cfg),
    )


# --------------------------------------------------------------------------------------- resources
def check_memory(cfg, worlds: int | None = None) -> None:
    """Refuse a batch, replay buffer or episode count that cannot fit in memory, before anything is
    written: a training run (``worlds=None``) holds a batch of ``env.num_envs x algo.steps_per_batch``
    env steps, its replay buffer and the evaluation's ``evaluation.episodes`` worlds; ``eval`` holds
    ``worlds`` (its episodes) worlds.

    The need is a lower bound measured on a one-world probe env (the bytes of one env step's
    tensordict), so a refusal is certain; counts that pass can still run out of memory in the
    update, which the CLI reports as one line too."""
    probe = make_env(cfg, num_envs=1, seed=cfg.seed)
    step_bytes, obs_dim = _step_bytes(probe), int(probe.obs_dim)
    if worlds is not None:
        needs = [(worlds * step_bytes, f"episodes={worlds} ({step_bytes} bytes per world)", "episodes", cfg.env.device)]
    else:
        a = cfg.algo
        needs = [
            (cfg.env.num_envs * a.steps_per_batch * step_bytes,
             f"env.num_envs={cfg.env.num_envs} x algo.steps_per_batch={a.steps_per_batch} ({step_bytes} bytes per world and step)",
             "env.num_envs or algo.steps_per_batch", cfg.env.device),
            (cfg.evaluation.episodes * step_bytes, f"evaluation.episodes={cfg.evaluation.episodes} ({step_bytes} bytes per world)", "evaluation.episodes", cfg.env.device),
        ]
        if "buffer_size" in a:  # flat per-drone transitions: observation, next observation, action, reward, flags
            per = 4 * (2 * obs_dim + max(1, probe.actions.dim if probe.actions.continuous else 1) + 3)
            needs.append((a.buffer_size * per, f"algo.buffer_size={a.buffer_size} ({per} bytes per transition)", "algo.buffer_size", a.get("buffer_device") or cfg.env.device))
    check_fits(needs)


def check_fits(needs) -> None:
    """``needs``: (bytes, what needs them, the keys to lower, device); their sums per device must fit."""
    per_device: dict[str, int] = {}
    for n, _, _, device in needs:
        per_device[str(device)] = per_device.get(str(device), 0) + n
    for device, total in per_device.items():
        free = available_memory(device)
        if free is not None and total > free:
            n, what, keys, _ = max((x for x in needs if str(x[3]) == device), key=lambda x: x[0])
            raise ConfigError(
                f"{what} needs at least {_gib(n)} of memory but {device} has {_gib(free)} available; lower {keys}"
            )


def available_memory(device) -> int | None:
    """Bytes that can still be allocated on ``device`` (RAM plus free swap for the CPU); None if unknown."""
    import torch

    dev = torch.device(device)
    if dev.type == "cuda":
        return int(torch.cuda.mem_get_info(dev)[0])
    if dev.type != "cpu":
        return None
    try:
        import psutil
    except ImportError:
        return None
    return int(psutil.virtual_memory().available + psutil.swap_memory().free)


def _gib(n: int) -> str:
    return f"{n / 2**30:,.1f} GiB"


def _step_bytes(probe) -> int:
    """The bytes of one step of a one-world ``probe`` env (closed afterwards): the tensordict of
    observations, actions, rewards, flags and statistics that a batch holds per world and step."""
    n = int(probe.rand_step(probe.reset()).bytes())
    close = getattr(probe.physics, "close", None)
    if close is not None:
        close()
    return n


@dataclass
class BenchOptions:
    """The options of ``volleybots bench`` (the keywords of ``volleybots.bench.run_bench``), typed and
    ranged like the config; a scalar where a list is expected is taken as a list of one."""

    tasks: Optional[list[str]] = None
    backends: Optional[list[str]] = None
    num_envs: Optional[list[int]] = ranged(None, ge=1)
    devices: Optional[list[str]] = None
    compile: Any = None  # a bool, or a list of bools to measure both ways
    repeats: int = ranged(3, ge=1)
    steps: Optional[int] = ranged(None, ge=1)
    action_space: str = "prt"
    threads: Optional[int] = ranged(None, ge=0, le=MAX_THREADS)
    train: bool = False  # also measure PPO (solo_bump) / MAPPO (3v3) training frames/s
    train_batches: int = ranged(3, ge=1)  # timed training batches per training row


def check_bench_options(options: dict) -> dict:
    """The ``volleybots bench`` options ``options`` checked (types, names, ranges, memory) and as
    plain values; raises ``ConfigError`` naming the first bad one. Only the given keys are returned."""
    import volleybots
    from volleybots.physics import ACTION_SPACES, BACKENDS
    from volleybots.tasks import TASKS

    lists = ("tasks", "backends", "num_envs", "devices")
    data = {k: (v if isinstance(v, list) or k not in lists else [v]) for k, v in options.items()}
    for k in lists:
        if data.get(k) == []:
            raise ConfigError(f"bad value for {k!r}: an empty list measures nothing")
    typed = _typed(BenchOptions, data, "")
    check_values(BenchOptions, typed, "")
    out = {k: to_dict(typed)[k] for k in data}
    for key, allowed in (("tasks", sorted(TASKS)), ("backends", list(BACKENDS)), ("action_space", list(ACTION_SPACES))):
        given = out.get(key)
        for v in given if isinstance(given, list) else [given] if given is not None else []:
            if v not in allowed:
                raise ConfigError(f"unknown {key} {v!r}; allowed: {', '.join(allowed)}")
    comp = out.get("compile")
    if comp is not None and not all(isinstance(c, bool) for c in (comp if isinstance(comp, list) else [comp])):
        raise ConfigError(f"bad value for 'compile': {comp!r} (must be true, false or a list of them)")
    for d in out.get("devices") or ():
        check_device("devices", d)
    n = max(out.get("num_envs") or [1])
    for task in out.get("tasks") or ["solo_bump"]:
        step_bytes = _step_bytes(volleybots.make_env(task, num_envs=1, action_space=out.get("action_space", "prt")))
        check_fits([(n * step_bytes, f"num_envs={n} ({task}, {step_bytes} bytes per world)", "num_envs", d) for d in out.get("devices") or ["cpu"]])
    return out


__all__ = [
    "Config", "ConfigError", "EnvConfig", "algo_action_space", "apply_overrides", "compose", "parse_value", "group_options", "load", "make_env", "task_kwargs",
    "task_schema", "to_dict", "validate", "check_values", "check_memory", "check_bench_options", "BenchOptions", "available_memory",
]
