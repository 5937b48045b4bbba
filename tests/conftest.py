"""Hooks and fixtures of the suite: the scheduling order, one torch thread per test, and a session-wide
cache of tiny trained runs, so that tests which only read a run (evaluate it, start from it, replay it) do
not each train their own. Plain helpers are in helpers.py.

Markers (registered in pyproject.toml) only select: `python -m pytest -q` runs every test, and
`python -m pytest -q -m "not slow"` is the quick local loop. A test's tier is said at the test itself
(``@pytest.mark.slow``, or ``learning``, which implies it); nothing here lists tests."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import torch
from helpers import QUIET, TINY_1V1

SECONDS_KEY = "volleybots/test_seconds"  # pytest's cache (.pytest_cache): what each test took when it last ran here
WORKER_KEY = "volleybots_test_seconds"  # the same, handed by the xdist controller to its workers
# what a test never timed here (a fresh clone) is assumed to take: a learning test trains to a floor (the longest,
# 45 to 140 s), other slow ones train, sweep or search (5 to 70 s), quick ones far less; so that without a record
# the modules holding learning and slow tests still start first
UNTIMED_LEARNING, UNTIMED_SLOW, UNTIMED = 60.0, 30.0, 0.5


def pytest_collection_modifyitems(items):
    """A learning test trains to a floor: it is slow by nature, so ``-m "not slow"`` leaves it out too.
    (This runs before the ``-m`` selection; the scheduling order is set after it, by ``Schedule``.)"""
    for item in items:
        if item.get_closest_marker("learning") and not item.get_closest_marker("slow"):
            item.add_marker(pytest.mark.slow)


class Schedule:
    """Longest modules first, by measured time: xdist's ``loadscope`` hands modules out in collection
    order, so the long ones start at once and the short ones fill in behind them (longest-first
    scheduling), instead of one worker finishing a long module alone at the end.

    A module's time is the sum over its *selected* tests of what each took in the last run that ran it
    (every phase, so a module's shared fixtures count), recorded in pytest's cache at the end of every
    session; a test not timed yet counts ``UNTIMED_LEARNING``, ``UNTIMED_SLOW`` or ``UNTIMED`` seconds by its marker. The
    controller reads the cache once and hands it to its workers, so that every worker orders the tests
    alike even while another session in the same checkout writes the cache (xdist refuses workers
    whose collections differ). Only the order changes: no test is selected or skipped by it."""

    def __init__(self, config):
        self.config = config
        self.took: dict[str, float] = {}
        if hasattr(config, "workerinput"):
            self.seconds = dict(config.workerinput.get(WORKER_KEY, {}))
        else:
            cache = getattr(config, "cache", None)  # absent under -p no:cacheprovider: every test untimed
            self.seconds = dict(cache.get(SECONDS_KEY, {})) if cache is not None else {}

    @pytest.hookimpl(optionalhook=True)
    def pytest_configure_node(self, node):
        node.workerinput[WORKER_KEY] = self.seconds

    @pytest.hookimpl(trylast=True)  # after the -m / -k selection: only the tests that will run count
    def pytest_collection_modifyitems(self, items):
        cost: dict[str, float] = {}
        for item in items:
            guess = (UNTIMED_LEARNING if item.get_closest_marker("learning") else UNTIMED_SLOW if item.get_closest_marker("slow")
                     else UNTIMED)
            cost[item.location[0]] = cost.get(item.location[0], 0.0) + self.seconds.get(item.nodeid, guess)
        items.sort(key=lambda item: (-cost[item.location[0]], item.location[0]))  # stable: a module's own order is kept

    def pytest_runtest_logreport(self, report):
        self.took[report.nodeid] = self.took.get(report.nodeid, 0.0) + report.duration

    def pytest_sessionfinish(self, session):
        cache = getattr(self.config, "cache", None)
        if hasattr(self.config, "workerinput") or cache is None or not self.took:
            return  # the controller (or the lone process of -n 0) records
        root = Path(str(self.config.rootpath))
        kept = {k: v for k, v in cache.get(SECONDS_KEY, {}).items() if (root / k.split("::")[0]).is_file()}  # drop removed files
        cache.set(SECONDS_KEY, {**kept, **{k: round(v, 3) for k, v in self.took.items()}})


def pytest_configure(config):
    config.pluginmanager.register(Schedule(config), "volleybots-schedule")


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


