"""Hierarchical members of a population (population.members=hierarchical): drills under a learned high level,
each oracle a high level trained against the meta-solver's mixture; kill and resume; every verb plays it."""

import json

import pytest
import torch
from helpers import one_line_exit_2, run_cli

from volleybots.config import ConfigError, load
from volleybots.files import sha256
from volleybots.policies import resolve_competitor
from volleybots.population import hierarchical
from volleybots.population.run import resume, start

TINY = [
    "task=3v3", "algo.fixed_opponents=[]", "algo.high_level_games=32", "algo.high_level_batch=16", "algo.payoff_games=4",
    "evaluation.episodes=2",
    "evaluation.record=false", "progress=false", "threads=1",
]


def tiny(*more, algo="psro_nash"):
    return load([*TINY, f"algo={algo}", *more])


def _members(run):
    return json.loads((run / "population" / "payoffs.json").read_text())["members"]


def test_members_auto_is_hierarchical_on_3v3_only_and_refused_where_it_cannot_play():
    cfg = load(["task=3v3", "algo=psro_nash"])
    pop = cfg.population
    assert pop.members == "hierarchical" and pop.seed_members == ["zoo:3v3/hcsp_return"] and pop.learner_init == "last"
    assert (pop.fixed_opponents, pop.fixed_share, pop.high_level_games) == (["scripted"], 0.5, 1024)
    assert load(["task=1v1", "algo=psro_nash"]).population.members == "flat"
    assert load(["task=3v3", "algo=sp"]).population.members == "flat"  # one learner on both teams is a flat policy
    assert load(["task=3v3", "algo=psro_nash", "algo.members=flat"]).population.learner_init == "bc"  # the paper's table 3, one key away
    # PSRO-uniform's oracles start from the first team (continuing would make it FSP run for run); FSP continues
    assert [load(["task=3v3", f"algo={a}"]).population.learner_init for a in ("psro_uniform", "fsp")] == ["first", "last"]
    with pytest.raises(ConfigError, match="population=fsp continues each learner from the newest member"):
        load(["task=3v3", "algo=fsp", "algo.learner_init=first"])
    with pytest.raises(ConfigError, match="unknown population.learner_init 'first'; allowed: scratch, last, bc, zoo"):
        load(["task=3v3", "algo=psro_uniform", "algo.members=flat", "algo.learner_init=first"])  # a flat learner has no high level
    with pytest.raises(ConfigError, match="population.members=hierarchical plays task 3v3, not '1v1'"):
        load(["task=1v1", "algo=psro_nash", "algo.members=hierarchical"])
    with pytest.raises(ConfigError, match="unknown population.members 'tree'; allowed: auto, flat, hierarchical"):
        load(["task=3v3", "algo=psro_nash", "algo.members=tree"])
    with pytest.raises(ConfigError, match="population.fixed_share=0.5 needs population.fixed_opponents"):
        load(["task=3v3", "algo=psro_nash", "algo.fixed_opponents=[]", "algo.fixed_share=0.5"])  # 3v3's default has [scripted]


@pytest.mark.slow  # trains or plays 3v3 games
def test_the_oracle_trains_against_the_meta_solvers_mixture_and_the_fixed_opponents_beside_it(tmp_path, monkeypatch):
    seen = []
    real = hierarchical.train_high_level

    def spy(match, drills, opponent, hc, log=None, start=None):
        seen.append(([m.label for m in opponent.members], [float(w) for w in opponent.mixture], bool(match.task.fall_fault),
                     start is not None))
        return real(match, drills, opponent, hc, log, start=start)

    monkeypatch.setattr(hierarchical, "train_high_level", spy)
    cfg = tiny("algo.iterations=2", "algo.seed_members=[zoo:3v3/hcsp_return,hierarchical]", "algo.fixed_opponents=[random]",
               "algo.fixed_share=0.25")
    start(cfg, tmp_path / "run")
    metas = [json.loads(line) for line in (tmp_path / "run" / "population" / "meta.jsonl").read_text().splitlines()]
    for (labels, weights, fall, warm), meta in zip(seen, metas[:-1], strict=True):  # oracle i against meta i - 1
        # the population's members with positive weight, scaled by 1 - fixed_share, then the fixed one
        kept = [w for w in meta["mixture"] if w > 0]
        assert labels[-1] == "random" and len(labels) == len(kept) + 1
        assert weights[:-1] == pytest.approx([0.75 * w / sum(kept) for w in kept]) and weights[-1] == pytest.approx(0.25)
        assert fall and warm  # trained under the volleyball rule, from the newest high level (learner_init=last)
    assert len(seen) == 2 and _members(tmp_path / "run") == ["zoo:3v3/hcsp_return", "hierarchical", "br1", "br2"]


