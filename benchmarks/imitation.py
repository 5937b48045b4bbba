"""Imitation then RL fine-tuning, per task, on a wall-clock budget (issue 18; docs/imitation.md).

For each task: ``algo=bc`` clones the scripted player for ``bc_minutes=``, then PPO (MAPPO on the
cooperative tasks) starts from the bc run (``init=``) with the fine-tuning recipe of docs/imitation.md
for ``ft_minutes=``. The teacher, the clone and the fine-tuned policy then play the same
``episodes=`` episodes on a held-out seed (``eval_seed=``, never used by training, whose own
periodic evaluations use seed + 10000). Writes a JSON of the figures and curves, a PNG of the
fine-tuning curves, and prints a Markdown table:

    python benchmarks/imitation.py tasks=solo_bump bc_minutes=6 ft_minutes=15
    python benchmarks/imitation.py tasks=[solo_bump,hit_the_ball,bump_and_pass,set_and_spike_easy] \\
        bc_minutes=20 ft_minutes=40                        # the issue's 60 minutes per task
    python benchmarks/imitation.py tasks=1v1 opponent=scripted   # a match: both runs seated against it

Each run keeps ``best.pt``, the policy of its best periodic evaluation (seed + 10000, never the
held-out seed): the fine-tuning starts from the clone's, and both the final and the best policy of
the fine-tuning are scored on the held-out seed. On a match the held-out score is the decisive-game
win rate against ``opponent=`` over ``games=`` games (cross-play, each side serving half).

Needs matplotlib (``pip install 'volleybots[plot]'``).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from volleybots.config.args import option, script_options

# the fine-tuning recipes (docs/imitation.md). PPO / MAPPO: a critic warm-up, then a slow, tightly
# clipped actor. SAC (a residual on the clone, critic warm-up by default): a slow actor, held near the
# clone (TD3+BC's weight: about mean |Q| / 2.5), aiming at about the entropy it starts with.
FINE_TUNE = {
    "sac": ["algo.actor_lr=5e-5", "algo.guide_coeff=10", "algo.target_entropy_scale=-1.25"],
}
LEARNERS = ("ppo", "mappo", *FINE_TUNE)  # PPO / MAPPO: the package's recipe (volleybots.algos.ppo.FINE_TUNE; stage I uses it too)


def fine_tune(algo: str) -> list[str]:
    """The fine-tuning overrides of ``algo``; PPO's are imported when a run needs them, so help stays fast."""
    if algo in ("ppo", "mappo"):
        from volleybots.algos.ppo import FINE_TUNE as PPO_FINE_TUNE

        return list(PPO_FINE_TUNE)
    return list(FINE_TUNE[algo])


def learner(task: str, choice: str = "auto") -> str:
    """The fine-tuning algorithm: ``choice``, or with ``auto`` PPO (MAPPO with several drones)."""
    from volleybots.algos.base import class_attr
    from volleybots.tasks import TASKS

    if choice != "auto":
        return choice
    return "ppo" if class_attr(TASKS[task], "n_drones") == 1 else "mappo"


def competitive(task: str) -> bool:
    from volleybots.algos.base import class_attr
    from volleybots.tasks import TASKS

    return class_attr(TASKS[task], "competitive")


def common(args, task: str, minutes: float) -> list[str]:
    return [
        *([f"opponent={args.opponent}"] if competitive(task) else []),
        f"task={task}", f"env.action_space={args.action_space}", f"env.num_envs={args.num_envs}", f"seed={args.seed}",
        f"threads={args.threads}", f"time_limit={minutes * 60}", "total_frames=1e12", f"evaluation.every={args.eval_every}",
        f"evaluation.episodes={args.eval_episodes}", "evaluation.record=false", "checkpoint.every=0", "progress=false",
    ]


def curve(run: Path, metric: str) -> list[dict]:
    from volleybots.runs import read_metrics

    return [
        {"minutes": r["wall_time"] / 60, "frames": r["frames"], metric: r[f"eval_{metric}"]}
        for r in read_metrics(run / "metrics.csv")
        if r["phase"] == "eval"
    ]


def policy_of(run: Path) -> Path:
    """A run's best.pt (its best periodic evaluation), else the run itself (final.pt)."""
    best = run / "checkpoints" / "best.pt"
    return best if best.is_file() else run


def held_out(target: str, args, task: str, metric: str) -> dict:
    from volleybots.eval import evaluate

    if competitive(task):
        return held_out_games(target, args, task)

    extra = [f"task={task}", f"env.action_space={args.action_space}"] if target in ("scripted", "random") else []
    res = evaluate(target, [*extra, *held_out_overrides(args, task)], episodes=args.episodes)
    return {"mean": res["stats"][metric]["mean"], "std": res["stats"][metric]["std"], "return": res["stats"]["return"]["mean"]}


