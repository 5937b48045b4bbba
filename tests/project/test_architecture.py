"""The floor plan of docs/architecture.md, held by the code: imports run down the floors, counting the
ones inside functions and the package ``__init__`` each import runs; no import cycle, of modules or of
folders; every module on a known floor; no module over 400 lines. The checker's functions take the
package root, so the tests at the end plant breakages in a copy and see each one caught."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[2] / "volleybots"
MAX_LINES = 400

# Floor of every module or package prefix (the longest prefix wins). Leaves import nothing of volleybots
# and may be imported from any floor; the top-level package ``volleybots`` is the façade above all.
FLOORS = {
    "volleybots.errors": 0, "volleybots.files": 0, "volleybots.paths": 0, "volleybots.version": 0, "volleybots.ratings": 0,
    "volleybots.zoo": 0, "volleybots.tasks.layout": 0,
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


def module_name(path: Path, pkg: Path = PKG) -> str:
    rel = path.relative_to(pkg.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules(pkg: Path = PKG) -> dict[str, Path]:
    return {module_name(p, pkg): p for p in sorted(pkg.rglob("*.py"))}


def floor(name: str) -> int:
    """The floor of module ``name``: its longest prefix in FLOORS. The top-level package alone is the
    façade; a module under no other prefix (a new loose module) has no known floor and raises."""
    known = [k for k in FLOORS if name == k or name.startswith(k + ".")]
    best = max(known, key=len, default="volleybots")
    if best == "volleybots" and name != "volleybots":
        raise KeyError(f"{name} has no known floor: give it one in FLOORS (tests/project/test_architecture.py)")
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


def edges(pkg: Path = PKG) -> list[tuple[str, str, int]]:
    """(importer, imported, line) for every import, and for every package ``__init__`` an import runs:
    ``import volleybots.population.loop`` runs ``volleybots/population/__init__.py`` first, unless the
    importer is inside that package already (then it ran before the importer). The top-level package's
    ``__init__`` is the façade every import runs; it is left out."""
    known = modules(pkg)
    found = []
    for name, path in known.items():
        for target, line in imports(name, path, known):
            while target not in known and "." in target:
                target = target.rsplit(".", 1)[0]
            parts = target.split(".")
            packages = [".".join(parts[:i]) for i in range(2, len(parts))]
            for dst in [*packages, target]:
                if dst != name and dst in known and not name.startswith(dst + "."):
                    found.append((name, dst, line))
    return found


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one node (Tarjan's algorithm)."""
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
    return comps


def module_cycles(pkg: Path = PKG) -> list[list[str]]:
    graph: dict[str, set[str]] = {}
    for src, dst, _ in edges(pkg):
        graph.setdefault(src, set()).add(dst)
    return cycles(graph)


def folder(name: str) -> str:
    return ".".join(name.split(".")[:2])


def folder_cycles(pkg: Path = PKG) -> list[list[str]]:
    """Cycles between the package's folders (``volleybots.algos`` -> ``volleybots.population`` -> ...)."""
    graph: dict[str, set[str]] = {}
    for src, dst, _ in edges(pkg):
        if folder(src) != folder(dst) and "volleybots" not in (src, dst):
            graph.setdefault(folder(src), set()).add(folder(dst))
    return cycles(graph)


def arrows_up(pkg: Path = PKG) -> list[str]:
    bad = []
    for src, dst, line in edges(pkg):
        f_src, f_dst = floor(src), floor(dst)
        if f_dst == LEAF or dst == src or src.startswith(dst + ".") and f_dst == f_src:
            continue
        if f_dst > f_src:
            bad.append(f"{src} (floor {f_src}) imports {dst} (floor {f_dst}) at line {line}")
    return bad


def test_imports_run_down_the_floors():
    bad = arrows_up()
    assert not bad, "\n".join(bad)


def test_no_import_cycle_counting_function_local_imports_and_package_inits():
    assert module_cycles() == []


def test_no_cycle_between_folders():
    assert folder_cycles() == []


