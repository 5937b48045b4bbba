"""Frictions of issue 55: ``volleybots list --json`` (the listing as data, equal to the lines it prints);
``bench task=`` (the singular every other verb takes, refused when given twice); a bad config key or
task reported before torch is imported (so in about a second, not ten)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from helpers import CLI_ENV, one_line_exit_2
from typer.testing import CliRunner

from volleybots.cli import app

runner = CliRunner()


@pytest.mark.slow  # lists twice: every algorithm's check against every task, 4-8 s on the shared cores
def test_list_json_holds_what_the_lines_show():
    from volleybots.algos import ALGOS
    from volleybots.tasks import TASKS

    res = runner.invoke(app, ["list", "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert [t["name"] for t in data["tasks"]] == list(TASKS) and [a["name"] for a in data["algorithms"]] == list(ALGOS)
    assert {t["name"]: t["drones"] for t in data["tasks"]}["3v3"] == 6
    algos = {a["name"]: a["tasks"] for a in data["algorithms"]}
    populations = {p["name"]: p["tasks"] for p in data["populations"]}  # their own registry (population=NAME)
    assert populations["sp"] == ["1v1", "3v3", "6v6"] and "hover" in algos["ppo"] and "1v1" not in algos["ppo"]
    zoo = {e["name"]: e for e in data["zoo"]}
    assert zoo["zoo:1v1/bc"]["kind"] == "policy" and zoo["zoo:1v1/fsp_long"]["kind"] == "mixture"
    assert zoo["zoo:1v1/fsp_long"]["members"] == 6 and "scripted" in data["players"]
    text = runner.invoke(app, ["list"]).stdout
    for name in [*TASKS, *ALGOS, *populations, *data["backends"], *data["action_spaces"], *data["players"], *zoo]:
        assert f"  {name} " in text, name


def test_bench_takes_task_as_every_verb_does():
    res = runner.invoke(app, ["bench", "task=hover", "backend=torch", "num_envs=[2]", "repeats=1", "steps=2", "--json"])
    assert res.exit_code == 0, res.output
    rows = json.loads(res.stdout)
    assert [(r["task"], r["backend"], r["num_envs"]) for r in rows] == [("hover", "torch", 2)]
    one_line_exit_2(runner.invoke(app, ["bench", "task=hover", "tasks=[3v3]"]), "'tasks' is given twice", "task=", "tasks=")
    one_line_exit_2(runner.invoke(app, ["bench", "taks=hover"]), "unknown bench option 'taks'", "task")


@pytest.mark.parametrize("argv", [["train", "task=hover", "algo.nonsense=1"], ["train", "task=hovr"],
                                  ["train", "-m", "task=hover", "seed=0,1", "algo.nonsens=1"], ["eval", "scripted", "task=hovr"],
                                  ["eval", "crossplay", "scripted", "random", "task=1vv1"], ["replay", "scripted", "task=hovr"]])
def test_config_errors_come_before_torch_loads(argv):
    """The error is the same one line, exit 2; and torch was never imported to give it (what made it take 8-11 s)."""
    code = ("import sys\nfrom volleybots.cli import app\ntry:\n    app(%r)\nexcept SystemExit as e:\n"
            "    print('exit', e.code, 'torch loaded' if 'torch' in sys.modules else 'torch not loaded')" % (argv,))
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=CLI_ENV, timeout=120)
    assert res.stdout.strip().splitlines()[-1] == "exit 2 torch not loaded", res.stdout + res.stderr
    err = res.stderr.strip()
    assert len(err.splitlines()) == 1 and err.startswith("error: unknown ") and ("allowed" in err), err


@pytest.mark.parametrize("argv, message", [
    (["train", "task=hover", "env.num_envs=-1"], "error: bad value for 'env.num_envs': -1 (must be >= 1)"),
    (["train", "task=hover", "evaluation.episodes=0"], "error: bad value for 'evaluation.episodes': 0 (must be >= 1)"),
    (["train", "-m", "task=hover", "seed=0,1", "total_frames=0"], "error: bad value for 'total_frames': 0 (must be >= 1)"),
    (["eval", "scripted", "task=hover", "episodes=0"], "error: bad value for 'episodes': 0 (must be >= 1)"),
])
def test_range_errors_of_the_fixed_keys_come_before_torch_loads(argv, message):
    """A number out of its key's range (issue 55: 8 s to report, torch first): the same line as validate's,
    from the words alone."""
    code = ("import sys\nfrom volleybots.cli import app\ntry:\n    app(%r)\nexcept SystemExit as e:\n"
            "    print('exit', e.code, 'torch loaded' if 'torch' in sys.modules else 'torch not loaded')" % (argv,))
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=CLI_ENV, timeout=120)
    assert res.stdout.strip().splitlines()[-1] == "exit 2 torch not loaded", res.stdout + res.stderr
    assert res.stderr.strip().startswith(message) and len(res.stderr.strip().splitlines()) == 1, res.stderr


def test_a_value_of_another_type_or_a_task_key_is_left_to_validate():
    from volleybots.config import ConfigError, load
    from volleybots.config.compose import check_fixed_values

    check_fixed_values(["env.num_envs=abc", "seed=0,1", "task.episode_len=0", "algo.actor_lr=-1", "total_frames=2e6", "junk"])
    with pytest.raises(ConfigError, match=r"^bad value for 'env.substeps': 100 \(must be in \[1, 64\]\)$"):
        check_fixed_values(["env.substeps=100"])
    with pytest.raises(ConfigError, match="'task.episode_len'"):  # validate still reports what this leaves
        load(["task=hover", "task.episode_len=0"])


def test_list_answers_before_torch_loads():
    """``list`` reads the registries' part from the shipped catalogue (and the zoo's cards), so torch is never imported."""
    code = ("import sys\nfrom volleybots.cli import app\ntry:\n    app(['list', '--json'])\nexcept SystemExit as e:\n"
            "    print('exit', e.code, 'torch loaded' if 'torch' in sys.modules else 'torch not loaded', file=sys.stderr)")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=CLI_ENV, timeout=120)
    assert res.stderr.strip().splitlines()[-1] == "exit 0 torch not loaded", res.stderr
    data = json.loads(res.stdout)
    assert {t["name"]: t["drones"] for t in data["tasks"]}["3v3"] == 6 and any(e["name"] == "zoo:3v3/headline" for e in data["zoo"])


@pytest.mark.slow  # every algorithm's check against every task, 4-8 s on the shared cores
def test_the_shipped_catalogue_is_what_the_registries_say():
    """volleybots/catalogue.json must be rewritten when a task, algorithm, backend or player is added:
    python -c "from volleybots.cli.tools import write_catalogue; write_catalogue()"."""
    from volleybots.cli.tools import CATALOGUE, registries

    assert json.loads(CATALOGUE.read_text()) == json.loads(json.dumps(registries()))
