"""The reliability guarantees of docs/usage.md: every numeric key has a range and a value outside it is
one line, exit code 2 and nothing written; runs started or resumed at the same time never share or
corrupt a directory; a run killed before its first checkpoint can be retried; resume checks
everything before it writes; usage errors of every verb are one line."""

from __future__ import annotations

import copy
import dataclasses
import inspect
import math
import signal
import subprocess
import sys
import time
import typing
from pathlib import Path

import pytest
import torch
from helpers import CLI_ENV, cli_cmd, snapshot, train_rows
from typer.testing import CliRunner

from volleybots.algos import ALGOS, PRESETS, is_population
from volleybots.algos.base import class_attr
from volleybots.cli import app
from volleybots.config import BenchOptions, Config, ConfigError, compose, task_schema, to_dict, validate
from volleybots.errors import Range, field_range
from volleybots.tasks import TASKS

runner = CliRunner()
STEPS, ENVS = 8, 4
FPB = STEPS * ENVS  # frames per batch
TINY = [
    f"env.num_envs={ENVS}", f"algo.steps_per_batch={STEPS}", "algo.minibatches=2", "algo.epochs=1",
    "algo.hidden=[16]", "task.episode_len=40", "threads=1", "progress=false", "evaluation.episodes=1",
    "evaluation.record=false", "evaluation.every=0",
]


def _one_line_exit_2(res, *words):
    """A CliRunner result or a CompletedProcess: exit 2, one line 'error: ...' naming ``words``."""
    code = res.exit_code if hasattr(res, "exit_code") else res.returncode
    err = res.stderr.strip()
    assert code == 2, (code, res.stdout, err)
    assert len(err.splitlines()) == 1 and err.startswith("error: ") and "Traceback" not in err, err
    for w in words:
        assert w in err, (w, err)
    return err


# ------------------------------------------------------------------------------------ the ranges
def _schemas():
    """(prefix, schema, a task it validates with, an algo) for every schema holding numeric keys."""
    out = [("", Config, "hover", "ppo")]
    methods = {**ALGOS, **PRESETS}  # algo=PRESET composes the population with its default learner
    for name, cls in methods.items():
        task = next(t for t, tc in sorted(TASKS.items()) if _fits(cls, tc))
        out.append(("population." if is_population(cls) else "algo.", cls.config_cls, task, name))
    for name in sorted(TASKS):
        out.append(("task.", task_schema(name), name, next(a for a, c in methods.items() if _fits(c, TASKS[name]))))
    return out


def _fits(algo_cls, task_cls) -> bool:
    competitive = bool(getattr(task_cls, "competitive", False))
    if is_population(algo_cls):
        return competitive
    return (algo_cls.multi_agent or class_attr(task_cls, "n_drones") == 1) and not competitive


def _numeric_fields(schema, prefix=""):
    """(key, the dataclass holding it, type) of every numeric field (int, float, lists of them,
    nested dataclasses)."""
    hints = typing.get_type_hints(schema)
    for f in dataclasses.fields(schema):
        tp = hints[f.name]
        if dataclasses.is_dataclass(tp):
            yield from _numeric_fields(tp, f"{prefix}{f.name}.")
            continue
        base = [a for a in typing.get_args(tp) if a is not type(None)] or [tp]
        base = typing.get_args(base[0]) or base  # list[int] -> int
        if base[0] in (int, float) or field_range(schema, f.name) is not None:
            yield prefix + f.name, schema, base[0]


def test_every_numeric_key_declares_its_range():
    missing = [
        f"{p}{k}"
        for p, schema, _, _ in _schemas()
        for k, owner, _ in _numeric_fields(schema)
        if field_range(owner, k.rsplit(".", 1)[-1]) is None
    ]
    assert not missing, f"numeric keys without a range (volleybots.errors.ranged / config.TASK_RANGES): {missing}"
    # the bench options are the keywords of run_bench, typed and ranged the same way
    from volleybots.bench import run_bench

    assert set(inspect.signature(run_bench).parameters) - {"progress"} == {f.name for f in dataclasses.fields(BenchOptions)}


