"""Pairs of an earlier cross-play played again for free (``reuse=FILE``).

A pair's games depend only on its two competitors, in that order, and on the settings every pair
shares (task, physics, games, seed, batch, scenario, deterministic, the package's version and the
fingerprint of its game code, ``version.play_code``): the pair's index in the table seeds nothing.
So a cross-play that adds a competitor to an earlier one need not replay the pairs the earlier one
played: each such pair is copied from its results file (W/D/L, game-by-game outcomes, sides, serves,
content), and the table comes out as a fresh cross-play of all of them would. A competitor is
recognised by what plays, not by its label or path: its members' kinds and sha256 and its mixture. A
pair whose two competitors stand in the other order is played again (the games from the other side
are other games), so add new competitors at the end.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from volleybots.errors import ConfigError
from volleybots.files import Fields

# what every pair of a cross-play shares, as its results file names it
SETTINGS = ("task", "action_space", "games_per_pair", "seed", "batch", "scenario", "deterministic")
CONFIG_PARTS = ("task", "env")  # the match config's sections that change a game


def identity(provenance: dict) -> str:
    """What plays, as a key: the members without their paths (a moved file is the same player)."""
    members = [{k: v for k, v in m.items() if k != "path"} for m in provenance["members"]]
    return json.dumps({"members": members, "mixture": [round(float(x), 12) for x in provenance["mixture"]]}, sort_keys=True)


def verified(provenance: dict) -> bool:
    """Whether what plays is pinned down by its record (a file's hash, a built-in's name), so that its
    earlier games may stand for new ones; a user's callable or ``module:function`` is not."""
    from volleybots.policies.foreign import UNVERIFIED

    return not any(m.get("kind") in UNVERIFIED for m in provenance["members"])


@dataclass
class Reused:
    """A pair copied from an earlier results file, shaped as ``play.games.Games`` is for a progress line."""

    wdl: np.ndarray  # [2, 3] W/D/L from the row's side, the row on team 0 / on team 1
    outcomes: str
    served: int
    pair_content: dict
    source: str

    @property
    def total(self) -> np.ndarray:
        return self.wdl.sum(0)

    def content(self) -> dict:
        return self.pair_content


class Reuse:
    """An earlier cross-play whose pairs a new one copies; its settings must be the new one's."""

    def __init__(self, path, earlier, meta: dict):
        """``earlier``: the ``CrossPlay`` read from ``path``; ``meta``: the new cross-play's settings."""
        self.path, self.old = str(path), earlier
        old = earlier.meta
        f = Fields(old, f"reuse={self.path!r}")
        for key in SETTINGS:
            if old.get(key) != meta[key]:
                raise ConfigError(
                    f"reuse={self.path!r} was played with {key}={old.get(key)!r}, this cross-play with {key}={meta[key]!r}; "
                    "only pairs played with the same settings can be reused")
        config = f.need("config", dict)
        for part in CONFIG_PARTS:
            if config.get(part) != meta["config"][part]:
                raise ConfigError(f"reuse={self.path!r} was played with other {part}.* settings than this cross-play; "
                                  "only pairs played with the same settings can be reused")
        versions = f.need("versions", dict)
        for key, what in (("volleybots", "volleybots"), ("play_code", "the game code (volleybots.version.play_code)")):
            was, now = versions.get(key), meta["versions"][key]
            if was != now:
                raise ConfigError(f"reuse={self.path!r} was played by {what} {was or 'unrecorded'}, this is {now}; "
                                  "its games may differ, play them again")
        _check_pairs(f, earlier, meta["games_per_pair"])
        self.index = {}
        for k, prov in enumerate(f.need("competitors", list)):
            self.index.setdefault(identity(prov), k)

    def pair(self, a: dict, b: dict) -> Reused | None:
        """The earlier games of competitor ``a`` (row) against ``b`` (provenances), if it played them in this order."""
        if not (verified(a) and verified(b)):  # a user's callable: nothing proves its code is what played then
            return None
        i, j = self.index.get(identity(a)), self.index.get(identity(b))
        if i is None or j is None or i >= j:
            return None
        key, old = f"{i},{j}", self.old
        if key not in old.outcomes:
            return None
        return Reused(np.asarray(old.side_wdl[key], dtype=int), old.outcomes[key], int(old.meta.get("served", {}).get(key, 0)),
                      old.content.get(key, {}), self.path)


def _check_pairs(f: Fields, old, games: int) -> None:
    """The whole of an earlier results file before any pair of it is copied: one provenance per
    competitor (members and a mixture over them), and every pair played holds ``games`` games with
    their sides, serves and content (a pair cut short would be copied as if complete)."""
    comps = f.need("competitors", list)
    if len(comps) != old.n:
        f.fail(f"'competitors' lists {len(comps)} provenances for {old.n} labels")
    for k, prov in enumerate(comps):
        p = Fields(prov, f"{f.where} (competitors[{k}])")
        members = p.need("members", list)
        if not members or not all(isinstance(m, dict) for m in members):
            p.fail("'members' must be a non-empty list of member records")
        p.mixture("mixture", len(members))
    served = f.need("served", dict)
    for key, seq in old.outcomes.items():
        if len(seq) != games:
            f.fail(f"pair {key} holds {len(seq)} games, not games_per_pair={games}")
        if key not in old.side_wdl or key not in old.content or (old.content[key] or {}).get("games") != games:
            f.fail(f"pair {key} lacks its {'side_wdl' if key not in old.side_wdl else 'content'} for its {games} games")
        n_served = served.get(key)
        if isinstance(n_served, bool) or not isinstance(n_served, int) or not 0 <= n_served <= games:
            f.fail(f"served[{key!r}] is {n_served!r}, not a count of at most {games} games")


def check_readable(path: str) -> None:
    """Refuse a ``reuse=`` that names nothing before the output folder is claimed."""
    if not path:
        raise ConfigError("reuse= names no file; give reuse=PATH/crossplay.json (a cross-play results file)")
    if not Path(path).is_file():
        raise ConfigError(f"reuse={path!r} is not a file; give a cross-play results file (crossplay.json)")


__all__ = ["Reuse", "Reused", "identity"]