def held_out_overrides(args, task: str) -> list[str]:
    """The held-out seed and the task's own episodes, whatever a run trained on (a shorter episode
    limit or Solo Bump's far starts in ft_overrides=)."""
    import dataclasses

    from volleybots.config import task_schema

    own = [
        "task.episode_len=null",
        *(["task.far_starts=0"] if "far_starts" in {f.name for f in dataclasses.fields(task_schema(task))} else []),
    ]
    return [f"seed={args.eval_seed}", f"threads={args.threads}", *own]


def paired_held_out(targets: dict[str, str], args, task: str) -> dict:
    """The teacher and ``targets`` (name -> run or checkpoint) on the same held-out episodes, each
    compared with the teacher episode by episode (``volleybots eval compare``)."""
    from volleybots.eval.compare import compare

    res = compare(["scripted", *targets.values(), f"episodes={args.episodes}", *held_out_overrides(args, task)])
    rows = dict(zip(["scripted", *targets], res["targets"], strict=True))
    return {
        k: {
            "mean": r["mean"],
            "std": r["std"],
            "return": None,
            "per_episode": r["per_episode"],
            **({"vs_teacher": r["vs_baseline"]} if "vs_baseline" in r else {}),
        }
        for k, r in rows.items()
    }


def scripted_held_out(args, task: str, metric: str) -> dict:
    """The teacher on the held-out episodes, or its figures from ``scripted_from=`` (a JSON of
    ``benchmarks/scripted.py seed=EVAL_SEED``: the same 100 episodes; the cooperative teachers'
    lookahead makes playing them again cost ~20 minutes of a core)."""
    if args.scripted_from and not competitive(task):
        rows = [
            r
            for r in json.loads(Path(args.scripted_from).read_text())["episodes"]
            if r["task"] == task and r["action_space"] == args.action_space and r["episodes"] == args.episodes
        ]
        if rows:
            return {"mean": rows[0]["mean"], "std": rows[0]["std"], "return": None, "from": args.scripted_from}
    return held_out("scripted", args, task, metric)


def held_out_games(target: str, args, task: str) -> dict:
    """Decisive-game win rate of ``target`` (mean actions) against ``opponent=`` on the held-out seed."""
    from volleybots.eval.crossplay import crossplay, match_config, resolve_all

    comps = resolve_all([f"learner={target}" if target not in ("scripted", "random") else target, f"opponent={args.opponent}"])
    cfg = match_config(comps, [f"task={task}", f"env.action_space={args.action_space}", f"threads={args.threads}"])
    res = crossplay(cfg, comps, games=args.games, seed=args.eval_seed, deterministic=True)
    (w, d, l_), (lo, hi) = res.wdl[0, 1], (x[0, 1] for x in res.interval())
    return {"mean": float(res.win_rate()[0, 1]), "std": float("nan"), "wilson95": [float(lo), float(hi)], "wdl": [int(w), int(d), int(l_)]}


def run_task(task: str, args, root: Path) -> dict:
    from volleybots.config import load
    from volleybots.tasks import TASKS
    from volleybots.train import train

    metric = TASKS[task].metric
    algo = learner(task, args.learner)
    bc_dir, ft_dir = root / f"{task}_bc", root / f"{task}_{algo}"
    if args.bc_dir:  # fine-tune a clone made before (one task)
        bc_dir = Path(args.bc_dir)
        bc = json.loads((bc_dir / "summary.json").read_text())
    else:
        bc = train(load([*common(args, task, args.bc_minutes), "algo=bc", *args.bc_overrides]), bc_dir)
    if args.ft_dir:  # evaluate a fine-tuning run made before
        ft_dir = Path(args.ft_dir)
        ft = json.loads((ft_dir / "summary.json").read_text())
    else:
        init = policy_of(bc_dir)
        ft = train(
            load([*common(args, task, args.ft_minutes), f"algo={algo}", f"init={init}", *fine_tune(algo), *args.ft_overrides]), ft_dir
        )
    runs = {"bc": str(policy_of(bc_dir)), "fine_tuned_final": str(ft_dir), "fine_tuned": str(policy_of(ft_dir))}
    if args.paired and not competitive(task):
        played = paired_held_out(runs, args, task)
    else:
        played = {"scripted": scripted_held_out(args, task, metric), **{k: held_out(v, args, task, metric) for k, v in runs.items()}}
    return {
        "task": task,
        "metric": metric,
        "wall_s": bc["wall_time_s"] + ft["wall_time_s"],  # training only; the held-out evaluations come on top
        "bc": {"run_dir": str(bc_dir), "frames": bc["frames"], "wall_s": bc["wall_time_s"], "curve": curve(bc_dir, metric)},
        "fine_tune": {
            "run_dir": str(ft_dir),
            "algo": algo,
            "frames": ft["frames"],
            "wall_s": ft["wall_time_s"],
            "curve": curve(ft_dir, metric),
        },
        "held_out": {
            "seed": args.eval_seed,
            "episodes": args.episodes,
            "random": held_out("random", args, task, metric),
            **played,
            "chosen": {"bc": bc.get("best_eval"), "fine_tuned": ft.get("best_eval")},  # on seed + 10000
        },
    }


