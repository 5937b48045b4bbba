"""A run directory received from elsewhere never makes a run write outside it (issue 49): links among the
files a run writes that lead out of the directory are refused before anything is written, and a W&B id
read back from the run is used only if it is an id, never a path."""

from __future__ import annotations

import json
import shutil

from conftest import one_line_exit_2, snapshot
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.train.wandb import run_identity

runner = CliRunner()


def test_a_metrics_csv_linked_out_of_the_run_is_refused_on_resume(tiny_1v1_run, copy_run, tmp_path):
    run = copy_run(tiny_1v1_run)
    outside = tmp_path / "elsewhere.csv"
    shutil.move(run / "metrics.csv", outside)
    (run / "metrics.csv").symlink_to(outside)
    before, text = snapshot(run), outside.read_text()
    one_line_exit_2(runner.invoke(app, ["train", f"resume={run}", "total_frames=256"]), "metrics.csv", "outside the run directory")
    assert outside.read_text() == text and snapshot(run) == before


def test_a_population_folder_linked_out_of_the_run_is_refused_on_resume(tiny_population, copy_run, tmp_path):
    run = copy_run(tiny_population)
    outside = tmp_path / "elsewhere"
    shutil.move(run / "population", outside)
    (run / "population").symlink_to(outside)
    before = snapshot(outside)
    one_line_exit_2(runner.invoke(app, ["train", f"resume={run}", "algo.iterations=2", "total_frames=512"]), "population",
                    "outside the run directory")
    assert snapshot(outside) == before and sorted(p.name for p in outside.iterdir()) == [
        "member_000.pt", "member_001.pt", "meta.jsonl", "payoffs.json"]


def test_a_lock_file_linked_out_of_the_run_is_never_truncated(tiny_1v1_run, copy_run, tmp_path):
    run = copy_run(tiny_1v1_run)
    outside = tmp_path / "precious.txt"
    outside.write_text("keep me\n")
    (run / ".lock").symlink_to(outside)
    one_line_exit_2(runner.invoke(app, ["train", f"resume={run}", "total_frames=256"]), ".lock", "outside the run directory")
    assert outside.read_text() == "keep me\n"


def test_a_wandb_id_with_path_segments_is_not_used(tmp_path, capsys):
    (tmp_path / "wandb_run.json").write_text(json.dumps({"id": "../../escape", "group": None}))
    identity = run_identity(tmp_path, resume=True)
    assert identity["id"] != "../../escape" and len(identity["id"]) == 16 and identity["id"].isalnum()
    assert "damaged" in capsys.readouterr().err
    assert json.loads((tmp_path / "wandb_run.json").read_text())["id"] == identity["id"]
    # a well-formed id is read back as it was saved
    assert run_identity(tmp_path, resume=True)["id"] == identity["id"]
