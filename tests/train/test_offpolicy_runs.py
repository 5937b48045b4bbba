"""Off-policy algorithms in the shared run loop: a tiny run of each writes metrics and checkpoints that
load with ``weights_only=True``; a resumed run continues the same learning curve (bit for bit with
the replay buffer checkpointed); the CLI picks the discrete action space for dqn and rejects a
continuous one with one line."""

from __future__ import annotations

import math

import pytest
import torch
from helpers import flat
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.config import load
from volleybots.runs import read_metrics
from volleybots.train import resume, train

TINY = [
    "task=hover", "task.episode_len=40", "env.num_envs=4", "algo.steps_per_batch=8", "algo.batch_size=32",
    "algo.buffer_size=4096", "algo.warmup_batches=2", "algo.hidden=[32,32]", "seed=3", "threads=1",
    "progress=false", "checkpoint.every=64", "checkpoint.keep=5", "evaluation.every=0", "evaluation.episodes=2",
    "evaluation.record=false",
]
FPB = 4 * 8  # frames per batch


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
@pytest.mark.parametrize("name", ["dqn", "ddpg", "td3", "sac"])
def test_a_tiny_run_writes_metrics_and_loadable_checkpoints(name, tmp_path):
    cfg = load([f"algo={name}", *TINY, "total_frames=128"])
    assert cfg.env.action_space == ("discrete" if name == "dqn" else "prt")
    summary = train(cfg, tmp_path / "run")
    assert summary["frames"] == 128 and summary["iterations"] == 128 // FPB
    rows = [r for r in read_metrics(tmp_path / "run" / "metrics.csv") if r["phase"] == "train"]
    assert [r["frames"] for r in rows] == [float(FPB * i) for i in range(1, 5)]
    loss_cols = [k for k in rows[0] if k.startswith("loss_")]
    assert loss_cols, rows[0].keys()
    # warm-up: two batches of 32 transitions; the first batch only fills the buffer
    assert all(isinstance(rows[0][k], str) or math.isnan(rows[0][k]) for k in loss_cols)
    for r in rows[1:]:
        assert all(isinstance(r[k], float) and math.isfinite(r[k]) for k in loss_cols), r
    assert [r["buffer_size"] for r in rows] == [float(FPB * i) for i in range(1, 5)]
    ck = tmp_path / "run" / "checkpoints"
    assert sorted(p.name for p in ck.iterdir()) == ["best.pt", "ckpt_000000000064.pt", "final.pt"]
    state = torch.load(ck / "final.pt", weights_only=True)
    assert state["frames"] == 128 and state["config"]["algo"]["name"] == name
    assert int(state["algo"]["counters"][0]) == 128 and "buffer" not in state["algo"]  # buffer off by default
    # the final evaluation ran the trained policy
    assert summary["final_eval"]["episodes"] == 2


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_resume_with_the_buffer_repeats_the_uninterrupted_run(tmp_path):
    common = ["algo=td3", *TINY, "algo.checkpoint_buffer=true"]
    # the uninterrupted run checkpoints (and so starts fresh episodes) at 64 and 128 frames, where
    # the interrupted one stops
    full = train(load([*common, "total_frames=192"]), tmp_path / "full")
    half = train(load([*common, "total_frames=128"]), tmp_path / "half")
    assert half["frames"] == 128
    state = torch.load(tmp_path / "half" / "checkpoints" / "final.pt", weights_only=True)
    assert state["algo"]["buffer"]["data"]["observation"].shape[0] == 128
    resumed = resume(tmp_path / "half", ["total_frames=192"])
    assert resumed["frames"] == full["frames"] == 192
    a = flat(torch.load(tmp_path / "full" / "checkpoints" / "final.pt", weights_only=True)["algo"])
    b = flat(torch.load(tmp_path / "half" / "checkpoints" / "final.pt", weights_only=True)["algo"])
    assert a.keys() == b.keys()
    for k in a:
        assert torch.equal(a[k], b[k]) if isinstance(a[k], torch.Tensor) else a[k] == b[k], k
    ra = [r for r in read_metrics(tmp_path / "full" / "metrics.csv") if r["phase"] == "train"]
    rb = [r for r in read_metrics(tmp_path / "half" / "metrics.csv") if r["phase"] == "train"]
    assert [r["frames"] for r in rb] == [float(FPB * i) for i in range(1, 7)]
    assert [r["loss_critic"] for r in ra] == [r["loss_critic"] for r in rb]


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_resume_without_the_buffer_warms_up_again_and_goes_on(tmp_path):
    common = ["algo=sac", *TINY]
    train(load([*common, "total_frames=96"]), tmp_path / "run")
    before = torch.load(tmp_path / "run" / "checkpoints" / "final.pt", weights_only=True)["algo"]
    summary = resume(tmp_path / "run", ["total_frames=192"])
    assert summary["frames"] == 192
    rows = [r for r in read_metrics(tmp_path / "run" / "metrics.csv") if r["phase"] == "train"]
    assert [r["frames"] for r in rows] == [float(FPB * i) for i in range(1, 7)]
    # the buffer restarts empty: it holds only what was collected after the resume
    assert [r["buffer_size"] for r in rows[3:]] == [32.0, 64.0, 96.0]
    after = torch.load(tmp_path / "run" / "checkpoints" / "final.pt", weights_only=True)["algo"]
    assert int(after["counters"][1]) > int(before["counters"][1])  # it trained on after the warm-up




