"""Meta-solvers: a population's payoff table -> the mixture the next best response plays against.

Each solver is a pure function ``payoffs [n, n] -> mixture [n]`` where ``payoffs[i, j]`` is the
zero-sum payoff of member i (row) against member j, e.g. (wins - losses) / games from i's side;
``SOLVERS`` registers them by the name ``algo=`` and the population loop use:

* ``uniform``: every member equally (fictitious self-play, PSRO-uniform);
* ``nash``: the row player's maximin mixture of the zero-sum game, by linear programming with
  scipy's HiGHS (PSRO-Nash); for the symmetric meta-games of self-play it is a Nash equilibrium.
  **Ties:** a game may have many maximin mixtures (a convex set: two copies of one policy, or a
  table of draws, make every split between them optimal), and an LP solver returns whichever vertex
  of that set its pivoting reaches, which can change with the order of the members. ``nash`` returns
  the **maximum-entropy** one instead: a second step maximises the Shannon entropy over the set of
  mixtures that guarantee the game value (within ``NASH_TOL``). Entropy is strictly concave, so the
  choice is unique and does not depend on the members' order; copies of a policy share its weight
  equally, and an all-draw table gives the uniform mixture (Ortiz et al. 2007's max-entropy Nash);
* ``last``: all weight on the newest member (self-play);
* ``alpharank``: the stationary distribution of single-population alpha-rank (Omidshafiei et al.
  2019), a ranking that exists where Nash equilibria are many.

``exploitability`` and ``member_exploitability`` measure how far a mixture or each member is from
unexploitable *within* the population (what a best response among the members gains).
"""

from __future__ import annotations

from typing import Callable

import numpy as np
import scipy  # scipy.optimize loads on first use (volleybots.ratings.bradley_terry says why)

from volleybots.ratings import record

CARRIES = 0.01  # a member "carries weight" in a mixture where its weight is at least this
ALPHARANK_ALPHA = 10.0  # selection intensity: large alpha ranks by who beats whom, not by how much
ALPHARANK_POP = 50  # the population size m of alpha-rank's Moran process
NASH_TOL = 1e-10  # a mixture guaranteeing the game value up to this counts as maximin (LP round-off)
NASH_ZERO = 1e-7  # weights below this after the entropy step are the slack's, not a tie's: set to 0


