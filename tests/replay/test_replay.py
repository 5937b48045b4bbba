"""Replays: `volleybots replay` writes a recording that `rerun rrd verify` accepts, holding the court,
net, drones (body, racket, team colour), the ball with its trail, events and per-step rewards."""

from __future__ import annotations

import re
import subprocess

import numpy as np
import pytest
import torch
from helpers import FakeRec
from typer.testing import CliRunner

import volleybots
from volleybots.cli import app
from volleybots.replay import TEAM_COLOURS, EpisodeRecorder

runner = CliRunner()


def _entities(path) -> set[str]:
    verify = subprocess.run(["rerun", "rrd", "verify", str(path)], capture_output=True, text=True, timeout=300)
    assert verify.returncode == 0, verify.stdout + verify.stderr
    out = subprocess.run(["rerun", "rrd", "print", str(path)], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return set(re.findall(r"/(?:world|events|reward|episode)[\w/]*", out.stdout))


def test_replay_writes_a_verified_recording_with_the_scene(tmp_path, monkeypatch):
    monkeypatch.setenv("DISPLAY", ":0")  # a display exists, but --no-viewer must keep the viewer closed
    import rerun as rr

    monkeypatch.setattr(rr.RecordingStream, "spawn", lambda *a, **k: pytest.fail("viewer spawned despite --no-viewer"))
    out = tmp_path / "ep.rrd"
    still = tmp_path / "ep.png"
    res = runner.invoke(app, ["replay", "random", "task=solo_bump", "threads=1", "--out", str(out), "--still", str(still), "--no-viewer"])
    assert res.exit_code == 0, res.output
    assert "solo_bump" in res.stdout and str(out) in res.stdout and str(still) in res.stdout
    assert still.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    ents = _entities(out)
    for e in ("/world/court", "/world/net", "/world/drone_0", "/world/drone_0/body", "/world/drone_0/racket",
              "/world/ball", "/world/ball_trail", "/events", "/reward/drone_0", "/episode/return",
              "/episode/bumps", "/episode/r_success_hit", "/episode/r_misbehave"):
        assert e in ents, (e, sorted(ents))
    assert not list(tmp_path.glob("*.part"))  # written whole, then moved into place


def test_replay_picks_a_fresh_default_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for _ in range(2):
        res = runner.invoke(app, ["replay", "random", "task=hover", "threads=1", "--no-viewer"])
        assert res.exit_code == 0, res.output
    files = sorted((tmp_path / "outputs" / "replays").glob("replay_hover_random_*.rrd"))
    assert len(files) == 2  # the second replay did not overwrite the first


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_replay_of_the_scripted_policy_or_a_clear_error(tmp_path):
    out = tmp_path / "scripted.rrd"
    # 100 steps hold the opening bump: the recording's layout is the point, not the player's whole 16 s (18 s to play)
    res = runner.invoke(app, ["replay", "scripted", "task=solo_bump", "task.episode_len=100", "threads=1", "--out", str(out),
                              "--no-viewer"])
    try:
        from volleybots.scripted import make_scripted_policy  # noqa: F401
    except ImportError:
        assert res.exit_code == 2 and "scripted policies are not available" in res.stderr
        assert not out.exists()
        return
    assert res.exit_code == 0, res.output
    assert "/world/ball" in _entities(out)




def _colour(boxes) -> tuple[int, ...]:
    packed = int(boxes.colors.as_arrow_array().to_pylist()[0])
    return tuple((packed >> s) & 0xFF for s in (24, 16, 8))


def test_recorder_logs_teams_ball_trail_rewards_and_events():
    torch.manual_seed(0)
    env = volleybots.make_env("1v1", num_envs=2, seed=0)
    rec = FakeRec()
    recorder = EpisodeRecorder(rec, env, env_index=1)
    # two teams, two colours
    c0, c1 = _colour(rec.at("world/drone_0/body", static=True)[0]), _colour(rec.at("world/drone_1/body", static=True)[0])
    assert {c0, c1} == set(TEAM_COLOURS)
    td = env.reset()
    expected = []
    for step in range(3):
        td = env.rand_action(td)
        td = env.step(td)
        if step == 1:  # the referee saw drone 1 hit the ball in env 1, and the ball touch the net in env 0
            ev = env.last_events
            ev.racket_hit[:] = False
            ev.racket_hit[1, 1] = True
            ev.ball_net[:] = torch.tensor([True, False])
        recorder(env, td, td["next"])
        expected.append(float(td["next", "agents", "reward"][1, 1]))
        td = td["next"]
    assert not rec.at("world/ball")  # kept until the episode ends (or flush), then sent as columns
    recorder.flush()
    recorder.flush()  # once only
    assert rec.steps["world/ball"] == [0, 1, 2] and rec.steps["reward/drone_1"] == [0, 1, 2]
    assert len(rec.at("world/ball")) == 3
    trail = rec.at("world/ball_trail")[-1]
    assert len(trail.strips.as_arrow_array().to_pylist()[0]) == 3  # the trail holds every position so far
    texts = [str(t.text.as_arrow_array().to_pylist()[0]) for t in rec.at("events")]
    assert any("drone 1 racket_hit" in t for t in texts)
    assert not any("ball_net" in t for t in texts)  # env 0's event is not env 1's
    assert len(rec.at("world/hits")) == 1
    rewards = [float(s.scalars.as_arrow_array().to_pylist()[0]) for s in rec.at("reward/drone_1")]
    assert rewards == pytest.approx(expected)  # drone 1's reward of env 1, one scalar per step


# ------------------------------------------------------------------ columns, layout, still
# value-by-value logging (one rr.log per value, before the columns; rerun 0.41) wrote 5,936,197 bytes
# for the 500-step scripted 3v3 rally of `volleybots replay scripted task=3v3`
VALUE_BY_VALUE_3V3_BYTES_PER_STEP = 5_936_197 / 500


def _record(path, task, **task_kw):
    from volleybots.replay import record_episode

    torch.manual_seed(0)
    env = volleybots.make_env(task, num_envs=1, seed=0, **task_kw)
    return record_episode(env, env.rand_action, path)


def _chunks_per_entity(path) -> dict[str, int]:
    out = subprocess.run(["rerun", "rrd", "stats", str(path)], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return {m[0]: int(m[1]) for m in re.findall(r"^(/[\w/\-]+): (\d+)$", out.stdout, re.MULTILINE)}


def _dump(path) -> str:
    out = subprocess.run(["rerun", "rrd", "print", "-vvv", str(path)], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return out.stdout


def test_a_recording_is_columns_small_and_holds_its_layout(tmp_path):
    long, short = tmp_path / "long.rrd", tmp_path / "short.rrd"
    stats = _record(long, "3v3")
    cut = _record(short, "3v3", episode_len=8)
    assert stats["episode_len"] >= 30 and cut["episode_len"] == 8
    size = long.stat().st_size
    assert size < 300_000, size  # 47 steps, six drones: about 230 KB, mostly rerun's per-chunk headers
    # what one more step costs, against what it cost logged value by value: at least ten times less
    per_step = (size - short.stat().st_size) / (stats["episode_len"] - cut["episode_len"])
    assert 10 * per_step <= VALUE_BY_VALUE_3V3_BYTES_PER_STEP, per_step
    chunks = _chunks_per_entity(long)
    for ent in (
        "/world/drone_0",
        "/world/drone_5",
        "/reward/drone_3",
        "/episode/return",
        "/score/touches_team1",
        "/score/points_team0",
        "/events",
    ):
        assert chunks.get(ent) == 1, (ent, chunks.get(ent))  # the whole episode in one send
    assert chunks["/world/ball"] == chunks["/world/ball_trail"] == 2  # and one static chunk for its colour and size
    dump = _dump(long)
    assert "Blueprint" in dump and "ViewportBlueprint:root_container" in dump
    for name in ("court (match)", "team 0 (blue) rewards", "team 1 (red) rewards", "score and touches per team", "how it ended", "events"):
        assert name in dump, name


def test_the_summary_names_how_it_ended_and_the_score():
    from volleybots.rules import Referee

    torch.manual_seed(1)
    env = volleybots.make_env("1v1", num_envs=1, seed=1)
    rec = FakeRec()
    recorder = EpisodeRecorder(rec, env, labels=("A", "B"))
    td = env.reset()
    while not recorder.sent:
        td = env.step(env.rand_action(td))
        recorder(env, td, td["next"])
        td = td["next"]
    (doc,) = rec.at("summary", static=True)
    text = str(doc.text.as_arrow_array().to_pylist()[0])
    winner, reason = int(recorder.stats["winner"][-1]), int(recorder.stats["reason"][-1])
    assert f"after **{recorder.step}** control steps the episode ended" in text
    if winner < 0:
        assert "no point" in text and "A (blue) 0 - 0 B (red)" in text
    else:
        loser = ("A (blue)", "B (red)")[1 - winner]
        assert f"{loser} faulted (**{Referee.FAULTS[reason]}**)" in text and f"**{int(winner == 0)} - {int(winner == 1)}**" in text
    points = [float(r.scalars.as_arrow_array().to_pylist()[0]) for r in rec.at(f"score/points_team{max(winner, 0)}")]
    assert points[:-1] == [0.0] * (len(points) - 1) and points[-1] == float(winner >= 0)
    assert len(rec.blueprints) == 1 and "team 1 (red) rewards" in _views(rec.blueprints[0])


def _views(blueprint) -> dict:
    found, stack = {}, [blueprint.root_container]
    while stack:
        c = stack.pop()
        if hasattr(c, "class_identifier"):
            found[str(c.name)] = c
        else:
            stack.extend(c.contents)
    return found


def test_the_layout_per_task_kind():
    from volleybots.replay.layout import episode_blueprint, task_kind

    assert [task_kind(t) for t in ((0,), (0, 0, 0), (0, 1))] == ["single", "cooperative", "match"]
    keys = ["return", "episode_len", "win", "winner", "reason", "hits_team0", "hits_team1", "r_win_or_lose", "r_success_hit"]
    match = episode_blueprint((0, 0, 0, 1, 1, 1), keys, drills=True)
    root = match.root_container
    assert type(root.contents[0]).__name__ == "Spatial3DView" and list(root.column_shares) == [3, 2]  # the court, large
    views = _views(match)
    assert views["team 0 (blue) rewards"].contents == ["+ /reward/drone_0", "+ /reward/drone_1", "+ /reward/drone_2"]
    assert views["team 1 (red) rewards"].contents == ["+ /reward/drone_3", "+ /reward/drone_4", "+ /reward/drone_5"]
    assert views["return and reward terms"].contents == ["+ /episode/return", "+ /episode/r_win_or_lose", "+ /episode/r_success_hit"]
    assert views["episode figures"].contents == ["+ /episode/episode_len"]  # a match's bookkeeping is in the summary
    assert "+ /score/**" in views["score and touches per team"].contents and "drill per drone (high level)" in views
    assert type(views["how it ended"]).__name__ == "TextDocumentView"
    coop = _views(episode_blueprint((0, 0, 0), ["return", "hits"]))
    assert coop["reward per drone"].contents == ["+ /reward/drone_0", "+ /reward/drone_1", "+ /reward/drone_2"]
    assert "court (cooperative)" in coop and not any("score" in n or "team" in n for n in coop)
    single = _views(episode_blueprint((0,), ["return", "bumps", "r_misbehave"]))
    assert {"court (single drone)", "reward", "return and reward terms", "episode figures", "how it ended", "events"} == set(single)


def test_curves_are_columns_grouped_by_quantity(tmp_path):
    from volleybots.replay import write_curves

    csv = tmp_path / "metrics.csv"
    rows = ["phase,frames,iteration,fps,return,bumps,loss_policy,entropy,r_success_hit"]
    rows += [f"train,{1024 * i},{i},{5000 + i},{0.5 * i},{i % 3},{1.0 / i},{0.9},{0.1 * i}" for i in range(1, 41)]
    rows += [f"eval,{1024 * i},,,{0.4 * i},{i % 2},,," for i in (10, 20, 30, 40)]
    csv.write_text("\n".join(rows) + "\n")
    out = tmp_path / "curves.rrd"
    write_curves(csv, out)
    chunks = _chunks_per_entity(out)
    assert chunks["/train/return"] == 1 and chunks["/train/loss_policy"] == 1 and chunks["/eval/bumps"] == 1
    assert "/eval/fps" not in chunks  # empty cells are no points
    dump = _dump(out)
    for name in ("train: task figures", "train: losses", "train: throughput", "train: reward terms", "eval: task figures"):
        assert name in dump, name


def _team_pixels(img, colour) -> int:
    rgb = img[..., :3] * 255
    return int((np.abs(rgb - np.asarray(colour)).max(-1) < 12).sum())


def test_the_still_draws_the_recorded_episode(tmp_path):
    from matplotlib.image import imread

    from volleybots.replay.still import draw_still

    torch.manual_seed(0)
    env = volleybots.make_env("1v1", num_envs=1, seed=0)
    recorder = EpisodeRecorder(FakeRec(), env)
    td = env.reset()
    for _ in range(20):
        td = env.step(env.rand_action(td))
        recorder(env, td, td["next"])
        td = td["next"]
    out = draw_still(recorder.episode(), tmp_path / "still.png", "1v1")
    img = imread(out)
    assert img.shape[:2] == (460, 800) and 5_000 < out.stat().st_size < 200_000
    assert img[..., :3].std() > 0.05  # a picture, not a blank
    for colour in TEAM_COLOURS:
        assert _team_pixels(img, colour) > 20, colour  # both teams' drones are drawn in their colours
    assert not list(tmp_path.glob("*.part"))


def test_the_committed_still_of_a_3v3_rally():
    from pathlib import Path

    from matplotlib.image import imread

    png = Path(__file__).resolve().parents[2] / "docs" / "img" / "rally_3v3.png"
    assert png.stat().st_size < 200_000
    img = imread(png)
    assert img.shape[:2] == (460, 800) and all(_team_pixels(img, c) > 20 for c in TEAM_COLOURS)


@pytest.mark.parametrize("argv, words", [
    (["--still", "{tmp}/x.jpg"], ["--still", "x.jpg", ".png"]),
    (["--still", "{tmp}/exists.png"], ["--still", "exists.png", "exists"]),
    (["a=random", "--still", "{tmp}/m.png"], ["--still", "one policy"]),
])
def test_bad_still_is_one_line_and_writes_nothing(tmp_path, argv, words):
    (tmp_path / "exists.png").write_bytes(b"x")
    argv = [a.format(tmp=tmp_path) for a in argv]
    res = runner.invoke(app, ["replay", "random", *argv, "task=hover", "--out", str(tmp_path / "r.rrd"), "--no-viewer"])
    assert res.exit_code == 2, res.output
    assert len(res.stderr.strip().splitlines()) == 1 and all(w in res.stderr for w in words), res.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["exists.png"]
