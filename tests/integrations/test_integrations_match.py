"""The batched matches for outside trainers (volleybots.integrations.match_env and sb3_match, issue 55):
the learner's rows are the TorchRL env's own numbers with the named competitor on the other team, the
opponent can be swapped or be the learner itself, a seed fixes a mixture's games, and SB3 PPO trains on it."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecMonitor
from tensordict import TensorDict, TensorDictBase

from volleybots import make_env
from volleybots.integrations import SnapshotOpponent, VolleyMatchSB3VecEnv, VolleyMatchVectorEnv, sb3_competitor
from volleybots.keys import ACTION, AGENTS, NEXT, OBS, REWARD
from volleybots.policies import callable_competitor, resolve_competitor
from volleybots.tasks.multi import TeamPolicies

WORLDS, STEPS, EPISODE = 3, 40, 15  # episodes of 15 steps: every world ends twice and resets within the run


def _actions(rows: int, seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [rng.uniform(-1, 1, (rows, 4)).astype(np.float32) for _ in range(STEPS)]


def _reference(task: str, opponent: str | None, team: int, actions: list[np.ndarray], seed: int):
    """The TorchRL env's own rollout (TorchRL's ``rollout``, its autoreset) with ``actions`` for the
    learner's drones and ``opponent``'s team policy for the others."""
    env = make_env(task, WORLDS, seed=seed, episode_len=EPISODE)
    step = iter(range(STEPS))

    def learner(td: TensorDictBase) -> TensorDictBase:
        a = torch.as_tensor(actions[next(step)])
        return td.set(ACTION, a.reshape(WORLDS, -1, 4))

    if opponent is None:
        policy = learner
    else:
        other = resolve_competitor(opponent).team_policy(env)
        policy = TeamPolicies(env, (learner, other) if team == 0 else (other, learner))
    return env, env.rollout(STEPS, policy, break_when_any_done=False, auto_reset=True)


@pytest.mark.parametrize(("task", "opponent", "team"), [("1v1", "scripted", 0), ("1v1", "scripted", 1), ("1v1", None, 0)])
def test_match_rows_are_the_torchrl_envs_numbers(task, opponent, team):
    """Same seed, same actions: the vector env's observations, rewards, ends and final observations are
    the TorchRL env's rows of the learner's drones, with the named competitor playing the other team
    (a scripted opponent gives the scripted games: its actions are those of resolve_competitor's)."""
    venv = VolleyMatchVectorEnv(task, WORLDS, opponent=opponent or "self", team=team, seed=5, episode_len=EPISODE)
    env, ref = _reference(task, opponent, team, _actions(venv.num_envs), seed=5)
    agents = list(range(env.n_drones)) if opponent is None else env.team_index(team).tolist()
    rows = lambda x: x[:, agents].reshape(venv.num_envs, *x.shape[2:]).numpy()  # noqa: E731
    assert venv.num_envs == WORLDS * len(agents)
    obs, _ = venv.reset(seed=5)
    np.testing.assert_array_equal(obs, rows(ref[:, 0].get(OBS)))
    ended = 0
    for t, a in enumerate(_actions(venv.num_envs)):
        obs, reward, term, trunc, info = venv.step(a)
        nxt = ref[:, t].get(NEXT)
        np.testing.assert_allclose(reward, rows(nxt.get(REWARD))[:, 0], rtol=1e-6)
        done = np.repeat(nxt.get("done").reshape(-1).numpy(), len(agents))
        np.testing.assert_array_equal(term | trunc, done)
        if done.any():
            ended += 1
            np.testing.assert_array_equal(info["final_obs"][done], rows(nxt.get(OBS))[done])
            assert set(info["final_stats"]) >= {"return_team0", "episode_len"}
        if t + 1 < STEPS:  # the next step's first observation: the reset one where a world ended
            np.testing.assert_array_equal(obs, rows(ref[:, t + 1].get(OBS)))
    assert ended >= 2


def test_the_opponent_is_the_named_competitor_and_can_be_swapped():
    """Random and scripted opponents give other games for the same learner actions; set_opponent
    swaps it between steps; a callable, a Competitor and a spec are all taken; bad ones are refused."""
    acts = _actions(WORLDS)
    runs = {}
    for opp in ("scripted", "zoo:1v1/bc"):
        venv = VolleyMatchVectorEnv("1v1", WORLDS, opponent=opp, seed=2, episode_len=EPISODE)
        venv.reset(seed=2)
        runs[opp] = np.stack([venv.step(a)[0] for a in acts[:10]])
    assert not np.array_equal(runs["scripted"], runs["zoo:1v1/bc"])
    venv = VolleyMatchVectorEnv("1v1", WORLDS, opponent="scripted", seed=2, episode_len=EPISODE)
    venv.reset(seed=2)
    seen = []
    venv.set_opponent(callable_competitor(lambda obs: seen.append(obs.shape) or torch.zeros(obs.shape[0], 4), "zeros"))
    venv.step(acts[0])
    assert seen == [(WORLDS, 39)] and venv.opponent.label == "zeros"
    with pytest.raises(ValueError, match="changes the rows"):
        venv.set_opponent("self")
    with pytest.raises(ValueError, match="not a match; allowed"):
        VolleyMatchVectorEnv("solo_bump", 2)
    with pytest.raises(ValueError, match="team must be 0 or 1"):
        VolleyMatchVectorEnv("1v1", 2, team=2)
    with pytest.raises(ValueError, match="plays task '3v3'"):
        VolleyMatchVectorEnv("1v1", 2, opponent="zoo:3v3/sp")
    with pytest.raises(ValueError, match="does not exist"):
        VolleyMatchVectorEnv("1v1", 2, opponent="no_such_dir/")


def test_a_seed_fixes_a_mixtures_games_and_3v3_has_three_rows_per_world():
    def run(seed):
        venv = VolleyMatchVectorEnv("1v1", 4, opponent="zoo:1v1/bc+zoo:1v1/bc_long", opponent_deterministic=True, seed=seed,
                                    episode_len=8)
        first, _ = venv.reset(seed=seed)
        return np.concatenate([first[None], np.stack([venv.step(a)[0] for a in _actions(4, seed=1)[:20]])])

    np.testing.assert_array_equal(run(3), run(3))
    venv = VolleyMatchVectorEnv("3v3", 2, opponent="random", team=1)
    obs, _ = venv.reset(seed=0)
    env = make_env("3v3", 2, seed=0)
    # team 1's three drones of each world, as the task gives them (mirrored to the +x side)
    np.testing.assert_array_equal(obs, env.reset().get(OBS)[:, env.team_index(1)].reshape(6, -1).numpy())
    assert venv.single_action_space.shape == (4,) and venv.action_space.shape == (6, 4)


def test_sb3_ppo_learns_on_the_batched_match_with_a_snapshot_opponent():
    """SB3's PPO runs on the match VecEnv (the rows are SB3's envs), with VecMonitor's episodes and the
    self-play snapshot refreshed as asked; an SB3 policy plays as a competitor."""
    env = VecMonitor(VolleyMatchSB3VecEnv("1v1", 8, opponent="zoo:1v1/bc", episode_len=20))
    model = PPO("MlpPolicy", env, n_steps=16, batch_size=64, n_epochs=1, seed=0, device="cpu")
    snap = SnapshotOpponent(every=2)
    model.learn(8 * 16 * 4, callback=snap)
    assert snap.refreshes == 3 and env.venv.venv.opponent.label == "snapshot_2"
    assert env.episode_count >= 8 * 3  # VecMonitor saw every world's episodes end (20 steps each)
    comp = sb3_competitor(model, "mine")
    env1 = make_env("1v1", 2, seed=0)
    sub = TensorDict({AGENTS: env1.select_team(env1.reset(), 0)}, batch_size=[2])
    expected = model.predict(sub.get(OBS)[:, 0].numpy(), deterministic=True)[0]
    np.testing.assert_allclose(comp.team_policy(env1)(sub).get(ACTION)[:, 0].numpy(), expected)
    self_env = VolleyMatchSB3VecEnv("3v3", 2, opponent="self", episode_len=10)
    assert self_env.num_envs == 12  # both teams' drones learn
    PPO("MlpPolicy", self_env, n_steps=8, batch_size=48, n_epochs=1, seed=0, device="cpu").learn(96)


@pytest.mark.slow
def test_the_sb3_match_example_trains_exports_and_ranks(tmp_path):
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "examples" / "sb3_match_1v1.py"
    spec = importlib.util.spec_from_file_location("sb3_match_1v1", path)
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    out = example.main(["--total-timesteps", "512", "--worlds", "4", "--games", "2", "--rivals", "zoo:1v1/bc", "--out", str(tmp_path)])
    assert out["timesteps"] == 512 and out["labels"] == ["sb3_ppo", "zoo:1v1/bc"]
    assert (tmp_path / "ppo_1v1.zip").is_file()
    assert resolve_competitor(f"torchscript:{tmp_path / 'policy.pt'}").sources[0]["kind"] == "torchscript"


def test_a_seed_fixes_sb3_ppo_on_the_match_against_a_mixture():
    def run():
        env = VolleyMatchSB3VecEnv("1v1", 4, opponent="scripted+zoo:1v1/bc", episode_len=12)
        model = PPO("MlpPolicy", env, n_steps=8, batch_size=32, n_epochs=1, seed=7, device="cpu").learn(64)
        return torch.cat([p.detach().flatten() for p in model.policy.parameters()])

    first, second = run(), run()
    assert torch.equal(first, second)
