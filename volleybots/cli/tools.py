"""``volleybots list``, ``bench`` and ``report``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import typer

from volleybots.cli.app import _PASS_THROUGH, _user_errors, app, options_help
from volleybots.config.verbs import BenchOptions
from volleybots.errors import ConfigError


@app.command("list")
def list_cmd(
    as_json: bool = typer.Option(False, "--json", help="Print the lists as one JSON object (tasks, algorithms, populations, backends, "
                                 "action spaces, players, zoo) instead of lines."),
) -> None:
    """List tasks, algorithms, population methods, physics backends, action spaces, built-in players and the zoo, one line each."""
    data = _catalogue()
    if as_json:
        typer.echo(json.dumps(data, indent=1))
        return
    typer.echo("tasks (task=NAME):")
    for t in data["tasks"]:
        n = t["drones"]
        cfg = "" if t["config_file"] else "  [no conf/task file]"
        typer.echo(f"  {t['name']:<20} {n:>2} drone{'s' if n > 1 else ' '}  metric: {t['metric']}{cfg}")
    typer.echo("algorithms (algo=NAME):")
    for a in data["algorithms"]:
        typer.echo(f"  {a['name']:<20} action spaces: {', '.join(a['action_spaces'])}; tasks: {', '.join(a['tasks'])}")
    typer.echo("population methods (population=NAME, or algo=NAME; their learner is algo=, mappo by default):")
    for p in data["populations"]:
        typer.echo(f"  {p['name']:<20} solver: {p['solver']}; learners: {', '.join(p['learners'])}; tasks: {', '.join(p['tasks'])}")
    for key, title in (("backends", "physics backends (env.physics=NAME):"), ("action_spaces", "action spaces (env.action_space=NAME):"),
                       ("players", "built-in players (eval NAME, competitors, opponent=):")):
        typer.echo(title)
        for name, text in data[key].items():
            typer.echo(f"  {name:<20} {text}")
    typer.echo("zoo (trained policies shipped with the package: zoo:TASK/METHOD wherever a competitor goes):")
    for e in data["zoo"]:
        figures = ", ".join(f"{k} {v}" for k, v in e["figures"].items())
        kind = {"policy": "", "mixture": f"a mixture of {e['members']} policies, ",
                "team": f"a hierarchical team ({', '.join(e['drills'])}), "}[e["kind"]]
        typer.echo(f"  {e['name']:<20} {kind}{e['frames']} frames, seed {e['seed']}; {figures}")
    if not data["zoo"]:
        typer.echo("  (none in this install)")


CATALOGUE = Path(__file__).resolve().parents[1] / "catalogue.json"  # the registries' part of list, written by write_catalogue()


def _catalogue() -> dict:
    """What ``list`` shows, as plain data (the text and the JSON are two views of it). The registries'
    part (tasks, algorithms, populations, backends, action spaces, players) is read from the shipped
    ``catalogue.json`` so that ``list`` answers before torch loads; a test holds it equal to what the
    registries say (``registries()``). The task files and the zoo are read live (neither needs torch)."""
    from volleybots.config.schema import group_options
    from volleybots.zoo import PREFIX, entries

    data = json.loads(CATALOGUE.read_text()) if CATALOGUE.is_file() else registries()
    files = set(group_options("task"))
    for t in data["tasks"]:
        t["config_file"] = t["name"] in files
    zoo = []
    for name, e in entries().items():
        kind = "team" if e.is_team else "mixture" if e.is_mixture else "policy"
        zoo.append({"name": PREFIX + name, "kind": kind, "task": e.card.get("task"), "members": len(e.members),
                    "drills": list(e.card.get("hierarchical") or ()), "frames": e.card.get("frames", "?"), "seed": e.card.get("seed", "?"),
                    "figures": dict(e.card.get("figures") or {})})
    return {**data, "zoo": zoo}


def registries() -> dict:
    """The registries' part of ``list``, from the classes themselves (imports torch)."""
    from volleybots.algos import ALGOS, LEARNERS, PRESETS
    from volleybots.algos.base import class_attr
    from volleybots.physics import ACTION_SPACE_INFO, BACKEND_INFO
    from volleybots.policies import PLAYERS
    from volleybots.tasks import TASKS

    tasks = [{"name": name, "drones": int(class_attr(cls, "n_drones")), "metric": cls.metric} for name, cls in TASKS.items()]
    algos = [{"name": name, "action_spaces": list(cls.action_spaces), "tasks": [t for t in TASKS if _fits(name, t)]}
             for name, cls in ALGOS.items()]
    populations = [{"name": name, "solver": p.solver, "learners": list(LEARNERS), "tasks": [t for t in TASKS if _fits(name, t)]}
                   for name, p in PRESETS.items()]
    return {"tasks": tasks, "algorithms": algos, "populations": populations, "backends": dict(BACKEND_INFO),
            "action_spaces": dict(ACTION_SPACE_INFO), "players": {name: p.description for name, p in PLAYERS.items()}}


