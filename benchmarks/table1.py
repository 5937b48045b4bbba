"""Paper table 1 on a small budget: Back and Forth, Hit the Ball, Solo Bump x CTBR / PRT x DQN, DDPG,
TD3, SAC, PPO, each cell the task metric's mean +- std over seeds.

Every run trains ``--frames`` env steps with ``--num-envs`` envs and the algorithm's own config (the
paper's hyperparameters), then plays ``--eval-episodes`` deterministic episodes with the final policy:
a seed's value is their mean metric. Two off-policy settings are scaled to the budget: the batch
(``--batch-size``, paper 4096) and the target networks' pace (``--tau 0.05`` every step, paper 0.005
every 4 steps): the paper's pace assumes ~1e6 gradient steps, and with the ~1e3 of a CPU budget its
targets would hardly move and the critics learn nothing (tests/algos/test_offpolicy_learning.py).
DQN acts in the discrete space (each rotor -1 or +1) whatever the column, so it runs once per seed
and its value fills both columns.

    python benchmarks/table1.py                               # the reduced version of docs/benchmarks.md
    python benchmarks/table1.py frames=2e6 seeds=[0,1,2,3,4] num_envs=1024 device=cuda
    python benchmarks/table1.py tasks=solo_bump algos=[td3,ppo] jobs=2

Runs live under ``--out`` as ``<task>_<space>_<algo>_s<seed>/`` (ordinary run directories: metrics.csv,
checkpoints, summary.json); a run that has its summary.json is not repeated, so an interrupted
benchmark continues where it stopped (and a finished one only re-tabulates). Writes ``table1.json``,
``table1.md`` (the task metric, and the episode return as a finer second table), ``table1.png`` and
``table1_return.png`` (learning curves: the training episodes' metric, or return, over frames, mean
over seeds) into ``--out``.
Needs matplotlib for the figure (``pip install 'volleybots[plot]'``).
"""

from __future__ import annotations

import dataclasses
import json
import math
import statistics
import sys
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

from volleybots.config.args import option, script_options

TASKS = ("back_and_forth", "hit_the_ball", "solo_bump")
SPACES = ("ctbr", "prt")
ALGOS = ("dqn", "ddpg", "td3", "sac", "ppo")
OFF_POLICY = ("dqn", "ddpg", "td3", "sac")
# paper table 1 (5 seeds, 5e8 frames, 4096 envs): (ctbr, prt) per task and algorithm
PAPER = {
    "back_and_forth": {"dqn": (0.00, 0.00), "ddpg": (1.14, 0.83), "td3": (1.12, 0.99), "sac": (0.90, 0.83), "ppo": (9.25, 10.04)},
    "hit_the_ball": {"dqn": (0.39, 1.88), "ddpg": (2.87, 3.98), "td3": (3.00, 3.91), "sac": (3.76, 3.87), "ppo": (10.48, 11.40)},
    "solo_bump": {"dqn": (0.00, 0.00), "ddpg": (0.44, 0.67), "td3": (3.68, 5.29), "sac": (0.54, 1.36), "ppo": (8.58, 10.83)},
}
TITLES = {"back_and_forth": "Back and Forth", "hit_the_ball": "Hit the Ball", "solo_bump": "Solo Bump"}


def jobs(args) -> list[tuple[str, str, str, int]]:
    """(task, space, algo, seed) of every run; dqn once per task and seed, in its discrete space."""
    out = []
    for task in args.tasks:
        for algo in args.algos:
            for space in ("discrete",) if algo == "dqn" else args.spaces:
                out += [(task, space, algo, seed) for seed in args.seeds]
    return out


def finished_summary(run_dir: Path) -> dict | None:
    """The summary of a finished run (not repeated), or None; an interrupted run is removed, to start
    again. A run still training (another invocation on the same ``--out`` holds its lock) is never
    removed: that raises ``InUseError``, which ``run_all`` reports as a skipped job."""
    if (run_dir / "summary.json").is_file():
        return json.loads((run_dir / "summary.json").read_text())
    if run_dir.exists():
        import shutil

        from volleybots.runs import locked

        with locked(run_dir):  # raises InUseError while another process trains in it
            shutil.rmtree(run_dir)
    return None


