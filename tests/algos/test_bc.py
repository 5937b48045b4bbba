"""algo=bc: the dataset holds the scripted teacher's actions (never the noisy executed ones), a tiny
Solo Bump run lowers the imitation loss and bumps where random play cannot, its run dir works with
`eval` and `init=`, and a resumed bc run repeats the uninterrupted one."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict

from volleybots.algos import ALGOS
from volleybots.algos.bc import TEACHER
from volleybots.config import load, make_env
from volleybots.errors import ConfigError
from volleybots.eval import evaluate
from volleybots.runs import RunDir, read_metrics
from volleybots.scripted import make_scripted_policy
from volleybots.train import Trainer, collect, train

QUIET = ["threads=1", "progress=false", "evaluation.record=false"]
# 6 batches of 64 envs x 64 steps: 2 of the teacher's play, then DAgger (half the envs the learner's)
SOLO_BUMP = [
    "task=solo_bump", "algo=bc", "env.num_envs=64", "algo.steps_per_batch=64", "algo.expert_frames=12288", "algo.replay_ratio=16",
    "algo.batch_size=1024", "algo.actor_lr=3e-3", "total_frames=24576", "evaluation.episodes=16", "seed=1", *QUIET,
]


@pytest.fixture(scope="module")
def solo_bump_bc(tmp_path_factory):
    torch.set_num_threads(1)
    path = tmp_path_factory.mktemp("bc") / "solo_bump"
    return path, train(load(SOLO_BUMP), path)


def test_the_dataset_holds_the_teachers_actions_not_the_executed_ones():
    torch.set_num_threads(1)
    cfg = load(["task=solo_bump", "algo=bc", "env.num_envs=16", "algo.action_noise=0.3", "algo.expert_frames=0", *QUIET])
    env = make_env(cfg)
    algo = ALGOS["bc"](cfg.algo, env, seed=0)
    algo.attach(env)  # from the first batch on, the learner drives half of the envs (DAgger)
    batch, _ = collect(env, algo.policy(), env.reset(), 8)
    executed, teacher = batch["agents", "action"], batch[TEACHER]
    assert (executed - teacher).abs().mean() > 0.1  # noise and the learner's own actions
    algo.update(batch)
    obs, labels = algo.data_obs[: algo.size], algo.data_act[: algo.size]
    assert algo.size == 16 * 8
    torch.testing.assert_close(labels, teacher.reshape(-1, 4))
    # the labels are what a fresh scripted player does in the stored states (it keeps no state)
    fresh = make_scripted_policy(env)(TensorDict({"agents": TensorDict({"observation": obs.unsqueeze(1)}, [len(obs), 1])}, [len(obs)]))
    torch.testing.assert_close(labels, fresh["agents", "action"].squeeze(1).clamp(-1, 1))
    assert not torch.allclose(labels, executed.reshape(-1, 4))


def test_bc_on_a_match_clones_its_own_teams_scripted_player(tmp_path):
    """On 1v1 the clone sits on team 0 against ``opponent=`` and its dataset holds what the scripted
    player does from team 0's (mirrored) observations, one row per step of its own drone."""
    torch.set_num_threads(1)
    cfg = load(["task=1v1", "algo=bc", "opponent=scripted", "env.num_envs=16", "algo.action_noise=0.3", "algo.expert_frames=0", *QUIET])
    run = RunDir(tmp_path / "bc_1v1")
    run.create(cfg)
    tr = Trainer(cfg, run)
    batch, _ = collect(tr.env, tr.seat.policy(tr.env, tr.algo.policy()), tr.env.reset(), 8)
    mine = tr.seat.view(tr.env, batch)
    tr.algo.update(mine)
    obs, labels = tr.algo.data_obs[: tr.algo.size], tr.algo.data_act[: tr.algo.size]
    assert tr.algo.size == 16 * 8  # team 0's drone only
    torch.testing.assert_close(obs, mine["agents", "observation"].reshape(-1, obs.shape[-1]))
    fresh = make_scripted_policy(tr.env)(TensorDict({"agents": TensorDict({"observation": obs.unsqueeze(1)}, [len(obs), 1])}, [len(obs)]))
    torch.testing.assert_close(labels, fresh["agents", "action"].squeeze(1).clamp(-1, 1))
    assert (mine["agents", "action"].reshape(-1, 4) - labels).abs().mean() > 0.1  # executed: noisy, half the learner's


