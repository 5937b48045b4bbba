"""Games, cross-play, ratings from the command line and match replays, on 1 vs 1 with the scripted and
random players (fast) and a tiny trained checkpoint (for file hashes and fitting checks)."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.config import load
from volleybots.eval.crossplay import CrossPlay, crossplay
from volleybots.play.games import play_games
from volleybots.policies import resolve_competitor
from volleybots.version import play_code

runner = CliRunner()


def _cfg(task="1v1"):
    return load([f"task={task}"])


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_scripted_beats_random_on_both_sides_equally_often():
    a, b = resolve_competitor("scripted"), resolve_competitor("random")
    g = play_games(_cfg(), a, b, 64, seed=0, batch=32)
    assert g.wdl.sum(1).tolist() == [32, 32]  # each side played half the games
    w, d, l_ = g.total
    assert w + l_ >= 16  # enough decisive games for the rate to mean something
    assert w / (w + l_) >= 0.95
    assert len(g.outcomes) == 64 and g.outcomes.count("W") == w
    assert g.faults[1].sum() == w and g.faults[0].sum() == l_  # every point is a fault of the loser


def test_serve_scenarios_fix_who_serves():
    a, b = resolve_competitor("random"), resolve_competitor("r=random")  # cheap players: who serves is the env's
    cfg = _cfg()
    assert play_games(cfg, a, b, 8, batch=4, scenario="serve").served == 8
    assert play_games(cfg, a, b, 8, batch=4, scenario="receive").served == 0
    assert 0 < play_games(cfg, a, b, 40, batch=20, scenario="any").served < 40


def test_games_are_determined_by_the_seed():
    a, b = resolve_competitor("random"), resolve_competitor("r=random")
    cfg = _cfg()
    g1, g2 = (play_games(cfg, a, b, 20, seed=3, batch=10) for _ in range(2))
    g3 = play_games(cfg, a, b, 20, seed=4, batch=10)
    assert g1.outcomes == g2.outcomes and g1.outcomes != g3.outcomes


def test_a_competitor_against_itself_is_near_even():
    comps = [resolve_competitor("a=random"), resolve_competitor("b=random")]
    res = crossplay(_cfg(), comps, 400, seed=1, batch=200)
    wr = res.win_rate()
    assert res.decisive()[0, 1] >= 200
    assert abs(wr[0, 1] - 0.5) < 0.1 and wr[0, 1] + wr[1, 0] == pytest.approx(1.0)
    lo, hi = res.interval()
    assert lo[0, 1] < 0.5 < hi[0, 1]  # the 95 % interval covers even odds
    assert np.isnan(wr[0, 0])  # a competitor is not played against itself
    assert res.payoffs() == pytest.approx(-res.payoffs().T)


@pytest.fixture(scope="module")
def tiny_ckpt(tiny_run):
    """A tiny 1v1 training run (seconds, in this process): its final checkpoint is a competitor with a file."""
    return tiny_run(
        "task=1v1", "algo=mappo", "total_frames=256", "env.num_envs=8", "algo.steps_per_batch=16", "algo.minibatches=2",
        "algo.epochs=1", "algo.hidden=[32,32]", "evaluation.episodes=2", "evaluation.every=0",
    )


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_crossplay_cli_writes_results_with_every_file_hash(tiny_ckpt, tmp_path):
    out = tmp_path / "cp"
    ckpt = tiny_ckpt / "checkpoints" / "final.pt"
    res = runner.invoke(app, ["eval", "crossplay", f"net={ckpt}", "scripted", "random", "games=8", "batch=4", "--out", str(out), "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert data == json.loads((out / "crossplay.json").read_text())
    assert (out / "crossplay.png").stat().st_size > 10_000
    import hashlib

    comp = {c["label"]: c for c in data["competitors"]}
    assert comp["net"]["members"][0]["sha256"] == hashlib.sha256(ckpt.read_bytes()).hexdigest()
    assert comp["net"]["spec"] == f"net={ckpt}" and comp["scripted"]["members"] == [{"kind": "scripted"}]
    assert data["task"] == "1v1" and data["games_per_pair"] == 8 and data["versions"]["torch"]
    wdl = np.array(data["wdl"])
    assert wdl.sum(-1)[np.triu_indices(3, 1)].tolist() == [8, 8, 8]
    assert (wdl == wdl.transpose(1, 0, 2)[..., ::-1]).all()
    for key, sides in data["side_wdl"].items():
        assert [sum(s) for s in sides] == [4, 4], key
    # the results file reads back and re-derives the same table
    back = CrossPlay.load(out / "crossplay.json")
    assert back.labels == ["net", "scripted", "random"] and np.array_equal(back.wdl, wdl)
    # the trained competitor against itself, under two labels
    res = runner.invoke(
        app, ["eval", "crossplay", f"a={ckpt}", f"b={tiny_ckpt}", "games=40", "batch=20", "--out", str(tmp_path / "self"), "--json"]
    )
    assert res.exit_code == 0, res.output
    d = json.loads(res.stdout)
    dec = d["wdl"][0][1][0] + d["wdl"][0][1][2]
    assert dec >= 10 and abs(d["win_rate"][0][1] - 0.5) < 0.25  # same policy: even up to noise


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_elo_cli_played_and_from_a_results_file(tmp_path):
    out = tmp_path / "elo"
    res = runner.invoke(
        app, ["eval", "elo", "scripted", "random", "task=1v1", "rounds=40", "batch=20", "k=32", "--out", str(out), "--json"]
    )
    assert res.exit_code == 0, res.output
    rep = json.loads(res.stdout)
    assert rep["elo"]["games"] == "played" and rep["elo"]["k"] == 32
    elo, bt = rep["elo"]["ratings"], rep["bradley_terry"]
    assert elo[0] > 1000 > elo[1] and sum(elo) == pytest.approx(2000)
    assert bt["ratings"][0] > bt["ratings"][1] and bt["low"][0] > bt["high"][1]
    assert rep["nash"] == pytest.approx([1.0, 0.0]) and rep["exploitability_in_population"][0] == pytest.approx(0.0)
    assert rep["exploitability_in_population"][1] > 0
    for f in ("crossplay.json", "crossplay.png", "ratings.json", "ratings.png"):
        assert (out / f).is_file(), f
    # Elo sampled from the file's frequencies: same order, BT identical (same counts)
    res = runner.invoke(
        app, ["eval", "elo", f"from={out / 'crossplay.json'}", "rounds=200", "k=16", "--out", str(tmp_path / "again"), "--json"]
    )
    assert res.exit_code == 0, res.output
    rep2 = json.loads(res.stdout)
    assert rep2["elo"]["games"] == "sampled" and rep2["elo"]["rounds"] == 200
    assert rep2["elo"]["ratings"][0] > rep2["elo"]["ratings"][1]
    assert rep2["bradley_terry"]["ratings"] == pytest.approx(bt["ratings"])


def test_match_replay_records_teams_touches_and_the_ending(tmp_path):
    from volleybots.replay import MatchLog

    messages = []

    class Rec:
        def log(self, path, obj, static=False):
            if hasattr(obj, "as_component_batches"):
                messages.append((path, str([b.as_arrow_array() for b in obj.as_component_batches()])))

    out = tmp_path / "m.rrd"
    res = runner.invoke(
        app, ["replay", "scripted", "rnd=random", "task=1v1", "scenario=receive", "threads=1", "--out", str(out), "--no-viewer"]
    )
    assert res.exit_code == 0, res.output
    assert "scripted (blue) against rnd (red)" in res.stdout and "scripted (blue) won" in res.stdout
    listing = subprocess.run(["rerun", "rrd", "print", str(out)], capture_output=True, text=True, timeout=300).stdout
    for ent in ("/match", "/score/touches_team0", "/world/drone_1/body", "/events"):
        assert ent in listing, ent
    # the log's words: colours at the start, the point and the fault at the end
    import torch

    import volleybots

    env = volleybots.make_env("1v1", num_envs=1)
    log = MatchLog(Rec(), env, ("A", "B"))
    stats = {"hits_team0": 1.0, "hits_team1": 0.0, "winner": 0.0, "reason": 5.0}
    nxt = {("stats", k): torch.tensor([v]) for k, v in stats.items()} | {"done": torch.tensor([True])}
    log(env, None, _Lookup(nxt))
    text = " ".join(m for _, m in messages)
    assert "A (blue, team 0, +x) against B (red, team 1, -x)" in text
    assert "touches: A 1, B 0" in text and "point to A" in text and "B faulted (ball_out)" in text


class _Lookup(dict):
    def __getitem__(self, key):
        return dict.__getitem__(self, key if isinstance(key, str) else tuple(key))


def _bad_cases(tmp, ckpt):
    other = tmp / "other.json"
    other.write_text(
        json.dumps(
            {
                "format": "volleybots.crossplay/1",
                "labels": ["x", "y"],
                "wdl": [[[0, 0, 0], [1, 0, 1]], [[1, 0, 1], [0, 0, 0]]],
                "outcomes": {},
                "side_wdl": {},
                "competitors": [{"label": "x", "members": [{}]}, {"label": "y", "members": [{}]}],
            }
        )
    )
    return [
        (["eval", "crossplay", "scripted", str(tmp / "nowhere"), "task=1v1"], ["nowhere", "does not exist"]),
        (["eval", "crossplay", "scripted", "task=1v1"], ["at least 2 competitors", "got 1"]),
        # out=DIR reads as a competitor labelled 'out': the line says so and names the option
        (["eval", "crossplay", "scripted", "random", "task=1v1", f"out={tmp / 'cp'}"], ["cp' does not exist", "named 'out'", "--out DIR"]),
        (["eval", "crossplay", "scripted", "random", "task=1v1", "games=0"], ["games=0", "even"]),
        (["eval", "crossplay", "scripted", "random", "task=1v1", "games=7"], ["games=7", "even"]),
        (["eval", "crossplay", "scripted", "random", "task=1v1", "games=many"], ["games='many'", "integer"]),
        (["eval", "crossplay", "scripted", "random"], ["task=1v1"]),
        (["eval", "crossplay", "scripted", "random", "task=hover"], ["hover", "not a match"]),
        (["eval", "crossplay", "scripted", "random", "task=1v1", "scenario=volley"], ["volley", "serve", "receive"]),
        (["eval", "crossplay", "scripted", "random", "task=1v1", "env.action_space=discrete"], ["scripted", "discrete"]),
        (["eval", "crossplay", str(ckpt), "random", "task=3v3"], ["1v1", "3v3"]),
        (["eval", "crossplay", str(ckpt), "random", "env.action_space=ctbr"], ["prt", "ctbr"]),
        (["eval", "crossplay", "random", "random", "task=1v1"], ["random", "label"]),
        (["eval", "elo", "scripted", "random", f"from={other}"], ["other.json", "scripted", "random"]),
        (["eval", "elo", f"from={tmp / 'none.json'}"], ["none.json", "does not exist"]),
        (["eval", "elo", f"from={ckpt}"], ["final.pt", "not a cross-play results file"]),
        (["eval", "elo", "scripted", "random", "task=1v1", "rounds=3"], ["rounds=3", "even"]),
        (["eval", "crossplay", "scripted", "random", "task=1v1", "--out", str(tmp / "full")], ["full", "never overwritten"]),
        (["replay", "scripted", "random", "r2=random", "task=1v1"], ["two competitors", "3"]),
    ]


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_bad_input_exits_2_with_one_line_and_writes_nothing(tiny_ckpt, tmp_path):
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "keep.txt").write_text("x")
    cases = _bad_cases(tmp_path, tiny_ckpt / "checkpoints" / "final.pt")
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    cwd = os.getcwd()
    os.chdir(tmp_path)  # default output folders would appear here
    try:
        for args, words in cases:
            res = runner.invoke(app, args)
            assert res.exit_code == 2, (args, res.exit_code, res.output)
            err = res.stderr.strip()
            assert "Traceback" not in res.output and len(err.splitlines()) == 1 and err.startswith("error: "), (args, res.output)
            for w in words:
                assert w in err, (args, w, err)
    finally:
        os.chdir(cwd)
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_reuse_copies_the_pairs_an_earlier_crossplay_played_and_the_table_is_the_fresh_one(tmp_path):
    """``reuse=FILE``: the pairs of an earlier results file, recognised by what plays (a relabelled
    checkpoint is the same player), are copied and the table equals a fresh cross-play of everyone; a pair
    in the other order is played again; other settings are refused before any game."""
    common = ["task=1v1", "task.episode_len=16", "games=4", "seed=3", "batch=4"]  # short games: the copy is the point

    def play(*specs, reuse=None):
        comps = [resolve_competitor(s) for s in specs]
        cfg = load(common[:2])
        return crossplay(cfg, comps, 4, seed=3, batch=4, specs=list(specs), reuse=reuse)

    first = tmp_path / "first.json"
    play("bc=zoo:1v1/bc", "random").save(first)
    fresh = play("bc=zoo:1v1/bc", "random", "sp=zoo:1v1/sp").to_dict()
    res = runner.invoke(app, ["eval", "crossplay", "clone=zoo:1v1/bc", "random", "sp=zoo:1v1/sp", *common, f"reuse={first}",
                              "--out", str(tmp_path / "grown")])
    assert res.exit_code == 0, res.output
    assert f"(reused from {first})" in res.stderr and "pair 0,2: W/D/L" in res.stderr and res.stderr.count("reused from") == 1
    grown = json.loads((tmp_path / "grown" / "crossplay.json").read_text())
    for key in ("wdl", "outcomes", "side_wdl", "content", "served", "average_win_rate"):
        assert fresh[key] == grown[key], key
    assert grown["reused"] == {"0,1": str(first)} and "reused" not in fresh
    # the pair the other way round holds other games: played, not copied
    assert "reused" not in play("random", "bc=zoo:1v1/bc", reuse=first).meta
    # another seed, or no such file: one line, exit 2, no folder
    bad = ["eval", "crossplay", "bc=zoo:1v1/bc", "random", *common, "seed=4", f"reuse={first}", "--out", str(tmp_path / "bad")]
    res = runner.invoke(app, bad)
    assert res.exit_code == 2 and res.stderr.strip() == (
        f"error: reuse={str(first)!r} was played with seed=3, this cross-play with seed=4; only pairs played with the same "
        "settings can be reused"), res.output
    res = runner.invoke(app, ["eval", "crossplay", "bc=zoo:1v1/bc", "random", *common, f"reuse={tmp_path / 'none.json'}"])
    assert res.exit_code == 2 and "is not a file" in res.stderr and len(res.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "bad").exists()
    # games played by other game code (the version string does not change between commits; the code's
    # fingerprint does), or by a build that did not record one: refused
    assert json.loads(first.read_text())["versions"]["play_code"] == play_code()
    for code in ("0123456789abcdef", None):
        other = json.loads(first.read_text())
        other["versions"]["play_code"] = code
        (tmp_path / "other.json").write_text(json.dumps(other))
        res = runner.invoke(app, ["eval", "crossplay", "bc=zoo:1v1/bc", "random", *common, f"reuse={tmp_path / 'other.json'}",
                                  "--out", str(tmp_path / "bad")])
        assert res.exit_code == 2 and res.stderr.strip() == (
            f"error: reuse={str(tmp_path / 'other.json')!r} was played by the game code (volleybots.version.play_code) "
            f"{code or 'unrecorded'}, this is {play_code()}; its games may differ, play them again"), res.output
        assert not (tmp_path / "bad").exists()


def test_the_game_code_fingerprint_covers_the_floors_that_play_and_no_others():
    """``play_code`` hashes the physics, referee, tasks, scripted players, networks, policy store, game loop
    and config, and not the verbs that only record or read games (a results file's reuse would otherwise
    be refused after every change to a report)."""
    import volleybots
    from volleybots.paths import conf_dir
    from volleybots.version import play_sources

    root = Path(volleybots.__file__).parent
    conf = [p for p in play_sources() if p.is_relative_to(conf_dir())]
    floors = {p.relative_to(root).parts[0] for p in play_sources() if p not in conf}
    assert floors == {"physics", "rules", "tasks", "scripted", "algos", "policies", "play", "config", "keys.py"}
    # and the config tree: a drone's or a task's YAML changes a game as much as code does (issue 49)
    assert conf_dir() / "env" / "drone" / "iris.yaml" in conf and conf_dir() / "task" / "1v1.yaml" in conf
    assert (root / "physics" / "torch_backend.py") in play_sources() and (root / "scripted" / "lookahead.py") in play_sources()
    assert len(play_code()) == 16 and int(play_code(), 16) >= 0
