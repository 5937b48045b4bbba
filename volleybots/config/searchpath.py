"""A user's own presets through Hydra's config search path: ``hydra.searchpath=[file://DIR]`` (and
``volleybots train --config-dir DIR``, read as the same) adds the folders whose ``algo/``, ``task/``,
``env/`` and ``population/`` files compose as options of those groups beside the packaged ``conf/``.

Hydra itself finds them at composition; this module tells the checks made before it (a group option
checked against ``conf/`` alone, in a second, before torch loads: ``compose.check_group_args``) where
else to look. The folders are read from the words themselves (``active`` while a verb checks and
composes them), so a Python caller's ``compose([...,"hydra.searchpath=[file://DIR]"])`` and the CLI's
``--config-dir`` take the same route. As in Hydra, the packaged ``conf/`` comes first: a user file of
a packaged option's name does not replace it (name yours ``algo/myppo.yaml``, with ``defaults: [ppo]``
to start from the packaged PPO).
"""

from __future__ import annotations

import contextlib
from pathlib import Path

from volleybots.errors import ConfigError
from volleybots.overrides import override_key, override_value, split_arg

SEARCHPATH = "hydra.searchpath"
_active: tuple[Path, ...] = ()  # the user's folders of the words being checked (``active``)


def _folder(entry: str) -> Path | None:
    """The folder of one search-path entry: ``file://DIR`` or a plain path (relative to the working
    directory, as Hydra reads it); ``pkg://a.b`` an installed package's folder. None: nothing to list."""
    if entry.startswith("pkg://"):
        from importlib.resources import files

        try:
            return Path(str(files(entry.removeprefix("pkg://").replace("/", "."))))
        except (ModuleNotFoundError, TypeError):
            return None  # Hydra warns that it is not available; a group option from it is then unknown
    return Path(entry.removeprefix("file://")).expanduser()


def _entries(words) -> list[str]:
    """The entries of the last ``hydra.searchpath=[...]`` among ``words`` (as Hydra takes the last)."""
    value = override_value([str(w) for w in words], SEARCHPATH)
    if value is None or value == "null":
        return []
    from hydra.core.override_parser.overrides_parser import OverridesParser  # Hydra's reading of the value (not compose's: a cycle)
    from hydra.errors import HydraException

    try:
        entries = OverridesParser.create().parse_override(f"k={value}").value()
    except HydraException:
        raise ConfigError(f"bad {SEARCHPATH} value {value!r}: expected a list of folders, e.g. [file:///home/me/conf]") from None
    if isinstance(entries, str):  # hydra.searchpath=file://DIR: Hydra wants a list; one entry is meant
        entries = [entries]
    if not isinstance(entries, list) or not all(isinstance(e, str) for e in entries):
        raise ConfigError(f"{SEARCHPATH} must be a list of folders, e.g. {SEARCHPATH}=[file:///home/me/conf]; got {value!r}")
    return entries


def user_dirs(words) -> tuple[Path, ...]:
    """The user's config folders named by ``words``; a missing one is a ``ConfigError`` (a typo of it
    would otherwise surface as an unknown option, far from its cause)."""
    dirs = []
    for entry in _entries(words):
        folder = _folder(entry)
        if folder is None:
            continue
        if not folder.is_dir():
            raise ConfigError(f"config folder {str(folder)!r} ({SEARCHPATH} entry {entry!r}) is not a directory")
        dirs.append(folder.resolve())
    return tuple(dirs)


def with_config_dir(words: list[str], config_dir: str | None) -> list[str]:
    """``words`` with ``--config-dir DIR`` as the first entry of ``hydra.searchpath`` (where Hydra's own
    ``--config-dir`` puts it: before the entries of ``hydra.searchpath``, after the packaged ``conf/``)."""
    if config_dir is None:
        return list(words)
    folder = Path(config_dir).expanduser()
    if not folder.is_dir():
        raise ConfigError(f"--config-dir {config_dir!r} is not a directory")
    entries = [f"file://{folder.resolve()}", *_entries(words)]
    from volleybots.overrides import hydra_quote

    quoted = ",".join(hydra_quote(e) for e in entries)  # a path with ',' or spaces stays one entry
    return [w for w in words if override_key(str(w)) != SEARCHPATH] + [f"{SEARCHPATH}=[{quoted}]"]


@contextlib.contextmanager
def active(words):
    """While checking and composing ``words``: their folders beside ``conf/`` for ``group_options``."""
    global _active
    before, _active = _active, user_dirs(words) or _active  # nested checks of the same words keep the outer folders
    try:
        yield _active
    finally:
        _active = before


def active_dirs() -> tuple[Path, ...]:
    return _active


def option_file(conf: Path, group: str, name: str) -> Path:
    """The file of option ``name`` of ``group``: the packaged one first, then the user's folders."""
    for root in (conf, *_active):
        path = root / group / f"{name}.yaml"
        if path.is_file():
            return path
    return conf / group / f"{name}.yaml"


def is_searchpath(word: str) -> bool:
    key, value = split_arg(str(word))
    return value is not None and override_key(str(word)) == SEARCHPATH


__all__ = ["SEARCHPATH", "active", "active_dirs", "is_searchpath", "option_file", "user_dirs", "with_config_dir"]
