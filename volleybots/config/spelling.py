"""The command line's population words, read once: old spellings to today's, and a task's default method.

A population method is the ``population=`` group (``conf/population/``); its learner is ``algo=``, composed
from the learner's own file. Three spellings of before keep working, rewritten here on the words
themselves, before Hydra sees them, so that a single run, ``--cfg`` and every job of a ``-m`` sweep
compose the same config:

* ``algo=psro_nash`` (any preset, the documented headline) is ``population=psro_nash`` with its default
  learner (``algo=mappo``, set by the population's file); no note, it is a spelling of its own;
* ``algo.learner=mat`` is ``algo=mat`` (with a one-line note): the only place the string is read;
* ``algo.iterations=3`` (any loop key) given with a population is ``population.iterations=3`` (a note).

A task with no ``algo=`` / ``population=`` trains its default method (``task_default``: ``sp`` on the
matches, MAPPO against an ``opponent=``). Words that set a population's keys (``train task=3v3
population.iterations=3``, ``algo.learner=``) take it here, before any key is checked, so that the
default population's keys are accepted; other words compose first and take it after
(``volleybots.config.compose``), so that a bad word is reported before the tasks (torch) load.
"""

from __future__ import annotations

from volleybots.config.schema import group_options
from volleybots.config.validate import OPPONENT_LEARNERS
from volleybots.errors import ConfigError
from volleybots.overrides import HYDRA_PREFIXES, names_key, override_key, override_value, split_arg

LEARNER_KEY = "algo.learner"  # the spelling of before of a population's learner (now algo=)


def loop_keys() -> set[str]:
    """The population loop's own keys (``population.*``), as ``algo.*`` spelt them before: those of the
    population files (which repeat ``LoopConfig``, tests/config/test_registries.py), read without loading
    an algorithm (torch), so that a bad word is still reported in a second."""
    from omegaconf import OmegaConf

    from volleybots.config.searchpath import option_file
    from volleybots.paths import conf_dir

    keys = set()
    for name in group_options("population"):  # a user's preset too (a --config-dir): its loop keys are accepted
        node = OmegaConf.load(option_file(conf_dir(), "population", name)).get("population") or {}
        keys |= set(node)
    return keys - {"name"}


def respell(overrides, population: bool | None = None) -> tuple[list[str], list[str]]:
    """``overrides`` in today's spelling, and the notes to print for old spellings (one line each).
    ``population``: whether the run is a population's (None: from the words and the task's default)."""
    words, notes = _preset_algo([str(o) for o in overrides]), []
    learner = override_value(words, LEARNER_KEY)
    if population is None:
        if learner is not None or _population_words(words):  # the task's default method decides what they mean
            words = [*words, *task_default(words, learner is not None)]
        population = names_key(words, "population") and override_value(words, "population") != "null"
    if learner is not None:
        plain = override_value(words, "algo")
        if plain is not None or not population:
            also = f"algo={plain} names it too" if plain is not None else "this run trains no population"
            raise ConfigError(f"{LEARNER_KEY}={learner} names a population's learner, now spelt algo={learner}, and {also}; "
                              f"give population=NAME algo={learner}")
        words = [w for w in words if override_key(w) != LEARNER_KEY] + [f"algo={learner}"]
        notes.append(f"{LEARNER_KEY}={learner} is read as algo={learner} (a population's learner is algo=; docs/usage.md)")
    if population:
        words, moved = _loop_words(words)
        if moved:
            new = ", ".join(f"population.{k.removeprefix('algo.')}" for k in moved)
            notes.append(f"{', '.join(moved)} read as {new} (the population loop's keys; docs/usage.md)")
    return words, notes


def _preset_algo(words: list[str]) -> list[str]:
    """``algo=PRESET`` (a sweep of presets too) as ``population=PRESET``; a sweep that mixes learners and
    presets is one line."""
    out = []
    for w in words:
        key, value = split_arg(w)
        if override_key(w) != "algo" or value is None:
            out.append(w)
            continue
        values = [v.strip() for v in value.split(",")]
        presets = [v for v in values if v in group_options("population")]  # the files: no algorithm (torch) loads
        if presets and len(presets) < len(values):
            raise ConfigError(f"algo={value} mixes learners and population methods; sweep population={','.join(presets)} "
                              f"and algo=LEARNER apart")
        out.append(f"{key.replace('algo', 'population')}={value}" if presets else w)
    return out


def _loop_words(words: list[str]) -> tuple[list[str], list[str]]:
    """``algo.KEY=...`` of a population loop key as ``population.KEY=...`` (prefixes kept); the words moved."""
    keys, out, moved = loop_keys(), [], []
    for w in words:
        key = override_key(w)
        if key.startswith("algo.") and key.removeprefix("algo.") in keys:
            prefix = w[: len(w) - len(w.lstrip(HYDRA_PREFIXES))]  # Hydra's +, ++ or ~, kept
            moved.append(key)
            w = f"{prefix}population.{w[len(prefix) + len('algo.'):]}"
        out.append(w)
    return out, moved


def _population_words(words: list[str]) -> bool:
    """Whether the words set a population's keys (``population.*``, or a loop key under ``algo``)."""
    keys = {override_key(w) for w in words}
    return any(k.startswith("population.") for k in keys) or bool({f"algo.{k}" for k in loop_keys()} & keys)


def task_default(words: list[str], for_learner: bool = False) -> list[str]:
    """The group override of the method the task trains with when the words name none: its
    ``default_algo`` (a population preset on the matches), MAPPO against an ``opponent=``; ``for_learner``:
    ``algo.learner=`` is given, which names a population's learner (the task's default population).
    A swept task is left to each job (``volleybots.config.compose.pin_default_algo``). It loads the tasks
    (torch): ``respell`` asks it only for words that need it, ``compose`` once the words composed."""
    from volleybots.algos.base import class_attr
    from volleybots.tasks import TASKS

    if names_key(words, "population") or (names_key(words, "algo") and not for_learner):
        return []
    task = override_value(words, "task")
    if task is None:
        task = _config_default("task")
    if "," in str(task) or task not in TASKS:
        return []  # a sweep, or a name that composition reports
    opponent = override_value(words, "opponent")
    default = OPPONENT_LEARNERS[0] if opponent not in (None, "null") else class_attr(TASKS[task], "default_algo")
    if default in group_options("population"):
        return [f"population={default}"]
    return [] if for_learner or default == _config_default("algo") else [f"algo={default}"]


def _config_default(group: str) -> str:
    """The option ``conf/config.yaml``'s defaults list gives ``group``."""
    import yaml

    from volleybots.paths import conf_dir

    for entry in yaml.safe_load((conf_dir() / "config.yaml").read_text())["defaults"]:
        if isinstance(entry, dict) and group in entry:
            return entry[group]
    raise KeyError(group)


__all__ = ["LEARNER_KEY", "loop_keys", "respell", "task_default"]
