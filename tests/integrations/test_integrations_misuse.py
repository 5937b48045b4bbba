"""Misuse of the Gymnasium, PettingZoo and SB3 adapters: each bad action, seed, switch or call order is
refused with a ValueError or RuntimeError naming the bad value and what is allowed, never reshaped,
truncated or carried out (issue 49)."""

from __future__ import annotations

import numpy as np
import pytest

from volleybots.integrations import VolleyGymEnv, VolleyParallelEnv, VolleySB3VecEnv, VolleyVectorEnv


@pytest.mark.parametrize("shape", [(16,), (2, 8), (4, 2, 2), (4, 1, 4)])
def test_vector_env_takes_only_its_exact_action_shape(shape):
    """A (4, 4) batch of 4 worlds: 16 numbers in any other shape are refused, not reshaped."""
    vec = VolleyVectorEnv("hover", num_envs=4)
    vec.reset(seed=0)
    with pytest.raises(ValueError, match=rf"got an action of shape \({shape[0]}, ?.*; expected shape \(4, 4\) of real numbers"):
        vec.step(np.zeros(shape, np.float32))
    obs, *_ = vec.step(np.zeros((4, 4), np.float32))
    assert obs.shape == (4, 26)


def test_shapes_and_dtypes_are_exact_on_every_adapter():
    one = VolleyGymEnv("hover")
    one.reset(seed=0)
    for bad, what in ((np.zeros((1, 4), np.float32), r"shape \(1, 4\); expected shape \(4,\)"),
                      (np.zeros((2, 2), np.float32), r"shape \(2, 2\); expected shape \(4,\)"),
                      (np.array(["a"] * 4), r"dtype <U1 .*expected real numbers"),
                      (np.ones(4, bool), r"dtype bool .*expected real numbers")):
        with pytest.raises(ValueError, match=what):
            one.step(bad)
    obs, *_ = one.step(np.zeros(4, np.int64))  # integers are real numbers: the env steps
    assert obs.shape == (26,)
    match = VolleyParallelEnv("1v1")
    match.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(2, 2\); expected shape \(4,\)"):
        match.step({"blue_0": np.zeros((2, 2), np.float32), "red_0": np.zeros(4, np.float32)})
    sb3 = VolleySB3VecEnv("hover", num_envs=2)
    sb3.reset()
    with pytest.raises(ValueError, match=r"shape \(8,\); expected shape \(2, 4\)"):
        sb3.step(np.zeros(8, np.float32))


def test_discrete_actions_must_be_integers_not_truncated():
    env = VolleyGymEnv("hover", action_space="discrete")
    env.reset(seed=0)
    for bad in (0.7, 3.9, np.float32(3.0), np.array([3]), True):
        with pytest.raises(ValueError, match=r"expected (shape \(\) of )?integers \(a Discrete action\)"):
            env.step(bad)
    with pytest.raises(ValueError, match="16"):  # outside 0..15: the env's own refusal
        env.step(16)
    env.step(np.int64(3))
    env.step(15)
    vec = VolleyVectorEnv("hover", num_envs=3, action_space="discrete")
    vec.reset(seed=0)
    with pytest.raises(ValueError, match=r"dtype float64 \(\[0\.7, 3\.9, 1\. \]\); expected integers"):
        vec.step(np.array([0.7, 3.9, 1.0]))
    with pytest.raises(ValueError, match=r"shape \(3, 1\); expected shape \(3,\)"):
        vec.step(np.zeros((3, 1), np.int64))
    coop = VolleyParallelEnv("bump_and_pass", action_space="discrete")
    coop.reset(seed=0)
    with pytest.raises(ValueError, match="expected integers"):
        coop.step({"drone_0": 0.7, "drone_1": 2})


def test_single_env_refuses_steps_after_its_episode_until_reset():
    env = VolleyGymEnv("hover", episode_len=3)
    env.reset(seed=0)
    ends = [env.step(np.zeros(4, np.float32))[3] for _ in range(3)]
    assert ends == [False, False, True]
    with pytest.raises(RuntimeError, match=r"episode has ended .*call reset\(\)"):
        env.step(np.zeros(4, np.float32))
    env.reset()
    assert env.step(np.zeros(4, np.float32))[3] is False
    match = VolleyParallelEnv("1v1", episode_len=1)
    match.reset(seed=0)
    match.step({a: np.zeros(4, np.float32) for a in match.agents})
    with pytest.raises(RuntimeError, match="call reset"):
        match.step({"blue_0": np.zeros(4, np.float32), "red_0": np.zeros(4, np.float32)})


