"""``volleybots eval`` (a target, ``compare``, ``crossplay``, ``exploitability``, ``elo``) and ``volleybots replay``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import List, Optional

import typer
from typer.core import TyperGroup

from volleybots.cli.app import _PASS_THROUGH, _refuse_flags, _user_errors, app, options_help, say, show
from volleybots.config.compose import check_fixed_values, check_group_args
from volleybots.config.verbs import CrossplayOptions, EloOptions, ExploitabilityOptions, ReplayOptions


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
_MATCH = "config overrides of the match (task=1v1, env.action_space=prt, task.KEY=, env.KEY=, threads=)"


@eval_app.command("policy", hidden=True, context_settings=_PASS_THROUGH)
@_user_errors
def eval_cmd(
    target: str = typer.Argument(..., help="A run directory, a checkpoint file, 'scripted' or 'random'."),
    overrides: Optional[List[str]] = typer.Argument(
        None, help="episodes=100 deterministic=true seed=0; for scripted/random also task=NAME env.action_space=ctbr."
    ),
    as_json: bool = typer.Option(False, "--json", help="Print the result as JSON instead of a table."),
) -> None:
    """Play N episodes (episodes=100) and report the task metric's mean / std and every per-term return."""
    check_group_args(overrides or [])  # a mistyped task= before the policies (and torch) load
    check_fixed_values(overrides or [])  # and episodes=0
    from volleybots.eval import evaluate, format_table

    _refuse_flags([target, *(overrides or [])], "--json, --help")
    result = evaluate(target, list(overrides or []))
    if as_json:
        typer.echo(json.dumps(result, indent=2))
    else:
        show(format_table(result))


@eval_app.command("compare", context_settings=_PASS_THROUGH)
@_user_errors
def compare_cmd(
    args: Optional[List[str]] = typer.Argument(
        None,
        help="BASELINE TARGET [TARGET ...] (run dirs, checkpoints, scripted, random), then episodes=100 seed=0 "
        "deterministic=true task.episode_len=... (scripted/random play the first run's task unless task= is given).",
    ),
    as_json: bool = typer.Option(False, "--json", help="Print the result, per-episode metrics included, as JSON instead of a table."),
) -> None:
    """Play every target on the same episodes and compare each with the first, episode by episode:
    mean improvement with its 95 % interval, W/T/L, Wilcoxon test."""
    check_group_args(args or [])  # a mistyped task= before the policies (and torch) load
    from volleybots.eval.compare import compare, format_table

    args = list(args or [])
    _refuse_flags(args, "--json, --help")
    result = compare(args)
    if as_json:
        typer.echo(json.dumps(result, indent=1))
    else:
        show(format_table(result))


class _PairProgress:
    """cross-play's line per pair on stderr: its W/D/L and game content, then how many pairs are done of
    how many, the time so far and the ETA (a cross-play of many competitors runs for hours)."""

    def __init__(self):
        from volleybots.train.progress import Count

        self.count = Count("pairs")

    def begin(self, total: int) -> None:
        self.count.begin(total)

    def __call__(self, i: int, j: int, games) -> None:
        from volleybots.eval.reuse import Reused

        reused = isinstance(games, Reused)
        c = games.content()
        t = c["touches"]
        typer.echo(
            f"  pair {i},{j}: W/D/L {'/'.join(map(str, games.total.tolist()))}, touches/game {t[0]:.2f}/{t[1]:.2f}, "
            f"rally {c['rally_steps']:.0f} steps" + (f" (reused from {games.source})" if reused else "")
            + f"  [{self.count.tick(timed=not reused)}]",
            err=True,
        )


def _show(data: dict, table, as_json: bool, files: list[Path]) -> None:
    """A verb's result: its JSON, or its table and the files it wrote."""
    if as_json:
        typer.echo(json.dumps(data, indent=1))
        return
    show(table)
    say(f"wrote {' and '.join(map(str, files))}")


@eval_app.command("crossplay", context_settings=_PASS_THROUGH, epilog=options_help(CrossplayOptions))
@_user_errors
def crossplay_cmd(
    args: Optional[List[str]] = typer.Argument(None, help=f"{_COMPETITORS}, then the key=value options below and {_MATCH}."),
    as_json: bool = typer.Option(False, "--json", help="Print the results JSON instead of the table."),
    out: Optional[Path] = typer.Option(
        None, "--out", help="Folder for crossplay.json and crossplay.png (new or empty; default outputs/crossplay/<time>_<task>)."
    ),
) -> None:
    """Every pair plays N games, each side half of them: W/D/L, win rates with Wilson intervals, average win rate, heatmap."""
    check_group_args(args or [])  # a mistyped task= before the policies (and torch) load
    from rich.console import Group

    from volleybots.eval.content import format_content
    from volleybots.eval.crossplay import format_table, run_crossplay

    res, path = run_crossplay(list(args or []), out, progress=_PairProgress())  # on stderr, --json or not
    tables = Group(format_table(res), format_content(res.labels, res.content))
    _show(res.to_dict(), tables, as_json, [path / "crossplay.json", path / "crossplay.png"])


