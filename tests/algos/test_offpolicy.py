"""Off-policy single-agent algorithms (dqn, ddpg, td3, sac): the replay data path, bootstrapping on
truncation only, warm-up, acting, and learning on a fixed batch. Runs of the full loop (checkpoints,
resume, the CLI) are in test_offpolicy_runs.py, learning on hover in test_offpolicy_learning.py."""

from __future__ import annotations

import math

import pytest
import torch

import volleybots
from volleybots.algos import ALGOS
from volleybots.algos.offpolicy import transitions
from volleybots.train import collect

OFF_POLICY = ("dqn", "ddpg", "td3", "sac")
SMALL = {"batch_size": 64, "buffer_size": 4096, "warmup_batches": 2, "hidden": [64, 64]}


def make(name: str, num_envs: int = 4, seed: int = 0, episode_len: int | None = None, **overrides):
    cls = ALGOS[name]
    space = "discrete" if name == "dqn" else "prt"
    env = volleybots.make_env("hover", num_envs=num_envs, action_space=space, seed=seed, episode_len=episode_len)
    cfg = cls.config_cls(**{**SMALL, **overrides})
    torch.manual_seed(seed)
    return cls(cfg, env, seed=seed), env


def rollout(algo, env, steps: int):
    batch, _ = collect(env, algo.policy(), env.reset(), steps)
    return batch


def test_transitions_flatten_agents_and_keep_the_pre_reset_observation():
    algo, env = make("ddpg", num_envs=4, episode_len=40)
    batch = rollout(algo, env, 100)  # random flight falls in ~25-60 steps (terminated) or lasts 40 (truncated)
    data = transitions(batch)
    assert data.batch_size == torch.Size([4 * 100])
    assert data["observation"].shape == (400, env.obs_dim) and data["action"].shape == (400, 4)
    assert data["next", "reward"].shape == (400, 1) and data["next", "terminated"].shape == (400, 1)
    flat_next = batch["next", "agents", "observation"].reshape(400, -1)
    assert torch.equal(data["next", "observation"], flat_next)
    done, terminated = batch["next", "done"].reshape(-1), batch["next", "terminated"].reshape(-1)
    assert (done & ~terminated).any() and terminated.any(), "the test needs both kinds of episode end"
    assert torch.equal(data["next", "terminated"].reshape(-1), terminated)
    assert torch.equal(data["next", "done"].reshape(-1), done)
    # within an env, the next observation of a step is the observation of the following step,
    # except across a reset, where it is the last observation of the ended episode
    obs = batch["agents", "observation"][:, :, 0]
    nxt = batch["next", "agents", "observation"][:, :, 0]
    same = (nxt[:, :-1] == obs[:, 1:]).all(-1)
    ended = batch["next", "done"][:, :-1, 0]
    assert same[~ended].all() and not same[ended].any()


@pytest.mark.parametrize("name", OFF_POLICY)
def test_truncation_bootstraps_and_termination_does_not(name):
    """The TD target of a transition cut by the time limit (done, not terminated) is the same as that
    of one that goes on; only ``terminated`` removes the bootstrap."""
    algo, env = make(name)
    data = transitions(rollout(algo, env, 16))[:64].clone()
    data["next", "reward"] = torch.full_like(data["next", "reward"], 0.5)

    def critic_loss(done: bool, terminated: bool) -> float:
        td = data.clone()
        td["next", "done"].fill_(done)
        td["next", "terminated"].fill_(terminated)
        torch.manual_seed(0)  # TD3's target smoothing noise, SAC's sampled next actions
        losses, _ = algo.losses(td)
        return float(losses["q" if name == "dqn" else "critic"].detach())

    going_on = critic_loss(False, False)
    truncated = critic_loss(True, False)
    terminated = critic_loss(True, True)
    assert truncated == pytest.approx(going_on, rel=1e-6)
    assert abs(terminated - going_on) > 1e-4 * max(1.0, abs(going_on))


def test_terminal_target_is_the_reward_and_truncated_target_bootstraps_from_the_target_networks():
    algo, env = make("ddpg")
    data = transitions(rollout(algo, env, 16))[:32].clone()
    reward = torch.linspace(-1, 1, 32).unsqueeze(-1)
    data["next", "reward"] = reward
    loss = algo.loss
    with torch.no_grad():
        # move the online networks away from the targets so the two can be told apart
        for p in loss.actor_network_params.values(True, True):
            p.add_(0.1)
        for p in loss.value_network_params.values(True, True):
            p.add_(0.1)
        data["next", "done"].fill_(True)
        data["next", "terminated"].fill_(True)
        _, info = loss.loss_value(data.clone())
        assert torch.allclose(info["target_value"], reward.squeeze(-1), atol=1e-6)
        data["next", "terminated"].fill_(False)
        _, info = loss.loss_value(data.clone())
        with loss.target_actor_network_params.to_module(loss.actor_network):
            nxt = loss.actor_network(data["next"].clone())
        with loss.target_value_network_params.to_module(loss.value_network):
            q_next = loss.value_network(nxt)["state_action_value"].squeeze(-1)
        expected = reward.squeeze(-1) + algo.cfg.gamma * q_next
        assert torch.allclose(info["target_value"], expected, atol=1e-5)


def test_dqn_acts_greedily_on_the_current_observation_with_the_online_network():
    algo, env = make("dqn", num_envs=8, eps_start=0.0, eps_end=0.0, random_warmup=False)
    td = env.reset()
    obs = td["agents", "observation"]
    # a ("next", ...) entry that would give other actions must not be looked at
    td.set(("next", "agents", "observation"), torch.randn_like(obs) * 5)
    with torch.no_grad():
        online = algo.qnet(obs).argmax(-1)
        # make the target network disagree with the online one
        for p in algo.loss.target_value_network_params.values(True, True):
            p.mul_(-1.0)
    for deterministic in (True, False):
        action = algo.policy(deterministic)(td.clone())["agents", "action"]
        assert action.shape == (8, 1) and action.dtype == torch.long
        assert torch.equal(action, online)