def run_one(job, args) -> dict:
    """Train and evaluate one run (in a worker process); returns its summary."""
    import torch

    from volleybots.config import load
    from volleybots.train import train

    task, space, algo, seed = job
    run_dir = Path(args.out) / f"{task}_{space}_{algo}_s{seed}"
    done = finished_summary(run_dir)
    if done is not None:
        return done
    torch.set_num_threads(args.threads)
    overrides = [
        f"task={task}", f"algo={algo}", f"env.action_space={space}", f"env.num_envs={args.num_envs}", f"env.device={args.device}",
        f"seed={seed}", f"threads={args.threads}", f"total_frames={int(args.frames)}", "progress=false",
        "checkpoint.every=0", "evaluation.every=0", f"evaluation.episodes={args.eval_episodes}", "evaluation.record=false",
    ]
    if algo in OFF_POLICY:
        overrides += [
            f"algo.batch_size={args.batch_size}", f"algo.buffer_size={int(args.frames)}", f"algo.tau={args.tau}",
            f"algo.target_update_interval={args.target_update_interval}",
        ]
    summary = train(load(overrides), run_dir)
    print(f"  {task} {space} {algo} seed {seed}: {summary['metric']} {summary['final_eval']['stats'][summary['metric']]['mean']:.3f} "
          f"({summary['wall_time_s']:.0f} s)", file=sys.stderr, flush=True)
    return summary


def collect_results(args, stat: str | None = None) -> dict:
    """{task: {algo: {space: [per-seed final evaluation mean]}}} of the task metric (or of ``stat``,
    e.g. ``return``) from the runs' summaries."""
    res: dict = {}
    for task, space, algo, seed in jobs(args):
        path = Path(args.out) / f"{task}_{space}_{algo}_s{seed}" / "summary.json"
        if not path.is_file():
            continue
        s = json.loads(path.read_text())
        value = s["final_eval"]["stats"][stat or s["metric"]]["mean"]
        for col in SPACES if algo == "dqn" else (space,):
            res.setdefault(task, {}).setdefault(algo, {}).setdefault(col, []).append(value)
    return res


def _cell(values) -> str:
    if not values:
        return "-"
    std = statistics.pstdev(values) if len(values) > 1 else 0.0
    return f"{statistics.fmean(values):.2f} ± {std:.2f}"


def format_table(res: dict, args, paper: bool = False) -> str:
    """Markdown in the layout of paper table 1 (``paper``: the paper's values instead)."""
    head = "| | " + " | ".join(f"{TITLES[t]} CTBR | {TITLES[t]} PRT" for t in args.tasks) + " |"
    sep = "|---" * (1 + 2 * len(args.tasks)) + "|"
    lines = [head, sep]
    for algo in args.algos:
        cells = []
        for task in args.tasks:
            for i, space in enumerate(SPACES):
                if paper:
                    cells.append(f"{PAPER[task][algo][i]:.2f}")
                else:
                    cells.append(_cell(res.get(task, {}).get(algo, {}).get(space, [])))
        lines.append(f"| {algo.upper()} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def curves(args, stat: str | None = None) -> dict:
    """{(task, space): {algo: (frames, mean over seeds of the smoothed training-episode metric)}}
    (or of ``stat``, e.g. ``return``)."""
    from volleybots.runs import read_metrics
    from volleybots.tasks import TASKS as ENVS

    out: dict = {}
    for task, space, algo, seed in jobs(args):
        path = Path(args.out) / f"{task}_{space}_{algo}_s{seed}" / "metrics.csv"
        if not path.is_file():
            continue
        metric = stat or ENVS[task].metric
        rows = [r for r in read_metrics(path) if r["phase"] == "train"]
        frames = [r["frames"] for r in rows]
        vals = _smooth([r.get(metric, math.nan) for r in rows], 5)
        for col in SPACES if algo == "dqn" else (space,):
            out.setdefault((task, col), {}).setdefault(algo, []).append((frames, vals))
    return mean_over_seeds(out)


def mean_over_seeds(out: dict) -> dict:
    """{panel: {algo: [(frames, values) of each seed]}} -> {panel: {algo: (frames, mean over seeds)}},
    over the batches every seed reached."""
    mean: dict = {}
    for key, by_algo in out.items():
        for algo, runs in by_algo.items():
            n = min(len(f) for f, _ in runs)
            mean.setdefault(key, {})[algo] = (runs[0][0][:n], [_nanmean([v[i] for _, v in runs]) for i in range(n)])
    return mean


def draw_panel(ax, curves_by_algo: dict, colors: dict, title: str, ylabel: str, label=str.upper) -> None:
    """One panel of learning curves (env steps on x), one line per algorithm."""
    for algo, (frames, vals) in sorted(curves_by_algo.items()):
        ax.plot(frames, vals, color=colors.get(algo), label=label(algo))
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("env steps")
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)