def _outside(rng: Range, tp) -> list:
    """Values just outside ``rng`` (below, above, not finite, a wrong length)."""
    if rng.length is not None:
        return [[1.0] * (rng.length - 1), [math.nan] * rng.length]
    vals = []
    if rng.low is not None:
        vals.append(rng.low if rng.low_open else rng.low - 1)
    if rng.high is not None:
        vals.append(rng.high if rng.high_open else rng.high + 1)
    if tp is float:
        vals += [math.nan, math.inf]
    return [tp(v) if math.isfinite(v) else v for v in vals]


def _cases():
    seen = set()  # a range inherited by several algorithms (or shared by tasks) is tried once
    for prefix, schema, task, algo in _schemas():
        for key, owner, tp in _numeric_fields(schema):
            name = key.rsplit(".", 1)[-1]
            rng = field_range(owner, name)
            if (prefix + key, id(rng)) in seen:
                continue
            seen.add((prefix + key, id(rng)))
            listed = typing.get_origin(typing.get_type_hints(owner)[name]) is list
            for v in _outside(rng, tp):
                yield task, algo, prefix + key, ([v] if listed and rng.length is None else v)


def test_every_numeric_key_rejects_values_outside_its_range_by_name():
    bases, seen = {}, 0
    for task, algo, key, value in _cases():
        if (task, algo) not in bases:
            bases[task, algo] = to_dict(compose([f"task={task}", f"algo={algo}"]))
        data = copy.deepcopy(bases[task, algo])
        node = data
        *parents, leaf = key.split(".")
        for p in parents:
            node = node[p]
        node[leaf] = value
        with pytest.raises(ConfigError) as e:
            validate(data)
        msg = str(e.value)
        assert f"'{key}'" in msg and "must be" in msg and "\n" not in msg, (key, value, msg)
        seen += 1
    assert seen > 120  # every algorithm's and task's keys, not a handful


