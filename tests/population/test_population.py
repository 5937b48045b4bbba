"""The opponent seam and the population loop: seats, mixtures, SP / FSP / PSRO runs, kill and resume."""

import json

import numpy as np
import pytest
import torch

import volleybots
from volleybots.config import ConfigError, load
from volleybots.policies import Competitor, builtin_member, resolve_competitor
from volleybots.population.loop import PopulationLoop
from volleybots.population.run import resume, start
from volleybots.ratings.payoffs import PayoffTable
from volleybots.runs import RunDir
from volleybots.train import SelfPlay, collect

pytestmark = pytest.mark.slow

TINY = [
    "task=1v1", "env.num_envs=16", "algo.steps_per_batch=16", "algo.minibatches=2", "algo.epochs=1", "algo.hidden=[32,32]",
    "algo.min_updates=2", "algo.max_updates=4", "algo.payoff_games=6", "evaluation.episodes=2", "evaluation.every=0",
    "evaluation.record=false", "checkpoint.every=512", "progress=false", "threads=1",
    "algo.start=scratch",  # learners and members from nothing unless a test names the clone (it costs a bc run)
]


def tiny(algo, *more):
    return load([*TINY, f"algo={algo}", *more])


def test_every_method_accepts_matches_only():
    for algo in ("sp", "fsp", "psro_uniform", "psro_nash"):
        assert tiny(algo).population.name == algo
        with pytest.raises(ConfigError, match="trains for matches"):
            load(["task=bump_and_pass", f"algo={algo}"])


@pytest.mark.parametrize("init", ["bc", "scratch"])
def test_fsp_refuses_a_learner_start_that_would_make_it_psro_uniform(init):
    """A 3v3 run of algo=fsp algo.learner_init=bc repeated PSRO-uniform's run oracle for oracle: FSP's one
    difference is that each learner continues from the newest member, so any other start is refused."""
    fsp = f"population=fsp continues .* not '{init}', which makes it population=psro_uniform.*seed_members=\\[bc\\]"
    with pytest.raises(ConfigError, match=fsp):
        tiny("fsp", f"algo.learner_init={init}")
    assert tiny("psro_uniform", f"algo.learner_init={init}").population.learner_init == init
    with pytest.raises(ConfigError, match="unknown population.solver 'best'; allowed: uniform, nash"):
        tiny("psro_nash", "algo.solver=best")
    # a match with no algo named trains self-play; a cooperative task MAPPO
    assert load(["task=3v3"]).population.name == "sp" and load(["task=bump_and_pass"]).algo.name == "mappo"


def test_mixture_draws_members_per_env_as_weighted_and_only_at_episode_starts():
    env = volleybots.make_env("1v1", num_envs=400, seed=0)
    comp = Competitor("mix", [builtin_member("random"), builtin_member("random")], [0.25, 0.75])
    pol = comp.team_policy(env, generator=torch.Generator().manual_seed(0))
    starts = torch.ones(400, dtype=torch.bool)
    pol.begin_episodes(starts)
    first = pol.choice.clone()
    assert abs(first.float().mean().item() - 0.75) < 0.07
    some = torch.zeros(400, dtype=torch.bool)
    some[:10] = True
    pol.begin_episodes(some)
    assert torch.equal(pol.choice[10:], first[10:])  # only starting envs draw again


def test_self_play_trains_on_both_sides_mirrored():
    """SP's batch is the two teams' slices stacked: the same transitions, each from its own side."""
    cfg = tiny("sp")
    env = volleybots.make_env("1v1", num_envs=8, seed=3, serve=0)
    seat = SelfPlay()
    torch.manual_seed(0)
    td = env.reset()
    policy = lambda t: t.set(("agents", "action"), torch.rand(8, 2, 4) * 2 - 1)  # noqa: E731
    batch, _ = collect(env, policy, td, 60)
    view = seat.view(env, batch)
    assert view.batch_size == (16, 60) and view["agents"].batch_size == (16, 60, 1)
    assert seat.spec(env).n_drones == 1 and cfg.population.self_play
    obs, nobs = batch["agents", "observation"], batch["next", "agents", "observation"]
    assert torch.equal(view["agents", "observation"][:8, :, 0], obs[:, :, 0])
    assert torch.equal(view["agents", "observation"][8:, :, 0], obs[:, :, 1])
    assert torch.equal(view["next", "agents", "observation"][8:, :, 0], nobs[:, :, 1])
    # each side sees itself on its own +x half (mirrored frames) at the start of every episode
    assert (view["agents", "observation"][:, 0, 0, 0] > 0).all()
    # zero-sum: where a rally is decided, one side's result is the other's loss
    decided = batch["next", "stats", "winner"][..., 0] >= 0
    done = batch["next", "done"][..., 0] & decided
    assert done.any()
    win_term = batch["next", "stats", "r_win_or_lose"][..., 0][done]
    assert torch.allclose(win_term, torch.zeros_like(win_term))  # team-mean of +100 and -100


