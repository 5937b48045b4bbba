"""Training a learner: ``train`` starts a run, ``resume`` continues one (``volleybots train``).

Modules: ``trainer`` (the run loop every algorithm shares), ``init`` (``init=``: start from another
run's networks), ``wandb`` (the optional W&B mirror). Population presets (``sp``, ``fsp``, ``psro_*``)
run the population loop over this trainer: ``volleybots.population.start`` dispatches.
"""

from __future__ import annotations

from contextlib import contextmanager

from volleybots.algos import population_of
from volleybots.config import apply_overrides, check_memory, to_dict
from volleybots.errors import ConfigError
from volleybots.play.episodes import collect, finished_stats
from volleybots.play.seats import AllAgents, SelfPlay, Versus, default_seat
from volleybots.policies.targets import check_references
from volleybots.runs import RunDir, check_writable, locked, memory_errors_as, read_checkpoint
from volleybots.train.init import apply_init, check_init, init_checkpoint, learner_spec
from volleybots.train.trainer import EVAL_SEED_OFFSET, RESUME_KEYS, Trainer, write_summary


def preflight(cfg) -> None:
    """Everything a start checks before writing: memory, the files the config names, ``init=``.

    (A population run gives each learner ``init=`` its clone itself, in configs that skip this.)"""
    pop = population_of(cfg)
    if pop is not None and pop.learner_init == "bc" and cfg.get("init") is not None:
        raise ConfigError(f"init={cfg.init!r} and population.learner_init=bc both say where learners start; give one "
                          f"(population.learner_init=scratch with init=, or no init=)")
    check_memory(cfg)
    check_references(cfg)
    check_init(cfg)
    if pop is not None:
        check_payoff_games(cfg)


def check_payoff_games(cfg) -> None:
    """Before anything is written or trained: the pool the payoff games play in (a ``RAY_ADDRESS``
    nothing answers at is refused here, not after the first oracle), and ``population.payoff_games`` against
    memory for the last member's row (``population.payoff_games=1e12`` is a one-line refusal)."""
    from volleybots.config.resources import check_play
    from volleybots.play.games import DEFAULT_BATCH
    from volleybots.play.pool import check_pool

    m = population_of(cfg)
    check_pool(m.payoff_pool, "population.payoff_pool")
    check_pool(m.oracle_pool, "population.oracle_pool")
    try:
        check_play(cfg, m.payoff_games, max(1, len(m.seed_members) + m.iterations - 1), DEFAULT_BATCH)
    except ConfigError as e:
        raise ConfigError(f"population.payoff_games={m.payoff_games}: {e} (population.payoff_games)") from None


def train(cfg, run_dir, checked: bool = False, stop=None, label: str = "train") -> dict:
    """Start a new run of the validated config ``cfg`` in ``run_dir``, holding its lock while it trains
    (``checked``: the caller ran ``preflight`` already); ``stop(row)`` may end it early after a batch
    (``Trainer.train_loop``); ``label`` starts its progress lines."""
    with new_run(cfg, run_dir, checked) as run:
        return Trainer(cfg, run, label=label).fit(stop)


@contextmanager
def new_run(cfg, run_dir, checked: bool = False):
    """What every new learner run trains inside (``train``, and ``eval exploitability``'s best responses):
    ``preflight`` unless ``checked``, the run dir's config written and its lock held, an out-of-memory
    error as one line naming the counts. Yields the ``RunDir``."""
    if not checked:
        preflight(cfg)
    run = RunDir(run_dir)
    with run.new_run(cfg), memory_errors_as(_counts(cfg)):
        yield run


def resume_config(run_dir, overrides=(), keys=RESUME_KEYS):
    """The saved config of the run in ``run_dir`` with the overrides a resume may make (``keys``)."""
    base = RunDir(run_dir).load_config()
    return apply_overrides(to_dict(base), overrides, keys, f"run {str(run_dir)!r} (resume)")


def resume(run_dir, overrides=(), label: str = "train") -> dict:
    """Continue the run in ``run_dir`` from its latest checkpoint (``train resume=DIR``); a run killed
    before its first checkpoint starts afresh, saying so.

    Everything is checked before anything is written (the config and overrides, the checkpoint
    against the run's task and networks, metrics.csv, memory); the run's lock is then taken, so a
    second resume of the same run is refused."""
    if not str(run_dir).strip():
        raise ConfigError("resume= needs a run directory: resume=RUN_DIR")
    run = RunDir(run_dir)
    cfg = resume_config(run_dir, overrides)
    check_writable(run.path, "the run directory")
    run.check_contained()
    ckpt = run.latest_checkpoint()
    stamp = run.checkpoint_stamp()
    if ckpt is not None:
        done = int(read_checkpoint(ckpt)["frames"])
        if done >= cfg.total_frames:
            raise ConfigError(
                f"run {str(run_dir)!r} already has {done} frames >= total_frames={cfg.total_frames}; raise total_frames to continue it"
            )
        run.check_metrics()
    else:
        run.check_clearable()
    check_memory(cfg)
    check_references(cfg)
    with memory_errors_as(_counts(cfg)):
        trainer = Trainer(cfg, run, checkpoint=ckpt, label=label)  # a checkpoint that does not fit the run fails here
        with locked(run.path):
            if run.checkpoint_stamp() != stamp:
                raise ConfigError(f"run {str(run_dir)!r} was trained by another process while this one checked it; run the command again")
            if ckpt is None:
                run.clear_unfinished()
            run.write_config(cfg)
            return trainer.fit()


def _counts(cfg) -> str:
    """The config's counts that decide the memory a run takes, for an out-of-memory message."""
    buffer = f", algo.buffer_size={cfg.algo.buffer_size}" if "buffer_size" in cfg.algo else ""
    return (
        f"env.num_envs={cfg.env.num_envs}, algo.steps_per_batch={cfg.algo.steps_per_batch}, "
        f"evaluation.episodes={cfg.evaluation.episodes}{buffer}"
    )

__all__ = [
    "AllAgents", "EVAL_SEED_OFFSET", "RESUME_KEYS", "SelfPlay", "Trainer", "Versus", "apply_init", "check_init", "collect", "default_seat",
    "check_payoff_games", "finished_stats", "init_checkpoint", "learner_spec", "new_run", "preflight", "resume", "resume_config", "train",
    "write_summary",
]
