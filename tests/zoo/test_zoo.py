"""The zoo: every shipped policy (each member of a mixture) loads with ``weights_only=True``, fits its
task, beats ``random`` in a few games and is listed by ``volleybots list``; ``zoo:`` names work wherever a
competitor goes, and a mixture is refused where one policy must play."""

from __future__ import annotations

import pytest
import torch
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.config import ConfigError
from volleybots.zoo import PREFIX, entries

ZOO = sorted(entries())


def test_the_zoo_ships_entries_with_cards():
    assert ZOO, "the package ships no zoo entries"
    assert any(e.is_mixture for e in entries().values()), "the package ships no mixture entry (zoo:1v1/psro_nash)"
    for name, e in entries().items():
        for key in ("command", "frames", "seed", "figures", "evaluation", *(("members", "mixture") if e.is_mixture else ())):
            assert key in e.card, f"{name}'s card lacks {key!r}"
        for f in e.members:
            assert f.stat().st_size < 2_000_000, f"{name}'s {f.name} is {f.stat().st_size} bytes: not weights only"
    # an entry trained on from another (init=zoo:...) records its start, and the frames of both together
    started = {name: e for name, e in entries().items() if str(e.card["config"].get("init") or "").startswith(PREFIX)}
    assert started, "no shipped entry continues another (zoo:1v1/sp_noanchor does)"
    for name, e in started.items():
        start = entries()[e.card["init"][len(PREFIX):]]
        assert e.card["init"] == e.card["config"]["init"], name
        assert e.card["frames_with_start"] == e.card["frames"] + start.card["frames"], name


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
@pytest.mark.parametrize("name", ZOO)
def test_every_zoo_entry_loads_weights_only_fits_its_task_and_beats_random(name):
    from volleybots.eval.crossplay import crossplay, match_config, resolve_all

    e = entries()[name]
    # a mixture's card lists every member of the run's final meta-strategy with its frames (the card's
    # frames are the run's total); a single policy's frames are the card's
    listed = {m["label"]: int(m["frames"]) for m in e.card.get("members", ())}
    assert len(e.members) == len(e.weights) or e.is_team  # a team plays as one member, its files together
    if e.is_team:  # a hierarchical team: each drill's file was trained on that drill; the card's frames are theirs
        frames = 0
        for key, f in zip(e.card["hierarchical"], e.members, strict=True):
            state = torch.load(f, weights_only=True)
            assert state["task"] == key if key != "high_level" else state["format"] == "volleybots-high-level/1"
            frames += int(state.get("frames", 0))
        assert frames == int(e.card["frames"])
    for f in e.members if not e.is_team else ():
        state = torch.load(f, weights_only=True)
        assert state["task"] == e.task
        assert int(state["frames"]) == (listed[state["label"]] if e.is_mixture else int(e.card["frames"])) <= int(e.card["frames"])
    comps = resolve_all([PREFIX + name, "random"])
    assert comps[0].mixture == pytest.approx(list(e.weights)) and sum(comps[0].mixture) == pytest.approx(1.0)
    assert len(comps[0].members) == (1 if e.is_team else len(e.members))
    cfg = match_config(comps, ["threads=1"])  # checks task, action space and observation size of every member
    assert cfg.task.name == e.task
    res = crossplay(cfg, comps, games=16, seed=123, batch=16)
    w, d, l_ = res.wdl[0, 1].astype(int).tolist()
    # a regression guard far below the card's figure (hundreds of games on a held-out seed)
    assert w > l_, f"{name} against random: W/D/L {w}/{d}/{l_}"


@pytest.fixture
def mixture_zoo(tmp_path, monkeypatch):
    """A zoo of one mixture entry, ``zoo:1v1/mix``: the shipped 1v1 bc and sp at weights 0.25 and 0.75."""
    import shutil

    import yaml

    from volleybots import zoo

    (tmp_path / "1v1" / "mix").mkdir(parents=True)
    for member, source in (("a", "bc"), ("b", "sp")):
        shutil.copy(entries()[f"1v1/{source}"].checkpoint, tmp_path / "1v1" / "mix" / f"{member}.pt")
    card = {"command": "a test's", "frames": 0, "seed": 0, "figures": {}, "evaluation": {},
            "mixture": [{"file": "mix/a.pt", "weight": 0.25}, {"file": "mix/b.pt", "weight": 0.75}]}
    (tmp_path / "1v1" / "mix.yaml").write_text(yaml.safe_dump(card))
    monkeypatch.setattr(zoo, "ZOO_DIR", tmp_path)
    return tmp_path


