"""Meta-solvers: ``payoffs [n, n]`` (the row player's zero-sum payoff) -> a mixture over the n members."""

from __future__ import annotations

import numpy as np
from scipy.optimize import linprog


def uniform(payoffs: np.ndarray) -> np.ndarray:
    n = len(payoffs)
    return np.full(n, 1.0 / n)


def last(payoffs: np.ndarray) -> np.ndarray:
    """Self-play: all weight on the newest member."""
    out = np.zeros(len(payoffs))
    out[-1] = 1.0
    return out


def nash(payoffs: np.ndarray) -> np.ndarray:
    """The row player's maximin mixture of the zero-sum game (HiGHS LP): max v s.t. x^T A >= v, sum x = 1."""
    a = np.asarray(payoffs, dtype=float)
    n, m = a.shape
    c = np.zeros(n + 1)
    c[-1] = -1.0
    res = linprog(c, A_ub=np.hstack([-a.T, np.ones((m, 1))]), b_ub=np.zeros(m), A_eq=[[1.0] * n + [0.0]], b_eq=[1.0],
                  bounds=[(0, None)] * n + [(None, None)], method="highs")
    x = np.clip(res.x[:n], 0.0, None)
    return x / x.sum()


SOLVERS = {"uniform": uniform, "nash": nash, "last": last}
