"""A user's own policy in every verb (volleybots.policies.foreign, issue 55): a Python callable (torch or
numpy), a ``module:function`` imported by name and a TorchScript file play a cross-play with exactly the
figures of the same policy loaded as a checkpoint; bad ones are refused in one line, before any game."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
import torch
from helpers import one_line_exit_2, snapshot
from typer.testing import CliRunner

from volleybots.cli import app
from volleybots.errors import ConfigError
from volleybots.eval.crossplay import crossplay, match_config, resolve_all
from volleybots.policies import callable_competitor, resolve_competitor

runner = CliRunner()
CHECKPOINT, OTHER = "zoo:1v1/bc", "zoo:1v1/bc_long"
@pytest.fixture
def user_module(monkeypatch):
    """examples/my_policy.py, importable by name as a user's own module would be (PYTHONPATH)."""
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[2] / "examples"))
    yield "my_policy"


def _play(specs, comps=None):
    comps = comps or resolve_all(specs)
    cfg = match_config(comps, ["task=1v1", "task.episode_len=120"])
    res = crossplay(cfg, comps, games=2, seed=11, batch=2, deterministic=True, specs=specs)
    return res.wdl.tolist(), res.outcomes, res.content


@pytest.mark.slow  # about 15 s on the shared 2 cores: three cross-plays of two games
def test_a_callable_and_a_module_function_play_the_checkpoints_games(user_module):
    expected = _play([f"me={CHECKPOINT}", OTHER])
    assert _play([f"me={user_module}:act", OTHER]) == expected
    assert _play([f"me={user_module}:numpy_player", OTHER]) == expected  # a Competitor built by the module, numpy in
    comp = resolve_competitor(f"{user_module}:act")
    assert comp.label == f"{user_module}:act" and comp.sources == [{"kind": "import", "spec": f"{user_module}:act"}]


def test_a_torchscript_file_plays_as_its_module_does(tmp_path):
    torch.manual_seed(0)
    net = torch.nn.Sequential(torch.nn.Linear(39, 4), torch.nn.Tanh())
    path = tmp_path / "net.pt"
    torch.jit.save(torch.jit.script(net), str(path))
    comp = resolve_competitor(f"ts=torchscript:{path}")
    assert comp.label == "ts" and comp.sources[0]["kind"] == "torchscript" and len(comp.sources[0]["sha256"]) == 64
    with torch.no_grad():
        as_callable = callable_competitor(lambda obs: net(obs), "ts")
    assert _play(None, [comp, resolve_competitor(OTHER)]) == _play(None, [as_callable, resolve_competitor(OTHER)])


@pytest.mark.parametrize(("activation", "net_arch", "space"), [(None, None, "prt"), ("ReLU", [32, 16], "prt"), (None, [8], "discrete")])
def test_an_sb3_zip_loads_without_unpickling_and_acts_as_predict(tmp_path, activation, net_arch, space):
    from stable_baselines3 import PPO
    from tensordict import TensorDict

    from volleybots import make_env
    from volleybots.integrations import VolleyMatchSB3VecEnv

    kwargs = {k: v for k, v in (("activation_fn", getattr(torch.nn, activation) if activation else None), ("net_arch", net_arch)) if v}
    model = PPO("MlpPolicy", VolleyMatchSB3VecEnv("1v1", 2, opponent="random", action_space=space), seed=0, device="cpu",
                policy_kwargs=kwargs)
    model.save(tmp_path / "model.zip")
    comp = resolve_competitor(f"mine=sb3:{tmp_path / 'model.zip'}")
    assert comp.label == "mine" and comp.sources[0]["kind"] == "sb3"
    env = make_env("1v1", 6, seed=3, action_space=space)
    team = TensorDict({"agents": env.select_team(env.reset(), 1)}, batch_size=[6])
    expected = model.predict(team.get(("agents", "observation"))[:, 0].numpy(), deterministic=True)[0]
    got = comp.team_policy(env)(team).get(("agents", "action"))[:, 0].numpy()
    assert got.shape == expected.shape and abs(got - expected).max() < 1e-5
    with pytest.raises(ConfigError, match="sees observations of size 39, the task gives 57"):
        comp.check_fits("3v3", space, 57)  # the saved network's input: a cross-play of 3v3 refuses it in one line


