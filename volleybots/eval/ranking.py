"""Ratings of a cross-play result: the paper's Elo, Bradley-Terry with profile-likelihood intervals, and the
Nash mixture of the meta-game with each competitor's exploitability within the population
(docs/evaluation.md). The arithmetic lives in ``volleybots.ratings`` and
``volleybots.ratings.solvers``; this module applies it to a ``CrossPlay`` and draws the plot.

Elo's games: when the cross-play played at least ``rounds`` games per pair, round r is every pair's
r-th game after a seeded shuffle of that pair's games (and the pairs of a round come in a seeded
random order); otherwise (or with ``sample=True``) each round's results are drawn from the pairs'
win/draw/loss frequencies, as the paper sampled them.

Why the shuffle: a cross-play plays each pair in batches, half its games with one competitor on team
0 and then half on team 1, and records them in that order. Sequential Elo weighs the latest games
most (with K = 168 a rating forgets within a few dozen games), so in play order the last side's batch
would decide the rating, and a side advantage would pass for a difference in strength. The games of
a pair are put in a canonical order and then permuted by the seeded generator, so the games used
depend on the pair's results and the seed only, never on the order in which they were played.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from volleybots.errors import ConfigError, Range
from volleybots.eval.content import by_competitor
from volleybots.eval.crossplay import CrossPlay, _nan_to_none
from volleybots.eval.plain import clean, plain
from volleybots.files import write_atomic, write_json
from volleybots.overrides import split_arg
from volleybots.ratings import ELO_K, ELO_START, bradley_terry_intervals, elo_history, record, round_robin, sample_round_robin
from volleybots.ratings.elo import elo_orders
from volleybots.ratings.solvers import exploitability, member_exploitability, nash

ORDERS = 100  # seeded game orders over which Elo's spread is reported
RESAMPLES = 200  # resampled payoff tables over which the Nash weights' sensitivity is reported
CARRIES = 0.01  # a member "carries weight" in a mixture where its weight is at least this

SCORE = dict(zip(record.OUTCOMES, record.SCORES))  # a game's score by its letter
K_RANGE = Range(low=0.0, low_open=True)  # Elo's K: a finite step > 0 (nan or inf would make every rating nan)


def elo_games(result: CrossPlay, rounds: int, rng: np.random.Generator, sample: bool = False) -> tuple[np.ndarray, str]:
    """The round-robin games [rounds x pairs, 3] for Elo and how they were obtained ("played" or "sampled")."""
    played = min((len(s) for s in result.outcomes.values()), default=0)
    if not sample and played >= rounds and len(result.outcomes) == result.n * (result.n - 1) // 2:
        # sorted first, so that the shuffled games depend on the results and the seed, not the play order
        shuffled = {key: rng.permutation(sorted(seq)) for key, seq in sorted(result.outcomes.items())}
        return round_robin(result.n, rounds, lambda a, b, r: SCORE[shuffled[f"{a},{b}"][r]], rng), "played"
    return sample_round_robin(result.wdl, rounds, rng), "sampled"


def nash_sensitivity(wdl, resamples: int = RESAMPLES, seed: int = 0) -> dict:
    """How much the Nash mixture rests on the payoff table's noise: each pair's W/D/L redrawn
    (multinomial at its observed frequencies and game count) ``resamples`` times, the mixture solved
    again, and for each competitor how often it carries weight (>= ``CARRIES``) and its mean weight."""
    wdl = np.asarray(wdl, float)
    n = wdl.shape[0]
    rng = np.random.default_rng([seed, 7])
    carries, weights = np.zeros(n), np.zeros(n)
    for _ in range(resamples):
        redrawn = np.zeros_like(wdl)
        for a in range(n):
            for b in range(a + 1, n):
                games = int(wdl[a, b].sum())
                if games:
                    redrawn[a, b] = rng.multinomial(games, wdl[a, b] / games)
                    redrawn[b, a] = redrawn[a, b][::-1]
        mix = nash(record.payoff(redrawn))
        carries += mix >= CARRIES
        weights += mix
    return {"resamples": resamples, "carries_weight": (carries / resamples).tolist(), "mean_weight": (weights / resamples).tolist(),
            "threshold": CARRIES}


def draw_rates(wdl) -> list:
    """Each competitor's share of drawn games over all its games (None: it played none)."""
    wdl = np.asarray(wdl, float)
    games, draws = wdl.sum((1, 2)), wdl[..., 1].sum(1)
    return [None if g == 0 else float(d / g) for d, g in zip(draws, games)]


