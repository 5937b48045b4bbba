"""The Gymnasium and PettingZoo views (volleybots.integrations): the official checkers pass, the views
give the batched env's own numbers for the same seed, seeds fix the run, agents are named per team, and
the CleanRL-style example trains through them."""

from __future__ import annotations

import importlib.util
import sys
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode
from pettingzoo.test import parallel_api_test

import volleybots
from volleybots.integrations import (
    IDS,
    VolleyGymEnv,
    VolleyParallelEnv,
    VolleyVectorEnv,
)

ROOT = Path(__file__).resolve().parents[2]
UNBOUNDED = ("minimum value is -infinity", "maximum value is infinity")  # positions and velocities are unbounded (no hard limit)


def test_solo_bump_passes_gymnasium_check_env():
    env = gym.make("volleybots/SoloBump-v0")
    assert isinstance(env.unwrapped, VolleyGymEnv) and env.unwrapped.task == "solo_bump"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    others = [str(w.message) for w in caught if not any(u in str(w.message) for u in UNBOUNDED)]
    assert others == []
    assert env.observation_space.shape == (32,) and env.observation_space.dtype == np.float32
    assert env.action_space == gym.spaces.Box(-1.0, 1.0, (4,), np.float32)
    discrete = VolleyGymEnv("hover", action_space="discrete")
    assert discrete.action_space == gym.spaces.Discrete(16) and discrete.observation_space.shape == (26,)


def test_every_single_drone_task_is_registered_and_only_those():
    assert IDS["volleybots/SoloBump-v0"] == "solo_bump" and IDS["volleybots/BackAndForth-v0"] == "back_and_forth"
    assert set(IDS.values()) == {"hover", "back_and_forth", "hit_the_ball", "solo_bump", "serve", "pass", "set", "attack", "receive"}
    vec = gym.make_vec("volleybots/Hover-v0", num_envs=3)
    assert isinstance(vec, VolleyVectorEnv) and vec.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    assert vec.observation_space.shape == (3, 26) and vec.action_space.shape == (3, 4)
    with pytest.raises(ValueError, match="'3v3' is not a single-drone task; use .*VolleyParallelEnv"):
        VolleyVectorEnv("3v3")
    with pytest.raises(ValueError, match=r"shape \(3, 3\); expected shape \(3, 4\)"):
        vec.reset(seed=0)
        vec.step(np.zeros((3, 3), np.float32))


def test_vector_env_gives_the_batched_envs_numbers_autoreset_included():
    """Same seed, same actions: the observations, rewards and ends of the TorchRL env, and at a
    truncation the final observation in info with the next episode's first one returned."""
    n, length = 3, 4
    vec = VolleyVectorEnv("solo_bump", num_envs=n, episode_len=length)
    ref = volleybots.make_env("solo_bump", num_envs=n, episode_len=length, seed=11)
    obs, _ = vec.reset(seed=11)
    td = ref.reset()
    np.testing.assert_array_equal(obs, td["agents", "observation"][:, 0].numpy())
    rng = np.random.default_rng(0)
    for step in range(length + 2):
        action = rng.uniform(-1, 1, (n, 4)).astype(np.float32)
        obs, reward, term, trunc, info = vec.step(action)
        td.set(("agents", "action"), torch.as_tensor(action).unsqueeze(1))
        cur, td = ref.step_and_maybe_reset(td)
        np.testing.assert_array_equal(obs, td["agents", "observation"][:, 0].numpy())
        np.testing.assert_allclose(reward, cur["next", "agents", "reward"][:, 0, 0].numpy())
        np.testing.assert_array_equal(term, cur["next", "terminated"][:, 0].numpy())
        np.testing.assert_array_equal(trunc, cur["next", "truncated"][:, 0].numpy())
        done = term | trunc
        if step == length - 1:  # every episode still running is cut here
            assert trunc.any() and "final_obs" in info
        if done.any():
            np.testing.assert_array_equal(info["_final_obs"], done)
            np.testing.assert_array_equal(info["final_obs"][done], cur["next", "agents", "observation"][done, 0].numpy())
            assert not np.array_equal(info["final_obs"][done], obs[done])  # the returned row is the new episode's
            np.testing.assert_allclose(info["final_stats"]["return"][done], cur["next", "stats", "return"][done, 0].numpy())
            assert set(info["final_stats"]) >= {"return", "episode_len", "bumps"} and "episode" not in info
        else:
            assert info == {}


def test_single_env_matches_the_batched_env_and_seeds_fix_the_run():
    env = VolleyGymEnv("hit_the_ball")
    ref = volleybots.make_env("hit_the_ball", num_envs=1, seed=5)
    obs, _ = env.reset(seed=5)
    np.testing.assert_array_equal(obs, ref.reset()["agents", "observation"][0, 0].numpy())

    def run(seed):
        out, _ = env.reset(seed=seed)
        trace = [out]
        for _ in range(5):
            o, r, *_ = env.step(np.full(4, 0.3, np.float32))
            trace += [o, np.array([r])]
        return np.concatenate(trace)

    np.testing.assert_array_equal(run(3), run(3))
    assert not np.array_equal(run(3), run(4))
    vec = VolleyVectorEnv("hit_the_ball", num_envs=2)
    assert np.array_equal(vec.reset(seed=9)[0], vec.reset(seed=9)[0]) and not np.array_equal(vec.reset(seed=9)[0], vec.reset(seed=10)[0])


