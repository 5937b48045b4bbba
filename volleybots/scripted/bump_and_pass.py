"""Scripted Bump and Pass pair: each drone bumps the ball over to its partner when it is its turn."""

from __future__ import annotations

from dataclasses import dataclass

import torch

from volleybots.scripted.ballistics import launch_for_apex
from volleybots.scripted.control import Gains
from volleybots.scripted.players import TouchConfig, _Player, is_drop, with_z
from volleybots.scripted.policies import SCRIPTED_POLICIES


# --------------------------------------------------------------------------- Bump and Pass
@dataclass(frozen=True)
class PassConfig:
    inward: float = 1.0  # the drones play this much closer to each other than their anchors: less tilt
    apex: float = 4.2  # a bump counts when it crosses the midline above 4 m; passes come out a little low
    first_apex: float = 4.0  # from rest the drone cannot swing hard enough for more
    first_to: float = 1.1  # |y| the opening pass is aimed at, and where the receiver waits during the drop


# the receiver of a pass flies up to 2 m to the ball and must arrive still: it plans its braking with
# 2.5 m/s^2, not the default 4, which it overshoots (then the ball meets its body, not the racket)
PASS_GAINS = Gains(pos_accel_xy=2.5)


class BumpAndPassPlayer(_Player):
    """Each drone bumps the ball over to its partner's spot when it is its turn, and otherwise waits
    at its own spot (its anchor moved ``inward`` toward the partner, at the contact height).

    The opening pass (of the ball dropped from rest) comes out weaker and less precise than the
    others: it is aimed short, near the midline, where the receiver waits for it during the drop."""

    task = "bump_and_pass"

    def __init__(self, action_space="prt", params=None, gains=None, cfg: PassConfig = PassConfig(),
                 touch: TouchConfig = TouchConfig(contact_z=1.8)):
        # met low (1.8 m, not 2.6 m) the ball falls longer between passes: more time to get under it
        super().__init__(action_space, params, gains or PASS_GAINS, touch)
        self.cfg = cfg

    def act(self, drone, t):
        c = self.cfg
        anchor = drone.pos - t[..., 0:3]
        ball_p, ball_v = self.ball(drone, t)
        my_turn = (t[..., 12:14] * t[..., 14:16]).sum(-1) > 0.5
        side = torch.sign(anchor[..., 1:2])  # -1 for drone 1, +1 for drone 2
        drop = is_drop(ball_v).unsqueeze(-1)
        spot_y = torch.where(drop, side * c.first_to, anchor[..., 1:2] - side * c.inward)
        spot_xy = torch.cat((anchor[..., :1], spot_y), -1)
        partner_xy = spot_xy * torch.tensor([1.0, -1.0], dtype=spot_xy.dtype, device=spot_xy.device)
        apex = torch.where(drop.squeeze(-1), c.first_apex, c.apex)
        land_z = self.touch.contact_z + self.planner.reach

        def want_out(bp, bv):
            return launch_for_apex(bp, partner_xy, apex, land_z, self.params.gravity)

        return self.play(drone, ball_p, ball_v, want_out, my_turn, with_z(spot_xy, self.touch.contact_z))


SCRIPTED_POLICIES.update({cls.task: cls for cls in (BumpAndPassPlayer,)})
