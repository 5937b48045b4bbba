"""Scripted players on the multi-drone tasks (not a test: it takes minutes).

    python benchmarks/multi.py [episodes=100] [envs=50] [tasks=bump_and_pass,1v1,...] [device=cpu] [action_space=prt|ctbr]

For each cooperative task it runs the scripted pair for ``episodes=`` finished episodes and reports
the task metric (mean, std). For 1 vs 1 and 3 vs 3 (6 vs 6 with ``tasks=``) it plays the scripted
team against uniformly random actions, on both sides and with both servers, and reports wins, losses,
draws and the win rate of decisive games; then scripted against itself, reporting the share of
games with a rally of at least 3 touches and how the rallies ended. Targets (spec): Bump and Pass
>= 13.71 bumps, Set and Spike Easy >= 0.99 and Hard >= 0.80 success rate; scripted teams win >= 95 %
of decisive games against random and rally (>= 3 touches) in most games against themselves.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import torch

import volleybots
from volleybots.config.args import option, script_options
from volleybots.rules import Referee
from volleybots.scripted import make_scripted_policy
from volleybots.tasks.coop import ANCHOR_COEF
from volleybots.tasks.multi import TeamPolicies

COOP = ("bump_and_pass", "set_and_spike_easy", "set_and_spike_hard")
MATCHES = ("1v1", "3v3")


def random_policy(td):
    agents = td.get("agents")
    td.set(("agents", "action"), torch.rand(*agents.batch_size, 4, device=td.device) * 2 - 1)
    return td


def finished_episodes(env, policy, episodes: int, keys) -> dict[str, torch.Tensor]:
    """Step ``env`` under ``policy`` (auto-resetting) until every env has finished its first
    ``ceil(episodes / num_envs)`` episodes; the stats of ``episodes`` of them, taken by env index, not
    by when they ended: taking whichever episodes end first would favour short (failed) episodes."""
    per_env = -(-episodes // env.num_envs)
    got = {k: torch.zeros(per_env, env.num_envs, device=env.device) for k in keys}
    count = torch.zeros(env.num_envs, dtype=torch.long, device=env.device)
    td = env.reset()
    while bool((count < per_env).any()):
        td = policy(td)
        out, td = env.step_and_maybe_reset(td)
        done = out["next", "done"].reshape(-1) & (count < per_env)
        if done.any():
            idx = done.nonzero().squeeze(-1)
            for k in keys:
                got[k][count[idx], idx] = out["next", "stats", k].reshape(-1)[idx].float()
            count += done.long()
    return {k: v.reshape(-1)[:episodes] for k, v in got.items()}


def coop(task: str, episodes: int, envs: int, device, seed: int, action_space: str = "prt") -> str:
    env = volleybots.make_env(task, num_envs=envs, device=device, seed=seed, action_space=action_space)
    keys = (env.metric, *env.extra_stats, "r_dist_to_anchor", "episode_len")
    st = finished_episodes(env, make_scripted_policy(env), episodes, keys)
    m = st[env.metric]
    parts = ", ".join(f"{k} {st[k].mean():.2f}" for k in env.extra_stats)
    # the paper asks the drones to stay within 0.5 m of their anchors; the tasks (like the reference)
    # only charge 0.05 per metre beyond it, so say how far beyond the players went
    excess = -st["r_dist_to_anchor"].sum() / (ANCHOR_COEF * st["episode_len"].sum())
    return f"| {task} | {env.metric} | {m.mean():.3f} +- {m.std():.3f} | {parts} | {excess:.2f} m |"


def match(task: str, episodes: int, envs: int, device, seed: int, action_space: str = "prt") -> list[str]:
    rows = []
    keys = ("win", "loss", "draw", "reason", "hits_team0", "hits_team1")
    for label, sides in (("scripted vs random", "random"), ("scripted vs itself", "self")):
        res = []
        for scripted_team in ((0, 1) if sides == "random" else (0,)):
            for serve in (0, 1):
                env = volleybots.make_env(task, num_envs=envs, device=device, seed=seed + serve, serve=serve, action_space=action_space)
                player = make_scripted_policy(env)
                pols = [player, player] if sides == "self" else [random_policy, random_policy]
                pols[scripted_team] = player
                st = finished_episodes(env, TeamPolicies(env, tuple(pols)), episodes // (4 if sides == "random" else 2), keys)
                if scripted_team == 1:  # count from the scripted team's side
                    st["win"], st["loss"] = st["loss"], st["win"]
                res.append(st)
        st = {k: torch.cat([r[k] for r in res]) for k in keys}
        w, l_, d = (int(st[k].sum()) for k in ("win", "loss", "draw"))
        rally = ((st["hits_team0"] + st["hits_team1"]) >= 3).float().mean()
        reasons = torch.bincount((st["reason"] + 1).long(), minlength=len(Referee.FAULTS) + 1)
        ended = ", ".join(f"{name} {int(c)}" for name, c in zip(("draw",) + Referee.FAULTS, reasons.tolist(), strict=True) if c)
        rate = w / max(w + l_, 1)
        rows.append(f"| {task} | {label} | {len(st['win'])} | {w} / {l_} / {d} | {rate:.2f} | {rally:.2f} | {ended} |")
    return rows


@dataclass
class Args:
    episodes: int = option(100, "episodes played")
    envs: int = option(50, "worlds stepped together")
    tasks: str = option(",".join(COOP + MATCHES), "the tasks")
    device: str = option("cpu", "torch device")
    seed: int = option(0, "the seed")
    action_space: str = option("prt", "the players' (and the random teams') action space", choices=("prt", "ctbr"))


def main() -> None:
    args = script_options(Args, None, __doc__)
    torch.manual_seed(args.seed)  # the random team draws from the global generator: one seed, one table
    tasks = args.tasks.split(",")
    t0 = time.time()
    print("| task | metric | mean +- std | components | beyond the 0.5 m anchor sphere (mean) |\n|---|---|---|---|---|")
    for task in tasks:
        if task in COOP:
            print(coop(task, args.episodes, args.envs, args.device, args.seed, args.action_space), flush=True)
    print("\n| task | games | n | scripted wins / losses / draws | win rate (decisive) | rally >= 3 touches | how games ended |")
    print("|---|---|---|---|---|---|---|")
    for task in tasks:
        if task not in COOP:
            for row in match(task, args.episodes, args.envs, args.device, args.seed, args.action_space):
                print(row, flush=True)
    print(f"\n{time.time() - t0:.0f} s on {args.device}")


if __name__ == "__main__":
    main()
