"""`logger=wandb` for real, read back from the offline runs' transaction logs: two tiny sweeps of two
jobs each keep four distinct run ids, each with its name, group, tags, config, every row of
metrics.csv and the final evaluation in its summary; a resume continues the same W&B run; artifacts
are logged when asked; a population run logs too."""

from __future__ import annotations

import json
import math
import struct
from pathlib import Path

import pytest
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.runs import read_metrics

pytestmark = [pytest.mark.slow, pytest.mark.subprocess]

wandb_pb = pytest.importorskip("wandb.proto.wandb_internal_pb2", reason="the wandb extra is part of the test install")

TINY = ["task=hover", "task.episode_len=20", "env.num_envs=4", "algo.steps_per_batch=16", "total_frames=128", "threads=1", "progress=false",
        "checkpoint.every=64", "evaluation.every=64", "evaluation.episodes=2", "logger=wandb", "wandb.mode=offline",
        "algo.minibatches=1", "algo.epochs=1", "algo.hidden=[16]"]  # one small gradient step a batch: W&B is what is tested


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
def wandb_env(tmp_path_factory):
    """Offline W&B with its own folders (no network, nothing written outside the test's tmp dir)."""
    root = tmp_path_factory.mktemp("wandb")
    with pytest.MonkeyPatch.context() as mp:
        for key in ("DIR", "CONFIG_DIR", "CACHE_DIR", "DATA_DIR"):
            mp.setenv(f"WANDB_{key}", str(root / f"wandb_{key.lower()}"))
        for key, value in (("WANDB_MODE", "offline"), ("WANDB_SILENT", "true"), ("WANDB_CONSOLE", "off"), ("OMP_NUM_THREADS", "1")):
            mp.setenv(key, value)
        mp.chdir(root)
        yield root


def _invoke(*args):
    import wandb

    res = CliRunner().invoke(app, list(args))
    wandb.teardown()  # a finished run's .wandb file is complete once W&B's service has shut down (as at exit)
    assert res.exit_code == 0, res.output[-3000:]


@pytest.fixture(scope="module")
def sweeps(wandb_env):
    """Sweep A in Hydra's dated layout (its group comes from the sweep dir), sweep B with its own group,
    tags and artifacts; then job 1 of sweep A resumed for one more batch."""
    a = wandb_env / "2030-01-01" / "12-00-00_hover_ppo"
    b = wandb_env / "sweep_b"
    _invoke("train", "-m", "seed=0,1", *TINY, f"hydra.sweep.dir={a}")
    _invoke("train", "-m", "seed=0,1", *TINY, "total_frames=64", "evaluation.every=0", "checkpoint.every=0", "wandb.group=ablation",
            "wandb.tags=[mine,hover]", "wandb.artifacts=true", f"hydra.sweep.dir={b}")
    _invoke("train", f"resume={a / '1'}", "total_frames=192")
    return a, b


def _logs(run_dir: Path) -> list[list]:
    """The records of each offline W&B run in ``run_dir``, oldest first."""
    return [read_wandb_log(p) for p in sorted(run_dir.glob("wandb/offline-run-*/run-*.wandb"))]


def _key(item) -> str:
    return item.key or ".".join(item.nested_key)  # wandb writes a key in either field


def _value(item) -> float | str:
    v = json.loads(item.value_json.replace("NaN", "null"))
    return math.nan if v is None else v


def _of(records: list, kind: str) -> list:
    return [getattr(r, kind) for r in records if r.WhichOneof("record_type") == kind]


def _summary(records: list) -> dict:
    out = {}
    for s in _of(records, "summary"):  # each record updates the summary
        out.update({_key(i): _value(i) for i in s.update})
    return out


def test_two_sweeps_keep_four_distinct_ids_with_name_group_and_tags(sweeps):
    a, b = sweeps
    runs = {}
    for sweep, group in ((a, "2030-01-01_12-00-00_hover_ppo"), (b, "ablation")):
        for job in ("0", "1"):
            (run,) = _of(_logs(sweep / job)[0], "run")
            assert run.display_name == f"hover_ppo_s{job}" and run.run_group == group and run.job_type == "train"
            assert run.project == "volleybots"
            runs[sweep.name, job] = run
            saved = json.loads((sweep / job / "wandb_run.json").read_text())
            assert saved["id"] == run.run_id and saved["group"] == ("2030-01-01_12-00-00_hover_ppo" if sweep == a else "sweep_b")
    assert len({r.run_id for r in runs.values()}) == 4
    assert all(len(r.run_id) == 16 for r in runs.values())
    assert list(runs["12-00-00_hover_ppo", "0"].tags) == ["hover", "ppo", "prt", "torch"]
    assert list(runs["sweep_b", "1"].tags) == ["hover", "ppo", "prt", "torch", "mine"]  # a repeated tag once


def test_offline_run_holds_the_config_and_every_logged_row(sweeps):
    run_dir = sweeps[0] / "0"
    (records,) = _logs(run_dir)
    (run,) = _of(records, "run")
    config = {_key(i): json.loads(i.value_json) for i in run.config.update}
    assert config["task"]["name"] == "hover" and config["algo"]["name"] == "ppo" and config["env"]["num_envs"] == 4
    assert config["seed"] == 0 and config["total_frames"] == 128 and config["logger"] == "wandb"
    assert config["wandb"] == {"project": "volleybots", "mode": "offline", "group": None, "tags": [], "artifacts": False}

    history = {}
    for h in _of(records, "history"):
        history[h.step.num] = {_key(i): _value(i) for i in h.item}
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


