"""The env's TensorDict keys are spelled once, in ``volleybots/keys.py``: no module of the package
writes ``"agents"`` or ``"next"`` (or a ``("stats", name)`` tuple) inline again."""

from __future__ import annotations

import ast
from pathlib import Path

from volleybots.keys import ACTION, AGENTS, NEXT, OBS, REWARD, STATS, leaf, nxt, stat

PKG = Path(__file__).resolve().parents[2] / "volleybots"
# the group names a key is built from; any string constant spelling them is a key spelled inline
GROUPS = {AGENTS, NEXT}


def docstrings(tree: ast.AST) -> set[int]:
    """ids of the docstring constants of ``tree`` (they describe the layout; they may spell it)."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                out.add(id(first.value))
    return out


def inline_keys(source: str) -> list[tuple[int, str]]:
    """(line, spelling) of every key written inline in ``source``, outside docstrings and comments."""
    tree = ast.parse(source)
    skip = docstrings(tree)
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and node.value in GROUPS and id(node) not in skip:
            found.append((node.lineno, repr(node.value)))
        elif isinstance(node, ast.Tuple) and node.elts and isinstance(node.elts[0], ast.Constant) and node.elts[0].value == STATS:
            found.append((node.lineno, ast.unparse(node)))
    return sorted(found)


def test_no_module_spells_an_env_key_inline():
    bad = [
        f"{path.relative_to(PKG.parent)}:{line}: {text} (use volleybots.keys)"
        for path in sorted(PKG.rglob("*.py"))
        if path != PKG / "keys.py"
        for line, text in inline_keys(path.read_text())
    ]
    assert not bad, "\n".join(bad)


def test_the_check_catches_each_spelling():
    src = '''"""A docstring may say ("agents", "observation")."""
a = td.get(("agents", "action"))  # a comment may too: ("agents", "x")
b = td["next", "agents", "reward"]
c = td.get("agents")
d = td.get(("stats", k))
e = ev["stats"]["win"]
'''
    assert [line for line, _ in inline_keys(src)] == [2, 3, 3, 4, 5]


def test_the_helpers_spell_the_layout():
    assert OBS == ("agents", "observation") and ACTION == ("agents", "action")
    assert nxt(REWARD) == ("next", "agents", "reward") and nxt("done") == ("next", "done")
    assert stat("win") == ("stats", "win") and leaf(OBS) == "observation" and leaf("done") == "done"
