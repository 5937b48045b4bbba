"""Nothing already written is lost or mixed with another writer's output (issue 49): a finished run whose
checkpoints are gone is never started afresh over its results; a still picture and a report's folder are
claimed before they are written, so a second writer is refused; a population resume reads its payoff
table and metrics.csv before it changes any file of the run."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
from helpers import hold_lock, one_line_exit_2, snapshot
from typer.testing import CliRunner

from volleybots.cli import app

runner = CliRunner()


def test_a_finished_run_without_checkpoints_is_never_started_afresh(tiny_1v1_run, copy_run):
    run = copy_run(tiny_1v1_run)
    shutil.rmtree(run / "checkpoints")
    before = snapshot(run)
    one_line_exit_2(runner.invoke(app, ["train", f"resume={run}", "total_frames=256"]), "finished run", "checkpoints are gone")
    assert snapshot(run) == before
    from volleybots.config import ConfigError, load
    from volleybots.runs import RunDir

    with pytest.raises(ConfigError, match="finished run"):
        RunDir(run).create(load(["task=1v1", "algo=mappo"]))
    assert {k: v for k, v in snapshot(run).items() if not k.endswith(".lock")} == before


def test_a_still_is_reserved_before_the_episode(tiny_1v1_run, tmp_path, monkeypatch):
    import volleybots.replay

    still = tmp_path / "new" / "folder" / "a.png"
    seen = {}

    def record(env, policy, out, viewer=False, still=None):
        seen["reserved"] = still is not None and still.is_file()
        raise KeyboardInterrupt  # the episode is cut short: the reserved file goes with it

    monkeypatch.setattr(volleybots.replay, "record_episode", record)
    runner.invoke(app, ["replay", str(tiny_1v1_run), "--no-viewer", "--out", str(tmp_path / "a.rrd"), "--still", str(still)])
    assert seen == {"reserved": True} and not still.exists()
    still.write_bytes(b"")  # another replay holds it: refused before any episode
    seen.clear()
    one_line_exit_2(runner.invoke(app, ["replay", str(tiny_1v1_run), "--no-viewer", "--out", str(tmp_path / "b.rrd"), "--still",
                                        str(still)]), "--still", "exists")
    assert seen == {}


def test_a_still_into_an_unwritable_folder_is_refused_before_the_episode(tiny_1v1_run, tmp_path):
    if os.geteuid() == 0:
        blocked = tmp_path / "file"
        blocked.write_text("")
        still = blocked / "a.png"  # a file where the folder should be: no user can write there
    else:
        locked = tmp_path / "ro"
        locked.mkdir(mode=0o500)
        still = locked / "a.png"
    one_line_exit_2(runner.invoke(app, ["replay", str(tiny_1v1_run), "--no-viewer", "--out", str(tmp_path / "a.rrd"), "--still",
                                        str(still)]), "--still")
    assert not (tmp_path / "a.rrd").exists()


def test_two_reports_to_one_folder_never_mix(tiny_1v1_run, tmp_path):
    out = tmp_path / "report"
    holder = hold_lock(out)
    try:
        one_line_exit_2(runner.invoke(app, ["report", str(tiny_1v1_run), "--out", str(out)]), "being written by another report")
    finally:
        holder.kill()
        holder.wait()
    assert [p.name for p in out.iterdir()] == [".lock"]
    assert runner.invoke(app, ["report", str(tiny_1v1_run), "--out", str(out)]).exit_code == 0
    assert (out / "report.md").is_file()
    one_line_exit_2(runner.invoke(app, ["report", str(tiny_1v1_run), "--out", str(out)]), "already holds a report")


@pytest.mark.parametrize("name, text, words", [
    ("population/payoffs.json", '{"members": ["random"', ["payoffs.json", "not JSON"]),
    ("metrics.csv", "a,b\n1,2\n", ["metrics.csv", "'frames'"]),
])
def test_a_population_resume_reads_its_files_before_changing_any(name, text, words, tiny_population, copy_run):
    run = copy_run(tiny_population)
    Path(run / name).write_text(text)
    before = snapshot(run)
    one_line_exit_2(runner.invoke(app, ["train", f"resume={run}", "algo.iterations=2", "total_frames=512"]), *words)
    assert snapshot(run) == before