def _invoke(*args):
    return CliRunner().invoke(app, list(args))


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_cli_trains_evaluates_and_replays_sac_and_picks_discrete_for_dqn(tmp_path, monkeypatch):
    # the verbs run in this process (each child process costs a fresh import of torch); tests/cli/test_cli.py runs the
    # command line as a real process
    monkeypatch.chdir(tmp_path)
    run = tmp_path / "sac"
    res = _invoke("train", "algo=sac", *TINY, "total_frames=64", f"hydra.run.dir={run}")
    assert res.exit_code == 0, res.output[-2000:]
    assert (run / "metrics.csv").is_file() and (run / "checkpoints" / "final.pt").is_file()
    res = _invoke("eval", str(run), "episodes=3", "--json")
    assert res.exit_code == 0, res.output[-2000:]
    assert '"episodes": 3' in res.stdout
    out = tmp_path / "sac.rrd"
    res = _invoke("replay", str(run), "--out", str(out), "--no-viewer")
    assert res.exit_code == 0 and out.is_file() and out.stat().st_size > 0, res.output[-2000:]

    dqn = tmp_path / "dqn"
    res = _invoke("train", "algo=dqn", *TINY, "total_frames=32", f"hydra.run.dir={dqn}")
    assert res.exit_code == 0, res.output[-2000:]
    state = torch.load(dqn / "checkpoints" / "final.pt", weights_only=True)
    assert state["action_space"] == "discrete"

    bad = tmp_path / "bad"
    res = _invoke("train", "algo=dqn", "env.action_space=prt", *TINY, "total_frames=32", f"hydra.run.dir={bad}")
    assert res.exit_code == 2
    lines = [line for line in res.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "dqn" in lines[0] and "discrete" in lines[0] and "'prt'" in lines[0], res.stderr
    assert not bad.exists()


def test_eval_may_change_the_episode_limit_but_not_the_task(tmp_path):
    from volleybots.errors import ConfigError
    from volleybots.policies import resolve_target

    train(load(["algo=sac", *TINY, "total_frames=64"]), tmp_path / "run")
    assert resolve_target(str(tmp_path / "run")).cfg.task.episode_len == 40  # as trained
    assert resolve_target(str(tmp_path / "run"), ["task.episode_len=500"]).cfg.task.episode_len == 500
    assert resolve_target(str(tmp_path / "run"), ["task.episode_len=null"]).cfg.task.episode_len is None  # the task's own
    with pytest.raises(ConfigError, match="cannot change 'task.target'"):
        resolve_target(str(tmp_path / "run"), ["task.target=[0,0,2]"])
