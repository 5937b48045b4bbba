"""The adapters beside the standard wrappers and tools: Gymnasium's RecordEpisodeStatistics (single and
vector, both autoreset modes), SB3's Monitor, RecordVideo on the rgb_array render, SuperSuit's type-only
agent indicator, the PettingZoo env's global state, and observation bounds that hold (issue 49)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import supersuit as ss
from stable_baselines3.common.monitor import Monitor

import volleybots
from volleybots.integrations import VolleyGymEnv, VolleyParallelEnv, VolleyVectorEnv

ZERO = np.zeros(4, np.float32)


def test_record_episode_statistics_and_monitor_work_beside_the_task_statistics():
    for wrap in (gym.wrappers.RecordEpisodeStatistics, lambda e: Monitor(e)):
        env = wrap(gym.make("volleybots/Hover-v0", episode_len=5))
        env.reset(seed=0)
        ends = []
        for _ in range(3):  # three episodes: past an end and on into the next
            trunc = False
            while not trunc:
                _, _, term, trunc, info = env.step(ZERO)
                assert not term
            ends.append(info)
            env.reset()
        for info in ends:
            assert info["episode"]["l"] == 5 and info["final_stats"]["episode_len"] == 5.0
            assert info["episode"]["r"] == pytest.approx(info["final_stats"]["return"], rel=1e-5)
            assert set(info["final_stats"]) >= {"return", "distance", "r_pose"}


@pytest.mark.parametrize("mode", ["same_step", "next_step"])
def test_vector_record_episode_statistics_in_both_autoreset_modes(mode):
    vec = gym.wrappers.vector.RecordEpisodeStatistics(VolleyVectorEnv("hover", num_envs=3, episode_len=4, autoreset_mode=mode))
    vec.reset(seed=1)
    seen = 0
    for _ in range(11):  # two episode ends (and, next_step, the resets after them)
        _, reward, _, _, info = vec.step(np.zeros((3, 4), np.float32))
        if "episode" in info:
            done = info["_episode"]
            np.testing.assert_array_equal(done, info["_final_stats"])
            np.testing.assert_allclose(info["episode"]["r"][done], info["final_stats"]["return"][done], rtol=1e-5)
            np.testing.assert_array_equal(info["episode"]["l"][done], 4)
            seen += int(done.sum())
    assert seen == 6


def test_next_step_autoreset_gives_the_same_episodes_one_step_later():
    """Same seed, same actions: next_step returns the last observation where same_step puts it in
    info, then (actions ignored, reward 0) the next episode's first one that same_step returned."""
    same = VolleyVectorEnv("hover", num_envs=2, episode_len=3)
    nxt = VolleyVectorEnv("hover", num_envs=2, episode_len=3, autoreset_mode="next_step")
    assert nxt.metadata["autoreset_mode"] == gym.vector.AutoresetMode.NEXT_STEP
    assert same.metadata["autoreset_mode"] == gym.vector.AutoresetMode.SAME_STEP
    np.testing.assert_array_equal(same.reset(seed=4)[0], nxt.reset(seed=4)[0])
    rng = np.random.default_rng(0)
    for _ in range(2):  # two episodes
        for t in range(3):
            action = rng.uniform(-1, 1, (2, 4)).astype(np.float32)
            o1, r1, _, tr1, i1 = same.step(action)
            o2, r2, _, tr2, i2 = nxt.step(action)
            np.testing.assert_allclose(r1, r2)
            np.testing.assert_array_equal(tr1, tr2)
            if t < 2:
                np.testing.assert_array_equal(o1, o2)
        assert tr2.all() and "final_obs" not in i2
        np.testing.assert_array_equal(o2, i1["final_obs"])
        np.testing.assert_allclose(i2["final_stats"]["return"], i1["final_stats"]["return"])
        o3, r3, te3, tr3, i3 = nxt.step(np.full((2, 4), np.nan, np.float32))  # ignored: no crash, no warning
        np.testing.assert_array_equal(o3, o1)
        assert (r3 == 0).all() and not te3.any() and not tr3.any() and i3 == {}


