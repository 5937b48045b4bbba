"""The ``volleybots`` Typer app, its error handling (one line, exit 2) and the helpers every verb shares.

Bad input (an unknown name, key, verb or option, a wrong type or an out-of-range value, an algorithm
that cannot act in the chosen action space, a missing or mismatched checkpoint, an output file that
exists or cannot be written, a run directory in use) prints one line naming the bad value and the
allowed ones, exits with code 2 and writes nothing. docs/usage.md lists the guarantees.
"""

from __future__ import annotations

import errno
import functools
import sys

import typer
from typer.core import TyperGroup

try:  # typer >= 0.2x carries its own copy of click
    from typer._click import exceptions as click_errors
except ImportError:
    from click import exceptions as click_errors

from volleybots.errors import ConfigError
from volleybots.files import printable
from volleybots.version import __version__


class _Verbs(TyperGroup):
    """Click's own usage errors (a missing argument, an unknown verb or option, an option without its
    value) as one line and exit code 2, like every other bad input, not a boxed usage message."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        try:
            rv = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        except click_errors.ClickException as e:
            if not standalone_mode:
                raise
            if type(e).__name__ == "NoArgsIsHelpError":  # bare `volleybots`: the help, as Click does
                typer.echo(e.format_message())
            else:
                say(f"error: {_usage_message(self, e)}", err=True)
            sys.exit(2 if isinstance(e, click_errors.UsageError) else e.exit_code)
        except typer.Abort:
            if not standalone_mode:
                raise
            typer.echo("error: aborted", err=True)
            sys.exit(1)
        if standalone_mode:
            sys.exit(rv if isinstance(rv, int) else 0)
        return rv


def _usage_message(group, e) -> str:
    msg = " ".join(e.format_message().split()).rstrip(".")
    ctx = getattr(e, "ctx", None)
    where = ctx.command_path if ctx is not None else "volleybots"
    if msg.startswith("No such command"):
        msg += f"; allowed: {', '.join(group.commands)}"
    return f"{msg[:1].lower()}{msg[1:]} (see: {where} --help)"


app = typer.Typer(
    cls=_Verbs,
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Multi-drone volleyball: train, evaluate and replay policies on batched drone-physics tasks.",
)
_PASS_THROUGH = {"allow_extra_args": True, "ignore_unknown_options": True}


# a disk that is full, over quota, read-only or past its file size limit: the user's to fix, not a bug
DISK_ERRORS = (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EFBIG)


def say(text: str, err: bool = False) -> None:
    """Print ``text`` (on stderr with ``err``), each line with its control characters written out: what
    the verbs print holds names from command lines and received files, and an escape sequence in one
    would retitle or rewrite the user's terminal (click strips colour codes only, and only off a terminal)."""
    typer.echo("\n".join(printable(line) for line in str(text).split("\n")), err=err)


def _fail(msg: str) -> None:
    say(f"error: {msg}", err=True)
    raise typer.Exit(2)


def _user_errors(fn):
    """Turn ``ConfigError`` (bad user input) into one line and exit code 2."""

    @functools.wraps(fn)
    def wrapper(*args, **kw):
        try:
            return fn(*args, **kw)
        except ConfigError as e:
            _fail(str(e))
        except OSError as e:
            if e.errno not in DISK_ERRORS:
                raise
            _fail(f"cannot write {str(e.filename) + ' ' if e.filename else ''}({e.strerror or e}); free space or choose another "
                  "folder (the files already written are whole: writes are atomic)")

    return wrapper


def _version(value: bool) -> None:
    if value:
        typer.echo(f"volleybots {__version__}")
        raise typer.Exit()


@app.callback()
def main(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True, help="Print the version and exit."),
) -> None:
    """Multi-drone volleyball: train, evaluate and replay policies on batched drone-physics tasks."""



def _refuse_flags(args: list[str], allowed: str) -> None:
    """An option Click passed through (the verbs take Hydra overrides after them) is a misspelt one."""
    flags = [a for a in args if a.startswith("-")]
    if flags:
        raise ConfigError(f"unknown option {flags[0]!r}; allowed: {allowed}")


def options_help(options: type, title: str = "key=value options") -> str:
    """The end of a verb's ``--help``: its options dataclass described (``volleybots.config.args.help_epilog``),
    escaped for rich's markup, which would take ``[solo_bump]`` or ``[0, 10]`` for a style and drop it."""
    from volleybots.config.args import help_epilog

    text = help_epilog(options, title)
    try:
        from rich.markup import escape
    except ImportError:  # typer without rich prints the text as it is
        return text
    return escape(text)


WIDE = 400  # columns a table may take when stdout is a file or a pipe (rich would cut it to 80)


def console():
    """The console tables are printed on: the terminal's width on a terminal; elsewhere (a file, a
    pipe) as wide as the table needs, so that a saved table is not folded into unreadable cells."""
    from rich.console import Console

    return Console() if sys.stdout.isatty() else Console(width=WIDE)


def show(renderable, out=None) -> None:
    """Print a verb's tables (a rich ``Table``, or a ``Group`` of tables and lines) on ``out`` (default:
    ``console()``). A table wider than the terminal is printed as one record per row, each cell under
    its column's name, instead of folded by rich into cells of a few letters each (``zoo:1v1/fsp_…``,
    ``touch…``) that no one can read; off a terminal the console is wide and tables keep their shape."""
    from rich.console import Group
    from rich.table import Table

    out = out or console()
    parts = list(renderable.renderables) if isinstance(renderable, Group) else [renderable]
    for part in parts:
        # measured unbounded: measuring at the console's width would report the folded table's width
        fits = not isinstance(part, Table) or out.measure(part, options=out.options.update_width(10 * WIDE)).maximum <= out.width
        out.print(part if fits else records(part))


def records(table):
    """``table`` as records: its title, then per row the first cell as a heading and every other cell
    on a line of its own after its column's name (a header of several lines on one)."""
    from rich.console import Group
    from rich.padding import Padding
    from rich.table import Table
    from rich.text import Text

    heads = [" ".join(str(c.header).split()) for c in table.columns]
    rows = list(zip(*(list(c.cells) for c in table.columns)))
    parts = [Text(str(table.title), style="bold")] if table.title else []
    for row in rows:
        grid = Table.grid(padding=(0, 2))
        grid.add_column(style="dim")
        grid.add_column()
        for head, cell in zip(heads[1:], row[1:]):
            grid.add_row(head, cell)
        first = Text.assemble(heads[0] + " " if heads[0] else "", row[0] if isinstance(row[0], (str, Text)) else str(row[0]))
        first.stylize("bold")
        parts += [first, Padding(grid, (0, 0, 0, 2))]
    if table.caption:
        parts.append(Text(str(table.caption)))
    return Group(*parts)