@eval_app.command("exploitability", context_settings=_PASS_THROUGH, epilog=options_help(ExploitabilityOptions))
@_user_errors
def exploitability_cmd(
    args: Optional[List[str]] = typer.Argument(
        None,
        help=f"TARGET (a competitor), then the key=value options below, {_MATCH}, and algo.KEY=VALUE for the responses' MAPPO "
        "(with init=, a critic warm-up of algo.actor_freeze_updates=10 batches unless given).",
    ),
    as_json: bool = typer.Option(False, "--json", help="Print the results JSON instead of a line (progress still goes to stderr)."),
    out: Optional[Path] = typer.Option(
        None, "--out", help="Folder for the trained responses' run dirs (br/, br_s1/, ...; br_serve/, br_receive/ with "
        "scenario=split) and exploitability.json (new or empty)."
    ),
) -> None:
    """A lower bound on TARGET's exploitability: the best of responses trained on several seeds, fixed
    responses, the target's members and the target itself, chosen on games apart from those that give the figure."""
    check_group_args(args or [])  # a mistyped task= before the policies (and torch) load
    from volleybots.eval.exploitability import RESULTS, format_line, run_exploitability

    args = list(args or [])
    if as_json:
        args.append("progress=false")
    report, path = run_exploitability(args, out, progress=lambda line: say(line, err=True))
    if as_json:
        typer.echo(json.dumps(report, indent=1, default=float))
        return
    say(format_line(report))
    runs = [t["run"] for p in (report.get("parts") or {"": report}).values() for t in (p.get("trained") or {}).values()]
    also = f" and the trained responses' runs {', '.join(runs)}" if runs else ""
    say(f"wrote {path / RESULTS}{also}")


@eval_app.command("elo", context_settings=_PASS_THROUGH, epilog=options_help(EloOptions))
@_user_errors
def elo_cmd(
    args: Optional[List[str]] = typer.Argument(
        None, help=f"{_COMPETITORS}, or from=CROSSPLAY_JSON; then the key=value options below and {_MATCH}."
    ),
    as_json: bool = typer.Option(False, "--json", help="Print the ratings JSON instead of the table."),
    out: Optional[Path] = typer.Option(None, "--out", help="Folder for ratings.json, ratings.png (and the games played); new or empty."),
) -> None:
    """Elo over rounds in which every pair meets once (the paper's), Bradley-Terry with profile-likelihood intervals, the Nash mixture."""
    check_group_args(args or [])  # a mistyped task= before the policies (and torch) load
    from volleybots.eval.ranking import format_table, run_elo

    report, path = run_elo(list(args or []), out, progress=_PairProgress())  # on stderr, --json or not
    _show(report, format_table(report), as_json, [path / "ratings.json", path / "ratings.png"])


@app.command(context_settings=_PASS_THROUGH, epilog=options_help(ReplayOptions, "key=value options of a match (A B)"))
@_user_errors
def replay(
    args: List[str] = typer.Argument(
        ...,
        help="TARGET [overrides]: a run dir, a checkpoint, 'scripted' or 'random' with seed=0 deterministic=true "
        "(for scripted/random also task=NAME env.action_space=ctbr); or A B, then the key=value options below and "
        f"{_MATCH}: a match between two competitors (name=PATH labels one).",
    ),
    out: Optional[Path] = typer.Option(None, "--out", help="The .rrd file to write (never overwritten)."),
    no_viewer: bool = typer.Option(False, "--no-viewer", help="Do not open the rerun viewer even when a display exists."),
    still: Optional[Path] = typer.Option(
        None, "--still", help="Also draw the episode to this .png (court, drones, ball flight; needs the 'plot' extra; never overwritten)."
    ),
) -> None:
    """Record one episode to a rerun file: court, net, drones, ball trail, hits / violations, rewards; for two
    competitors, one match with each team's colour, the touches and the fault that ended the rally."""
    check_group_args(args or [])  # a mistyped task= before the policies (and torch) load
    from volleybots.eval.replays import replay_verb
    from volleybots.replay import has_display

    _refuse_flags(args, "--out FILE.rrd, --still FILE.png, --no-viewer, --help")
    say(replay_verb(list(args), out, not no_viewer and has_display(), still))


