"""The ``volleybots`` command line: train, eval, replay, list, bench.

Bad input (an unknown name, key, verb or option, a wrong type or an out-of-range value, an algorithm
that cannot act in the chosen action space, a missing or mismatched checkpoint, an output file that
exists or cannot be written, a run directory in use) prints one line naming the bad value and the
allowed ones, exits with code 2 and writes nothing. docs/usage.md lists the guarantees.
"""

from __future__ import annotations

import functools
import itertools
import json
import sys
import time
from pathlib import Path
from typing import List, Optional

import typer
from typer.core import TyperGroup

try:  # typer >= 0.2x carries its own copy of click
    from typer._click import exceptions as click_errors
except ImportError:
    from click import exceptions as click_errors

import volleybots
from volleybots.errors import ConfigError


class _Verbs(TyperGroup):
    """Click's own usage errors (a missing argument, an unknown verb or option, an option without its
    value) as one line and exit code 2, like every other bad input, not a boxed usage message."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        try:
            rv = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        except click_errors.ClickException as e:
            if not standalone_mode:
                raise
            if type(e).__name__ == "NoArgsIsHelpError":  # bare `volleybots`: the help, as Click does
                typer.echo(e.format_message())
            else:
                typer.echo(f"error: {_usage_message(self, e)}", err=True)
            sys.exit(2 if isinstance(e, click_errors.UsageError) else e.exit_code)
        except typer.Abort:
            if not standalone_mode:
                raise
            typer.echo("error: aborted", err=True)
            sys.exit(1)
        if standalone_mode:
            sys.exit(rv if isinstance(rv, int) else 0)
        return rv


def _usage_message(group, e) -> str:
    msg = " ".join(e.format_message().split()).rstrip(".")
    ctx = getattr(e, "ctx", None)
    where = ctx.command_path if ctx is not None else "volleybots"
    if msg.startswith("No such command"):
        msg += f"; allowed: {', '.join(group.commands)}"
    return f"{msg[:1].lower()}{msg[1:]} (see: {where} --help)"


app = typer.Typer(
    cls=_Verbs,
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Multi-drone volleyball: train, evaluate and replay policies on batched drone-physics tasks.",
)
_PASS_THROUGH = {"allow_extra_args": True, "ignore_unknown_options": True}


def _fail(msg: str) -> None:
    typer.echo(f"error: {msg}", err=True)
    raise typer.Exit(2)


def _user_errors(fn):
    """Turn ``ConfigError`` (bad user input) into one line and exit code 2."""

    @functools.wraps(fn)
    def wrapper(*args, **kw):
        try:
            return fn(*args, **kw)
        except ConfigError as e:
            _fail(str(e))

    return wrapper


def _version(value: bool) -> None:
    if value:
        typer.echo(f"volleybots {volleybots.__version__}")
        raise typer.Exit()


@app.callback()
def main(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True, help="Print the version and exit."),
) -> None:
    """Multi-drone volleyball: train, evaluate and replay policies on batched drone-physics tasks."""


# ------------------------------------------------------------------------------------------ train
def _jobs(overrides: list[str], multirun: bool) -> list[list[str]]:
    """The override lists of the jobs a command line asks for (one without -m; the sweep's product with)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import HydraException

    try:
        parsed = OverridesParser.create().parse_overrides(overrides)
    except HydraException as e:
        raise ConfigError(f"bad override: {' '.join(str(e).split())}") from None
    sweeps = [o for o in parsed if o.is_sweep_override()]
    if sweeps and not multirun:
        raise ConfigError(f"override {sweeps[0].input_line!r} sweeps several values; add -m to run one job per value")
    choices = [
        [f"{o.get_key_element()}={v}" for v in o.sweep_string_iterator()] if o.is_sweep_override() else [o.input_line]
        for o in parsed
    ]
    return [list(c) for c in itertools.product(*choices)] or [[]]


_DIR_KEYS = {False: "hydra.run.dir", True: "hydra.sweep.dir"}
_NONEMPTY = ("resume", "hydra.run.dir", "hydra.sweep.dir", "hydra.sweep.subdir", "hydra.job.name")


def _refuse_flags(args: list[str], allowed: str) -> None:
    """An option Click passed through (the verbs take Hydra overrides after them) is a misspelt one."""
    flags = [a for a in args if a.startswith("-")]
    if flags:
        raise ConfigError(f"unknown option {flags[0]!r}; allowed: {allowed}")


def _refuse_empty(overrides: list[str]) -> None:
    """``resume=`` or ``hydra.run.dir=`` with nothing after the '=' would silently mean "none" / "here"."""
    for o in overrides:
        key, eq, value = o.partition("=")
        if eq and key.lstrip("+") in _NONEMPTY and not value.strip():
            raise ConfigError(f"{key}= is empty; give it a value ({key}=DIR) or leave it out")


def _claim_dir(job: list[str], overrides: list[str], multirun: bool) -> str:
    """Resolve the run directory (the sweep's with -m) that Hydra would use and lock it for this
    process; the default, time-stamped one gets a suffix when taken (two starts in one second)."""
    from volleybots.config import compose
    from volleybots.runs import claim_run_dir

    key = _DIR_KEYS[multirun]
    cfg = compose(job, hydra_node=True)
    path = str(cfg.hydra.sweep.dir if multirun else cfg.hydra.run.dir)
    if not path.strip():
        raise ConfigError(f"{key} is empty; give it a directory")
    explicit = any(o.partition("=")[0].lstrip("+") == key for o in overrides)
    return str(claim_run_dir(path, unique=not explicit, sweep=multirun))


def _hydra_quote(value: str) -> str:
    return "'" + value.replace("\\", "\\\\").replace("'", "\\'") + "'"


def _run_hydra(overrides: list[str], multirun: bool, extra: list[str]) -> None:
    import hydra

    from volleybots.paths import conf_dir

    @hydra.main(config_path=str(conf_dir()), config_name="config", version_base="1.3")
    def _job(cfg) -> None:
        from hydra.core.hydra_config import HydraConfig

        from volleybots.config import algo_action_space, validate
        from volleybots.runner import start as train_run

        try:
            cfg = algo_action_space(cfg, HydraConfig.get().overrides.task)
            summary = train_run(validate(cfg), HydraConfig.get().runtime.output_dir)
        except ConfigError as e:
            # SystemExit passes through Hydra's error report (which would exit 1 with a banner)
            typer.echo(f"error: {e}", err=True)
            sys.exit(2)
        _echo_summary(summary, HydraConfig.get().runtime.output_dir)

    argv = sys.argv
    sys.argv = ["volleybots-train", *overrides, *(["--multirun"] if multirun else []), *extra]
    try:
        _job()
    finally:
        sys.argv = argv


def _echo_summary(summary: dict, run_dir) -> None:
    if "population" in summary:
        pop = summary["population"]
        mix = ", ".join(f"{m} {w:.2f}" for m, w in zip(pop["members"], pop["mixture"]))
        typer.echo(
            f"run {run_dir}: {summary['frames']} frames in {summary['wall_time_s']:.0f} s ({summary['frames_per_s']:,.0f} frames/s); "
            f"{summary['iterations']} iteration(s), population {len(pop['members'])}, meta-strategy ({pop['solver']}): {mix}"
        )
        return
    ev = summary["final_eval"]["stats"][summary["metric"]]
    typer.echo(
        f"run {run_dir}: {summary['frames']} frames in {summary['wall_time_s']:.0f} s "
        f"({summary['frames_per_s']:,.0f} frames/s); eval {summary['metric']} {ev['mean']:.4g} +- {ev['std']:.3g}"
    )


@app.command(context_settings=_PASS_THROUGH)
@_user_errors
def train(
    overrides: Optional[List[str]] = typer.Argument(None, help="Hydra overrides: task=solo_bump algo=ppo env.num_envs=256 env.action_space=ctbr seed=3 total_frames=2e6 hydra.run.dir=DIR, or resume=RUN_DIR [total_frames=N]."),
    multirun: bool = typer.Option(False, "-m", "--multirun", help="Sweep: one job per combination of comma-separated values (seed=0,1,2)."),
    show: Optional[str] = typer.Option(None, "--cfg", "-c", help="Print the composed config (job, hydra or all) instead of training."),
) -> None:
    """Train a policy; writes a run directory (config, metrics.csv, checkpoints, summary.json, recordings)."""
    overrides = list(overrides or [])
    _refuse_flags(overrides, "-m/--multirun, --cfg job|hydra|all, --help")
    _refuse_empty(overrides)
    if show is not None and show not in ("job", "hydra", "all"):
        raise ConfigError(f"unknown --cfg {show!r}; allowed: job, hydra, all")
    if show is not None and multirun:
        raise ConfigError("--cfg prints the config of one job; it cannot be combined with -m")
    from volleybots.launchers import check_launcher

    check_launcher(overrides)
    resume_dir = next((o.partition("=")[2] for o in overrides if o.startswith("resume=")), None)
    if resume_dir is not None and resume_dir != "null":
        from volleybots.runner import resume

        if multirun or show:
            raise ConfigError("resume= continues one run; it takes neither -m nor --cfg")
        summary = resume(resume_dir, [o for o in overrides if not o.startswith("resume=")])
        _echo_summary(summary, resume_dir)
        return
    from volleybots.config import check_memory, compose, validate

    jobs = _jobs(overrides, multirun)
    cfgs = [validate(compose(job)) for job in jobs]
    if show is None:
        from volleybots.train import check_init

        for c in cfgs:
            check_init(c)  # init= fits, before Hydra writes the run dir
    if not any(o.split("=", 1)[0].lstrip("+~") == "algo" for o in overrides):
        # the task's own default (MAPPO for cooperative tasks, SP for matches) when no algo is named
        algos = sorted({c.algo.name for c in cfgs})
        if len(algos) > 1:
            raise ConfigError(f"the swept tasks train with different default algorithms ({', '.join(algos)}); name one with algo=NAME")
        overrides = [*overrides, f"algo={algos[0]}"]
    if show is not None:
        _run_hydra(overrides, multirun, ["--cfg", show])
        return
    for cfg in cfgs:
        check_memory(cfg)
    from volleybots.runs import unlock

    key = _DIR_KEYS[multirun]
    run_dir = _claim_dir(_jobs(overrides, multirun)[0], overrides, multirun)
    try:
        pinned = [o for o in overrides if o.partition("=")[0].lstrip("+") != key]
        _run_hydra([*pinned, f"{key}={_hydra_quote(run_dir)}"], multirun, [])
    finally:
        unlock(run_dir)


# ------------------------------------------------------------------------------------ eval, replay
class _EvalGroup(TyperGroup):
    """``eval`` is a group of verbs (crossplay, elo) whose first argument may instead be a target:
    ``volleybots eval RUN_DIR episodes=3`` runs the hidden ``policy`` verb."""

    def parse_args(self, ctx, args):
        if args and args[0] not in self.commands and not args[0].startswith("-"):
            args = ["policy", *args]
        return super().parse_args(ctx, args)


eval_app = typer.Typer(
    cls=_EvalGroup,
    no_args_is_help=True,
    help="Evaluate: `eval TARGET episodes=100 ...` plays one policy (a run dir, a checkpoint, scripted, random) "
    "and reports the task metric; `eval compare A B ...` plays several on the same episodes and tests their differences; "
    "`eval crossplay` and `eval elo` rank competitors of a match.",
)
app.add_typer(eval_app, name="eval")
_COMPETITORS = "Competitors (a run dir, a checkpoint, a population run, scripted, random; label one with name=PATH)"


@eval_app.command("policy", hidden=True, context_settings=_PASS_THROUGH)
@_user_errors
def eval_cmd(
    target: str = typer.Argument(..., help="A run directory, a checkpoint file, 'scripted' or 'random'."),
    overrides: Optional[List[str]] = typer.Argument(None, help="episodes=100 deterministic=true seed=0; for scripted/random also task=NAME env.action_space=ctbr."),
    as_json: bool = typer.Option(False, "--json", help="Print the result as JSON instead of a table."),
) -> None:
    """Play N episodes (episodes=100) and report the task metric's mean / std and every per-term return."""
    from volleybots.eval import evaluate, format_table

    _refuse_flags([target, *(overrides or [])], "--json, --help")
    result = evaluate(target, list(overrides or []))
    if as_json:
        typer.echo(json.dumps(result, indent=2))
    else:
        from rich.console import Console

        Console().print(format_table(result))


@eval_app.command("compare", context_settings=_PASS_THROUGH)
@_user_errors
def compare_cmd(
    args: Optional[List[str]] = typer.Argument(None, help="BASELINE TARGET [TARGET ...] (run dirs, checkpoints, scripted, random), then episodes=100 seed=0 deterministic=true task.episode_len=... (scripted/random play the first run's task unless task= is given)."),
    as_json: bool = typer.Option(False, "--json", help="Print the result, per-episode metrics included, as JSON instead of a table."),
) -> None:
    """Play every target on the same episodes and compare each with the first, episode by episode: mean improvement with its 95 % interval, W/T/L, Wilcoxon test."""
    from volleybots.eval.compare import compare, format_table

    args = list(args or [])
    _refuse_flags(args, "--json, --help")
    result = compare(args)
    if as_json:
        typer.echo(json.dumps(result, indent=1))
    else:
        from rich.console import Console

        Console().print(format_table(result))


def _pair_progress(i: int, j: int, games) -> None:
    typer.echo(f"  pair {i},{j}: W/D/L {'/'.join(map(str, games.total.tolist()))}", err=True)


def _show(data: dict, table, as_json: bool, files: list[Path]) -> None:
    """A verb's result: its JSON, or its table and the files it wrote."""
    if as_json:
        typer.echo(json.dumps(data, indent=1))
        return
    from rich.console import Console

    Console().print(table)
    typer.echo(f"wrote {' and '.join(map(str, files))}")


@eval_app.command("crossplay", context_settings=_PASS_THROUGH)
@_user_errors
def crossplay_cmd(
    args: Optional[List[str]] = typer.Argument(None, help=f"{_COMPETITORS}, then games=1000 seed=0 batch=256 scenario=any|serve|receive deterministic=false task=1v1 env.action_space=prt."),
    as_json: bool = typer.Option(False, "--json", help="Print the results JSON instead of the table."),
    out: Optional[Path] = typer.Option(None, "--out", help="Folder for crossplay.json and crossplay.png (new or empty; default outputs/crossplay/<time>_<task>)."),
) -> None:
    """Every pair plays N games, each side half of them: W/D/L, win rates with Wilson intervals, average win rate, heatmap."""
    from volleybots.eval.crossplay import format_table, run_crossplay

    res, path = run_crossplay(list(args or []), out, progress=None if as_json else _pair_progress)
    _show(res.to_dict(), format_table(res), as_json, [path / "crossplay.json", path / "crossplay.png"])


@eval_app.command("exploitability", context_settings=_PASS_THROUGH)
@_user_errors
def exploitability_cmd(
    args: Optional[List[str]] = typer.Argument(None, help="TARGET (a competitor), then budget=1000000 games=1000 seed=0 scenario=any|serve|receive init=RUN num_envs=N batch=256 task=1v1 env.action_space=prt."),
    as_json: bool = typer.Option(False, "--json", help="Print the results JSON instead of a line."),
    out: Optional[Path] = typer.Option(None, "--out", help="Folder for the best response's run dir (br/) and exploitability.json (new or empty)."),
) -> None:
    """Train a best response with (MA)PPO against TARGET for a budget of frames, play it: 100 x (BR win rate - 0.5)."""
    from volleybots.eval.exploitability import RESULTS, format_line, run_exploitability

    args = list(args or [])
    if as_json:
        args.append("progress=false")
    report, path = run_exploitability(args, out)
    if as_json:
        typer.echo(json.dumps(report, indent=1, default=float))
        return
    typer.echo(format_line(report))
    typer.echo(f"wrote {path / RESULTS} and the best response's run {path / 'br'}")


@eval_app.command("elo", context_settings=_PASS_THROUGH)
@_user_errors
def elo_cmd(
    args: Optional[List[str]] = typer.Argument(None, help=f"{_COMPETITORS}, or from=CROSSPLAY_JSON; then rounds=2000 k=168 bootstrap=1000 seed=0 and cross-play's options."),
    as_json: bool = typer.Option(False, "--json", help="Print the ratings JSON instead of the table."),
    out: Optional[Path] = typer.Option(None, "--out", help="Folder for ratings.json, ratings.png (and the games played); new or empty."),
) -> None:
    """Elo over rounds in which every pair meets once (the paper's), Bradley-Terry with bootstrap intervals, the Nash mixture."""
    from volleybots.eval.ranking import format_table, run_elo

    report, path = run_elo(list(args or []), out, progress=None if as_json else _pair_progress)
    _show(report, format_table(report), as_json, [path / "ratings.json", path / "ratings.png"])


def _free_path(path: Path) -> Path:
    stem, n = path.stem, 2
    while path.exists():
        path = path.with_name(f"{stem}_{n}{path.suffix}")
        n += 1
    return path


@app.command(context_settings=_PASS_THROUGH)
@_user_errors
def replay(
    args: List[str] = typer.Argument(..., help="TARGET [overrides]: a run dir, a checkpoint, 'scripted' or 'random' with seed=0 deterministic=true (for scripted/random also task=NAME env.action_space=ctbr); or A B [task=3v3 seed=0 scenario=any|serve|receive]: a match between two competitors (name=PATH labels one)."),
    out: Optional[Path] = typer.Option(None, "--out", help="The .rrd file to write (never overwritten)."),
    no_viewer: bool = typer.Option(False, "--no-viewer", help="Do not open the rerun viewer even when a display exists."),
    still: Optional[Path] = typer.Option(None, "--still", help="Also draw the episode to this .png (court, drones, ball flight; needs the 'plot' extra; never overwritten)."),
) -> None:
    """Record one episode to a rerun file: court, net, drones, ball trail, hits / violations, rewards; for two
    competitors, one match with each team's colour, the touches and the fault that ended the rally."""
    from volleybots.replay import has_display
    from volleybots.runs import check_writable

    _refuse_flags(args, "--out FILE.rrd, --still FILE.png, --no-viewer, --help")
    for opt, path, suffix in (("--out", out, ".rrd"), ("--still", still, ".png")):
        if path is not None and path.suffix != suffix:
            raise ConfigError(f"{opt} {str(path)!r} must end in {suffix}")
        if path is not None and (path.exists() or path.is_symlink()):
            raise ConfigError(f"{opt} {str(path)!r} exists; choose another file (replays never overwrite)")
        if path is not None:
            check_writable(path.parent, f"the folder of {opt}")
    viewer = not no_viewer and has_display()
    from volleybots.eval.crossplay import is_competitor_spec, replay_match

    if sum(map(is_competitor_spec, args)) >= 2:
        if still is not None:
            raise ConfigError("--still draws one policy's episode (replay TARGET ...); a match replay takes --out and --no-viewer only")
        stats, out, labels = replay_match(args, out, viewer)
        where = str(out) if out is not None else "the viewer"
        who = {0: f"{labels[0]} (blue) won", 1: f"{labels[1]} (red) won", -1: "a draw"}[int(stats["winner"])]
        typer.echo(f"recorded one match of {labels[0]} (blue) against {labels[1]} (red) to {where}: {who}")
        return
    _replay_one(args[0], args[1:], out, viewer, still)


def _replay_one(target: str, overrides: list[str], out: Path | None, viewer: bool, still: Path | None = None) -> None:
    from volleybots.config import make_env
    from volleybots.eval import resolve_target
    from volleybots.replay import record_episode
    from volleybots.runs import check_writable, make_dir

    t = resolve_target(target, overrides)
    if out is None and not viewer:
        stamp = time.strftime("%Y%m%d-%H%M%S")
        base = Path(target) if Path(target).is_dir() else Path("outputs") / "replays"
        check_writable(base, "the replay folder (choose another with --out)")
        out = _free_path(base / f"replay_{t.cfg.task.name}_{t.label.replace('@', '_')}_{stamp}.rrd")
    if out is not None:
        make_dir(out.parent, "the folder of --out")
    env = make_env(t.cfg, num_envs=1, seed=t.cfg.seed)
    stats = record_episode(env, t.make_policy(env), out, viewer=viewer, still=still)
    where = str(out) if out is not None else "the viewer"
    where += f" and {still}" if still is not None else ""
    typer.echo(f"recorded one episode of {t.label} on {t.cfg.task.name} to {where}: {env.metric} {stats[env.metric]:.4g}, return {stats['return']:.4g}")


# -------------------------------------------------------------------------------------- list, bench
@app.command("list")
def list_cmd() -> None:
    """List tasks, algorithms, physics backends and action spaces, one line each."""
    from volleybots.algos import ALGOS
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
    typer.echo("physics backends (env.physics=NAME):")
    for name, text in BACKEND_INFO.items():
        typer.echo(f"  {name:<20} {text}")
    typer.echo("action spaces (env.action_space=NAME):")
    for name, text in ACTION_SPACE_INFO.items():
        typer.echo(f"  {name:<20} {text}")


def _fits(algo: str, task: str) -> bool:
    """Whether ``algo`` accepts ``task`` in its own first action space (its ``check`` decides)."""
    from volleybots.algos import ALGOS
    from volleybots.config import EnvConfig
    from volleybots.tasks import TASKS

    cls = ALGOS[algo]
    try:
        from omegaconf import OmegaConf

        cls.check(OmegaConf.structured(cls.config_cls), TASKS[task], EnvConfig(action_space=cls.action_spaces[0]))
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
    from volleybots.config import check_bench_options, parse_value

    allowed = [p for p in inspect.signature(run_bench).parameters if p != "progress"]
    kwargs = {"compile": True} if compile else {}
    for o in options or []:
        key, eq, value = o.partition("=")
        if not eq or key not in allowed:
            raise ConfigError(f"unknown bench option {key!r}; allowed: {', '.join(allowed)}")
        kwargs[key] = parse_value(value)
    kwargs = check_bench_options(kwargs)
    try:
        rows = run_bench(**kwargs, progress=lambda row: typer.echo(f"  measured {row.get('task')} {row.get('kind', 'env')} {row.get('backend')} x{row.get('num_envs')}: {row.get('env_steps_per_s', 0):,.0f}/s", err=True))
    except ValueError as e:
        raise ConfigError(str(e).splitlines()[0]) from None
    typer.echo(json.dumps(rows, indent=1) if as_json else format_table(rows))


# ------------------------------------------------------------------------------------------ report
@app.command()
@_user_errors
def report(
    dirs: List[Path] = typer.Argument(..., help="Run directories, or folders that hold them (a sweep's multirun/<date>/<time>_<task>_<algo>)."),
    out: Optional[Path] = typer.Option(None, "--out", help="Also write report.md, report.json and curves_<task>.png to this folder (never overwritten)."),
    as_json: bool = typer.Option(False, "--json", help="Print the report as JSON instead of Markdown."),
    stale_after: float = typer.Option(1800.0, "--stale-after", help="Seconds without a write after which a run with no summary.json counts as failed, not running."),
) -> None:
    """Aggregate runs across seeds: per task x algorithm the final metric's mean, IQM and 95% bootstrap intervals, learning curves."""
    from volleybots.report import build_report, check_out, format_markdown, write_report

    if out is not None:
        check_out(out)
    result = build_report(dirs, stale_after=stale_after)
    if out is not None:
        write_report(result, out)
    typer.echo(json.dumps(result, indent=2) if as_json else format_markdown(result))


if __name__ == "__main__":
    app()
