"""A population run's final evaluation: its final mixture against the fixed yardstick
(``population.eval_opponent``), as a plain run evaluates its learner at the end.

The games are ``play_games``: both sides equally often, a member drawn per game from the mixture, on
seeds of their own (the run's seed + ``EVAL_SEED_OFFSET``). The result has the trainer's summary
format (``stats``: mean and std per game of ``win``, ``loss``, ``draw``), so the tools that read a
plain run's ``final_eval`` (``volleybots report``, the benchmarks) read this one too, plus the W/D/L
and the games' content (touches, rally length, faults, serving and receiving).
"""

from __future__ import annotations

import numpy as np

from volleybots.play.games import play_games
from volleybots.policies import resolve_competitor
from volleybots.runs import MetricsLog
from volleybots.train import EVAL_SEED_OFFSET


def evaluate_mixture(cfg, mixture, opponent: str) -> dict:
    """``evaluation.episodes`` games (rounded up to even) of the ``mixture`` competitor against ``opponent``."""
    n = max(2, cfg.evaluation.episodes + cfg.evaluation.episodes % 2)
    g = play_games(cfg, mixture, resolve_competitor(opponent), n, seed=cfg.seed + EVAL_SEED_OFFSET)
    stats = {}
    for key, letter in (("win", "W"), ("loss", "L"), ("draw", "D")):
        x = np.array([o == letter for o in g.outcomes], dtype=float)
        stats[key] = {"mean": float(x.mean()), "std": float(x.std())}
    return {"metric": "win", "episodes": n, "of": "final mixture", "opponent": opponent, "stats": stats,
            "wdl": g.total.tolist(), "content": g.content()}


def log_final_eval(run, final_eval: dict, frames: int, iteration: int, wall: float) -> None:
    """The final evaluation as an ``eval`` row of metrics.csv (and so of curves.rrd)."""
    if not run.metrics_path.is_file():
        return
    win = final_eval["stats"]["win"]
    MetricsLog(run.metrics_path, keep_until_frames=frames).write(
        {"phase": "eval", "frames": frames, "iteration": iteration, "wall_time": wall, "eval_win": win["mean"], "eval_win_std": win["std"]})
