"""What ``volleybots train`` starts: a population preset (``sp``, ``fsp``, ``psro_*``) runs the population
loop over the trainer; any other algorithm the trainer alone."""

from __future__ import annotations

from volleybots.algos import ALGOS
from volleybots.algos.population import CLONE
from volleybots.errors import ConfigError
from volleybots.policies.targets import check_references
from volleybots.runs import RunDir, unlock


def is_population(cfg) -> bool:
    return bool(getattr(ALGOS[cfg.algo.name], "population", False))


def start(cfg, run_dir) -> dict:
    """Start a new run of the validated config ``cfg`` in ``run_dir`` (locked by the caller or not)."""
    from volleybots.train import check_init, train

    if not is_population(cfg):
        return train(cfg, run_dir)
    from volleybots.population.loop import start as start_population

    if cfg.algo.learner_init == CLONE and cfg.get("init") is not None:
        raise ConfigError(f"init={cfg.init!r} and algo.learner_init=bc both say where learners start; give one "
                          f"(algo.learner_init=scratch with init=, or no init=)")
    check_references(cfg)
    check_init(cfg)
    try:
        return start_population(cfg, run_dir)
    finally:
        unlock(run_dir)  # taken by RunDir.create


def resume(run_dir, overrides=()) -> dict:
    """Continue the run in ``run_dir`` (``train resume=DIR``)."""
    from volleybots.train import resume as resume_learner

    if not is_population(RunDir(run_dir).load_config()):
        return resume_learner(run_dir, overrides)
    from volleybots.population.loop import resume as resume_population

    return resume_population(run_dir, overrides)


__all__ = ["is_population", "resume", "start"]