def test_observation_bounds_hold_where_given_and_are_physical():
    env = VolleyGymEnv("solo_bump")
    low, high = env.observation_space.low, env.observation_space.high
    root = volleybots.make_env("solo_bump").obs_layout().parts  # pos 3, quat 4, vel 3, omega 3, heading 3, up 3, throttle 4
    unit = np.float32(1 + 1e-4)  # [-1, 1] and float32 rounding
    assert np.isinf(low[:3]).all() and (low[3:7] == -unit).all() and (high[3:7] == unit).all()  # position free, quaternion unit
    assert np.isinf(high[7:13]).all() and (high[13:23] == unit).all() and (low[13:23] == -unit).all() and np.isinf(low[23:]).all()
    assert root[0] == ("root", 23)
    assert VolleyGymEnv("hover", action_space="ctbr").observation_space.shape == (22,)  # no throttles
    rng = np.random.default_rng(0)
    for task in ("solo_bump", "attack", "3v3", "bump_and_pass", "set_and_spike_easy"):
        if task in ("solo_bump", "attack"):
            vec = VolleyVectorEnv(task, num_envs=8)
            obs, _ = vec.reset(seed=2)
            for _ in range(40):
                assert vec.observation_space.contains(obs), task
                obs, *_ = vec.step(rng.uniform(-1, 1, (8, 4)).astype(np.float32))
        else:
            pz = VolleyParallelEnv(task, episode_len=40)
            obs, _ = pz.reset(seed=2)
            while pz.agents:
                for a, o in obs.items():
                    assert pz.observation_space(a).contains(o), (task, a)
                obs, *_ = pz.step({a: rng.uniform(-1, 1, 4).astype(np.float32) for a in pz.agents})
            space, turn = pz.observation_space(pz.possible_agents[0]), pz.env.layout.slice("turn")
            assert (space.low[turn] == 0).all() and (space.high[turn] == 1).all()  # the turn one-hot
            assert np.isinf(space.high[pz.env.layout.slice("ball_vel")]).all()


def test_parallel_env_state_and_supersuit_type_only_indicator():
    env = VolleyParallelEnv("3v3")
    obs, _ = env.reset(seed=3)
    state = env.state()
    np.testing.assert_array_equal(state, np.concatenate([obs[a] for a in env.possible_agents]))
    assert env.state_space.shape == (6 * 57,) and env.state_space.contains(state)
    obs, *_ = env.step({a: np.zeros(4, np.float32) for a in env.agents})
    np.testing.assert_array_equal(env.state(), np.concatenate([obs[a] for a in env.possible_agents]))
    # the <type>_<n> names give SuperSuit's type-only indicator one type per team
    wrapped = ss.agent_indicator_v0(VolleyParallelEnv("1v1"), type_only=True)
    obs, _ = wrapped.reset(seed=0)
    assert wrapped.observation_space("blue_0").shape == (41,)  # 39 and one slot per team
    np.testing.assert_array_equal(obs["blue_0"][-2:], [1, 0])
    np.testing.assert_array_equal(obs["red_0"][-2:], [0, 1])
    assert VolleyParallelEnv("1v1", legacy_names=True).possible_agents == ["team0_drone0", "team1_drone0"]
    with pytest.raises(AssertionError, match="infinite bounds"):  # positions and velocities have none (docs/integrations.md)
        ss.normalize_obs_v0(VolleyParallelEnv("1v1"))


def test_rgb_array_frames_follow_the_episode():
    env = VolleyGymEnv("solo_bump", render_mode="rgb_array")
    assert env.render_mode == "rgb_array" and "rgb_array" in env.metadata["render_modes"]
    env.reset(seed=0)
    first = env.render()
    assert first.shape == (368, 640, 3) and first.dtype == np.uint8
    assert (first.reshape(-1, 3) != first[0, 0]).any(axis=1).mean() > 0.05  # a picture, not a blank canvas
    for _ in range(25):
        env.step(np.ones(4, np.float32))  # full throttle: the drone climbs
    assert not np.array_equal(env.render(), first)
    assert VolleyGymEnv("hover").render() is None
    frame = VolleyParallelEnv("1v1", render_mode="rgb_array")
    frame.reset(seed=0)
    assert frame.render().shape == (368, 640, 3)


@pytest.mark.slow
def test_record_video_writes_a_playable_file(tmp_path):
    imageio = pytest.importorskip("imageio.v2")
    env = gym.wrappers.RecordVideo(gym.make("volleybots/SoloBump-v0", render_mode="rgb_array", episode_len=12), str(tmp_path / "videos"),
                                   episode_trigger=lambda e: True, disable_logger=True)
    env.reset(seed=0)
    trunc = term = False
    while not (term or trunc):
        _, _, term, trunc, _ = env.step(env.action_space.sample())
    env.close()
    [video] = list((tmp_path / "videos").glob("*.mp4"))
    reader = imageio.get_reader(str(video))
    frames = [f for f in reader]
    assert reader.get_meta_data()["fps"] == 50 and frames[0].shape == (368, 640, 3)
    assert len(frames) >= 12
