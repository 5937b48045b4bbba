"""1v1 self-play, fictitious self-play, PSRO-uniform and PSRO-Nash on one budget (issue 14's benchmark).

Each method trains with the same env count, batch and frame budget (``frames=``) on seed ``seed=``;
the script records the population size, the oracles' updates and convergence, the final meta-strategy,
the end-to-end frames per second, and copies each run's payoff PNG into ``out=``. The run dirs feed
the evaluation's table-3 layout (``volleybots eval crossplay`` over them).

    python benchmarks/competitive.py                                  # the default budget
    python benchmarks/competitive.py frames=2e6 num_envs=256      # longer
"""

from __future__ import annotations

import json
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

from volleybots.config.args import option, script_options

METHODS = ("sp", "fsp", "psro_uniform", "psro_nash")


def run(method: str, args, root: Path) -> dict:
    from volleybots.config import load
    from volleybots.population.run import start

    cfg = load([
        "task=1v1", f"algo={method}", f"env.num_envs={args.num_envs}", f"seed={args.seed}", f"threads={args.threads}",
        f"total_frames={int(args.frames)}", f"algo.iterations={args.iterations}", f"algo.max_updates={args.max_updates}",
        f"algo.min_updates={args.min_updates}", f"algo.payoff_games={args.games}", "evaluation.every=0", "evaluation.episodes=32",
        "evaluation.record=false", "progress=false",
        "algo.start=scratch",  # the from-scratch study of docs/competitive.md (the defaults now start from the clone)
        *args.overrides,
    ])
    run_dir = root / f"{method}_s{args.seed}_{time.strftime('%Y%m%d-%H%M%S')}"
    t0 = time.perf_counter()
    summary = start(cfg, run_dir)
    wall = time.perf_counter() - t0
    png = Path(args.out) / f"competitive_{method}_payoffs.png"
    shutil.copyfile(run_dir / "payoffs.png", png)
    return {
        "method": method, "run_dir": str(run_dir), "frames": summary["frames"], "wall_s": wall,
        "frames_per_s_end_to_end": summary["frames"] / wall, "population": summary["population"],
        "oracles": summary["oracles"], "png": str(png),
    }


@dataclass
class Args:
    methods: str = option(",".join(METHODS), "")
    frames: float = option(1.5e6, "env frames per method (all iterations together)")
    num_envs: int = option(128, "worlds stepped together")
    iterations: int = option(4, "population iterations")
    max_updates: int = option(40, "most updates of a best response per iteration")
    min_updates: int = option(10, "fewest updates of a best response per iteration")
    games: int = option(200, "games per payoff entry")
    seed: int = option(0, "the seed")
    threads: int = option(1, "torch threads")
    root: str = option("outputs/benchmarks/competitive", "where the runs go")
    out: str = option("results/competitive", "folder of competitive.json and the payoff heatmaps")
    overrides: list[str] = option(help="further config overrides", factory=lambda: [], positional=True)


def main() -> None:
    args = script_options(Args, None, __doc__)
    root = Path(args.root)
    root.mkdir(parents=True, exist_ok=True)
    rows = [run(m, args, root) for m in args.methods.split(",")]
    Path(args.out, "competitive.json").write_text(json.dumps({"args": vars(args), "rows": rows}, indent=1) + "\n")
    print("| method | frames | wall (s) | frames/s | members | meta-strategy | oracle updates (converged) |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        pop = r["population"]
        mix = ", ".join(f"{m} {w:.2f}" for m, w in zip(pop["members"], pop["mixture"], strict=True))
        ups = ", ".join(f"{o['updates']}{'*' if o.get('converged') else ''}" for o in r["oracles"])
        print(
            f"| {r['method']} | {r['frames']:,} | {r['wall_s']:.0f} | {r['frames_per_s_end_to_end']:,.0f} | "
            f"{len(pop['members'])} | {mix} | {ups} |"
        )


if __name__ == "__main__":
    main()
