"""`logger=wandb` for real: a tiny training logs to an offline W&B run, whose transaction log holds the
run's config and every row of metrics.csv (metrics.csv and the rerun recordings are still written)."""

from __future__ import annotations

import json
import math
import os
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from volleybots.runs import read_metrics

pytestmark = [pytest.mark.slow, pytest.mark.subprocess]

wandb_pb = pytest.importorskip("wandb.proto.wandb_internal_pb2", reason="the wandb extra is part of the test install")

TINY = ["task=hover", "task.episode_len=50", "env.num_envs=4", "algo.steps_per_batch=16", "total_frames=128", "threads=1", "progress=false",
        "checkpoint.every=64", "evaluation.every=64", "evaluation.episodes=2", "seed=3"]


def read_wandb_log(path: Path) -> list:
    """The records of an offline run's ``run-<id>.wandb`` file: a ``:W&B`` header, then LevelDB's log
    format (32 KiB blocks of chunks, each ``crc32 | length | type``, a record split over
    FIRST/MIDDLE/LAST chunks), each record a ``wandb_internal_pb2.Record``. wandb 0.31 ships no Python
    reader of its own (its core that writes the file is a Go binary)."""
    data = path.read_bytes()
    assert data[:4] == b":W&B" and struct.unpack("<HB", data[4:7]) == (0xBEE1, 0)
    block, pos, pending, records = 32768, 7, b"", []
    while pos + 7 <= len(data):
        left = block - pos % block
        if left < 7:  # a block's tail too short for a chunk header is padding
            pos += left
            continue
        _, length, kind = struct.unpack("<IHB", data[pos:pos + 7])
        if kind == 0:
            pos += left
            continue
        pending += data[pos + 7:pos + 7 + length]
        pos += 7 + length
        if kind in (1, 4):  # FULL or LAST: a whole record
            rec = wandb_pb.Record()
            rec.ParseFromString(pending)
            records.append(rec)
            pending = b""
    return records


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("wandb")
    env = {**os.environ, "OMP_NUM_THREADS": "1", "WANDB_SILENT": "true", "WANDB_CONFIG_DIR": str(root / "wandb_config"),
           "WANDB_CACHE_DIR": str(root / "wandb_cache")}
    res = subprocess.run([sys.executable, "-m", "volleybots.cli", "train", *TINY, "logger=wandb", "wandb.mode=offline",
                          f"hydra.run.dir={root / 'run'}"], cwd=root, env=env, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-3000:]
    return root / "run"


def _key(item) -> str:
    return item.key or ".".join(item.nested_key)  # wandb writes a key in either field


def _value(item) -> float | str:
    v = json.loads(item.value_json.replace("NaN", "null"))
    return math.nan if v is None else v


def test_offline_run_holds_the_config_and_every_logged_row(run_dir):
    (log,) = run_dir.glob("wandb/offline-run-*/run-*.wandb")
    records = read_wandb_log(log)
    (run,) = [r.run for r in records if r.WhichOneof("record_type") == "run"]
    config = {_key(i): json.loads(i.value_json) for i in run.config.update}
    assert run.project == "volleybots" and run.run_id == "run"
    assert config["task"]["name"] == "hover" and config["algo"]["name"] == "ppo" and config["env"]["num_envs"] == 4
    assert config["seed"] == 3 and config["total_frames"] == 128 and config["logger"] == "wandb"

    history = {}
    for r in records:
        if r.WhichOneof("record_type") == "history":
            history[r.history.step.num] = {_key(i): _value(i) for i in r.history.item}
    rows = read_metrics(run_dir / "metrics.csv")
    assert sorted(history) == sorted({int(r["frames"]) for r in rows}) == [64, 128]
    # an evaluation row is logged at the step of the batch before it: wandb merges the two (the later
    # one's wall_time wins)
    expected: dict[int, dict] = {}
    for row in rows:
        expected.setdefault(int(row["frames"]), {}).update({k: v for k, v in row.items() if isinstance(v, float) and not math.isnan(v)})
    checked = 0
    for step, row in expected.items():  # metrics.csv keeps 6 significant digits; wandb the full float
        logged = history[step]
        for key, v in row.items():
            assert logged[key] == pytest.approx(v, rel=1e-5, abs=1e-6), (step, key)
            checked += 1
    assert checked > 30 and "eval_distance" in history[128] and "loss_objective" in history[128]


def test_the_default_outputs_are_still_written(run_dir):
    assert (run_dir / "metrics.csv").is_file() and (run_dir / "curves.rrd").is_file()
    assert sorted(p.name for p in run_dir.glob("eval_*.rrd")) == ["eval_000000000064.rrd", "eval_000000000128.rrd"]
    assert json.loads((run_dir / "summary.json").read_text())["seed"] == 3


def test_without_wandb_installed_logger_wandb_names_the_extra(monkeypatch, tmp_path):
    import importlib.util

    from typer.testing import CliRunner

    from volleybots.cli import app

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "wandb" else real(name, *a))
    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(app, ["train", "logger=wandb"])
    assert res.exit_code == 2 and res.stderr.strip().startswith("error: logger=wandb needs the wandb package")
    assert "volleybots[wandb]" in res.stderr and not any(tmp_path.iterdir())
