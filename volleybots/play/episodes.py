"""Rollouts: batches of steps for training, whole episodes for evaluation, and their statistics.

Every floor above stands on these: ``train`` collects batches, ``eval`` and ``replay`` play episodes,
``play.games`` plays matches. A policy is any ``td -> td`` writing ``("agents", "action")``.
"""

from __future__ import annotations

import math

import torch
from torchrl.envs.utils import step_mdp

from volleybots.keys import DONE, NEXT, STATS, stat


def stat_keys(env) -> list[str]:
    return list(env.observation_spec[STATS].keys())


def run_episodes(env, policy, on_step=None) -> dict[str, torch.Tensor]:
    """Play until every env of the batch has finished one episode; return the statistics of those
    first episodes ([num_envs] per statistic). ``on_step(env, td, next_td)`` sees every step before
    the finished envs are reset (the recorder uses it)."""
    keys = stat_keys(env)
    n = env.num_envs
    finished = torch.zeros(n, dtype=torch.bool, device=env.device)
    out = {k: torch.zeros(n, device=env.device) for k in keys}
    td = env.reset()
    # a task may end episodes by itself, but never later than its time limit
    for _ in range(env.episode_len + 1):
        td = policy(td)
        td = env.step(td)
        nxt = td[NEXT]
        if on_step is not None:
            on_step(env, td, nxt)
        new = nxt[DONE].reshape(n) & ~finished
        for k in keys:
            out[k] = torch.where(new, nxt[stat(k)].reshape(n), out[k])
        finished |= new
        if bool(finished.all()):
            break
        td = env.maybe_reset(step_mdp(td, keep_other=True, exclude_action=True))
    return out


def summarize(results: dict[str, torch.Tensor], metric: str) -> dict:
    """Mean and standard deviation of every statistic; the task metric first."""
    table = {}
    for k in [metric, *[k for k in results if k != metric]]:
        v = results[k].double()
        table[k] = {"mean": float(v.mean()), "std": float(v.std(unbiased=False)) if v.numel() > 1 else 0.0}
    return {"metric": metric, "episodes": int(next(iter(results.values())).numel()), "stats": table}


def collect(env, policy, td, steps: int):
    """``steps`` steps of every env; returns the [num_envs, steps] batch and the next input."""
    out = []
    for _ in range(steps):
        td = policy(td)
        step, td = env.step_and_maybe_reset(td)
        out.append(step)
    return torch.stack(out, dim=1), td


def finished_stats(batch, team: int | None = None) -> dict[str, float]:
    """Means of the statistics of the episodes that ended in ``batch`` (NaN when none did).

    ``team=0`` (a seat whose learner plays team 0): ``return`` and ``r_*`` are that team's (a
    competitive task's ``*_team0`` statistics) and the all-drone means move to ``*_all``; on a match
    the all-drone ``r_win_or_lose`` is 0 by construction, since one team's win is the other's loss."""
    nxt = batch[NEXT]
    done = nxt[DONE].reshape(-1)
    n = int(done.sum())
    out = {"episodes": float(n)}
    for k in nxt[STATS].keys():
        v = nxt[stat(k)].reshape(-1)[done]
        out[k] = float(v.mean()) if n else math.nan
    suffix = f"_team{team}"
    if team is not None:
        for base in [k for k in out if k == "return" or k.startswith("r_")]:
            if base + suffix in out:
                out[f"{base}_all"], out[base] = out[base], out.pop(base + suffix)
    return out


__all__ = ["collect", "finished_stats", "run_episodes", "stat_keys", "summarize"]
