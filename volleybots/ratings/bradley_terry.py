"""Bradley-Terry ratings: P(i beats j) = 1 / (1 + exp(s_j - s_i)), strengths s by Firth-penalised
maximum likelihood (scipy's BFGS on the exact gradient), with penalised profile-likelihood
intervals.

Choices (docs/evaluation.md): draws are left out, the fit uses decisive games only (``draws="decisive"``,
the default), and callers report each competitor's draw rate beside. Counting a draw as half a win
(``draws="half"``) rated a player that draws most games and never wins above players that beat it in
every decisive game (3v3: ``random``, 70-80 % draws, above two learned teams): with decisive games a
player without a win has no evidence of strength against anyone. Strengths are reported on the Elo
scale (1000 + 400 / ln 10 x s, mean 1000), so a BT gap reads like an Elo gap.

Why Firth and a profile: cross-play is often *separable*: scripted wins every decisive game against
random, and a short cross-play leaves some pair 10-0. The plain likelihood then has no maximum, and a
bootstrap that resamples the record repeats 10-0 in every resample, so its interval has zero width
and covers a true 400-point gap at 10 games only about 60 % of the time. Firth's penalty, half the
log-determinant of the Fisher information (the Jeffreys prior), keeps the estimate finite and
removes most of the small-sample bias (for two players w wins of n it is the logit of
(w + 0.5) / (n + 1)). The interval of each rating is where twice the drop of the penalised
log-likelihood, maximised over the other strengths, stays under the chi-square(1) quantile (3.84 for
95 %), the interval logistf gives in logistic regression (Heinze and Schemper 2002); it stays wide on
the unbounded side of an unbeaten record and covers at about its nominal rate (tests/test_ratings.py).

A weak Gaussian prior on s (``prior_sd`` logits, default 10, about 1740 Elo points) is kept beside
the penalty: it ties together competitors that never met, directly or through others (the
likelihood says nothing about their relative strength), and moves connected ratings by a hair.
"""

from __future__ import annotations

import math

# scipy's submodules load on first use: every training process imports this module (its games keep
# records), and scipy.stats alone takes about 1.6 s to import, paid only by those that rate
import numpy as np
import scipy

from volleybots.ratings.record import points

ELO_SCALE = 400.0 / math.log(10.0)
PRIOR_SD = 10.0
_MAX_LOGITS = 200.0  # an interval end beyond this (35,000 Elo points) is reported as that: only the prior bounds it


DRAWS = ("decisive", "half")  # draws left out (the default), or half a win for each side


def half_win_matrix(wdl) -> np.ndarray:
    """[n, n] wins of the row over the column, a draw counting half."""
    return points(wdl)


def win_matrix(wdl, draws: str = "decisive") -> np.ndarray:
    """[n, n] wins of the row over the column: decisive games only, or a draw counting half."""
    if draws not in DRAWS:
        raise ValueError(f"draws={draws!r}; allowed: {', '.join(DRAWS)}")
    return half_win_matrix(wdl) if draws == "half" else np.asarray(wdl, float)[..., 0]


class _Objective:
    """The negative penalised log-likelihood of strengths s [n] and its gradient."""

    def __init__(self, wins: np.ndarray, prior_sd: float, firth: bool):
        self.wins, self.prior_var, self.firth = wins, prior_sd**2, firth
        self.games = wins + wins.T
        # the likelihood fixes strengths only up to a shift per connected group of competitors; the
        # projector onto each group's constant vector completes the Fisher information to full rank
        # without changing its determinant on what the data identify
        _, group = scipy.sparse.csgraph.connected_components(self.games > 0, directed=False)
        same = group[:, None] == group[None, :]
        self.proj = same / same.sum(1, keepdims=True)

    def __call__(self, s: np.ndarray) -> tuple[float, np.ndarray]:
        x = s[:, None] - s[None, :]  # x[i, j] = s_i - s_j
        loss = -np.sum(self.wins * scipy.special.log_expit(x)) + 0.5 * np.sum(s * s) / self.prior_var
        g = self.wins * scipy.special.expit(-x)  # d(-log P(i beats j)) / d s_j, and minus that for s_i
        grad = g.sum(0) - g.sum(1) + s / self.prior_var
        if self.firth:
            pq = np.exp(scipy.special.log_expit(x) + scipy.special.log_expit(-x))
            w = np.maximum(self.games * pq, 1e-300 * (self.games > 0))  # underflow would make the information singular
            info = np.diag(w.sum(1)) - w + self.proj
            _, logdet = np.linalg.slogdet(info)
            a = np.linalg.inv(info)
            d = np.diag(a)
            resistance = d[:, None] + d[None, :] - 2.0 * a  # d logdet / d w_ij
            dw = self.games * pq * np.tanh(-x / 2.0)  # d w_ij / d s_i, (1 - 2p) = tanh(-x / 2)
            loss -= 0.5 * logdet
            grad -= 0.5 * np.sum(resistance * dw, axis=1)
        return float(loss), grad


