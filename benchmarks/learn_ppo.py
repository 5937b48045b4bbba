"""PPO on Solo Bump with CTBR and PRT actions: the task metric over wall time, and end-to-end speed.

Targets (issue 3): with CTBR, >= 8.58 bumps (paper table 1) within 60 minutes, and >= 50k env-steps/s
end to end (collection + update). Each action space trains for ``minutes=`` of wall time (the run
loop's ``time_limit``), evaluating every ``eval_every=`` frames. The script writes a PNG of the
curves and a JSON of the figures, and prints a Markdown table:

    python benchmarks/learn_ppo.py                                 # the full benchmark, 2 x 60 min
    python benchmarks/learn_ppo.py minutes=5 num_envs=1024     # a short version
    python benchmarks/learn_ppo.py device=cuda num_envs=4096   # on a GPU

    python benchmarks/learn_ppo.py diagnose=[RUN_OR_CHECKPOINT,...]   # what a policy does instead of bumping

``diagnose=`` plays 64 episodes (held-out seed 1000) with each given policy and reports where its
return comes from (per reward term), how it ends its episodes, its hits, the share of them struck
farther than 1 m from the anchor (which the metric does not count and the reward does not punish),
the apexes of at least 3.5 m, and how long it carries the ball (resting on the racket: within the
racket's radius sideways, at most 0.3 m above the drone, moving with it to 0.3 m/s).

Needs matplotlib (``pip install 'volleybots[plot]'``).
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path

from volleybots.config.args import option, script_options

TARGET_BUMPS = 8.58
TARGET_FPS = 50_000


def run(space: str, args, root: Path) -> dict:
    from volleybots.config import load
    from volleybots.runs import read_metrics
    from volleybots.train import train

    overrides = [
        "task=solo_bump", "algo=ppo", f"env.action_space={space}", f"env.num_envs={args.num_envs}", f"env.device={args.device}",
        f"env.compile={str(args.compile).lower()}", f"seed={args.seed}", f"threads={args.threads}",
        f"time_limit={args.minutes * 60}", "total_frames=1e12", f"evaluation.every={args.eval_every}",
        f"evaluation.episodes={args.eval_episodes}", "evaluation.record=false", f"checkpoint.every={args.eval_every * 10}",
        f"progress={str(args.progress).lower()}", *args.overrides,
    ]
    cfg = load(overrides)
    run_dir = root / f"{space}_{time.strftime('%Y%m%d-%H%M%S')}"
    summary = train(cfg, run_dir)
    rows = read_metrics(run_dir / "metrics.csv")
    train_rows = [r for r in rows if r["phase"] == "train"]
    evals = [(r["wall_time"], r["frames"], r["eval_bumps"]) for r in rows if r["phase"] == "eval"]
    reached = next((t for t, _, b in evals if b >= TARGET_BUMPS), None)
    return {
        "action_space": space,
        "run_dir": str(run_dir),
        "frames": summary["frames"],
        "wall_s": summary["wall_time_s"],
        "env_steps_per_s": summary["frames_per_s"],  # end to end: collection, update, logging, evaluation
        "train_env_steps_per_s": _median([r["fps"] for r in train_rows]),  # one batch: collection + update
        "best_eval_bumps": max((b for _, _, b in evals), default=math.nan),
        "final_eval_bumps": summary["final_eval"]["stats"]["bumps"]["mean"],
        "minutes_to_target": None if reached is None else reached / 60,
        "curve": {
            "eval": [{"minutes": t / 60, "frames": f, "bumps": b} for t, f, b in evals],
            "train": [
                {"minutes": r["wall_time"] / 60, "frames": r["frames"], "return": r["return"], "bumps": r["bumps"]} for r in train_rows
            ],
        },
    }


def diagnose(target: str, episodes: int = 64, seed: int = 1000) -> dict:
    """Where a Solo Bump policy's return comes from and what it does with the ball (module docstring)."""
    import torch

    from volleybots.config import make_env
    from volleybots.play import run_episodes
    from volleybots.policies import BUILTIN as POLICY_NAMES
    from volleybots.policies import resolve_target

    t = resolve_target(target, [*(["task=solo_bump"] if target in POLICY_NAMES else []), f"seed={seed}", "threads=1"])
    env = make_env(t.cfg, num_envs=episodes, seed=seed)
    n = env.num_envs
    live = torch.ones(n, dtype=torch.bool)
    carry, steps, apex_after_hit = torch.zeros(n), torch.zeros(n), torch.zeros(n)
    far_hits, last_hits = torch.zeros(n), torch.zeros(n)
    ends = {"ball_low": 0, "ball_high": 0, "drone_low_or_high": 0, "wrong_hit_or_ball_out": 0, "time_limit": 0}

    def on_step(env, td, nxt):
        s = env.physics.state
        rel = s.ball_pos - s.pos[:, 0]
        on = (
            (rel[:, :2].norm(dim=-1) < env.params.drone.racket_radius)
            & (rel[:, 2] > 0)
            & (rel[:, 2] < 0.3)
            & ((s.ball_vel - s.vel[:, 0]).norm(dim=-1) < 0.3)
        )
        carry.add_(on.float() * live)
        steps.add_(live.float())
        hits_now = env.referee.hits[:, 0].float()
        new_hit = live & (hits_now > last_hits)
        far_hits.add_((new_hit & ~env.hit_ok).float())  # the metric counts no bump hit farther than 1 m from the anchor
        last_hits.copy_(torch.where(live, hits_now, last_hits))
        hit_before = env.referee.hits[:, 0] > 0
        apex_after_hit.copy_(torch.where(live & hit_before, torch.maximum(apex_after_hit, s.ball_pos[:, 2]), apex_after_hit))
        done = nxt["done"].reshape(n) & live
        if done.any():
            term = nxt["terminated"].reshape(n)
            bz = s.ball_pos[:, 2]
            for i in done.nonzero().flatten().tolist():
                if not term[i]:
                    ends["time_limit"] += 1
                elif bz[i] > 4.5:
                    ends["ball_high"] += 1
                elif bz[i] < 0.2:
                    ends["ball_low"] += 1
                elif not (0.4 <= float(s.pos[i, 0, 2]) <= 2.5):
                    ends["drone_low_or_high"] += 1
                else:
                    ends["wrong_hit_or_ball_out"] += 1  # a second touch within 25 steps, a body hit, the ball out of court
        live.mul_(~done)

    res = run_episodes(env, t.make_policy(env), on_step=on_step)
    hits = res["hits"]
    return {
        "target": t.label,
        "episodes": n,
        "seed": seed,
        "bumps": float(res["bumps"].mean()),
        "return": float(res["return"].mean()),
        "return_terms": {k[2:]: float(v.mean()) for k, v in res.items() if k.startswith("r_")},
        "episode_len": float(steps.mean()),
        "hits_per_episode": float(hits.mean()),
        "episodes_with_a_hit": float((hits > 0).float().mean()),
        "apex_after_first_hit_m": float(apex_after_hit[hits > 0].mean()) if bool((hits > 0).any()) else None,
        "carry_share_of_steps": float(carry.sum() / steps.sum()),
        "hits_farther_than_1m_from_anchor": float(far_hits.sum() / hits.sum().clamp_min(1)),
        "apexes_at_least_3_5m_per_episode": float(res["r_success_height"].mean()) / env.height_reward,  # paid once per such apex
        "ends": ends,
    }


