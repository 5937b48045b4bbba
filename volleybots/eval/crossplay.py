"""Cross-play: every pair of competitors plays N games, both sides equally often (docs/evaluation.md).

``crossplay`` fills a ``CrossPlay``: the wins, draws and losses of each row competitor against each
column one, the game-by-game outcomes (for Elo rounds), and the provenance of every competitor (path,
file sha256, config) with the seed, the scenario and the package versions. From it: the win rate over
decisive games with Wilson 95 % intervals, each competitor's average win rate against the others, the
zero-sum payoff table of the meta-game, a heatmap and a JSON file that ``CrossPlay.load`` reads back.
``content`` holds what each pair's games held (touches, rally length, ending faults, serving and
receiving apart; ``volleybots.eval.content``).

A competitor is not played against itself: its diagonal cell is empty (to measure a competitor against
itself, enter it twice under two labels, ``a=PATH b=PATH``).
"""

from __future__ import annotations

import platform
from dataclasses import dataclass, field
from itertools import combinations
from pathlib import Path

import numpy as np

from volleybots.config import load, make_env, to_dict
from volleybots.config.args import split_args
from volleybots.config.resources import check_play
from volleybots.config.verbs import CrossplayOptions, PlayOptions
from volleybots.errors import ConfigError
from volleybots.eval.crossplay_view import format_table, heatmap  # noqa: F401 (the views, importable from here as before)
from volleybots.eval.results import check_consistent
from volleybots.eval.reuse import Reuse, check_readable
from volleybots.files import Fields, read_json, write_json
from volleybots.keys import OBS
from volleybots.overrides import split_arg
from volleybots.play.games import DEFAULT_BATCH, check_scenario, play_games
from volleybots.ratings import record

FORMAT = "volleybots.crossplay/1"


