"""The config tree: every task has a config, every key a comment, every task x action space composes
into an env and a policy, and the schemas reject misspelt keys and wrong types by name."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest
import torch

from volleybots.algos import ALGOS, method_name
from volleybots.algos.base import class_attr
from volleybots.config import ConfigError, group_options, load, make_env
from volleybots.paths import conf_dir
from volleybots.physics import ACTION_SPACES
from volleybots.tasks import TASKS


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_every_registered_task_has_a_config():
    missing = sorted(set(TASKS) - set(group_options("task")))
    assert not missing, f"tasks without conf/task/<name>.yaml: {missing}"
    for name in TASKS:
        cfg = load([f"task={name}", f"algo={_algo_for(name)}"])
        assert cfg.task.name == name  # the file's name key is the registered one


def test_every_config_is_a_known_task_or_algo():
    assert set(group_options("task")) <= set(TASKS)
    assert set(group_options("algo")) <= set(ALGOS)


def test_every_yaml_key_has_a_comment():
    bad = []
    for path in sorted(conf_dir().rglob("*.yaml")):
        for i, line in enumerate(path.read_text().splitlines(), 1):
            code = line.split("#", 1)[0]
            is_key = re.match(r"^\s*[A-Za-z_][\w.]*:", code)
            is_item = re.match(r"^\s*- ", code)
            # Hydra's defaults-list scaffolding ("defaults:", "- _self_") is structure, not a setting
            structural = re.match(r"^\s*(defaults:\s*$|- _self_\s*$)", code)
            if (is_key or is_item) and not structural and "#" not in line:
                bad.append(f"{path.relative_to(conf_dir())}:{i}: {line.strip()}")
    assert not bad, "keys without a comment:\n" + "\n".join(bad)


def _algo_for(task: str) -> str:
    return "ppo" if class_attr(TASKS[task], "n_drones") == 1 else "mappo"


@pytest.mark.parametrize("action_space", ACTION_SPACES)
@pytest.mark.parametrize("task", sorted(TASKS))
def test_every_task_and_action_space_composes_into_a_working_policy(task, action_space):
    cfg = load([f"task={task}", f"algo={_algo_for(task)}", f"env.action_space={action_space}", "env.num_envs=2"])
    assert cfg.env.action_space == action_space and cfg.env.num_envs == 2
    env = make_env(cfg)
    algo = ALGOS[cfg.algo.name](cfg.algo, env, seed=0)
    td = algo.policy()(env.reset())
    action = td["agents", "action"]
    n = class_attr(TASKS[task], "n_drones")
    if action_space == "discrete":
        assert action.shape == (2, n) and action.dtype == torch.long
        assert int(action.min()) >= 0 and int(action.max()) < 16
    else:
        assert action.shape == (2, n, 4) and action.dtype == torch.float32
    value = algo.critic(td)["agents", "state_value"]
    assert value.shape == (2, n, 1) and torch.isfinite(value).all()
    out = env.step(td)["next"]
    assert out["agents", "observation"].shape == (2, n, env.obs_dim)


def test_task_options_reach_the_env():
    cfg = load(["task=solo_bump", "task.hit_reward=1.0", "task.episode_len=123", "task.reward_shaping=false", "env.num_envs=1"])
    env = make_env(cfg)
    assert env.hit_reward == 1.0 and env.episode_len == 123 and env.reward_shaping is False


def test_a_multi_drone_task_gets_a_multi_agent_algo_unless_one_is_named():
    assert load(["task=hover"]).algo.name == "ppo"  # the config's default
    for task, algo in (("bump_and_pass", "mappo"), ("3v3", "sp"), ("1v1", "sp")):  # cooperative: MAPPO; matches: self-play
        cfg = load([f"task={task}"])
        assert method_name(cfg) == algo and ALGOS[cfg.algo.name].multi_agent
    with pytest.raises(ConfigError, match="trains one drone"):
        load(["task=3v3", "algo=ppo"])  # named: still an error, not silently replaced


def test_integral_floats_are_accepted_for_counts():
    cfg = load(["total_frames=2e6", "env.num_envs=64.0"])
    assert cfg.total_frames == 2_000_000 and isinstance(cfg.total_frames, int)
    assert cfg.env.num_envs == 64


@pytest.mark.parametrize(
    "overrides, words",
    [
        (["env.num_envz=3"], ["env.num_envz", "num_envs"]),
        (["algo.clip_epsilom=0.2"], ["algo.clip_epsilom", "clip_epsilon"]),
        (["task=solo_bump", "task.hit_rewrd=1"], ["task.hit_rewrd", "hit_reward"]),
        (["env.num_envs=many"], ["env.num_envs", "many"]),
        (["algo.gamma=high"], ["algo.gamma", "high"]),
        (["task=hovr"], ["hovr", "hover", "solo_bump"]),
        (["algo=not_an_algo"], ["not_an_algo", "ppo", "mappo"]),
        (["env=gpu"], ["gpu", "cpu", "cuda"]),
        (["env.action_space=rpm"], ["rpm", "prt", "ctbr", "discrete"]),
        (["algo.activation=swish"], ["swish", "elu"]),
        (["task=3v3", "algo=ppo"], ["ppo", "3v3", "mappo"]),
        (["env.num_envs=0"], ["env.num_envs", ">= 1"]),
    ],
)
def test_bad_config_is_rejected_naming_the_key(overrides, words):
    with pytest.raises(ConfigError) as err:
        load(overrides)
    msg = str(err.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, (w, msg)


def test_misspelt_key_inside_a_yaml_file_is_rejected(tmp_path):
    from volleybots.config import validate

    base = load(["task=hover"])
    from volleybots.config import to_dict

    data = to_dict(base)
    data["task"]["targt"] = [0, 0, 1]
    with pytest.raises(ConfigError, match="task.targt"):
        validate(data)


@pytest.mark.slow  # not slow by nature, but measured too long for the quick tier
def test_configs_are_found_from_any_working_directory(tmp_path):
    code = "from volleybots.config import load; print(load(['task=solo_bump', 'algo=ppo']).task.hit_reward)"
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "2.0"


def test_configs_saved_with_the_old_compile_physics_task_key_still_load():
    """Runs written before the whole step compiled kept ``task.compile_physics``; they still evaluate."""
    from volleybots.config import to_dict, validate

    old = to_dict(load(["task=1v1"]))
    old["task"]["compile_physics"] = False
    assert validate(old).task.name == "1v1"
    old["task"]["compile_phisics"] = False
    with pytest.raises(ConfigError, match="compile_phisics"):
        validate(old)


def test_a_verbs_count_option_reads_an_integral_float_and_refuses_a_fraction():
    # ``budget=4e6`` as ``total_frames=2e6`` reads in a config; 2.5 frames is no count
    from volleybots.config.args import split_args
    from volleybots.config.verbs import ExploitabilityOptions
    from volleybots.errors import ConfigError

    names, opts, over = split_args(["random", "budget=4e6", "games=400", "task=1v1"], ExploitabilityOptions)
    assert names == ["random"] and over == ["task=1v1"]
    assert (opts.budget, opts.games, opts.seeds) == (4_000_000, 400, 2) and type(opts.budget) is int
    assert opts.given == {"budget", "games"}
    with pytest.raises(ConfigError, match=r"budget='2\.5' must be an integer"):
        split_args(["budget=2.5"], ExploitabilityOptions)
    with pytest.raises(ConfigError, match="out of range"):  # (budget=0 is exploitability's "no trained BR")
        split_args(["budget=-1e0"], ExploitabilityOptions)
