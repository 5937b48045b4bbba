"""What many test files share: quiet tiny-run overrides, the command line in a child process, readers of run
directories and checkpoints, and a session-wide cache of tiny trained runs, so that tests which only read a
run (evaluate it, start from it, replay it) do not each train their own.

Markers (registered in pyproject.toml) only select: `python -m pytest -q` runs every test, and
`python -m pytest -q -m "not slow"` is the quick local loop."""

from __future__ import annotations

import csv
import functools
import io
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import torch

ROOT = Path(__file__).resolve().parents[1]
# one torch thread, no progress bar and no rerun recording of evaluations: what every tiny run wants
QUIET = ["threads=1", "progress=false", "evaluation.record=false"]
# a child process with one OpenMP thread: the suite shares two cores
CLI_ENV = {**os.environ, "OMP_NUM_THREADS": "1"}


def cli_cmd(*args: str) -> list[str]:
    """The argv of `volleybots ARGS` run by this interpreter (the package under test, not an installed copy)."""
    return [sys.executable, "-m", "volleybots.cli", *map(str, args)]


def run_cli(*args: str, cwd=None, timeout: int = 600, env=None) -> subprocess.CompletedProcess:
    """`volleybots ARGS` in a child process, its output captured as text."""
    return subprocess.run(cli_cmd(*args), cwd=cwd, env=env or CLI_ENV, capture_output=True, text=True, timeout=timeout)


