"""Files received from others cannot stall a verb (issue 57, class 4): a YAML alias bomb is refused
before a loader expands it, metrics.csv is read with the bound every file has, and a label past
``MAX_LABEL`` characters is refused before any table or plot draws it."""

from __future__ import annotations

import time

import numpy as np
import pytest
from helpers import one_line_exit_2, snapshot
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.config import ConfigError
from volleybots.eval.crossplay import MAX_LABEL, CrossPlay, resolve_all
from volleybots.files import MAX_READ_BYTES
from volleybots.runs import RunDir

runner = CliRunner()
# 378 bytes that a YAML loader expands to 9^9 strings
BOMB = 'a: &a ["x","x","x","x","x","x","x","x","x"]\n' + "".join(
    f"{c}: &{c} [*{p},*{p},*{p},*{p},*{p},*{p},*{p},*{p},*{p}]\n" for p, c in zip("abcdefgh", "bcdefghi", strict=True)
) + "hierarchical: {attack: *i}\n"


def test_a_team_file_with_aliases_is_refused_unexpanded(tmp_path):
    (tmp_path / "team.yaml").write_text(BOMB)
    t0 = time.perf_counter()
    one_line_exit_2(runner.invoke(app, ["eval", "crossplay", f"t={tmp_path / 'team.yaml'}", "random", "task=3v3", "games=2",
                                        "--out", str(tmp_path / "o")]), "team.yaml", "YAML alias (*a)")
    assert time.perf_counter() - t0 < 30 and not (tmp_path / "o").exists()


def test_a_run_config_with_aliases_is_refused_and_listed(tiny_1v1_run, copy_run):
    run = copy_run(tiny_1v1_run)
    text = (run / "config.yaml").read_text()
    (run / "config.yaml").write_text("anchor: &big [1, 2]\n" + text + "extra: *big\n")
    before = snapshot(run)
    with pytest.raises(ConfigError, match=r"config.yaml' holds a YAML alias \(\*big\)"):
        RunDir(run).load_config()
    res = runner.invoke(app, ["report", str(run)])
    assert res.exit_code == 0 and "failed" in res.output and "YAML alias" in res.output, res.output
    assert snapshot(run) == before


def test_a_huge_metrics_csv_is_refused_unread(tiny_1v1_run, copy_run):
    run = copy_run(tiny_1v1_run)
    with open(run / "metrics.csv", "r+b") as f:  # sparse: past the bound without using the disk
        f.truncate(MAX_READ_BYTES + 1)
    t0 = time.perf_counter()
    res = runner.invoke(app, ["report", str(run)])
    assert time.perf_counter() - t0 < 30
    assert res.exit_code == 0 and "failed" in res.output and "metrics.csv" in res.output and "larger than" in res.output, res.output


def test_a_label_past_the_bound_is_refused_before_drawing(tmp_path):
    wdl = np.zeros((2, 2, 3))
    wdl[0, 1], wdl[1, 0] = [1, 0, 1], [1, 0, 1]
    CrossPlay(["x" * 100_000, "b"], wdl, {"0,1": "WL"}).save(tmp_path / "cp.json")
    err = one_line_exit_2(runner.invoke(app, ["eval", "elo", f"from={tmp_path / 'cp.json'}", "--out", str(tmp_path / "elo")]),
                          "100,000 characters long", f"at most {MAX_LABEL}")
    assert len(err) < 400 and not (tmp_path / "elo").exists()
    with pytest.raises(ConfigError, match=f"at most {MAX_LABEL}"):
        resolve_all([f"{'y' * (MAX_LABEL + 1)}=random", "scripted"])
    assert [c.label for c in resolve_all([f"{'y' * MAX_LABEL}=random", "scripted"])][0] == "y" * MAX_LABEL
