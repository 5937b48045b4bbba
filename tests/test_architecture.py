"""The floor plan of docs/architecture.md, held by the code: imports run down the floors, counting the
ones inside functions; no import cycle; no module over 400 lines."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "volleybots"
MAX_LINES = 400

# Floor of every module or package prefix (the longest prefix wins). Leaves import nothing of volleybots
# and may be imported from any floor; the top-level package ``volleybots`` is the façade above all.
FLOORS = {
    "volleybots.errors": 0, "volleybots.files": 0, "volleybots.paths": 0, "volleybots.version": 0, "volleybots.ratings": 0,
    "volleybots.population.solvers": 0, "volleybots.zoo": 0, "volleybots.population.payoffs": 0, "volleybots.tasks.layout": 0,
    "volleybots.keys": 0, "volleybots.overrides": 0,
    "volleybots.physics": 1,
    "volleybots.rules": 2,
    "volleybots.tasks": 3,
    "volleybots.scripted": 4,
    "volleybots.algos": 5,
    "volleybots.config": 6,
    "volleybots.runs": 7,
    "volleybots.policies": 8,
    "volleybots.play": 9,
    "volleybots.replay": 10,
    "volleybots.integrations": 10,
    "volleybots.train": 11,
    "volleybots.population": 12,
    "volleybots.eval": 13,
    "volleybots.bench": 14, "volleybots.report": 14, "volleybots.launchers": 14,
    "volleybots.cli": 15,
    "volleybots": 16,
}
LEAF = 0


def module_name(path: Path) -> str:
    rel = path.relative_to(PKG.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PKG.rglob("*.py"))}


def floor(name: str) -> int:
    best = max((k for k in FLOORS if name == k or name.startswith(k + ".")), key=len)
    return FLOORS[best]


def imports(name: str, path: Path, known: dict) -> list[tuple[str, int]]:
    """(imported module, line) for every import of a volleybots module in ``path``, at any depth."""
    is_pkg = path.name == "__init__.py"
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_pkg else name.split(".")[:-1]
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if not target.startswith("volleybots"):
                continue
            for alias in node.names:
                full = f"{target}.{alias.name}"
                out.append((full if full in known else target, node.lineno))
        elif isinstance(node, ast.Import):
            out += [(a.name, node.lineno) for a in node.names if a.name.startswith("volleybots")]
    return out


def edges() -> list[tuple[str, str, int]]:
    known = modules()
    found = []
    for name, path in known.items():
        for target, line in imports(name, path, known):
            while target not in known and "." in target:
                target = target.rsplit(".", 1)[0]
            if target != name:
                found.append((name, target, line))
    return found


def test_imports_run_down_the_floors():
    bad = []
    for src, dst, line in edges():
        f_src, f_dst = floor(src), floor(dst)
        if f_dst == LEAF or dst == src or src.startswith(dst + ".") and f_dst == f_src:
            continue
        if f_dst > f_src:
            bad.append(f"{src} (floor {f_src}) imports {dst} (floor {f_dst}) at line {line}")
    assert not bad, "\n".join(bad)


def test_no_import_cycle_counting_function_local_imports():
    graph: dict[str, set[str]] = {}
    for src, dst, _ in edges():
        graph.setdefault(src, set()).add(dst)
    # Tarjan's strongly connected components, iteratively small enough for ~100 modules
    index, low, stack, on, comps, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                comps.append(sorted(comp))

    for v in list(graph):
        if v not in index:
            visit(v)
    assert comps == []


def test_every_module_has_a_floor_and_none_is_over_the_line_limit():
    long = {n: len(p.read_text().splitlines()) for n, p in modules().items()}
    assert {n: k for n, k in long.items() if k > MAX_LINES} == {}
    for n in long:
        floor(n)  # a module under no known prefix raises (max of an empty sequence)


@pytest.mark.parametrize("layer", ["volleybots.play", "volleybots.policies", "volleybots.config", "volleybots.train", "volleybots.cli"])
def test_the_layers_import_on_their_own(layer):
    import importlib

    assert importlib.import_module(layer).__doc__


def test_the_leaves_load_scipy_where_they_use_it():
    """Every process imports the leaves (a training run's games keep records), and scipy's submodules
    take seconds to import (scipy.stats alone about 1.6 s); at module level a leaf imports only the
    ``scipy`` package, which loads a submodule on its first use."""
    eager = []
    for name, path in modules().items():
        if floor(name) != LEAF:
            continue
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("scipy"):
                eager.append((name, node.lineno, node.module))
            elif isinstance(node, ast.Import):
                eager += [(name, node.lineno, a.name) for a in node.names if a.name.startswith("scipy.")]
    assert eager == []


def test_every_config_error_is_imported_from_errors():
    """``ConfigError`` lives in the leaf ``volleybots.errors``; a module that takes it from ``config`` (which
    re-exports it for users) climbs a floor for nothing, and once reopened an import cycle (algos -> config)."""
    elsewhere = []
    for name, path in modules().items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and any(a.name == "ConfigError" for a in node.names):
                if node.level or node.module != "volleybots.errors":
                    elsewhere.append((name, node.lineno, node.module))
    assert elsewhere == []