def _read(run):
    meta = [json.loads(x) for x in (run / "population" / "meta.jsonl").read_text().splitlines()]
    pay = json.loads((run / "population" / "payoffs.json").read_text())
    members = sorted((run / "population").glob("member_*.pt"))
    return meta, pay, members


def test_psro_run_grows_the_population_and_fills_the_payoffs(tmp_path):
    cfg = tiny("psro_nash", "algo.iterations=2", "total_frames=100000")
    summary = start(cfg, tmp_path / "run")
    meta, pay, members = _read(tmp_path / "run")
    assert [m["iteration"] for m in meta] == [0, 1, 2] and len(members) == 3
    assert pay["members"] == ["random", "br1", "br2"]
    games = np.array(pay["games"])
    assert (games[~np.eye(3, dtype=bool)] == 6).all() and (np.diag(games) == 0).all()
    p = np.array(pay["payoff"])
    assert np.allclose(p, -p.T)
    for m in meta:
        assert len(m["mixture"]) == len(m["members"]) and abs(sum(m["mixture"]) - 1) < 1e-9
    assert all(2 <= m["oracle"]["updates"] <= 4 for m in meta[1:])
    for path in members:
        torch.load(path, weights_only=True)
    assert (tmp_path / "run" / "payoffs.png").stat().st_size > 1000
    assert summary["population"]["members"] == ["random", "br1", "br2"]
    # the run is a competitor: its members with the final meta-strategy
    comp = resolve_competitor(f"pop={tmp_path / 'run'}")
    assert len(comp.members) == 3 and comp.mixture == meta[-1]["mixture"]
    # a finished run is refused untouched; more iterations continue it
    before = (tmp_path / "run" / "config.yaml").read_text()
    with pytest.raises(ConfigError, match="has finished .*raise population.iterations"):
        resume(tmp_path / "run")
    with pytest.raises(ConfigError, match="cannot change 'population.solver'"):
        resume(tmp_path / "run", ["algo.solver=uniform"])
    assert (tmp_path / "run" / "config.yaml").read_text() == before
    resume(tmp_path / "run", ["algo.iterations=3"])
    meta, pay, members = _read(tmp_path / "run")
    assert [m["iteration"] for m in meta] == [0, 1, 2, 3] and pay["members"] == ["random", "br1", "br2", "br3"]


def test_an_oracle_the_budget_cannot_give_min_updates_is_not_started_and_a_resume_trains_it(tmp_path):
    """Iteration 2's oracle would get one batch of total_frames (256 of its min_updates 2 x 256): it could
    be no response to anything, so it is not started (a bare default run once spent minutes on such an
    oracle and dropped it); the run ends with {random, br1} and its frames unspent; a resume with more
    frames trains iteration 2 and br2 joins."""
    cfg = tiny("psro_nash", "algo.iterations=3", "algo.max_updates=2", "total_frames=768")
    summary = start(cfg, tmp_path / "run")
    meta, pay, members = _read(tmp_path / "run")
    assert pay["members"] == ["random", "br1"] and len(members) == 2 and [m["iteration"] for m in meta] == [0, 1]
    assert summary["population"]["members"] == ["random", "br1"] and summary["frames"] == 512
    assert "dropped_oracle" not in summary and summary["iterations"] == 1
    from volleybots.cli.train import _echo_summary

    # an oracle a time limit cuts short is still dropped, and said so
    assert "oracle 2 dropped: the budget ended it after 1 update(s) (256 frames)" in _echo_text(
        _echo_summary, {**summary, "dropped_oracle": {"iteration": 2, "updates": 1, "frames": 256}}, tmp_path / "run")
    summary = resume(tmp_path / "run", ["total_frames=1024"])
    meta, pay, _ = _read(tmp_path / "run")
    assert pay["members"] == ["random", "br1", "br2"] and meta[-1]["oracle"]["updates"] == 2
    assert "dropped_oracle" not in summary and summary["frames"] == 1024


