"""A best response's stop rules: one interface (``StopRule``), two rules.

``Convergence`` is the population loop's: an oracle stops once its win rate over a window has reached a
level and settled (or at ``max_updates``). ``Plateau`` is ``eval exploitability``'s: a response stops once
its win rate has stopped rising, whatever its level (a level would censor every figure near it). The
best response (``population/oracle.py``) calls the rule after every batch with the batch's metrics row,
records ``state_dict()`` in each periodic checkpoint so a resumed response stops where the whole one
would, asks ``judged`` whether what it trained is a response at all, and reports ``summary()``.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np

from volleybots.algos.population import LoopConfig
from volleybots.ratings.best_response import plateau

WINDOW = LoopConfig().win_window  # batches a plateau window spans (the oracles' window)


@dataclass
class StopRule(ABC):
    """What every stop rule keeps: its updates and the win rates it saw (its whole resumable state)."""

    updates: int = field(default=0, kw_only=True)
    win_rates: list[float] = field(default_factory=list, kw_only=True)

    def __call__(self, row: dict) -> bool:
        """After a batch (its metrics ``row``): whether to stop now."""
        self.updates += 1
        self.record(row.get("win"))
        return self.done()

    @abstractmethod
    def record(self, win) -> None:
        """Keep this batch's win rate (None where the batch finished no episode), as the rule counts it."""

    @abstractmethod
    def done(self) -> bool:
        """Whether the win rates kept so far say stop."""

    @property
    def judged(self) -> bool:
        """Whether the response trained long enough for the rule to judge it (one that was not is no
        response: the population loop drops it)."""
        return True

    @abstractmethod
    def summary(self) -> dict:
        """What the report and the member's record say of the stop (its criterion and where it stood)."""

    def state_dict(self) -> dict:
        return {"updates": self.updates, "win_rates": list(self.win_rates)}

    def load_state_dict(self, state: dict) -> None:
        self.updates, self.win_rates = int(state["updates"]), [float(w) for w in state["win_rates"]]


@dataclass
class Convergence(StopRule):
    """The population oracle's rule: the win rate over the last ``window`` batches has mean >= ``mean``
    and std <= ``std`` after ``min_updates`` updates, or ``max_updates`` updates are done. With
    ``early=False`` the criterion never stops the run (a best response of a fixed budget); it is still
    judged on the last window."""

    min_updates: int
    max_updates: int
    window: int
    mean: float
    std: float
    early: bool = True

    def record(self, win) -> None:
        if win is not None and not math.isnan(win):  # a batch where no episode ended says nothing
            self.win_rates.append(float(win))

    def done(self) -> bool:
        return self.updates >= self.max_updates or (self.early and self.updates >= self.min_updates and self.converged)

    @property
    def judged(self) -> bool:
        return self.updates >= self.min_updates

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


@dataclass
class Plateau(StopRule):
    """``eval exploitability``'s rule: never (``early=False``, ``until=budget``), or once the training win
    rate has plateaued (``until=plateau``, ``ratings.best_response.plateau`` over two windows of
    ``window`` batches); the plateau test is judged either way and reported."""

    early: bool = False
    window: int = WINDOW

    def record(self, win) -> None:
        if win is not None:  # NaN kept: the summary's window counts batches, as the exploitability reports always have
            self.win_rates.append(float(win))

    def done(self) -> bool:
        return self.early and plateau(self.win_rates, self.window)["plateau"]

    def summary(self) -> dict:
        recent = [w for w in self.win_rates[-self.window:] if w == w]
        return {"updates": self.updates, "win_rate": sum(recent) / len(recent) if recent else None, **plateau(self.win_rates, self.window)}


__all__ = ["WINDOW", "Convergence", "Plateau", "StopRule"]
