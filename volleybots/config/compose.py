"""Composition: Hydra overrides to a config, and ``key=value`` values read the way Hydra reads them.

``load`` composes and validates once; every verb that takes overrides goes through it (or through
``apply_overrides`` for a saved run's config), so a misspelt key or a bad group option is reported the
same way everywhere.
"""

from __future__ import annotations

import dataclasses

from omegaconf import DictConfig, OmegaConf

from volleybots.config import searchpath
from volleybots.config.schema import GROUPS, group_options, to_dict
from volleybots.config.spelling import respell, task_default
from volleybots.config.validate import validate
from volleybots.errors import ConfigError
from volleybots.overrides import names_key, override_key, split_arg
from volleybots.paths import conf_dir


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
                check_group_value(key, v)


def check_group_value(group: str, value) -> None:
    """``value`` must be an option of config group ``group`` (a file of ``conf/<group>/``); ``population=null``
    is none, and ``algo=`` may name a population method (read as ``population=``: ``config.spelling``)."""
    if (group == "population" and value is None) or (group == "algo" and str(value) in group_options("population")):
        return
    if str(value) not in group_options(group):
        raise ConfigError(f"unknown {group} {value!r}; allowed: {', '.join(group_options(group))}")


def check_group_args(args) -> None:
    """The group choices (``task=``, ``algo=``, ``env=``) among a verb's words checked against ``conf/``
    alone (and a user's config folders, ``hydra.searchpath``): a verb calls this first, so a mistyped
    task is reported before torch and the policies load."""
    with searchpath.active(args):
        for arg in args:
            key, value = split_arg(str(arg))
            if value is not None and key in GROUPS:
                check_group_value(key, value)


def check_fixed_values(args) -> None:
    """The numbers that ``key=value`` words give the run's fixed keys (``schema.Config``: ``env.num_envs``,
    ``seed``, ``total_frames``, ``evaluation.*``, ...) against their ranges. ``validate`` checks them too, but
    only once the task and algorithm registries have loaded torch (8 s and more); from the words alone a bad
    value is one line at once. A value of another type, a sweep, a task's or an algorithm's key is left to ``validate``.
    For the words of a run's config only (``train``, ``eval TARGET``): the match verbs' own ``seed=`` has another range."""
    import typing

    from volleybots.config.schema import Config, Range, check_magnitude, check_range, field_range

    for arg in args:
        key, value = split_arg(str(arg))
        if value is None or key.startswith(("+", "~")):
            continue
        found = _fixed_field(Config, key)
        kind = typing.get_type_hints(found[0]).get(found[1]) if found else None
        if kind not in (int, float):
            continue
        schema, name = found
        try:
            v = parse_value(value)
        except ConfigError:
            continue  # Hydra's grammar reports it
        if isinstance(v, bool) or not isinstance(v, (int, float)) or (kind is int and not isinstance(v, int)):
            continue
        rng = field_range(schema, name)
        check_range(key, v, rng or (Range() if isinstance(v, float) else None))
        check_magnitude(key, v, rng)


def _fixed_field(schema, key: str):
    """(dataclass, field name) of the dotted ``key`` under ``schema`` (``env.num_envs``: ``EnvConfig``,
    ``num_envs``); None where a part is no field or no section (``task.*`` and ``algo.*`` are typed ``Any``)."""
    import typing

    *sections, name = key.split(".")
    for part in sections:
        sub = typing.get_type_hints(schema).get(part)
        if not dataclasses.is_dataclass(sub):
            return None
        schema = sub
    return (schema, name) if name in typing.get_type_hints(schema) else None


def compose(overrides: list[str] | tuple[str, ...] = (), hydra_node: bool = False) -> DictConfig:
    """Compose ``conf/config.yaml`` with Hydra overrides (no sweeps), in today's spelling and with the
    task's default method where none is named (``volleybots.config.spelling``). Raises ``ConfigError``.

    A misspelt key is reported with the keys allowed beside it."""
    with searchpath.active(overrides):  # a user's presets (hydra.searchpath) are options of their groups
        return _compose(list(overrides), hydra_node)


def _compose(overrides: list[str], hydra_node: bool) -> DictConfig:
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir
    from hydra.errors import HydraException

    overrides = respell(overrides)[0]
    _check_overrides(overrides)
    check_fixed_values(overrides)  # before the registries (and torch) load
    with initialize_config_dir(config_dir=str(conf_dir()), version_base="1.3"):
        try:
            cfg = hydra_compose("config", overrides=overrides, return_hydra_config=hydra_node)
            # then the task's default method where none is named (a bad word is reported above, before torch loads)
            # by the composed task's registered name: a user's preset (task=my1v1, defaults: [1v1]) trains as its task does
            default = [] if names_key(overrides, "algo", "population") else task_default([*overrides, f"task={cfg.task.name}"])
            if default:
                overrides = respell([*overrides, *default], population=names_key(default, "population"))[0]
                cfg = hydra_compose("config", overrides=overrides, return_hydra_config=hydra_node)
            return population_budget(algo_action_space(cfg, overrides), overrides)
        except HydraException as e:
            _explain_unknown_key(overrides, hydra_compose)
            raise ConfigError(f"bad override: {_one_line(e)}") from None