@dataclass
class CrossPlay:
    labels: list[str]
    wdl: np.ndarray  # [n, n, 3] wins, draws, losses of the row against the column
    outcomes: dict[str, str] = field(default_factory=dict)  # "i,j" (i < j) -> W/D/L per game from i's side, in play order
    side_wdl: dict[str, list] = field(default_factory=dict)  # "i,j" -> [2, 3]: i on team 0 / team 1
    meta: dict = field(default_factory=dict)  # task, games, seed, scenario, competitors' provenance, versions
    content: dict[str, dict] = field(default_factory=dict)  # "i,j" -> Games.content() from i's side

    @property
    def n(self) -> int:
        return len(self.labels)

    def decisive(self) -> np.ndarray:
        return record.decisive(self.wdl)

    def win_rate(self) -> np.ndarray:
        """[n, n] wins / decisive games of the row against the column (nan where none)."""
        return record.win_rate(self.wdl)

    def interval(self, confidence: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
        """Wilson intervals [n, n] of ``win_rate``."""
        return record.win_rate_interval(self.wdl, confidence)

    def average_win_rate(self) -> np.ndarray:
        """[n]: each competitor's mean win rate against the others (pairs without a decisive game left out)."""
        return record.average_win_rate(self.wdl)

    def payoffs(self) -> np.ndarray:
        """[n, n] the zero-sum payoff (wins - losses) / games of the row (docs/competitive.md); the
        diagonal is 0, a competitor's value against itself in a symmetric game."""
        return record.payoff(self.wdl)

    # ------------------------------------------------------------------ files
    def to_dict(self) -> dict:
        lo, hi = self.interval()
        return {
            "format": FORMAT,
            **self.meta,
            "labels": self.labels,
            "wdl": self.wdl.astype(int).tolist(),
            "side_wdl": self.side_wdl,
            "win_rate": _nan_to_none(self.win_rate()),
            "win_rate_low": _nan_to_none(lo),
            "win_rate_high": _nan_to_none(hi),
            "average_win_rate": _nan_to_none(self.average_win_rate()),
            "outcomes": self.outcomes,
            "content": self.content,
        }

    def save(self, path: Path) -> None:
        write_json(path, self.to_dict(), "the cross-play results")

    @classmethod
    def load(cls, path) -> CrossPlay:
        """Read a results file that ``save`` wrote, checked key by key (labels, an n x n x 3 table of
        counts, outcomes of W/D/L per pair); anything else is one ``ConfigError`` line."""
        data = read_json(path, "cross-play results file")
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            raise ConfigError(f"{str(path)!r} is not a cross-play results file (format is not {FORMAT!r})")
        f = Fields(data, f"cross-play results file {str(path)!r}")
        labels = f.need("labels", list)
        n = len(labels)
        if n < 2 or not all(isinstance(x, str) for x in labels):
            f.fail("'labels' must name at least two competitors")
        check_labels(labels, f"'labels' of {str(path)!r}")
        wdl = np.asarray(f.counts("wdl", (n, n, 3)), dtype=float)
        outcomes = f.need("outcomes", dict)
        for key, seq in outcomes.items():
            i, _, j = str(key).partition(",")
            if not (i.isdigit() and j.isdigit() and int(i) < int(j) < n) or not isinstance(seq, str) or set(seq) - set(record.OUTCOMES):
                f.fail(f"outcomes[{key!r}] is not a pair 'i,j' of competitors with a string of W, D and L")
            counted = record.tally(seq).tolist()
            if counted != wdl[int(i), int(j)].astype(int).tolist():
                said = "/".join(map(str, wdl[int(i), int(j)].astype(int)))
                f.fail(f"outcomes[{key!r}] holds {'/'.join(map(str, counted))} games, wdl says {said}")
        side_wdl = f.need("side_wdl", dict)
        for key in side_wdl:
            Fields(side_wdl, f.where).counts(key, (2, 3))
        meta = {k: v for k, v in data.items() if k not in _DERIVED}
        content = data.get("content") or {}
        if not isinstance(content, dict):
            f.fail("'content' must be a mapping of pairs 'i,j' to game content")
        check_consistent(f, n, wdl.astype(int).tolist(), side_wdl, content)
        return cls(list(labels), wdl, dict(outcomes), dict(side_wdl), meta, dict(content))


_DERIVED = ("format", "labels", "wdl", "side_wdl", "win_rate", "win_rate_low", "win_rate_high", "average_win_rate", "outcomes", "content")


def _nan_to_none(a: np.ndarray):
    """JSON has no NaN: a missing rate is null."""
    return [_nan_to_none(x) for x in a] if np.ndim(a) else (None if np.isnan(a) else float(a))


def versions() -> dict:
    import scipy
    import tensordict
    import torch
    import torchrl

    from volleybots.version import __version__, play_code

    return {
        "volleybots": __version__,
        "play_code": play_code(),
        "python": platform.python_version(),
        "torch": torch.__version__,
        "torchrl": torchrl.__version__,
        "tensordict": tensordict.__version__,
        "numpy": np.__version__,
        "scipy": scipy.__version__,
    }




MAX_LABEL = 1000  # characters: past any file or run name (a long one still replays), short enough to draw at once


def check_labels(labels, where: str) -> None:
    """Refuse a label longer than ``MAX_LABEL``: every table and plot draws it (a 100,000-character one
    took minutes to draw), and no file or run name is that long."""
    long = next((lab for lab in labels if len(lab) > MAX_LABEL), None)
    if long is not None:
        raise ConfigError(f"{where}: {long[:40]!r}... is {len(long):,} characters long; a label has at most {MAX_LABEL}")


def resolve_all(specs) -> list:
    """Competitors from their specs (``volleybots.policies.resolve_competitor``); labels must differ."""
    from volleybots.policies import resolve_competitor

    comps = [resolve_competitor(s) for s in specs]
    labels = [c.label for c in comps]
    check_labels(labels, "a competitor's label")
    dup = sorted({lab for lab in labels if labels.count(lab) > 1})
    if dup:
        raise ConfigError(f"two competitors are labelled {dup[0]!r}; label them apart: name=PATH")
    return comps


def match_config(competitors, overrides=()):
    """The validated config of the match every competitor plays: the task and action space of the
    trained competitors unless ``task=`` / ``env.action_space=`` say (then they must fit), and the
    overrides; each competitor builds its team policy once here, so a bad one fails before any game."""
    keys = {split_arg(o)[0] for o in overrides}
    if "task.serve" in keys:  # each game's serve is the scenario's: a task.serve would be overwritten, yet recorded
        given = next(o for o in overrides if split_arg(o)[0] == "task.serve")
        raise ConfigError(f"{given} is not a match setting: who serves is scenario=any|serve|receive (any: a random side "
                          "each game; serve: the first competitor serves; receive: the other one does)")
    trained = [m for c in competitors for m in c.members if m.task is not None]
    extra = []
    if "task" not in keys:
        if not trained:
            raise ConfigError("name the match the scripted/random competitors play: task=1v1, task=3v3 or task=6v6")
        extra.append(f"task={trained[0].task}")
    spaces = [m.action_space for m in trained if m.action_space is not None]  # a hierarchical team fits any
    if "env.action_space" not in keys and spaces:
        extra.append(f"env.action_space={spaces[0]}")
    cfg = load([*extra, *overrides])
    check_scenario("any", cfg)
    env = make_env(cfg, num_envs=1, seed=0)
    obs_dim = env.observation_spec[OBS].shape[-1]
    for c in competitors:
        c.check_fits(cfg.task.name, cfg.env.action_space, obs_dim)
        c.team_policy(env)
    return cfg


def provenance(competitor, spec: str) -> dict:
    """What a results file says about a competitor: its spec, members (paths, sha256) and mixture."""
    return {"label": competitor.label, "spec": spec, "members": competitor.sources, "mixture": [float(x) for x in competitor.mixture]}


def crossplay(cfg, competitors, games: int, seed: int = 0, batch: int = DEFAULT_BATCH, scenario: str = "any",
              deterministic: bool = False, specs=None, progress=None, reuse=None, pool: str = "serial") -> CrossPlay:
    """Play ``games`` games for every pair of ``competitors`` on the match task of ``cfg``.

    Args:
        cfg: the match config (``match_config``): task, action space, physics.
        competitors: two or more resolved competitors (``resolve_all``).
        games: games per pair, each competitor on each side half of them.
        seed: seeds the games; the same seed replays the same games.
        batch: worlds played together.
        scenario: "any", "serve" (the row competitor serves) or "receive".
        deterministic: competitors act with their mode instead of sampling.
        specs: the competitors as named on the command line, for the provenance.
        progress: called as ``progress(i, j, games)`` after each pair; one with a ``begin`` method is first
            told the number of pairs (``begin(total)``: its done / total and ETA).
        reuse: an earlier results file whose pairs are copied instead of played (``volleybots.eval.reuse``).
        pool: "serial" (pairs in turn) or "ray" (pairs as Ray tasks together; the same numbers: every
            pair plays on ``seed``).

    Returns:
        The ``CrossPlay``: win / draw / loss counts per ordered pair, game-by-game outcomes and the
        provenance of every competitor.
    """
    n = len(competitors)
    if n < 2:
        raise ConfigError(f"cross-play needs at least two competitors; got {n}")
    labels = [c.label for c in competitors]
    wdl = np.zeros((n, n, 3))
    outcomes, sides, served, content, reused = {}, {}, {}, {}, {}
    meta = {
        "task": cfg.task.name, "action_space": cfg.env.action_space, "games_per_pair": games, "seed": seed, "batch": batch,
        "scenario": scenario, "deterministic": deterministic,
        "competitors": [provenance(c, s) for c, s in zip(competitors, specs or labels)],
        "served": served,  # "i,j" -> games in which i served
        "config": to_dict(cfg),
        "versions": versions(),
    }
    earlier = Reuse(reuse, CrossPlay.load(reuse), meta) if reuse is not None else None  # refused here, before any game, if it does not fit
    pairs = list(combinations(range(n), 2))
    copied = {(i, j): earlier.pair(meta["competitors"][i], meta["competitors"][j]) for i, j in pairs} if earlier is not None else {}
    todo = [(i, j) for i, j in pairs if copied.get((i, j)) is None]
    if hasattr(progress, "begin"):
        progress.begin(len(pairs))
    from volleybots.play.pool import pool_map

    played = pool_map(_play_pair, cfg, [(competitors[i], competitors[j], games, seed, batch, scenario, deterministic) for i, j in todo],
                      pool)
    for i, j in pairs:
        key = f"{i},{j}"
        g = copied.get((i, j))
        if g is None:
            g = next(played)
        else:
            reused[key] = g.source
        record.put(wdl, i, j, g.total)
        outcomes[key], served[key], sides[key], content[key] = g.outcomes, g.served, g.wdl.tolist(), g.content()
        if progress is not None:
            progress(i, j, g)
    if reused:
        meta["reused"] = reused  # "i,j" -> the results file the pair was copied from
    return CrossPlay(labels, wdl, outcomes, sides, meta, content)


def _play_pair(cfg, a, b, games: int, seed: int, batch: int, scenario: str, deterministic: bool):
    """One pair's games (a Ray task's body with ``pool=ray``)."""
    return play_games(cfg, a, b, games, seed=seed, batch=batch, scenario=scenario, deterministic=deterministic)


RESULTS = "crossplay.json"
HEATMAP = "crossplay.png"


def default_out(task: str, verb: str) -> Path:
    import time

    return Path("outputs") / verb / f"{time.strftime('%Y-%m-%d_%H-%M-%S')}_{task}"


def setup(args, options: type[PlayOptions] = CrossplayOptions, min_competitors: int = 2, games: int | None = None):
    """(competitors, specs, options, config) of a cross-play command line, all validated; ``games``: the
    games per pair when given (``eval elo`` plays its rounds), else ``options``' own (None: none played)."""
    specs, opts, overrides = split_args(args, options)
    if len(specs) < min_competitors:
        raise ConfigError(f"cross-play needs at least {min_competitors} competitors; got {len(specs)} ({' '.join(specs) or 'none'})")
    games = games if games is not None else getattr(opts, "games", None)
    if games is not None and games % 2:  # (>= 2: the option's range)
        raise ConfigError(f"games={games} must be an even number >= 2 (each side plays half of them)")
    if getattr(opts, "reuse", None) is not None:
        check_readable(opts.reuse)
    if "pool" in opts.given:  # (the name is the option's choice; ray's install and cluster are checked here)
        from volleybots.play.pool import check_pool

        check_pool(opts.pool, "pool")
    comps = resolve_all(specs)
    cfg = match_config(comps, overrides)
    check_scenario(opts.scenario, cfg)
    if games is not None:  # absurd counts are refused here, before any game
        check_play(cfg, games, len(comps) * (len(comps) - 1) // 2, getattr(opts, "batch", DEFAULT_BATCH))
    return comps, specs, opts, cfg


def run_crossplay(args, out: Path | None = None, progress=None, verb: str = "crossplay") -> tuple[CrossPlay, Path]:
    """``volleybots eval crossplay``: validate, play every pair, write the results JSON and the heatmap.

    Args:
        args: the command's words: competitors and ``key=value`` options (``games=``, ``seed=``,
            ``task=``, ``scenario=``, ...).
        out: the output directory; ``None`` picks one under ``outputs/``.
        progress: called as ``progress(i, j, games)`` after each pair.
        verb: the verb, naming the default output directory.

    Returns:
        ``(result, directory)``: the ``CrossPlay`` and where its files were written.
    """
    from volleybots.runs import output_dir

    comps, specs, opts, cfg = setup(args)
    with output_dir(out, default_out(cfg.task.name, verb)) as path:  # claimed and locked before the games
        res = play_and_save(comps, specs, opts, cfg, path, progress)
    return res, path


def play_and_save(comps, specs, opts: PlayOptions, cfg, path: Path, progress=None, games: int | None = None) -> CrossPlay:
    """Play the cross-play ``setup`` validated (``games`` per pair when given, else ``opts.games``) and
    write its results and heatmap into ``path``."""
    res = crossplay(
        cfg, comps, games if games is not None else opts.games, seed=opts.seed, batch=opts.batch, scenario=opts.scenario,
        deterministic=opts.deterministic, specs=specs, progress=progress, reuse=opts.reuse, pool=opts.pool,
    )
    res.save(path / RESULTS)
    heatmap(res, path / HEATMAP)
    return res
