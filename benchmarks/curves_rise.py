"""Curves that rise: the SB3 and CleanRL-style examples on Hover, two seeds each, their learning
curves (the task's metric, Hover's mean distance to the target, against env-steps) as CSV and one
figure for docs/integrations.md.

    python benchmarks/curves_rise.py                       # runs the four trainings (two at a time), then plots
    python benchmarks/curves_rise.py --plot-only           # the figure again from the CSVs
    cp results/integrations/curves/curves_rise.png docs/img/  # the copy docs/integrations.md shows

Each training is the example's own command (``examples/sb3_ppo_hover.py``,
``examples/cleanrl_ppo_solo_bump.py --env-id volleybots/Hover-v0``), run as a child process with one
torch thread; ``--parallel`` of them at once (the machine's two cores). The JSON beside the CSVs holds
each command, its seed, its wall time and the load average (``os.getloadavg``) before and after it.
"""

from __future__ import annotations

import csv
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from volleybots.config.args import option, script_options

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "results" / "integrations" / "curves"
FIGURE = OUT / "curves_rise.png"  # docs/img/curves_rise.png is a copy (no benchmark writes into docs/)
STEPS = 1_000_000  # env-steps per training: minutes on one core, and Hover's distance has fallen by then
SEEDS = (0, 1)


def commands(steps: int) -> dict[str, list[str]]:
    """Each example's command line, ``{seed}`` and ``{curve}`` left to fill."""
    return {
        "sb3": ["examples/sb3_ppo_hover.py", "--total-timesteps", str(steps), "--seed", "{seed}", "--curve", "{curve}"],
        "cleanrl": ["examples/cleanrl_ppo_solo_bump.py", "--env-id", "volleybots/Hover-v0", "--num-envs", "64", "--num-steps", "64",
                    "--total-timesteps", str(steps), "--seed", "{seed}", "--curve", "{curve}"],
    }


def _start(name: str, argv: list[str], seed: int) -> dict:
    curve = OUT / f"{name}_hover_seed{seed}.csv"
    args = [a.format(seed=seed, curve=curve.relative_to(ROOT)) for a in argv]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(ROOT)}  # the examples import this checkout
    log = open(OUT / f"{name}_hover_seed{seed}.log", "w")
    proc = subprocess.Popen([sys.executable, *args], cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT)
    return {"name": name, "seed": seed, "command": "python " + " ".join(args), "proc": proc, "log": log,
            "start": time.time(), "load_before": list(os.getloadavg())}


def run_all(steps: int, parallel: int) -> list[dict]:
    """The trainings, ``parallel`` at a time; each one's command, wall time and load."""
    OUT.mkdir(parents=True, exist_ok=True)
    todo = [(name, argv, seed) for name, argv in commands(steps).items() for seed in SEEDS]
    running, done = [], []
    while todo or running:
        while todo and len(running) < parallel:
            running.append(_start(*todo.pop(0)))
        time.sleep(2)
        for job in [j for j in running if j["proc"].poll() is not None]:
            running.remove(job)
            job["log"].close()
            if job["proc"].returncode != 0:
                raise SystemExit(f"{job['command']} failed; see {job['log'].name}")
            done.append({"name": job["name"], "seed": job["seed"], "command": job["command"],
                         "wall_s": round(time.time() - job["start"], 1), "load_before": job["load_before"],
                         "load_after": list(os.getloadavg())})
            print(f"{job['name']} seed {job['seed']}: {done[-1]['wall_s']:.0f} s, load {done[-1]['load_after'][0]:.1f}")
    return done


def read_curve(path: Path) -> dict[str, list[float]]:
    with open(path) as fh:
        rows = list(csv.DictReader(fh))
    return {k: [float(r[k]) for r in rows] for k in rows[0]}


def plot(runs: list[dict] | None = None) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6), sharey=True)
    walls = {(r["name"], r["seed"]): r["wall_s"] for r in runs or []}
    for ax, (name, title) in zip(axes, (("sb3", "SB3 PPO (examples/sb3_ppo_hover.py)"),
                                        ("cleanrl", "CleanRL-style PPO (examples/cleanrl_ppo_solo_bump.py)")), strict=True):
        for seed, colour in zip(SEEDS, ("tab:blue", "tab:orange"), strict=True):
            c = read_curve(OUT / f"{name}_hover_seed{seed}.csv")
            wall = walls.get((name, seed), c["seconds"][-1])
            ax.plot([s / 1e6 for s in c["steps"]], c["distance"], color=colour, label=f"seed {seed} ({wall / 60:.1f} min)")
        ax.set(title=title, xlabel="env-steps (millions)")
        ax.title.set_fontsize(9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_ylabel("Hover: mean distance to target (m)\nlast 20 episodes, lower is better")
    fig.tight_layout()
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(FIGURE, dpi=100)
    plt.close(fig)
    return FIGURE


@dataclass
class Args:
    steps: int = option(STEPS, "environment steps of each training")
    parallel: int = option(2, "trainings at once")
    plot_only: bool = option(False, "redraw the figure from the summary already written")


def main(argv=None) -> None:
    args = script_options(Args, argv, __doc__)
    from volleybots.files import read_json, write_json

    summary = OUT / "curves_rise.json"
    if args.plot_only:
        runs = read_json(summary, "the curves summary")["runs"] if summary.is_file() else None
    else:
        runs = run_all(args.steps, args.parallel)
        for r in runs:
            c = read_curve(OUT / f"{r['name']}_hover_seed{r['seed']}.csv")
            r["distance_first"], r["distance_last"] = c["distance"][0], c["distance"][-1]
            r["return_first"], r["return_last"] = c["return"][0], c["return"][-1]
        write_json(summary, {"task": "hover", "steps": args.steps, "seeds": list(SEEDS), "cpu_count": os.cpu_count(), "runs": runs})
    print(f"wrote {plot(runs)}")


if __name__ == "__main__":
    main()
