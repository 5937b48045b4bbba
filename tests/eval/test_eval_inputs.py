"""Bad arguments and output paths of the evaluation verbs (issue 32): absurd counts are refused before any game,
an unwritable --out before the games, two writers of one --out never overwrite each other, a full disk is one
line with no temporary file left, and valid input (a run dir named with ',' or '=') is accepted."""

from __future__ import annotations

import errno
import os
import shutil
from pathlib import Path

import pytest
from helpers import hold_lock, one_line_exit_2
from typer.testing import CliRunner

from volleybots.cli import app

runner = CliRunner()
MATCH = ["random", "scripted", "task=1v1", "task.episode_len=20"]


@pytest.fixture
def no_games(monkeypatch):
    """Any game played fails the test: refusals must come before the first."""

    def played(*a, **k):
        raise AssertionError("a game was played")

    monkeypatch.setattr("volleybots.eval.crossplay.play_games", played)


@pytest.mark.parametrize("args, words", [
    (["eval", "crossplay", *MATCH, "seed=99999999999999999999"], ["seed=99999999999999999999", "[0, 4611686018427387904]"]),
    (["eval", "crossplay", *MATCH, "seed=-1"], ["seed=-1"]),
    (["eval", "crossplay", *MATCH, "games=1000000000000000"], ["games=1000000000000000", "needs at least", "lower games"]),
    (["eval", "crossplay", *MATCH, "games=1000000000", "batch=1000000000"], ["batch=1000000000", "lower batch"]),
    (["eval", "crossplay", *MATCH, "batch=0"], ["batch=0", ">= 1"]),
    (["eval", "elo", *MATCH, "rounds=1000000000000000"], ["rounds=1000000000000000"]),
    (["eval", "elo", *MATCH, "k=nan"], ["k=nan"]),
    (["eval", "elo", *MATCH, "k=-3"], ["k=-3"]),
])
def test_absurd_counts_are_refused_before_any_game(args, words, no_games, tmp_path):
    one_line_exit_2(runner.invoke(app, [*args, "--out", str(tmp_path / "o")]), *words)
    assert not (tmp_path / "o").exists()


def test_absurd_rounds_over_a_results_file_are_refused_before_rating(tmp_path):
    from helpers import crossplay_file

    path = crossplay_file(tmp_path / "crossplay.json")
    one_line_exit_2(runner.invoke(app, ["eval", "elo", f"from={path}", "rounds=100000000000000000", "--out", str(tmp_path / "o")]),
                    "rounds=100000000000000000", "lower rounds")


def test_absurd_episodes_are_refused_before_playing(tmp_path):
    one_line_exit_2(runner.invoke(app, ["eval", "random", "task=hover", "episodes=100000000000000"]), "episodes=100000000000000")


def test_an_unwritable_out_is_refused_before_the_games(no_games, tmp_path):
    (tmp_path / "afile").write_text("x")
    one_line_exit_2(runner.invoke(app, ["eval", "crossplay", *MATCH, "games=2", "--out", str(tmp_path / "afile" / "o")]),
                    "afile", "not a directory")
    one_line_exit_2(runner.invoke(app, ["eval", "elo", *MATCH, "rounds=2", "--out", str(tmp_path / "afile" / "o")]), "afile")
    if os.geteuid() != 0:  # root writes anywhere
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o500)
        one_line_exit_2(runner.invoke(app, ["eval", "crossplay", *MATCH, "games=2", "--out", str(ro / "o")]), "no permission")


