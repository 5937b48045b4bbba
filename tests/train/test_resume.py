"""A run killed between checkpoints and resumed with `train resume=DIR` ends with exactly the
parameters, optimiser state and learning curve of the same run left uninterrupted."""

from __future__ import annotations

import os
import signal
import subprocess
import time

import pytest
import torch
from helpers import cli_cmd, flat, train_rows
from typer.testing import CliRunner

from volleybots.cli import app

pytestmark = [pytest.mark.slow, pytest.mark.subprocess]

STEPS, ENVS = 16, 16
FPB = STEPS * ENVS  # frames per batch
TOTAL = 6 * FPB
COMMON = [
    "task=hover", f"env.num_envs={ENVS}", f"algo.steps_per_batch={STEPS}", "algo.minibatches=4", "seed=5",
    "threads=1", "progress=false", f"checkpoint.every={2 * FPB}", "checkpoint.keep=5",
    f"evaluation.every={3 * FPB}", "evaluation.episodes=2", "evaluation.record=false", f"total_frames={TOTAL}",
    "task.episode_len=60",  # the evaluations in the curve are compared, not their length: 60 steps each, not 500
]


def test_resume_after_a_kill_repeats_the_uninterrupted_run(tmp_path):
    full, killed = tmp_path / "full", tmp_path / "killed"
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    ref = subprocess.Popen(cli_cmd("train", *COMMON, f"hydra.run.dir={full}"), env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    victim = subprocess.Popen(
        cli_cmd("train", *COMMON, f"hydra.run.dir={killed}"), env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    deadline = time.time() + 300
    while len(train_rows(killed)) < 3 and victim.poll() is None and time.time() < deadline:
        time.sleep(0.02)
    victim.send_signal(signal.SIGKILL)
    victim.wait()
    assert victim.returncode == -signal.SIGKILL
    assert not (killed / "checkpoints" / "final.pt").exists(), "the run finished before it could be killed"
    ckpts = sorted((killed / "checkpoints").glob("ckpt_*.pt"))
    assert ckpts, "killed before the first checkpoint"
    kill_frames = int(train_rows(killed)[-1]["frames"])
    ck_frames = int(torch.load(ckpts[-1], weights_only=True)["frames"])
    assert ck_frames < kill_frames or ck_frames < TOTAL  # there is work after the checkpoint to redo or finish

    res = CliRunner().invoke(app, ["train", f"resume={killed}"])  # the resume's point is its result, not its process
    assert res.exit_code == 0, res.output[-2000:]
    ref.wait(timeout=600)
    assert ref.returncode == 0, ref.stderr.read().decode()[-2000:]

    a = torch.load(full / "checkpoints" / "final.pt", weights_only=True)
    b = torch.load(killed / "checkpoints" / "final.pt", weights_only=True)
    assert a["frames"] == b["frames"] == TOTAL and a["iteration"] == b["iteration"] == TOTAL // FPB
    fa, fb = flat(a["algo"]), flat(b["algo"])
    assert fa.keys() == fb.keys()
    for k in fa:
        if isinstance(fa[k], torch.Tensor):
            assert torch.equal(fa[k], fb[k]), k
        else:
            assert fa[k] == fb[k], k
    # the learning curve is the same too, with no duplicate rows from the killed stretch
    ra, rb = train_rows(full), train_rows(killed)
    assert [r["frames"] for r in ra] == [r["frames"] for r in rb] == [str(FPB * i) for i in range(1, 7)]
    for col in ("return", "episode_len", "loss_critic", "entropy"):
        assert [r[col] for r in ra] == [r[col] for r in rb], col
    # the periodic evaluation (between two checkpoints) and the final one agree as well
    ea, eb = a["evals"], b["evals"]
    assert [e["frames"] for e in ea] == [e["frames"] for e in eb] == [3 * FPB, TOTAL]
    assert ea == eb
    # a fresh run of the same config differs: equality above is not vacuous
    assert any(not torch.equal(fa[k], torch.zeros_like(fa[k])) for k in fa if isinstance(fa[k], torch.Tensor) and k.startswith("actor"))
