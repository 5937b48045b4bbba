"""Command-line arguments of the verbs: ``key=value`` options, config overrides and positional names.

One grammar for every verb (``eval crossplay``, ``elo``, ``exploitability``, ``replay A B``, ``bench``)
and for the scripts of ``benchmarks/``: a verb's options are one dataclass (``volleybots.config.verbs``)
whose fields carry their help and allowed values (``option``); an argument whose key is one of its
fields is that option, typed by ``parse_value`` (as Hydra reads values) and checked against the field's
type, range and choices; ``task=``, ``task.KEY=``, ``env.KEY=`` and ``threads=`` are config overrides;
anything else names what plays (``name=PATH`` included). The help a verb prints is ``describe``d from
the same fields, so the list a user reads is the list the parser takes (CleanRL's ``Args`` is the model).
"""

from __future__ import annotations

import dataclasses
import typing
from pathlib import Path

from volleybots.config.compose import parse_value
from volleybots.errors import ConfigError, Range
from volleybots.overrides import split_arg

OVERRIDE_KEYS = ("task", "threads")  # and every task.KEY / env.KEY
OVERRIDE_PREFIXES = ("task.", "env.")


def option(default=None, help: str = "", *, ge=None, gt=None, le=None, lt=None, choices=(), key: str | None = None,
           factory=dataclasses.MISSING, positional: bool | str = False):
    """A verb option: a dataclass field with its ``help``, its range (``ge``/``gt``/``le``/``lt``, as
    ``volleybots.errors.ranged``: ``check_values`` reads it too), its allowed ``choices`` and the ``key``
    it is spelt with where that is no Python name (``from=``). ``factory`` for a list default;
    ``positional``: a script's bare words fill it (``table3.py A B C``; ``parse``), ``"+"``: at least one."""
    bounds = (ge, gt, le, lt)
    rng = None if all(b is None for b in bounds) else Range(
        low=gt if gt is not None else ge, high=lt if lt is not None else le, low_open=gt is not None, high_open=lt is not None)
    meta = {"help": help, "range": rng, "choices": tuple(choices), "key": key, "positional": positional}
    if factory is not dataclasses.MISSING:
        return dataclasses.field(default_factory=factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


@dataclasses.dataclass
class VerbOptions:
    """The base of a verb's options. ``given`` (no field) names the keys the command line set: a few
    checks depend on it (``eval elo from=FILE`` refuses ``batch=``, which would play games it does not)."""

    def __post_init__(self):
        self.given = frozenset()


def _kind(hint) -> tuple[type, bool]:
    """(the type one value is read as, whether the option takes several) of a field's type hint:
    ``int``, ``Optional[str]``, ``list[str]`` (``response=A response=B``, ``tasks=[hover,1v1]``)."""
    args = [a for a in typing.get_args(hint) if a is not type(None)]
    if typing.get_origin(hint) is not list and len(args) == 1 and type(None) in typing.get_args(hint):
        hint = args[0]  # Optional[X] is X
    if typing.get_origin(hint) is list:
        return typing.get_args(hint)[0], True
    return hint, False


def fields_of(options: type) -> dict[str, tuple[dataclasses.Field, type, bool]]:
    """key -> (field, one value's type, repeats) of a verb's options dataclass, keys as spelt."""
    hints = typing.get_type_hints(options)
    return {f.metadata.get("key") or f.name: (f, *_kind(hints[f.name])) for f in dataclasses.fields(options)}


def typed_option(key: str, value: str, kind: type, rng: Range | None = None, choices=(), help: str = ""):
    """``value`` of option ``key`` read as ``kind``: an int is a float where a float is asked, and an
    integral float an int where an int is (``budget=4e6``, as ``total_frames=2e6`` reads in a config);
    then checked against ``rng`` and ``choices``. A bad one raises one line naming it and what is allowed."""
    # a text option (a path: reuse=, from=) is taken as written, unless quoted: Hydra's grammar would refuse
    # the ',', '=' and non-ASCII letters that folder names may hold (run dirs with them already work)
    v = value if kind in (str, Path) and value[:1] not in ("'", '"') else parse_value(value)
    if kind is typing.Any:  # (bench's compile=: a bool or a list of them, its schema checks which)
        return v
    if kind is Path and isinstance(v, str):
        v = Path(v)
    if kind is float and isinstance(v, int) and not isinstance(v, bool):
        v = float(v)
    if kind is int and isinstance(v, float) and v.is_integer():
        v = int(v)
    if not isinstance(v, kind) or (kind is int and isinstance(v, bool)):
        what = {int: "an integer", bool: "true or false", Path: "a path"}.get(kind, "a " + kind.__name__)
        raise ConfigError(f"{key}={value!r} must be {what}")
    why = f" ({help})" if help else ""
    if rng is not None and kind in (int, float) and v not in rng:
        raise ConfigError(f"{key}={v} is out of range: it must be {_what(kind)} {rng}{why}")
    if choices and v not in choices:
        raise ConfigError(f"unknown {key} {v!r}; allowed: {', '.join(map(str, choices))}{why}")
    return v


def _what(kind: type) -> str:
    # "finite": a float range refuses nan and inf too (``Range.__contains__``)
    return "an integer" if kind is int else "a finite number"


def _items(text: str) -> list[str]:
    """The items of a list's text ``a,b=[1,2],c``: split at the commas outside brackets, so that an
    override item keeps its own list (``train_overrides=[algo.hidden=[64,64],algo.epochs=2]``)."""
    items, depth, start = [], 0, 0
    for i, ch in enumerate(text + ","):
        depth += {"[": 1, "]": -1}.get(ch, 0)
        if ch == "," and depth == 0:
            items.append(text[start:i].strip())
            start = i + 1
    return [t for t in items if t]


def fill(options: type, pairs, names=()) -> VerbOptions:
    """The ``options`` dataclass filled from ``(key, text)`` pairs, each read by ``typed_option``; a
    list field takes a repeated key (``response=A response=B``) or a list (``tasks=[hover,1v1]``), any
    other field the last value given. ``names``: the bare words, for the field marked ``positional``."""
    known = fields_of(options)
    values = {}
    for key, text in pairs:
        f, kind, repeats = known[key]
        m = f.metadata
        read = _items(text[1:-1]) if repeats and text[:1] == "[" and text[-1:] == "]" else [text]
        for t in read:
            v = typed_option(key, t, kind, m.get("range"), m.get("choices", ()), m.get("help", ""))
            if repeats:
                values.setdefault(f.name, []).append(v)
            else:
                values[f.name] = v
    given = frozenset(k for k, (f, *_) in known.items() if f.name in values)
    names = list(names)
    for f, kind, repeats in known.values():  # in order: a single one takes one word, a list the rest
        if not f.metadata.get("positional"):
            continue
        if repeats:
            if not names and f.metadata["positional"] == "+":
                raise ConfigError(f"name at least one of the {f.name} ({f.metadata.get('help') or 'bare words'})")
            values[f.name], names = [kind(n) for n in names], []
        elif names:
            values[f.name] = kind(names.pop(0))
        elif f.default is None:
            raise ConfigError(f"name the {f.name} ({f.metadata.get('help') or 'a bare word'}) before the key=value options")
    if names:
        raise ConfigError(f"{names[0]!r} is neither a key=value option nor a name this takes")
    out = options(**values)
    out.given = given
    return out


def parse(options: type, args, what: str) -> VerbOptions:
    """Only ``key=value`` options (a script of ``benchmarks/``): each key one of the fields of ``options``,
    and bare words only where a field is ``positional`` (``table3.py A B C``); anything else is refused
    in one line naming it and the keys allowed."""
    known = fields_of(options)
    takes_names = any(f.metadata.get("positional") for f, *_ in known.values())
    pairs, names = [], []
    for arg in args:
        key, value = split_arg(arg)
        if arg.startswith("--"):  # the argparse spelling these scripts had
            key = arg[2:].partition("=")[0].replace("-", "_")
            raise ConfigError(f"unknown {what} option {arg!r}: options are key=value ({key}=...); allowed: "
                              f"{', '.join(f'{k}=' for k in known)}")
        if value is not None and key in known:
            pairs.append((key, value))
        elif takes_names:
            names.append(arg)
        else:
            raise ConfigError(f"unknown {what} option {arg!r}; allowed: {', '.join(f'{k}=' for k in known)}")
    return fill(options, pairs, names)


def script_options(options: type, argv=None, doc: str | None = None) -> VerbOptions:
    """A script's options (``benchmarks/``) from its command line, ``key=value`` as the verbs take them:
    ``help`` prints ``doc`` and every option; a bad one prints one line and exits with code 2."""
    import sys

    argv = sys.argv[1:] if argv is None else list(argv)
    what = Path(sys.argv[0]).name
    if any(a in ("help", "-h", "--help") for a in argv):
        print(f"{(doc or '').strip()}\n\nusage: {what} [key=value ...]\n{help_epilog(options)}")
        raise SystemExit(0)
    try:
        return parse(options, argv, what)
    except ConfigError as e:
        print(f"error: {e}", file=sys.stderr)
        raise SystemExit(2) from None


def parse_options(args, allowed, what: str, aliases: dict | None = None) -> dict:
    """Only ``key=value`` options, values as Hydra reads them (``bench``, whose lists ``tasks=[a,b]`` its
    ``BenchOptions`` schema then types and ranges): each key one of ``allowed`` or of ``aliases`` (another
    name of an allowed key: ``task`` for ``tasks``, as every other verb spells it)."""
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


def split_args(args, options: type | None = None, override_keys=OVERRIDE_KEYS) -> tuple[list[str], VerbOptions | None, list[str]]:
    """A command line's names of what plays, its ``options`` (a ``VerbOptions`` dataclass, filled;
    ``None``: the verb has none) and its config overrides (``override_keys``, ``task.KEY=`` and
    ``env.KEY=``). Anything that is neither option nor override is a name, ``name=PATH`` included."""
    known = fields_of(options) if options is not None else {}
    specs, pairs, overrides = [], [], []
    for arg in args:
        key, value = split_arg(arg)
        if value is not None and key in known:
            pairs.append((key, value))
        elif value is not None and (key in override_keys or key.startswith(OVERRIDE_PREFIXES)):
            overrides.append(arg)
        else:
            specs.append(arg)
    return specs, fill(options, pairs) if options is not None else None, overrides


def allowed(f: dataclasses.Field, kind) -> str:
    """What a field takes, in words: its choices, type and range."""
    m = f.metadata
    if m.get("choices"):
        return "|".join(map(str, m["choices"]))
    if typing.get_origin(kind) is list:  # bench's lists: tasks=[solo_bump,3v3], or one value
        return f"one or a list [a,b] of: {allowed(f, typing.get_args(kind)[0])}"
    if kind is bool:
        return "true or false"
    if kind in (int, float):
        rng = m.get("range")
        return f"{_what(kind)} {rng}" if rng is not None else _what(kind)
    return {str: "text", Path: "a path"}.get(kind, "true, false or a list of them")


def _shown(value) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, list):
        return "[" + ",".join(map(_shown, value)) + "]"
    return "unset" if value is None else str(value)


def describe(options: type) -> list[str]:
    """One line per option of ``options``: ``key=DEFAULT (what it takes): help``, as the verb's help shows them."""
    lines = []
    for key, (f, kind, repeats) in fields_of(options).items():
        default = f.default_factory() if f.default is dataclasses.MISSING else f.default
        again = ", or a list [a,b]" if repeats else ""
        spelt = f"{f.name.upper()}{' ...' if repeats else ''}" if f.metadata.get("positional") else f"{key}={_shown(default)}"
        lines.append(f"{spelt} ({allowed(f, kind)}{again}): {f.metadata.get('help', '')}")
    return lines


def help_epilog(options: type, title: str = "key=value options") -> str:
    """The block a verb's ``--help`` ends with: every option of ``options`` with its default, help and range."""
    # (a blank line before the list: the site renders the help as Markdown, where a list must start a block)
    return "\n".join([f"{title}:", "", *("- " + line for line in describe(options))])


__all__ = ["OVERRIDE_KEYS", "VerbOptions", "describe", "fields_of", "fill", "help_epilog", "option", "parse", "parse_options",
           "script_options", "split_args",
           "typed_option"]