def test_a_full_disk_is_one_line_and_leaves_no_temporary_file(monkeypatch, tmp_path):
    import volleybots.files

    def full(f, data):
        f.write(b"partial")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(volleybots.files, "_write", full)
    out = tmp_path / "o"
    one_line_exit_2(
        runner.invoke(app, ["eval", "crossplay", *MATCH, "games=2", "--json", "--out", str(out)]), "crossplay.json", "No space left"
    )
    assert not out.exists()  # the folder it made is removed with the lock file
    assert not [p for p in tmp_path.rglob("*") if p.suffix in (".tmp", ".part")]


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_two_writers_of_one_out_never_overwrite_each_other(no_games, tmp_path, monkeypatch):
    out = tmp_path / "o"
    holder = hold_lock(out)
    try:
        one_line_exit_2(runner.invoke(app, ["eval", "crossplay", *MATCH, "games=2", "--out", str(out)]), "being written by another")
        one_line_exit_2(runner.invoke(app, ["eval", "elo", *MATCH, "rounds=2", "--out", str(out)]), "being written by another")
        # a default, time-stamped folder in use moves on to the next name
        from volleybots.runs import output_dir

        with output_dir(None, out) as claimed:
            assert claimed == tmp_path / "o_2"
    finally:
        holder.kill()
        holder.wait()
    assert [p.name for p in out.iterdir()] == [".lock"]


def test_replays_reserve_their_file_and_shorten_long_labels(tmp_path):
    from volleybots.eval.replays import replay_name
    from volleybots.runs import reserve_file

    a = reserve_file(tmp_path / "r.rrd", explicit=False)
    b = reserve_file(tmp_path / "r.rrd", explicit=False)
    assert (a.name, b.name) == ("r.rrd", "r_2.rrd") and a.stat().st_size == 0
    long = replay_name("1v1", ["x" * 300, "y/z"], "20260101-000000")
    assert len(long.encode()) <= 200 and long.startswith("replay_1v1_xxx") and long.endswith("_20260101-000000.rrd")
    assert replay_name("1v1", ["x" * 300, "a"], "s") != replay_name("1v1", ["x" * 300, "b"], "s")
    one_line_exit_2(runner.invoke(app, ["replay", "random", "task=hover", "--no-viewer", "--out", str(tmp_path / ("n" * 300 + ".rrd"))]),
                    "too long for a file name")
    assert not [p for p in tmp_path.iterdir() if p.name.startswith("n")]


def test_a_match_replay_with_a_label_too_long_for_a_file_name_records(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res = runner.invoke(app, ["replay", f"{'x' * 300}=random", "scripted", "task=1v1", "task.episode_len=20", "--no-viewer"])
    assert res.exit_code == 0, res.output
    files = list((tmp_path / "outputs" / "replays").iterdir())
    assert len(files) == 1 and files[0].suffix == ".rrd" and files[0].stat().st_size > 0


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_a_run_dir_named_with_comma_and_equals_is_usable(tiny_1v1_run, tmp_path):
    run = Path(shutil.copytree(tiny_1v1_run, tmp_path / "a,b=c", ignore=shutil.ignore_patterns(".lock")))
    # (20-step games: every verb only has to read the run dir and play)
    res = runner.invoke(app, ["eval", str(run), "episodes=1", "task.episode_len=20", "--json"])
    assert res.exit_code == 0, res.output
    res = runner.invoke(app, ["eval", "crossplay", str(run), "random", "games=2", "task.episode_len=20", "--out", str(tmp_path / "o")])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "o" / "crossplay.json").is_file()
    res = runner.invoke(app, ["eval", "compare", str(run), "random", "episodes=2", "task.episode_len=20"])
    assert res.exit_code == 0, res.output
    res = runner.invoke(app, ["replay", str(run), "--no-viewer", "--out", str(tmp_path / "r.rrd"), "task.episode_len=20"])
    assert res.exit_code == 0, res.output


def test_a_non_ascii_run_dir_gets_the_quoting_hint(tmp_path):
    where = tmp_path / "läufe"
    err = one_line_exit_2(runner.invoke(app, ["train", "task=hover", f"hydra.run.dir={where}"]), "quote it")
    assert f"hydra.run.dir='{where}'" in err and not where.exists()


def test_a_yardstick_of_another_task_is_refused_before_the_run_dir(tmp_path):
    where = tmp_path / "run"
    one_line_exit_2(runner.invoke(app, ["train", "task=1v1", "algo=sp", "algo.eval_opponent=hierarchical", f"hydra.run.dir={where}"]),
                    "population.eval_opponent='hierarchical'", "3v3")
    assert not where.exists()
