"""The best response: the one object that trains a response, for the population loop and for ``eval
exploitability`` alike (OpenSpiel's ``psro_v2`` oracle: called by the solver's loop, built apart from it).

Handed a config (seed and budget), a run dir, an opponent (a seat: ``Versus`` a competitor, or
``SelfPlay``), a stop rule (``population/convergence.py``: ``Convergence`` or ``Plateau``) and a
``Start``, it trains and returns a ``Member``: the response's checkpoint state and what its stop rule
said. Neither caller touches the trainer: its counters, resumes, warm starts and checkpoints' extra
state are the best response's business. ``BestResponse`` builds the learner the run's ``algo=`` names
(MAPPO by default, HAPPO or MAT on teams of several drones), so the members it writes hold the class
the policy store rebuilds them as; ``HighLevelResponse`` is a hierarchical population's oracle behind
the same call (a high level over the run's drills, ``population/hierarchical.py``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from volleybots.policies.store import learner_class
from volleybots.runs import read_checkpoint
from volleybots.train import SelfPlay, Trainer, default_seat, new_run


@dataclass(frozen=True)
class Start:
    """Where a response starts. ``frames``, ``updates`` and ``wall`` are the counters of the run before it
    (a population's next oracle continues them, so metrics.csv and the frame budget run on); ``members``
    the population before it (the response is written as member ``len(members)``); ``warm``: start from
    the newest of them whose networks fit (FSP's ``learner_init=last``), else from the config's ``init=``
    or scratch; ``resume``: a periodic checkpoint of this same response, continued bit for bit;
    ``iteration``: the population iteration it is, recorded in each checkpoint (None: a run of its own)."""

    frames: int = 0
    updates: int = 0
    wall: float = 0.0
    members: tuple = ()
    warm: bool = False
    resume: Path | None = None
    iteration: int | None = None


@dataclass
class Member:
    """A trained response: ``state`` its checkpoint (with ``label`` and ``oracle``, the stop rule's
    summary: what a member file holds); ``kept`` False when the stop rule could not judge it (the budget
    ended it first: no response, not to join); ``eval_wall`` its periodic evaluations' seconds;
    ``summary`` its run's summary.json (``final=True`` alone)."""

    state: dict
    kept: bool = True
    eval_wall: float = 0.0
    summary: dict | None = None


@dataclass(frozen=True)
class Presentation:
    """How a response reports while it trains (no effect on what it learns): the caller's W&B run, the
    progress line's note ``note(frames, fps)``, and columns added to every metrics row."""

    logger: object = None
    note: object = None
    row_extra: dict = field(default_factory=dict)


@dataclass(frozen=True)
class BestResponse:
    learner_cls: type | None = None  # None: the class ``ALGOS`` registers for the config's ``algo.name``

    @classmethod
    def of(cls, cfg) -> "BestResponse":
        """The best response of config ``cfg``: its learner (``algo=``)."""
        return cls(learner_class(cfg.algo))

    def __call__(self, cfg, run, opponent, stop, start: Start = Start(), label: str | None = None,
                 show: Presentation = Presentation(), final: bool = False) -> Member:
        """Train a response under ``cfg`` in ``run`` (a ``RunDir``) from ``opponent``'s seat until ``stop``
        says so or the budget ends (``stop`` None: the budget alone, self-play's whole run). ``final``: end as
        a run of its own (final evaluation, final.pt, summary.json)."""
        tag = start.iteration is not None  # a population's: its checkpoints say which iteration they are
        extra = (lambda: {"population": {"iteration": start.iteration, "oracle": stop.state_dict() if stop else None}}) if tag else None
        tr = Trainer(cfg, run, checkpoint=start.resume, seat=opponent, learner_cls=self.learner_cls, extra_state=extra, logger=show.logger)
        if start.resume is not None:
            if stop is not None:
                stop.load_state_dict(tr.checkpoint_state["population"]["oracle"])
        else:
            tr.start_at(start.frames, start.updates, start.wall)
            if start.warm:
                continue_from(tr, list(start.members))
        tr.train_loop(stop=stop, row_extra=show.row_extra or None, note=show.note)
        if final:
            summary = tr.finish({"stop": stop.summary()} if stop is not None else None)
            return Member(tr.state(), True, tr.eval_wall, summary)
        state = tr.state()
        if stop is not None and not stop.judged:
            return Member(state, False, tr.eval_wall)
        state.update(label=label or f"br{start.iteration}",
                     oracle=stop.summary() if stop is not None else {"updates": tr.iteration - start.updates, "converged": None})
        return Member(state, True, tr.eval_wall)

    def run(self, cfg, run_dir, stop) -> Member:
        """A response as a run of its own in ``run_dir`` (``eval exploitability``'s): against the config's
        ``opponent=``, checked, written and locked as ``train`` starts a run, ending with its final evaluation."""
        with new_run(cfg, run_dir) as run:
            return self(cfg, run, default_seat(cfg), stop, final=True)


def continue_from(tr: Trainer, members: list[Path]) -> Path | None:
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


@dataclass(frozen=True)
class HighLevelResponse:
    """A hierarchical population's oracle behind the best response's call: a high level over the run's
    drills (``population/hierarchical.train_member``) trained for ``population.high_level_games`` games
    against the seat's competitor, or itself from a ``SelfPlay`` seat (no stop rule: its budget is games). ``run_cfg`` is the run's config
    (the match the high level plays); the iteration config handed in gives its seed and time limit."""

    run_cfg: object

    def __call__(self, cfg, run, opponent, stop, start: Start = Start(), label: str | None = None,
                 show: Presentation = Presentation(), final: bool = False) -> Member:
        from volleybots.population.hierarchical import train_member

        left = cfg.time_limit - start.wall if self.run_cfg.time_limit else float("inf")  # the loop's limit, less the payoff games' reserve
        against = None if isinstance(opponent, SelfPlay) else opponent.opponent  # None: the high level plays itself (population=sp)
        state = train_member(self.run_cfg, run.path, run.metrics_path, start.iteration, len(start.members), against, start.frames, left,
                             cfg.seed)
        return Member(state)


__all__ = ["BestResponse", "HighLevelResponse", "Member", "Presentation", "Start", "continue_from", "fits"]