@pytest.mark.slow  # trains or plays 3v3 games
def test_psro_uniform_starts_every_oracle_from_the_first_team_and_fsp_from_the_newest(tmp_path, monkeypatch):
    starts = {}
    real = hierarchical.train_high_level

    def spy(match, drills, opponent, hc, log=None, start=None):
        starts.setdefault(method, []).append({k: v.clone() for k, v in start.state_dict().items()})
        return real(match, drills, opponent, hc, log, start=start)

    monkeypatch.setattr(hierarchical, "train_high_level", spy)
    for method in ("psro_uniform", "fsp"):
        start(tiny("algo.iterations=2", algo=method), tmp_path / method)
    def equal(a, b):
        return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)

    uniform, fsp = starts["psro_uniform"], starts["fsp"]
    assert len(uniform) == len(fsp) == 2 and equal(uniform[0], fsp[0])  # both first oracles from the first team's high level
    assert equal(uniform[1], uniform[0])  # PSRO-uniform's second oracle too ...
    br1 = torch.load(tmp_path / "fsp" / "population" / "high_level_001.pt", weights_only=True)["state_dict"]
    assert equal(fsp[1], br1) and not equal(fsp[1], fsp[0])  # ... FSP's from br1's, the newest


@pytest.mark.slow  # trains drills and plays 3v3 games
def test_stage_one_trains_the_drills_in_the_run_and_every_member_plays_them(tmp_path):
    from volleybots.population.stage_one import TRAINED, team_path

    cfg = tiny("algo.iterations=1", "algo.drills=train", "algo.drill_bc_frames=2048", "algo.drill_frames=2048", "env.num_envs=16")
    assert cfg.population.seed_members == ["train"]  # member 0: the trained drills under the rules
    run = tmp_path / "run"
    summary = start(cfg, run)
    team = team_path(run)
    text = team.read_text()
    for name in TRAINED:  # each drill imitated, then fine-tuned from its clone, in the run
        ppo = json.loads((team.parent / name / "ppo" / "summary.json").read_text())
        assert ppo["task"] == name and ppo["algo"] == "ppo" and ppo["frames"] >= 2048
        assert f"{name}: {name}/ppo/checkpoints/final.pt" in text
    assert summary["wall_time_split"]["drills"] > 0
    # every member (the first team and br1) plays the trained drills, copied into the run by content
    trained = {n: sha256(team.parent / n / "ppo" / "checkpoints" / "final.pt")[:12] for n in TRAINED}
    for k in (0, 1):
        record = torch.load(run / "population" / f"member_{k:03d}.pt", weights_only=True)
        assert {n: record["drills"][n].split("-")[-1][:12] for n in TRAINED} == trained
    # a resume finds the team file made and trains no drill again
    stamp = team.stat().st_mtime_ns
    resume(run, ["algo.iterations=2"])
    assert team.stat().st_mtime_ns == stamp and _members(run) == ["trained_drills", "br1", "br2"]
    with pytest.raises(ConfigError, match="drill_frames"):
        tiny("algo.drills=train", "algo.drill_frames=0")


@pytest.mark.slow  # trains or plays 3v3 games
def test_a_tiny_hierarchical_population_saves_resumes_bit_for_bit_and_plays_in_every_verb(tmp_path):
    whole = start(tiny("algo.iterations=2"), tmp_path / "whole")
    assert whole["population"]["members"] == ["zoo:3v3/hcsp_return", "br1", "br2"]
    start(tiny("algo.iterations=1"), tmp_path / "cut")  # a run stopped after its first oracle ...
    resume(tmp_path / "cut", ["algo.iterations=2"])  # ... and given its second
    pop_w, pop_c = tmp_path / "whole" / "population", tmp_path / "cut" / "population"
    for k in range(3):  # every member and high level the same, weight for weight
        a, b = (torch.load(p / f"member_{k:03d}.pt", weights_only=True) for p in (pop_w, pop_c))
        assert a == b and a["builtin"] == "hierarchical" and not any(v.startswith("/") for v in a["drills"].values())
        ha, hb = (torch.load(p / f"high_level_{k:03d}.pt", weights_only=True)["state_dict"] for p in (pop_w, pop_c))
        assert ha.keys() == hb.keys() and all(torch.equal(ha[n], hb[n]) for n in ha)
    mix = [json.loads(line)["mixture"] for line in (pop_c / "meta.jsonl").read_text().splitlines()][-1]
    assert mix == whole["population"]["mixture"]
    # the seed member's high level is the zoo team's own, copied into the run
    zoo_high = resolve_competitor("zoo:3v3/hcsp_return").members[0].source["drills"]["high_level"]
    assert (pop_w / "high_level_000.pt").read_bytes() == open(zoo_high, "rb").read()
    # the run is one competitor (its mixture) in cross-play, and eval RUN plays the same mixture and says so
    res = run_cli("eval", "crossplay", f"run={tmp_path / 'whole'}", "random", "task=3v3", "games=2", "seed=4",
                  "--out", tmp_path / "cp")
    assert res.returncode == 0, res.stderr
    res = run_cli("eval", tmp_path / "whole", "episodes=2", "--json")
    assert res.returncode == 0, res.stderr
    assert "mixture" in json.loads(res.stdout)["target"]


