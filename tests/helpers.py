"""What many test files share, in one module: quiet tiny-run overrides, the command line in a child process,
readers of run directories and checkpoints, and scripted rollouts several modules read. Test modules import
these (``from helpers import ...``); the fixtures built on them live in conftest.py."""

from __future__ import annotations

import csv
import functools
import io
import json
import os
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
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


# a quiet 1v1 run of a few frames: the session-wide shared runs of conftest.py and tests that train their own alike
TINY_1V1 = [
    "task=1v1", "env.num_envs=8", "algo.steps_per_batch=16", "algo.minibatches=1", "algo.epochs=1", "algo.hidden=[16]",
    "evaluation.episodes=2", "evaluation.every=0", "evaluation.record=false", "progress=false", "threads=1",
]


# a quiet Hover PPO run of a few frames (HOVER_FPB frames a batch): the run-directory and resume tests
TINY_HOVER = [
    "env.num_envs=4", "algo.steps_per_batch=8", "algo.minibatches=2", "algo.epochs=1",
    "algo.hidden=[16]", "task.episode_len=40", "threads=1", "progress=false", "evaluation.episodes=1",
    "evaluation.record=false", "evaluation.every=0",
]
HOVER_FPB = 4 * 8  # env.num_envs x algo.steps_per_batch


def tiny_hover_run(path: Path, *extra: str, task: str = "hover") -> Path:
    """A finished ``TINY_HOVER`` run (of ``task``) trained in this process into ``path``."""
    from typer.testing import CliRunner

    from volleybots.cli import app

    res = CliRunner().invoke(app, ["train", f"task={task}", *TINY_HOVER, f"hydra.run.dir={path}", *extra])
    assert res.exit_code == 0, res.output
    return path


def hold_lock(path: Path) -> subprocess.Popen:
    """Another process that makes ``path`` and holds its run-dir lock for up to a minute (kill it when
    done): a second writer, as real as it gets, since the lock is the operating system's."""
    holder = subprocess.Popen(
        [sys.executable, "-c", (
            "import time; from volleybots.runs import lock; from pathlib import Path; "
            f"Path({str(path)!r}).mkdir(parents=True, exist_ok=True); lock({str(path)!r}); print('locked', flush=True); time.sleep(60)")],
        env=CLI_ENV, stdout=subprocess.PIPE, text=True,
    )
    assert holder.stdout.readline().strip() == "locked"
    return holder


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


# ---- fakes and files more than one module builds
class _Batch:
    def __init__(self, arr):
        self.arr = arr

    def as_arrow_array(self):
        return self.arr


class FakeRec:
    """Captures what the recorder logs; a ``send_columns`` call becomes one entry per row, holding
    that row's components by field name (``row.scalars.as_arrow_array()``), at its step."""

    def __init__(self):
        self.logs: list[tuple[str, object, bool]] = []
        self.steps: dict[str, list[int]] = {}
        self.blueprints: list = []

    def log(self, path, archetype, static=False):
        self.logs.append((path, archetype, static))

    def send_columns(self, path, indexes, columns):
        steps = indexes[0].as_arrow_array().to_pylist()
        cols = {c.component_descriptor().component.split(":")[-1]: c.as_arrow_array() for c in columns}
        for i, step in enumerate(steps):
            self.logs.append((path, types.SimpleNamespace(**{k: _Batch(a[i].values) for k, a in cols.items()}), False))
            self.steps.setdefault(path, []).append(step)

    def send_blueprint(self, blueprint):
        self.blueprints.append(blueprint)

    def at(self, path, static=False):
        return [a for p, a, st in self.logs if p == path and st == static]


def crossplay_file(path: Path, edit=None) -> Path:
    """A small valid crossplay.json at ``path`` (``edit`` changes its data first): a results file to damage."""
    from volleybots.eval.crossplay import CrossPlay

    wdl = np.array([[[0, 0, 0], [3, 1, 0]], [[0, 1, 3], [0, 0, 0]]], dtype=float)
    res = CrossPlay(["a", "b"], wdl, {"0,1": "WWDW"}, {"0,1": [[2, 0, 0], [1, 1, 0]]}, {"task": "1v1", "games_per_pair": 4, "seed": 0})
    data = res.to_dict()
    if edit:
        edit(data)
    path.write_text(json.dumps(data))
    return path
