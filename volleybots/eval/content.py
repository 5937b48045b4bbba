"""What a cross-play's games held (touches, rally length, ending faults, serving and receiving),
per pair and per competitor, and its rich table.

Win rates alone cannot tell a player that rallies from one that wins on the other side's serve faults;
these figures can. ``CrossPlay.content`` holds ``play.games.Games.content()`` of every pair, from the
row competitor's side ("i,j" with i < j); ``by_competitor`` folds a competitor's pairs into one
record, weighting each pair by its games.
"""

from __future__ import annotations

import numpy as np

from volleybots.eval.plain import plain
from volleybots.ratings import record


def pair_view(content: dict, me_first: bool) -> dict:
    """A pair's content from one competitor's side: (own touches, opponent's touches, rally steps,
    rally touches, own serve W/D/L, own receive W/D/L, own ending faults, games)."""
    t = content["touches"]
    own, opp = (t[0], t[1]) if me_first else (t[1], t[0])
    serve, receive = content["serve_wdl"], content["receive_wdl"]
    if not me_first:  # B served exactly when A received
        serve, receive = record.flip(receive).tolist(), record.flip(serve).tolist()
    faults = content["faults"]["A" if me_first else "B"]
    return {"games": content["games"], "touches": own, "opponent_touches": opp, "rally_steps": content["rally_steps"],
            "rally_touches": content["rally_touches"], "serve_wdl": serve, "receive_wdl": receive, "faults": faults}


def by_competitor(labels: list[str], content: dict[str, dict]) -> list[dict | None]:
    """Per competitor, over all its pairs: mean touches (own and the opponents'), rally steps and
    touches per game, W/D/L serving and receiving, and the faults that lost it games (None: no games)."""
    out = []
    for c in range(len(labels)):
        views = []
        for key, cont in content.items():
            i, j = map(int, key.split(","))
            if c in (i, j) and cont.get("games"):
                views.append(pair_view(cont, c == i))
        if not views:
            out.append(None)
            continue
        w = np.array([v["games"] for v in views], dtype=float)
        mean = lambda k, views=views, w=w: float(np.average([v[k] for v in views], weights=w))  # noqa: E731
        faults: dict[str, int] = {}
        for v in views:
            for f, n in v["faults"].items():
                faults[f] = faults.get(f, 0) + n
        out.append({
            "games": int(w.sum()),
            "touches": mean("touches"),
            "opponent_touches": mean("opponent_touches"),
            "rally_steps": mean("rally_steps"),
            "rally_touches": mean("rally_touches"),
            "serve_wdl": np.sum([v["serve_wdl"] for v in views], 0).astype(int).tolist(),
            "receive_wdl": np.sum([v["receive_wdl"] for v in views], 0).astype(int).tolist(),
            "faults": dict(sorted(faults.items(), key=lambda kv: -kv[1])),
        })
    return out


def _faults(d: dict) -> str:
    return plain(", ".join(f"{f} {n}" for f, n in sorted(d.items(), key=lambda kv: -kv[1])) or "-")


def format_content(labels: list[str], content: dict[str, dict], title: str = "game content"):
    """A rich table, one row per pair: touches per game of each, rally length (steps, touches), games
    of 3+ touches, the faults that ended them per team, and the row's W/D/L serving and receiving."""
    from rich.table import Table

    table = Table(title=f"{title}: per game, from the first competitor's side (A vs B)")
    for col in ("A vs B", "touches A/B", "rally steps", "rally touches (max)", "3+ touches", "faults of A", "faults of B",
                "A serving W/D/L", "A receiving W/D/L"):
        table.add_column(col, justify="left" if col in ("A vs B", "faults of A", "faults of B") else "right")
    for key, c in sorted(content.items(), key=lambda kv: tuple(map(int, kv[0].split(",")))):
        i, j = map(int, key.split(","))
        if not c.get("games"):
            continue
        t = c["touches"]
        table.add_row(
            plain(f"{labels[i]} vs {labels[j]}"), f"{t[0]:.2f} / {t[1]:.2f}", f"{c['rally_steps']:.0f}",
            f"{c['rally_touches']:.2f} ({c['rally_touches_max']})", f"{c['games_3plus_touches']}/{c['games']}",
            _faults(c["faults"]["A"]), _faults(c["faults"]["B"]),
            "/".join(map(str, c["serve_wdl"])), "/".join(map(str, c["receive_wdl"])),
        )
    return table