def test_3v3_passes_the_parallel_api_test_with_agents_per_team():
    env = VolleyParallelEnv("3v3")
    parallel_api_test(env, num_cycles=300)
    team0 = ["blue_0", "blue_1", "blue_2"]
    team1 = ["red_0", "red_1", "red_2"]
    assert env.possible_agents == team0 + team1 and env.n_agents == 6
    assert env.groups == {"team0": team0, "team1": team1}
    assert [env.team_of[a] for a in env.possible_agents] == list(env.env.teams)
    assert env.observation_space("red_2").shape == (57,) and env.action_space("blue_0").shape == (4,)
    # the same seed gives the batched env's observations, each agent its row
    obs, _ = env.reset(seed=21)
    ref = volleybots.make_env("3v3", num_envs=1, seed=21).reset()["agents", "observation"][0].numpy()
    for i, agent in enumerate(env.possible_agents):
        np.testing.assert_array_equal(obs[agent], ref[i])
    with pytest.raises(ValueError, match=r"missing \['red_2'\]"):
        env.step({a: np.zeros(4, np.float32) for a in env.possible_agents[:-1]})


def test_parallel_env_episode_end_and_cooperative_names():
    env = VolleyParallelEnv("bump_and_pass", episode_len=3, action_space="discrete")
    assert env.possible_agents == ["drone_0", "drone_1"] and env.groups == {"agents": ["drone_0", "drone_1"]}
    env.reset(seed=0)
    for _ in range(3):
        *_, trunc, info = env.step({a: 5 for a in env.agents})
    assert trunc == {"drone_0": True, "drone_1": True} and env.agents == []
    assert info["drone_0"]["final_stats"]["episode_len"] == 3.0 and np.isfinite(info["drone_1"]["final_stats"]["return"])
    with pytest.raises(RuntimeError, match="call reset"):
        env.step({})


def test_missing_extras_are_named(monkeypatch):
    # the re-imports below rebind volleybots.integrations: put the real one back afterwards
    monkeypatch.setattr(volleybots, "integrations", sys.modules["volleybots.integrations"])

    def fresh_import():
        for mod in [m for m in sys.modules if m.startswith("volleybots.integrations")]:
            monkeypatch.delitem(sys.modules, mod)
        return importlib.import_module("volleybots.integrations")

    monkeypatch.setitem(sys.modules, "pettingzoo", None)  # None in sys.modules: "import pettingzoo" fails
    integrations = fresh_import()  # the Gymnasium side needs no pettingzoo
    assert integrations.VolleyVectorEnv.__name__ == "VolleyVectorEnv"
    with pytest.raises(ImportError, match=r"pip install 'volleybots\[pettingzoo\]'"):
        integrations.VolleyParallelEnv  # noqa: B018
    for name in ("stable_baselines3", "stable_baselines3.common.vec_env"):  # the submodule too: another test may have imported it
        monkeypatch.setitem(sys.modules, name, None)
    integrations = fresh_import()
    with pytest.raises(ImportError, match=r"pip install 'volleybots\[sb3\]'"):
        integrations.VolleySB3VecEnv  # noqa: B018
    monkeypatch.setitem(sys.modules, "gymnasium", None)
    with pytest.raises(ImportError, match=r"pip install 'volleybots\[gym\]'"):
        fresh_import()


def test_cleanrl_example_trains_on_solo_bump():
    spec = importlib.util.spec_from_file_location("cleanrl_ppo_solo_bump", ROOT / "examples" / "cleanrl_ppo_solo_bump.py")
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    returns = example.main(["--total-timesteps", "512", "--num-envs", "8", "--num-steps", "64", "--update-epochs", "1"])
    assert len(returns) >= 1 and np.all(np.isfinite(returns))


def _example(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "examples" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _curve(path) -> list[dict]:
    import csv

    with open(path) as fh:
        return list(csv.DictReader(fh))


def test_the_examples_write_learning_curves_of_the_tasks_metric(tmp_path):
    """Both examples write their curve (benchmarks/curves_rise.py plots them): one row per iteration /
    rollout, the step counts rising by one rollout each, the task's metric (Hover's distance) by name."""
    example = _example("cleanrl_ppo_solo_bump")
    example.main(["--env-id", "volleybots/Hover-v0", "--total-timesteps", "256", "--num-envs", "4", "--num-steps", "32",
                  "--update-epochs", "1", "--curve", str(tmp_path / "cleanrl.csv")])
    rows = _curve(tmp_path / "cleanrl.csv")
    assert list(rows[0]) == ["steps", "seconds", "episodes", "return", "distance"]
    assert [int(r["steps"]) for r in rows] == [128, 256]
    pytest.importorskip("stable_baselines3")
    sb3 = _example("sb3_ppo_hover")
    out = sb3.main(["--total-timesteps", "256", "--num-envs", "4", "--n-steps", "32", "--epochs", "1", "--curve", str(tmp_path / "sb3.csv"),
                    "--task", "hover"])
    rows = _curve(tmp_path / "sb3.csv")
    assert list(rows[0]) == ["steps", "seconds", "episodes", "return", "distance"]
    assert [int(r["steps"]) for r in rows] == [128, 256] and [r[0] for r in out] == [128, 256]
