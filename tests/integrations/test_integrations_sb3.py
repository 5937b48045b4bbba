"""The shipped Stable-Baselines3 VecEnv (volleybots.integrations.VolleySB3VecEnv): SB3's conventions
(terminal observation, time-limit flag, one info per world) on the batched env's own numbers, and SB3
PPO training through it on Solo Bump (issue 49)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecMonitor

from volleybots.integrations import VolleySB3VecEnv, VolleyVectorEnv
from volleybots.integrations.sb3_env import ppo_kwargs


def test_sb3_vecenv_steps_the_batched_env_with_sb3_conventions():
    """Same seed and actions as the Gymnasium vector env: the same observations and rewards, the
    final observation and statistics in the done worlds' infos, time-limit cuts flagged."""
    sb3 = VolleySB3VecEnv("hover", num_envs=3, episode_len=4)
    gym_vec = VolleyVectorEnv("hover", num_envs=3, episode_len=4)
    assert sb3.seed(7) == [7, 7, 7]
    np.testing.assert_array_equal(sb3.reset(), gym_vec.reset(seed=7)[0])
    assert sb3.observation_space == gym_vec.single_observation_space and sb3.action_space.shape == (4,)
    rng = np.random.default_rng(0)
    for t in range(6):
        action = rng.uniform(-1, 1, (3, 4)).astype(np.float32)
        obs, reward, dones, infos = sb3.step(action)
        g_obs, g_reward, term, trunc, info = gym_vec.step(action)
        np.testing.assert_array_equal(obs, g_obs)
        np.testing.assert_allclose(reward, g_reward, rtol=1e-6)
        assert reward.dtype == np.float32 and dones.dtype == bool and len(infos) == 3
        np.testing.assert_array_equal(dones, term | trunc)
        for i in range(3):
            if dones[i]:
                np.testing.assert_array_equal(infos[i]["terminal_observation"], info["final_obs"][i])
                assert infos[i]["TimeLimit.truncated"] == bool(trunc[i] and not term[i])
                assert infos[i]["final_stats"]["return"] == pytest.approx(float(info["final_stats"]["return"][i]))
                assert "episode" not in infos[i]  # left to VecMonitor
            else:
                assert infos[i] == {}
        if t == 3:
            assert dones.all()
    assert sb3.get_attr("task") == ["hover"] * 3 and sb3.env_is_wrapped(VecMonitor, indices=[0, 2]) == [False, False]
    sb3.close()


@pytest.mark.slow
def test_sb3_ppo_trains_through_the_vecenv_on_solo_bump():
    torch.manual_seed(0)
    env = VecMonitor(VolleySB3VecEnv("solo_bump", num_envs=4, episode_len=60))
    ends = []

    class Ends(BaseCallback):
        def _on_step(self):
            ends.extend(i for i in self.locals["infos"] if "episode" in i)
            return True

    model = PPO("MlpPolicy", env, n_epochs=2, seed=0, device="cpu", **ppo_kwargs(4, n_steps=128))  # the documented keywords
    assert model.batch_size == 128 and model.policy.optimizer.defaults["foreach"] and model.policy.optimizer.defaults["eps"] == 1e-5
    before = [p.detach().clone() for p in model.policy.parameters()]
    model.learn(total_timesteps=3072, callback=Ends())
    assert model.num_timesteps == 3072
    assert any(not torch.equal(a, b) for a, b in zip(before, model.policy.parameters(), strict=True))  # it learned something
    assert len(ends) >= 4 and len(model.ep_info_buffer) == min(len(ends), 100)
    for info in ends:  # VecMonitor's return and length beside the task's own statistics
        assert info["episode"]["r"] == pytest.approx(info["final_stats"]["return"], rel=1e-4, abs=1e-4)
        assert info["episode"]["l"] == info["final_stats"]["episode_len"] <= 60
        assert np.isfinite(info["final_stats"]["bumps"])
    action, _ = model.predict(env.reset(), deterministic=True)
    assert action.shape == (4, 4) and np.isfinite(action).all()


@pytest.mark.slow
def test_supersuit_vector_conversion_trains_sb3_on_a_match():
    """docs/integrations.md's SuperSuit snippet: the type-only indicator, one SB3 world per agent."""
    ss = pytest.importorskip("supersuit")
    from volleybots.integrations import VolleyParallelEnv

    env = ss.agent_indicator_v0(VolleyParallelEnv("1v1", episode_len=50), type_only=True)
    vec = ss.concat_vec_envs_v1(ss.pettingzoo_env_to_vec_env_v1(env), 2, base_class="stable_baselines3")
    assert vec.num_envs == 4 and vec.observation_space.shape == (41,)
    # no PPO(seed=): SuperSuit's ConcatVecEnv has no seed() for SB3 to call
    model = PPO("MlpPolicy", vec, n_steps=64, batch_size=64, n_epochs=1, device="cpu").learn(total_timesteps=512)
    assert model.num_timesteps == 512
    obs = vec.reset()
    np.testing.assert_array_equal(obs[:, -2:], [[1, 0], [0, 1], [1, 0], [0, 1]])  # blue, red in each copy


def test_ppo_kwargs_split_the_rollout_into_minibatches():
    kw = ppo_kwargs(64)
    assert (kw["n_steps"], kw["batch_size"]) == (128, 2048)  # 64 worlds x 128 steps in 4 minibatches
    assert kw["policy_kwargs"] == {"optimizer_kwargs": {"eps": 1e-5, "foreach": True}}  # SB3's own eps kept
    assert ppo_kwargs(8, n_steps=64, minibatches=8)["batch_size"] == 64
    with pytest.raises(ValueError, match="minibatches must divide the rollout of 3 x 128 = 384 samples, got 5"):
        ppo_kwargs(3, minibatches=5)
