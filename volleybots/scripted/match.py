"""Scripted match player (serve, receive, set, attack) used by teams of 1, 3 and 6 drones."""

from __future__ import annotations

from dataclasses import dataclass

import torch

from volleybots.rules import COURTS
from volleybots.scripted.ballistics import crossing, launch_for_apex, time_to_height
from volleybots.scripted.players import TouchConfig, _Player, is_drop, with_z
from volleybots.scripted.policies import SCRIPTED_POLICIES
from volleybots.tasks.match import OneVsOne, SixVsSix, ThreeVsThree


# --------------------------------------------------------------------------- matches
@dataclass(frozen=True)
class MatchConfig:
    net_clear: float = 1.5  # m the ball's apex must be above the net top
    # attacks land at this fraction of the opponent's half length from the net (teams: aim at the opponent nearest that point)
    depth: float = 0.3
    guard_x: float = 0.6  # a drone closer than this to the net drops everything and backs off (crossing loses the rally)
    reach_margin: float = 0.3  # ... and does not go for balls coming down closer than guard_x + this
    side_cost: float = 0.1  # m of depth one metre sideways counts for when choosing whom to pass to


class _MatchPlayer(_Player):
    """One player of a match team (1 vs 1, 3 vs 3, 6 vs 6), in its own mirrored frame (its half is
    x > 0, the net at x = 0).

    - Who plays the ball: in 1 vs 1 the drone whose turn it is; in teams, of the drones of the team
      whose turn it is, the one nearest to where the ball comes down (if it may still touch it);
      an opponents' ball on its way over the net is flown for before it crosses (when it becomes
      the team's), or the receiver would be late.
    - Attack: over the net, with an apex ``net_clear`` above the net, landing ``depth`` of the way
      into the opponent's half (1 vs 1). Teams aim at an opponent instead: the ball comes down
      through the contact height right where the opponent's drone nearest that point waits (its
      anchor), so a receiver has its ball without flying for it; a ball nobody plays still lands in
      the court.
    - In teams the first touch of a possession (the serve, or a ball that came over the net) is a
      pass to the teammate nearest the net, who attacks: a pass asks for a small turn of the ball,
      where sending an incoming attack straight back needs racket tilts the drone does not have.
    - Everyone else holds at its anchor (at the contact height).
    """

    task_cls: type = type(None)  # the match task: court, team size and anchors come from it
    default_cfg = MatchConfig()
    # along the early (sideways) axis the drone waits on the contact point and only the lock tilts it:
    # fed forward the whole approach, the sideways acceleration left the ball on the racket's rim
    default_touch = TouchConfig(contact_z=2.6, first_contact_z=2.1, early=(1,), early_feed=False)

    def __init_subclass__(cls, **kw):
        super().__init_subclass__(**kw)
        t = cls.task_cls
        cls.task = t.name
        cls.half_length = COURTS[t.court].length / 2
        cls.team_size = t.team_size
        cls.anchors = t.anchors_xyz[: t.team_size]  # the team's anchors in its own frame (the task's team 0 anchors)

    def __init__(self, action_space="prt", params=None, gains=None, cfg: MatchConfig | None = None, touch: TouchConfig | None = None):
        super().__init__(action_space, params, gains, touch or self.default_touch)
        self.cfg = cfg or self.default_cfg

    def parse(self, drone, t):
        """(anchor, ball position, ball velocity, I may hit, my team's turn, my teammates' positions [..., k, 3])."""
        anchor = drone.pos - t["anchor"]
        if self.team_size == 1:  # 1 vs 1 observes drone minus ball, its turn flag is "I may hit"
            ball_p, ball_v = drone.pos - t["ball"], t["ball_vel"]
            may = t["turn"][..., 0] > 0.5
            return anchor, ball_p, ball_v, may, may, drone.pos.unsqueeze(-2)
        k = self.team_size
        ball_p, ball_v = drone.pos + t["ball"], t["ball_vel"]
        team_turn = t["turn"][..., 0] > 0.5
        may = t["may_hit"][..., 0] > 0.5
        pos = t["positions"][..., : 3 * k].unflatten(-1, (k, 3))  # the own team's, first
        return anchor, ball_p, ball_v, may, team_turn, pos

    def attack_target(self, ball_p):
        """Where the attack is to come down (xy [..., 2]) and through which ball height."""
        c = self.cfg
        point = torch.stack((torch.full_like(ball_p[..., 0], -c.depth * self.half_length), ball_p[..., 1]), -1)
        if self.team_size == 1:
            return point, 0.2
        # the opponents' anchors: the own ones turned by 180 degrees about z
        opp = -torch.tensor(self.anchors, dtype=ball_p.dtype, device=ball_p.device)[:, :2]
        near = (opp - point.unsqueeze(-2)).norm(dim=-1).argmin(-1)
        return opp[near], self.touch.contact_z + self.planner.reach

    def pass_target(self, ball_p, me):
        """Where a pass goes (xy [..., 2]): to the anchor, where it waits, of the teammate nearest the
        net and, of those, nearest the ball sideways; not mine (``me`` [...], my index). Anchors, not
        positions: two teammates about as near would swap as they move, and the racket with them."""
        own = torch.tensor(self.anchors, dtype=ball_p.dtype, device=ball_p.device)[:, :2]
        cost = own[:, 0] + self.cfg.side_cost * (own[:, 1] - ball_p[..., 1:2]).abs()
        cost = torch.where(torch.arange(len(own), device=me.device) == me.unsqueeze(-1), torch.full_like(cost, float("inf")), cost)
        return own[cost.argmin(-1)]

    def meet_height(self, drone, ball_p, ball_v, ours) -> torch.Tensor | None:
        """The drone's height [...] at the next contact where it is not the default one (``TouchConfig``);
        None: the defaults everywhere. ``ours`` [...]: the ball is the team's to play, or the opponents'
        ball flying over the net to us."""
        return None

    def fly(self, drone, ball_p, ball_v, want_out, mine, home, drone_z) -> torch.Tensor:
        """The touch's flight (``_Player.play``); ``drone_z`` as ``meet_height`` gave it."""
        return self.play(drone, ball_p, ball_v, want_out, mine, home, drone_z=drone_z)

    def act(self, drone, t):
        c = self.cfg
        g = self.params.gravity
        anchor, ball_p, ball_v, may, team_turn, team_pos = self.parse(drone, t)
        contact_z = self.contact_height(ball_p, ball_v)
        # where the ball comes down to the contact height; the nearest teammate takes it
        fall, _ = crossing(ball_p, ball_v, contact_z, g)
        # the opponents' ball flying over the net to us is ours from when it crosses (everyone may
        # touch it then): the receiver gets under it before, it would not make it from there
        incoming = ~team_turn & (ball_v[..., 0] > 0) & (fall[..., 0] > 0)
        drone_z = self.meet_height(drone, ball_p, ball_v, (may & team_turn) | incoming)
        if drone_z is not None:  # a player that meets some balls lower: plan those there
            contact_z = self.contact_height(ball_p, ball_v, drone_z=drone_z)
            fall, _ = crossing(ball_p, ball_v, contact_z, g)
        d = (team_pos[..., :2] - fall[..., None, :2]).norm(dim=-1)
        me = (team_pos[..., :2] - drone.pos[..., None, :2]).norm(dim=-1).argmin(-1)
        nearest = d.argmin(-1) == me
        # a ball coming down too close to the net is let go: reaching it would cross (losing anyway)
        mine = ((may & team_turn) | incoming) & (nearest | (self.team_size == 1)) & (fall[..., 0] > c.guard_x + c.reach_margin)
        # the touch that sent the ball was where it last passed the contact height going up: on the
        # opponent's side (x < 0) it came over the net and this is the possession's first touch
        t_up = time_to_height(ball_p[..., 2], ball_v[..., 2], contact_z, g, descending=False)
        sent_x = ball_p[..., 0] + ball_v[..., 0] * torch.where(torch.isfinite(t_up), t_up, torch.zeros_like(t_up))
        passing = (is_drop(ball_v) | (sent_x < 0)) & (self.team_size > 1)
        apex = torch.maximum(torch.as_tensor(2.43 + c.net_clear), contact_z + 0.5)

        def want_out(bp, bv):
            target, land_z = self.attack_target(bp)
            over = launch_for_apex(bp, target, apex, land_z, g)
            fwd = launch_for_apex(bp, self.pass_target(bp, me), apex, self.touch.contact_z + self.planner.reach, g)
            return torch.where(passing.unsqueeze(-1), fwd, over)

        home = with_z(anchor[..., :2], self.touch.contact_z)
        action = self.fly(drone, ball_p, ball_v, want_out, mine, home, drone_z)
        back = self.ctrl.act(drone, home, torch.zeros_like(home))
        return torch.where((drone.pos[..., :1] < c.guard_x), back, action)


class OneVsOnePlayer(_MatchPlayer):
    task_cls = OneVsOne
    # on the small court a shot 30 % deep comes down where the receiver must let it go (too close to
    # the net); deep shots are playable. The serve is met higher: from 2.1 m it goes into the net.
    default_cfg = MatchConfig(depth=0.8)
    default_touch = TouchConfig(contact_z=2.6, first_contact_z=2.4, early=(1,), early_feed=False)


class ThreeVsThreePlayer(_MatchPlayer):
    task_cls = ThreeVsThree
    # high, soft attacks (apex 5.4 m): they come down steeply onto the receiver waiting at its
    # anchor, so it meets them without running and with a racket tilt it can hold
    default_cfg = MatchConfig(net_clear=3.0)


class SixVsSixPlayer(_MatchPlayer):
    task_cls = SixVsSix
    default_cfg = MatchConfig(net_clear=2.5)  # high attacks, as in 3 vs 3 (from 3.0 m more games end in collisions of teammates)


SCRIPTED_POLICIES.update({cls.task: cls for cls in (OneVsOnePlayer, ThreeVsThreePlayer, SixVsSixPlayer,)})
