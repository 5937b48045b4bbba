"""The reliability guarantees of docs/usage.md: every numeric key has a range and a value outside it is
one line, exit code 2 and nothing written; resume checks everything before it writes; usage errors of
every verb are one line. (Those that live in the run directory, runs started or resumed at the same
time and runs killed early, are tests/runs/test_run_dirs.py's.)"""

from __future__ import annotations

import copy
import dataclasses
import inspect
import math
import typing

import pytest
from helpers import HOVER_FPB, TINY_HOVER, snapshot, tiny_hover_run, train_rows
from typer.testing import CliRunner

from volleybots.algos import ALGOS, PRESETS, is_population
from volleybots.algos.base import class_attr
from volleybots.cli import app
from volleybots.config import BenchOptions, Config, ConfigError, compose, task_schema, to_dict, validate
from volleybots.errors import Range, field_range
from volleybots.tasks import TASKS

runner = CliRunner()
FPB, TINY = HOVER_FPB, TINY_HOVER


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
    # run_bench takes the bench options as one dataclass, typed and ranged the same way
    from volleybots.bench import run_bench

    assert list(inspect.signature(run_bench).parameters) == ["options", "progress"]
    assert inspect.signature(run_bench).parameters["options"].annotation in (BenchOptions, "BenchOptions | None")


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


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
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


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
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


# ------------------------------------------------------------------- resume checks before it writes
@pytest.fixture(scope="module")
def two_runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("runs")
    hover = tiny_hover_run(root / "hover", f"total_frames={FPB}")
    bump = tiny_hover_run(root / "bump", f"total_frames={FPB}", task="solo_bump")
    return hover, bump


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
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
