"""Record the serves a team meets: a ball bank for the drills (HCSP's stage III; docs/competitive.md).

``record_serves`` plays games in which competitor A receives and B serves (the ``receive`` scenario
of ``play.games``) and keeps, per game, the ball as B's last hit before the net sent it over: its
position and velocity right after that hit, in A's frame (A on +x, as a drill's team). That is
where a drill's reset places an incoming ball (``tasks.drills``: ``serve_bank``), so the Pass and
Attack drills can be fine-tuned on the serves the population actually plays rather than on the
scripted team's alone. A hit is a jump of the ball's velocity away from free flight (as the
hierarchical high level detects one), seen while the ball is in B's half. A game in which no ball
came over (a serve fault) adds nothing.
"""

from __future__ import annotations

import torch

from volleybots.files import write_atomic
from volleybots.keys import DONE
from volleybots.play.episodes import run_episodes
from volleybots.play.games import batch_sizes, side_env
from volleybots.scripted.hierarchical import HIT_JUMP  # a hit, as the high level detects one
from volleybots.tasks.drills import BANK_FORMAT
from volleybots.tasks.multi import TeamPolicies


class _Watch:
    """Per env: the ball right after B's latest hit, and the first one that crossed into A's half."""

    def __init__(self, n: int, sign: float, gravity: float, dt: float):
        self.sign, self.fall = sign, torch.tensor((0.0, 0.0, -gravity * dt))
        self.last = torch.zeros(n, 6)
        self.hit = torch.zeros(n, dtype=torch.bool)
        self.kept = torch.zeros(n, dtype=torch.bool)
        self.balls = torch.zeros(n, 6)
        self.prev_vel = None
        self.ended = torch.zeros(n, dtype=torch.bool)

    def __call__(self, env, td, nxt) -> None:
        s = env.physics.state
        mirror = torch.tensor((self.sign, self.sign, 1.0))  # B's side is always -x in A's frame
        ball = torch.cat((s.ball_pos.cpu() * mirror, s.ball_vel.cpu() * mirror), -1)
        if self.prev_vel is not None:
            jump = (ball[:, 3:] - (self.prev_vel + self.fall)).norm(dim=-1) > HIT_JUMP
            b_hit = jump & (ball[:, 0] < 0)
            self.last = torch.where(b_hit.unsqueeze(-1), ball, self.last)
            self.hit |= b_hit
            over = (ball[:, 0] > 0) & self.hit & ~self.kept
            self.balls = torch.where(over.unsqueeze(-1), self.last, self.balls)
            self.kept |= over
        self.prev_vel = ball[:, 3:].clone()
        self.ended |= nxt[DONE].reshape(-1).cpu()

    def settled(self) -> bool:
        """Every game has kept its serve or ended (a serve fault keeps none)."""
        return bool((self.kept | self.ended).all())


def record_serves(cfg, a, b, games: int, seed: int, batch: int = 256) -> torch.Tensor:
    """[K, 6] the serves of competitor B that came over to A in ``games`` games (half with A on each
    side) on the match task of ``cfg``, seeded by ``seed`` alone: position and velocity right after
    B's hit that sent each over, in A's frame (A on +x). K <= ``games``: serve faults add none."""
    out = []
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        gen = torch.Generator().manual_seed(seed)
        for side, n in enumerate((games - games // 2, games // 2)):
            for size in batch_sizes(n, batch) if n else []:
                env = side_env(cfg, side, "receive", size, seed + 2 * len(out))
                pa, pb = (c.team_policy(env, False, gen) for c in (a, b))
                watch = _Watch(size, 1.0 if side == 0 else -1.0, env.params.gravity, env.params.dt)
                # a game's serve is kept once it came over: the rest of the rally is not needed
                run_episodes(env, TeamPolicies(env, (pa, pb) if side == 0 else (pb, pa)), watch, until=watch.settled)
                out.append(watch.balls[watch.kept])
    return torch.cat(out) if out else torch.zeros(0, 6)


def write_bank(path, balls: torch.Tensor, **info) -> None:
    """Write ``balls`` [K, 6] as a ball bank file (``tasks.drills.read_ball_bank`` reads it; weights-only)."""
    state = {"format": BANK_FORMAT, "balls": balls.detach().cpu().float().contiguous(), **info}
    write_atomic(path, lambda f: torch.save(state, f), "a ball bank")


__all__ = ["record_serves", "write_bank"]
