"""(MA)PPO: truncation is bootstrapped and termination is not, the Huber value loss has the paper's
delta, discrete and multi-drone variants learn from a batch, and PPO clearly improves Hover."""

from __future__ import annotations

import pytest
import torch
import torch.nn.functional as F

from volleybots.algos import ALGOS
from volleybots.algos.ppo import HuberMAPPOLoss
from volleybots.config import load, make_env
from volleybots.runs import read_metrics
from volleybots.train import collect, train


def _setup(*overrides):
    torch.set_num_threads(1)
    cfg = load(["threads=1", *overrides])
    env = make_env(cfg)
    torch.manual_seed(cfg.seed)
    return cfg, env, ALGOS[cfg.algo.name](cfg.algo, env, seed=cfg.seed)


def test_gae_bootstraps_truncation_but_not_termination():
    cfg, env, algo = _setup("task=hover", "env.num_envs=2")
    batch, _ = collect(env, algo.policy(), env.reset(), 4)
    nxt = batch["next"]
    nxt["agents", "reward"].zero_()
    for key in ("done", "terminated", "truncated"):
        nxt[key].zero_()
    t = 1  # env 0 hits its time limit at step 1, env 1 crashes at step 1
    nxt["done"][:, t] = True
    nxt["truncated"][0, t] = True
    nxt["terminated"][1, t] = True
    with torch.no_grad():
        algo.loss.value_estimator(batch)
        v = algo.critic(batch[:, t].clone())["agents", "state_value"].reshape(2)
        v_next = algo.critic(nxt[:, t].clone())["agents", "state_value"].reshape(2)
    adv = batch["advantage"][:, t].reshape(2)
    gamma = cfg.algo.gamma
    assert v_next.abs().min() > 1e-4  # a bootstrap of zero would prove nothing
    torch.testing.assert_close(adv[0], gamma * v_next[0] - v[0])  # truncated: bootstrap V(s')
    torch.testing.assert_close(adv[1], -v[1])  # terminated: no future value


def test_huber_value_loss_has_the_configured_delta():
    delta = 10.0
    loss = HuberMAPPOLoss.__new__(HuberMAPPOLoss)
    torch.nn.Module.__init__(loss)
    loss.value_norm = None
    loss.huber_delta = delta
    target = torch.tensor([0.0, 3.0, -25.0, 40.0])
    pred = torch.zeros(4)
    t, v, _ = loss._critic_loss_inputs(target, pred, None)
    ours = delta**2 * F.smooth_l1_loss(v, t, reduction="none")
    torch.testing.assert_close(ours, F.huber_loss(pred, target, delta=delta, reduction="none"))


def _learns_one_batch(*overrides):
    cfg, env, algo = _setup(*overrides)
    before = [p.detach().clone() for p in algo.actor.parameters()]
    batch, _ = collect(env, algo.policy(), env.reset(), cfg.algo.steps_per_batch)
    logs = algo.update(batch)
    moved = max(float((p.detach() - b).abs().max()) for p, b in zip(algo.actor.parameters(), before, strict=True))
    assert moved > 0.0
    for k in ("loss_objective", "loss_critic", "entropy", "kl_approx"):
        assert k in logs and logs[k] == logs[k]  # present and not NaN
    return cfg, env, algo, batch, logs


def test_discrete_actions_use_a_categorical_policy():
    cfg, env, algo, batch, logs = _learns_one_batch("task=hover", "env.action_space=discrete", "env.num_envs=8", "algo.steps_per_batch=16")
    a = batch["agents", "action"]
    assert a.dtype == torch.long and a.shape == (8, 16, 1)
    assert int(a.min()) >= 0 and int(a.max()) < 16 and len(a.unique()) > 4  # it explores several actions
    # the entropy of a near-uniform Categorical over 16 actions at the start
    assert abs(logs["entropy"] - torch.log(torch.tensor(16.0)).item()) < 0.05


