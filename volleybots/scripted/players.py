"""Scripted players of the multi-drone tasks, built from the single-drone pieces (control.py, plan.py,
and the strike flight of policies.py): a bump-and-pass pair, a setter and an attacker, and a match
player used by teams of 1, 3 and 6.

Like every scripted policy they read ``("agents", "observation")`` only and write
``("agents", "action")``; each agent decides from its own observation (they share no memory and keep
none between steps). What they may know besides the observation are the task's constants: anchors,
court, target. Observation layouts: tasks/coop.py and tasks/match.py (matches are seen in the
agent's own mirrored frame, where its half is x > 0).

Every touch is one ``StrikePlanner`` plan: where the ball comes down through the contact height, the
outgoing velocity the play wants, and the racket normal and speed that give it; the drone flies it
with ``strike_action`` (hold behind the contact point, a timed approach, the racket locked on the
normal for the last moments). The first touch of a ball dropped from rest is special: the drone starts
at rest and has only the fall to get under the ball, so it meets it lower and asks less of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from volleybots.scripted.ballistics import crossing, launch_for_apex, launch_for_range, racket_for
from volleybots.scripted.control import DroneObs
from volleybots.scripted.plan import StrikePlanner
from volleybots.rules import COURTS
from volleybots.scripted.policies import SCRIPTED_POLICIES, _BallPolicy

DROP_SPEED = 0.5  # m/s: a ball moving horizontally slower than this is the opening drop (at rest at reset)


def apex_height(pos: torch.Tensor, vel: torch.Tensor, g: float) -> torch.Tensor:
    """[...] apex height of the ball's parabola (past or future): constant along a free flight."""
    return pos[..., 2] + vel[..., 2] ** 2 / (2.0 * g)


def is_drop(ball_vel: torch.Tensor) -> torch.Tensor:
    return ball_vel[..., :2].norm(dim=-1) < DROP_SPEED


def with_z(xy: torch.Tensor, z) -> torch.Tensor:
    return torch.cat((xy, torch.as_tensor(z, dtype=xy.dtype, device=xy.device).expand_as(xy[..., :1])), -1)


@dataclass(frozen=True)
class TouchConfig:
    """How a player meets the ball: heights, approach timing and limits."""

    contact_z: float = 2.6  # drone centre height at contact
    first_contact_z: float = 2.1  # ... for the opening drop (from rest there is no time to climb)
    apex_margin: float = 0.3  # a ball peaking below the contact height is met this far under its apex
    window: float = 0.4  # s of the timed approach into the contact state
    first_window: float = 0.4
    lock: float = 0.25  # s before contact the racket is locked on the planned normal
    first_lock: float = 0.3
    early: tuple[int, ...] = (0,)  # world axes flown straight to the contact point (no racket speed along them)
    max_tilt: float = math.radians(40.0)


class _Player(_BallPolicy):
    """A ball-playing scripted player: plans and flies one touch; subclasses say where it goes."""

    def __init__(self, action_space="prt", params=None, gains=None, touch: TouchConfig = TouchConfig()):
        super().__init__(action_space, params, gains)
        self.touch = touch
        self.planner = StrikePlanner(self.params)

    def contact_height(self, ball_p, ball_v) -> torch.Tensor:
        """Ball-centre height of the next contact: the opening drop is met low, a ball that will not
        come up to the contact height under its apex."""
        t = self.touch
        z = torch.where(is_drop(ball_v), t.first_contact_z, t.contact_z) + self.planner.reach
        return torch.minimum(z, apex_height(ball_p, ball_v, self.params.gravity) - t.apex_margin)

    def play(self, drone: DroneObs, ball_p, ball_v, want_out, mine: torch.Tensor, wait: torch.Tensor, early=None) -> torch.Tensor:
        """Fly the touch given by ``want_out(ball_at_contact, ball_velocity_in) -> v_out`` where
        ``mine`` [...] is set; elsewhere hold still at ``wait`` [..., 3]."""
        t = self.touch
        drop = is_drop(ball_v)
        strike = self.planner.plan(ball_p, ball_v, self.contact_height(ball_p, ball_v), want_out, t.max_tilt)
        window = torch.where(drop, t.first_window, t.window)
        lock = torch.where(drop, t.first_lock, t.lock)
        hit = self.strike_action(drone, strike, wait, window, lock, early=t.early if early is None else early)
        idle = self.ctrl.act(drone, wait, torch.zeros_like(wait))
        return torch.where(mine.unsqueeze(-1), hit, idle)


# --------------------------------------------------------------------------- Bump and Pass
@dataclass(frozen=True)
class PassConfig:
    inward: float = 1.0  # the drones play this much closer to each other than their anchors: less tilt
    apex: float = 4.2  # a bump counts when it crosses the midline above 4 m; passes come out a little low
    first_apex: float = 4.0  # from rest the drone cannot swing hard enough for more


