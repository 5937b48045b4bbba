"""The oracle's stopping rule, shared by the population loop's oracles and exploitability's best responses."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class Convergence:
    """The oracle's stopping rule: the win rate over the last ``window`` batches has mean >= ``mean``
    and std <= ``std`` after ``min_updates`` updates, or ``max_updates`` updates are done. With
    ``early=False`` the criterion never stops the run (a best response of a fixed budget); it is still
    judged on the last window."""

    min_updates: int
    max_updates: int
    window: int
    mean: float
    std: float
    early: bool = True
    updates: int = 0
    win_rates: list[float] = field(default_factory=list)

    def __call__(self, row: dict) -> bool:
        self.updates += 1
        w = row.get("win", math.nan)
        if w is not None and not math.isnan(w):
            self.win_rates.append(float(w))
        return self.updates >= self.max_updates or (self.early and self.updates >= self.min_updates and self.converged)

    @property
    def recent(self) -> np.ndarray:
        return np.asarray(self.win_rates[-self.window:], dtype=float)

    @property
    def converged(self) -> bool:
        r = self.recent
        return len(r) == self.window and r.mean() >= self.mean and r.std() <= self.std

    def summary(self) -> dict:
        """What the oracle reached: ``win_rate`` is its final win rate (the mean over the last ``window``
        batches, the figure the criterion judges; ``win_mean`` the same, kept for older readers), and
        ``stopped`` says why it stopped: ``converged``, ``max_updates``, or ``budget`` (the run's
        total_frames or time_limit ran out first)."""
        r = self.recent
        win = float(r.mean()) if len(r) else None
        stopped = "converged" if self.early and self.converged else "max_updates" if self.updates >= self.max_updates else "budget"
        return {
            "updates": self.updates,
            "converged": bool(self.converged),
            "stopped": stopped,
            "win_rate": win,
            "win_mean": win,
            "win_std": float(r.std()) if len(r) else None,
        }

    def state_dict(self) -> dict:
        return {"updates": self.updates, "win_rates": list(self.win_rates)}

    def load_state_dict(self, state: dict) -> None:
        self.updates, self.win_rates = int(state["updates"]), [float(w) for w in state["win_rates"]]
