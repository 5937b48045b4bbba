"""The documentation site: `mkdocs build --strict` passes (no broken link, no bad docstring, no missing
page), and the reference pages written at build time name every verb, task and algorithm there is."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
import tomllib

pytestmark = [pytest.mark.slow, pytest.mark.subprocess]

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    out = tmp_path_factory.mktemp("site")
    env = {**os.environ, "OMP_NUM_THREADS": "1", "NO_MKDOCS_2_WARNING": "1"}
    res = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-5000:]
    assert "WARNING" not in res.stderr, res.stderr[-5000:]
    return out


def _text(site: Path, page: str) -> str:
    html = (site / page / "index.html").read_text()
    return re.sub(r"<[^>]+>", "", html)


def test_cli_reference_has_every_verb_and_option(site):
    import typer

    from volleybots.cli import app

    text = _text(site, "reference/cli")
    group = typer.main.get_command(app)
    for name, command in group.commands.items():
        assert f"volleybots {name}" in text, name
        for param in command.params:
            for opt in param.opts if param.param_type_name == "option" else []:
                assert opt in text, (name, opt)


def test_task_and_algorithm_references_have_every_entry(site):
    from volleybots.algos import ALGOS
    from volleybots.tasks import TASKS

    tasks, algos = _text(site, "reference/tasks"), _text(site, "reference/algorithms")
    for name, cls in TASKS.items():
        assert f"task={name}" in tasks and f"metric: {cls.metric}" in tasks, name
    for name in ALGOS:
        assert f"algo={name}" in algos, name
    assert "algo.actor_lr" in algos and "algo.tau" in algos  # a key of ppo.yaml, one of the shared off-policy file
    config = _text(site, "reference/config")
    assert "total_frames" in config and "evaluation.every" in config and "env.num_envs" in config


def test_api_reference_is_generated_from_the_docstrings(site):
    text = _text(site, "reference/api")
    assert "make_env" in text and "Build the TorchRL env of" in text  # volleybots.make_env's docstring
    assert "build_report" in text and "Interquartile mean" in text  # volleybots.report
    assert "check_launcher" in text


def test_getting_started_walks_to_a_crossplay_heatmap(site):
    text = _text(site, "getting-started")
    for step in ('pip install -e ".[test]"', "volleybots train task=hover", "volleybots eval runs/hover_s0",
                 "volleybots report runs/sweep", "volleybots eval crossplay scripted random task=1v1 games=200"):
        assert step.replace('"', "&quot;") in text or step in text, step


def test_license_matches_pyproject():
    license_id = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["license"]["text"]
    assert license_id == "MIT"
    assert (ROOT / "LICENSE").read_text().startswith("MIT License\n")
