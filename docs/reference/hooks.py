"""mkdocs hook: the reference pages written from the code and the config tree at build time.

A page holds a marker such as ``<!-- generated: cli -->``; the build replaces it with the reference
drawn from the source of truth (the Typer app, the task and algorithm registries, the YAML files of
``conf/`` with their one-line comments), so the references cannot drift from what the code does.

The Python API reference is one page per package of ``volleybots/`` (``reference/api/<package>.md``)
plus one for the top-level modules (``reference/api/volleybots.md``), generated from the package tree
(``on_files``) and put under "Python API" in the sidebar (``on_config``): a new package or module gets
its page and its entry without editing anything.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

from mkdocs.structure.files import File

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "volleybots"
API_DIR = "reference/api"  # where the per-package pages of the Python API go (src_uri, relative to docs/)
API_INDEX = "reference/api.md"  # the page listing them, the nav entry they hang under

# document the checkout being built, whichever copy of the package is installed
sys.path.insert(0, str(ROOT))

MARKER = re.compile(r"<!-- generated: (\w+) -->")
# a setting of conf/*.yaml: indentation, key, value, its one-line comment
SETTING = re.compile(r"^(?P<indent>\s*)(?P<key>[A-Za-z_][\w]*):\s*(?P<value>[^#]*?)\s*(?:#\s*(?P<comment>.*))?$")


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|")


def _header(path: Path) -> str:
    """The comment lines that open a config file: what the file is."""
    lines = []
    for line in path.read_text().splitlines():
        if not line.startswith("#"):
            break
        lines.append(line.lstrip("# ").rstrip())
    return " ".join(lines)


def settings(path: Path) -> dict[str, tuple[str, str]]:
    """dotted key -> (value as written, comment) for every setting of a conf/ file, those of the files
    its defaults list includes first (a key of the file itself overrides them)."""
    out: dict[str, tuple[str, str]] = {}
    own: dict[str, tuple[str, str]] = {}
    stack: list[tuple[int, str]] = []
    in_defaults = False
    for line in path.read_text().splitlines():
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        include = re.match(r"^\s*- ([\w/]+)(@_here_)?\s*(#.*)?$", line)  # another file of this group, merged here
        choice = re.match(r"^\s*- (\w+): (\w+)\s*(?:#\s*(.*))?$", line)  # a group's default option (task: hover)
        if in_defaults and include:
            if include.group(1) != "_self_":
                out.update(settings(path.parent / f"{include.group(1)}.yaml"))
            continue
        if in_defaults and choice:
            own[choice.group(1)] = (choice.group(2), choice.group(3) or "")
            continue
        m = SETTING.match(line)
        if not m:
            continue
        in_defaults = m["key"] == "defaults" and not m["indent"]
        if in_defaults:
            continue
        depth = len(m["indent"])
        stack = [(d, k) for d, k in stack if d < depth]
        key = ".".join([k for _, k in stack] + [m["key"]])
        if m["value"]:
            own[key] = (m["value"], m["comment"] or "")
        else:
            stack.append((depth, m["key"]))
    out.update(own)
    return out


def settings_table(values: dict[str, tuple[str, str]], prefix: str = "") -> str:
    rows = ["| key | default | meaning |", "|---|---|---|"]
    rows += [f"| `{prefix}{k}` | `{_cell(v)}` | {_cell(c)} |" for k, (v, c) in values.items()]
    return "\n".join(rows)


def _doc(cls) -> str:
    """The first paragraph of a class's docstring, as a Markdown paragraph (nothing when it has none)."""
    text = " ".join((cls.__doc__ or "").strip().split("\n\n")[0].split())
    return f"{text}\n\n" if text else ""


# ------------------------------------------------------------------------------------- generators
def cli_reference() -> str:
    import typer
    from typer.cli import get_docs_for_click

    from volleybots.cli import app

    command = typer.main.get_command(app)
    return get_docs_for_click(obj=command, ctx=typer.Context(command, info_name="volleybots"), name="volleybots", indent=1)