@pytest.mark.slow  # trains or plays 3v3 games
def test_a_member_whose_drill_is_missing_is_one_line(tmp_path):
    from typer.testing import CliRunner

    from volleybots.cli import app

    start(tiny("algo.iterations=1"), tmp_path / "run")
    attack = next((tmp_path / "run" / "population" / "drills").glob("attack-*.pt"))
    attack.unlink()
    res = CliRunner().invoke(app, ["eval", "crossplay", str(tmp_path / "run"), "random", "task=3v3", "games=2",
                                   "--out", str(tmp_path / "cp")])
    one_line_exit_2(res, "attack", "does not exist")
    assert not (tmp_path / "cp").exists()


@pytest.mark.slow  # trains or plays 3v3 games
def test_a_fall_is_its_teams_fault_under_the_volleyball_rule_and_a_draw_under_the_papers():
    from volleybots.config import load as load_cfg
    from volleybots.play.games import play_games

    outcomes = {}
    for rule in (False, True):
        cfg = load_cfg(["task=3v3", f"task.fall_fault={str(rule).lower()}"])
        g = play_games(cfg, resolve_competitor("scripted"), resolve_competitor("random"), 8, seed=3)
        c = g.content()
        outcomes[rule] = (g.total.tolist(), c["faults"]["B"].get("fell", 0))
    (w0, d0, l0), fell0 = outcomes[False]
    (w1, d1, l1), fell1 = outcomes[True]
    assert fell0 == 0 and d0 > 0  # the paper's rule: random's falls end its games drawn
    assert fell1 >= d0 and d1 < d0 and w1 == w0 + (d0 - d1)  # the same games: each fall now loses random the rally


@pytest.mark.slow  # trains a high level in 3v3 games
def test_self_play_with_hierarchical_members_trains_one_high_level_against_itself(tmp_path, monkeypatch):
    """population=sp with population.members=hierarchical: one oracle, its opponent the learning high level
    itself (None: the same net under a second chooser that records nothing); the final mixture is it alone."""
    seen = []
    real = hierarchical.train_high_level

    def spy(match, drills, opponent, hc, log=None, start=None):
        seen.append((opponent, start is not None))
        return real(match, drills, opponent, hc, log, start=start)

    monkeypatch.setattr(hierarchical, "train_high_level", spy)
    cfg = tiny("algo.members=hierarchical", "algo.high_level_games=16", "algo.high_level_batch=8", algo="sp")
    assert cfg.population.self_play and cfg.population.members == "hierarchical"
    start(cfg, tmp_path / "run")
    assert seen == [(None, True)]  # self-play, continued from the drills' team's high level (start=clone)
    assert _members(tmp_path / "run") == ["zoo:3v3/hcsp_return", "sp"]
    meta = json.loads((tmp_path / "run" / "population" / "meta.jsonl").read_text().splitlines()[-1])
    assert meta["mixture"] == [0.0, 1.0]
    high = torch.load(tmp_path / "run" / "population" / "high_level_001.pt", weights_only=True)
    assert high["info"]["opponent"] == "self"


@pytest.mark.slow  # records 3v3 serves and fine-tunes a drill
def test_stage_three_tunes_the_receiving_drills_on_the_recorded_serves_and_the_oracle_plays_them(tmp_path):
    """population.tune_drills=[attack]: before the first oracle, the opponent's serves are recorded into a ball
    bank, the attack drill is fine-tuned on it by PPO, and the member trained then names the tuned drill."""
    from volleybots.population.tune_drills import record_path
    from volleybots.tasks.drills import read_ball_bank

    cfg = tiny("algo.iterations=1", "algo.tune_drills=[attack]", "algo.tune_games=8", "algo.tune_frames=2048",
               "algo.high_level_games=16", "algo.high_level_batch=8", "env.num_envs=16", "algo.seed_members=[zoo:3v3/hcsp_return]")
    start(cfg, tmp_path / "run")
    pop = tmp_path / "run" / "population"
    record = json.loads(record_path(tmp_path / "run", 1).read_text())
    tuned = record["drills"]["attack"]
    assert list(record["drills"]) == ["attack"] and record["serves"] == len(read_ball_bank(pop / "tune" / "001" / "serves.pt")) > 0
    first, second = (torch.load(pop / f"member_{k:03d}.pt", weights_only=True)["drills"] for k in (0, 1))
    assert second["attack"] == tuned != first["attack"]  # the new member plays the tuned drill, the seed member its own
    assert {k: v for k, v in second.items() if k not in ("attack", "high_level")} == \
        {k: v for k, v in first.items() if k not in ("attack", "high_level")}
    base, after = (torch.load(pop / f, weights_only=True)["algo"] for f in (first["attack"], tuned))
    # PPO trained on the bank: two updates, in the recipe's critic warm-up (the actor held for 10)
    assert int(after["updates"]) == 2 and any(not torch.equal(base["critic"][k], after["critic"][k]) for k in base["critic"])
    assert all(torch.equal(base["actor"][k], after["actor"][k]) for k in base["actor"])
    with pytest.raises(ConfigError, match="population.tune_drills: 'set' cannot be tuned on recorded serves; allowed: pass, attack"):
        tiny("algo.tune_drills=[set]")
    with pytest.raises(ConfigError, match="tunes a hierarchical team's drills; give population.members=hierarchical"):
        tiny("algo.tune_drills=[attack]", "algo.members=flat")