def test_every_adapter_refuses_use_after_close():
    one, vec, match = VolleyGymEnv("hover"), VolleyVectorEnv("hover", num_envs=2), VolleyParallelEnv("1v1")
    sb3 = VolleySB3VecEnv("hover", 2)
    for env in (one, vec, match):
        env.reset(seed=0)
    sb3.reset()
    for env in (one, vec, match, sb3):
        env.close()
    with pytest.raises(RuntimeError, match="VolleyGymEnv is closed"):
        one.step(np.zeros(4, np.float32))
    with pytest.raises(RuntimeError, match="VolleyGymEnv is closed"):
        one.reset()
    with pytest.raises(RuntimeError, match="VolleyVectorEnv is closed"):
        vec.step(np.zeros((2, 4), np.float32))
    with pytest.raises(RuntimeError, match="VolleyParallelEnv is closed"):
        match.step({a: np.zeros(4, np.float32) for a in match.possible_agents})
    with pytest.raises(RuntimeError, match="VolleyParallelEnv is closed"):
        match.state()
    with pytest.raises(RuntimeError, match="VolleyVectorEnv is closed"):
        sb3.reset()


@pytest.mark.parametrize("seed", [1.7, 1.0, 2**63, 2**64, -1, True, "3"])
def test_bad_seeds_are_refused_alike_everywhere(seed):
    msg = r"seed must be None or an integer in \[0, 9223372036854775807\], got "
    for env in (VolleyGymEnv("hover"), VolleyVectorEnv("hover", num_envs=2), VolleyParallelEnv("1v1")):
        with pytest.raises(ValueError, match=msg):
            env.reset(seed=seed)
    sb3 = VolleySB3VecEnv("hover", 2)
    with pytest.raises(ValueError, match=msg):
        sb3.seed(seed)


def test_largest_seed_and_numpy_ints_are_taken():
    env = VolleyParallelEnv("1v1")
    a = env.reset(seed=2**63 - 1)[0]["blue_0"]
    b = env.reset(seed=np.int64(2**63 - 1))[0]["blue_0"]
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, env.reset(seed=0)[0]["blue_0"])


@pytest.mark.parametrize("kw", [{"reward_shaping": "no"}, {"reward_shaping": 0}, {"downwash": "false"}, {"seed": 1.5},
                                {"seed": 2**64}])
def test_constructor_switches_and_seeds_are_checked(kw):
    key, value = next(iter(kw.items()))
    allowed = f"{key} must be True or False, got {value!r}" if key != "seed" else f"seed must be None or an integer in .*, got {value!r}"
    for make in (lambda: VolleyGymEnv("hover", **kw), lambda: VolleyVectorEnv("hover", 2, **kw), lambda: VolleyParallelEnv("1v1", **kw)):
        with pytest.raises(ValueError, match=allowed):
            make()


@pytest.mark.parametrize("n", [2.5, 0, True, "4"])
def test_num_envs_must_be_a_positive_int(n):
    with pytest.raises(ValueError, match=rf"num_envs must be an integer >= 1, got {n!r}"):
        VolleyVectorEnv("hover", num_envs=n)


def test_bad_modes_are_named():
    with pytest.raises(ValueError, match=r"autoreset_mode must be one of \['same_step', 'next_step'\].*'later'"):
        VolleyVectorEnv("hover", 2, autoreset_mode="later")
    with pytest.raises(ValueError, match=r"render_mode must be None or one of \['rgb_array'\], got 'human'"):
        VolleyGymEnv("hover", render_mode="human")
    with pytest.raises(ValueError, match=r"render_mode must be None or one of \['rgb_array'\], got 'human'"):
        VolleyVectorEnv("hover", 2, render_mode="human")  # the vector envs render too (rgb_array), nothing else
    with pytest.raises(ValueError, match=r"legacy_names must be True or False, got 'yes'"):
        VolleyParallelEnv("1v1", legacy_names="yes")
