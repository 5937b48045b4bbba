"""The base of the scripted players of the multi-drone tasks, built from the single-drone pieces
(control.py, plan.py, and the strike flight of policies.py). The players themselves live one task
family per module: bump_and_pass.py (a bump-and-pass pair), set_and_spike.py (a setter and an
attacker) and match.py (a match player used by teams of 1, 3 and 6).

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

from volleybots.scripted.control import DroneObs
from volleybots.scripted.plan import StrikePlanner
from volleybots.scripted.policies import _BallPolicy

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
    early_feed: bool = True  # ... with the contact's velocity and acceleration fed forward the whole way (False: from the lock on)
    max_tilt: float = math.radians(40.0)


class _Player(_BallPolicy):
    """A ball-playing scripted player: plans and flies one touch; subclasses say where it goes."""

    def __init__(self, action_space="prt", params=None, gains=None, touch: TouchConfig = TouchConfig()):
        super().__init__(action_space, params, gains)
        self.touch = touch
        self.planner = StrikePlanner(self.params)

    def contact_height(self, ball_p, ball_v, drop=None, drone_z=None) -> torch.Tensor:
        """Ball-centre height of the next contact: the drone centre at ``drone_z`` [...] (default: the
        opening drop is met low, any other ball at the contact height), lower for a ball that will not
        come up that high under its apex. ``drop`` [...] marks the opening drop (default: ``is_drop``)."""
        t = self.touch
        if drone_z is None:
            drone_z = torch.where(is_drop(ball_v) if drop is None else drop, t.first_contact_z, t.contact_z)
        return torch.minimum(drone_z + self.planner.reach, apex_height(ball_p, ball_v, self.params.gravity) - t.apex_margin)

    def play(self, drone: DroneObs, ball_p, ball_v, want_out, mine: torch.Tensor, wait: torch.Tensor, early=None,
             drop=None, drone_z=None, idle=None, touch: TouchConfig | None = None) -> torch.Tensor:
        """Fly the touch given by ``want_out(ball_at_contact, ball_velocity_in) -> v_out`` where
        ``mine`` [...] is set, from ``wait`` [..., 3]; elsewhere hold still at ``idle`` (default
        ``wait``). ``drop`` and ``drone_z`` as in ``contact_height``: a player that tells the opening
        drop apart better than by the ball's speed, or meets balls at other heights, says so;
        ``touch`` times this touch's approach instead of the player's own ``TouchConfig``."""
        t = touch or self.touch
        drop = is_drop(ball_v) if drop is None else drop
        strike = self.planner.plan(ball_p, ball_v, self.contact_height(ball_p, ball_v, drop, drone_z), want_out, t.max_tilt)
        window = torch.where(drop, t.first_window, t.window)
        lock = torch.where(drop, t.first_lock, t.lock)
        hit = self.strike_action(drone, strike, wait, window, lock, early=t.early if early is None else early, early_feed=t.early_feed)
        idle = wait if idle is None else idle
        idle = self.ctrl.act(drone, idle, torch.zeros_like(idle))
        return torch.where(mine.unsqueeze(-1), hit, idle)