def ratings(result: CrossPlay, rounds: int = 2000, k: float = ELO_K, seed: int = 0, sample: bool = False, orders: int = ORDERS,
            resamples: int = RESAMPLES) -> dict:
    """Ratings of a cross-play: Elo, Bradley-Terry, the Nash mixture and the exploitabilities.

    Args:
        result: the cross-play whose counts (and, unless ``sample``, game-by-game outcomes) are rated.
        rounds: Elo rounds, every pair meeting once a round.
        k: Elo's update step.
        seed: seeds the round order and the sampled results.
        sample: draw Elo's games from each pair's frequencies (as the paper did) instead of replaying
            the games that were played.
        orders: further seeded game orders whose final Elo ratings give the spread (mean, 95 %).
        resamples: payoff tables redrawn to show how often each competitor carries Nash weight.

    Returns:
        A JSON-ready dict: ``labels``, ``elo`` (final ratings and the trajectory), ``bradley_terry``
        (ratings with 95 % profile-likelihood intervals), ``average_win_rate``, ``payoffs``, ``nash`` (the mixture),
        ``nash_exploitability``, ``exploitability_in_population`` and the cross-play's settings.
    """
    rng = np.random.default_rng(seed)
    games, how = elo_games(result, rounds, rng, sample)
    pairs = result.n * (result.n - 1) // 2
    history = elo_history(games, result.n, k)
    points = _trajectory_rounds(rounds)
    bt, lo, hi = bradley_terry_intervals(result.wdl)  # decisive games only: draws are reported beside
    pay = result.payoffs()
    mix = nash(pay)
    spread = elo_orders(result.wdl, rounds, orders, seed, k, outcomes=None if sample else result.outcomes)
    return {
        "labels": result.labels,
        "elo": {"k": k, "start": ELO_START, "rounds": rounds, "games": how, "seed": seed, "ratings": history[-1].tolist(),
                "trajectory_rounds": [r + 1 for r in points], "trajectory": history[[(r + 1) * pairs for r in points]].tolist(),
                # the same Elo over `orders` other seeded orders: what the order alone moves it by
                "orders": orders, "order_mean": spread.mean(0).tolist(), "order_low": np.percentile(spread, 2.5, 0).tolist(),
                "order_high": np.percentile(spread, 97.5, 0).tolist()},
        "bradley_terry": {"ratings": bt.tolist(), "low": lo.tolist(), "high": hi.tolist(),
                           "interval": "95 % Firth-penalised profile likelihood", "draws": "left out (decisive games only)"},
        "draw_rate": draw_rates(result.wdl),
        "average_win_rate": _nan_to_none(result.average_win_rate()),
        "payoffs": pay.tolist(),
        "nash": mix.tolist(),
        "nash_sensitivity": nash_sensitivity(result.wdl, resamples, seed),
        # percentage points of score, 100 x (score - 0.5), score = (wins + draws / 2) / games
        "nash_exploitability": 50.0 * exploitability(pay, mix),
        "exploitability_in_population": (50.0 * member_exploitability(pay)).tolist(),
        "crossplay": {k: result.meta.get(k) for k in ("task", "action_space", "games_per_pair", "seed", "scenario", "competitors")},
        # what the games held: per competitor over all its pairs, and per pair from the first one's side
        "content": {"competitors": by_competitor(result.labels, result.content), "pairs": result.content},
    }


def _trajectory_rounds(rounds: int, points: int = 200) -> list[int]:
    return sorted({int(r) for r in np.linspace(0, rounds - 1, min(points, rounds))})


