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


def test_eval_names_a_matchs_outcome_codes_and_gives_their_legend():
    """``winner`` / ``reason`` / ``serve_team`` are codes: counted by name (the referee's faults), never averaged."""
    import torch
    from rich.console import Console

    from volleybots.eval import format_table, outcome_counts

    res = {"win": torch.tensor([1.0, 0, 0, 0, 0]), "winner": torch.tensor([0.0, 1, -1, -1, 0]),
           "reason": torch.tensor([7.0, 5, -1, -1, 12]), "serve_team": torch.tensor([0.0, 0, 1, 1, 0])}
    counts = outcome_counts(res)
    assert counts == {"winner": {"team0": 2, "team1": 1, "draw": 2}, "reason": {"ball_out": 1, "landed": 1, "none": 2, "code 12": 1},
                      "serve_team": {"team0": 3, "team1": 2}}
    assert outcome_counts({"win": torch.tensor([1.0])}) == {}  # a drill has no codes
    result = {"target": "scripted", "task": "1v1", "action_space": "prt", "episodes": 5, "metric": "win", "outcomes": counts,
              "stats": {k: {"mean": float(v.mean()), "std": 0.0} for k, v in res.items()}}
    console = Console(width=100, record=True)
    console.print(format_table(result))
    text = console.export_text()
    assert "won by" in text and "team0 2, team1 1, draw 2" in text and "ball_out 1, landed 1, none 2, code 12 1" in text
    assert "  landed: the ball landed in the team's half" in text and "  none: no fault: a draw" in text
    assert "winner" not in text and "reason" not in text  # no mean of a code


def test_eval_json_of_a_match_counts_its_outcomes_by_name():
    res = runner.invoke(app, ["eval", "scripted", "task=1v1", "episodes=2", "task.episode_len=30", "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    # 30 steps: no rally is decided, every episode is a draw at the time limit
    assert out["outcomes"]["winner"] == {"draw": 2} and out["outcomes"]["reason"] == {"none": 2}
    assert sum(out["outcomes"]["serve_team"].values()) == 2


def test_crossplay_elo_and_bench_tell_done_total_and_eta_on_stderr(tmp_path):
    import re

    step = r"\[(\d)/(\d) {} \((\d+) %\), elapsed \d+:\d\d:\d\d, ETA (\d+:\d\d:\d\d|-)\]$"
    args = ["random", "b=random", "c=random", "task=1v1", "batch=2"]
    for verb, games in (("crossplay", "games=2"), ("elo", "rounds=2")):  # elo's rounds are its games per pair
        res = runner.invoke(app, ["eval", verb, *args, games, "--json", "--out", str(tmp_path / verb)])
        assert res.exit_code == 0, res.output
        lines = res.stderr.splitlines()
        found = [re.search(step.format("pairs"), line) for line in lines if line.startswith("  pair ")]
        assert [(m[1], m[2], m[3]) for m in found] == [("1", "3", "33"), ("2", "3", "67"), ("3", "3", "100")], res.stderr
        assert found[-1][4] == "0:00:00"
    res = runner.invoke(app, ["bench", "task=hover", "backend=torch", "num_envs=[2,3]", "repeats=1", "steps=2", "--json"])
    assert res.exit_code == 0, res.output
    found = [re.search(step.format("rows"), line) for line in res.stderr.splitlines()]
    assert [(m[1], m[2], m[3]) for m in found] == [("1", "2", "50"), ("2", "2", "100")], res.stderr


def test_bench_plans_as_many_rows_as_it_measures():
    from volleybots.bench import _env_cases, _train_cases

    cases = _env_cases(("hover",), ("torch", "mujoco"), (2, 4), ("cpu", "cuda"), (False, True))
    # per env count: torch on 2 devices x 2 compile modes, MuJoCo once (CPU, nothing to compile)
    assert len(cases) == 10 and cases[:5] == [("hover", "torch", 2, "cpu", False), ("hover", "torch", 2, "cpu", True),
                                              ("hover", "torch", 2, "cuda", False), ("hover", "torch", 2, "cuda", True),
                                              ("hover", "mujoco", 2, "cpu", False)]
    trained = _train_cases(("solo_bump", "3v3"), (8,), ("cpu",), False)
    assert [(t[0], t[-1]) for t in trained] == [("solo_bump", None), ("3v3", None), ("3v3", "sp"), ("3v3", "psro oracle"),
                                                ("3v3", "best response")]


def test_tables_fit_a_terminal_of_80_columns_as_records_with_every_label_whole(tmp_path, monkeypatch):
    """On a terminal narrower than a table, each row becomes a record (its cells under their columns' names),
    not rich's folding into cells of a few letters (``zoo:1v1/fsp_…``, ``touch…``)."""
    import importlib
    import io

    from rich.console import Console

    cli_app = importlib.import_module("volleybots.cli.app")  # the module: the package's attribute ``app`` is the Typer app
    screens = []

    def terminal():
        screens.append(io.StringIO())
        return Console(file=screens[-1], width=80, force_terminal=False)

    monkeypatch.setattr(cli_app, "console", terminal)
    labels = ["a_long_label_for_the_first_player=random", "another_long_label_for_the_second=random"]
    res = runner.invoke(app, ["eval", "crossplay", *labels, "task=1v1", "games=2", "batch=2", "--out", str(tmp_path / "cp")])
    assert res.exit_code == 0, res.output
    res = runner.invoke(app, ["eval", "elo", f"from={tmp_path / 'cp' / 'crossplay.json'}", "rounds=10", "--out", str(tmp_path / "elo")])
    assert res.exit_code == 0, res.output
    crossplay, elo = (s.getvalue() for s in screens)
    for text in (crossplay, elo):
        assert max(len(line) for line in text.splitlines()) <= 80 and "…" not in text, text
        for name in ("a_long_label_for_the_first_player", "another_long_label_for_the_second"):
            assert name in text
    # the matrix as records: a row's heading, then each column's cell after the column's name
    lines = crossplay.splitlines()
    assert lines[1] == "a_long_label_for_the_first_player"
    assert lines[2].split() == ["a_long_label_for_the_first_player", "-"] and lines[3].split()[0] == "another_long_label_for_the_second"
    assert any(line.split()[:3] == ["rally", "touches", "(max)"] for line in lines)  # a header of three lines on one


def test_a_table_that_fits_keeps_its_shape():
    import io

    from rich.console import Console
    from rich.table import Table

    from volleybots.cli.app import show

    table = Table(title="t")
    table.add_column("name")
    table.add_column("value")
    table.add_row("a", "1")
    out = io.StringIO()
    show(table, Console(file=out, width=80))
    assert "┃ name ┃ value ┃" in out.getvalue()
