"""`init=RUN_OR_CHECKPOINT`: a new run starts from exactly the saved actor (and critic where it fits),
with a fresh optimiser; a run that does not fit is refused with one line naming both sides, exit 2,
before anything is written."""

from __future__ import annotations

import pytest
import torch
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.config import load
from volleybots.errors import ConfigError
from volleybots.runs import RunDir
from volleybots.train import Trainer, train

TINY = ["env.num_envs=8", "threads=1", "progress=false", "evaluation.episodes=2", "evaluation.record=false", "seed=3"]
PPO_TINY = [*TINY, "algo.steps_per_batch=8", "algo.minibatches=2", "total_frames=128"]


@pytest.fixture(scope="module")
def hover_run(tiny_run):
    # init= checks the task's name, not its episode length: 40-step episodes keep the final evaluation short
    return tiny_run("task=hover", *PPO_TINY, "task.episode_len=40")


def _equal(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for k in a:
        assert torch.equal(a[k], b[k]), k


def _trainer(tmp_path, overrides):
    cfg = load(overrides)
    run = RunDir(tmp_path / "new")
    run.create(cfg)
    return Trainer(cfg, run)


def test_init_loads_exactly_the_saved_actor_and_critic(hover_run, tmp_path):
    saved = torch.load(hover_run / "checkpoints" / "final.pt", weights_only=True)["algo"]
    # another seed: its own random weights would differ from the saved ones
    tr = _trainer(tmp_path, ["task=hover", *PPO_TINY, "seed=11", f"init={hover_run}"])
    _equal(tr.algo.actor.state_dict(), saved["actor"])
    _equal(tr.algo.critic.state_dict(), saved["critic"])
    assert tr.init_info["loaded"] == ["actor", "critic"] and tr.init_info["frames"] == 128
    assert not tr.algo.optim.state  # a fresh optimiser: nothing of the source's Adam moments
    fresh = _trainer(tmp_path / "b", ["task=hover", *PPO_TINY, "seed=11"])
    assert not torch.equal(fresh.algo.actor.state_dict()["module.0.module.0.0.weight"], saved["actor"]["module.0.module.0.0.weight"])


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_init_of_mappo_from_ppo_and_off_policy_targets(hover_run, tmp_path):
    saved = torch.load(hover_run / "checkpoints" / "final.pt", weights_only=True)["algo"]
    tr = _trainer(tmp_path, ["task=hover", "algo=mappo", *PPO_TINY, f"init={hover_run}"])
    _equal(tr.algo.actor.state_dict(), saved["actor"])
    # an off-policy run started from another: its targets start from the loaded critics
    sac = tmp_path / "sac"
    train(
        load(["task=hover", "algo=sac", *TINY, "total_frames=64", "algo.steps_per_batch=8", "algo.batch_size=16", "task.episode_len=40"]),
        sac,
    )
    tr = _trainer(
        tmp_path / "s", ["task=hover", "algo=sac", *TINY, "total_frames=64", "algo.steps_per_batch=8", "algo.batch_size=16", f"init={sac}"]
    )
    src = torch.load(sac / "checkpoints" / "final.pt", weights_only=True)["algo"]["loss"]
    here = tr.algo.loss.state_dict()
    assert here.keys() == src.keys() and any(k.startswith("target_") for k in here)
    for k, v in here.items():
        assert torch.equal(v, here[k.removeprefix("target_")] if k.startswith("target_") else src[k]), k


@pytest.mark.parametrize(
    "overrides, words",
    [
        (["task=solo_bump"], ["task hover", "task solo_bump", "the task differs"]),
        (["task=hover", "env.action_space=ctbr"], ["env.action_space=prt", "env.action_space=ctbr", "action space differs"]),
        (["task=hover", "algo.hidden=[64]"], ["actor's networks differ", "[256] there, [64] here"]),
        (["task=hover", "algo=td3"], ["algo ppo", "algo td3", "actor's networks differ"]),
    ],
)
def test_a_run_that_does_not_fit_is_refused_naming_both_sides(hover_run, overrides, words):
    with pytest.raises(ConfigError) as e:
        from volleybots.train import check_init

        check_init(load([*overrides, *TINY, f"init={hover_run}"]))
    msg = str(e.value)
    assert "\n" not in msg and f"init={str(hover_run)!r}" in msg
    for w in words:
        assert w in msg, (w, msg)


def test_sac_from_a_ppo_run_keeps_its_actor_as_a_guide(hover_run, tmp_path):
    """SAC's networks cannot take PPO's actor: it becomes SAC's frozen guide (tests/algos/test_sac_init.py)."""
    saved = torch.load(hover_run / "checkpoints" / "final.pt", weights_only=True)["algo"]
    tr = _trainer(tmp_path, ["task=hover", "algo=sac", *TINY, "algo.batch_size=16", f"init={hover_run}"])
    assert tr.init_info["loaded"] == ["guide"] and tr.init_info["algo"] == "ppo"
    _equal(tr.algo.guide.actor.state_dict(), saved["actor"])


def test_cli_refuses_a_mismatched_init_with_exit_2_and_writes_nothing(hover_run, tmp_path):
    # in this process (a child process costs a fresh import of torch); tests/cli/test_cli.py checks a real one's exit
    out = tmp_path / "refused"
    res = CliRunner().invoke(app, ["train", "task=solo_bump", *PPO_TINY, f"init={hover_run}", f"hydra.run.dir={out}"])
    assert res.exit_code == 2, res.output[-2000:]
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "task hover" in lines[0] and "task solo_bump" in lines[0]
    assert not out.exists()


def test_init_names_a_missing_source(tmp_path):
    from volleybots.train import check_init

    with pytest.raises(ConfigError, match="nowhere.*neither a run directory"):
        check_init(load(["task=hover", *TINY, f"init={tmp_path / 'nowhere'}"]))


def test_actor_freeze_updates_lets_only_the_critic_learn_first():
    from volleybots.algos import ALGOS
    from volleybots.config import make_env
    from volleybots.train import collect

    torch.set_num_threads(1)
    cfg = load(["task=hover", *PPO_TINY, "algo.actor_freeze_updates=1"])
    env = make_env(cfg)
    algo = ALGOS["ppo"](cfg.algo, env, seed=0)
    td = env.reset()

    def step():
        nonlocal td
        actor = {k: v.clone() for k, v in algo.actor.state_dict().items()}
        critic = {k: v.clone() for k, v in algo.critic.state_dict().items()}
        batch, td = collect(env, algo.policy(), td, 8)
        logs = algo.update(batch)
        moved = lambda old, new: any(not torch.equal(old[k], new[k]) for k in old)  # noqa: E731
        return logs["actor_frozen"], moved(actor, algo.actor.state_dict()), moved(critic, algo.critic.state_dict())

    assert step() == (1.0, False, True)
    assert step() == (0.0, True, True)
    assert algo.state_dict()["updates"] == 2


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_best_pt_holds_the_policy_of_the_best_evaluation(tmp_path):
    """checkpoint.best: best.pt is the state at the evaluation with the best metric (Hover: the lowest
    distance, ties to the earliest), equal to the periodic checkpoint of that moment; resume ignores it."""
    torch.set_num_threads(1)
    cfg = load(
        [
            "task=hover",
            *TINY,
            "algo.steps_per_batch=16",
            "algo.minibatches=2",
            "total_frames=1024",
            "evaluation.every=128",
            "checkpoint.every=128",
            "checkpoint.keep=100",
            "task.episode_len=30",  # 8 evaluations of 2 episodes: 30 steps each instead of 500
        ]
    )
    summary = train(cfg, tmp_path / "run")
    run = RunDir(tmp_path / "run")
    evals = [(e["stats"]["distance"]["mean"], e["frames"]) for e in torch.load(run.final_path, weights_only=True)["evals"]]
    assert len(evals) == 8 and len({d for d, _ in evals}) > 1  # the evaluations differ, so the choice matters
    frames = min(evals, key=lambda e: e[0])[1]  # min keeps the first of equals
    best = torch.load(run.best_path, weights_only=True)
    assert best["frames"] == frames == summary["best_eval"]["frames"]
    assert summary["best_eval"]["distance"] == min(d for d, _ in evals)
    same = torch.load(run.final_path if frames == 1024 else run.ckpt_dir / f"ckpt_{frames:012d}.pt", weights_only=True)
    _equal(best["algo"]["actor"], same["algo"]["actor"])
    assert run.latest_checkpoint() == run.final_path


def test_the_anchor_holds_the_actor_near_where_it_started_and_decays():
    """algo.anchor_coeff: a KL penalty toward the actor as the run started (a frozen copy, checkpointed);
    with a large weight the actor moves far less from it than without, and the weight decays linearly
    to 0 over algo.anchor_updates batches."""
    from volleybots.algos import ALGOS
    from volleybots.config import make_env
    from volleybots.train import collect

    torch.set_num_threads(1)

    def run(extra):
        cfg = load(["task=hover", *PPO_TINY, "algo.actor_lr=3e-3", *extra])
        env = make_env(cfg)
        algo = ALGOS["ppo"](cfg.algo, env, seed=0)
        start = {k: v.clone() for k, v in algo.actor.state_dict().items()}
        td, weights = env.reset(), []
        for _ in range(3):
            batch, td = collect(env, algo.policy(), td, 8)
            weights.append(algo.update(batch)["anchor_weight"])
        probe, _ = collect(env, algo.policy(), td, 8)
        ref = ALGOS["ppo"](cfg.algo, env, seed=0)
        ref.actor.load_state_dict(start)
        with torch.no_grad():
            flat = probe.reshape(-1)
            kl = torch.distributions.kl_divergence(ref.actor.get_dist(flat), algo.actor.get_dist(flat)).mean().item()
        return algo, start, weights, kl

    _, _, weights, free = run([])
    assert weights == [0.0, 0.0, 0.0]
    algo, start, weights, held = run(["algo.anchor_coeff=1000", "algo.anchor_updates=2"])
    assert weights == [1000.0, 500.0, 0.0]
    assert free > 1e-3 and held < 0.2 * free, (free, held)
    _equal(algo.state_dict()["anchor"], start)  # the anchor is the starting actor, and it is checkpointed
    resumed = ALGOS["ppo"](algo.cfg, make_env(load(["task=hover", *PPO_TINY])), seed=5)
    resumed.load_state_dict(algo.state_dict())
    _equal(resumed.anchor.state_dict(), start)


def test_the_anchor_is_refused_where_the_actors_update_their_own_way():
    with pytest.raises(ConfigError, match="'happo' updates its actors its own way: algo.anchor_coeff must be 0"):
        load(["task=bump_and_pass", "algo=happo", *PPO_TINY, "algo.anchor_coeff=1"])
