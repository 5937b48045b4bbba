"""Run directories (volleybots/runs): one process per directory however they are started, a fresh suffix
when the default directory is taken, two resumes at once train once, a run killed before its first
checkpoint can be retried, and a benchmark's rerun never removes a run another process is training
(the reliability guarantees of docs/usage.md that live in the run directory)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch
from helpers import CLI_ENV, HOVER_FPB, TINY_HOVER, cli_cmd, hold_lock, tiny_hover_run, train_rows
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.config import ConfigError

runner = CliRunner()
FPB, TINY = HOVER_FPB, TINY_HOVER


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_claim_gives_a_fresh_suffix_when_the_default_dir_is_taken_or_in_use(tmp_path):
    from volleybots.runs import claim_run_dir, unlock

    base = tmp_path / "12-00-00_hover_ppo"
    holder = hold_lock(base)
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


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
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
    holder = hold_lock(live)
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


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
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


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
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


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_two_resumes_at_once_train_once_and_lose_nothing(tmp_path):
    run = tiny_hover_run(tmp_path / "run", f"total_frames={FPB}")
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


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
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