@pytest.mark.parametrize(
    "args",
    [
        ["train", "algo.gamma=2"],
        ["train", "algo.actor_lr=-1"],
        ["train", "task.episode_len=0"],
        ["train", "env.substeps=0"],
        ["train", "seed=-1"],
        ["train", "time_limit=inf"],
        ["train", "algo=sac", "algo.tau=nan"],
        ["train", "algo.hidden=[0]"],
        ["train", "task=1v1", "task.serve=2"],
        ["train", "-m", "seed=0,-1"],
        ["eval", "random", "episodes=0"],
        ["replay", "random", "seed=-5"],
        ["bench", "repeats=0"],
        ["bench", "num_envs=[0]"],
        ["bench", "threads=-1"],
    ],
)
def test_out_of_range_on_the_command_line_is_one_line_and_writes_nothing(args, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    key = next(a.split("=")[0].split(".")[-1] for a in args[1:] if "=" in a and not a.startswith(("task=", "algo=")))
    _one_line_exit_2(runner.invoke(app, args), key)
    assert not any(tmp_path.iterdir())


def test_make_env_names_a_bad_keyword():
    import volleybots

    for kw, key in (
        (dict(substeps=0), "substeps"),
        (dict(num_envs=0), "num_envs"),
        (dict(episode_len=0), "episode_len"),
        (dict(ball_drag=math.nan), "ball_drag"),
    ):
        with pytest.raises(ValueError, match=f"'{key}'"):
            volleybots.make_env("hover", **kw)


# ------------------------------------------------------------------- empty values, usage, paths, memory
@pytest.mark.parametrize(
    "args,words",
    [
        (["train", "resume="], ["resume="]),
        (["train", "hydra.run.dir="], ["hydra.run.dir"]),
        (["train", "-m", "seed=0,1", "hydra.sweep.dir="], ["hydra.sweep.dir"]),
        (["train", "wandb.project="], ["wandb.project", "empty"]),
        (["fly"], ["fly", "train", "eval"]),
        (["replay"], ["missing argument"]),
        (["eval", "random", "--foo"], ["--foo", "--json"]),
        (["eval", "--jsn", "random"], ["--jsn"]),
        (["replay", "random", "--outt", "x.rrd"], ["--outt", "--out"]),
        (["replay", "random", "--out"], ["--out", "requires an argument"]),
        (["train", "--frames", "3"], ["--frames", "--multirun"]),
        (["list", "extra"], ["extra"]),
        (["list", "--all"], ["--all"]),
        (["bench", "--fast"], ["--fast", "num_envs"]),
        (["bench", "num_envs=abc"], ["num_envs"]),
        (["bench", "tasks=[nope]"], ["nope", "hover"]),
        (["train", "env.num_envs=1e12"], ["env.num_envs=1000000000000", "memory"]),
        (["train", "algo=sac", "algo.buffer_size=1e14"], ["algo.buffer_size=100000000000000", "memory"]),
        (["train", "evaluation.episodes=1e12"], ["evaluation.episodes=1000000000000", "memory"]),
        (["eval", "random", "episodes=1e12"], ["episodes=1000000000000", "memory"]),
        (["bench", "num_envs=[1e13]"], ["num_envs=10000000000000", "memory"]),
    ],
)
def test_bad_input_of_every_verb_is_one_line(args, words, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _one_line_exit_2(runner.invoke(app, args), *words)
    assert not any(tmp_path.iterdir())


def test_unwritable_output_paths_are_one_line(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("x")
    before = snapshot(tmp_path)
    for args in (
        ["train", *TINY, f"hydra.run.dir={tmp_path / 'afile' / 'run'}"],
        ["train", "-m", "seed=0,1", *TINY, f"hydra.sweep.dir={tmp_path / 'afile' / 'sweep'}"],
        ["replay", "random", "--no-viewer", "--out", str(tmp_path / "afile" / "x.rrd")],
    ):
        _one_line_exit_2(runner.invoke(app, args), "afile", "not a directory")
    assert snapshot(tmp_path) == before


# ------------------------------------------------------------------------ run directories and locks
def _tiny_run(path: Path, *extra, task="hover") -> Path:
    res = runner.invoke(app, ["train", f"task={task}", *TINY, f"hydra.run.dir={path}", *extra])
    assert res.exit_code == 0, res.output
    return path


def _hold_lock(path: Path) -> subprocess.Popen:
    """Another process that makes ``path`` and holds its run-dir lock for up to a minute (kill it when done)."""
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            (
                "import time; from volleybots.runs import lock; from pathlib import Path; "
                f"Path({str(path)!r}).mkdir(parents=True, exist_ok=True); lock({str(path)!r}); print('locked', flush=True); time.sleep(60)"
            ),
        ],
        env=CLI_ENV,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert holder.stdout.readline().strip() == "locked"
    return holder


def test_claim_gives_a_fresh_suffix_when_the_default_dir_is_taken_or_in_use(tmp_path):
    from volleybots.runs import claim_run_dir, unlock

    base = tmp_path / "12-00-00_hover_ppo"
    holder = _hold_lock(base)
    try:
        second = claim_run_dir(base, unique=True)
        assert second == base.with_name(base.name + "_2")
        with pytest.raises(ConfigError, match="in use by process"):
            claim_run_dir(base, unique=False)  # an explicit dir in use is refused
    finally:
        holder.kill()
        holder.wait()
    unlock(second)
    (second / "config.yaml").write_text("{}\n")  # a run started there: the next claim moves on
    (second / "checkpoints").mkdir()
    (second / "checkpoints" / "final.pt").write_bytes(b"")
    assert claim_run_dir(base, unique=True) == base  # the killed holder left no stuck lock
    unlock(base)
    assert claim_run_dir(second, unique=True) == base.with_name(base.name + "_2_2")


def test_a_benchmark_rerun_never_removes_a_run_another_process_is_training(tmp_path):
    """benchmarks/table1.py removes an unfinished run dir to start it again, but not while another
    invocation on the same --out holds its lock (that collision once removed a live run)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    try:
        from table1 import _skip_in_use, finished_summary
    finally:
        sys.path.pop(0)
    from volleybots.runs import InUseError

    live, dead = tmp_path / "live", tmp_path / "dead"
    for d in (live, dead):
        d.mkdir()
        (d / "config.yaml").write_text("{}\n")
    holder = _hold_lock(live)
    try:
        with pytest.raises(InUseError, match="in use by process"):
            finished_summary(live)
        assert (live / "config.yaml").is_file()
        assert _skip_in_use(lambda job, args: finished_summary(live), "job", None) is None  # one line, no crash
    finally:
        holder.kill()
        holder.wait()
    assert finished_summary(dead) is None and not dead.exists()  # interrupted, unlocked: removed to start again
    (live / "summary.json").write_text('{"frames": 3}')
    assert finished_summary(live) == {"frames": 3}


def test_two_starts_at_once_make_two_intact_runs(tmp_path):
    procs = [
        subprocess.Popen(
            cli_cmd("train", *TINY, f"total_frames={2 * FPB}", f"seed={s}"),
            cwd=tmp_path,
            env=CLI_ENV,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for s in (1, 2)
    ]
    outs = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [o[1][-2000:] for o in outs]
    runs = sorted(p.parent for p in (tmp_path / "outputs").rglob("summary.json"))
    assert len(runs) == 2 and runs[0] != runs[1]
    from volleybots.runs import RunDir

    seeds = sorted(RunDir(r).load_config().seed for r in runs)
    assert seeds == [1, 2]
    for r in runs:  # each run's own records: Hydra's too
        seed = RunDir(r).load_config().seed
        assert f"seed={seed}" in (r / ".hydra" / "overrides.yaml").read_text()
        assert [int(x["frames"]) for x in train_rows(r)] == [FPB, 2 * FPB]


def test_two_starts_into_one_dir_end_with_one_run_and_one_refusal(tmp_path):
    run = tmp_path / "run"
    procs = [
        subprocess.Popen(
            cli_cmd("train", *TINY, f"total_frames={2 * FPB}", f"seed={s}", f"hydra.run.dir={run}"),
            env=CLI_ENV,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for s in (1, 2)
    ]
    outs = [p.communicate(timeout=300) for p in procs]
    codes = sorted(p.returncode for p in procs)
    assert codes == [0, 2], [o[1][-2000:] for o in outs]
    loser = next(o for p, o in zip(procs, outs, strict=True) if p.returncode == 2)
    assert len(loser[1].strip().splitlines()) == 1 and ("in use" in loser[1] or "already holds a run" in loser[1]), loser[1]
    winner = 1 + [p.returncode for p in procs].index(0)
    from volleybots.runs import RunDir

    assert RunDir(run).load_config().seed == winner
    assert f"seed={winner}" in (run / ".hydra" / "overrides.yaml").read_text()  # not overwritten by the loser
    assert [int(x["frames"]) for x in train_rows(run)] == [FPB, 2 * FPB] and (run / "summary.json").is_file()


def test_two_resumes_at_once_train_once_and_lose_nothing(tmp_path):
    run = _tiny_run(tmp_path / "run", f"total_frames={FPB}")
    procs = [
        subprocess.Popen(
            cli_cmd("train", f"resume={run}", f"total_frames={4 * FPB}"),
            env=CLI_ENV,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _ in range(2)
    ]
    outs = [p.communicate(timeout=300) for p in procs]
    assert sorted(p.returncode for p in procs) == [0, 2], [o[1][-2000:] for o in outs]
    loser = next(o for p, o in zip(procs, outs, strict=True) if p.returncode == 2)
    assert len(loser[1].strip().splitlines()) == 1, loser[1]
    assert [int(x["frames"]) for x in train_rows(run)] == [FPB * i for i in range(1, 5)]  # no duplicate rows
    assert torch.load(run / "checkpoints" / "final.pt", weights_only=True)["frames"] == 4 * FPB


def test_a_run_killed_before_its_first_checkpoint_can_be_retried(tmp_path):
    run = tmp_path / "run"
    victim = subprocess.Popen(
        cli_cmd("train", *TINY, "total_frames=1e9", "checkpoint.every=0", f"hydra.run.dir={run}"),
        env=CLI_ENV,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.time() + 300
    while not ((run / "metrics.csv").is_file() and len(train_rows(run)) >= 2) and victim.poll() is None and time.time() < deadline:
        time.sleep(0.05)
    victim.send_signal(signal.SIGKILL)
    victim.wait()
    assert victim.returncode == -signal.SIGKILL and not (run / "checkpoints").exists()
    # resume= starts it afresh from frame 0 (saying so); the dead process left no lock behind
    res = runner.invoke(app, ["train", f"resume={run}", f"total_frames={2 * FPB}"])
    assert res.exit_code == 0, res.output[-2000:]
    assert "note:" in res.stderr and "afresh" in res.stderr
    assert [int(x["frames"]) for x in train_rows(run)] == [FPB, 2 * FPB]
    # and the same for the plain command run again, after another early death
    (run / "checkpoints" / "final.pt").unlink()
    (run / "summary.json").unlink()  # an early death writes none (a finished run without checkpoints is refused: issue 49)
    (run / "checkpoints" / "ckpt_000000000000.tmp").write_bytes(b"half")  # a kill while saving
    res = runner.invoke(app, ["train", *TINY, f"total_frames={FPB}", "seed=9", f"hydra.run.dir={run}"])
    assert res.exit_code == 0, res.output
    assert "afresh" in res.stderr
    from volleybots.runs import RunDir

    assert RunDir(run).load_config().seed == 9 and [int(x["frames"]) for x in train_rows(run)] == [FPB]
    assert not list((run / "checkpoints").glob("*.tmp"))


# ------------------------------------------------------------------- resume checks before it writes
@pytest.fixture(scope="module")
def two_runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("runs")
    hover = _tiny_run(root / "hover", f"total_frames={FPB}")
    bump = _tiny_run(root / "bump", f"total_frames={FPB}", task="solo_bump")
    return hover, bump


def test_resume_onto_a_mismatched_checkpoint_names_both_and_writes_nothing(two_runs, tmp_path):
    hover, bump = two_runs
    run = tmp_path / "hover"
    import shutil

    shutil.copytree(hover, run)
    shutil.copy(bump / "checkpoints" / "final.pt", run / "checkpoints" / "final.pt")
    before = snapshot(run)
    err = _one_line_exit_2(runner.invoke(app, ["train", f"resume={run}", f"total_frames={4 * FPB}"]))
    assert "checkpoint is solo_bump (obs 32, prt, ppo), run is hover (obs 26, prt, ppo)" in err, err
    assert snapshot(run) == before


def test_resume_of_a_damaged_run_is_one_line(two_runs, tmp_path):
    import shutil

    hover, _ = two_runs
    for name, damage, words in (
        ("config.yaml", "task: [unclosed\n", ["config.yaml", "damaged"]),
        ("config.yaml", "- a list\n", ["config.yaml", "damaged"]),
        ("metrics.csv", "phase,frames\ntrain,abc\ntrain,64\n", ["metrics.csv", "line 2", "abc"]),
        ("metrics.csv", "garbage\n1,2\n", ["metrics.csv", "frames"]),
        ("checkpoints/final.pt", "not a checkpoint", ["final.pt", "not a volleybots checkpoint", "move it out"]),
    ):
        run = tmp_path / f"r_{name.replace('/', '_')}_{len(damage)}"
        shutil.copytree(hover, run)
        (run / name).write_text(damage)
        before = snapshot(run)
        _one_line_exit_2(runner.invoke(app, ["train", f"resume={run}", f"total_frames={2 * FPB}"]), *words)
        assert snapshot(run) == before, name


def test_resume_drops_a_row_cut_short_by_a_kill(two_runs, tmp_path):
    import shutil

    hover, _ = two_runs
    run = tmp_path / "cut"
    shutil.copytree(hover, run)
    with (run / "metrics.csv").open("a") as f:
        f.write("tra")  # the start of a row when the process died
    res = runner.invoke(app, ["train", f"resume={run}", f"total_frames={2 * FPB}"])
    assert res.exit_code == 0, res.output
    assert [int(x["frames"]) for x in train_rows(run)] == [FPB, 2 * FPB]