def _echo_text(echo, summary, run) -> str:
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        echo(summary, run)
    return out.getvalue()


def test_fsp_learner_starts_from_the_previous_one(tmp_path, monkeypatch):
    cfg = tiny("fsp", "algo.iterations=2", "algo.max_updates=2", "algo.min_updates=2", "total_frames=100000")
    seen = []
    orig = PopulationLoop._oracle

    def spy(self, i, k, frames, updates, wall):
        out = orig(self, i, k, frames, updates, wall)
        seen.append(torch.load(self.run.path / "population" / f"member_{k:03d}.pt", weights_only=True)["algo"]["actor"])
        return out

    monkeypatch.setattr(PopulationLoop, "_oracle", spy)
    start(cfg, tmp_path / "fsp")
    # two updates move the second learner only a little from the first: far closer than a fresh init
    w1, w2 = (next(v for k, v in a.items() if k.endswith("0.weight")) for a in seen)
    assert (w2 - w1).abs().mean() < 0.1 * w1.abs().mean()



def test_a_learner_that_starts_from_a_clone_member_keeps_its_own_optimiser(tmp_path):
    """learner_init=last with a clone as the newest member: the learner takes the clone's networks, not
    its optimiser. Loading the clone's whole state once set the actor's learning rate to the clone's
    1e-3 (PPO's is 5e-4), and a 1v1 oracle's first free update then moved its policy by a KL of 106
    against 0.1 from init= (seed 3): it lost every game from there on."""
    from volleybots import zoo

    cfg = tiny("psro_nash", "algo.hidden=[256,128,128]", "algo.seed_members=[zoo:1v1/bc]", "algo.learner_init=last",
               "algo.iterations=1", "algo.min_updates=2", "algo.max_updates=2", "total_frames=100000")
    start(cfg, tmp_path / "p")
    member = torch.load(tmp_path / "p" / "population" / "member_001.pt", weights_only=True)["algo"]
    assert [g["lr"] for g in member["optim"]["param_groups"]] == [cfg.algo.actor_lr, cfg.algo.critic_lr] == [5e-4, 5e-4]
    clone = torch.load(zoo.lookup("zoo:1v1/bc").members[0], weights_only=True)["algo"]["actor"]
    w1, w2 = (next(v for k, v in a.items() if k.endswith("0.weight")) for a in (clone, member["actor"]))
    assert (w2 - w1).abs().mean() < 0.1 * w1.abs().mean()  # two updates from the clone, not a fresh init


def test_sp_run_is_one_member_with_full_weight(tmp_path):
    cfg = tiny("sp", "total_frames=1024")
    summary = start(cfg, tmp_path / "sp")
    meta, pay, members = _read(tmp_path / "sp")
    assert len(members) == 1 and meta[-1]["mixture"] == [1.0] and summary["frames"] == 1024
    assert (tmp_path / "sp" / "checkpoints" / "final.pt").is_file()


def test_killed_mid_iteration_resumes_to_the_same_population(tmp_path, monkeypatch):
    args = ("algo.iterations=2", "algo.min_updates=3", "algo.max_updates=4", "total_frames=100000")
    start(tiny("psro_uniform", *args), tmp_path / "whole")

    from volleybots.population import loop

    calls = {"n": 0}
    orig = loop.Convergence.__call__

    def crash(self, row):
        calls["n"] += 1
        if calls["n"] == 7:  # iteration 2, after its first periodic checkpoint
            raise KeyboardInterrupt("killed")
        return orig(self, row)

    monkeypatch.setattr(loop.Convergence, "__call__", crash)
    with pytest.raises(KeyboardInterrupt):
        start(tiny("psro_uniform", *args), tmp_path / "cut")
    monkeypatch.setattr(loop.Convergence, "__call__", orig)
    cut = tmp_path / "cut"
    assert len(_read(cut)[2]) == 2 and RunDir(cut).periodic_checkpoints()  # killed inside iteration 2
    resume(cut)
    (m1, p1, f1), (m2, p2, f2) = _read(tmp_path / "whole"), _read(cut)
    assert p1 == p2
    assert [m["mixture"] for m in m1] == [m["mixture"] for m in m2]
    assert [m["oracle"] for m in m1] == [m["oracle"] for m in m2]
    for a, b in zip(f1, f2, strict=True):
        sa, sb = torch.load(a, weights_only=True), torch.load(b, weights_only=True)
        if "algo" in sa:
            for k, v in sa["algo"]["actor"].items():
                assert torch.equal(v, sb["algo"]["actor"][k]), k