def test_mappo_shares_the_actor_and_centralises_the_critic():
    cfg, env, algo, batch, logs = _learns_one_batch("task=bump_and_pass", "algo=mappo", "env.num_envs=8", "algo.steps_per_batch=16")
    assert env.n_drones == 2
    first = next(algo.actor.parameters())
    assert first.shape[-1] == env.obs_dim  # one actor over one drone's observation, shared by both
    critic_in = algo.critic.module.net[0].in_features
    assert critic_in == 2 * env.obs_dim  # the critic sees both drones' observations
    with torch.no_grad():
        algo.loss.value_estimator(batch)
    assert batch["advantage"].shape == (8, 16, 2, 1)
    # the centralised value of drone 0 depends on drone 1's observation
    td = batch[:, 0].clone()
    v0 = algo.critic(td.clone())["agents", "state_value"][:, 0]
    td["agents", "observation"][:, 1] += 1.0
    v1 = algo.critic(td)["agents", "state_value"][:, 0]
    assert (v0 - v1).abs().max() > 1e-6


def test_observation_normalisation_tracks_the_batches():
    cfg, env, algo, batch, _ = _learns_one_batch("task=hover", "algo.obs_norm=true", "env.num_envs=8", "algo.steps_per_batch=16")
    stats = algo.obs_norm.module.stats
    assert int(stats.count) == 8 * 16
    obs = batch["next", "agents", "observation"].reshape(-1, env.obs_dim)
    torch.testing.assert_close(stats.mean, obs.mean(0), rtol=1e-4, atol=1e-4)


@pytest.mark.learning
def test_ppo_improves_hover(tmp_path):
    """About a minute on two busy cores: 100k frames of 64 envs. Random flight crashes within ~30 steps
    (return ~2); PPO must at least quintuple the return and beat random play in evaluation."""
    torch.set_num_threads(1)
    cfg = load(
        [
            "task=hover", "env.num_envs=64", "total_frames=1e5", "seed=0", "threads=1", "progress=false",
            "checkpoint.every=0", "evaluation.every=0", "evaluation.episodes=16", "evaluation.record=false",
        ]
    )
    summary = train(cfg, tmp_path / "run")
    rows = [r for r in read_metrics(tmp_path / "run" / "metrics.csv") if r["phase"] == "train"]
    first = sum(r["return"] for r in rows[:3]) / 3
    last = sum(r["return"] for r in rows[-3:]) / 3
    assert last > 5 * first and last > 20.0, (first, last)
    assert rows[-1]["episode_len"] > 2 * rows[0]["episode_len"]
    final = summary["final_eval"]["stats"]["return"]["mean"]
    from volleybots.eval import evaluate

    rand = evaluate("random", ["task=hover", "episodes=16", "threads=1"])["stats"]["return"]["mean"]
    assert final > 5 * max(rand, 1.0), (final, rand)


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
@pytest.mark.parametrize("name", ["mappo", "happo"])
def test_target_kl_stops_an_update_once_the_actor_has_moved(name):
    """``algo.target_kl``: an update ends before the first minibatch (from the second on) on which the
    actor is already more than 1.5 x target_kl from the policy that collected the batch, by TorchRL's
    approximate KL (the mean log-probability drop, which can be negative). With a target that any move
    exceeds, fewer than the 2 x 4 steps are taken; with one no step can reach, all; without one, none is logged."""
    over = ("task=bump_and_pass", f"algo={name}", "env.num_envs=8", "algo.steps_per_batch=16", "algo.minibatches=4", "algo.epochs=2")
    *_, logs = _learns_one_batch(*over, "algo.target_kl=1e-12")
    assert 1 / 8 <= logs["kl_steps"] < 1 and logs["kl_last"] > 1.5e-12  # what stopped it is logged
    *_, logs = _learns_one_batch(*over, "algo.target_kl=1e9")
    assert logs["kl_steps"] == 1.0
    *_, logs = _learns_one_batch(*over)
    assert "kl_steps" not in logs
    # the rule itself: 1.5 x the target, never while the actor is frozen, never without a target
    _, _, algo = _setup(*over, "algo.target_kl=0.02")
    assert algo.kl_stop({"kl_approx": torch.tensor(0.031)}) and not algo.kl_stop({"kl_approx": torch.tensor(0.029)})
    assert not algo.kl_stop({"kl_approx": torch.tensor(0.031)}, frozen=True)
    _, _, algo = _setup(*over)
    assert not algo.kl_stop({"kl_approx": torch.tensor(1e9)})