@pytest.mark.learning
def test_bc_on_solo_bump_lowers_the_imitation_loss_and_bumps(solo_bump_bc):
    path, summary = solo_bump_bc
    rows = [r for r in read_metrics(path / "metrics.csv") if r["phase"] == "train"]
    teacher_phase = [r for r in rows if r["dagger"] == 0.0]
    assert len(teacher_phase) >= 2
    assert teacher_phase[-1]["action_mse"] < 0.7 * teacher_phase[0]["action_mse"]
    assert teacher_phase[-1]["loss_bc"] < teacher_phase[0]["loss_bc"]
    assert all(r["teacher_s"] > 0 for r in rows)  # the teacher's time is counted
    bumps = summary["final_eval"]["stats"]["bumps"]["mean"]
    # the same 16 held-out episodes (seed 1 + 10000) played by random actions make no bump at all
    random = evaluate("random", ["task=solo_bump", f"seed={1 + 10_000}", "threads=1"], episodes=16)["stats"]["bumps"]["mean"]
    assert random == 0.0
    assert bumps >= 2.0, bumps


@pytest.mark.slow
def test_a_bc_run_dir_evaluates_and_starts_ppo(solo_bump_bc, tmp_path):
    path, summary = solo_bump_bc
    # 200-step episodes (of 800): the clone bumps 3 times in each on average (5.5 in whole ones)
    res = evaluate(str(path), ["seed=1", "threads=1", "task.episode_len=200"], episodes=4)
    assert res["target"].startswith("bc@") and res["stats"]["bumps"]["mean"] > 0
    saved = torch.load(path / "checkpoints" / "final.pt", weights_only=True)["algo"]
    cfg = load(["task=solo_bump", "algo=ppo", "env.num_envs=8", f"init={path}", *QUIET])
    run = RunDir(tmp_path / "ppo")
    run.create(cfg)
    tr = Trainer(cfg, run)
    for part in ("actor", "critic"):
        sd = getattr(tr.algo, part).state_dict()
        assert sd.keys() == saved[part].keys()
        assert all(torch.equal(sd[k], saved[part][k]) for k in sd), part


def test_bc_refuses_tasks_without_a_teacher_and_discrete_actions():
    with pytest.raises(ConfigError, match="opponent="):  # a match's player plays one team: seat the clone
        load(["task=1v1", "algo=bc"])
    with pytest.raises(ConfigError, match="action_space"):
        load(["task=hover", "algo=bc", "env.action_space=discrete"])
    with pytest.raises(ConfigError, match="learner_envs"):
        load(["task=hover", "algo=bc", "algo.learner_envs=1.5"])


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_a_resumed_bc_run_repeats_the_uninterrupted_one(tmp_path):
    torch.set_num_threads(1)
    common = ["task=hover", "algo=bc", "env.num_envs=8", "algo.steps_per_batch=16", "algo.expert_frames=256", "algo.batch_size=64",
              "total_frames=512", "checkpoint.every=256", "evaluation.episodes=2", "seed=2", *QUIET,
              "task.episode_len=40"]  # episodes of 40 steps: the two final evaluations (not compared) stay short
    train(load(common), tmp_path / "full")
    cut = load(common)
    run = RunDir(tmp_path / "cut")
    run.create(cut)
    tr = Trainer(cut, run)
    tr.train_loop(stop=lambda row: row["frames"] >= 384)  # killed after the checkpoint at 256 frames
    ckpt = run.periodic_checkpoints()[-1]
    Trainer(cut, run, checkpoint=ckpt).fit()
    a = torch.load(tmp_path / "full" / "checkpoints" / "final.pt", weights_only=True)["algo"]
    b = torch.load(tmp_path / "cut" / "checkpoints" / "final.pt", weights_only=True)["algo"]
    for part in ("actor", "critic"):
        assert all(torch.equal(a[part][k], b[part][k]) for k in a[part]), part
    assert torch.equal(a["data"]["obs"], b["data"]["obs"]) and torch.equal(a["counters"], b["counters"])


@pytest.mark.learning
def test_bc_on_a_drill_lowers_the_imitation_loss_and_touches_the_ball(tmp_path):
    """The drills (tasks/drills.py) are single-drone tasks with a scripted player: bc clones them.
    3 batches of 64 envs x 64 steps of the teacher's play (the Serve's ball is struck at once)."""
    torch.set_num_threads(1)
    cfg = load(["task=serve", "algo=bc", "env.num_envs=64", "algo.steps_per_batch=64", "algo.expert_frames=12288",
                "total_frames=12288", "evaluation.episodes=16", "seed=1", *QUIET])
    summary = train(cfg, tmp_path / "serve")
    rows = [r for r in read_metrics(tmp_path / "serve" / "metrics.csv") if r["phase"] == "train"]
    assert len(rows) == 3
    assert rows[-1]["action_mse"] < 0.7 * rows[0]["action_mse"] and rows[-1]["loss_bc"] < rows[0]["loss_bc"]
    hits = summary["final_eval"]["stats"]["hits"]["mean"]
    # the same 16 episodes (seed 1 + 10000) with random actions: the drone hardly meets the dropped ball
    random = evaluate("random", ["task=serve", f"seed={1 + 10_000}", "threads=1"], episodes=16)["stats"]["hits"]["mean"]
    assert hits >= 0.8 and hits > random + 0.5, (hits, random)
