"""Config schemas, composition and validation (the ``conf/`` YAML tree, checked against dataclasses).

The YAML tree lives in ``conf/`` (found by ``volleybots.paths.conf_dir()`` wherever the package is
installed). Hydra composes it (``compose``); ``validate`` then checks the result against dataclass
schemas so that a misspelt key or a value of the wrong type is rejected with one line naming the key:

* the fixed part (env, logging, checkpoints, ...) is ``schema.Config``;
* a task's keys are derived from its class's constructor signature (``schema.task_schema``), so a new
  task needs only its YAML file;
* an algorithm's keys are its own dataclass config (``volleybots.algos.ALGOS[name].config_cls``), a
  population method's loop keys (``population.*``) its preset's (``volleybots.algos.PRESETS[name].config_cls``).

Modules: ``schema`` (dataclasses, ranges), ``validate``, ``compose`` (Hydra, ``key=value`` values),
``spelling`` (the command line's population words: old spellings, a task's default method),
``envs`` (an env from a config), ``resources`` (memory checks, bench options), ``searchpath`` (a user's
own presets through ``hydra.searchpath`` / ``--config-dir``).
"""

from volleybots.config.compose import algo_action_space, apply_overrides, compose, load, parse_value
from volleybots.config.envs import build_env, make_env, task_kwargs
from volleybots.config.resources import BenchOptions, available_memory, check_bench_options, check_fits, check_memory
from volleybots.config.schema import (
    MAX_SEED,
    MAX_THREADS,
    Config,
    EnvConfig,
    check_env_args,
    check_range,
    check_values,
    group_options,
    task_schema,
    to_dict,
)
from volleybots.config.validate import OPPONENT_LEARNERS, validate
from volleybots.errors import ConfigError

__all__ = [
    "BenchOptions", "Config", "ConfigError", "EnvConfig", "MAX_SEED", "MAX_THREADS", "OPPONENT_LEARNERS", "algo_action_space",
    "apply_overrides", "available_memory", "build_env", "check_bench_options", "check_env_args", "check_fits", "check_memory",
    "check_range", "check_values", "compose", "group_options", "load", "make_env", "parse_value", "task_kwargs", "task_schema",
    "to_dict", "validate",
]