def test_payoff_table_adds_rows_antisymmetric():
    t = PayoffTable()
    t.add_member("a", [])
    t.add_member("b", [[6, 2, 2]])
    assert t.matrix()[1, 0] == pytest.approx(0.4) and t.matrix()[0, 1] == pytest.approx(-0.4)
    with pytest.raises(ValueError):
        t.add_member("c", [[1, 0, 0]])


def test_a_payoff_table_of_the_three_matrix_layout_loads_and_grows_in_the_wdl_layout(tmp_path):
    """payoffs.json once held wins, draws and losses as three [n][n] matrices: a run written then
    resumes, its table read as one wdl and written back in that layout."""
    path = tmp_path / "payoffs.json"
    old = {"members": ["a", "b"], "wins": [[0, 6], [2, 0]], "draws": [[0, 2], [2, 0]], "losses": [[0, 2], [6, 0]],
           "games": [[0, 10], [10, 0]], "payoff": [[0.0, 0.4], [-0.4, 0.0]]}
    path.write_text(json.dumps(old))
    t = PayoffTable.load(path)
    assert t.labels == ["a", "b"] and t.wdl.tolist() == [[[0, 0, 0], [6, 2, 2]], [[2, 2, 6], [0, 0, 0]]]
    assert t.matrix()[0, 1] == pytest.approx(0.4) and t.games.tolist() == old["games"]
    t.add_member("c", [[1, 0, 3], [0, 4, 0]])
    t.save(path)
    new = json.loads(path.read_text())
    assert not {"wins", "draws", "losses"} & set(new)
    assert new["wdl"][2] == [[1, 0, 3], [0, 4, 0], [0, 0, 0]] and new["wdl"][0][2] == [3, 0, 1]
    assert PayoffTable.load(path).wdl.tolist() == t.wdl.tolist()


def test_bad_seed_members_are_refused_before_anything_is_written(tmp_path):
    """Validation opens no file (a saved config stays valid when its files move); the pre-flight check
    that every start runs before writing anything does."""
    from volleybots.policies import check_references

    bad = tiny("fsp", f"algo.seed_members=[{tmp_path / 'nope.pt'}]")
    with pytest.raises(ConfigError, match="does not exist"):
        check_references(bad)
    with pytest.raises(ConfigError, match="does not exist"):
        start(bad, tmp_path / "never")
    assert not (tmp_path / "never").exists()
    start(tiny("sp", "total_frames=256"), tmp_path / "sp1v1")
    ckpt = tmp_path / "sp1v1" / "checkpoints" / "final.pt"
    ok = tiny("fsp", f"algo.seed_members=[random,{ckpt}]")
    check_references(ok)
    assert ok.population.seed_members[1] == str(ckpt)
    with pytest.raises(ConfigError, match="plays task '1v1', not '3v3'"):
        check_references(load(["task=3v3", "algo=fsp", f"algo.seed_members=[{ckpt}]"]))
    # an SP run is a single policy (its one member), so it may seed a population
    check_references(tiny("fsp", f"algo.seed_members=[{tmp_path / 'sp1v1'}]"))


def test_a_learner_trains_against_a_named_opponent_and_learns_from_its_team_only(tmp_path):
    """``opponent=``: MAPPO plays team 0 of 3v3 against a frozen random team; its critic is sized for
    its own three drones and its checkpoint records them."""
    from volleybots.train import Trainer, Versus, train

    cfg = load(["task=3v3", "opponent=random", "env.num_envs=8", "algo.steps_per_batch=8", "algo.minibatches=2", "algo.epochs=1",
                "algo.hidden=[32]", "total_frames=128", "evaluation.episodes=2", "evaluation.record=false", "progress=false"])
    assert cfg.algo.name == "mappo"
    summary = train(cfg, tmp_path / "br")
    state = torch.load(tmp_path / "br" / "checkpoints" / "final.pt", weights_only=True)
    assert state["n_agents"] == 3 and state["config"]["opponent"] == "random"
    critic_in = next(v for k, v in state["algo"]["critic"].items() if k.endswith("net.0.weight"))
    assert critic_in.shape[1] == 3 * 57  # the team's observations, not all six drones'
    assert summary["final_eval"]["stats"]["win"]["mean"] >= 0
    tr = Trainer(cfg, RunDir(tmp_path / "other"))
    assert isinstance(tr.seat, Versus) and tr.seat.opponent.label == "random"
    for bad, words in (
        (["task=bump_and_pass", "opponent=random"], "is for matches"),
        (["task=1v1", "algo=sp", "opponent=random"], "seed_members"),
    ):
        with pytest.raises(ConfigError, match=words):
            load(bad)
    # a missing opponent file: validation opens no file, the pre-flight check of every start does
    from volleybots.policies import check_references

    with pytest.raises(ConfigError, match="does not exist"):
        check_references(load(["task=3v3", "algo=mappo", f"opponent={tmp_path / 'missing'}"]))