def test_dqn_epsilon_anneals_with_frames_and_explores_that_often():
    algo, env = make("dqn", num_envs=64, eps_start=1.0, eps_end=0.1, eps_anneal_frames=1000, random_warmup=False)
    assert algo.epsilon == 1.0
    algo.frames = 500
    assert algo.epsilon == pytest.approx(0.55)
    algo.frames = 5000
    assert algo.epsilon == pytest.approx(0.1)
    obs = torch.randn(4000, env.obs_dim)
    greedy = algo.greedy(obs)
    explored = algo.explore(obs)
    # a random action equals the greedy one 1 time in 16: P(differ) = eps x 15/16
    assert (explored != greedy).float().mean().item() == pytest.approx(0.1 * 15 / 16, abs=0.02)


@pytest.mark.parametrize("name", OFF_POLICY)
def test_warm_up_acts_at_random_and_updates_only_once_a_few_batches_are_stored(name):
    algo, env = make(name, num_envs=4, batch_size=64, warmup_batches=2)  # warm-up: 128 transitions
    logs1 = algo.update(rollout(algo, env, 16))  # 64 transitions
    assert algo.grad_steps == 0 and logs1["buffer_size"] == 64
    losses1 = {k: v for k, v in logs1.items() if k.startswith("loss")}
    assert losses1 and all(math.isnan(v) for v in losses1.values())
    # still warming up: uniformly random actions (spread over the whole range, unlike a fresh actor)
    actions = algo.policy()(env.reset())["agents", "action"]
    many = torch.stack([algo.policy()(env.reset())["agents", "action"] for _ in range(50)])
    if name == "dqn":
        assert len(many.unique()) >= 12
    else:
        assert many.min() < -0.9 and many.max() > 0.9 and actions.abs().max() <= 1.0
    logs2 = algo.update(rollout(algo, env, 16))  # 128: warm
    assert list(logs2) == list(logs1), "the columns of every batch must be the same (metrics.csv header)"
    # replay_ratio 8 x 64 frames / 64 per batch = 8 gradient steps
    assert algo.grad_steps == 8 and logs2["grad_steps"] == 8
    assert all(math.isfinite(v) for k, v in logs2.items() if k.startswith("loss"))


def test_td3_delays_the_actor_and_targets_follow_every_interval():
    algo, env = make("td3", target_update_interval=4, policy_delay=2, tau=0.5)
    algo.buffer.extend(transitions(rollout(algo, env, 32)))
    actor0 = [p.clone() for p in algo.loss.actor_network_params.values(True, True)]
    target0 = [p.clone() for p in algo.loss.target_qvalue_network_params.values(True, True)]
    logs = algo.train_step(algo.buffer.sample())
    assert "loss_actor" not in logs  # step 1: critic only
    assert all(torch.equal(a, b) for a, b in zip(actor0, algo.loss.actor_network_params.values(True, True), strict=True))
    logs = algo.train_step(algo.buffer.sample())
    assert "loss_actor" in logs  # step 2: critic and actor
    assert not all(torch.equal(a, b) for a, b in zip(actor0, algo.loss.actor_network_params.values(True, True), strict=True))
    algo.train_step(algo.buffer.sample())
    assert all(torch.equal(a, b) for a, b in zip(target0, algo.loss.target_qvalue_network_params.values(True, True), strict=True))
    algo.train_step(algo.buffer.sample())  # step 4: Polyak step with tau 0.5
    online = list(algo.loss.qvalue_network_params.values(True, True))
    target = list(algo.loss.target_qvalue_network_params.values(True, True))
    for t0, t, o in zip(target0, target, online, strict=True):
        assert torch.allclose(t, 0.5 * t0 + 0.5 * o, atol=1e-6)


def test_sac_temperature_moves_toward_the_target_entropy():
    algo, env = make("sac", alpha_init=0.1, alpha_lr=1e-2)
    assert algo.loss.target_entropy.item() == pytest.approx(-0.5 * 4)
    algo.buffer.extend(transitions(rollout(algo, env, 32)))
    alpha0 = algo.loss.log_alpha.exp().item()
    logs = [algo.train_step(algo.buffer.sample()) for _ in range(20)]
    # a fresh tanh-Gaussian has entropy well above -2 nats, so the temperature falls
    assert logs[0]["entropy"] > -2.0
    assert algo.loss.log_alpha.exp().item() < alpha0 * 0.9


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
@pytest.mark.parametrize("name", OFF_POLICY)
def test_losses_decrease_on_a_fixed_batch(name):
    """Repeated steps on one batch: the critic fits its (slowly moving) targets and the actor climbs
    the critic, so both losses end clearly below where they started."""
    algo, env = make(name, num_envs=8, lr=1e-3)
    batch = transitions(rollout(algo, env, 32))[:256]
    logs = [algo.train_step(batch.clone()) for _ in range(150)]
    critic = "loss_q" if name == "dqn" else "loss_critic"
    first = sum(log[critic] for log in logs[:10]) / 10
    last = sum(log[critic] for log in logs[-10:]) / 10
    assert last < 0.5 * first, (first, last)
    if name != "dqn":
        actor = [log["loss_actor"] for log in logs if "loss_actor" in log]
        assert sum(actor[-5:]) / 5 < sum(actor[:5]) / 5 - 0.05, (actor[:5], actor[-5:])
