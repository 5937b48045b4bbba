"""Command-line arguments of the verbs: ``key=value`` options, config overrides and positional names.

One grammar for every verb (``eval crossplay``, ``elo``, ``exploitability``, ``replay A B``, ``bench``):
an argument whose key is one of the verb's options is that option, typed by ``parse_value`` (as Hydra
reads values) and checked against its type; ``task=``, ``task.KEY=``, ``env.KEY=`` and ``threads=`` are
config overrides; anything else names what plays (``name=PATH`` included).
"""

from __future__ import annotations

from volleybots.config.compose import parse_value
from volleybots.errors import ConfigError, Range
from volleybots.overrides import split_arg

# The ranges of the verbs' count options, checked as they are read (memory is checked later, against
# the match: ``volleybots.config.resources.check_play``). A seed leaves room for the offsets the verbs
# add per pair, side and game, so that no generator is seeded past int64.
OPTION_SEED_MAX = 2**62
OPTION_RANGES = {
    "seed": Range(0, OPTION_SEED_MAX),
    "rounds": Range(low=1),
    "batch": Range(low=1),
    "episodes": Range(low=1),
    "budget": Range(low=0),  # exploitability's budget=0: no trained BR, fixed responses only (checked there)
    "num_envs": Range(low=1),
}
OVERRIDE_KEYS = ("task", "threads")  # and every task.KEY / env.KEY
OVERRIDE_PREFIXES = ("task.", "env.")


def typed_option(key: str, value: str, kind: type):
    """``value`` of option ``key`` read as ``kind``: an int is a float where a float is asked, and an
    integral float an int where an int is (``budget=4e6``, as ``total_frames=2e6`` reads in a config)."""
    # a text option (a path: reuse=, from=) is taken as written, unless quoted: Hydra's grammar would refuse
    # the ',', '=' and non-ASCII letters that folder names may hold (run dirs with them already work)
    v = value if kind is str and value[:1] not in ("'", '"') else parse_value(value)
    if kind is float and isinstance(v, int) and not isinstance(v, bool):
        v = float(v)
    if kind is int and isinstance(v, float) and v.is_integer():
        v = int(v)
    if not isinstance(v, kind) or (kind is int and isinstance(v, bool)):
        what = "an integer" if kind is int else "true or false" if kind is bool else "a " + kind.__name__
        raise ConfigError(f"{key}={value!r} must be {what}")
    rng = OPTION_RANGES.get(key)
    if rng is not None and kind in (int, float) and v not in rng:
        raise ConfigError(f"{key}={value} is out of range: it must be {'an integer' if kind is int else 'a number'} {rng}")
    return v


def split_args(args, options: dict, override_keys=OVERRIDE_KEYS) -> tuple[list[str], dict, list[str]]:
    """A command line's names of what plays, its ``options`` (typed: key -> type) and its config
    overrides (``override_keys``, ``task.KEY=`` and ``env.KEY=``). Anything that is neither option nor
    override is a name, ``name=PATH`` included."""
    specs, opts, overrides = [], {}, []
    for arg in args:
        key, value = split_arg(arg)
        if value is not None and key in options:
            opts[key] = typed_option(key, value, options[key])
        elif value is not None and (key in override_keys or key.startswith(OVERRIDE_PREFIXES)):
            overrides.append(arg)
        else:
            specs.append(arg)
    return specs, opts, overrides


def parse_options(args, allowed, what: str, aliases: dict | None = None) -> dict:
    """Only ``key=value`` options (``bench``): each key one of ``allowed`` or of ``aliases`` (another
    name of an allowed key: ``task`` for ``tasks``, as every other verb spells it), values as Hydra reads them."""
    aliases = aliases or {}
    out, spelled = {}, {}
    for o in args:
        key, value = split_arg(o)
        if value is None or (key not in allowed and key not in aliases):
            raise ConfigError(f"unknown {what} option {key!r}; allowed: {', '.join([*allowed, *aliases])}")
        name = aliases.get(key, key)
        if name in out:
            both = f" (as {spelled[name]}= and {key}=)" if spelled[name] != key else ""
            raise ConfigError(f"{what} option {name!r} is given twice{both}; give it once")
        out[name], spelled[name] = parse_value(value), key
    return out


__all__ = ["OVERRIDE_KEYS", "OPTION_RANGES", "OPTION_SEED_MAX", "parse_options", "split_args", "typed_option"]
