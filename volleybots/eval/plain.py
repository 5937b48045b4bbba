"""Text read from a results file (labels, task names, fault names) shown as plain text.

A results file may come from anyone (``from=``, ``reuse=``): its strings are never read as Rich markup
(``[bold]x`` stays ``[bold]x``, ``[/]`` cannot break a table) and never reach the terminal as control
characters (an escape sequence is shown as ``\\x1b]...``, so it cannot retitle or rewrite the terminal).
"""

from __future__ import annotations

from volleybots.files import printable as clean  # the one rule, shared with the CLI's every line


def plain(s):
    """``s`` as a Rich ``Text``: cleaned, and not parsed as markup where a table or a console shows it."""
    from rich.text import Text

    return Text(clean(s))


__all__ = ["clean", "plain"]
