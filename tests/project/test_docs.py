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

ROOT = Path(__file__).resolve().parents[2]


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
    text = _text(site, "reference/api/volleybots")
    assert "make_env" in text and "Build the TorchRL env of" in text  # volleybots.make_env's docstring
    assert "build_report" in text and "Interquartile mean" in text  # volleybots.report
    assert "check_launcher" in text
    assert "wilson_interval" in _text(site, "reference/api/ratings") and "Referee" in _text(site, "reference/api/rules")


def test_entry_points_render_their_parameters(site):
    """The public entry points carry Google-style Args/Returns, which mkdocstrings renders as tables."""
    pages = {"volleybots": ["make_env"], "scripted": ["scripted.policies.make_scripted_policy"], "tasks": ["tasks.multi.TeamPolicies"],
             "ratings": ["ratings.elo.elo", "ratings.elo.elo_history", "ratings.intervals.wilson_interval"],
             "eval": ["eval.compare.compare", "eval.crossplay.crossplay", "eval.ranking.ratings", "eval.exploitability.run_exploitability"]}
    for page, names in pages.items():
        html = (site / "reference" / "api" / page / "index.html").read_text()
        for name in names:
            block = re.search(rf'id="volleybots\.{re.escape(name)}"(.*?)(?=<h[23] id=|$)', html, re.DOTALL)
            assert block, (page, name)
            assert "Parameters:" in block.group(1) and ("Returns:" in block.group(1) or name.endswith("TeamPolicies")), (page, name)
    make_env = _text(site, "reference/api/volleybots")
    assert "num_envs" in make_env and "worlds stepped together in one batch" in make_env


def test_every_package_has_an_api_page(site):
    """One page per package of volleybots/ (found from the tree, as a new package would be), listed on the
    index page and in the sidebar, documenting each of its modules."""
    packages = sorted(p.parent for p in (ROOT / "volleybots").glob("*/__init__.py"))
    assert {p.name for p in packages} >= {"physics", "rules", "tasks", "scripted", "algos", "population", "ratings", "eval"}
    index = (site / "reference" / "api" / "index.html").read_text()
    top = (site / "reference" / "api" / "volleybots" / "index.html").read_text()
    for pkg in packages:
        html = (site / "reference" / "api" / pkg.name / "index.html").read_text()
        assert f'href="{pkg.name}/"' in index and f'href="../{pkg.name}/"' in top, pkg.name  # index table, sidebar
        for module in pkg.glob("[!_]*.py"):
            assert f'id="volleybots.{pkg.name}.{module.stem}"' in html, (pkg.name, module.stem)
    for module in (ROOT / "volleybots").glob("[!_]*.py"):
        assert f'id="volleybots.{module.stem}"' in top, module.stem


def test_task_reference_has_the_sizes_of_every_action_space(site):
    """The sizes on the page are those of the envs (computed at build time), for every task and space."""
    import volleybots
    from volleybots.physics import ACTION_SPACES
    from volleybots.tasks import TASKS

    text = _text(site, "reference/tasks")
    assert "Observation and action sizes" in text
    for name in TASKS:
        for space in ACTION_SPACES:
            env = volleybots.make_env(name, num_envs=1, action_space=space)
            obs = env.observation_spec["agents", "observation"].shape[-1]
            action = "1 of 16" if space == "discrete" else "4 in [-1, 1]"
            assert f"{space}: observation {obs}, action {action}" in text, (name, space)
    assert "3v3 6 57 4 in [-1, 1] 53 4 in [-1, 1] 57 1 of 16" in " ".join(text.split())  # the summary table's row


def test_getting_started_walks_to_a_crossplay_heatmap(site):
    text = _text(site, "getting-started")
    for step in ('pip install -e ".[test]"', "volleybots train task=hover", "volleybots eval runs/hover_s0",
                 "volleybots report runs/sweep", "volleybots eval crossplay scripted random task=1v1 games=200"):
        assert step.replace('"', "&quot;") in text or step in text, step


def test_markdown_is_lint_clean():
    """pymarkdown with the rules of .pymarkdown.yml (blank lines around lists and headings, no bare URL,
    heading levels one step at a time, fenced code with a language, ...) over every page and the README."""
    from pymarkdown.api import PyMarkdownApi

    failures = []
    for path in (ROOT / "docs", ROOT / "README.md"):
        api = PyMarkdownApi().enable_strict_configuration().configuration_file_path(str(ROOT / ".pymarkdown.yml"))
        result = api.scan_path(str(path), recurse_if_directory=True)
        assert not result.critical_errors and not result.pragma_errors, (result.critical_errors, result.pragma_errors)
        failures += [f"{f.scan_file}:{f.line_number}: {f.rule_id} {f.rule_description}" for f in result.scan_failures]
    assert not failures, "\n".join(failures)


def test_no_list_renders_as_a_paragraph(site):
    """Python-Markdown starts a list only after a blank line and nests one only at 4 spaces; a list that
    misses either renders as "- a - b" inside a paragraph."""
    runs = []
    for page in site.rglob("*.html"):
        for para in re.findall(r"<p>(.*?)</p>", page.read_text(), re.DOTALL):
            if re.search(r"\n\s*[-*+] \S", para):
                runs.append(f"{page.relative_to(site)}: {para[:80]!r}")
    assert not runs, "\n".join(runs)


def test_docs_cite_nothing_outside_the_repository():
    pages = [*ROOT.joinpath("docs").rglob("*.md"), ROOT / "README.md"]
    outside = [f"{p.relative_to(ROOT)}:{i}" for p in pages for i, line in enumerate(p.read_text().splitlines(), 1)
               if re.search(r"\.\./shared|shared/(spec|paper|gpu|hooks)", line)]
    assert not outside, outside


def test_license_matches_pyproject():
    license_id = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["license"]["text"]
    assert license_id == "MIT"
    assert (ROOT / "LICENSE").read_text().startswith("MIT License\n")
