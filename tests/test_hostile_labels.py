"""Labels read from a results file are shown as plain text (issue 49): never parsed as Rich markup, and
never sent to the terminal as control characters."""

from __future__ import annotations

import json

import numpy as np
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.eval.crossplay import CrossPlay
from volleybots.eval.plain import clean

runner = CliRunner()
LABELS = ["[bold red]x", "y[/]\x1b]0;owned\x07"]


def test_markup_and_escapes_in_labels_are_printed_as_text(tmp_path):
    wdl = np.array([[[0, 0, 0], [3, 1, 0]], [[0, 1, 3], [0, 0, 0]]], dtype=float)
    res = CrossPlay(LABELS, wdl, {"0,1": "WWDW"}, {"0,1": [[2, 0, 0], [1, 1, 0]]}, {"task": "1v1 [blink]", "games_per_pair": 4, "seed": 0})
    path = tmp_path / "crossplay.json"
    path.write_text(json.dumps(res.to_dict()))
    out = runner.invoke(app, ["eval", "elo", f"from={path}", "rounds=10", "--out", str(tmp_path / "o")], env={"COLUMNS": "400"})
    assert out.exit_code == 0, out.output
    assert "[bold red]x" in out.output and "1v1 [blink]" in out.output
    assert "\x1b" not in out.output and "\x07" not in out.output
    assert "y[/]\\x1b]0;owned\\x07" in out.output


def test_clean_writes_control_characters_out():
    assert clean("a\x1b[2Jb\u202ec") == "a\\x1b[2Jb\\u202ec"
    assert clean("plain [b]label[/b] é") == "plain [b]label[/b] é"