def _minimise(f, x0: np.ndarray) -> tuple[np.ndarray, float]:
    res = scipy.optimize.minimize(f, x0, jac=True, method="BFGS", options={"maxiter": 2000, "gtol": 1e-9})
    return res.x, float(res.fun)


def _check(wdl, draws: str = "decisive") -> np.ndarray:
    wdl = np.asarray(wdl, float)
    if wdl.ndim != 3 or wdl.shape[0] != wdl.shape[1] or wdl.shape[2] != 3:
        raise ValueError(f"game counts must be [n, n, 3] (wins, draws, losses of the row), got shape {wdl.shape}")
    if not np.isfinite(wdl).all() or (wdl < 0).any():
        raise ValueError("game counts must be finite and >= 0")
    return win_matrix(wdl, draws)


def bradley_terry(wdl, prior_sd: float = PRIOR_SD, firth: bool = True, draws: str = "decisive") -> np.ndarray:
    """Ratings [n] on the Elo scale (mean 1000) from the game counts ``wdl`` [n, n, 3] (``draws``: left
    out, or half a win each).

    ``firth=False`` gives the plain maximum-a-posteriori fit under the weak prior alone (the fit
    choix's ``opt_pairwise`` computes with ``alpha = 1 / (2 prior_sd^2)``)."""
    wins = _check(wdl, draws)
    s, _ = _minimise(_Objective(wins, prior_sd, firth), np.zeros(wins.shape[0]))
    return 1000.0 + ELO_SCALE * (s - s.mean())


def draw_dispersion(wdl, s) -> float:
    """The variance of a game's score (1, 1/2, 0) over the binomial variance the half-win likelihood
    assumes, pooled over all games at strengths ``s``: a game of half-win probability p with draw
    probability d has variance p q - d / 4, not p q, so the likelihood understates what draws tell
    and its intervals would be too wide. 1 without draws; floored at 0.1 so that a record of nearly
    all draws cannot shrink an interval to a point (the quasi-likelihood dispersion of McCullagh and
    Nelder, estimated from the draws alone: estimating it from the wins as well would make it near 0
    on an unbeaten record)."""
    wdl = np.asarray(wdl, float)
    iu = np.triu_indices(wdl.shape[0], 1)
    x = (s[:, None] - s[None, :])[iu]
    pq = np.exp(scipy.special.log_expit(x) + scipy.special.log_expit(-x))
    binomial = float(np.sum(wdl[iu].sum(-1) * pq))
    draws = float(np.sum(wdl[iu][:, 1]))
    if draws == 0 or binomial <= 0:
        return 1.0
    return float(np.clip(1.0 - draws / 4.0 / binomial, 0.1, 1.0))


def bradley_terry_intervals(wdl, confidence: float = 0.95, prior_sd: float = PRIOR_SD, draws: str = "decisive"):
    """(ratings [n], low [n], high [n]) on the Elo scale: the Firth-penalised fit and, for every
    competitor, the penalised profile-likelihood interval of its rating (its strength minus the
    mean strength), at ``confidence``. With draws the allowed drop of the log-likelihood is scaled by
    ``draw_dispersion`` (draws make a game's score less variable than a win or a loss) when they count
    half; left out, they change nothing."""
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence={confidence} must be in (0, 1)")
    wins = _check(wdl, draws)
    n = wins.shape[0]
    f = _Objective(wins, prior_sd, firth=True)
    s_hat, f_hat = _minimise(f, np.zeros(n))
    theta = s_hat - s_hat.mean()
    lo, hi = theta.copy(), theta.copy()
    if n > 1:
        limit = scipy.stats.chi2.ppf(confidence, 1) / 2.0 * (draw_dispersion(wdl, s_hat) if draws == "half" else 1.0)
        for i in range(n):
            rest = np.arange(n) != i
            warm = [s_hat[rest]]

            def drop(c, i=i, rest=rest, warm=warm):
                """Half the profile deviance at theta_i = c, minus its allowed value (< 0 inside)."""

                def constrained(u):
                    s = np.empty(n)
                    s[rest] = u
                    s[i] = (n * c + u.sum()) / (n - 1)  # the s_i with s_i - mean(s) = c
                    val, g = f(s)
                    return val, g[rest] + g[i] / (n - 1)

                u, val = _minimise(constrained, warm[0])
                warm[0] = u
                return val - f_hat - limit

            for sign, out in ((-1.0, lo), (1.0, hi)):
                warm[0] = s_hat[rest]
                step, inside = 0.5, theta[i]
                while step <= _MAX_LOGITS and drop(theta[i] + sign * step) < 0:
                    inside, step = theta[i] + sign * step, 2.0 * step
                if step > _MAX_LOGITS:
                    out[i] = theta[i] + sign * _MAX_LOGITS
                else:
                    out[i] = scipy.optimize.brentq(drop, *sorted((inside, theta[i] + sign * step)), xtol=1e-6)
    return 1000.0 + ELO_SCALE * theta, 1000.0 + ELO_SCALE * lo, 1000.0 + ELO_SCALE * hi
