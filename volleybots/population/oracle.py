"""The population loop's oracle: what trains a best response (OpenSpiel's ``psro_v2`` is handed its
oracle the same way). The loop decides against whom and for how long; the oracle builds the learner
that the run's ``algo=`` names (MAPPO by default, HAPPO or MAT on teams of several drones), so
the members it writes hold the class the policy store rebuilds them as."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from volleybots.policies.store import learner_class
from volleybots.runs import read_checkpoint
from volleybots.train import Trainer


@dataclass(frozen=True)
class Oracle:
    learner_cls: type

    @classmethod
    def of(cls, cfg) -> "Oracle":
        """The oracle of the population config ``cfg``: its learner (``algo=``)."""
        return cls(learner_class(cfg.algo))

    def trainer(self, cfg, run, checkpoint: Path | None, seat, extra_state, logger) -> Trainer:
        """A trainer of one learner for iteration config ``cfg``, resuming ``checkpoint`` if given."""
        return Trainer(cfg, run, checkpoint=checkpoint, seat=seat, learner_cls=self.learner_cls, extra_state=extra_state, logger=logger)

    def continue_from(self, tr: Trainer, members: list[Path]) -> Path | None:
        """Start ``tr``'s learner from the networks of the newest of ``members`` that it can hold (FSP's
        ``learner_init=last``; a seed member of another learner's shape is passed over): networks only, the
        optimiser and counters stay the learner's. Returns the member used (None: none fits)."""
        for path in reversed(members):
            state = read_checkpoint(path, device=tr.env.device)
            if "algo" in state and fits(tr.algo, state["algo"]):
                tr.algo.load_networks(state["algo"])
                return path
        return None


def fits(algo, state: dict) -> bool:
    """Whether the actor and critic weights of ``state`` have ``algo``'s names and shapes."""
    for part in ("actor", "critic"):
        mine, theirs = getattr(algo, part).state_dict(), state.get(part)
        if not isinstance(theirs, dict) or mine.keys() != theirs.keys():
            return False
        if any(tuple(mine[k].shape) != tuple(theirs[k].shape) for k in mine):
            return False
    return True


__all__ = ["Oracle", "fits"]