def test_the_summary_holds_the_final_evaluation_and_the_run_summary(sweeps):
    for run_dir in (sweeps[0] / "0", sweeps[1] / "1"):
        summary = _summary(_logs(run_dir)[0])
        saved = json.loads((run_dir / "summary.json").read_text())
        stats = saved["final_eval"]["stats"]
        assert summary["final_eval_distance"] == pytest.approx(stats["distance"]["mean"], rel=1e-9)
        assert summary["final_eval_distance_std"] == pytest.approx(stats["distance"]["std"], rel=1e-9)
        assert summary["final_eval_return"] == pytest.approx(stats["return"]["mean"], rel=1e-9)
        assert summary["final_eval_return_std"] == pytest.approx(stats["return"]["std"], rel=1e-9)
        assert summary["final_eval_episodes"] == 2 and stats["distance"]["mean"] > 0
        for key in ("task", "algo", "action_space", "seed", "frames", "iterations", "metric", "version"):
            assert summary[key] == saved[key], key
        assert summary["frames"] == saved["frames"] == (128 if run_dir.parent == sweeps[0] else 64) and summary["metric"] == "distance"


def test_resume_continues_the_same_wandb_run(sweeps):
    run_dir = sweeps[0] / "1"
    first, second = _logs(run_dir)
    (r1,), (r2,) = _of(first, "run"), _of(second, "run")
    assert r2.run_id == r1.run_id and r2.display_name == r1.display_name == "hover_ppo_s1"
    assert r2.run_group == r1.run_group == "2030-01-01_12-00-00_hover_ppo"  # kept, though the resume is no sweep
    assert sorted(h.step.num for h in _of(second, "history")) == [192]
    assert _summary(second)["frames"] == 192


def test_artifacts_are_logged_only_when_asked(sweeps):
    a, b = sweeps
    assert _of(_logs(a / "0")[0], "artifact") == []
    for job in ("0", "1"):
        records = _logs(b / job)[0]
        (run,) = _of(records, "run")
        arts = {x.type: x for x in _of(records, "artifact")}
        assert set(arts) == {"model", "recording"}
        assert arts["model"].name == f"model-{run.run_id}" and arts["recording"].name == f"recordings-{run.run_id}"
        files = {t: {e.path: e.size for e in x.manifest.contents} for t, x in arts.items()}
        ckpts = b / job / "checkpoints"
        assert files["model"] == {"final.pt": (ckpts / "final.pt").stat().st_size, "best.pt": (ckpts / "best.pt").stat().st_size}
        assert files["recording"] == {p.name: p.stat().st_size for p in (b / job).glob("*.rrd")}
        assert set(files["recording"]) == {"curves.rrd", "eval_000000000064.rrd"}
        assert json.loads(arts["model"].metadata) == {"task": "hover", "algo": "ppo", "action_space": "prt", "seed": int(job), "frames": 64}
        assert "frames_64" in arts["model"].aliases


def test_a_population_run_logs_one_wandb_run(wandb_env):
    run_dir = wandb_env / "pop"
    _invoke("train", "task=1v1", "algo=psro_uniform", "algo.start=scratch",
            "env.num_envs=8", "algo.steps_per_batch=16", "algo.minibatches=2", "algo.epochs=1",
            "algo.hidden=[16,16]", "algo.iterations=2", "algo.min_updates=1", "algo.max_updates=1", "algo.payoff_games=2",
            "evaluation.every=0", "evaluation.episodes=2", "evaluation.record=false", "progress=false", "threads=1",
            "logger=wandb", f"hydra.run.dir={run_dir}")
    (records,) = _logs(run_dir)
    (run,) = _of(records, "run")
    assert run.display_name == "1v1_psro_uniform_s0" and run.run_group == "" and list(run.tags) == ["1v1", "psro_uniform", "prt", "torch"]
    steps = sorted(h.step.num for h in _of(records, "history"))
    rows = read_metrics(run_dir / "metrics.csv")
    assert steps == sorted({int(r["frames"]) for r in rows}) and len(steps) >= 1  # every iteration's rows, one run
    # every iteration's rows (the final evaluation of the last mixture is a row of its own, outside them)
    assert {int(r["pop_iteration"]) for r in rows if r.get("pop_iteration") != ""} == {1, 2}
    summary, saved = _summary(records), json.loads((run_dir / "summary.json").read_text())
    assert summary["iterations"] == saved["iterations"] == 2 and summary["population"]["solver"] == "uniform"
    assert summary["population"]["members"] == saved["population"]["members"]


def test_without_wandb_installed_logger_wandb_names_the_extra(monkeypatch, tmp_path):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "wandb" else real(name, *a))
    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(app, ["train", "logger=wandb"])
    assert res.exit_code == 2 and res.stderr.strip().startswith("error: logger=wandb needs the wandb package")
    assert "volleybots[wandb]" in res.stderr and not any(tmp_path.iterdir())
