"""No escape sequence from a command line or a received file reaches the terminal (issue 57, class 6):
every line the CLI prints (results, progress, the one error line) shows control characters written
out, so a label or a folder name cannot retitle (OSC) or recolour (CSI) the user's terminal."""

from __future__ import annotations

from helpers import one_line_exit_2
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.files import printable

runner = CliRunner()
OSC, CSI = "\x1b]0;PWN\x07", "\x1b[31m"


def test_a_label_with_escapes_is_shown_written_out(tmp_path):
    res = runner.invoke(app, ["replay", f"{CSI}RED{OSC}=random", "scripted", "task=1v1", "--no-viewer", "--out", str(tmp_path / "m.rrd")])
    assert res.exit_code == 0, res.output
    assert "\x1b" not in res.output and "\x07" not in res.output
    assert "\\x1b[31mRED\\x1b]0;PWN\\x07 (blue)" in res.output


def test_a_refused_value_with_escapes_is_one_line_written_out(tmp_path):
    res = runner.invoke(app, ["train", "task=1v1", f"hydra.run.dir={tmp_path}/run{OSC}", "total_frames=10", "threads=1"])
    err = one_line_exit_2(res, "hydra.run.dir")
    assert "\x1b" not in res.output and "\\x1b]0;PWN\\x07" in err
    res = runner.invoke(app, [f"bogus{OSC}"])
    assert res.exit_code == 2 and "\x1b" not in res.output and "bogus\\x1b]0;PWN\\x07" in res.output


def test_printable_keeps_text_and_writes_out_every_control_character():
    assert printable("ball à 3 m") == "ball à 3 m"
    assert printable(f"a{OSC}\u202eb\n") == "a\\x1b]0;PWN\\x07\\u202eb\\n"