def test_a_mixture_entry_is_a_competitor_of_its_members_and_no_single_policy(mixture_zoo):
    from volleybots.config import load
    from volleybots.policies import check_references, policy_checkpoint, resolve_competitor, resolve_target
    from volleybots.policies.store import parse_spec
    from volleybots.train.init import init_checkpoint

    assert parse_spec("zoo:1v1/mix").kind == "mixture" and parse_spec("m=zoo:1v1/mix").label == "m"
    comp = resolve_competitor("zoo:1v1/mix")
    assert comp.label == "zoo:1v1/mix" and [m.label for m in comp.members] == ["mix/a", "mix/b"]
    assert comp.mixture == [0.25, 0.75] and sum(comp.mixture) == pytest.approx(1.0)
    assert [m.source["algo"] for m in comp.members] == ["bc", "sp"]
    one = "is a zoo mixture of 2 policies, not one policy; give one of its member files instead \\(a.pt, b.pt in "
    for refuse in (lambda: policy_checkpoint("zoo:1v1/mix", "init="), lambda: init_checkpoint("zoo:1v1/mix"),
                   lambda: resolve_target("zoo:1v1/mix"),
                   lambda: check_references(load(["task=1v1", "algo=psro_nash", "algo.seed_members=[zoo:1v1/mix]"]))):
        with pytest.raises(ConfigError, match=one) as err:
            refuse()
        assert "\n" not in str(err.value) and "'zoo:1v1/mix'" in str(err.value)


def test_a_damaged_mixture_card_is_one_line_naming_it(mixture_zoo):
    from volleybots import zoo

    card = mixture_zoo / "1v1" / "mix.yaml"
    good = card.read_text()
    card.write_text(good.replace("weight: 0.25", "weight: 0.5"))
    with pytest.raises(ConfigError, match="mix.yaml'.*sums to 1.25, not 1"):
        zoo.entries()
    card.write_text(good.replace("mix/b.pt", "mix/c.pt"))
    with pytest.raises(ConfigError, match="member file 'mix/c.pt' is missing"):
        zoo.entries()
    card.write_text(good.replace("weight: 0.25", "weight: 0"))
    with pytest.raises(ConfigError, match="is not .*weight: w > 0"):
        zoo.entries()


def test_volleybots_list_shows_the_zoo_and_an_unknown_entry_is_one_line():
    res = CliRunner().invoke(app, ["list"])
    assert res.exit_code == 0
    for name in ZOO:
        assert PREFIX + name in res.output
    from volleybots.policies import resolve_competitor, resolve_target

    with pytest.raises(ConfigError, match="not in the zoo; shipped: zoo:"):
        resolve_competitor("zoo:1v1/nothing")
    # a single entry is a target too (eval, replay TARGET), and labels itself by its zoo name as a competitor
    assert resolve_target("zoo:1v1/sp").checkpoint == entries()["1v1/sp"].checkpoint
    assert resolve_competitor("zoo:1v1/sp").label == "zoo:1v1/sp" and resolve_competitor("mine=zoo:1v1/sp").label == "mine"


def test_every_card_gives_the_seed_its_command_names():
    """`volleybots list` printed zoo:1v1/sp's learner seed (1001) where its command and the docs say seed 1."""
    import re

    for name, e in entries().items():
        # a command of several steps (a clone, then RL from it) names the shipped run's seed last
        said = re.findall(r"\bseed=(\d+)", e.card["command"])
        assert not said or int(said[-1]) == int(e.card["seed"]), (name, e.card["seed"], e.card["command"])


def test_a_team_entry_is_the_hierarchical_competitor_with_its_files(tmp_path, monkeypatch):
    """A card with ``hierarchical:`` (drills and a learned high level, files beside it) plays as the
    hierarchical team; a missing file is one line naming it."""
    import yaml

    from volleybots import zoo
    from volleybots.policies import resolve_competitor
    from volleybots.policies.high_level import HighLevelNet, save_high_level
    from volleybots.policies.store import parse_spec

    save_high_level(HighLevelNet((8,)), tmp_path / "3v3" / "team" / "high_level.pt")
    card = {"command": "a test's", "frames": 0, "seed": 0, "figures": {}, "evaluation": {},
            "hierarchical": {"high_level": "team/high_level.pt"}}
    (tmp_path / "3v3" / "team.yaml").write_text(yaml.safe_dump(card))
    monkeypatch.setattr(zoo, "ZOO_DIR", tmp_path)
    e = entries()["3v3/team"]
    assert e.is_team and e.checkpoint is None and e.members == (tmp_path / "3v3" / "team" / "high_level.pt",)
    assert parse_spec("zoo:3v3/team").kind == "drills"
    comp = resolve_competitor("zoo:3v3/team")
    assert comp.label == "zoo:3v3/team" and comp.members[0].source["kind"] == "hierarchical"
    assert comp.members[0].source["drill_files"]["high_level"]["path"].endswith("team/high_level.pt")
    res = CliRunner().invoke(app, ["list"])
    assert "zoo:3v3/team" in res.output and "a hierarchical team (high_level)" in res.output
    (tmp_path / "3v3" / "team" / "high_level.pt").unlink()
    with pytest.raises(ConfigError, match="file 'team/high_level.pt' is missing"):
        entries()