def _median(xs):
    xs = sorted(x for x in xs if isinstance(x, float))
    return xs[len(xs) // 2] if xs else math.nan


def plot(results: list[dict], path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4))
    for res in results:
        ev, tr = res["curve"]["eval"], res["curve"]["train"]
        label = f"{res['action_space']} ({res['env_steps_per_s']:,.0f} env-steps/s)"
        ax1.plot([e["minutes"] for e in ev], [e["bumps"] for e in ev], marker="o", label=label)
        ax2.plot([t["minutes"] for t in tr], [t["return"] for t in tr], label=res["action_space"])
    ax1.axhline(TARGET_BUMPS, color="grey", ls="--", label=f"paper CTBR ({TARGET_BUMPS})")
    ax1.set(xlabel="wall time (min)", ylabel="bumps (evaluation, deterministic)", title="Solo Bump: metric")
    ax2.set(xlabel="wall time (min)", ylabel="episode return (training)", title="Solo Bump: return")
    ax1.legend()
    ax2.legend()
    fig.suptitle(title)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


@dataclass
class Args:
    minutes: float = option(60.0, "wall-clock budget per action space")
    spaces: list[str] = option(help="action spaces to train", factory=lambda: ["ctbr", "prt"])
    num_envs: int = option(4096, "worlds stepped together")
    device: str = option("cpu", "torch device")
    compile: bool = option(False, "torch.compile the physics")
    threads: int = option(0, "torch CPU threads (0: default)")
    seed: int = option(0, "the seed")
    eval_every: int = option(2_000_000, "frames between evaluations")
    eval_episodes: int = option(64, "episodes of each evaluation")
    progress: bool = option(False, "print the runs' progress")
    runs: Path = option(Path("outputs/bench_learn_ppo"), "where the run directories go")
    out: Path = option(Path("results/training/learn_ppo.png"), "PNG of the curves (a .json goes beside it)")
    overrides: list[str] = option(help="further config overrides, e.g. algo.obs_norm=true", factory=lambda: [], positional=True)
    diagnose: list[str] = option(help="runs or checkpoints to diagnose instead of training", factory=lambda: [])


def main() -> None:
    args = script_options(Args, None, __doc__)
    if args.diagnose:
        import torch

        torch.set_num_threads(max(args.threads, 1))
        print(json.dumps([diagnose(t) for t in args.diagnose], indent=1))
        return

    results = [run(space, args, args.runs) for space in args.spaces]
    import torch

    title = f"PPO, {args.num_envs} envs on {args.device} ({torch.get_num_threads()} threads), {args.minutes:g} min per action space"
    plot(results, args.out, title)
    meta = {
        "title": title,
        "targets": {"bumps_ctbr": TARGET_BUMPS, "env_steps_per_s": TARGET_FPS},
        "args": {k: str(v) for k, v in vars(args).items()},
    }
    args.out.with_suffix(".json").write_text(json.dumps({**meta, "results": results}, indent=1) + "\n")
    print(f"\n{title}\n")
    print("| action space | frames | wall (min) | env-steps/s end to end | best eval bumps | minutes to 8.58 |")
    print("|---|---|---|---|---|---|")
    for r in results:
        reach = "-" if r["minutes_to_target"] is None else f"{r['minutes_to_target']:.1f}"
        print(
            f"| {r['action_space']} | {r['frames']:,} | {r['wall_s'] / 60:.1f} | {r['env_steps_per_s']:,.0f} | "
            f"{r['best_eval_bumps']:.2f} | {reach} |"
        )
    print(f"\nwrote {args.out} and {args.out.with_suffix('.json')}")


if __name__ == "__main__":
    main()