def plot(results: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(results), figsize=(5.5 * len(results), 4), squeeze=False)
    for ax, res in zip(axes[0], results, strict=True):
        m, bc_end = res["metric"], res["bc"]["wall_s"] / 60
        ax.plot([p["minutes"] for p in res["bc"]["curve"]], [p[m] for p in res["bc"]["curve"]], marker="o", label="bc")
        ax.plot(
            [bc_end + p["minutes"] for p in res["fine_tune"]["curve"]],
            [p[m] for p in res["fine_tune"]["curve"]],
            marker="o",
            label=f"{res['fine_tune']['algo']} from bc",
        )
        ax.axhline(res["held_out"]["scripted"]["mean"], color="grey", ls="--", label="scripted (held-out seed)")
        ax.set(title=res["task"], xlabel="minutes (2 shared CPU cores)", ylabel=f"{m} (periodic evaluation)")
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def table(results: list[dict]) -> str:
    lines = [
        "| task | metric | random | scripted (teacher) | bc (best) | fine-tuned (final) | fine-tuned (best) | bc / "
        "fine-tune frames | minutes |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        h = r["held_out"]

        def cell(k, h=h):
            if k not in h:
                return "-"
            if "wdl" in h[k]:  # a match: decisive win rate [Wilson 95 %] (W/D/L)
                return f"{h[k]['mean']:.3f} [{h[k]['wilson95'][0]:.2f}, {h[k]['wilson95'][1]:.2f}] ({'/'.join(map(str, h[k]['wdl']))})"
            c = h[k].get("vs_teacher")  # paired with the teacher: mean improvement [95 % interval]
            return f"{h[k]['mean']:.3g} +- {h[k]['std']:.2g}" + (f" ({c['diff']:+.3g} [{c['low']:+.3g}, {c['high']:+.3g}])" if c else "")

        lines.append(
            f"| {r['task']} | {r['metric']} | {cell('random')} | {cell('scripted')} | {cell('bc')} | "
            f"{cell('fine_tuned_final')} | {cell('fine_tuned')} | "
            f"{r['bc']['frames']:,} / {r['fine_tune']['frames']:,} | {r['wall_s'] / 60:.0f} |"
        )
    return "\n".join(lines)


@dataclass
class Args:
    tasks: list[str] = option(help="the tasks", factory=lambda: ["solo_bump"])
    action_space: str = option("prt", "the action space")
    bc_minutes: float = option(20.0, "wall-clock minutes of each bc run")
    ft_minutes: float = option(40.0, "wall-clock minutes of each fine-tuning run")
    num_envs: int = option(256, "worlds stepped together")
    seed: int = option(0, "the seed")
    threads: int = option(1, "torch threads")
    eval_every: int = option(200_000, "frames between periodic evaluations")
    eval_episodes: int = option(32, "episodes of each evaluation")
    eval_seed: int = option(1000, "held-out seed of the final 100-episode comparison")
    episodes: int = option(100, "episodes played")
    paired: bool = option(False, "play the teacher too and compare every policy with it episode by episode (eval compare)")
    scripted_from: Optional[str] = option(None, "the teacher's held-out figures from this benchmarks/scripted.py JSON (run on eval_seed=)")
    opponent: str = option("scripted", "matches: whom both runs and the held-out games play against")
    games: int = option(1000, "matches: held-out games against opponent=")
    bc_overrides: list[str] = option(help="extra overrides of the bc runs (algo.replay_ratio=8 ...)", factory=lambda: [])
    bc_dir: Optional[str] = option(None, "a finished bc run of the (one) task to fine-tune instead of a new one")
    ft_dir: Optional[str] = option(None, "a finished fine-tuning run of the (one) task to evaluate instead of a new one")
    learner: str = option("auto", "the fine-tuning algorithm (auto: PPO, MAPPO with several drones)", choices=["auto", *LEARNERS])
    ft_overrides: list[str] = option(help="extra overrides of the fine-tuning runs", factory=lambda: [])
    root: str = option("outputs/imitation", "where the runs go")
    out: str = option("results/imitation/imitation.json", "where the results go")
    png: str = option("results/imitation/imitation.png", "the figure's file")
    combine: list[str] = option(help="JSONs of earlier invocations: write their results together to out=/ png=", factory=lambda: [])


def main() -> None:
    args = script_options(Args, None, __doc__)
    if args.combine:
        parts = [json.loads(Path(f).read_text()) for f in args.combine]
        results = [r for part in parts for r in part["results"]]
        Path(args.out).write_text(json.dumps({"runs": [part["args"] for part in parts], "results": results}, indent=2) + "\n")
        plot(results, Path(args.png))
        print(table(results))
        return
    root = Path(args.root) / time.strftime("%Y%m%d-%H%M%S")
    results = []
    for task in args.tasks:
        results.append(run_task(task, args, root))
        Path(args.out).write_text(
            json.dumps({"args": vars(args), "results": results}, indent=2) + "\n"
        )  # after each task: a partial result survives
    plot(results, Path(args.png))
    print(table(results))


if __name__ == "__main__":
    main()
