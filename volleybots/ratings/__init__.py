"""The game theory of the package: ratings of competitors from games between them, the payoff tables
and meta-solvers of populations (docs/evaluation.md, docs/competitive.md). A leaf: it imports nothing
of volleybots but other leaves, and never torch (tests/project/test_architecture.py holds it to that).

Small pure functions over numpy arrays, usable without the CLI or the env:

* ``record``: the one layout of game results and its arithmetic (decisive games, win rates,
  zero-sum payoffs, the other side's view);
* ``wilson_interval``: a 95 % interval for a win rate (``intervals``);
* ``elo`` and its round-robin game schedules: the paper's sequential Elo (``elo``);
* ``bradley_terry`` and ``bradley_terry_intervals``: Firth-penalised maximum-likelihood strengths
  with penalised profile-likelihood intervals, honest on unbeaten records (``bradley_terry``);
* ``payoffs.PayoffTable``: a population's W/D/L counts per ordered pair and its zero-sum payoff matrix;
* ``solvers.SOLVERS``: the meta-solvers (uniform, Nash by linear programming, last) over such a matrix.
* ``methods.RATINGS``: the rating methods of ``eval elo`` (Elo, Bradley-Terry, average win rate, Nash),
  each with its table columns and what it draws.

Game results come in one layout everywhere (``record``): a count array whose last axis is the wins,
draws and losses, ``wdl`` [n, n, 3] for the row competitor against the column one (so
``wdl[j, i] == record.flip(wdl[i, j])``).
"""

from volleybots.ratings import record
from volleybots.ratings.bradley_terry import bradley_terry, bradley_terry_intervals, half_win_matrix
from volleybots.ratings.elo import ELO_K, ELO_START, elo, elo_history, expected_score, round_robin, sample_round_robin
from volleybots.ratings.intervals import wilson_interval

__all__ = [
    "ELO_K",
    "ELO_START",
    "bradley_terry",
    "bradley_terry_intervals",
    "elo",
    "elo_history",
    "expected_score",
    "half_win_matrix",
    "record",
    "round_robin",
    "sample_round_robin",
    "wilson_interval",
]
