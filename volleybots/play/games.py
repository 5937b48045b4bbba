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

Besides the results, a ``Games`` keeps every game's content from the episode statistics the match
task already reports: the touches of each team, the rally's length in steps, who served, and the
fault that ended it. ``Games.content()`` sums them up (means per side, ending faults per team, W/D/L
with A serving and receiving apart), so that a table shows whether the players play volleyball or
win on the other side's serve faults.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import torch
from omegaconf import OmegaConf

from volleybots.config import make_env, to_dict
from volleybots.config.verbs import DEFAULT_BATCH, SCENARIOS  # (the verbs' options show them in their help)
from volleybots.errors import ConfigError
from volleybots.play.episodes import run_episodes
from volleybots.ratings.record import OUTCOMES
from volleybots.rules import Referee
from volleybots.tasks.multi import TeamPolicies


@dataclass
class Games:
    """Results of games between A and B, from A's side."""

    wdl: np.ndarray  # [2, 3] int: A on team 0 / on team 1 -> wins, draws, losses
    outcomes: str  # one letter of OUTCOMES per game, in play order
    # [A, B] x fault: the faults that lost games
    faults: np.ndarray = field(default_factory=lambda: np.zeros((2, len(Referee.FAULTS)), dtype=int))
    side: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))  # [games] A's team in each game
    a_served: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))  # [games] A served
    touches: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=int))  # [games, 2] touches of A, of B
    steps: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))  # [games] rally length in control steps

    @property
    def served(self) -> int:
        """Games in which A served."""
        return int(self.a_served.sum())

    def serve_wdl(self) -> np.ndarray:
        """[2, 3] wins, draws, losses from A's side: the games A served, the games A received."""
        out = np.zeros((2, 3), dtype=int)
        for o, s in zip(self.outcomes, self.a_served):
            out[0 if s else 1, OUTCOMES.index(o)] += 1
        return out

    def content(self) -> dict:
        """What the games held, from A's side: touches per team and rally length (means overall and
        per side, A on team 0 / team 1), the faults that ended them per team, W/D/L serving and receiving."""
        rally = self.touches.sum(1)
        per_side = [self.side == s for s in (0, 1)]
        serve, receive = self.serve_wdl().tolist()
        return {
            "games": len(self.outcomes),
            "touches": _mean(self.touches),
            "touches_per_side": [_mean(self.touches[m]) for m in per_side],
            "rally_steps": _mean(self.steps),
            "rally_steps_per_side": [_mean(self.steps[m]) for m in per_side],
            "rally_touches": _mean(rally),
            "rally_touches_max": int(rally.max()) if rally.size else 0,
            "games_3plus_touches": int((rally >= 3).sum()),
            "faults": {team: {f: int(n) for f, n in zip(Referee.FAULTS, row) if n} for team, row in zip("AB", self.faults)},
            "serve_wdl": serve,
            "receive_wdl": receive,
        }

    @property
    def total(self) -> np.ndarray:
        """[3] wins, draws, losses over both sides."""
        return self.wdl.sum(0)

    @property
    def games(self) -> int:
        return int(self.wdl.sum())


def _mean(a: np.ndarray):
    """Mean over games (axis 0): a float, a list per team, or None when there is no game."""
    if len(a) == 0:
        return None if a.ndim == 1 else [None] * a.shape[1]
    m = a.mean(0)
    return float(m) if np.ndim(m) == 0 else [float(x) for x in m]


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


def play_games(
    cfg, a, b, games: int, seed: int = 0, batch: int = DEFAULT_BATCH, scenario: str = "any", deterministic: bool = False
) -> Games:
    """Play ``games`` games of competitor A against B on the match task of ``cfg``: half with A on
    team 0 (an odd one more there), in alternating batches per side."""
    if games < 1 or batch < 1:
        raise ConfigError(f"games={games!r} and batch={batch!r} must be >= 1")
    check_scenario(scenario, cfg)
    wdl = np.zeros((2, 3), dtype=int)
    faults = np.zeros((2, len(Referee.FAULTS)), dtype=int)
    outcomes: list[str] = []
    side_of, served, touches, steps = [], [], [], []
    per_side = (batch_sizes(games - games // 2, batch), batch_sizes(games // 2, batch) if games > 1 else [])
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        gen = torch.Generator().manual_seed(seed)  # members of population competitors
        sides = [_Side(cfg, side, scenario, max(sizes), seed, a, b, deterministic, gen) for side, sizes in enumerate(per_side) if sizes]
        for k in range(len(per_side[0])):
            for side, player in enumerate(sides):
                if k >= len(per_side[side]):
                    continue
                for o, reason, a_served, hits, length in player.play(per_side[side][k]):
                    wdl[side, OUTCOMES.index(o)] += 1
                    if o != "D":
                        faults[0 if o == "L" else 1, reason] += 1  # a lost game is the loser's fault
                    outcomes.append(o)
                    side_of.append(side)
                    served.append(a_served)
                    touches.append(hits)
                    steps.append(length)
    return Games(wdl, "".join(outcomes), faults, np.array(side_of, dtype=int), np.array(served, dtype=bool),
                 np.array(touches, dtype=int).reshape(-1, 2), np.array(steps, dtype=int))


class _Side:
    """One side's env (built once, reused by every batch) and the two team policies in it."""

    def __init__(self, cfg, side: int, scenario: str, num_envs: int, seed: int, a, b, deterministic: bool, gen):
        self.side = side
        self.env = side_env(cfg, side, scenario, num_envs, seed)
        pa, pb = (c.team_policy(self.env, deterministic, gen) for c in (a, b))
        self.policy = TeamPolicies(self.env, (pa, pb) if side == 0 else (pb, pa))

    def play(self, size: int) -> list[tuple[str, int, bool, tuple[int, int], int]]:
        """(outcome from A's side, index of the ending fault or -1, whether A served, touches of A and
        of B, rally steps) for ``size`` games."""
        res = run_episodes(self.env, self.policy)
        keys = ("winner", "reason", "serve_team", "hits_team0", "hits_team1", "episode_len")
        winner, reason, serve, h0, h1, length = (res[k][:size].round().long().tolist() for k in keys)
        a = self.side
        return [
            (outcome(w, a), r, s == a, (t0, t1) if a == 0 else (t1, t0), n)
            for w, r, s, t0, t1, n in zip(winner, reason, serve, h0, h1, length)
        ]


def outcome(winner: int, side: int) -> str:
    """A game's outcome letter from the side of the team ``side``: the referee's winner is -1 for a draw."""
    return "D" if winner < 0 else "W" if winner == side else "L"
