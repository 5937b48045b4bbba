"""The run directory: resolved config, metrics.csv, checkpoints, summary.json, recordings.

Layout of a run::

    config.yaml            the resolved, validated config (what `train resume=` and `eval` read)
    metrics.csv            one row per training batch, plus rows of the periodic evaluations
    checkpoints/           ckpt_<frames>.pt (the last `checkpoint.keep`), final.pt and best.pt (the
                           policy at the best evaluation; for `eval` and `init=`, never resumed from)
    summary.json           frames, wall time, final evaluation, checkpoints
    curves.rrd             the training curves as a rerun recording (rebuilt from metrics.csv by volleybots.replay)
    eval_<frames>.rrd      one recorded evaluation episode per periodic evaluation
    .hydra/                Hydra's own record of the overrides (when started by `volleybots train`)
    .lock                  locked (``fcntl.flock``) by the process training in the directory

A directory whose run wrote no checkpoint (killed or crashed early) holds nothing worth keeping: a new
run or ``resume=`` starts it afresh. Checkpoints hold tensors, numbers, strings and plain containers
only, so that ``torch.load(path, weights_only=True)`` reads them.

Persistence only: ``rundir`` (RunDir, checkpoints, claiming a directory), ``contents`` (a run's
policies and population, checked against what the run says it holds), ``metrics`` (metrics.csv),
``locks`` (the directory lock, writable paths, out-of-memory as one line).
"""

from volleybots.runs.contents import (
    META_FILE,
    Population,
    is_population_run,
    member_path,
    population_members,
    read_metas,
    read_population,
    run_policy_checkpoint,
)
from volleybots.runs.locks import (
    LOCK_NAME,
    InUseError,
    check_writable,
    lock,
    locked,
    make_dir,
    memory_errors_as,
    note,
    output_dir,
    reserve_file,
    unlock,
)
from volleybots.runs.metrics import MetricsLog, read_metrics, wall_at
from volleybots.runs.rundir import (
    CKPT_FORMAT,
    POPULATION_DIR,
    RunDir,
    claim_run_dir,
    config_problem,
    load_algo_state,
    read_checkpoint,
    refuse_interpolation,
)

__all__ = [
    "CKPT_FORMAT", "LOCK_NAME", "META_FILE", "POPULATION_DIR", "Population", "is_population_run", "member_path", "population_members",
    "read_metas", "read_population", "refuse_interpolation", "run_policy_checkpoint", "InUseError", "MetricsLog", "RunDir",
    "check_writable", "claim_run_dir", "config_problem", "load_algo_state", "lock",
    "locked", "make_dir", "memory_errors_as", "note", "output_dir", "reserve_file", "read_checkpoint", "read_metrics", "unlock", "wall_at",
]
