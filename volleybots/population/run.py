"""What ``volleybots train`` starts: a population preset (``sp``, ``fsp``, ``psro_*``) runs the population
loop over the trainer; any other algorithm the trainer alone."""

from __future__ import annotations

from volleybots.algos import is_population as _is_population
from volleybots.runs import RunDir


def is_population(cfg) -> bool:
    """Whether the run config ``cfg`` trains a population (it has a ``population`` node)."""
    return _is_population(cfg)


def start(cfg, run_dir, checked: bool = False) -> dict:
    """Start a new run of the validated config ``cfg`` in ``run_dir`` (``checked``: the caller ran
    ``volleybots.train.preflight`` already)."""
    from volleybots.train import preflight, train

    if not is_population(cfg):
        return train(cfg, run_dir, checked=checked)
    from volleybots.population.loop import start as start_population

    if not checked:
        preflight(cfg)
    return start_population(cfg, run_dir)


def resume(run_dir, overrides=()) -> dict:
    """Continue the run in ``run_dir`` (``train resume=DIR``)."""
    from volleybots.train import resume as resume_learner

    if not is_population(RunDir(run_dir).load_config()):
        return resume_learner(run_dir, overrides)
    from volleybots.population.loop import resume as resume_population
    from volleybots.train import check_payoff_games

    return resume_population(run_dir, overrides, check=check_payoff_games)


__all__ = ["is_population", "resume", "start"]
