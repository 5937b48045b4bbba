"""Games between two competitors on a match: batched, both sides played equally often.

Each env of a batch plays one game (a rally: the first episode of that env), so a result never
favours short games. Frozen policies act stochastically unless ``deterministic`` is set. A game's
random numbers come from ``seed`` alone (the caller's generator state is left as it was), so the same
call gives the same counts whatever ran before it.
"""

from __future__ import annotations

import torch

from volleybots.config import make_env

MAX_ENVS = 1024  # games played at once; more are played in further batches


def play_sides(cfg, team0, team1, games: int, seed: int, deterministic: bool = False) -> dict[str, int]:
    """``games`` games with competitor ``team0`` on team 0; W/D/L counts from team 0's side."""
    from volleybots.eval import run_episodes
    from volleybots.tasks.multi import TeamPolicies

    counts = {"wins": 0, "draws": 0, "losses": 0}
    done = 0
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        while done < games:
            n = min(MAX_ENVS, games - done)
            env = make_env(cfg, num_envs=n, seed=seed + done)
            gen = torch.Generator().manual_seed(seed + done)
            policy = TeamPolicies(env, (team0.team_policy(env, deterministic, gen), team1.team_policy(env, deterministic, gen)))
            winner = run_episodes(env, policy)["winner"].round().long()
            counts["wins"] += int((winner == 0).sum())
            counts["losses"] += int((winner == 1).sum())
            counts["draws"] += int((winner < 0).sum())
            done += n
    return counts


def head_to_head(cfg, a, b, games: int, seed: int, deterministic: bool = False) -> dict[str, int]:
    """``games`` games of ``a`` against ``b``, each on either side half the time (an odd one with ``a``
    on team 0); W/D/L counts from ``a``'s side."""
    first = play_sides(cfg, a, b, games - games // 2, seed, deterministic)
    second = play_sides(cfg, b, a, games // 2, seed + 7919, deterministic)
    return {"wins": first["wins"] + second["losses"], "draws": first["draws"] + second["draws"], "losses": first["losses"] + second["wins"]}
