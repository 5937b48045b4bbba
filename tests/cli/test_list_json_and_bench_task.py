"""``volleybots list --json`` and ``bench task=`` (issue 55): the listing as data, equal to the lines it
prints; bench takes the singular ``task=`` every other verb takes, and refuses it given twice."""

from __future__ import annotations

import json

from helpers import one_line_exit_2
from typer.testing import CliRunner

from volleybots.cli import app

runner = CliRunner()


def test_list_json_holds_what_the_lines_show():
    from volleybots.algos import ALGOS
    from volleybots.tasks import TASKS

    res = runner.invoke(app, ["list", "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert [t["name"] for t in data["tasks"]] == list(TASKS) and [a["name"] for a in data["algorithms"]] == list(ALGOS)
    assert {t["name"]: t["drones"] for t in data["tasks"]}["3v3"] == 6
    algos = {a["name"]: a["tasks"] for a in data["algorithms"]}
    assert algos["sp"] == ["1v1", "3v3", "6v6"] and "hover" in algos["ppo"] and "1v1" not in algos["ppo"]
    zoo = {e["name"]: e for e in data["zoo"]}
    assert zoo["zoo:1v1/bc"]["kind"] == "policy" and zoo["zoo:1v1/fsp_long"]["kind"] == "mixture"
    assert zoo["zoo:1v1/fsp_long"]["members"] == 6 and "scripted" in data["players"]
    text = runner.invoke(app, ["list"]).stdout
    for name in [*TASKS, *ALGOS, *data["backends"], *data["action_spaces"], *data["players"], *zoo]:
        assert f"  {name} " in text, name


def test_bench_takes_task_as_every_verb_does():
    res = runner.invoke(app, ["bench", "task=hover", "backend=torch", "num_envs=[2]", "repeats=1", "steps=2", "--json"])
    assert res.exit_code == 0, res.output
    rows = json.loads(res.stdout)
    assert [(r["task"], r["backend"], r["num_envs"]) for r in rows] == [("hover", "torch", 2)]
    one_line_exit_2(runner.invoke(app, ["bench", "task=hover", "tasks=[3v3]"]), "'tasks' is given twice", "task=", "tasks=")
    one_line_exit_2(runner.invoke(app, ["bench", "taks=hover"]), "unknown bench option 'taks'", "task")
