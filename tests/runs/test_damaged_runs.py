"""Damaged and hand-edited run directories (issue 32): every competitor is exactly what its run holds or is
refused with one line naming what is missing or damaged; resume of a damaged population writes nothing;
the files the project writes are read back through one checked reader."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import torch
import yaml
from helpers import crossplay_file, one_line_exit_2
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.config import ConfigError, validate
from volleybots.policies import resolve_competitor, resolve_target
from volleybots.ratings.payoffs import PayoffTable
from volleybots.runs import RunDir, read_population

runner = CliRunner()


def snapshot(root: Path) -> dict:
    return {str(p): (p.stat().st_mtime_ns, p.stat().st_size) for p in root.rglob("*")}


def _meta(run: Path, edit) -> None:
    path = run / "population" / "meta.jsonl"
    lines = [json.loads(x) for x in path.read_text().splitlines()]
    edit(lines)
    path.write_text("".join(json.dumps(x) + "\n" for x in lines))


def _lines(run: Path, keep: int) -> None:
    path = run / "population" / "meta.jsonl"
    path.write_text("".join(line + "\n" for line in path.read_text().splitlines()[:keep]))


RUN_DAMAGE = {
    "checkpoints deleted": (lambda r: [p.unlink() for p in (r / "checkpoints").iterdir()], ["checkpoints are gone", "final.pt"]),
    "final.pt truncated": (lambda r: (r / "checkpoints/final.pt").write_bytes((r / "checkpoints/final.pt").read_bytes()[:3000]),
                           ["final.pt", "damaged"]),
}
POP_DAMAGE = {
    "member gone": (lambda r: (r / "population/member_001.pt").unlink(), ["member_001.pt is missing", "iteration 1"]),
    "member replaced": (
        lambda r: shutil.copy(r / "population/member_000.pt", r / "population/member_001.pt"),
        ["member_001.pt", "'random'", "'br1'"],
    ),
    "bad json line": (lambda r: (r / "population/meta.jsonl").open("a").write("{oops\n"), ["meta.jsonl", "line 3 is not JSON"]),
    "mixture not summing to 1": (lambda r: _meta(r, lambda ls: ls[-1].update(mixture=[0.7, 0.7])), ["line 2", "sums to 1.4"]),
    "negative weight": (lambda r: _meta(r, lambda ls: ls[-1].update(mixture=[1.5, -0.5])), ["mixture[1]", "weight >= 0"]),
    "mixture missing": (lambda r: _meta(r, lambda ls: ls[-1].pop("mixture")), ["no 'mixture'"]),
    "garbage line": (lambda r: (r / "population/meta.jsonl").open("a").write('["garbage"]\n'), ["line 3", "not a JSON object"]),
    "no complete iteration": (lambda r: _lines(r, 0), ["no complete iteration"]),
}


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
@pytest.mark.parametrize("case", list(RUN_DAMAGE))
def test_a_damaged_run_is_refused_by_every_verb(case, tiny_1v1_run, copy_run, tmp_path):
    run = copy_run(tiny_1v1_run)
    damage, words = RUN_DAMAGE[case]
    damage(run)
    out = tmp_path / "out"
    one_line_exit_2(runner.invoke(app, ["eval", "crossplay", str(run), "random", "games=2", "--out", str(out)]), *words)
    one_line_exit_2(runner.invoke(app, ["eval", str(run), "episodes=1"]), *words)
    one_line_exit_2(runner.invoke(app, ["replay", str(run), "--no-viewer"]), *words)
    assert not out.exists() and not list(run.glob("replay_*"))


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
@pytest.mark.parametrize("case", list(POP_DAMAGE))
def test_a_damaged_population_is_refused_and_its_resume_writes_nothing(case, tiny_population, copy_run, tmp_path):
    run = copy_run(tiny_population)
    damage, words = POP_DAMAGE[case]
    damage(run)
    with pytest.raises(ConfigError) as e:
        resolve_competitor(str(run))
    assert all(w in str(e.value) for w in words), str(e.value)
    one_line_exit_2(runner.invoke(app, ["eval", "crossplay", str(run), "random", "games=2", "--out", str(tmp_path / "o")]), *words)
    before = snapshot(run)
    if case != "no complete iteration":  # that one resumes: nothing of it was played
        one_line_exit_2(runner.invoke(app, ["train", f"resume={run}", "algo.iterations=2"]), *words)
        assert snapshot(run) == before


def test_a_population_killed_between_member_and_meta_plays_its_last_complete_iteration(tiny_population, copy_run, capsys):
    run = copy_run(tiny_population)
    _lines(run, 1)  # member_001.pt written, its meta.jsonl line not
    comp = resolve_competitor(str(run))
    assert [m.label for m in comp.members] == [f"{run.name}/member_000"] and comp.mixture == [1.0]
    assert comp.members[0].source == {"kind": "random"}
    err = capsys.readouterr().err
    assert "stopped during iteration 1" in err and "playing iteration 0" in err and "member_001.pt" in err
    # as a target (eval RUN, replay RUN) it plays what cross-play plays: the last complete iteration's
    # mixture (random alone here), never the unfinished learner
    t = resolve_target(str(run))
    assert t.label == run.name and t.checkpoint is None and t.cfg.task.name == "1v1"
    pop = read_population(run, "run", quiet=True)
    assert pop.iteration == 0 and [p.name for p in pop.pending] == ["member_001.pt"]


def test_an_intact_population_plays_every_member_with_its_mixture(tiny_population):
    comp = resolve_competitor(str(tiny_population))
    assert len(comp.members) == 2 and comp.mixture == [0.5, 0.5]
    assert comp.members[1].source["kind"] == "checkpoint"


def test_a_population_killed_before_its_first_checkpoint_starts_afresh(tiny_population, copy_run, capsys):
    run = copy_run(tiny_population)
    cfg = RunDir(run).load_config()
    # killed with its seed member and iteration 0 written, before any learner's checkpoint
    shutil.rmtree(run / "checkpoints")
    (run / "population/member_001.pt").unlink()
    _lines(run, 1)
    (run / "summary.json").unlink()
    assert not RunDir(run).has_checkpoint()
    RunDir(run).create(cfg)
    from volleybots.runs import unlock

    unlock(run)
    assert not (run / "population").exists() and not (run / "payoffs.png").exists()
    assert "population" in capsys.readouterr().err


def test_a_population_with_a_learned_member_is_never_cleared(tiny_population, copy_run):
    run = copy_run(tiny_population)
    shutil.rmtree(run / "checkpoints")  # its learner's checkpoints gone, the learned member kept
    assert RunDir(run).has_checkpoint()
    with pytest.raises(ConfigError, match="already holds a run"):
        RunDir(run).create(RunDir(run).load_config())
    assert (run / "population/member_001.pt").is_file()


def test_resume_of_a_finished_self_play_run_says_what_continues_it(tiny_population, copy_run):
    run = copy_run(tiny_population)
    cfg = yaml.safe_load((run / "config.yaml").read_text())
    cfg["population"].update(name="sp", self_play=True, seed_members=[])  # the loop's keys
    (run / "config.yaml").write_text(yaml.safe_dump(cfg))
    validate(cfg)
    err = one_line_exit_2(runner.invoke(app, ["train", f"resume={run}", "total_frames=100000"]), "self-play", f"init={run}")
    assert "raise" not in err


def test_a_planted_interpolation_is_refused_and_never_resolved(tiny_1v1_run, copy_run, monkeypatch):
    monkeypatch.setenv("VB_TEST_SECRET", "hunter2")
    run = copy_run(tiny_1v1_run)
    text = (run / "config.yaml").read_text().replace("project: volleybots", "project: ${oc.env:VB_TEST_SECRET}")
    assert "VB_TEST_SECRET" in text
    (run / "config.yaml").write_text(text)
    before = snapshot(run)
    err = one_line_exit_2(runner.invoke(app, ["train", f"resume={run}", "total_frames=256"]), "wandb.project", "interpolation")
    assert "hunter2" not in err and snapshot(run) == before
    # the same planted in a checkpoint's saved config
    state = torch.load(run / "checkpoints/final.pt", weights_only=True)
    state["config"]["wandb"]["project"] = "${oc.env:VB_TEST_SECRET}"
    torch.save(state, run / "checkpoints/final.pt")
    one_line_exit_2(runner.invoke(app, ["eval", str(run), "episodes=1"]), "wandb.project", "interpolation")


# ------------------------------------------------------------------------------ the files the project writes
CROSSPLAY_DAMAGE = {
    "missing key": (lambda d: d.pop("wdl"), ["no 'wdl'"]),
    "ragged counts": (lambda d: d["wdl"][1].pop(), ["wdl[1]", "list of 2 entries"]),
    "negative count": (lambda d: d["wdl"][0][1].__setitem__(2, -1), ["wdl[0][1][2]", "non-negative"]),
    "fractional count": (lambda d: d["wdl"][0][1].__setitem__(0, 2.5), ["wdl[0][1][0]"]),
    "outcomes disagree": (lambda d: d["outcomes"].update({"0,1": "LLLL"}), ["outcomes['0,1']", "0/0/4"]),
    "labels not a list": (lambda d: d.update(labels="ab"), ["'labels' is str"]),
    "not JSON": (None, ["not JSON"]),
}


@pytest.mark.parametrize("case", list(CROSSPLAY_DAMAGE))
def test_a_damaged_crossplay_file_is_one_line(case, tmp_path):
    edit, words = CROSSPLAY_DAMAGE[case]
    path = crossplay_file(tmp_path / "crossplay.json", edit)
    if edit is None:
        path.write_text('{"format": ')
    one_line_exit_2(runner.invoke(app, ["eval", "elo", f"from={path}", "--out", str(tmp_path / "o")]), *words)
    assert not (tmp_path / "o").exists()


def test_an_intact_crossplay_file_rates(tmp_path):
    path = crossplay_file(tmp_path / "crossplay.json")
    res = runner.invoke(app, ["eval", "elo", f"from={path}", "rounds=10", "--json", "--out", str(tmp_path / "o")])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["labels"] == ["a", "b"]
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == [".lock", "crossplay.png", "ratings.json", "ratings.png"]


def test_a_damaged_payoff_table_is_one_line(tmp_path):
    path = tmp_path / "payoffs.json"
    PayoffTable(["a", "b"], [[[0, 0, 0], [1, 0, 2]], [[2, 0, 1], [0, 0, 0]]]).save(path)
    assert PayoffTable.load(path).wdl[..., 0].tolist() == [[0, 1], [2, 0]]
    data = json.loads(path.read_text())
    data["wdl"] = [data["wdl"][0]]
    path.write_text(json.dumps(data))
    with pytest.raises(ConfigError, match="wdl should be a list of 2 entries"):
        PayoffTable.load(path)
    # the layout before one wdl: three matrices, damaged the same way
    path.write_text(json.dumps({"members": ["a", "b"], "wins": [[0, 1], [2, 0]], "draws": [[0, 0], [0, 0]], "losses": [[0, 2]]}))
    with pytest.raises(ConfigError, match="losses should be a list of 2 entries"):
        PayoffTable.load(path)
    path.write_text("[1, 2")
    with pytest.raises(ConfigError, match="is damaged or not a payoff table"):
        PayoffTable.load(path)


@pytest.mark.parametrize("text, words", [
    ("hierarchical: {pass: [1, 2]}", ["no hierarchical team"]),
    ("hierarchical: {juggle: x.pt}", ["unknown drills", "juggle"]),
    ("hierarchical: {pass: missing.pt}", ["missing.pt", "does not exist"]),
    ("hierarchical: [\n  - : ", ["no hierarchical team file"]),
    ("just a string", ["no hierarchical team"]),
])
def test_a_broken_drills_file_is_one_line(text, words, tmp_path):
    path = tmp_path / "team.yaml"
    path.write_text(text)
    one_line_exit_2(
        runner.invoke(app, ["eval", "crossplay", str(path), "random", "task=3v3", "games=2", "--out", str(tmp_path / "o")]), *words
    )
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("edit, reason", [
    (lambda c: c.update(task=5), "task.name is not a name"),
    (lambda c: c["task"].update(name=[1]), "task.name is not a name"),
    (lambda c: c.update(algo=[1, 2]), "algo.name is not a name"),
    (lambda c: c.update(seed="x"), "seed is 'x'"),
    (lambda c: c.update(total_frames="many"), "total_frames is 'many'"),
    (lambda c: c.update(evaluation="oops"), "evaluation is str"),
])
def test_report_lists_a_run_whose_config_has_wrong_types_as_failed(edit, reason, tiny_1v1_run, copy_run):
    bad, good = copy_run(tiny_1v1_run, "bad"), copy_run(tiny_1v1_run, "good")
    cfg = yaml.safe_load((bad / "config.yaml").read_text())
    edit(cfg)
    (bad / "config.yaml").write_text(yaml.safe_dump(cfg))
    res = runner.invoke(app, ["report", str(bad), str(good), "--json"])
    assert res.exit_code == 0, res.output
    runs = {Path(r["path"]).name: r for r in json.loads(res.stdout)["runs"]}
    assert runs["bad"]["status"] == "failed" and reason in runs["bad"]["reason"]
    assert runs["good"]["status"] == "complete"
