"""Scripted players of the multi-drone tasks, built from the single-drone pieces (control.py, plan.py):
a bump-and-pass pair, a setter and an attacker, and a match player used by teams of 1, 3 and 6.

Like every scripted policy they read ``("agents", "observation")`` only and write
``("agents", "action")``; each agent decides from its own observation (they share no memory and keep
none between steps). What they may know besides the observation are the task's constants: anchors,
court, target. Layouts: tasks/coop.py and tasks/match.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from volleybots.scripted.ballistics import launch_for_apex
from volleybots.scripted.control import DroneObs
from volleybots.scripted.plan import StrikePlanner
from volleybots.scripted.policies import ScriptedPolicy


def strike_thrust(ctrl, planner: StrikePlanner, drone: DroneObs, strike, window: float, lead: float) -> torch.Tensor:
    """Specific thrust [..., 3] that flies ``strike``: the planner's reference (hold behind the contact
    point, then the last ``window`` seconds into the contact state) tracked by the position loop, and
    for the last ``lead`` seconds the thrust turned onto the racket normal (same vertical part): the
    attitude needs that long to follow, and the racket's tilt is what aims the ball."""
    p, v, a = planner.reference(strike, window)
    f = ctrl.thrust_vector(drone, ctrl.position_accel(drone, p, v, a))
    n = strike.normal
    f_n = f[..., 2:] / n[..., 2:].clamp_min(0.3) * n
    return torch.where((strike.t < lead).unsqueeze(-1), f_n, f)


def apex_height(pos: torch.Tensor, vel: torch.Tensor, g: float) -> torch.Tensor:
    """[...] the highest point of the ball's flight from now on."""
    return pos[..., 2] + vel[..., 2].clamp_min(0.0) ** 2 / (2.0 * g)


def hold_thrust(ctrl, drone: DroneObs, point: torch.Tensor) -> torch.Tensor:
    return ctrl.thrust_vector(drone, ctrl.position_accel(drone, point, torch.zeros_like(point)))


@dataclass(frozen=True)
class PassConfig:
    contact_z: float = 2.6  # drone centre height at contact
    first_contact_z: float = 2.1  # ... for the first touch of the ball dropped from rest (no time to climb)
    apex_margin: float = 0.3  # a ball peaking lower than the contact height is met this far below its apex
    inward: float = 0.5  # the drones play this much closer to each other than their anchors
    apex: float = 4.12  # a bump counts when it crosses the midline above 4 m
    window: float = 0.4  # s of approach before contact
    lead: float = 0.25  # s before contact the thrust turns onto the racket normal
    max_tilt: float = math.radians(40.0)


class BumpAndPassPlayer(ScriptedPolicy):
    """Each drone bumps the ball over to its partner when it is its turn, and otherwise waits at its
    playing spot (its anchor moved ``inward`` toward the partner, at the contact height)."""

    task = "bump_and_pass"

    def __init__(self, action_space="prt", params=None, gains=None, cfg: PassConfig = PassConfig()):
        super().__init__(action_space, params, gains)
        self.cfg = cfg
        self.planner = StrikePlanner(self.params)

    def act(self, drone, t):
        c = self.cfg
        anchor = drone.pos - t[..., 0:3]
        ball_p, ball_v = drone.pos - t[..., 3:6], t[..., 6:9]
        my_turn = (t[..., 12:14] * t[..., 14:16]).sum(-1) > 0.5
        side = torch.sign(anchor[..., 1:2])  # -1 for drone 0, +1 for drone 1
        spot = torch.cat((anchor[..., :1], anchor[..., 1:2] - side * c.inward, torch.full_like(side, c.contact_z)), -1)
        partner_xy = spot[..., :2] * torch.tensor([1.0, -1.0], dtype=spot.dtype, device=spot.device)
        # the opening drop falls straight down from rest: meet it near the drone's start height;
        # a pass that will not come up to the contact height is met lower, under its apex
        drop = ball_v[..., :2].norm(dim=-1) < 0.5
        contact_ball_z = torch.where(drop, c.first_contact_z, c.contact_z) + self.planner.reach
        contact_ball_z = torch.minimum(contact_ball_z, apex_height(ball_p, ball_v, self.params.gravity) - c.apex_margin)

        def want_out(bp, bv):
            return launch_for_apex(bp, partner_xy, c.apex, contact_ball_z, self.params.gravity)

        strike = self.planner.plan(ball_p, ball_v, contact_ball_z, want_out, c.max_tilt)
        play = (my_turn & strike.valid).unsqueeze(-1)
        f = torch.where(play, strike_thrust(self.ctrl, self.planner, drone, strike, c.window, c.lead), hold_thrust(self.ctrl, drone, spot))
        return self.ctrl.act_thrust(drone, f)
