"""Games between two competitors on a match task, batched on the env (docs/evaluation.md).

A game is one episode of a match (one rally: it ends at the first fault, a draw, or the time limit).
``play_games`` plays ``games`` of them between A and B, half with A on team 0 (+x) and half with A on
team 1, each half in batches of worlds, and counts wins, draws and losses from A's side per side, so a
side advantage shows and cancels. A *scenario* fixes who serves through the task's ``serve``
override: ``serve`` (A serves every game), ``receive`` (B serves), ``any`` (a random side per game,
the task's default); the paper evaluated 3 vs 3 serve and rally situations apart.

A competitor (``volleybots.policies.competitors``) acts for a team through ``team_policy(env, deterministic,
generator)``: ``tasks.multi.TeamPolicies`` gives it only its team's agents, mirrored, and a
population competitor draws its member per env when that env's episode starts. A game's random
numbers come from ``seed`` alone (torch's global generator is forked, so the caller's state is left
as it was): the same call gives the same games whatever ran before it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
import numpy as np
import torch
from omegaconf import OmegaConf

from volleybots.config import make_env, to_dict
from volleybots.errors import ConfigError
from volleybots.play.episodes import run_episodes
from volleybots.rules import Referee
from volleybots.tasks.multi import TeamPolicies

SCENARIOS = ("any", "serve", "receive")
OUTCOMES = "WDL"  # win, draw, loss: the letters of a game's result from A's side
DEFAULT_BATCH = 256  # worlds per batch: bounded so memory stays small while the batch amortises stepping


@dataclass
class Games:
    """Results of games between A and B, from A's side."""

    wdl: np.ndarray  # [2, 3] int: A on team 0 / on team 1 -> wins, draws, losses
    outcomes: str  # one letter of OUTCOMES per game, in play order
    faults: np.ndarray = field(default_factory=lambda: np.zeros((2, len(Referee.FAULTS)), dtype=int))  # [A, B] x fault: the faults that lost games
    served: int = 0  # games in which A served

    @property
    def total(self) -> np.ndarray:
        """[3] wins, draws, losses over both sides."""
        return self.wdl.sum(0)

    @property
    def games(self) -> int:
        return int(self.wdl.sum())


def check_games(games: int) -> int:
    """Games come in pairs, one per side, so that both sides are played equally often."""
    if not isinstance(games, int) or isinstance(games, bool) or games < 2 or games % 2:
        raise ConfigError(f"games={games!r} must be an even number >= 2 (each side plays half of them)")
    return games


def check_scenario(scenario: str, cfg) -> str:
    if scenario not in SCENARIOS:
        raise ConfigError(f"unknown scenario {scenario!r}; allowed: {', '.join(SCENARIOS)}")
    if "serve" not in cfg.task:
        raise ConfigError(f"task {cfg.task.name!r} is not a match (it has no serve); games need 1v1, 3v3 or 6v6")
    return scenario


def serve_for(scenario: str, side: int):
    """The task's ``serve`` value when A plays team ``side``."""
    return {"any": None, "serve": side, "receive": 1 - side}[scenario]


def side_env(cfg, side: int, scenario: str, num_envs: int, seed: int):
    """The env in which A plays team ``side``: the task with ``serve`` set for the scenario."""
    c = OmegaConf.create(to_dict(cfg))
    c.task.serve = serve_for(scenario, side)
    return make_env(c, num_envs=num_envs, seed=seed + side)


def batch_sizes(n: int, batch: int) -> list[int]:
    """``n`` games in as few batches of at most ``batch`` worlds as possible, of near-equal size."""
    k = math.ceil(n / batch)
    return [n // k + (i < n % k) for i in range(k)]


def play_games(cfg, a, b, games: int, seed: int = 0, batch: int = DEFAULT_BATCH, scenario: str = "any", deterministic: bool = False) -> Games:
    """Play ``games`` games of competitor A against B on the match task of ``cfg``: half with A on
    team 0 (an odd one more there), in alternating batches per side."""
    if games < 1 or batch < 1:
        raise ConfigError(f"games={games!r} and batch={batch!r} must be >= 1")
    check_scenario(scenario, cfg)
    wdl = np.zeros((2, 3), dtype=int)
    faults = np.zeros((2, len(Referee.FAULTS)), dtype=int)
    outcomes: list[str] = []
    a_served = 0
    per_side = (batch_sizes(games - games // 2, batch), batch_sizes(games // 2, batch) if games > 1 else [])
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        gen = torch.Generator().manual_seed(seed)  # members of population competitors
        sides = [_Side(cfg, side, scenario, max(sizes), seed, a, b, deterministic, gen) for side, sizes in enumerate(per_side) if sizes]
        for k in range(len(per_side[0])):
            for side, player in enumerate(sides):
                if k >= len(per_side[side]):
                    continue
                for o, reason, served in player.play(per_side[side][k]):
                    wdl[side, OUTCOMES.index(o)] += 1
                    a_served += served
                    if o != "D":
                        faults[0 if o == "L" else 1, reason] += 1  # a lost game is the loser's fault
                    outcomes.append(o)
    return Games(wdl, "".join(outcomes), faults, a_served)


def head_to_head(cfg, a, b, games: int, seed: int, deterministic: bool = False) -> dict[str, int]:
    """W/D/L counts from ``a``'s side of ``games`` games, each side played half the time (the payoff
    table of a population run uses these)."""
    w, d, l_ = play_games(cfg, a, b, games, seed, deterministic=deterministic).total.tolist()
    return {"wins": int(w), "draws": int(d), "losses": int(l_)}


class _Side:
    """One side's env (built once, reused by every batch) and the two team policies in it."""

    def __init__(self, cfg, side: int, scenario: str, num_envs: int, seed: int, a, b, deterministic: bool, gen):
        self.side = side
        self.env = side_env(cfg, side, scenario, num_envs, seed)
        pa, pb = (c.team_policy(self.env, deterministic, gen) for c in (a, b))
        self.policy = TeamPolicies(self.env, (pa, pb) if side == 0 else (pb, pa))

    def play(self, size: int) -> list[tuple[str, int, bool]]:
        """(outcome from A's side, index of the ending fault or -1, whether A served) for ``size`` games."""
        res = run_episodes(self.env, self.policy)
        winner, reason, serve = (res[k][:size].round().long().tolist() for k in ("winner", "reason", "serve_team"))
        return [("D" if w < 0 else "W" if w == self.side else "L", r, s == self.side) for w, r, s in zip(winner, reason, serve)]
