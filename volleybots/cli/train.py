"""``volleybots train``: Hydra overrides to a run directory (or a sweep of them), or ``resume=RUN``."""

from __future__ import annotations

import itertools
import sys
from typing import List, Optional

import typer

from volleybots.cli.app import _PASS_THROUGH, _refuse_flags, _user_errors, app, say
from volleybots.errors import ConfigError
from volleybots.overrides import hydra_quote, names_key, override_key, override_value, split_arg


def _jobs(overrides: list[str], multirun: bool) -> list[list[str]]:
    """The override lists of the jobs a command line asks for (one without -m; the sweep's product with)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import HydraException

    try:
        parsed = OverridesParser.create().parse_overrides(overrides)
    except HydraException as e:
        raise ConfigError(f"bad override: {' '.join(str(e).split())}{_quote_hint(overrides)}") from None
    sweeps = [o for o in parsed if o.is_sweep_override()]
    if sweeps and not multirun:
        raise ConfigError(
            f"override {sweeps[0].input_line!r} sweeps several values; add -m to run one job per value"
            f"{_quote_hint([sweeps[0].input_line])}"
        )
    choices = [
        [f"{o.get_key_element()}={v}" for v in o.sweep_string_iterator()] if o.is_sweep_override() else [o.input_line]
        for o in parsed
    ]
    return [list(c) for c in itertools.product(*choices)] or [[]]


def _quote_hint(overrides: list[str]) -> str:
    """A hint for a value Hydra's grammar reads only quoted (non-ASCII letters, ',', '=', spaces): a
    directory name may hold them when written as KEY='VALUE'."""
    for o in overrides:
        key, value = split_arg(o)
        if value is None:
            continue
        pathlike = "/" in value or override_key(o).endswith(("dir", "resume", "init", "opponent"))
        if pathlike and not value.startswith(("'", '"')) and (not value.isascii() or any(c in value for c in ",= ()[]{}")):
            return f" (if {key} is one value, quote it for Hydra: \"{key}={hydra_quote(value)}\")"
    return ""


_DIR_KEYS = {False: "hydra.run.dir", True: "hydra.sweep.dir"}
_NONEMPTY = ("resume", "hydra.run.dir", "hydra.sweep.dir", "hydra.sweep.subdir", "hydra.job.name")


def _refuse_empty(overrides: list[str]) -> None:
    """``resume=`` or ``hydra.run.dir=`` with nothing after the '=' would silently mean "none" / "here"."""
    for o in overrides:
        key, value = split_arg(o)
        if value is not None and override_key(o) in _NONEMPTY and not value.strip():
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
    explicit = names_key(overrides, key)
    return str(claim_run_dir(path, unique=not explicit, sweep=multirun))


def _run_hydra(overrides: list[str], multirun: bool, extra: list[str]) -> None:
    import hydra

    from volleybots.paths import conf_dir

    @hydra.main(config_path=str(conf_dir()), config_name="config", version_base="1.3")
    def _job(cfg) -> None:
        from hydra.core.hydra_config import HydraConfig

        from volleybots.config import algo_action_space, validate
        from volleybots.population.run import start as train_run

        try:
            cfg = algo_action_space(cfg, HydraConfig.get().overrides.task)
            summary = train_run(validate(cfg), HydraConfig.get().runtime.output_dir)
        except ConfigError as e:
            # SystemExit passes through Hydra's error report (which would exit 1 with a banner)
            say(f"error: {e}", err=True)
            sys.exit(2)
        _echo_summary(summary, HydraConfig.get().runtime.output_dir)

    argv = sys.argv
    sys.argv = ["volleybots-train", *overrides, *(["--multirun"] if multirun else []), *extra]
    try:
        _job()
    finally:
        sys.argv = argv


def _oracle_text(i: int, o: dict) -> str:
    """One best response's end: its final win rate against its opponent mixture and whether it converged."""
    rate = o.get("win_rate", o.get("win_mean"))  # runs written before win_rate named it win_mean
    win = "n/a" if rate is None else f"{rate:.2f}"
    state = "converged" if o["converged"] else f"not converged ({o.get('stopped', 'max_updates')})"
    return f"br{i} win {win} after {o['updates']} updates, {state}"


