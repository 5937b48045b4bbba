"""The referee: hit attribution, turns, violations and rally outcome (docs/physics.md).

It reads the physics state and the contact events of one control step and knows nothing of rewards:
tasks turn its events into rewards and terminations. One class serves the solo drills, the
cooperative tasks and the matches; what differs between them is configuration:

* ``turns``: who may hit next.
    - ``"free"``: anyone, any time (solo tasks);
    - ``"alternate"``: strict alternation, the hitter may not hit again until another drone has
      (Bump and Pass, 1 vs 1);
    - ``"sequence"``: drones in ``order`` one after the other, then nobody (Set and Spike);
    - ``"possession"``: a team keeps the ball until it crosses the net; each drone touches it at most
      once per possession and only the server makes the first touch (3 vs 3, 6 vs 6).
* thresholds of the drone and ball violations, and whether an out-of-court ball counts at any height.

Team 0 plays on the +x half, team 1 on the -x half.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

TURN_MODES = ("free", "alternate", "sequence", "possession")


@dataclass(frozen=True)
class Court:
    length: float = 18.0
    width: float = 9.0
    net_height: float = 2.43

    def in_court(self, xy: torch.Tensor) -> torch.Tensor:
        return (xy[..., 0].abs() <= self.length / 2) & (xy[..., 1].abs() <= self.width / 2)


COURTS = {
    "full": Court(18.0, 9.0),
    "1v1": Court(6.0, 3.0),
    "3v3": Court(12.0, 6.0),
}


@dataclass(frozen=True)
class RefereeConfig:
    court: Court = Court()
    turns: str = "free"
    order: tuple[int, ...] = ()  # for turns="sequence"
    debounce_steps: int = 3  # a new hit by the same drone needs this many env steps since its last contact
    min_hit_gap: int = 0  # steps between two true hits of one drone; closer is "too soon" (solo: 25)
    drone_min_z: float = 0.4
    drone_max_z: float = float("inf")
    drone_net_margin: float = 0.2  # a drone within this of the net plane, below its top, touches it
    ball_net_margin: float = 0.3  # 3 ball radii
    ball_low_z: float = 0.2  # the ball "lands" when its centre is below this
    out_at_any_height: bool = True  # 1 vs 1 and drills: out of court as soon as it leaves; 3v3/6v6: when it lands

    def __post_init__(self):
        if self.turns not in TURN_MODES:
            raise ValueError(f"unknown turn mode {self.turns!r}; allowed: {list(TURN_MODES)}")


@dataclass
class Events:
    """What the referee saw in one control step. Per drone [N, D], per env [N]."""

    hit: torch.Tensor  # a new (debounced) touch by the drone, racket or body
    racket_hit: torch.Tensor
    body_hit: torch.Tensor
    wrong_turn: torch.Tensor  # a touch by a drone that was not allowed to hit
    too_soon: torch.Tensor  # a second true hit within min_hit_gap steps
    wrong_hit: torch.Tensor  # body | wrong turn | too soon
    drone_low: torch.Tensor
    drone_high: torch.Tensor
    drone_net: torch.Tensor
    drone_cross: torch.Tensor
    ball_net: torch.Tensor  # [N]
    ball_out: torch.Tensor  # [N]
    ball_landed: torch.Tensor  # [N]: centre below ball_low_z
    ball_crossed: torch.Tensor  # [N]: the ball's x changed sign this step
    landed_side: torch.Tensor  # [N] long: team whose half the ball is over when it lands, -1 otherwise
    last_hitter: torch.Tensor  # [N] long: drone that last hit (after this step), -1 none


@dataclass
class Outcome:
    """Rally outcome of one step (matches): which team lost, draws, and which violation ended it."""

    fault: torch.Tensor  # [N, 2] bool: team t committed a rally-losing fault this step
    winner: torch.Tensor  # [N] long: 0, 1, or -1 (no decision)
    draw: torch.Tensor  # [N] bool: both teams faulted in the same step
    ended: torch.Tensor  # [N] bool
    reason: torch.Tensor  # [N] long: index into Referee.FAULTS of the first fault, -1 none


class Referee:
    # "fell": a drone below the crash height, a fault only where the match says so (task.fall_fault)
    FAULTS = ("cross", "net_drone", "wrong_turn", "body_hit", "too_soon", "ball_out", "ball_net", "landed", "fell")
    # what each fault means, for the legends of the verbs that count them (``eval``'s "ended by" row)
    FAULT_TEXT = {
        "cross": "a drone crossed into the other half", "net_drone": "a drone touched the net",
        "wrong_turn": "a touch out of turn", "body_hit": "the ball hit a drone's body, not its racket",
        "too_soon": "a drone's second hit too soon after its first", "ball_out": "the last hitter sent the ball out",
        "ball_net": "the last hitter sent the ball into the net", "landed": "the ball landed in the team's half",
        "fell": "a drone fell below the crash height (task.fall_fault)",
    }

    def __init__(self, cfg: RefereeConfig, num_envs: int, team: list[int] | torch.Tensor, device="cpu"):
        self.cfg = cfg
        self.num_envs = num_envs
        self.device = torch.device(device)
        self.team = torch.as_tensor(team, device=self.device, dtype=torch.long)  # [D]
        self.n_drones = len(self.team)
        self.side = 1.0 - 2.0 * self.team.float()  # +1 for team 0 (+x half), -1 for team 1
        n, d = num_envs, self.n_drones
        kw = dict(device=self.device)
        big = 10**6
        self.step = torch.zeros(n, dtype=torch.long, **kw)
        self.last_contact = torch.full((n, d), -big, dtype=torch.long, **kw)
        self.last_hit = torch.full((n, d), -big, dtype=torch.long, **kw)
        self.last_hitter = torch.full((n,), -1, dtype=torch.long, **kw)
        self.may_hit = torch.ones(n, d, dtype=torch.bool, **kw)
        self.touched = torch.zeros(n, d, dtype=torch.bool, **kw)  # this possession ("possession" mode)
        self.seq_index = torch.zeros(n, dtype=torch.long, **kw)
        self.hits = torch.zeros(n, d, dtype=torch.long, **kw)
        self.prev_ball_x = torch.zeros(n, **kw)
        self.order = torch.as_tensor(cfg.order or list(range(d)), device=self.device, dtype=torch.long)

    # ----------------------------------------------------------------------------- reset
    def reset(self, mask: torch.Tensor, ball_pos: torch.Tensor, first: torch.Tensor | None = None) -> None:
        """Reset the envs in ``mask``. ``first`` [N] names the drone that must make the first touch
        (the server, the setter, the first bumper); by default drone 0 (``free`` mode ignores it).

        Written as masked selects over all envs (no boolean indexing), so that the compiled env step
        has the same shapes whichever envs reset."""
        big = 10**6
        m = mask.unsqueeze(1)  # [N, 1], against the per-drone buffers
        self.step = torch.where(mask, 0, self.step)
        self.last_contact = torch.where(m, -big, self.last_contact)
        self.last_hit = torch.where(m, -big, self.last_hit)
        self.last_hitter = torch.where(mask, -1, self.last_hitter)
        self.touched = self.touched & ~m
        self.seq_index = torch.where(mask, 0, self.seq_index)
        self.hits = torch.where(m, 0, self.hits)
        self.prev_ball_x = torch.where(mask, ball_pos[:, 0], self.prev_ball_x)
        if self.cfg.turns == "free":
            self.may_hit = self.may_hit | m
        else:
            if first is None:
                first = self.order[0].expand(self.num_envs)
            one_hot = torch.nn.functional.one_hot(first, self.n_drones).bool()
            self.may_hit = torch.where(m, one_hot, self.may_hit)

    # ----------------------------------------------------------------------------- update
    def update(self, pos: torch.Tensor, ball_pos: torch.Tensor, racket: torch.Tensor, body: torch.Tensor) -> Events:
        cfg = self.cfg
        self.step += 1
        step = self.step.unsqueeze(1)
        contact = racket | body
        hit = contact & (step - self.last_contact >= cfg.debounce_steps)
        self.last_contact = torch.where(contact, step, self.last_contact)
        racket_hit = hit & racket
        body_hit = hit & ~racket
        too_soon = hit & (step - self.last_hit < cfg.min_hit_gap)
        wrong_turn = hit & ~self.may_hit
        self.last_hit = torch.where(hit, step, self.last_hit)
        self.hits += hit.long()

        # the hitter of this step (at most one in practice; the first in drone order otherwise)
        any_hit = hit.any(1)
        hitter = torch.where(any_hit, hit.long().argmax(1), self.last_hitter)
        self.last_hitter = hitter

        crossed = (torch.sign(ball_pos[:, 0]) != torch.sign(self.prev_ball_x)) & (self.prev_ball_x != 0)
        self.prev_ball_x = ball_pos[:, 0].clone()
        self._advance_turns(hit, any_hit, hitter, crossed, ball_pos)

        court = cfg.court
        x, y, z = pos[..., 0], pos[..., 1], pos[..., 2]
        below_net = z < court.net_height
        drone_net = (x.abs() < cfg.drone_net_margin) & below_net & (y.abs() <= court.width / 2)
        drone_cross = x * self.side < 0
        bx, by, bz = ball_pos.unbind(-1)
        ball_net = (bx.abs() < cfg.ball_net_margin) & (by.abs() < court.width / 2) & (bz < court.net_height)
        ball_landed = bz < cfg.ball_low_z
        outside = ~court.in_court(ball_pos[:, :2])
        ball_out = outside if cfg.out_at_any_height else outside & ball_landed
        landed_side = torch.where(ball_landed & ~outside, torch.where(bx >= 0, 0, 1), -1)
        return Events(
            hit=hit,
            racket_hit=racket_hit,
            body_hit=body_hit,
            wrong_turn=wrong_turn,
            too_soon=too_soon,
            wrong_hit=body_hit | wrong_turn | too_soon,
            drone_low=z < cfg.drone_min_z,
            drone_high=z > cfg.drone_max_z,
            drone_net=drone_net,
            drone_cross=drone_cross,
            ball_net=ball_net,
            ball_out=ball_out,
            ball_landed=ball_landed,
            ball_crossed=crossed,
            landed_side=landed_side.long(),
            last_hitter=hitter,
        )

    def _advance_turns(self, hit, any_hit, hitter, crossed, ball_pos) -> None:
        mode = self.cfg.turns
        if mode == "free":
            return
        hitter_oh = torch.nn.functional.one_hot(hitter.clamp_min(0), self.n_drones).bool() & any_hit.unsqueeze(1)
        if mode == "alternate":
            nxt = ~hitter_oh
            self.may_hit = torch.where(any_hit.unsqueeze(1), nxt, self.may_hit)
        elif mode == "sequence":
            self.seq_index = self.seq_index + any_hit.long()
            nxt = torch.nn.functional.one_hot(self.order[self.seq_index.clamp_max(len(self.order) - 1)], self.n_drones).bool()
            nxt = nxt & (self.seq_index < len(self.order)).unsqueeze(1)
            self.may_hit = torch.where(any_hit.unsqueeze(1), nxt, self.may_hit)
        elif mode == "possession":
            self.touched = self.touched | hitter_oh
            hitter_team = self.team[hitter.clamp_min(0)]
            same_team = self.team.unsqueeze(0) == hitter_team.unsqueeze(1)
            after_hit = same_team & ~self.touched
            self.may_hit = torch.where(any_hit.unsqueeze(1), after_hit, self.may_hit)
            # the ball crossing into a half gives that team a fresh possession
            side_team = torch.where(ball_pos[:, 0] >= 0, 0, 1)
            receiving = self.team.unsqueeze(0) == side_team.unsqueeze(1)
            self.may_hit = torch.where(crossed.unsqueeze(1), receiving, self.may_hit)
            self.touched = torch.where(crossed.unsqueeze(1), torch.zeros_like(self.touched), self.touched)

    # ----------------------------------------------------------------------------- outcome
    def turn_team(self) -> torch.Tensor:
        """[N] team allowed to hit now (the team of the first drone that may), -1 if nobody may."""
        anyone = self.may_hit.any(1)
        return torch.where(anyone, self.team[self.may_hit.long().argmax(1)], -1)

    def outcome(self, ev: Events) -> Outcome:
        """Rally faults with blame: drone faults on the drone's team, ball faults on the last hitter's
        team (the serving team if nobody hit yet is handled by last_hitter = -1 -> nobody), a ball
        landing in a half on that half's team. Both teams faulting in one step is a draw."""
        team_oh = torch.nn.functional.one_hot(self.team, 2).bool()  # [D, 2]

        def per_team(flags):  # [N, D] -> [N, 2]
            return (flags.unsqueeze(-1) & team_oh).any(1)

        hitter_team = torch.where(ev.last_hitter >= 0, self.team[ev.last_hitter.clamp_min(0)], -1)
        hitter_oh = torch.nn.functional.one_hot(hitter_team.clamp_min(0), 2).bool() & (hitter_team >= 0).unsqueeze(1)
        landed_oh = torch.nn.functional.one_hot(ev.landed_side.clamp_min(0), 2).bool() & (ev.landed_side >= 0).unsqueeze(1)
        faults = [
            per_team(ev.drone_cross),
            per_team(ev.drone_net),
            per_team(ev.wrong_turn),
            per_team(ev.body_hit),
            per_team(ev.too_soon),
            hitter_oh & ev.ball_out.unsqueeze(1),
            hitter_oh & ev.ball_net.unsqueeze(1),
            landed_oh & ~ev.ball_out.unsqueeze(1),
        ]
        stack = torch.stack(faults, 1)  # [N, F, 2]
        fault = stack.any(1)
        any_fault = stack.any(-1)  # [N, F]
        reason = torch.where(any_fault.any(1), any_fault.long().argmax(1), -1)
        draw = fault.all(1)
        ended = fault.any(1)
        winner = torch.where(ended & ~draw, torch.where(fault[:, 0], 1, 0), -1)
        return Outcome(fault=fault, winner=winner.long(), draw=draw, ended=ended, reason=reason.long())
