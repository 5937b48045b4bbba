"""Scripted match player (serve, receive, set, attack) used by teams of 1, 3 and 6 drones."""

from __future__ import annotations

from dataclasses import dataclass

import torch

from volleybots.rules import COURTS
from volleybots.scripted.ballistics import crossing, launch_for_apex
from volleybots.scripted.players import TouchConfig, _Player, with_z
from volleybots.scripted.policies import SCRIPTED_POLICIES


# --------------------------------------------------------------------------- matches
@dataclass(frozen=True)
class MatchConfig:
    net_clear: float = 1.5  # m the ball's apex must be above the net top
    depth: float = 0.3  # attacks land at this fraction of the opponent's half length from the net
    back_x: float = 0.6  # in teams a touch taken deeper than this fraction of the half length passes to the teammate nearest the net
    guard_x: float = 0.6  # a drone closer than this to the net drops everything and backs off (crossing loses the rally)
    reach_margin: float = 0.3  # ... and does not go for balls coming down closer than guard_x + this


class _MatchPlayer(_Player):
    """One player of a match team (1 vs 1, 3 vs 3, 6 vs 6), in its own mirrored frame (its half is
    x > 0, the net at x = 0).

    - Who plays the ball: in 1 vs 1 the drone whose turn it is; in teams, of the drones of the team
      whose turn it is, the one nearest to where the ball comes down (if it may still touch it).
    - Serve and attack: over the net, landing ``depth`` of the way into the opponent's half, with an
      apex ``net_clear`` above the net. In teams a touch taken deep in the own half (beyond
      ``back_x`` of the half length) is a pass forward to the set spot near the net instead, so the
      attack is short.
    - Everyone else holds at its anchor (at the contact height).
    """

    half_length: float = 0.0  # the task's court
    team_size: int = 1
    default_cfg = MatchConfig()
    default_touch = TouchConfig(contact_z=2.6, first_contact_z=2.1, early=(1,))

    def __init__(self, action_space="prt", params=None, gains=None, cfg: MatchConfig | None = None, touch: TouchConfig | None = None):
        super().__init__(action_space, params, gains, touch or self.default_touch)
        self.cfg = cfg or self.default_cfg

    def parse(self, drone, t):
        """(anchor, ball position, ball velocity, I may hit, my team's turn, my teammates' positions [..., k, 3])."""
        anchor = drone.pos - t[..., 0:3]
        if self.team_size == 1:
            ball_p, ball_v = drone.pos - t[..., 3:6], t[..., 6:9]
            may = t[..., 12] > 0.5
            return anchor, ball_p, ball_v, may, may, drone.pos.unsqueeze(-2)
        k = self.team_size
        ball_p, ball_v = drone.pos + t[..., 3:6], t[..., 6:9]
        team_turn = t[..., 9] > 0.5
        may = t[..., 11 + k] > 0.5
        pos = t[..., 13 + k : 13 + k + 3 * k].unflatten(-1, (k, 3))
        return anchor, ball_p, ball_v, may, team_turn, pos

    def act(self, drone, t):
        c = self.cfg
        g = self.params.gravity
        anchor, ball_p, ball_v, may, team_turn, team_pos = self.parse(drone, t)
        contact_z = self.contact_height(ball_p, ball_v)
        # where the ball comes down to the contact height; the nearest teammate takes it
        fall, _ = crossing(ball_p, ball_v, contact_z, g)
        d = (team_pos[..., :2] - fall[..., None, :2]).norm(dim=-1)
        me = (team_pos[..., :2] - drone.pos[..., None, :2]).norm(dim=-1).argmin(-1)
        nearest = d.argmin(-1) == me
        # a ball coming down too close to the net is let go: reaching it would cross (losing anyway)
        mine = may & team_turn & (nearest | (self.team_size == 1)) & (fall[..., 0] > c.guard_x + c.reach_margin)
        attack_xy = torch.tensor((-c.depth * self.half_length, 0.0), dtype=ball_p.dtype, device=ball_p.device)
        # the teammate nearest the net (not me) receives a back-court pass
        others_x = torch.where(torch.arange(team_pos.shape[-2], device=me.device) == me.unsqueeze(-1), torch.full_like(team_pos[..., 0], float("inf")), team_pos[..., 0])
        front = others_x.argmin(-1) if self.team_size > 1 else me
        set_xy = torch.gather(team_pos[..., :2], -2, front[..., None, None].expand(*front.shape, 1, 2)).squeeze(-2)
        deep = (fall[..., 0] > c.back_x * self.half_length) & (self.team_size > 1)
        apex = torch.maximum(torch.as_tensor(2.43 + c.net_clear), contact_z + 0.5)

        def want_out(bp, bv):
            over = launch_for_apex(bp, attack_xy.expand_as(bp[..., :2]), apex, 0.2, g)
            fwd = launch_for_apex(bp, set_xy, apex, self.touch.contact_z + self.planner.reach, g)
            return torch.where(deep.unsqueeze(-1), fwd, over)

        home = with_z(anchor[..., :2], self.touch.contact_z)
        action = self.play(drone, ball_p, ball_v, want_out, mine, home)
        back = self.ctrl.act(drone, home, torch.zeros_like(home))
        return torch.where((drone.pos[..., :1] < c.guard_x), back, action)


class OneVsOnePlayer(_MatchPlayer):
    task = "1v1"
    half_length = COURTS["1v1"].length / 2
    team_size = 1
    # on the small court a shot 30 % deep comes down where the receiver must let it go (too close to
    # the net); deep shots are playable. The serve is met higher: from 2.1 m it goes into the net.
    default_cfg = MatchConfig(depth=0.8)
    default_touch = TouchConfig(contact_z=2.6, first_contact_z=2.4, early=(1,))


class ThreeVsThreePlayer(_MatchPlayer):
    task = "3v3"
    half_length = COURTS["3v3"].length / 2
    team_size = 3


class SixVsSixPlayer(_MatchPlayer):
    task = "6v6"
    half_length = COURTS["full"].length / 2
    team_size = 6


SCRIPTED_POLICIES.update({cls.task: cls for cls in (OneVsOnePlayer, ThreeVsThreePlayer, SixVsSixPlayer,)})