def write_catalogue() -> Path:
    """Write ``catalogue.json`` from the registries: after adding a task, algorithm, backend or player
    (``python -c "from volleybots.cli.tools import write_catalogue; write_catalogue()"``)."""
    CATALOGUE.write_text(json.dumps(registries(), indent=1) + "\n")
    return CATALOGUE


def _fits(algo: str, task: str) -> bool:
    """Whether ``algo`` (or a population method with its default learner) accepts ``task`` in its own first
    action space (its ``check`` decides)."""
    from omegaconf import OmegaConf

    from volleybots.algos import ALGOS, PRESETS
    from volleybots.config import EnvConfig
    from volleybots.tasks import TASKS

    preset = PRESETS.get(algo)
    cls = preset.learner_cls if preset is not None else ALGOS[algo]
    try:
        cfg = OmegaConf.structured(cls.config_cls)
        env = EnvConfig(action_space=cls.action_spaces[0])
        if preset is not None:  # a population preset fills its start's learner_init / seed_members first, as validate does
            pop = OmegaConf.structured(preset.config_cls)
            preset.resolve(pop, task=task)
            preset.check(pop, cfg, TASKS[task], env)
        else:
            cls.check(cfg, TASKS[task], env)
    except ConfigError:
        return False
    return True


# the singular names every other verb takes (task=3v3), for bench's lists (tasks=[3v3]; one value is a list of one)
BENCH_ALIASES = {"task": "tasks", "backend": "backends", "device": "devices"}


@app.command(context_settings=_PASS_THROUGH, epilog=options_help(BenchOptions, "key=value options (task=, backend=, device=: one of each)"))
@_user_errors
def bench(
    options: Optional[List[str]] = typer.Argument(
        None, help="The key=value options below: task=solo_bump or tasks=[solo_bump,3v3] num_envs=[256,4096] train=true ..."
    ),
    compile: bool = typer.Option(False, "--compile", help="Compile the torch env step (static shapes); same as compile=true."),
    as_json: bool = typer.Option(False, "--json", help="Print the measured rows as JSON instead of a table."),
) -> None:
    """Measure env-steps/s (and with train=true training frames/s) per task, backend, env count and device; print the table."""
    import dataclasses

    try:
        from volleybots.bench import format_table, run_bench
    except ImportError:
        raise ConfigError("the benchmark module volleybots.bench is not available in this install") from None
    from volleybots.config import check_bench_options
    from volleybots.config.args import parse_options

    allowed = [f.name for f in dataclasses.fields(BenchOptions)]
    kwargs = {"compile": True} if compile else {}
    kwargs.update(parse_options(options or [], allowed, "bench", aliases=BENCH_ALIASES))
    kwargs = check_bench_options(kwargs)

    try:
        rows = run_bench(BenchOptions(**kwargs), progress=_RowProgress())
    except ValueError as e:
        raise ConfigError(str(e).splitlines()[0]) from None
    typer.echo(json.dumps(rows, indent=1) if as_json else format_table(rows))


class _RowProgress:
    """bench's line per measured row on stderr, with the rows done of how many and the ETA (train=true
    on several env counts takes many minutes)."""

    def __init__(self):
        from volleybots.train.progress import Count

        self.count = Count("rows")

    def begin(self, total: int) -> None:
        self.count.begin(total)

    def __call__(self, row: dict) -> None:
        typer.echo(f"  measured {row.get('task')} {row.get('kind', 'env')} {row.get('backend')} x{row.get('num_envs')}: "
                   f"{row.get('env_steps_per_s', 0):,.0f}/s  [{self.count.tick()}]", err=True)


# ------------------------------------------------------------------------------------------ report
@app.command()
@_user_errors
def report(
    dirs: List[Path] = typer.Argument(
        ..., help="Run directories, or folders that hold them (a sweep's multirun/<date>/<time>_<task>_<algo>)."
    ),
    out: Optional[Path] = typer.Option(
        None, "--out", help="Also write report.md, report.json and curves_<task>.png to this folder (never overwritten)."
    ),
    as_json: bool = typer.Option(False, "--json", help="Print the report as JSON instead of Markdown."),
    stale_after: float = typer.Option(
        1800.0,
        "--stale-after",
        help="Seconds without a write after which a run with no summary.json counts as failed, not running.",
    ),
) -> None:
    """Aggregate runs across seeds: per task x algorithm the final metric's mean, IQM and 95% bootstrap intervals, learning curves."""
    from volleybots.report import build_report, check_out, format_markdown, write_report

    if out is not None:
        check_out(out)
    result = build_report(dirs, stale_after=stale_after)
    if out is not None:
        write_report(result, out)
    typer.echo(json.dumps(result, indent=2) if as_json else format_markdown(result))