def plot(report: dict, path: Path) -> None:
    """Two panels: Elo over the rounds, and the final Elo beside Bradley-Terry with its interval."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = [clean(lab) for lab in report["labels"]]  # a label from a results file may hold control characters
    e, bt = report["elo"], report["bradley_terry"]
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4))
    traj = np.asarray(e["trajectory"])
    for i, lab in enumerate(labels):
        left.plot(e["trajectory_rounds"], traj[:, i], label=lab)
    left.set_xlabel("round (every pair meets once)")
    left.set_ylabel("Elo")
    left.set_title(f"Elo, K={e['k']:g}, {e['rounds']} rounds of {e['games']} games, seed {e['seed']}", fontsize=9)
    left.legend(fontsize=8)
    x = np.arange(len(labels))
    r, lo, hi = (np.asarray(bt[k]) for k in ("ratings", "low", "high"))
    right.errorbar(x + 0.1, r, yerr=[r - lo, hi - r], fmt="o", capsize=4, label="Bradley-Terry (95 % profile likelihood)")
    right.plot(x - 0.1, e["ratings"], "s", label="Elo (final)")
    if e.get("orders"):  # the order's own spread of Elo: what a reader must not read as a difference in strength
        m, lo_, hi_ = (np.asarray(e[k]) for k in ("order_mean", "order_low", "order_high"))
        right.errorbar(x - 0.2, m, yerr=[m - lo_, hi_ - m], fmt="s", mfc="none", capsize=3, label=f"Elo over {e['orders']} orders (95 %)")
    right.set_xticks(x, labels, rotation=30, ha="right")
    cp = report["crossplay"]
    right.set_title(f"{cp['task']}: {cp['games_per_pair']} games per pair, cross-play seed {cp['seed']}", fontsize=9)
    right.legend(fontsize=8)
    fig.tight_layout()
    try:
        write_atomic(path, lambda fh: fig.savefig(fh, format="png", dpi=120), "the ratings plot")
    finally:
        plt.close(fig)


def format_table(report: dict):
    from rich.table import Table

    e, bt = report["elo"], report["bradley_terry"]
    orders = e.get("orders")
    table = Table(
        title=plain(f"ratings on {report['crossplay']['task']}: Elo K={e['k']:g} over {e['rounds']} rounds ({e['games']} games)"
        + (f", with its mean [95 %] over {orders} game orders" if orders else "")
        + "; BT on decisive games with 95 % profile-likelihood intervals; Nash weight (share of resampled tables where it carries weight)")
    )
    cols = ("competitor", "Elo", "Elo over orders", "Bradley-Terry [95 %]", "draws", "avg win rate", "Nash weight",
            "exploitability in population (pp)", "touches/game (opp.)", "rally steps", "serving W/D/L", "receiving W/D/L")
    for col in cols:
        table.add_column(col, justify="left" if col == "competitor" else "right")
    content = report.get("content", {}).get("competitors") or [None] * len(report["labels"])
    sens = report.get("nash_sensitivity")
    draws = report.get("draw_rate") or [None] * len(report["labels"])
    for i, lab in enumerate(report["labels"]):
        avg = report["average_win_rate"][i]
        c = content[i]
        played = ("-",) * 4 if c is None else (
            f"{c['touches']:.2f} ({c['opponent_touches']:.2f})", f"{c['rally_steps']:.0f}",
            "/".join(map(str, c["serve_wdl"])), "/".join(map(str, c["receive_wdl"])))
        table.add_row(
            plain(lab),
            f"{e['ratings'][i]:.0f}",
            f"{e['order_mean'][i]:.0f} [{e['order_low'][i]:.0f}, {e['order_high'][i]:.0f}]" if orders else "-",
            f"{bt['ratings'][i]:.0f} [{bt['low'][i]:.0f}, {bt['high'][i]:.0f}]",
            "-" if draws[i] is None else f"{draws[i]:.2f}",
            "n/a" if avg is None else f"{avg:.3f}",
            f"{report['nash'][i]:.3f}" + (f" ({sens['carries_weight'][i]:.2f})" if sens else ""),
            f"{report['exploitability_in_population'][i]:.1f}",
            *played,
        )
    return table


# ------------------------------------------------------------------ command line
# options of `volleybots eval elo` besides cross-play's (rounds replaces games)
ELO_OPTIONS = {"rounds": int, "k": float, "sample": bool, "from": str, "orders": int}
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
    from volleybots.eval.crossplay import HEATMAP, OPTIONS, RESULTS, default_out, heatmap, play_and_save, resolve_all, setup, split_args
    from volleybots.runs import output_dir

    if any(split_arg(a)[0] == "bootstrap" for a in args):
        raise ConfigError(
            "bootstrap= is no longer an option of eval elo: Bradley-Terry's intervals are profile-likelihood intervals, "
            "which draw no resamples; leave it out"
        )
    options = {**{k: v for k, v in OPTIONS.items() if k != "games"}, **ELO_OPTIONS}
    specs, opts, _ = split_args(args, options)
    rounds = opts.get("rounds", 2000)
    if rounds < 1:
        raise ConfigError(f"rounds={rounds} must be >= 1")
    k = opts.get("k", ELO_K)
    if k not in K_RANGE:
        raise ConfigError(f"k={k} must be a finite number > 0 (Elo's step; the paper's is {ELO_K:g})")
    orders = opts.get("orders", ORDERS)
    if not 1 <= orders <= 10_000:
        raise ConfigError(f"orders={orders} must be 1 to 10000 (seeded game orders over which Elo's spread is reported)")
    source = opts.get("from")
    if source is not None:
        playing = [key for key in ("reuse", "batch", "scenario", "deterministic", "pool") if key in opts]
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
        play = [a for a in args if split_arg(a)[0] not in ELO_OPTIONS] + [f"games={rounds}"]
        comps, specs, play_opts, cfg = setup(play, OPTIONS)
        task, sample = cfg.task.name, opts.get("sample", False)
    with output_dir(out, default_out(task, "elo")) as path:  # claimed and locked before any game
        if source is None:
            result = play_and_save(comps, specs, play_opts, cfg, path, progress)
        report = ratings(result, rounds, k, opts.get("seed", 0), sample, orders=orders)
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