def save_figure(fig, axes, path: Path, title: str) -> None:
    import matplotlib.pyplot as plt

    axes[0][0].legend(fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _nanmean(xs):
    xs = [x for x in xs if isinstance(x, float) and not math.isnan(x)]
    return statistics.fmean(xs) if xs else math.nan


def _smooth(xs, k):
    """Trailing mean over the last ``k`` batches that finished episodes (NaN rows have none)."""
    out, window = [], []
    for x in xs:
        if isinstance(x, float) and not math.isnan(x):
            window = (window + [x])[-k:]
        out.append(statistics.fmean(window) if window else math.nan)
    return out


def plot(args, path: Path, stat: str | None = None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from volleybots.tasks import TASKS as ENVS

    data = curves(args, stat)
    fig, axes = plt.subplots(len(SPACES), len(args.tasks), figsize=(max(4.2 * len(args.tasks), 8.0), 6.5), squeeze=False)
    colors = {"dqn": "tab:red", "ddpg": "tab:blue", "td3": "tab:green", "sac": "tab:purple", "ppo": "tab:orange"}
    for j, task in enumerate(args.tasks):
        for i, space in enumerate(SPACES):
            draw_panel(
                axes[i][j], data.get((task, space), {}), colors, f"{TITLES[task]} ({space.upper()})",
                f"train episodes: {stat or ENVS[task].metric}", label=lambda a: f"{a.upper()}{' (discrete)' if a == 'dqn' else ''}",
            )
    save_figure(fig, axes, path, f"{int(args.frames):,} env steps x {len(args.seeds)} seeds, {args.num_envs} envs (mean "
                                 f"over seeds, last 5 batches)")


@dataclasses.dataclass
class RunArgs:
    """The options of a benchmark's runs (budget, seeds, off-policy scaling, device, parallelism); table 2
    takes them too, with its own defaults."""

    seeds: list[int] = option(help="seeds of every run", factory=lambda: [0, 1])
    frames: float = option(1e5, "env steps per run", gt=0)
    num_envs: int = option(64, "parallel envs per run", ge=1)
    batch_size: int = option(1024, "off-policy sampling batch (paper: 4096)", ge=1)
    tau: float = option(0.05, "off-policy target Polyak factor (paper: 0.005, see the docstring)", gt=0, le=1)
    eval_episodes: int = option(32, "final deterministic evaluation episodes per run", ge=1)
    device: str = option("cpu", "torch device of env and networks")
    threads: int = option(1, "torch threads per run", ge=1)
    jobs: int = option(1, "runs trained at the same time (processes)", ge=1)
    out: str = option("outputs/table1", "folder of the runs and the results")


def run_all(run_one, todo, args) -> None:
    """``run_one(job, args)`` for every job, ``args.jobs`` processes at a time."""
    print(f"# {len(todo)} runs of {int(args.frames):,} env steps, {args.num_envs} envs, {args.jobs} at a time", file=sys.stderr)
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs, mp_context=get_context("spawn")) as pool:
            list(pool.map(_skip_in_use, [run_one] * len(todo), todo, [args] * len(todo)))
    else:
        for job in todo:
            _skip_in_use(run_one, job, args)


def _skip_in_use(run_one, job, args) -> dict | None:
    """``run_one(job, args)``, or None with one line where another process is training that run."""
    from volleybots.runs import InUseError

    try:
        return run_one(job, args)
    except InUseError as e:
        print(f"  skipped {job}: {e}", file=sys.stderr, flush=True)
        return None


@dataclasses.dataclass
class Args(RunArgs):
    tasks: list[str] = option(help="tasks", factory=lambda: list(TASKS), choices=TASKS)
    algos: list[str] = option(help="algorithms", factory=lambda: list(ALGOS), choices=ALGOS)
    spaces: list[str] = option(help="continuous action spaces", factory=lambda: list(SPACES), choices=SPACES)
    target_update_interval: int = option(1, "off-policy gradient steps between target updates (paper: 4)", ge=1)


def main(argv=None) -> int:
    args = script_options(Args, argv, __doc__)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    run_all(run_one, jobs(args), args)
    res, returns = collect_results(args), collect_results(args, "return")
    table, table_returns = format_table(res, args), format_table(returns, args)
    (out / "table1.json").write_text(json.dumps({"args": dataclasses.asdict(args), "metric": res, "return": returns}, indent=1) + "\n")
    (out / "table1.md").write_text(f"Task metric:\n\n{table}\n\nEpisode return:\n\n{table_returns}\n")
    print(f"task metric:\n{table}\n\nepisode return:\n{table_returns}")
    try:
        plot(args, out / "table1.png")
        plot(args, out / "table1_return.png", "return")
    except ImportError:
        print("matplotlib is not installed: no figure (pip install 'volleybots[plot]')", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