def config_reference() -> str:
    from volleybots.paths import conf_dir

    conf = conf_dir()
    parts = [f"## `conf/config.yaml`\n\n{_header(conf / 'config.yaml')}\n\n{settings_table(settings(conf / 'config.yaml'))}"]
    for path in sorted((conf / "env").glob("*.yaml")):
        parts.append(f"## `env={path.stem}` (`conf/env/{path.name}`)\n\n{_header(path)}\n\n{settings_table(settings(path), 'env.')}")
    for path in sorted((conf / "env" / "drone").glob("*.yaml")):
        parts.append(f"## `env.drone={path.stem}` (`conf/env/drone/{path.name}`)\n\n{_header(path)}\n\n{settings_table(settings(path))}")
    return "\n\n".join(parts)


def _action(spec) -> str:
    """One drone's action as the env's spec says it: a vector with its bounds, or a choice among n."""
    n = getattr(spec, "n", None)
    if n is not None:
        return f"1 of {n}"
    return f"{spec.shape[-1]} in [{spec.low.min().item():g}, {spec.high.max().item():g}]"


def task_sizes() -> dict[str, dict[str, tuple[int, int, str]]]:
    """task -> action space -> (drones, observation size per drone, action per drone), read from the
    specs of a one-world env of each (about 20 ms each on a CPU)."""
    import volleybots
    from volleybots.physics import ACTION_SPACES
    from volleybots.tasks import TASKS

    out: dict[str, dict[str, tuple[int, int, str]]] = {}
    for name in TASKS:
        out[name] = {}
        for space in ACTION_SPACES:
            env = volleybots.make_env(name, num_envs=1, action_space=space)
            obs = env.observation_spec["agents", "observation"].shape
            out[name][space] = (obs[-2], obs[-1], _action(env.full_action_spec["agents", "action"]))
    return out


def sizes_table(sizes: dict[str, dict[str, tuple[int, int, str]]]) -> str:
    """The observation and action sizes per drone of every task, one column pair per action space."""
    spaces = list(next(iter(sizes.values())))
    head = "| task | drones | " + " | ".join(f"obs `{s}` | action `{s}`" for s in spaces) + " |"
    rows = [head, "|" + "---|" * (2 + 2 * len(spaces))]
    for name, per in sizes.items():
        cells = " | ".join(f"{per[s][1]} | {per[s][2]}" for s in spaces)
        rows.append(f"| [`{name}`](#{name}) | {per[spaces[0]][0]} | {cells} |")
    return "\n".join(rows)


def tasks_reference() -> str:
    from volleybots.algos.base import class_attr
    from volleybots.paths import conf_dir
    from volleybots.tasks import TASKS

    sizes = task_sizes()
    parts = [
        "## Observation and action sizes\n\nPer drone, as the env's specs give them: "
        "`(\"agents\", \"observation\")` has shape `[num_envs, drones, obs]`, `(\"agents\", \"action\")` "
        "`[num_envs, drones, 4]` in the continuous spaces and `[num_envs, drones]` (an index) in `discrete`. "
        "CTBR observations leave out the 4 rotor throttles.\n\n" + sizes_table(sizes)
    ]
    for name, cls in TASKS.items():
        path = conf_dir() / "task" / f"{name}.yaml"
        n = class_attr(cls, "n_drones")
        parts.append(
            f"## `{name}`\n\n{_doc(cls)}"
            f"- drones: {n}\n- metric: `{cls.metric}`\n"
            + "".join(f"- `{s}`: observation {o}, action {a}\n" for s, (_, o, a) in sizes[name].items())
            + f"- class: `{cls.__module__}.{cls.__qualname__}`\n\n"
            f"`task={name}` (`conf/task/{name}.yaml`): {_header(path)}\n\n{settings_table(settings(path), 'task.')}"
        )
    return "\n\n".join(parts)


