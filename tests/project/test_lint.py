"""The lint gate: `ruff check` over the package, the tests and the benchmarks with the rules set in pyproject.toml
(skipped where ruff is not installed; the `test` extra installs it, so CI runs it)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _ruff(*args: str, stdin: str | None = None) -> subprocess.CompletedProcess:
    pytest.importorskip("ruff")
    cmd = [sys.executable, "-m", "ruff", *args]
    return subprocess.run(cmd, cwd=ROOT, input=stdin, capture_output=True, text=True, timeout=120)


def _codes(source: str) -> set[str]:
    """The rule codes ruff reports for ``source`` as if it were a test file (so the project's config applies)."""
    res = _ruff("check", "--no-cache", "--output-format", "concise", "--stdin-filename", "tests/_probe.py", "-", stdin=source)
    assert res.returncode in (0, 1), res.stderr
    return {word for line in res.stdout.splitlines() for word in line.split() if word[:1].isupper() and word[1:].isdigit()}


def test_ruff_passes_on_package_tests_and_benchmarks():
    res = _ruff("check", "--no-cache", "volleybots", "tests", "benchmarks")
    assert res.returncode == 0, res.stdout[-4000:] + res.stderr[-2000:]


def test_ruff_reads_the_project_rules():
    # the gate is only as strong as the configuration it reads: lines up to 140 characters pass, 141 do not, and
    # pyflakes, import order and bugbear findings are all reported
    line = "x = '{}'\n"
    assert _codes(line.format("a" * (140 - len(line.format("")) + 1))) == set()
    assert _codes(line.format("a" * (141 - len(line.format("")) + 1))) == {"E501"}
    assert _codes("import os\n") == {"F401"}
    assert _codes("import sys\nimport os\n\nprint(os, sys)\n") == {"I001"}
    assert _codes("def f(x=[]):\n    return x\n") == {"B006"}
