"""The env step as one static-shape function (docs/performance.md), and what it does with bad actions
(docs/physics.md "Bad actions"): compiled once per (task, env count), never recompiled by partial
resets, equal to the eager step and to TorchRL's generic step-and-reset; a non-finite action crashes
its drone's episode; a discrete action outside 0..15 is refused. Both backends where it applies."""

import json
import warnings

import pytest
import torch
from torchrl.envs import EnvBase
from typer.testing import CliRunner

import volleybots
import volleybots.tasks.base as base
from volleybots.cli import app


class CountingBackend:
    """A torch.compile backend that runs the captured graph as is and counts every (re)compilation:
    dynamo's guards and recompiles are the same as with inductor, without its code generation."""

    def __init__(self):
        self.graphs = 0

    def __call__(self, gm, example_inputs):
        self.graphs += 1
        return gm.forward


def run(env, steps, seed=0):
    """Random actions (seeded) through step_and_maybe_reset, with a partial reset of two envs at step 4
    (so that episodes end out of step) and a full reset at step 25; returns the stacked step outputs
    and how many envs were done at each step."""
    gen = torch.Generator().manual_seed(seed)
    td = env.reset()
    out, done = [], []
    for i in range(steps):
        act = torch.rand(env.num_envs, env.n_drones, 4, generator=gen) * 2 - 1
        step, td = env.step_and_maybe_reset(td.set(("agents", "action"), act))
        out.append(step.exclude("agents").clone())
        done.append(int(step["next", "done"].sum()))
        if i == 4:
            mask = (torch.arange(env.num_envs) < 2).unsqueeze(-1)
            td = env.reset(td.set("_reset", mask))
        elif i == 25:
            td = env.reset()
    return torch.stack(out), done


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
@pytest.mark.parametrize("task", ["solo_bump", "3v3"])
def test_compiled_step_compiles_once_and_matches_eager(task, monkeypatch):
    counter = CountingBackend()
    monkeypatch.setattr(base, "COMPILE_BACKEND", counter)
    compiled = volleybots.make_env(task, num_envs=6, seed=4, compile=True, episode_len=9)
    eager = volleybots.make_env(task, num_envs=6, seed=4, episode_len=9)
    a, done = run(compiled, 40)
    b, _ = run(eager, 40)
    assert counter.graphs == 2  # one step graph, one reset graph: partial resets of any size reuse them
    assert len(set(done)) >= 3  # resets of different numbers of envs did happen
    for key in [("next", "agents", "observation"), ("next", "agents", "reward"), ("next", "done"), ("next", "stats", "return")]:
        assert torch.allclose(a[key], b[key], atol=1e-5), key


def test_own_step_and_reset_equals_torchrls_generic_one():
    """The env's step_and_maybe_reset (one step, one masked reset, tensordicts built directly) gives
    what TorchRL's generic step + partial reset gives, both returned tensordicts, key by key."""
    envs = [volleybots.make_env("bump_and_pass", num_envs=5, seed=1, episode_len=6) for _ in range(2)]
    tds = [env.reset() for env in envs]
    gen = torch.Generator().manual_seed(0)
    resets = 0
    for _ in range(14):
        act = torch.rand(5, 2, 4, generator=gen) * 2 - 1
        ours = envs[0].step_and_maybe_reset(tds[0].set(("agents", "action"), act.clone()))
        generic = EnvBase._step_and_maybe_reset(envs[1], tds[1].set(("agents", "action"), act.clone()))
        for x, y in zip(ours, generic, strict=True):
            assert set(x.keys(True, True)) == set(y.keys(True, True))
            for k in x.keys(True, True):
                assert torch.equal(x[k], y[k]), k
        tds = [ours[1], generic[1]]
        resets += int(ours[0]["next", "done"].sum())
    assert resets >= 10  # the comparison went through resets


