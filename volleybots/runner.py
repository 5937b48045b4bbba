"""What `volleybots train` starts: a learner's run loop (``volleybots.train``) or, for the population
methods (``sp``, ``fsp``, ``psro_*``), the population loop (``volleybots.population.loop``) over it."""

from __future__ import annotations

from volleybots.algos import ALGOS


def is_population(cfg) -> bool:
    return bool(getattr(ALGOS[cfg.algo.name], "population", False))


def start(cfg, run_dir) -> dict:
    """Start a new run of the validated config ``cfg`` in ``run_dir``."""
    if is_population(cfg):
        from volleybots.population.loop import start as start_population
        from volleybots.runs import unlock

        try:
            return start_population(cfg, run_dir)
        finally:
            unlock(run_dir)  # taken by RunDir.create
    from volleybots.train import train

    return train(cfg, run_dir)


def resume(run_dir, overrides=()) -> dict:
    """Continue the run in ``run_dir`` (``train resume=DIR``)."""
    from volleybots.runs import RunDir
    from volleybots.train import resume as resume_learner

    if not is_population(RunDir(run_dir).load_config()):
        return resume_learner(run_dir, overrides)
    from volleybots.population.loop import resume as resume_population

    return resume_population(run_dir, overrides)
