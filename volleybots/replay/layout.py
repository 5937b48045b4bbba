"""Default rerun layouts (blueprints) sent with every recording, so a replay opens readable.

Three kinds of episode share one shape: the court's 3D view takes the left three fifths; on the right
the curves, one time series view per team (its drones' rewards) and per quantity group (return and
reward terms; outcome counters; a match's score and touches; a hierarchical team's drills), and under
them the summary (how it ended, the score and the fault) beside the event log.

- single drone: one drone, one reward view;
- cooperative: several drones of one team, their rewards in one view;
- match: two teams, one reward view per team (blue, red) and a score view.

Training curves (``curves.rrd``) get one view per quantity group: the task's figures, losses,
throughput.
"""

from __future__ import annotations

from volleybots.replay.style import TEAM_NAMES

# statistics that are bookkeeping of a match (who won, why, who served), shown in the summary
MATCH_BOOKKEEPING = ("winner", "reason", "serve_team", "win", "loss", "draw", "hits_team0", "hits_team1")


def task_kind(teams) -> str:
    """``single``, ``cooperative`` or ``match`` from the team of each drone."""
    if len(set(teams)) > 1:
        return "match"
    return "single" if len(teams) == 1 else "cooperative"


def _series(name: str, paths: list[str]):
    import rerun.blueprint as rrb

    return rrb.TimeSeriesView(name=name, origin="/", contents=[f"+ /{p}" for p in paths])


def episode_blueprint(teams, stat_keys: list[str], drills: bool = False, prefix: str = ""):
    """The layout of one recorded episode (see the module docstring), its paths under ``prefix``."""
    import rerun.blueprint as rrb

    teams = tuple(int(t) for t in teams)
    kind = task_kind(teams)
    p = prefix

    def drones(team=None):
        return [f"{p}reward/drone_{k}" for k, t in enumerate(teams) if team is None or t == team]

    if kind == "match":
        rewards = [_series(f"team {t} ({TEAM_NAMES[t]}) rewards", drones(t)) for t in (0, 1)]
    else:
        rewards = [_series("reward per drone" if kind == "cooperative" else "reward", drones())]
    terms = [f"{p}episode/{k}" for k in stat_keys if k == "return" or k.startswith("r_")]
    bookkeeping = MATCH_BOOKKEEPING if kind == "match" else ()
    counters = [f"{p}episode/{k}" for k in stat_keys if k not in bookkeeping and k != "return" and not k.startswith("r_")]
    curves = [*rewards, _series("return and reward terms", terms)]
    if counters:
        curves.append(_series("episode figures", counters))
    if kind == "match":
        curves.append(_series("score and touches per team", [f"{p}score/**"]))
    if drills:
        curves.append(_series("drill per drone (high level)", [f"{p}drill/**"]))
    court = rrb.Spatial3DView(name=f"court ({kind.replace('single', 'single drone')})", origin=f"/{p}world")
    texts = rrb.Horizontal(
        rrb.TextDocumentView(name="how it ended", origin=f"/{p}summary"),
        rrb.TextLogView(name="events", origin="/", contents=[f"+ /{p}events", f"+ /{p}match", f"+ /{p}decisions"]),
    )
    right = rrb.Vertical(rrb.Grid(*curves), texts, row_shares=[3, 2])
    return rrb.Blueprint(rrb.Horizontal(court, right, column_shares=[3, 2]), collapse_panels=True)


# metrics.csv columns by group; a column in none of them goes to the task's figures
_LOSS_WORDS = ("loss", "entropy", "kl", "grad", "clip", "alpha", "q_value", "td_")
_SPEED = ("fps", "wall_time", "iteration")


def curves_group(column: str) -> str:
    """The view a metrics.csv column is drawn in."""
    if column in _SPEED:
        return "throughput"
    if any(w in column for w in _LOSS_WORDS):
        return "losses"
    if column.startswith("r_"):
        return "reward terms"
    return "task figures"


def curves_blueprint(paths: list[str]):
    """The layout of ``curves.rrd``: per phase (train, eval, ...), one time series view per group of
    ``curves_group``; ``paths`` are the logged ``phase/column`` entities."""
    import rerun.blueprint as rrb

    groups: dict[str, list[str]] = {}
    for path in paths:
        phase, _, column = path.partition("/")
        groups.setdefault(f"{phase}: {curves_group(column)}", []).append(path)
    order = ("task figures", "reward terms", "losses", "throughput")
    names = sorted(groups, key=lambda g: (g.split(": ")[0] != "train", order.index(g.split(": ")[1]), g))
    return rrb.Blueprint(rrb.Grid(*[_series(n, groups[n]) for n in names]), collapse_panels=True)