def test_every_module_has_a_floor_and_none_is_over_the_line_limit():
    long = {n: len(p.read_text().splitlines()) for n, p in modules().items()}
    assert {n: k for n, k in long.items() if k > MAX_LINES} == {}
    for n in long:
        floor(n)  # a module under no known prefix raises


def test_the_test_tree_has_a_folder_for_every_package():
    """The tests mirror the floors: each package of volleybots (``volleybots/<name>/``) has its tests in
    ``tests/<name>/``, so a floor without tests of its own shows as a missing folder, not as a file lost
    among another floor's."""
    tests = PKG.parent / "tests"
    missing = sorted(d.name for d in PKG.iterdir() if (d / "__init__.py").is_file() and not any((tests / d.name).glob("test_*.py")))
    assert missing == [], f"no tests/<name>/test_*.py for the packages {missing}"


def test_the_game_theory_package_imports_no_torch():
    """Records, payoff tables, meta-solvers and ratings (``volleybots.ratings``) load without torch: a
    notebook over a crossplay.json or payoffs.json needs numpy and scipy only."""
    import subprocess
    import sys

    code = ("import importlib, pkgutil, sys, volleybots.ratings as r\n"
            "names = [m.name for m in pkgutil.iter_modules(r.__path__)]\n"
            "[importlib.import_module('volleybots.ratings.' + n) for n in names]\n"
            "assert {'solvers', 'methods', 'payoffs', 'record', 'elo', 'bradley_terry'} <= set(names), names\n"
            "assert 'torch' not in sys.modules, sorted(m for m in sys.modules if m.startswith('torch'))[:5]\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=PKG.parent)
    assert res.returncode == 0, res.stderr


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


# ------------------------------------------------------------------------ the checker, tested
@pytest.fixture
def planted(tmp_path):
    """A copy of the package's sources to plant breakages in."""
    import shutil

    dst = tmp_path / "volleybots"
    shutil.copytree(PKG, dst, ignore=lambda d, names: [n for n in names if not (n.endswith(".py") or (Path(d) / n).is_dir())])
    return dst


def test_the_copy_is_clean_as_the_package_is(planted):
    assert arrows_up(planted) == [] and module_cycles(planted) == [] and folder_cycles(planted) == []


def test_a_new_loose_module_has_no_known_floor(planted):
    (planted / "helpers.py").write_text("X = 1\n")
    with pytest.raises(KeyError, match="volleybots.helpers has no known floor"):
        [floor(n) for n in modules(planted)]


def test_a_cycle_through_a_package_init_is_caught(planted):
    """population/__init__ importing its loop, and train importing a population leaf inside a function:
    no module imports a module that imports it back, but ``import volleybots.population.convergence``
    runs population/__init__, which imports the loop, which imports train."""
    init = planted / "population" / "__init__.py"
    init.write_text(init.read_text() + "\nfrom volleybots.population.loop import PopulationLoop  # noqa\n")
    trainer = planted / "train" / "trainer.py"
    trainer.write_text(trainer.read_text() + "\n\ndef _planted():\n    from volleybots.population.convergence import Convergence\n")
    assert any({"volleybots.population", "volleybots.train.trainer"} <= set(c) for c in module_cycles(planted))
    assert any("volleybots.train.trainer (floor 11) imports volleybots.population (floor 12)" in a for a in arrows_up(planted))


def test_a_function_local_import_back_up_is_an_arrow_up_and_a_folder_cycle(planted):
    games = planted / "play" / "games.py"
    games.write_text(games.read_text() + "\n\ndef _planted():\n    from volleybots.eval.ranking import elo_table\n")
    assert any(a.startswith("volleybots.play.games (floor 9) imports volleybots.eval") for a in arrows_up(planted))
    assert any({"volleybots.play", "volleybots.eval"} <= set(c) for c in folder_cycles(planted))


def test_a_long_module_is_counted(planted):
    (planted / "play" / "long.py").write_text("x = 1\n" * (MAX_LINES + 1))
    assert max(len(p.read_text().splitlines()) for p in modules(planted).values()) > MAX_LINES
