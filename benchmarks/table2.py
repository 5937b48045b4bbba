"""Paper table 2 on a small budget: Bump and Pass, Set and Spike (Easy), Set and Spike (Hard) x without /
with reward shaping x QMIX, MADDPG, MAPPO, HAPPO, MAT; each cell the task metric's mean +- std over
seeds, and the frames per second each run reached end to end (collection, updates, evaluation).

Every run trains ``--frames`` env steps with ``--num-envs`` envs and the algorithm's own config (the
paper's hyperparameters), then plays ``--eval-episodes`` deterministic episodes with the final policy:
a seed's value is their mean metric. As in ``table1.py`` MADDPG's batch and target pace are scaled to
the budget (``--batch-size``, ``--tau`` every step: the paper's pace assumes ~1e6 gradient steps);
QMIX keeps its own (128 chunks of 64 steps, tau 0.005 every 4 steps) and acts in the discrete space.

    python benchmarks/table2.py                                   # the reduced version of docs/marl.md
    python benchmarks/table2.py frames=5e6 seeds=[0,1,2] num_envs=1024 device=cuda
    python benchmarks/table2.py tasks=bump_and_pass algos=[mappo,happo] shaping=on jobs=2

Runs live under ``--out`` as ``<task>_<shaping>_<algo>_s<seed>/`` (ordinary run directories); a run
that has its summary.json is not repeated, so an interrupted benchmark continues where it stopped.
Writes ``table2.json``, ``table2.md`` (metric, return and frames/s tables), ``table2.png`` and
``table2_return.png`` (learning curves: the training episodes' metric, or return, over frames, mean
over seeds) into ``--out``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import statistics
import sys
from pathlib import Path

from table1 import RunArgs, _cell, _smooth, draw_panel, finished_summary, mean_over_seeds, run_all, save_figure

from volleybots.config.args import option, script_options

TASKS = ("bump_and_pass", "set_and_spike_easy", "set_and_spike_hard")
SHAPING = ("off", "on")
ALGOS = ("qmix", "maddpg", "mappo", "happo", "mat")
# paper table 2 (5 seeds, 1e9 frames, 4096 envs): (without, with shaping) per task and algorithm
PAPER = {
    "bump_and_pass": {"qmix": (0.09, 0.09), "maddpg": (0.79, 0.84), "mappo": (11.32, 13.71), "happo": (7.95, 12.14), "mat": (7.39, 13.11)},
    "set_and_spike_easy": {"qmix": (0.02, 0.02), "maddpg": (0.22, 0.23), "mappo": (0.25, 0.99), "happo": (0.25, 0.98), "mat": (0.25, 0.89)},
    "set_and_spike_hard": {"qmix": (0.02, 0.02), "maddpg": (0.22, 0.22), "mappo": (0.25, 0.75), "happo": (0.25, 0.79), "mat": (0.25, 0.80)},
}
TITLES = {"bump_and_pass": "Bump and Pass", "set_and_spike_easy": "Set and Spike (Easy)", "set_and_spike_hard": "Set and Spike (Hard)"}
COLORS = {"qmix": "tab:red", "maddpg": "tab:blue", "mappo": "tab:green", "happo": "tab:purple", "mat": "tab:orange"}


def jobs(args) -> list[tuple[str, str, str, int]]:
    return [(t, s, a, seed) for t in args.tasks for s in args.shaping for a in args.algos for seed in args.seeds]


def _run_dir(args, job) -> Path:
    task, shaping, algo, seed = job
    return Path(args.out) / f"{task}_{shaping}_{algo}_s{seed}"


def run_one(job, args) -> dict:
    """Train and evaluate one run (in a worker process); returns its summary."""
    import torch

    from volleybots.config import load
    from volleybots.train import train

    task, shaping, algo, seed = job
    run_dir = _run_dir(args, job)
    done = finished_summary(run_dir)
    if done is not None:
        return done
    torch.set_num_threads(args.threads)
    overrides = [
        f"task={task}", f"algo={algo}", f"task.reward_shaping={'true' if shaping == 'on' else 'false'}", f"env.num_envs={args.num_envs}",
        f"env.device={args.device}", f"seed={seed}", f"threads={args.threads}", f"total_frames={int(args.frames)}", "progress=false",
        "checkpoint.every=0", "evaluation.every=0", f"evaluation.episodes={args.eval_episodes}", "evaluation.record=false",
    ]
    if algo == "maddpg":
        overrides += [
            f"algo.batch_size={args.batch_size}",
            f"algo.buffer_size={int(args.frames)}",
            f"algo.tau={args.tau}",
            "algo.target_update_interval=1",
        ]
    summary = train(load(overrides), run_dir)
    m = summary["final_eval"]["stats"][summary["metric"]]["mean"]
    print(
        f"  {task} shaping {shaping} {algo} seed {seed}: {summary['metric']} {m:.3f} ({summary['frames_per_s']:.0f} frames/s)",
        file=sys.stderr,
        flush=True,
    )
    return summary


def collect_results(args) -> dict:
    """{task: {algo: {shaping: {"metric": [...], "return": [...], "fps": [...]}}}} over seeds."""
    res: dict = {}
    for job in jobs(args):
        path = _run_dir(args, job) / "summary.json"
        if not path.is_file():
            continue
        s = json.loads(path.read_text())
        task, shaping, algo, _ = job
        cell = res.setdefault(task, {}).setdefault(algo, {}).setdefault(shaping, {"metric": [], "return": [], "fps": []})
        cell["metric"].append(s["final_eval"]["stats"][s["metric"]]["mean"])
        cell["return"].append(s["final_eval"]["stats"]["return"]["mean"])
        cell["fps"].append(s["frames_per_s"])
    return res


def format_table(res: dict, args, what: str = "metric", paper: bool = False) -> str:
    """Markdown in the layout of paper table 2 (``what``: metric, return or fps; ``paper``: its values)."""
    head = "| | " + " | ".join(f"{TITLES[t]} {'w.o.' if s == 'off' else 'w.'} shaping" for t in args.tasks for s in args.shaping) + " |"
    lines = [head, "|---" * (1 + len(args.tasks) * len(args.shaping)) + "|"]
    for algo in args.algos:
        cells = []
        for task in args.tasks:
            for shaping in args.shaping:
                if paper:
                    cells.append(f"{PAPER[task][algo][SHAPING.index(shaping)]:.2f}")
                    continue
                values = res.get(task, {}).get(algo, {}).get(shaping, {}).get(what, [])
                cells.append(f"{statistics.fmean(values):,.0f}" if what == "fps" and values else _cell(values))
        lines.append(f"| {algo.upper()} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def curves(args, key: str | None = None) -> dict:
    """{(task, shaping): {algo: (frames, mean over seeds of the smoothed training episodes' ``key``)}};
    ``key`` None is the task's metric."""
    from volleybots.runs import read_metrics
    from volleybots.tasks import TASKS as ENVS

    out: dict = {}
    for job in jobs(args):
        path = _run_dir(args, job) / "metrics.csv"
        if not path.is_file():
            continue
        task, shaping, algo, _ = job
        rows = [r for r in read_metrics(path) if r["phase"] == "train"]
        vals = _smooth([r.get(key or ENVS[task].metric, math.nan) for r in rows], 5)
        out.setdefault((task, shaping), {}).setdefault(algo, []).append(([r["frames"] for r in rows], vals))
    return mean_over_seeds(out)


def plot(args, path: Path, key: str | None = None) -> None:
    """Learning curves, one panel per task and shaping: the task's metric, or ``key`` (e.g. return)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from volleybots.tasks import TASKS as ENVS

    data = curves(args, key)
    fig, axes = plt.subplots(len(args.shaping), len(args.tasks), figsize=(4.4 * len(args.tasks), 3.4 * len(args.shaping)), squeeze=False)
    for j, task in enumerate(args.tasks):
        for i, shaping in enumerate(args.shaping):
            title = f"{TITLES[task]} ({'with' if shaping == 'on' else 'without'} shaping)"
            draw_panel(axes[i][j], data.get((task, shaping), {}), COLORS, title, f"train episodes: {key or ENVS[task].metric}")
    seeds = ",".join(map(str, args.seeds))
    save_figure(fig, axes, path, f"{int(args.frames):,} env steps x seeds {seeds}, {args.num_envs} envs (mean over seeds, last 5 batches)")


@dataclasses.dataclass
class Args(RunArgs):
    # table 2's budget; batch_size=, tau=: MADDPG's
    seeds: list[int] = option(help="seeds of every run", factory=lambda: [0])
    frames: float = option(2e4, "env steps per run", gt=0)
    eval_episodes: int = option(8, "final deterministic evaluation episodes per run", ge=1)
    out: str = option("outputs/table2", "folder of the runs and the results")
    tasks: list[str] = option(help="tasks", factory=lambda: list(TASKS), choices=TASKS)
    algos: list[str] = option(help="algorithms", factory=lambda: list(ALGOS), choices=ALGOS)
    shaping: list[str] = option(help="reward shaping off, on", factory=lambda: list(SHAPING), choices=SHAPING)


def main(argv=None) -> int:
    args = script_options(Args, argv, __doc__)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    run_all(run_one, jobs(args), args)
    res = collect_results(args)
    tables = {what: format_table(res, args, what) for what in ("metric", "return", "fps")}
    (out / "table2.json").write_text(json.dumps({"args": dataclasses.asdict(args), "results": res}, indent=1) + "\n")
    (out / "table2.md").write_text(
        f"Task metric:\n\n{tables['metric']}\n\nEpisode return:\n\n{tables['return']}\n\nFrames per second (end to "
        f"end):\n\n{tables['fps']}\n\n"
        f"Paper (5 seeds, 1e9 frames):\n\n{format_table(res, args, paper=True)}\n"
    )
    print(f"task metric:\n{tables['metric']}\n\nframes/s:\n{tables['fps']}")
    try:
        plot(args, out / "table2.png")
        plot(args, out / "table2_return.png", "return")  # finer than the metric where few episodes score
    except ImportError:
        print("matplotlib is not installed: no figure (pip install 'volleybots[plot]')", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
