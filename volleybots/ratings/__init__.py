"""Ratings of competitors from games between them (docs/evaluation.md).

Small pure functions over numpy arrays, usable without the CLI or the env:

* ``wilson_interval``: a 95 % interval for a win rate (``intervals``);
* ``elo`` and its round-robin game schedules: the paper's sequential Elo (``elo``);
* ``bradley_terry`` and ``bradley_terry_intervals``: Firth-penalised maximum-likelihood strengths
  with penalised profile-likelihood intervals, honest on unbeaten records (``bradley_terry``).

Game results come in one layout everywhere: ``wdl`` [n, n, 3], the wins, draws and losses of the
row competitor against the column one (so ``wdl[j, i] == wdl[i, j, ::-1]``).
"""

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
    "round_robin",
    "sample_round_robin",
    "wilson_interval",
]
