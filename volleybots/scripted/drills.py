"""Scripted players of the hierarchical policy's drills: Serve, Pass, Set, Attack (tasks/drills.py).

Each is one touch of the 3 vs 3 scripted player's kind (``_Player.play``: one ``StrikePlanner`` plan,
flown by ``strike_action``), with the 3 vs 3 player's touch settings, and a play of its own (where
the ball should go). They read the drill's observation only (its named parts: tasks/drills.py), in
the team's own frame (its half is x > 0), plus the team's anchors, and keep no memory:

- **Serve** (the back drone): the dropped ball, met low as the match's serve is, sent with an apex
  of ``serve_apex`` to land on ``serve_aim`` in the opponent's half.
- **Pass** (the back drone): the ball coming over the net is flown for as soon as it heads for the
  own half (before it crosses: from the crossing on it may be touched, and a receiver starting then
  is late), and sent with an apex of ``pass_apex`` down through the contact height onto the front-left
  anchor, where the setter waits.
- **Set** (the front-left drone): the same, onto the front-right anchor.
- **Attack** (the front-right drone): over the net with an apex ``net_clear`` above its top, to land
  on the middle of the quarter of the opponent's court the ``side`` one-hot names.

Where the drone may not (or no longer) play the ball it waits at its anchor, at the contact height;
a drone closer than ``guard_x`` to the net backs off first (crossing it loses the rally).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import torch

from volleybots.scripted.ballistics import crossing, launch_for_apex
from volleybots.scripted.match import ThreeVsThreePlayer
from volleybots.scripted.players import _Player, with_z
from volleybots.scripted.policies import SCRIPTED_POLICIES
from volleybots.tasks.drills import CONTACT_Z, FRONT_LEFT, FRONT_RIGHT, TEAM_ANCHORS, Attack, Serve

NET_TOP = 2.43  # m


@dataclass(frozen=True)
class DrillConfig:
    apex: float = 4.8  # m: sets peak here (a setter swinging from rest set the Set and Spike balls this high)
    # m: passes peak here (higher asks less racket tilt of the passer: 4.8 m made 0.34 of the passes, 6.0 m 0.46-0.56)
    pass_apex: float = 6.0
    # m (x, y): the pass is aimed this far from the setter's anchor (x > 0: away from the net); aimed at
    # the anchor, passes came down 0.65 m short of it toward the net (seeds 0-1, docs/hierarchical.md)
    pass_aim: tuple[float, float] = (0.25, 0.1)
    serve_apex: float = 4.5  # m: the serve's apex
    serve_aim: tuple[float, float] = Serve.aim_xy  # where the serve lands (xy)
    net_clear: float = 3.0  # m above the net's top the attack peaks (the 3 vs 3 player's high, soft attack)
    attack_depth: float = -Attack.quarter[0]  # m from the net the attack lands ...
    attack_width: float = Attack.quarter[1]  # ... and this far to the named side of the middle line
    land_z: float = 0.2  # m: the ball lands when its centre is this low
    guard_x: float = 0.6  # m: closer to the net than this the drone backs off first


class _DrillPlayer(_Player):
    """A drill's touch: ``want_out`` says where the ball goes; ``mine`` when the drone plays it."""

    default_touch = ThreeVsThreePlayer.default_touch  # the match player's contact heights and approach

    def __init__(self, action_space="prt", params=None, gains=None, cfg: DrillConfig | None = None, touch=None):
        super().__init__(action_space, params, gains, touch or self.default_touch)
        self.cfg = cfg or DrillConfig()

    def ball(self, drone, obs):
        """Ball position and velocity (the drills observe ball minus drone, as the 3 vs 3 match)."""
        return drone.pos + obs["ball"], obs["ball_vel"]

    def want_out(self, bp: torch.Tensor, bv: torch.Tensor, obs) -> torch.Tensor:
        """The velocity [..., 3] the ball should leave the racket with."""
        raise TypeError(f"{type(self).__name__} must define want_out()")

    def mine(self, may: torch.Tensor, ball_p: torch.Tensor, ball_v: torch.Tensor) -> torch.Tensor:
        return may

    def to_teammate(self, bp: torch.Tensor, role: int, apex: float, shift=(0.0, 0.0)) -> torch.Tensor:
        """Down through the contact height onto a teammate's anchor (moved by ``shift``, xy), peaking at ``apex``."""
        kw = {"dtype": bp.dtype, "device": bp.device}
        target = torch.tensor(TEAM_ANCHORS[role][:2], **kw) + torch.tensor(shift, **kw)
        return launch_for_apex(bp, target, torch.maximum(torch.as_tensor(apex), bp[..., 2] + 0.5), CONTACT_Z, self.params.gravity)

    def act(self, drone, obs):
        anchor = drone.pos - obs["anchor"]
        ball_p, ball_v = self.ball(drone, obs)
        mine = self.mine(obs["may_hit"][..., 0] > 0.5, ball_p, ball_v)
        home = with_z(anchor[..., :2], self.touch.contact_z)
        action = self.play(drone, ball_p, ball_v, lambda bp, bv: self.want_out(bp, bv, obs), mine, home)
        back = self.ctrl.act(drone, home, torch.zeros_like(home))
        return torch.where(drone.pos[..., :1] < self.cfg.guard_x, back, action)


