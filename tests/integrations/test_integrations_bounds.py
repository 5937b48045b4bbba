"""The adapters' opt-in declared observation bounds (``clip_obs=True``): finite everywhere, the court
plus a margin and the documented caps, observations clipped into them with the clipped values counted,
and SuperSuit's ``normalize_obs_v0`` working on them (issue 49)."""

from __future__ import annotations

import numpy as np
import pytest
import supersuit as ss

from volleybots.integrations import VolleyGymEnv, VolleyParallelEnv, VolleySB3VecEnv, VolleyVectorEnv
from volleybots.integrations.bounds import HEIGHT, MARGIN, SPEED_CAP, SPIN_CAP, ObsClip


def test_declared_bounds_are_finite_and_follow_the_court():
    env = VolleyParallelEnv("1v1", clip_obs=True)  # the 1 vs 1 court: 6 m x 3 m
    space, layout = env.observation_space("blue_0"), env.env.layout
    assert np.isfinite(space.low).all() and np.isfinite(space.high).all()
    np.testing.assert_array_equal(space.high[:3], [3 + MARGIN, 1.5 + MARGIN, HEIGHT[1]])  # the drone's position
    np.testing.assert_array_equal(space.low[:3], [-3 - MARGIN, -1.5 - MARGIN, HEIGHT[0]])
    np.testing.assert_array_equal(space.high[7:10], [SPEED_CAP] * 3)  # its velocity, then its angular velocity
    np.testing.assert_array_equal(space.high[10:13], [SPIN_CAP] * 3)
    ball = layout.slice("ball")  # one point minus another: twice the half-extents
    np.testing.assert_array_equal(space.high[ball], [2 * (3 + MARGIN), 2 * (1.5 + MARGIN), HEIGHT[1] - HEIGHT[0]])
    assert (space.high[layout.slice("turn")] == 1).all() and (space.low[layout.slice("id")] == 0).all()
    assert env.state_space.shape == (2 * space.shape[0],) and np.isfinite(env.state_space.high).all()
    wide = VolleyGymEnv("solo_bump", clip_obs=True).observation_space  # the full court: 18 m x 9 m
    assert wide.high[0] == 9 + MARGIN and wide.high[1] == 4.5 + MARGIN
    plain = VolleyGymEnv("solo_bump").observation_space  # without the opt-in: unbounded where the physics is
    assert np.isinf(plain.high[:3]).all() and VolleyGymEnv("solo_bump").obs_clip is None


def test_obs_clip_clips_onto_the_bounds_and_counts():
    clip = ObsClip(np.array([-1.0, 0.0], np.float32), np.array([1.0, 2.0], np.float32))
    out = clip(np.array([[0.5, 3.0], [-4.0, 1.0], [1.0, 0.0]], np.float32))
    np.testing.assert_array_equal(out, [[0.5, 2.0], [-1.0, 1.0], [1.0, 0.0]])
    assert (clip.clipped, clip.seen) == (2, 6)


def test_supersuit_normalize_obs_works_on_the_declared_bounds():
    with pytest.raises(AssertionError, match="infinite bounds"):  # the default spaces are unbounded where the physics is
        ss.normalize_obs_v0(VolleyParallelEnv("1v1"))
    wrapped = VolleyParallelEnv("1v1", clip_obs=True, episode_len=30)
    env = ss.normalize_obs_v0(wrapped)
    raw = VolleyParallelEnv("1v1", clip_obs=True, episode_len=30)  # the same episode, unnormalised
    space = raw.observation_space("blue_0")
    obs, _ = env.reset(seed=3)
    raw_obs, _ = raw.reset(seed=3)
    rng = np.random.default_rng(0)
    steps = 0
    while env.agents:
        for a, o in obs.items():
            assert o.min() >= 0.0 and o.max() <= 1.0, a
            np.testing.assert_allclose(o, (raw_obs[a] - space.low) / (space.high - space.low), rtol=1e-5, atol=1e-6)
        actions = {a: rng.uniform(-1, 1, 4).astype(np.float32) for a in env.agents}
        obs, *_ = env.step(actions)
        raw_obs, *_ = raw.step(actions)
        steps += 1
    assert steps == 30 or raw.agents == []
    assert wrapped.obs_clip.seen == (steps + 1) * 2 * space.shape[0]
    assert wrapped.obs_clip.clipped <= wrapped.obs_clip.seen // 100  # random play seldom reaches the declared bounds


def test_vector_adapters_clip_into_their_declared_space():
    vec = VolleyVectorEnv("hover", num_envs=4, clip_obs=True, episode_len=20, autoreset_mode="next_step")
    obs, _ = vec.reset(seed=0)
    rng = np.random.default_rng(1)
    for _ in range(25):  # past the episode's end: the reset rows are clipped too
        assert vec.observation_space.contains(obs)
        obs, *_ = vec.step(rng.uniform(-1, 1, (4, 4)).astype(np.float32))
    rows, rest = divmod(vec.obs_clip.seen, obs.shape[1])  # every row returned, and the reset rows of next_step
    assert rest == 0 and rows > 26 * 4
    sb3 = VolleySB3VecEnv("hover", num_envs=2, clip_obs=True)
    assert np.isfinite(sb3.observation_space.high).all() and sb3.observation_space.contains(sb3.reset()[0])
    with pytest.raises(ValueError, match="clip_obs must be True or False, got 'yes'"):
        VolleyParallelEnv("1v1", clip_obs="yes")