def test_a_learners_batch_holds_each_steps_own_actions_and_their_log_probabilities(tmp_path):
    """The learner's slice of a collected batch: every step's own sampled action, with the log-probability
    of that action under the acting policy (a write into a tensor the env carries from step to step
    would leave every step holding the last one)."""
    from volleybots.train import Trainer

    cfg = load(["task=1v1", "opponent=random", "env.num_envs=8", "algo.steps_per_batch=8", "progress=false"])
    tr = Trainer(cfg, RunDir(tmp_path / "unused"))
    batch, _ = collect(tr.env, tr.seat.policy(tr.env, tr.algo.policy()), tr.env.reset(), 8)
    view = tr.seat.view(tr.env, batch)
    action = view["agents", "action"]
    assert not torch.equal(action[:, 0], action[:, 1])
    with torch.no_grad():
        lp = tr.algo.actor.get_dist(view.select(("agents", "observation")).clone()).log_prob(action)
    assert torch.allclose(lp, view["agents", "action_log_prob"], atol=1e-5)


def test_a_bc_seeded_population_starts_from_a_clone_that_beats_random_and_resumes_without_recloning(tmp_path, monkeypatch):
    """``algo.learner_init=bc algo.seed_members=[bc,random]``: the clone is trained once, in
    population/bc/, is member 0 and the start of every learner; a resume reuses it.

    Tiny budget: 4096 clone frames fitted at ``algo.bc_replay_ratio=128`` (128 Adam steps). The clone
    must already win most decisive games against random: a regression guard far below the zoo's clone
    (165/235/0 in 400 games). Measured here: 14/18/0 in 32 games (at the default ratio 8, 8 Adam
    steps: 7/1/8 in 16 games)."""
    import volleybots.train as train_pkg
    from volleybots.play.games import play_games
    from volleybots.ratings import record

    run = tmp_path / "run"
    cfg = tiny("psro_nash", "algo.learner_init=bc", "algo.seed_members=[bc,random]", "algo.bc_frames=4096", "algo.bc_replay_ratio=128",
               "env.num_envs=32", "algo.hidden=[64,64]", "algo.iterations=1", "algo.min_updates=1", "algo.max_updates=1",
               "total_frames=4096")
    assert cfg.algo.anchor_coeff == 0.3 and cfg.algo.actor_freeze_updates == 10  # the recipe, by default
    summary = start(cfg, run)
    assert summary["wall_time_split"]["clone"] > 0  # the clone's making is a part of the run's wall time of its own
    clone = run / "population" / "bc"
    assert (clone / "checkpoints" / "final.pt").is_file() and RunDir(clone).load_config().algo.name == "bc"
    assert RunDir(clone).load_config().algo.replay_ratio == 128
    meta, pay, members = _read(run)
    assert pay["members"] == ["bc", "random", "br1"]
    assert sum(pay["games"][0]) == 12  # the clone played its payoff games like any member
    # the clone learned its teacher: its fit's error fell over its 8 batches
    import csv

    mse = [float(r["action_mse"]) for r in csv.DictReader((clone / "metrics.csv").open()) if r.get("action_mse")]
    assert len(mse) == 8 and mse[-1] < 0.8 * mse[0], mse
    # the first member, the clone, already plays: it wins most decisive games against random
    g = play_games(cfg, resolve_competitor(f"bc={members[0]}"), resolve_competitor("random"), 32, seed=11, batch=32)
    w, d, l_ = (int(x) for x in g.total)
    assert w >= 8 and record.win_rate(g.total) >= 0.75, (w, d, l_)
    assert len(torch.load(members[0], weights_only=True)["algo"]["data"]["obs"]) == 0  # the member holds no dataset
    br1 = torch.load(members[2], weights_only=True)
    assert br1["init"]["source"].startswith("population/bc/") and br1["init"]["algo"] == "bc"  # the learner started from the clone (init=)
    # a resume with one more iteration reuses the clone: training or resuming a run now fails the test
    stamp = (clone / "checkpoints" / "final.pt").stat().st_mtime_ns

    def refuse(*a, **k):
        raise AssertionError("the clone was trained again")

    monkeypatch.setattr(train_pkg, "train", refuse)
    monkeypatch.setattr(train_pkg, "resume", refuse)
    resume(run, ["algo.iterations=2"])
    meta, pay, _ = _read(run)
    assert pay["members"] == ["bc", "random", "br1", "br2"]
    assert (clone / "checkpoints" / "final.pt").stat().st_mtime_ns == stamp