@pytest.mark.parametrize("physics", ["torch", "mujoco"])
@pytest.mark.parametrize("action_space", ["prt", "ctbr"])
def test_nonfinite_action_crashes_its_drone_only(physics, action_space):
    env = volleybots.make_env("bump_and_pass", num_envs=3, seed=0, physics=physics, action_space=action_space)
    td = env.reset()
    act = torch.zeros(3, 2, 4)
    act[1, 0, 2] = float("nan")
    act[2, 1] = float("inf")
    with pytest.warns(RuntimeWarning, match="non-finite action"):
        out = env.step(td.set(("agents", "action"), act))["next"]
    assert out["terminated"].squeeze(-1).tolist() == [False, True, True]
    assert out["stats", "nonfinite_action"].squeeze(-1).tolist() == [0.0, 1.0, 1.0]
    for key in [("agents", "observation"), ("agents", "reward")]:
        assert torch.isfinite(out[key]).all(), key
    for v in env.physics.state.tensors().values():
        assert torch.isfinite(v).all()
    # the crashed worlds reset cleanly and the warning is not repeated
    td = env.maybe_reset(out.exclude("agents").update({"agents": {"observation": out["agents", "observation"]}}))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = env.step(td.set(("agents", "action"), act))["next"]
    assert out["stats", "nonfinite_action"].squeeze(-1).tolist() == [0.0, 1.0, 1.0]


@pytest.mark.parametrize("physics", ["torch", "mujoco"])
@pytest.mark.parametrize("bad", [-1, 16, 3.7, float("nan")])
def test_discrete_action_out_of_range_is_refused(physics, bad):
    env = volleybots.make_env("solo_bump", num_envs=2, seed=0, physics=physics, action_space="discrete")
    td = env.reset()
    before = env.physics.state.pos.clone()
    act = torch.tensor([[15.0], [bad]]) if isinstance(bad, float) else torch.tensor([[15], [bad]])
    with pytest.raises(ValueError, match=r"discrete action .* out of range: allowed integers 0\.\.15"):
        env.step(td.set(("agents", "action"), act))
    assert torch.equal(env.physics.state.pos, before) and (env.t == 0).all()  # nothing stepped
    ok = env.step(td.set(("agents", "action"), torch.tensor([[15], [0]])))["next"]
    assert torch.isfinite(ok["agents", "observation"]).all()


def test_bench_json_rows():
    res = CliRunner().invoke(
        app, ["bench", "--json", "tasks=[hover]", "backends=[torch]", "num_envs=[4]", "devices=[cpu]", "repeats=1", "steps=3"]
    )
    assert res.exit_code == 0, res.output
    rows = json.loads(res.stdout)
    assert [(r["task"], r["kind"], r["backend"], r["num_envs"]) for r in rows] == [("hover", "env", "torch", 4)]
    assert rows[0]["env_steps_per_s"] > 0 and rows[0]["compile"] is False


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_bench_training_rows():
    """train=True adds the trainer's end-to-end rate (collection + update) of PPO on Solo Bump, labelled
    in the table and left out of the torch/MuJoCo ratios."""
    from volleybots.bench import format_table, run_bench, speed_ratios
    from volleybots.config import BenchOptions

    rows = run_bench(BenchOptions(tasks=["solo_bump"], backends=["torch"], num_envs=[2], devices=["cpu"], repeats=1, steps=2, threads=1,
                                  train=True, train_batches=1))
    assert [(r["kind"], r["task"]) for r in rows] == [("env", "solo_bump"), ("train ppo", "solo_bump")]
    train = rows[1]
    assert train["steps"] == 64 and train["num_envs"] == 2 and train["env_steps_per_s"] > 0 and train["env_steps_per_cpu_s"] > 0
    assert speed_ratios(rows) == {}
    assert format_table(rows).splitlines()[3].startswith("| solo_bump | train ppo | 1 | torch | cpu | no | 1 | 2 |")


@pytest.mark.parametrize("physics", ["torch", "mujoco"])
def test_nonfinite_action_in_a_match_is_a_crash_draw(physics):
    """A match ended by a NaN action is scored as a crash of that drone: a draw, the drone's misbehave
    penalty, no winner (it used to end with neither a winner nor a draw)."""
    env = volleybots.make_env("1v1", num_envs=2, seed=0, physics=physics)
    td = env.reset()
    act = torch.zeros(2, 2, 4)
    act[1, 1, 0] = float("nan")
    with pytest.warns(RuntimeWarning, match="non-finite action"):
        out = env.step(td.set(("agents", "action"), act))["next"]
    assert out["terminated"].squeeze(-1).tolist() == [False, True]
    stats = out["stats"]
    assert stats["draw"].squeeze(-1).tolist() == [0.0, 1.0] and stats["winner"].squeeze(-1).tolist() == [-1.0, -1.0]
    assert stats["r_drone_misbehave"][1].item() < 0 and stats["r_drone_misbehave"][0].item() == 0