def _square(payoffs) -> np.ndarray:
    a = np.asarray(payoffs, dtype=float)
    if a.ndim != 2 or a.shape[0] != a.shape[1] or a.shape[0] == 0:
        raise ValueError(f"payoffs must be a non-empty square matrix; got shape {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError("payoffs must be finite")
    return a


def uniform(payoffs) -> np.ndarray:
    n = _square(payoffs).shape[0]
    return np.full(n, 1.0 / n)


def last(payoffs) -> np.ndarray:
    n = _square(payoffs).shape[0]
    out = np.zeros(n)
    out[-1] = 1.0
    return out


def nash_with_value(payoffs) -> tuple[np.ndarray, float]:
    """The row player's maximin mixture x and the game value v: maximise v subject to
    (x^T A)_j >= v for every column j, sum x = 1, x >= 0."""
    a = _square(payoffs)
    n = a.shape[0]
    c = np.zeros(n + 1)
    c[-1] = -1.0  # minimise -v
    a_ub = np.hstack((-a.T, np.ones((n, 1))))  # v - (x^T A)_j <= 0
    a_eq = np.hstack((np.ones((1, n)), np.zeros((1, 1))))
    bounds = [(0.0, None)] * n + [(None, None)]
    res = scipy.optimize.linprog(c, A_ub=a_ub, b_ub=np.zeros(n), A_eq=a_eq, b_eq=[1.0], bounds=bounds, method="highs")
    if res.status != 0:
        raise RuntimeError(f"the Nash linear program failed: {res.message}")
    x = np.clip(res.x[:n], 0.0, None)
    return x / x.sum(), float(res.x[-1])


def nash(payoffs) -> np.ndarray:
    """The maximum-entropy maximin mixture (the module's docstring: ties)."""
    x, v = nash_with_value(payoffs)
    return max_entropy(_square(payoffs), v, x)


def max_entropy(a: np.ndarray, value: float, start: np.ndarray) -> np.ndarray:
    """The mixture of largest entropy among those with (x^T A)_j >= value - NASH_TOL for every column
    j (the maximin set), from the LP's solution ``start`` (which is in it).

    The largest-entropy mixture weights every member that some maximin mixture weights (the entropy's
    slope is infinite at 0), so that support is found first, by one LP per member maximising its weight
    over the set: the mean of those solutions lies inside the set on that support, and SLSQP climbs
    from there over the support alone, where the entropy is smooth. Whatever SLSQP reports, its answer
    is kept when it stays in the set and has the larger entropy; a failure never falls back to a vertex
    the LP happened to reach, which would change with the members' order."""
    n = a.shape[0]
    if n == 1:
        return np.ones(1)
    floor = value - NASH_TOL
    points = [start]
    for i in range(n):
        if start[i] > NASH_ZERO:
            continue
        c = np.zeros(n)
        c[i] = -1.0
        res = scipy.optimize.linprog(c, A_ub=-a.T, b_ub=np.full(n, -floor), A_eq=np.ones((1, n)), b_eq=[1.0],
                                     bounds=[(0.0, None)] * n, method="highs")
        if res.status == 0 and res.x[i] > NASH_ZERO:
            points.append(np.clip(res.x, 0.0, None))
    x0 = np.mean(points, axis=0)
    support = x0 > NASH_ZERO / n
    x0 = np.where(support, x0, 0.0)
    x0 /= x0.sum()
    s = a[support]  # rows of the supported members: the constraints are over every column still

    def neg_entropy(x):
        x = np.clip(x, 1e-300, None)
        return float(np.sum(x * np.log(x)))

    def grad(x):
        return np.log(np.clip(x, 1e-300, None)) + 1.0

    def feasible(x) -> bool:
        return bool(x.sum() > 0 and (s.T @ (x / x.sum())).min() >= value - 1e-6)

    best = x0[support]
    k = int(support.sum())
    if k > 1:
        cons = [{"type": "ineq", "fun": lambda x: s.T @ x - floor, "jac": lambda x: s.T},
                {"type": "eq", "fun": lambda x: np.sum(x) - 1.0, "jac": lambda x: np.ones((1, k))}]
        res = scipy.optimize.minimize(neg_entropy, best, jac=grad, bounds=[(0.0, 1.0)] * k, constraints=cons, method="SLSQP",
                                      options={"maxiter": 1000, "ftol": 1e-14})
        x = np.clip(res.x, 0.0, None)
        if feasible(x) and neg_entropy(x / x.sum()) <= neg_entropy(best):
            best = x / x.sum()
    out = np.zeros(n)
    out[support] = best
    out = np.where(out < NASH_ZERO, 0.0, out)
    return out / out.sum()


def alpharank(payoffs, alpha: float = ALPHARANK_ALPHA, m: int = ALPHARANK_POP) -> np.ndarray:
    """Single-population alpha-rank of a symmetric game: a Markov chain over the members in which a
    mutant j takes over a population of i with the Moran fixation probability of fitness gap
    f = A[j, i] - A[i, j]; the mixture is the chain's stationary distribution."""
    a = _square(payoffs)
    n = a.shape[0]
    if n == 1:
        return np.ones(1)
    gap = a.T - a  # gap[i, j] = A[j, i] - A[i, j]: what mutant j gains over resident i
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        x = alpha * gap
        fix = np.where(np.abs(x) < 1e-12, 1.0 / m, -np.expm1(-x) / -np.expm1(-m * x))
    fix = np.nan_to_num(fix, nan=0.0, posinf=1.0)
    chain = fix / (n - 1)
    np.fill_diagonal(chain, 0.0)
    np.fill_diagonal(chain, 1.0 - chain.sum(1))
    w, v = np.linalg.eig(chain.T)
    pi = np.abs(np.real(v[:, np.argmin(np.abs(w - 1.0))]))
    return pi / pi.sum()


SOLVERS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "uniform": uniform,
    "nash": nash,
    "last": last,
    "alpharank": alpharank,
}


def nash_sensitivity(wdl, resamples: int, seed: int = 0) -> dict:
    """How much the Nash mixture rests on the payoff table's noise: each pair's W/D/L of ``wdl`` [n, n, 3]
    redrawn (multinomial at its observed frequencies and game count) ``resamples`` times, the mixture
    solved again, and for each competitor how often it carries weight (>= ``CARRIES``) and its mean weight."""
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


def exploitability(payoffs, mixture) -> float:
    """What the best pure member gains against ``mixture`` over the mixture itself:
    max_i (A sigma)_i - sigma^T A sigma (0 for a Nash mixture of a symmetric zero-sum game)."""
    a = _square(payoffs)
    s = np.asarray(mixture, float)
    return float(np.max(a @ s) - s @ a @ s)


def member_exploitability(payoffs) -> np.ndarray:
    """[n]: for each member i, max_j A[j, i] - A[i, i] over every member j, i itself included: what
    the best response to i *within the population* gains against it beyond what i gets against
    itself (the exploitability within the population of docs/evaluation.md).

    i is a candidate because exploitability, max over pi' of U(pi', pi) - U(pi, pi), maximises over
    every policy, pi among them: it is never below 0, and 0 means no member does better against i
    than i itself, as for a member that beats all others. Leaving i out would make such a member's
    figure negative (minus its smallest margin), a margin of victory rather than an exploitability."""
    a = _square(payoffs)
    return a.max(0) - np.diag(a)


__all__ = ["SOLVERS", "alpharank", "exploitability", "last", "max_entropy", "member_exploitability", "nash", "nash_sensitivity",
           "nash_with_value", "uniform"]