def _time_bound(summary: dict, run_dir) -> str:
    """A population run's time limit and whether it ended the run before its iterations ('' for none): a
    bound the user did not give (``population.default_time_limit``, the bare 6v6 headline) is said aloud."""
    from volleybots.runs import RunDir

    try:
        cfg = RunDir(run_dir).load_config()
    except ConfigError:
        return ""
    limit, planned = float(cfg.time_limit or 0), int(cfg.population.iterations)
    if not limit:
        return ""
    given = "population.default_time_limit" if cfg.population.default_time_limit.get(cfg.task.name) == limit else "time_limit"
    if summary["iterations"] >= planned:
        return f"  time_limit {limit:.0f} s ({given}): not reached, all {planned} iteration(s) done"
    return (f"  time_limit {limit:.0f} s ({given}) ended the run after {summary['iterations']} of {planned} iteration(s); "
            f"resume={run_dir} time_limit=SECONDS (above {limit:.0f}) continues it")


def _echo_summary(summary: dict, run_dir) -> None:
    if "population" in summary:
        pop = summary["population"]
        mix = ", ".join(f"{m} {w:.2f}" for m, w in zip(pop["members"], pop["mixture"]))
        say(
            f"run {run_dir}: {summary['frames']} frames in {summary['wall_time_s']:.0f} s ({summary['frames_per_s']:,.0f} frames/s); "
            f"{summary['iterations']} iteration(s), population {len(pop['members'])}, meta-strategy ({pop['solver']}): {mix}"
        )
        ev, split = summary.get("final_eval"), summary.get("wall_time_split")
        if ev:
            say(f"  final mixture against {ev['opponent']}: W/D/L {'/'.join(map(str, ev['wdl']))} over {ev['episodes']} games")
        if split:
            say("  wall time: " + ", ".join(f"{k.replace('_', ' ')} {v:.0f} s" for k, v in split.items()))
        if bound := _time_bound(summary, run_dir):
            say(bound)
        oracles = [o for o in summary.get("oracles", []) if o and o.get("converged") is not None]
        if oracles:
            say("oracles: " + "; ".join(_oracle_text(i, o) for i, o in enumerate(oracles, 1)))
        if d := summary.get("dropped_oracle"):
            say(f"oracle {d['iteration']} dropped: the budget ended it after {d['updates']} update(s) ({d['frames']} frames), "
                f"before population.min_updates; resume with more total_frames or time_limit to train it")
        return
    ev = summary["final_eval"]["stats"][summary["metric"]]
    say(
        f"run {run_dir}: {summary['frames']} frames in {summary['wall_time_s']:.0f} s "
        f"({summary['frames_per_s']:,.0f} frames/s); eval {summary['metric']} {ev['mean']:.4g} +- {ev['std']:.3g}"
    )


@app.command(context_settings=_PASS_THROUGH)
@_user_errors
def train(
    overrides: Optional[List[str]] = typer.Argument(
        None,
        help="Hydra overrides: task=solo_bump algo=ppo env.num_envs=256 env.action_space=ctbr seed=3 total_frames=2e6 "
        "hydra.run.dir=DIR, or resume=RUN_DIR [total_frames=N].",
    ),
    multirun: bool = typer.Option(False, "-m", "--multirun", help="Sweep: one job per combination of comma-separated values (seed=0,1,2)."),
    show: Optional[str] = typer.Option(None, "--cfg", "-c", help="Print the composed config (job, hydra or all) instead of training."),
    config_dir: Optional[str] = typer.Option(
        None, "--config-dir", "-cd", help="A folder of your own presets (algo/NAME.yaml, task/NAME.yaml, ...) beside the packaged ones "
        "(as hydra.searchpath=[file://DIR]; docs/usage.md).",
    ),
) -> None:
    """Train a policy; writes a run directory (config, metrics.csv, checkpoints, summary.json, recordings)."""
    overrides = list(overrides or [])
    _refuse_flags(overrides, "-m/--multirun, --cfg job|hydra|all, --config-dir DIR, --help")
    from volleybots.config.searchpath import active, with_config_dir

    # --config-dir is read as the first hydra.searchpath entry, so every job and Hydra itself see the same words
    overrides = with_config_dir(overrides, config_dir)
    with active(overrides):  # the checks before composition know the user's presets
        _train(overrides, multirun, show)