def _explain_unknown_key(overrides: list[str], hydra_compose) -> None:
    """After a failed composition: raise a ConfigError naming an override's key that does not exist,
    with the keys allowed beside it (Hydra's own message lists none)."""
    from hydra.errors import HydraException

    try:
        # the groups and the search path that finds a user's presets: the keys a user preset declares are known
        base = hydra_compose("config", overrides=[o for o in overrides if override_key(o) in GROUPS or searchpath.is_searchpath(o)])
    except HydraException:
        return
    for o in overrides:
        key, value = split_arg(o)
        if value is None or key.startswith(("+", "~", "hydra.")) or key in GROUPS:
            continue
        if OmegaConf.select(base, key, default=_ABSENT) is _ABSENT:
            parent = key.rpartition(".")[0]
            node = OmegaConf.select(base, parent) if parent else base
            allowed = ", ".join(str(k) for k in node.keys()) if isinstance(node, DictConfig) else "(none: not a section)"
            raise ConfigError(f"unknown config key {key!r}; allowed{' under ' + repr(parent) if parent else ''}: {allowed}")


_ABSENT = object()


def pin_default_algo(cfgs, overrides) -> list[str]:
    """The overrides (in today's spelling) with the default method the composed ``cfgs`` took pinned (each
    task's own, ``respell``: ``population=sp`` on a match) for a launcher that composes again; unchanged
    when the command line names one; swept tasks of different defaults are one ``ConfigError`` line."""
    from volleybots.algos import method_name

    if names_key(overrides, "algo", "population"):
        return overrides
    methods = sorted({method_name(c) for c in cfgs})
    if len(methods) > 1:
        raise ConfigError(f"the swept tasks train with different default methods ({', '.join(methods)}); name one with "
                          "algo=NAME or population=NAME")
    pin = f"population={methods[0]}" if cfgs[0].population is not None else f"algo={methods[0]}"
    return respell([*overrides, pin], population=cfgs[0].population is not None)[0]


def algo_action_space(cfg: DictConfig, overrides) -> DictConfig:
    """An algorithm that cannot act in the default action space (``dqn``: discrete only) gets its own
    first one, unless the command line names ``env.action_space`` (then ``validate`` rejects a bad one)."""
    from volleybots.algos import ALGOS

    if names_key(overrides, "env.action_space"):
        return cfg
    algo_cls = ALGOS.get(OmegaConf.select(cfg, "algo.name", default=None))
    if algo_cls is not None and cfg.env.action_space not in algo_cls.action_spaces:
        cfg.env.action_space = algo_cls.action_spaces[0]
    return cfg


def population_budget(cfg: DictConfig, overrides) -> DictConfig:
    """A population run that the command line gives no ``total_frames`` gets the frames its iterations
    take at most (``iterations x max_updates`` batches), so that it trains every iteration it announces;
    the clone's ``bc_frames`` come on top. Self-play keeps ``total_frames``: its one learner is the budget."""
    from volleybots.algos import population_of

    if names_key(overrides, "total_frames"):
        return cfg
    m = population_of(cfg)
    if m is None or m.get("self_play"):
        return cfg
    try:
        cfg.total_frames = int(m.iterations) * int(m.max_updates) * int(cfg.env.num_envs) * int(cfg.algo.steps_per_batch)
    except (TypeError, ValueError):  # a bad value: validate names it
        pass
    return cfg


def _one_line(e: BaseException) -> str:
    """The innermost message of an exception chain, on one line."""
    while e.__cause__ is not None:
        e = e.__cause__
    return " ".join(str(e).split())


def load(overrides=()) -> DictConfig:
    """Compose and validate: the typed config for ``overrides``."""
    return validate(compose(overrides))


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
        key, value = split_arg(o)
        if value is None:
            raise ConfigError(f"bad override {o!r}: expected key=value")
        if not any(key == a or key.startswith(a + ".") for a in allowed):
            raise ConfigError(f"cannot change {key!r} of {what}; allowed: {', '.join(allowed)}")
        OmegaConf.update(data, key, parse_value(value), merge=True)
    return validate(to_dict(data))


