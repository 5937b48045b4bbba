"""Validation: a composed config checked against the schemas and the registries, in one pass.

``validate`` checks names, types, ranges and the choices that depend on each other (an algorithm that
cannot act in the action space, ``opponent=`` on a task that is no match). It never opens the files a
config names (``opponent=``, ``init=``, ``population.seed_members``): a saved run's config stays valid after
the files it was trained against have moved. Whether those files exist and fit is the pre-flight
check of whoever is about to use them (``volleybots.policies.check_references``).
"""

from __future__ import annotations

import importlib.util
import os

from omegaconf import DictConfig, OmegaConf

from volleybots.config.schema import LOGGERS, WANDB_MODES, Config, _typed, check_values, group_options, task_schema
from volleybots.errors import ConfigError, check_device


def validate(cfg) -> DictConfig:
    """Check a composed config (DictConfig or dict) against the schemas and the registries.

    Returns a typed, resolved DictConfig without the ``hydra`` node. Raises ``ConfigError``."""
    from volleybots.algos import ALGOS, upgrade_saved
    from volleybots.algos.base import class_attr
    from volleybots.physics import ACTION_SPACES, BACKENDS
    from volleybots.tasks import TASKS

    data = cfg if isinstance(cfg, dict) else OmegaConf.to_container(cfg, resolve=True)
    data = upgrade_saved({k: v for k, v in data.items() if k != "hydra"})  # a population run saved before population=
    task, algo = data.get("task"), data.get("algo")
    if isinstance(task, dict) and "compile_physics" in task:
        # saved by versions whose task constructor took compile_physics (now env.compile): the
        # runs and checkpoints they wrote still load; the value only ever mirrored env.compile
        task = {k: v for k, v in task.items() if k != "compile_physics"}
    if not isinstance(task, dict) or not isinstance(task.get("name"), str):
        raise ConfigError(f"the config has no task; choose one with task=NAME, allowed: {', '.join(sorted(TASKS))}")
    if task["name"] not in TASKS:
        raise ConfigError(f"unknown task {task['name']!r}; allowed: {', '.join(sorted(TASKS))}")
    if not isinstance(algo, dict) or not isinstance(algo.get("name"), str):
        raise ConfigError(f"the config has no algo; choose one with algo=NAME, allowed: {', '.join(ALGOS)}")
    if algo["name"] not in ALGOS:
        raise ConfigError(f"unknown algo {algo['name']!r}; allowed: {', '.join(ALGOS)}")
    task_cls_schema = task_schema(task["name"])
    typed_task = _typed(task_cls_schema, task, "task.")
    preset, typed_pop = _population(data.get("population"), data.get("init") is not None, task["name"], algo["name"])
    algo_cls = preset.learner_of(algo) if preset is not None else ALGOS[algo["name"]]  # a population's learner is one of LEARNERS
    typed_algo = _typed(algo_cls.config_cls, algo, "algo.")
    rest = _typed(Config, {k: v for k, v in data.items() if k not in ("task", "algo", "population")}, "")
    rest.task, rest.algo, rest.population = typed_task, typed_algo, typed_pop
    if typed_pop is not None and not rest.time_limit:  # a population's bound on a slow task (the bare 6v6 headline)
        rest.time_limit = float(typed_pop.default_time_limit.get(typed_task.name, 0.0))

    check_values(Config, rest, "")
    check_values(task_cls_schema, typed_task, "task.")
    check_values(algo_cls.config_cls, typed_algo, "algo.")
    if preset is not None:
        check_values(preset.config_cls, typed_pop, "population.")
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
    for tag in rest.wandb.tags:  # W&B refuses a run whose tag is empty or longer than 64 characters
        if not 1 <= len(tag.strip()) <= 64:
            raise ConfigError(f"bad value for 'wandb.tags': {tag!r} (each tag must be 1 to 64 characters)")
    if rest.logger == "wandb":
        if importlib.util.find_spec("wandb") is None:
            raise ConfigError("logger=wandb needs the wandb package: pip install 'volleybots[wandb]' (or use logger=csv)")
        check_wandb(rest.wandb)
    if preset is not None:  # a population checks its learner as one team's
        preset.check(typed_pop, typed_algo, TASKS[typed_task.name], env)
    else:
        algo_cls.check(typed_algo, TASKS[typed_task.name], env)
    if rest.opponent is not None:
        _check_opponent(rest, TASKS[typed_task.name], algo_cls)
    elif getattr(algo_cls, "needs_seat_on_matches", False) and class_attr(TASKS[typed_task.name], "competitive"):
        raise ConfigError(
            f"algo {algo_cls.name!r} on a match learns one team: give it opponent=COMPETITOR (scripted, random, a run dir, ...)"
        )
    return rest



