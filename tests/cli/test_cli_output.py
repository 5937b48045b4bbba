"""What a verb prints where no terminal reads it: tables at their full width in a file or a pipe, and
the progress of a --json run on stderr, its stdout the JSON alone."""

import json

from typer.testing import CliRunner

from volleybots.cli import app

runner = CliRunner()


def test_a_crossplay_table_off_a_terminal_is_not_folded_and_json_keeps_its_progress_on_stderr(tmp_path):
    args = ["eval", "crossplay", "random", "second_random_player=random", "task=1v1", "games=2", "batch=2"]
    res = runner.invoke(app, [*args, "--out", str(tmp_path / "a")])
    assert res.exit_code == 0, res.output
    lines = res.stdout.splitlines()
    # the game-content table is wider than 80 columns; rich folds it to 80 off a terminal unless told
    assert max(len(line) for line in lines) > 120 and "…" not in res.stdout
    assert any("second_random_player" in line and "random" in line for line in lines)
    res = runner.invoke(app, [*args, "--json", "--out", str(tmp_path / "b")])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["labels"] == ["random", "second_random_player"]
    assert res.stderr.startswith("  pair 0,1: W/D/L ")