def test_bad_user_policies_are_one_line(tmp_path, user_module):
    for spec, words in ((f"{user_module}:nope", "has no attribute 'nope'"), ("no_such_module_x:act", "cannot import module"),
                        (f"{user_module}:__doc__", "is a str; expected a function")):
        with pytest.raises(ConfigError, match=words):
            resolve_competitor(spec)
    bad = callable_competitor(lambda obs: torch.zeros(obs.shape[0], 3), "short")
    with pytest.raises(ConfigError, match=r"returned actions of shape \((\d+), 3\) for \1 observations; expected shape \(\1, 4\)"):
        _play(None, [bad, resolve_competitor(OTHER)])
    (tmp_path / "bad_policies.py").write_text("import torch\n\ndef short(obs):\n    return torch.zeros(obs.shape[0], 3)\n")
    sys.path.insert(0, str(tmp_path))
    try:  # from the command line the same: one line, exit 2, no results folder
        res = runner.invoke(app, ["eval", "crossplay", "bad_policies:short", "random", "task=1v1", "games=2", "--out", str(tmp_path / "o")])
    finally:
        sys.path.remove(str(tmp_path))
    one_line_exit_2(res, "'bad_policies:short' returned actions of shape", "expected shape")
    assert not (tmp_path / "o").exists()
    text = tmp_path / "notes.pt"
    text.write_text("not a model")
    out = tmp_path / "out"
    before = snapshot(tmp_path)
    res = runner.invoke(app, ["eval", "crossplay", f"torchscript:{text}", "scripted", "task=1v1", "games=2", "--out", str(out)])
    one_line_exit_2(res, "is not a TorchScript file", str(text))
    assert snapshot(tmp_path) == before  # nothing written
    ckpt = resolve_competitor(CHECKPOINT).sources[0]["path"]
    with pytest.raises(ConfigError, match="is not a TorchScript file"):
        resolve_competitor(f"torchscript:{ckpt}")  # a checkpoint is no TorchScript file either
    with pytest.raises(ConfigError, match="is not a saved Stable-Baselines3 model"):
        resolve_competitor(f"sb3:{ckpt}")


@pytest.mark.slow
def test_the_cli_verbs_take_a_module_function(tmp_path, user_module):
    out = tmp_path / "cp"
    res = runner.invoke(app, ["eval", "crossplay", f"me={user_module}:act", OTHER, "task=1v1", "games=2", "batch=2",
                              "deterministic=true", "--out", str(out), "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads((out / "crossplay.json").read_text())
    assert data["labels"] == ["me", OTHER] and data["competitors"][0]["members"] == [{"kind": "import", "spec": f"{user_module}:act"}]
    res = runner.invoke(app, ["eval", "elo", f"me={user_module}:act", OTHER, "task=1v1", "games=2", "batch=2", "rounds=10",
                              "--out", str(tmp_path / "elo"), "--json"])
    assert res.exit_code == 0, res.output
    report = json.loads((tmp_path / "elo" / "ratings.json").read_text())
    assert "me" in json.dumps(report["labels"] if "labels" in report else report)


def test_reuse_never_copies_a_user_functions_games(user_module):
    """A cross-play's reuse= copies a pair only where its players are pinned by their records: a
    checkpoint's or an exported file's sha256, a built-in's name; a user's function is played again."""
    from volleybots.eval.crossplay import provenance
    from volleybots.eval.reuse import verified

    for spec, pinned in ((f"{user_module}:act", False), (f"{user_module}:numpy_player", False), (CHECKPOINT, True), ("scripted", True),
                         (f"{user_module}:act+scripted", False)):
        assert verified(provenance(resolve_competitor(spec), spec)) is pinned, spec