def _population(pop, has_init: bool, task: str, learner: str):
    """The preset and the typed ``population`` node of a config (``(None, None)`` for a run of one learner),
    with what ``population.start`` and ``members=auto`` leave to the preset filled in (``has_init``: the run
    names ``init=``; ``task``, ``learner``: the run's task and ``algo=``)."""
    from volleybots.algos import PRESETS

    if pop is None:
        return None, None
    if not isinstance(pop, dict) or pop.get("name") not in PRESETS:
        name = pop.get("name") if isinstance(pop, dict) else pop
        raise ConfigError(f"unknown population {name!r}; allowed: {', '.join(PRESETS)}")
    preset = PRESETS[pop["name"]]
    typed = _typed(preset.config_cls, pop, "population.")
    preset.resolve(typed, has_init=has_init, task=task, learner=learner)
    return preset, typed


WANDB_ENV_MODES = ("online", "offline", "shared", "disabled", "dryrun", "run")  # what wandb reads from WANDB_MODE
WANDB_PROJECT_CHARS = "/\\#?%:"  # characters W&B refuses in a project name (at most 128 characters)


def check_wandb(w) -> None:
    """Refuse what ``wandb.init`` would refuse with a traceback after the run started: a project name
    W&B does not accept, a ``WANDB_MODE`` it does not know, online mode without an API key."""
    bad = sorted(set(WANDB_PROJECT_CHARS) & set(w.project))
    if bad or len(w.project) > 128:
        raise ConfigError(f"bad value for 'wandb.project': {w.project!r} (W&B takes at most 128 characters and none of "
                          f"{' '.join(WANDB_PROJECT_CHARS)}; the entity is set with WANDB_ENTITY)")
    env_mode = os.environ.get("WANDB_MODE")
    if env_mode is not None and env_mode not in WANDB_ENV_MODES:
        raise ConfigError(f"the environment's WANDB_MODE={env_mode!r} is not a W&B mode ({', '.join(WANDB_ENV_MODES)}); "
                          "unset it or use wandb.mode=")
    if w.mode == "online" and env_mode in (None, "online", "run") and not _wandb_key():
        raise ConfigError("wandb.mode=online needs a W&B API key: set WANDB_API_KEY or run `wandb login` "
                          "(or log offline with wandb.mode=offline and `wandb sync` later)")


def _wandb_key() -> bool:
    """Whether W&B has credentials here: WANDB_API_KEY, an identity token file, or ``wandb login``'s netrc entry."""
    import netrc
    from urllib.parse import urlparse

    if os.environ.get("WANDB_API_KEY") or os.environ.get("WANDB_IDENTITY_TOKEN_FILE"):
        return True
    host = urlparse(os.environ.get("WANDB_BASE_URL") or "https://api.wandb.ai").hostname or "api.wandb.ai"
    try:
        return netrc.netrc(os.environ.get("NETRC")).authenticators(host) is not None
    except (OSError, netrc.NetrcParseError):
        return False


OPPONENT_LEARNERS = ("mappo", "bc")  # learners that can play one team (MAPPO over one drone is PPO; bc clones the team's scripted player)


def _check_opponent(cfg, task_cls, algo_cls) -> None:
    """``opponent=``: a match and a learner that plays one team (whether the competitor it names
    exists and fits is ``volleybots.policies.check_references``'s: this opens no file)."""
    from volleybots.algos.base import class_attr

    if not class_attr(task_cls, "competitive"):
        raise ConfigError(f"opponent={cfg.opponent!r} is for matches (1v1, 3v3, 6v6), not task {task_cls.name!r}")
    if cfg.population is not None:
        raise ConfigError(f"population={cfg.population.name} chooses its own opponents; give it population.seed_members=[...] "
                          "instead of opponent=")
    if algo_cls.name not in OPPONENT_LEARNERS:
        raise ConfigError(f"algo {algo_cls.name!r} cannot learn one team against opponent=; allowed: {', '.join(OPPONENT_LEARNERS)}")


