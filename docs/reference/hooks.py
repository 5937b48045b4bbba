"""mkdocs hook: the reference pages written from the code and the config tree at build time.

A page holds a marker such as ``<!-- generated: cli -->``; the build replaces it with the reference
drawn from the source of truth (the Typer app, the task and algorithm registries, the YAML files of
``conf/`` with their one-line comments), so the references cannot drift from what the code does.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

# document the checkout being built, whichever copy of the package is installed
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

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


def tasks_reference() -> str:
    from volleybots.algos.base import class_attr
    from volleybots.paths import conf_dir
    from volleybots.tasks import TASKS

    parts = []
    for name, cls in TASKS.items():
        path = conf_dir() / "task" / f"{name}.yaml"
        n = class_attr(cls, "n_drones")
        parts.append(
            f"## `{name}`\n\n{_doc(cls)}"
            f"- drones: {n}\n- metric: `{cls.metric}`\n- class: `{cls.__module__}.{cls.__qualname__}`\n\n"
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
            f"- class: `{cls.__module__}.{cls.__qualname__}`\n\n"
            f"`algo={name}` (`conf/algo/{name}.yaml`): {_header(path)}\n\n{settings_table(settings(path), 'algo.')}"
        )
    return "\n\n".join(parts)


GENERATORS = {"cli": cli_reference, "config": config_reference, "tasks": tasks_reference, "algorithms": algorithms_reference}


def on_page_markdown(markdown: str, page, config, files) -> str:  # noqa: ARG001 - mkdocs' hook signature
    def generate(m: re.Match) -> str:
        if m.group(1) not in GENERATORS:
            raise ValueError(f"{page.file.src_path}: unknown generated section {m.group(1)!r}; allowed: {', '.join(GENERATORS)}")
        return GENERATORS[m.group(1)]()

    return MARKER.sub(generate, markdown)