class ServePlayer(_DrillPlayer):
    task = "serve"

    def want_out(self, bp, bv, obs):
        aim = torch.tensor(self.cfg.serve_aim, dtype=bp.dtype, device=bp.device)
        return launch_for_apex(bp, aim, self.cfg.serve_apex, self.cfg.land_z, self.params.gravity)


class PassPlayer(_DrillPlayer):
    task = "pass"
    # the pass turns a ball flying in at ~6 m/s back toward the net: the racket tilts ~30 degrees,
    # which the drone reaches only with the racket locked on its normal for longer (0.25 s: no pass
    # came down within 1 m of the setter; 0.35 s: about half); met lower (drone at 2.2 m, not 2.6)
    # the ball has come nearer and the drone has had longer to get there (0.46 -> 0.5 of the passes);
    # with ``pass_aim`` (which takes the overshoot out) met lower still and locked 0.3 s: 0.73 / 0.76
    # of the passes on seeds 0 / 1, more of them coming down at all (93 % against 81 %)
    default_touch = replace(_DrillPlayer.default_touch, lock=0.3, contact_z=2.0)

    def mine(self, may, ball_p, ball_v):
        # a ball flying over the net toward the own half is played before it crosses
        fall, _ = crossing(ball_p, ball_v, self.touch.contact_z + self.planner.reach, self.params.gravity)
        incoming = (ball_p[..., 0] < 0) & (ball_v[..., 0] > 0) & (fall[..., 0] > self.cfg.guard_x)
        return may | incoming

    def want_out(self, bp, bv, obs):
        return self.to_teammate(bp, FRONT_LEFT, self.cfg.pass_apex, self.cfg.pass_aim)


class SetPlayer(_DrillPlayer):
    task = "set"

    def want_out(self, bp, bv, obs):
        return self.to_teammate(bp, FRONT_RIGHT, self.cfg.apex)


class AttackPlayer(_DrillPlayer):
    task = "attack"

    def want_out(self, bp, bv, obs):
        c = self.cfg
        right = obs["side"][..., 1:2] > 0.5
        y = torch.where(right, c.attack_width, -c.attack_width)
        aim = torch.cat((torch.full_like(y, -c.attack_depth), y), -1)
        return launch_for_apex(bp, aim, NET_TOP + c.net_clear, c.land_z, self.params.gravity)


DRILL_PLAYERS = (ServePlayer, PassPlayer, SetPlayer, AttackPlayer)
SCRIPTED_POLICIES.update({cls.task: cls for cls in DRILL_PLAYERS})

__all__ = ["AttackPlayer", "DRILL_PLAYERS", "DrillConfig", "PassPlayer", "ServePlayer", "SetPlayer"]