def _train(overrides: list[str], multirun: bool, show: str | None) -> None:
    _refuse_empty(overrides)
    if show is not None and show not in ("job", "hydra", "all"):
        raise ConfigError(f"unknown --cfg {show!r}; allowed: job, hydra, all")
    if show is not None and multirun:
        raise ConfigError("--cfg prints the config of one job; it cannot be combined with -m")
    from volleybots.launchers import check_launcher

    check_launcher(overrides)
    resume_dir = override_value([o for o in overrides if o.startswith("resume=")], "resume")
    if resume_dir is not None and resume_dir != "null":
        from volleybots.population.run import resume

        if multirun or show:
            raise ConfigError("resume= continues one run; it takes neither -m nor --cfg")
        summary = resume(resume_dir, [o for o in overrides if not o.startswith("resume=")])
        _echo_summary(summary, resume_dir)
        return
    from volleybots.config.spelling import respell

    # old spellings and the task's default method, once for every job; the notes on old spellings are
    # printed once the config is accepted (a refusal stays one line)
    overrides, notes = respell(overrides)
    if not multirun and show is None:
        _single_run(overrides, notes)
        return
    from volleybots.config import compose, validate
    from volleybots.config.compose import pin_default_algo

    jobs = _jobs(overrides, multirun)
    cfgs = [validate(compose(job)) for job in jobs]
    from volleybots.train import preflight

    if show is None:
        for c in cfgs:
            preflight(c)  # memory, opponent= / seed_members / init= files: before Hydra writes any run dir
    overrides = pin_default_algo(cfgs, overrides)
    _echo_notes(notes)
    if show is not None:
        _run_hydra(overrides, multirun, ["--cfg", show])
        return
    from volleybots.runs import unlock

    key = _DIR_KEYS[multirun]
    run_dir = _claim_dir(_jobs(overrides, multirun)[0], overrides, multirun)
    try:
        pinned = [o for o in overrides if override_key(o) != key]
        _run_hydra([*pinned, f"{key}={hydra_quote(run_dir)}"], multirun, [])
    finally:
        unlock(run_dir)
    _sweep_report(run_dir)


def _sweep_report(sweep_dir) -> None:
    """When a sweep ends, its report (``volleybots report``) is written beside its jobs: ``report.md``,
    ``report.json`` and ``curves_<task>.png`` in the sweep directory (files, so no job folder is added)."""
    from pathlib import Path

    from volleybots.report import build_report, write_report

    sweep = Path(sweep_dir)
    if (sweep / "report.md").exists():  # never overwritten: a second sweep into the same folder keeps the first report
        return
    files = write_report(build_report([sweep]), sweep)
    say(f"sweep report: {files[0]}")


def _echo_notes(notes: list[str]) -> None:
    for note in notes:
        say(f"note: {note}", err=True)


def _single_run(overrides: list[str], notes: list[str]) -> None:
    """One run without a sweep: the config is composed once (its ``hydra`` node gives the run dir) and
    validated once, every file it names is checked, and only then is the directory claimed and
    written. Hydra's launcher machinery is for sweeps; a single run records its overrides in
    ``.hydra/`` as Hydra would."""
    from pathlib import Path

    from volleybots.config import compose, validate

    _jobs(overrides, False)  # a sweep value without -m is one clear line
    # composed before the trainer is imported: a misspelt key or group option is reported before torch loads
    full = compose(overrides, hydra_node=True)
    from volleybots.population.run import start
    from volleybots.runs import claim_run_dir, unlock
    from volleybots.train import preflight

    key = _DIR_KEYS[False]
    path = str(full.hydra.run.dir)
    if not path.strip():
        raise ConfigError(f"{key} is empty; give it a directory")
    from omegaconf import OmegaConf

    cfg = validate(OmegaConf.masked_copy(full, [k for k in full if k != "hydra"]))
    preflight(cfg)
    _echo_notes(notes)
    explicit = names_key(overrides, key)
    run_dir = claim_run_dir(Path(path).absolute(), unique=not explicit)  # absolute, as Hydra's output_dir is
    try:
        _write_hydra_record(run_dir, full, overrides)
        summary = start(cfg, run_dir, checked=True)
    finally:
        unlock(run_dir)
    _echo_summary(summary, run_dir)


def _write_hydra_record(run_dir, full, overrides: list[str]) -> None:
    """``.hydra/config.yaml``, ``hydra.yaml`` and ``overrides.yaml`` as ``hydra.main`` writes them."""
    from omegaconf import OmegaConf

    record = run_dir / ".hydra"
    record.mkdir(exist_ok=True)
    job = OmegaConf.masked_copy(full, [k for k in full if k != "hydra"])
    (record / "config.yaml").write_text(OmegaConf.to_yaml(job))
    (record / "hydra.yaml").write_text(OmegaConf.to_yaml(OmegaConf.create({"hydra": OmegaConf.to_container(full.hydra, resolve=False)})))
    (record / "overrides.yaml").write_text(OmegaConf.to_yaml(OmegaConf.create(list(overrides))))