def algorithms_reference() -> str:
    from volleybots.algos import ALGOS
    from volleybots.paths import conf_dir

    parts = []
    for name, cls in ALGOS.items():
        path = conf_dir() / "algo" / f"{name}.yaml"
        kind = "one or more drones (multi-agent)" if cls.multi_agent else "one drone"
        parts.append(
            f"## `{name}`\n\n{_doc(cls)}"
            f"- trains: {kind}\n- action spaces: {', '.join(f'`{a}`' for a in cls.action_spaces)}\n"
            + (f"- class: `{cls.__module__}.{cls.__qualname__}`\n\n" if isinstance(cls, type) else
               f"- a population preset (`volleybots.algos.population.PRESETS`): the population loop trains "
               f"`{cls.learner_cls.__name__}` learners\n\n") +
            f"`algo={name}` (`conf/algo/{name}.yaml`): {_header(path)}\n\n{settings_table(settings(path), 'algo.')}"
        )
    return "\n\n".join(parts)


# ------------------------------------------------------------------------------------- Python API
def _summary(path: Path) -> str:
    """The first sentence of a module's docstring (read with ast: nothing is imported)."""
    doc = ast.get_docstring(ast.parse(path.read_text())) or ""
    first = " ".join(doc.split("\n\n")[0].split())
    return first.split(". ")[0].rstrip(".") + "." if first else ""


def _modules(package: Path) -> list[str]:
    """The dotted names of a package's public modules and subpackages, in file order, recursively."""
    names = []
    for path in sorted(package.iterdir()):
        if path.name.startswith("_"):
            continue
        if path.suffix == ".py":
            names.append(path.stem)
        elif (path / "__init__.py").exists():
            names.append(path.name)
            names += [f"{path.name}.{sub}" for sub in _modules(path)]
    return names


def api_pages() -> dict[str, tuple[str, Path, list[str]]]:
    """page name -> (title, the file whose docstring sums it up, the objects it documents): one page per
    package of volleybots/, one ("volleybots") for the package itself and its top-level modules."""
    top = [p.stem for p in sorted(PACKAGE.glob("*.py")) if not p.name.startswith("_")]
    pages = {"volleybots": ("volleybots (top-level modules)", PACKAGE / "__init__.py",
                            ["volleybots"] + [f"volleybots.{m}" for m in top])}
    for pkg in sorted(p for p in PACKAGE.iterdir() if (p / "__init__.py").exists()):
        objs = [f"volleybots.{pkg.name}"] + [f"volleybots.{pkg.name}.{m}" for m in _modules(pkg)]
        pages[pkg.name] = (f"volleybots.{pkg.name}", pkg / "__init__.py", objs)
    return pages


def api_page(name: str) -> str:
    title, init, objs = api_pages()[name]
    blocks = "\n\n".join(f"::: {obj}" for obj in objs)
    return f"# `{title}`\n\n{_summary(init)} Generated from the docstrings when the site is built.\n\n{blocks}\n"


def api_index() -> str:
    rows = ["| page | what it holds |", "|---|---|"]
    rows += [f"| [`{title}`](api/{name}.md) | {_cell(_summary(init))} |" for name, (title, init, _) in api_pages().items()]
    return "\n".join(rows)


def on_config(config):
    """Hang one sidebar entry per API page under the nav entry of the index page."""
    def expand(items):
        for i, item in enumerate(items):
            if isinstance(item, dict):
                (label, value), = item.items()
                if value == API_INDEX:
                    pages = [{"Overview": API_INDEX}] + [{title: f"{API_DIR}/{n}.md"} for n, (title, _, _) in api_pages().items()]
                    items[i] = {label: pages}
                elif isinstance(value, list):
                    expand(value)
    expand(config.nav or [])
    return config


def on_files(files, config):
    for name in api_pages():
        files.append(File.generated(config, f"{API_DIR}/{name}.md", content=api_page(name)))
    return files


GENERATORS = {"api": api_index, "cli": cli_reference, "config": config_reference, "tasks": tasks_reference, "algorithms": algorithms_reference}


def on_page_markdown(markdown: str, page, config, files) -> str:  # noqa: ARG001 - mkdocs' hook signature
    def generate(m: re.Match) -> str:
        if m.group(1) not in GENERATORS:
            raise ValueError(f"{page.file.src_path}: unknown generated section {m.group(1)!r}; allowed: {', '.join(GENERATORS)}")
        return GENERATORS[m.group(1)]()

    return MARKER.sub(generate, markdown)
