"""``key=value`` arguments, read once (a leaf: it imports nothing).

Every verb takes Hydra overrides and options as ``key=value`` words; Hydra's ``+key=`` (add), ``++key=``
(add or set) and ``~key`` (delete) prefixes mark the same key. These are the few questions asked of such
words, so that each place asks them the same way."""

from __future__ import annotations

HYDRA_PREFIXES = "+~"


def split_arg(arg) -> tuple[str, str | None]:
    """``(key, value)`` of a ``key=value`` word as written (prefixes kept); value None when it has no ``=``."""
    key, eq, value = str(arg).partition("=")
    return key, (value if eq else None)


def override_key(arg) -> str:
    """The config key a word names, without Hydra's ``+``, ``++`` and ``~`` prefixes."""
    return split_arg(arg)[0].lstrip(HYDRA_PREFIXES)


def names_key(overrides, *keys: str) -> bool:
    """Whether any of ``overrides`` names one of ``keys`` (``total_frames=...``, ``+total_frames=...``, ``~total_frames``)."""
    return any(override_key(o) in keys for o in overrides)


def override_value(overrides, key: str, default=None):
    """The value the last override of ``key`` gives it as written (a string), else ``default``."""
    for o in reversed(list(overrides)):
        k, value = split_arg(o)
        if k.lstrip(HYDRA_PREFIXES) == key and value is not None:
            return value
    return default


def hydra_quote(value: str) -> str:
    """``value`` as one quoted string of Hydra's grammar: a path may hold ',', '=', spaces or letters
    that Hydra would read as a list, a second key or a syntax error."""
    return "'" + str(value).replace("\\", "\\\\").replace("'", "\\'") + "'"


__all__ = ["HYDRA_PREFIXES", "hydra_quote", "names_key", "override_key", "override_value", "split_arg"]
