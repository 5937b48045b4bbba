"""No function of the package, the benchmarks or the examples takes more than 12 parameters: a verb, a
loop or a configuration function with more is positional plumbing, and its options belong in one
dataclass (``volleybots.config.verbs``: a verb's options, ``BenchOptions``; ``eval exploitability``'s
``Plan``). The physics kernels too: ``torch_backend.touch`` takes the ball's ``Approach`` (a NamedTuple,
which ``torch.compile`` traces as its tensors) rather than seven loose tensors. ``KERNELS`` may exempt a
kernel by name, and a test fails when an exemption is no longer needed. The checker takes the
folders, so the last tests plant an offender in a copy and see it caught."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
FOLDERS = ("volleybots", "benchmarks", "examples")
MAX_PARAMETERS = 12
# physics kernels allowed flat tensor arguments beyond the bound (none now: touch takes an Approach)
KERNELS: set[str] = set()


def parameters(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> list[str]:
    """The parameters of ``fn`` a caller passes: every name, ``*args`` and ``**kw`` counting one each;
    a method's ``self`` or ``cls`` is not passed."""
    a = fn.args
    names = [x.arg for x in (*a.posonlyargs, *a.args, *a.kwonlyargs)]
    names += [x.arg for x in (a.vararg, a.kwarg) if x is not None]
    return names[1:] if names[:1] in (["self"], ["cls"]) else names


def offenders(root: Path = ROOT, folders=FOLDERS, exempt=KERNELS) -> list[tuple[str, int]]:
    """(module.qualified_name, parameter count) of every function over ``MAX_PARAMETERS`` not ``exempt``."""
    found = []
    for folder in folders:
        for path in sorted((root / folder).rglob("*.py")):
            module = ".".join(path.relative_to(root).with_suffix("").parts)
            found += _walk(ast.parse(path.read_text()), module, exempt)
    return found


def _walk(node: ast.AST, prefix: str, exempt) -> list[tuple[str, int]]:
    out = []
    for child in ast.iter_child_nodes(node):
        if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            name = f"{prefix}.{child.name}"
            if not isinstance(child, ast.ClassDef):
                n = len(parameters(child))
                if n > MAX_PARAMETERS and name not in exempt:
                    out.append((name, n))
            out += _walk(child, name, exempt)
        else:
            out += _walk(child, prefix, exempt)
    return out


def test_no_function_takes_more_than_12_parameters():
    assert offenders() == [], f"over {MAX_PARAMETERS} parameters (give them one options dataclass): {offenders()}"


def test_the_exempt_kernels_exist_and_are_the_only_long_ones():
    # an exemption outlives its kernel silently unless it is checked: each names a function still over the bound
    assert sorted(offenders(exempt=set())) == sorted((k, n) for k, n in offenders(exempt=set()) if k in KERNELS)
    assert all(any(k == name for name, _ in offenders(exempt=set())) for k in KERNELS)


def test_a_planted_offender_is_caught_with_its_count_methods_and_nesting_included(tmp_path):
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "m.py").write_text(
        "def ok(a, b, c, d, e, f, g, h, i, j, k, l): pass\n"
        "def long(a, b, c, d, e, f, g, h, i, j, k, l, m): pass\n"
        "class C:\n"
        "    def method(self, a, b, c, d, e, f, g, h, i, j, k, l): pass\n"
        "    def many(self, a, *rest, b, c, d, e, f, g, h, i, j, k, **kw): pass\n"
        "def outer():\n"
        "    def inner(a, b, c, d, e, f, g, h, i, j, k, l, m, n): pass\n"
    )
    assert offenders(tmp_path, ("pkg",)) == [("pkg.m.long", 13), ("pkg.m.C.many", 13), ("pkg.m.outer.inner", 14)]
    assert offenders(tmp_path, ("pkg",), exempt={"pkg.m.long", "pkg.m.C.many", "pkg.m.outer.inner"}) == []