def flat(state, prefix: str = "") -> dict:
    """Every tensor / number of a nested checkpoint dict (or list), by dotted key."""
    out = {}
    for k, v in state.items() if isinstance(state, dict) else enumerate(state):
        if isinstance(v, (dict, list)):
            out.update(flat(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def train_rows(run: Path) -> list[dict]:
    """The raw (string) rows of phase ``train`` in a run's metrics.csv; none while the file is not written yet
    (so a test can poll a run that is still starting)."""
    path = Path(run) / "metrics.csv"
    if not path.is_file():
        return []
    # a run that is still writing can be read between its bytes (seen on CI: a header without its last
    # columns), so only whole lines count, and a row without a phase is not a train row yet
    text = path.read_text()
    text = text[: text.rfind("\n") + 1]
    return [r for r in csv.DictReader(io.StringIO(text, newline="")) if r.get("phase") == "train"]


def snapshot(root: Path) -> dict:
    """Modification time and size of everything under ``root``: equal snapshots mean nothing was written."""
    root = Path(root)
    return {str(p): (p.stat().st_mtime_ns, p.stat().st_size) for p in root.rglob("*")} if root.exists() else {}


def one_line_exit_2(res, *words) -> str:
    """A CLI refusal as the README promises it: exit code 2 and one ``error:`` line naming ``words``
    (after the progress lines of games already played, when the refusal comes after them: a full disk)."""
    err = "\n".join(line for line in res.stderr.splitlines() if line.strip() and not line.startswith("  pair ")).strip()
    assert res.exit_code == 2, (res.exit_code, res.output)
    assert len(err.splitlines()) == 1 and err.startswith("error: "), err
    for w in words:
        assert w in err, (w, err)
    return err


# Seconds each of the heaviest test modules took on the 2-core machine (xdist, 2 workers, 2026-11-28, main 904c7e0).
# Only the order of scheduling reads them; no test is selected or skipped by them.
MODULE_SECONDS = {
    "test_offpolicy_learning": 142, "test_population": 102, "test_reliability": 88, "test_cli": 83, "test_scripted_set_and_spike": 70,
    "test_launchers": 70, "test_marl": 64, "test_scripted_set_and_spike_ctbr": 63, "test_crossplay": 61, "test_ppo": 59, "test_zoo": 58,
    "test_exploitability": 55, "test_scripted_bump_and_pass": 47, "test_bc": 44, "test_docs": 36, "test_registries": 32,
    "test_payoff_pool": 29, "test_scripted": 28, "test_sac_init": 25, "test_lookahead": 24, "test_wandb": 23, "test_hierarchical": 23,
    "test_config": 23, "test_compiled_step": 22, "test_env": 21,
}


def pytest_collection_modifyitems(items):
    """A learning test trains to a floor: it is slow by nature, so ``-m "not slow"`` leaves it out too.

    The longest modules are collected first (``MODULE_SECONDS``, then the ones holding slow tests):
    xdist's ``loadscope`` hands modules out in collection order, so the long ones start at once and
    the short ones fill in behind them (longest-first scheduling), instead of one worker finishing a
    long module alone at the end."""
    for item in items:
        if item.get_closest_marker("learning") and not item.get_closest_marker("slow"):
            item.add_marker(pytest.mark.slow)
    slow = {item.module.__name__ for item in items if item.get_closest_marker("slow")}

    def cost(item) -> tuple:
        name = item.module.__name__
        return -MODULE_SECONDS.get(name, 0), name not in slow

    items.sort(key=cost)  # stable: a module's own order is kept


@pytest.fixture(autouse=True)
def _one_torch_thread():
    """One intra-op thread for every test (on a shared machine it is several times faster than two under
    contention), and the count put back afterwards, so one test's setting (``threads=N``) never leaks into the next."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


@pytest.fixture(scope="session")
def tiny_run(tmp_path_factory):
    """``tiny_run(*overrides)``: the run directory of ``train(load(overrides + QUIET))``, trained once per session
    for each distinct list of overrides. Tests that only read a run share it; a test that writes into a run dir
    (resume, extra checkpoints) trains its own instead."""
    from volleybots.config import load
    from volleybots.train import train

    runs: dict[tuple[str, ...], Path] = {}

    def get(*overrides: str) -> Path:
        key = tuple(overrides)
        if key not in runs:
            torch.set_num_threads(1)
            path = tmp_path_factory.mktemp("tiny_run") / "run"
            given = {o.split("=", 1)[0] for o in overrides}
            train(load([*overrides, *(q for q in QUIET if q.split("=", 1)[0] not in given)]), path)
            runs[key] = path
        return runs[key]

    return get


# ---- session-scoped tiny runs for the tests of damaged runs and of the evaluation verbs' input checks:
# each is trained once and copied by a test that damages it
TINY_1V1 = [
    "task=1v1", "env.num_envs=8", "algo.steps_per_batch=16", "algo.minibatches=1", "algo.epochs=1", "algo.hidden=[16]",
    "evaluation.episodes=2", "evaluation.every=0", "evaluation.record=false", "progress=false", "threads=1",
]


def _train(path: Path, *args) -> Path:
    from typer.testing import CliRunner

    from volleybots.cli import app

    res = CliRunner().invoke(app, ["train", *TINY_1V1, *args, f"hydra.run.dir={path}"])
    assert res.exit_code == 0, res.output
    return path


@pytest.fixture(scope="session")
def tiny_1v1_run(tmp_path_factory) -> Path:
    """A finished 1v1 MAPPO run of 128 frames (final.pt, summary.json listing it)."""
    return _train(tmp_path_factory.mktemp("shared") / "run", "algo=mappo", "total_frames=128")


@pytest.fixture(scope="session")
def tiny_population(tmp_path_factory) -> Path:
    """A finished PSRO run of one iteration over a random seed member: members random and br1."""
    return _train(tmp_path_factory.mktemp("shared") / "pop", "algo=psro_uniform", "algo.start=scratch", "algo.iterations=1",
                  "total_frames=256", "algo.min_updates=1", "algo.max_updates=1", "algo.payoff_games=2")


@pytest.fixture
def copy_run(tmp_path):
    """``copy_run(src, name)``: a copy of a shared run in this test's folder, free to damage."""

    def copy(src: Path, name: str = "copy") -> Path:
        return Path(shutil.copytree(src, tmp_path / name, ignore=shutil.ignore_patterns(".lock")))

    return copy


# ---- scripted rollouts read by several tests of one module (each module runs on one xdist worker)
SCRIPTED_STEPS = 170  # every first Set and Spike episode is over by then (a spiked ball lands about 2.8 s in)


def rollout_first_episodes(env, policy, steps: int):
    """What ``env.rollout(steps, policy, break_when_any_done=False)`` returns ([N, T], the same
    steps), cut short after the step by which every env has finished its first episode: what comes
    later belongs to second episodes, and a scripted player's lookahead makes each step cost most of
    a second. T is ``steps`` where some env's first episode is still running."""
    n = env.num_envs
    over = torch.zeros(n, dtype=torch.bool)
    out = []
    td = env.reset()
    for _ in range(steps):
        td.update(policy(td))
        step, td = env.step_and_maybe_reset(td)
        out.append(step)
        over |= step["next", "done"].reshape(n)
        if bool(over.all()):
            break
    return torch.stack(out, 1)


@functools.cache  # several tests read the same episodes (nothing mutates them)
def first_episodes(task, n=16, seed=2, action_space="prt", steps=SCRIPTED_STEPS):
    """The stats of each env's first episode under the task's scripted policy, the rollout, and the
    mask [N, T] of each env's first done step."""
    import volleybots
    from volleybots.scripted import make_scripted_policy

    env = volleybots.make_env(task, num_envs=n, seed=seed, action_space=action_space)
    td = rollout_first_episodes(env, make_scripted_policy(env), steps)
    nxt = td["next"]
    done = nxt["done"].squeeze(-1)
    first = done & (done.long().cumsum(1) == 1)
    assert bool(first.any(1).all()), "an env did not finish its first episode"
    return {k: nxt["stats", k].squeeze(-1)[first] for k in env._stats_keys}, td, first


def setter_sets_and_stays_home(task: str) -> None:
    """Set and Spike's scripted setter always sets, and until its episode ends never leaves its own
    half or drops low (asserted on each env's first episode)."""
    st, td, first = first_episodes(task)
    assert (st["setter_hit"] == 1).all()
    alive = (first.long().cumsum(1) - first.long()) == 0
    setter = td["next", "agents", "observation"][..., 0, :3][alive]
    assert (setter[:, 0] > 0.2).all() and (setter[:, 2] > 1.0).all()
