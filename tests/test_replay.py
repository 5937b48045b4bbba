"""Replays: `volleybots replay` writes a recording that `rerun rrd verify` accepts, holding the court,
net, drones (body, racket, team colour), the ball with its trail, events and per-step rewards."""

from __future__ import annotations

import re
import subprocess

import pytest
import torch
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
    res = runner.invoke(app, ["replay", "random", "task=solo_bump", "threads=1", "--out", str(out), "--no-viewer"])
    assert res.exit_code == 0, res.output
    assert "solo_bump" in res.stdout and str(out) in res.stdout
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


def test_replay_of_the_scripted_policy_or_a_clear_error(tmp_path):
    out = tmp_path / "scripted.rrd"
    res = runner.invoke(app, ["replay", "scripted", "task=solo_bump", "threads=1", "--out", str(out), "--no-viewer"])
    try:
        from volleybots.scripted import make_scripted_policy  # noqa: F401
    except ImportError:
        assert res.exit_code == 2 and "scripted policies are not available" in res.stderr
        assert not out.exists()
        return
    assert res.exit_code == 0, res.output
    assert "/world/ball" in _entities(out)


class FakeRec:
    """Captures what the recorder logs."""

    def __init__(self):
        self.logs: list[tuple[str, object, bool]] = []
        self.times: list[int] = []

    def log(self, path, archetype, static=False):
        self.logs.append((path, archetype, static))

    def set_time(self, timeline, sequence=None):
        self.times.append(sequence)

    def at(self, path):
        return [a for p, a, _ in self.logs if p == path]


def _colour(boxes) -> tuple[int, ...]:
    packed = int(boxes.colors.as_arrow_array().to_pylist()[0])
    return tuple((packed >> s) & 0xFF for s in (24, 16, 8))


def test_recorder_logs_teams_ball_trail_rewards_and_events():
    torch.manual_seed(0)
    env = volleybots.make_env("1v1", num_envs=2, seed=0)
    rec = FakeRec()
    recorder = EpisodeRecorder(rec, env, env_index=1)
    # two teams, two colours
    c0, c1 = _colour(rec.at("world/drone_0/body")[0]), _colour(rec.at("world/drone_1/body")[0])
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
    assert rec.times == [0, 1, 2]
    assert len(rec.at("world/ball")) == 3
    trail = rec.at("world/ball_trail")[-1]
    assert len(trail.strips.as_arrow_array().to_pylist()[0]) == 3  # the trail holds every position so far
    texts = [str(t.text.as_arrow_array().to_pylist()[0]) for t in rec.at("events")]
    assert any("drone 1 racket_hit" in t for t in texts)
    assert not any("ball_net" in t for t in texts)  # env 0's event is not env 1's
    assert len(rec.at("world/hits")) == 1
    rewards = [float(s.scalars.as_arrow_array().to_pylist()[0]) for s in rec.at("reward/drone_1")]
    assert rewards == pytest.approx(expected)  # drone 1's reward of env 1, one scalar per step