@pytest.mark.parametrize("task", ["1v1", "3v3", "6v6"])
def test_the_defaults_start_every_population_from_the_clone_and_fit_every_announced_iteration(task):
    """A bare ``train task=T algo=M`` is the recipe that plays: on 6v6 the clone as every learner's start
    (FSP: its first learner continues from it) and as the first member, on 1v1 the zoo start
    (zoo:1v1/dag_rally, sp keeping the clone), on 3v3 hierarchical members from zoo:3v3/hcsp_return's
    team (sp flat from the clone); a flat budget is the frames the announced iterations take;
    ``algo.start=scratch`` is the flat from-scratch recipe, one setting away."""
    want = {"sp": ("bc", []), "fsp": ("last", ["bc"]), "psro_uniform": ("bc", ["bc"]), "psro_nash": ("bc", ["bc"])}
    if task == "1v1":
        zoo = ["zoo:1v1/dag_rally"]
        want.update(fsp=("last", zoo), psro_uniform=("zoo", zoo), psro_nash=("zoo", zoo))
    if task == "3v3":
        # hierarchical oracles continue from the newest high level, PSRO-uniform's from the first team's
        first = {"psro_uniform": "first"}
        want.update({a: (first.get(a, "last"), ["zoo:3v3/hcsp_return"]) for a in ("fsp", "psro_uniform", "psro_nash")})
    scratch = {"sp": ("scratch", []), "fsp": ("last", ["random"]), "psro_uniform": ("scratch", ["random"]),
               "psro_nash": ("scratch", ["random"])}
    for algo in want:
        cfg = load([f"task={task}", f"algo={algo}"])
        assert (cfg.population.learner_init, list(cfg.population.seed_members)) == want[algo]
        raw = load([f"task={task}", f"algo={algo}", "algo.start=scratch"]).population
        assert (raw.learner_init, list(raw.seed_members), raw.members) == (*scratch[algo], "flat")
        if algo != "sp" and cfg.population.members == "flat":
            per_batch = cfg.env.num_envs * cfg.algo.steps_per_batch
            assert cfg.total_frames == cfg.population.iterations * cfg.population.max_updates * per_batch
            loop = PopulationLoop.__new__(PopulationLoop)
            loop.cfg, loop.m, loop.hierarchical = cfg, cfg.population, False
            assert loop._planned(1, 0) == cfg.population.iterations  # the progress line's "iteration i/N"
            # a budget that leaves the last oracle fewer than min_updates batches announces one iteration less
            short = cfg.total_frames - per_batch * (cfg.population.max_updates - 1)
            loop.cfg = load([f"task={task}", f"algo={algo}", f"total_frames={short}"])
            assert loop._planned(1, 0) == cfg.population.iterations - 1
    # an explicit value wins over algo.start; a bad start is one line
    assert load(["task=1v1", "algo=psro_nash", "algo.start=scratch", "algo.learner_init=bc"]).population.learner_init == "bc"
    with pytest.raises(ConfigError, match="unknown population.start 'none'; allowed: auto, clone, scratch, zoo"):
        load(["task=1v1", "algo=psro_nash", "algo.start=none"])


def test_the_cli_reports_each_oracle(tmp_path):
    from volleybots.cli.train import _oracle_text

    assert _oracle_text(2, {"updates": 14, "converged": True, "win_rate": 0.934}) == "br2 win 0.93 after 14 updates, converged"
    assert _oracle_text(1, {"updates": 20, "converged": False, "stopped": "max_updates", "win_rate": 0.4}).endswith(
        "not converged (max_updates)"
    )
    with pytest.raises(ConfigError, match="init=.*learner_init=bc"):
        start(tiny("psro_nash", "algo.learner_init=bc", f"init={tmp_path / 'x.pt'}"), tmp_path / "never")
    assert not (tmp_path / "never").exists()
