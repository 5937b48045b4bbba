"""``volleybots list``, ``bench`` and ``report``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import typer

from volleybots.cli.app import _PASS_THROUGH, _user_errors, app
from volleybots.errors import ConfigError


@app.command("list")
def list_cmd() -> None:
    """List tasks, algorithms, physics backends and action spaces, one line each."""
    from volleybots.algos import ALGOS, LEARNERS, PRESETS
    from volleybots.algos.base import class_attr
    from volleybots.config import group_options
    from volleybots.physics import ACTION_SPACE_INFO, BACKEND_INFO
    from volleybots.tasks import TASKS

    typer.echo("tasks (task=NAME):")
    for name, cls in TASKS.items():
        n = class_attr(cls, "n_drones")
        cfg = "" if name in group_options("task") else "  [no conf/task file]"
        typer.echo(f"  {name:<20} {n:>2} drone{'s' if n > 1 else ' '}  metric: {cls.metric}{cfg}")
    typer.echo("algorithms (algo=NAME):")
    for name, cls in ALGOS.items():
        fits = [t for t in TASKS if _fits(name, t)]
        typer.echo(f"  {name:<20} action spaces: {', '.join(cls.action_spaces)}; tasks: {', '.join(fits)}")
    typer.echo("population methods (population=NAME, or algo=NAME; their learner is algo=, mappo by default):")
    for name, preset in PRESETS.items():
        fits = [t for t in TASKS if _fits(name, t)]
        typer.echo(f"  {name:<20} solver: {preset.solver}; learners: {', '.join(LEARNERS)}; tasks: {', '.join(fits)}")
    typer.echo("physics backends (env.physics=NAME):")
    for name, text in BACKEND_INFO.items():
        typer.echo(f"  {name:<20} {text}")
    typer.echo("action spaces (env.action_space=NAME):")
    for name, text in ACTION_SPACE_INFO.items():
        typer.echo(f"  {name:<20} {text}")
    from volleybots.policies import PLAYERS
    from volleybots.zoo import PREFIX, entries

    typer.echo("built-in players (eval NAME, competitors, opponent=):")
    for name, player in PLAYERS.items():
        typer.echo(f"  {name:<20} {player.description}")
    typer.echo("zoo (trained policies shipped with the package: zoo:TASK/METHOD wherever a competitor goes):")
    for name, e in entries().items() or ():
        figures = ", ".join(f"{k} {v}" for k, v in (e.card.get("figures") or {}).items())
        mixture = f"a mixture of {len(e.members)} policies, " if e.is_mixture else ""
        mixture = f"a hierarchical team ({', '.join(e.card['hierarchical'])}), " if e.is_team else mixture
        typer.echo(f"  {PREFIX + name:<20} {mixture}{e.card.get('frames', '?')} frames, seed {e.card.get('seed', '?')}; {figures}")
    if not entries():
        typer.echo("  (none in this install)")


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


@app.command(context_settings=_PASS_THROUGH)
@_user_errors
def bench(
    options: Optional[List[str]] = typer.Argument(
        None,
        help="key=value arguments of volleybots.bench.run_bench: tasks=[solo_bump,3v3] num_envs=[256,4096] backends=[torch,mujoco] "
        "devices=[cpu] threads=1 repeats=3 steps=100 train=true (adds PPO / MAPPO training frames/s).",
    ),
    compile: bool = typer.Option(False, "--compile", help="Compile the torch env step (static shapes); same as compile=true."),
    as_json: bool = typer.Option(False, "--json", help="Print the measured rows as JSON instead of a table."),
) -> None:
    """Measure env-steps/s (and with train=true training frames/s) per task, backend, env count and device; print the table."""
    import inspect

    try:
        from volleybots.bench import format_table, run_bench
    except ImportError:
        raise ConfigError("the benchmark module volleybots.bench is not available in this install") from None
    from volleybots.config import check_bench_options
    from volleybots.config.args import parse_options

    allowed = [p for p in inspect.signature(run_bench).parameters if p != "progress"]
    kwargs = {"compile": True} if compile else {}
    kwargs.update(parse_options(options or [], allowed, "bench"))
    kwargs = check_bench_options(kwargs)

    def measured(row: dict) -> None:
        typer.echo(
            f"  measured {row.get('task')} {row.get('kind', 'env')} {row.get('backend')} x{row.get('num_envs')}: "
            f"{row.get('env_steps_per_s', 0):,.0f}/s",
            err=True,
        )

    try:
        rows = run_bench(**kwargs, progress=measured)
    except ValueError as e:
        raise ConfigError(str(e).splitlines()[0]) from None
    typer.echo(json.dumps(rows, indent=1) if as_json else format_table(rows))


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
