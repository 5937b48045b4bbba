"""A cross-play results file checked as a whole: its parts agree with each other.

``CrossPlay.load`` reads each key with its type and shape (``volleybots.files.Fields``); here the parts
are checked against each other, so that a hand-edited or damaged file is refused with one line rather
than rated or reused as if it were one cross-play: the counts of (j, i) mirror those of (i, j), each
pair's counts per side add up to its counts, and each pair's game content holds what the tables read.
"""

from __future__ import annotations

import math

PAIR_NUMBERS = ("rally_steps", "rally_touches")  # the content's means a table shows (null: no game)
PAIR_COUNTS = ("games", "rally_touches_max", "games_3plus_touches")


def pair_of(key, n: int) -> tuple[int, int] | None:
    """``(i, j)`` of a pair key ``"i,j"`` with ``0 <= i < j < n``; None for anything else."""
    i, _, j = str(key).partition(",")
    if not (i.isdigit() and j.isdigit() and len(i) <= 6 and len(j) <= 6 and int(i) < int(j) < n):
        return None
    return int(i), int(j)


def check_consistent(f, n: int, wdl, side_wdl: dict, content: dict) -> None:
    """Fail ``f`` (a ``Fields`` of the file) unless its parts agree (module docstring)."""
    f.mirrored("wdl", wdl)
    for key, sides in side_wdl.items():
        pair = pair_of(key, n)
        if pair is None:
            f.fail(f"side_wdl[{key!r}] is not a pair 'i,j' of competitors")
        total = [int(a + b) for a, b in zip(*sides)]
        if total != [int(x) for x in wdl[pair[0]][pair[1]]]:
            f.fail(f"side_wdl[{key!r}] adds up to {'/'.join(map(str, total))}, wdl says "
                   f"{'/'.join(str(int(x)) for x in wdl[pair[0]][pair[1]])}")
    for key, c in content.items():
        pair = pair_of(key, n)
        problem = "is not a pair 'i,j' of competitors" if pair is None else content_problem(c)
        if problem:
            f.fail(f"content[{key!r}] {problem}")


def _count(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and v >= 0


def _number(v) -> bool:
    return v is None or (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v))


def content_problem(c) -> str:
    """What is wrong with one pair's game content (``play.games.Games.content()``); "" when nothing."""
    if not isinstance(c, dict):
        return f"is {type(c).__name__}, not a mapping"
    for k in PAIR_COUNTS:
        if not _count(c.get(k)):
            return f"{k!r} is {c.get(k)!r}, not a count"
    for k in PAIR_NUMBERS:
        if not _number(c.get(k)):
            return f"{k!r} is {c.get(k)!r}, not a number"
    t = c.get("touches")
    if not (isinstance(t, list) and len(t) == 2 and all(_number(x) for x in t)):
        return f"'touches' is {t!r}, not two numbers"
    for k in ("serve_wdl", "receive_wdl"):
        v = c.get(k)
        if not (isinstance(v, list) and len(v) == 3 and all(_count(x) for x in v)):
            return f"{k!r} is {v!r}, not three counts"
    faults = c.get("faults")
    if not (isinstance(faults, dict) and set(faults) == {"A", "B"}
            and all(isinstance(d, dict) and all(isinstance(k, str) and _count(x) for k, x in d.items()) for d in faults.values())):
        return "'faults' is not {A: {fault: count}, B: {fault: count}}"
    if sum(c["serve_wdl"]) + sum(c["receive_wdl"]) != c["games"]:
        return f"serves and receives add up to {sum(c['serve_wdl']) + sum(c['receive_wdl'])} games, not {c['games']}"
    return ""


__all__ = ["check_consistent", "content_problem", "pair_of"]
