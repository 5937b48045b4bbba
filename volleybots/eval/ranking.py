"""Ratings of a cross-play (docs/evaluation.md): every method registered in
``volleybots.ratings.methods.RATINGS`` (the paper's Elo, Bradley-Terry with profile-likelihood
intervals, the average win rate, the Nash mixture of the meta-game with each competitor's
exploitability within the population) applied to a ``CrossPlay``, tabled and plotted. The arithmetic
and each method's columns live in ``volleybots.ratings``; this module knows no method by name: it loops
over the registry, and adds the cross-play's own settings and what the games held.

Elo's games: when the cross-play played at least ``rounds`` games per pair, round r is every pair's
r-th game after a seeded shuffle of that pair's games (``volleybots.ratings.elo.elo_games`` says why);
otherwise (or with ``sample=True``) each round's results are drawn from the pairs' win/draw/loss
frequencies, as the paper sampled them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from volleybots.config.verbs import EloOptions
from volleybots.errors import ConfigError
from volleybots.eval.content import by_competitor
from volleybots.eval.crossplay import CrossPlay
from volleybots.eval.plain import clean, plain
from volleybots.files import write_atomic, write_json
from volleybots.overrides import split_arg
from volleybots.ratings import ELO_K
from volleybots.ratings.methods import ORDERS, RATINGS, RESAMPLES, ROUNDS, Games, rate

CONTENT_COLUMNS = ("touches/game (opp.)", "rally steps", "serving W/D/L", "receiving W/D/L")  # what the games held, after the ratings


def ratings(result: CrossPlay, rounds: int = ROUNDS, k: float = ELO_K, seed: int = 0, sample: bool = False, orders: int = ORDERS,
            resamples: int = RESAMPLES) -> dict:
    """Ratings of a cross-play by every method of ``RATINGS``.

    Args:
        result: the cross-play whose counts (and, unless ``sample``, game-by-game outcomes) are rated.
        rounds: Elo rounds, every pair meeting once a round.
        k: Elo's update step.
        seed: seeds the round order, the sampled results and the resampled tables.
        sample: draw Elo's games from each pair's frequencies (as the paper did) instead of replaying
            the games that were played.
        orders: further seeded game orders whose final Elo ratings give the spread (mean, 95 %).
        resamples: payoff tables redrawn to show how often each competitor carries Nash weight.

    Returns:
        A JSON-ready dict: ``labels``, each method's keys (``elo``, ``bradley_terry`` and ``draw_rate``,
        ``average_win_rate``, ``payoffs``, ``nash``, ``nash_sensitivity``, ``nash_exploitability``,
        ``exploitability_in_population`` for the built-in ones), the cross-play's settings and what the
        games held.
    """
    games = Games(result.labels, result.wdl, result.outcomes, seed,
                  {"rounds": rounds, "k": k, "sample": sample, "orders": orders, "resamples": resamples})
    return {
        "labels": result.labels,
        **rate(games),
        "crossplay": {k: result.meta.get(k) for k in ("task", "action_space", "games_per_pair", "seed", "scenario", "competitors")},
        # what the games held: per competitor over all its pairs, and per pair from the first one's side
        "content": {"competitors": by_competitor(result.labels, result.content), "pairs": result.content},
    }


def plot(report: dict, path: Path) -> None:
    """A panel for each method that has one (Elo's trajectory), then one panel of every method's
    ratings on the Elo scale side by side (Elo's final and its spread over orders, Bradley-Terry with
    its interval)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    report = {**report, "labels": [clean(lab) for lab in report["labels"]]}  # a label from a results file may hold control characters
    panels = [m.panel for m in RATINGS.values() if m.panel is not None]
    fig, axes = plt.subplots(1, len(panels) + 1, figsize=(5.5 * (len(panels) + 1), 4), squeeze=False)
    for draw, ax in zip(panels, axes[0], strict=False):
        draw(report, ax)
    shared = axes[0][-1]
    x = np.arange(len(report["labels"]))
    for method in RATINGS.values():
        if method.plot is not None:
            method.plot(report, shared, x)
    shared.set_xticks(x, report["labels"], rotation=30, ha="right")
    cp = report["crossplay"]
    shared.set_title(f"{cp['task']}: {cp['games_per_pair']} games per pair, cross-play seed {cp['seed']}", fontsize=9)
    shared.legend(fontsize=8)
    fig.tight_layout()
    try:
        write_atomic(path, lambda fh: fig.savefig(fh, format="png", dpi=120), "the ratings plot")
    finally:
        plt.close(fig)


def format_table(report: dict):
    """The table of ``eval elo``: a row per competitor, each method's columns in ``RATINGS`` order, then
    what its games held; the title joins each method's part."""
    from rich.table import Table

    parts = [title for title in (m.title(report) for m in RATINGS.values()) if title]
    table = Table(title=plain(f"ratings on {report['crossplay']['task']}: " + "; ".join(parts)))
    for col in ("competitor", *(c for m in RATINGS.values() for c in m.columns), *CONTENT_COLUMNS):
        table.add_column(col, justify="left" if col == "competitor" else "right")
    content = report.get("content", {}).get("competitors") or [None] * len(report["labels"])
    for i, lab in enumerate(report["labels"]):
        c = content[i]
        played = ("-",) * len(CONTENT_COLUMNS) if c is None else (
            f"{c['touches']:.2f} ({c['opponent_touches']:.2f})", f"{c['rally_steps']:.0f}",
            "/".join(map(str, c["serve_wdl"])), "/".join(map(str, c["receive_wdl"])))
        table.add_row(plain(lab), *(cell for m in RATINGS.values() for cell in m.cells(report, i)), *played)
    return table


# ------------------------------------------------------------------ command line
REPORT = "ratings.json"
PLOT = "ratings.png"


def run_elo(args, out: Path | None = None, progress=None) -> tuple[dict, Path]:
    """``volleybots eval elo``: ratings of games played now or of a cross-play results file.

    Args:
        args: the command's words: competitors and ``key=value`` options (``rounds=``, ``k=``,
            ``from=FILE`` to rate a cross-play already played, whose competitors must be the ones
            named, if any).
        out: the output directory; ``None`` picks one under ``outputs/``.
        progress: called as ``progress(i, j, games)`` after each pair played.

    Returns:
        ``(report, directory)``: the dict of ``ratings`` and where it was written (JSON and plot).
    """
    from volleybots.config.resources import check_rounds
    from volleybots.eval.crossplay import HEATMAP, RESULTS, default_out, heatmap, play_and_save, resolve_all, setup, split_args
    from volleybots.runs import output_dir

    if any(split_arg(a)[0] == "bootstrap" for a in args):
        raise ConfigError(
            "bootstrap= is no longer an option of eval elo: Bradley-Terry's intervals are profile-likelihood intervals, "
            "which draw no resamples; leave it out"
        )
    specs, opts, _ = split_args(args, EloOptions)  # (each option's type and range checked as it is read)
    if opts.games is not None and "rounds" not in opts.given:  # games= is rounds= as eval crossplay spells it
        opts.rounds = opts.games
    # (with both, rounds= counts, as it always did: a command line copied from eval crossplay and given its own
    # rounds= keeps playing what it played)
    rounds, k, orders, source = opts.rounds, opts.k, opts.orders, opts.source
    if source is not None:
        playing = [key for key in ("reuse", "batch", "scenario", "deterministic", "pool", "games") if key in opts.given]
        if playing:  # they say how games are played, and from= plays none: silently ignored, they would mislead
            raise ConfigError(f"{'= and '.join(playing)}= play games, but from={source!r} rates a cross-play already played; "
                              "leave them out, or name competitors instead of from= to play")
        result = CrossPlay.load(source)
        unplayed = [(a, b) for a in range(result.n) for b in range(a + 1, result.n) if result.wdl[a, b].sum() == 0]
        if unplayed:  # sampled Elo draws each pair's games from its results: a pair without any has none to draw
            a, b = unplayed[0]
            raise ConfigError(f"from={str(source)!r}: {result.labels[a]!r} and {result.labels[b]!r} played no game, so "
                              f"Elo has no results of theirs to sample ({len(unplayed)} such pair(s)); play them first (eval crossplay)")
        if specs:
            _check_same_competitors(result, resolve_all(specs), source)
        check_rounds(rounds, result.n, orders)
        task, sample = result.meta.get("task", "task"), True
    else:
        if rounds % 2:
            raise ConfigError(f"rounds={rounds} must be even: the games of every pair are played half on each side")
        check_rounds(rounds, max(2, len(specs)), orders)  # before the competitors load: rounds are the games per pair
        comps, specs, opts, cfg = setup(args, EloOptions, games=rounds)
        task, sample = cfg.task.name, opts.sample
    with output_dir(out, default_out(task, "elo")) as path:  # claimed and locked before any game
        if source is None:
            result = play_and_save(comps, specs, opts, cfg, path, progress, games=rounds)
        report = ratings(result, rounds, k, opts.seed, sample, orders=orders)
        report["source"] = str(source) if source is not None else str(path / RESULTS)
        write_json(path / REPORT, report, "the ratings")
        plot(report, path / PLOT)
        if source is not None:
            heatmap(result, path / HEATMAP)
    return report, path


def _check_same_competitors(result: CrossPlay, competitors, source) -> None:
    """The competitors named must be the file's: the same labels and the same member files."""
    mine = [(c.label, [m.get("sha256") for m in c.sources]) for c in competitors]
    theirs = [(p["label"], [m.get("sha256") for m in p["members"]]) for p in result.meta.get("competitors", [])]
    if mine != theirs:
        raise ConfigError(
            f"{str(source)!r} holds games of {[t[0] for t in theirs]}, not of the competitors named {[m[0] for m in mine]} "
            "(or their files changed)"
        )