class BumpAndPassPlayer(_Player):
    """Each drone bumps the ball over to its partner's spot when it is its turn, and otherwise waits
    at its own spot (its anchor moved ``inward`` toward the partner, at the contact height)."""

    task = "bump_and_pass"

    def __init__(self, action_space="prt", params=None, gains=None, cfg: PassConfig = PassConfig(),
                 touch: TouchConfig = TouchConfig(contact_z=1.8)):
        # met low (1.8 m, not 2.6 m) the ball falls longer between passes: more time to get under it
        super().__init__(action_space, params, gains, touch)
        self.cfg = cfg

    def act(self, drone, t):
        c = self.cfg
        anchor = drone.pos - t[..., 0:3]
        ball_p, ball_v = self.ball(drone, t)
        my_turn = (t[..., 12:14] * t[..., 14:16]).sum(-1) > 0.5
        side = torch.sign(anchor[..., 1:2])  # -1 for drone 1, +1 for drone 2
        spot_xy = torch.cat((anchor[..., :1], anchor[..., 1:2] - side * c.inward), -1)
        partner_xy = spot_xy * torch.tensor([1.0, -1.0], dtype=spot_xy.dtype, device=spot_xy.device)
        apex = torch.where(is_drop(ball_v), c.first_apex, c.apex)
        land_z = self.touch.contact_z + self.planner.reach

        def want_out(bp, bv):
            return launch_for_apex(bp, partner_xy, apex, land_z, self.params.gravity)

        return self.play(drone, ball_p, ball_v, want_out, my_turn, with_z(spot_xy, self.touch.contact_z))


# --------------------------------------------------------------------------- Set and Spike
@dataclass(frozen=True)
class SpikeConfig:
    attack_spot: tuple[float, float, float] = (1.5, 0.5, 3.0)  # where the attacker meets the set (drone centre), clear of the net
    set_apex: float = 4.6  # the set's apex: a steep fall onto the attacker needs less racket tilt
    target: tuple[float, float] = (-4.5, 0.0)  # where the spike should land
    land_z: float = 0.1
    elevations: tuple[float, float, int] = (-40.0, -1.0, 40)  # downward launch angles tried for the spike (deg)
    max_vx: float = float("inf")  # cap on the spike's speed toward -x (a tip under 2 m/s never wakes the defence racket)


class SetAndSpikePlayer(_Player):
    """Drone 1 (the setter) sets the dropped ball to the attack spot; drone 2 (the attacker) waits
    there and spikes it down to the target with the launch angle that needs the least racket tilt.
    Before and after its touch each waits at its spot."""

    task = "set_and_spike_easy"

    def __init__(self, action_space="prt", params=None, gains=None, cfg: SpikeConfig = SpikeConfig(),
                 touch: TouchConfig = TouchConfig(contact_z=3.0, first_contact_z=2.45, early=())):
        super().__init__(action_space, params, gains, touch)
        self.cfg = cfg

    def spike(self, bp, bv):
        """Outgoing velocity [..., 3] that lands the ball on the target, going down, with the least tilt."""
        c = self.cfg
        lo, hi, k = c.elevations
        elev = torch.deg2rad(torch.linspace(lo, hi, k, dtype=bp.dtype, device=bp.device))
        shape = bp.shape[:-1] + (k,)
        target = torch.tensor(c.target, dtype=bp.dtype, device=bp.device).expand(*shape, 2)
        v = launch_for_range(bp.unsqueeze(-2).expand(*shape, 3), target, c.land_z, elev.expand(shape))
        n, _ = racket_for(bv.unsqueeze(-2).expand_as(v), v, self.params.ball.restitution)
        cost = torch.where(torch.isfinite(v).all(-1) & (v[..., 0] >= -c.max_vx), -n[..., 2], torch.full_like(n[..., 2], float("inf")))
        best = cost.argmin(-1)
        return torch.gather(v, -2, best[..., None, None].expand(*bp.shape[:-1], 1, 3)).squeeze(-2)

    def act(self, drone, t):
        c = self.cfg
        anchor = drone.pos - t[..., 0:3]
        ball_p, ball_v = self.ball(drone, t)
        turn = t[..., 12:15]
        setter = t[..., 15] > 0.5
        attack = torch.tensor(c.attack_spot, dtype=ball_p.dtype, device=ball_p.device)
        land_z = attack[2] + self.planner.reach

        def want_out(bp, bv):
            set_v = launch_for_apex(bp, attack[:2].expand_as(bp[..., :2]), c.set_apex, land_z, self.params.gravity)
            return torch.where(setter.unsqueeze(-1), set_v, self.spike(bp, bv))

        mine = torch.where(setter, turn[..., 0] > 0.5, turn[..., 1] > 0.5)
        wait = torch.where(setter.unsqueeze(-1), anchor, attack.expand_as(anchor))
        return self.play(drone, ball_p, ball_v, want_out, mine, wait)


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


class SetAndSpikeHardPlayer(SetAndSpikePlayer):
    task = "set_and_spike_hard"


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


PLAYERS = (BumpAndPassPlayer, SetAndSpikePlayer, SetAndSpikeHardPlayer, OneVsOnePlayer, ThreeVsThreePlayer, SixVsSixPlayer)
SCRIPTED_POLICIES.update({cls.task: cls for cls in PLAYERS})
