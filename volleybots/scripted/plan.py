"""Trajectory primitives: quintic segments, a minimum-time "go to" law and the ball strike planner.

The strike planner is what every ball-playing scripted player uses: from the ball's state it
predicts when and where the ball comes down through a contact height, asks the caller which
velocity the ball should leave with, solves the racket normal and speed for that (ballistics.py),
and gives the drone a reference (position, velocity, acceleration) that arrives at the contact
point on time, with the racket tilted along the normal and moving at the right speed. The
reference is a pure function of the ball state, so a policy using it keeps no memory.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import torch

from volleybots.physics.math import num
from volleybots.physics.params import WorldParams
from volleybots.scripted.ballistics import ball_at, racket_for, time_to_height


def quintic(p0, v0, a0, p1, v1, a1, duration: torch.Tensor, t: torch.Tensor):
    """Evaluate at time ``t`` the quintic from (p0, v0, a0) to (p1, v1, a1) over ``duration``.

    States are [..., 3], ``duration`` and ``t`` are [...]. Returns (position, velocity, acceleration).
    The quintic is the minimum-jerk path between two full states (Mueller et al. 2015).
    """
    k = functools.partial(num, like=duration)  # the numbers as 0-d tensors: physics.math.num
    half = k(0.5)
    T = duration.clamp_min(k(1e-3)).unsqueeze(-1)
    t = t.unsqueeze(-1).clamp(min=k(0.0)).minimum(T)
    dp = p1 - p0 - v0 * T - half * a0 * T * T
    dv = v1 - v0 - a0 * T
    da = a1 - a0
    c3 = (k(10.0) * dp - k(4.0) * dv * T + half * da * T * T) / T**3
    c4 = (k(-15.0) * dp + k(7.0) * dv * T - da * T * T) / T**4
    c5 = (k(6.0) * dp - k(3.0) * dv * T + half * da * T * T) / T**5
    pos = p0 + v0 * t + half * a0 * t * t + c3 * t**3 + c4 * t**4 + c5 * t**5
    vel = v0 + a0 * t + k(3.0) * c3 * t**2 + k(4.0) * c4 * t**3 + k(5.0) * c5 * t**4
    acc = a0 + k(6.0) * c3 * t + k(12.0) * c4 * t**2 + k(20.0) * c5 * t**3
    return pos, vel, acc


def goto_accel(pos, vel, target, accel: float, speed: float, k_v: float = 6.0, k_p: float = 2.5, brake: float | None = None,
               stop_at: float = 0.0, lead: float = 0.0) -> torch.Tensor:
    """Near minimum-time guidance to ``target`` [..., 3]: fly at the speed from which a braking of
    ``brake`` (default ``accel``) stops ``stop_at`` metres short of the target, capped at ``speed``
    and, close in, at ``k_p`` times the distance (a plain P law there, no chatter); the speed is
    tracked with gain ``k_v``. The braking is planned ``lead`` seconds early: the drone needs that
    long to turn its thrust around. Returns the commanded acceleration, at most ``accel`` in norm."""
    d = target - pos
    k = functools.partial(num, like=d)
    zero = k(0.0)
    dist = d.norm(dim=-1, keepdim=True)
    closing = (vel * d).sum(-1, keepdim=True) / dist.clamp_min(k(1e-6))
    to_go = (dist - k(stop_at) - k(lead) * closing.clamp_min(zero)).clamp_min(zero)
    brake = accel if brake is None else brake
    v_mag = torch.minimum(torch.sqrt(k(2.0 * brake) * to_go), k(k_p) * to_go).clamp(max=k(speed))
    v_des = d / dist.clamp_min(k(1e-6)) * v_mag
    a = k(k_v) * (v_des - vel)
    n = a.norm(dim=-1, keepdim=True)
    return a * (n.clamp_min(k(1e-9)).reciprocal() * k(accel)).clamp(max=k(1.0))


@dataclass
class Strike:
    """A planned contact. Per batch element: time to go, the ball at contact, the racket solution,
    and the drone's state at contact (position of its centre, velocity and acceleration)."""

    t: torch.Tensor  # [...] seconds to contact, +inf when the ball never comes down to the height
    ball_pos: torch.Tensor  # [..., 3] ball centre at contact
    ball_in: torch.Tensor  # [..., 3] incoming ball velocity
    ball_out: torch.Tensor  # [..., 3] wanted outgoing velocity
    normal: torch.Tensor  # [..., 3] racket normal = body z axis at contact
    speed: torch.Tensor  # [...] racket speed along the normal at contact
    drone_pos: torch.Tensor  # [..., 3]
    drone_vel: torch.Tensor  # [..., 3]
    drone_acc: torch.Tensor  # [..., 3]

    @property
    def valid(self) -> torch.Tensor:
        return torch.isfinite(self.t)


class StrikePlanner:
    """Plans racket strikes for one airframe and ball (``WorldParams``).

    ``plan(ball_pos, ball_vel, contact_z, want_out)``: ``contact_z`` [...] is the height of the
    ball's centre at contact and ``want_out(ball_pos_at_contact, ball_vel_in) -> v_out`` says where
    the ball should go. The racket moves along its normal at contact (``drone_vel = speed * normal``)
    and the drone's acceleration at contact makes its thrust point along the normal, with
    ``contact_thrust`` m/s^2 of specific thrust (None: exactly what keeps the height).

    ``reference(strike, window)``: a fixed path into the contact state (hold, then a quintic).
    """

    def __init__(self, params: WorldParams | None = None, contact_thrust: float | None = None):
        self.params = params or WorldParams()
        self.g = self.params.gravity
        self.reach = self.params.ball.radius + self.params.drone.racket_offset  # ball centre above the drone centre
        self.e = self.params.ball.restitution
        self.contact_thrust = contact_thrust

    def plan(self, ball_pos, ball_vel, contact_z, want_out: Callable[[torch.Tensor, torch.Tensor], torch.Tensor],
             max_tilt: float | None = None) -> Strike:
        t = time_to_height(ball_pos[..., 2], ball_vel[..., 2], contact_z, self.g)
        t0 = torch.where(torch.isfinite(t), t, torch.zeros_like(t))
        bp, bv = ball_at(ball_pos, ball_vel, t0, self.g)
        v_out = want_out(bp, bv)
        n, s = racket_for(bv, v_out, self.e)
        k = functools.partial(num, like=n)
        if max_tilt is not None:
            n = limit_tilt(n, max_tilt)
            s = (bv * n).sum(-1) + (v_out - bv).norm(dim=-1) / k(1.0 + self.e)
        drone_pos = bp - k(self.reach) * n
        drone_vel = s.unsqueeze(-1) * n
        nz = n[..., 2].clamp_min(k(0.2))
        thrust = nz.reciprocal() * k(self.g) if self.contact_thrust is None else torch.full_like(nz, self.contact_thrust)
        drone_acc = thrust.unsqueeze(-1) * n
        drone_acc = torch.cat((drone_acc[..., :2], drone_acc[..., 2:] - k(self.g)), -1)
        return Strike(t, bp, bv, v_out, n, s, drone_pos, drone_vel, drone_acc)

    def hold_point(self, strike: Strike, window: float | torch.Tensor) -> torch.Tensor:
        """Behind the contact point by the distance a uniform acceleration from rest over ``window``
        seconds covers to reach the contact velocity."""
        window = torch.as_tensor(window, dtype=strike.t.dtype, device=strike.t.device).expand_as(strike.t)
        return strike.drone_pos - strike.drone_vel * (0.5 * window).unsqueeze(-1)

    def reference(self, strike: Strike, window: float | torch.Tensor, hold: torch.Tensor | None = None):
        """The drone's reference (position, velocity, acceleration) now: before the last ``window``
        seconds it holds still at ``hold`` (by default behind the contact point by the distance a
        uniform acceleration from rest covers), then it follows the quintic from there into the
        contact state. The path depends on the plan only, so re-planning every step gives the
        same path."""
        window = torch.as_tensor(window, dtype=strike.t.dtype, device=strike.t.device).expand_as(strike.t)
        if hold is None:
            hold = self.hold_point(strike, window)
        zero = torch.zeros_like(hold)
        elapsed = (window - strike.t).clamp_min(0.0)
        return quintic(hold, zero, zero, strike.drone_pos, strike.drone_vel, strike.drone_acc, window, elapsed)


def off_centre(strike: Strike, pos: torch.Tensor, slack: float) -> Strike:
    """Let the racket meet the ball up to ``slack`` metres off its centre, on the side where the
    drone (centre ``pos``) already is: a flat racket sends the ball the same way wherever it lands
    on it, and the drone has less to fly."""
    n = strike.normal
    d = pos - strike.drone_pos
    d = d - (d * n).sum(-1, keepdim=True) * n  # in the racket plane
    shift = d * (slack / d.norm(dim=-1, keepdim=True).clamp_min(1e-9)).clamp(max=1.0)
    strike.drone_pos = strike.drone_pos + shift
    return strike


def limit_tilt(n: torch.Tensor, max_tilt: float) -> torch.Tensor:
    """Tilt the unit vectors ``n`` back toward vertical so that they are at most ``max_tilt`` off it."""
    h = n[..., :2]
    hn = h.norm(dim=-1, keepdim=True)
    cap = torch.tan(torch.as_tensor(max_tilt, dtype=n.dtype, device=n.device))
    nz = n[..., 2:].clamp_min(1e-6)
    h = h * (cap * nz / hn.clamp_min(1e-9)).clamp(max=1.0)
    out = torch.cat((h, nz), -1)
    return out / out.norm(dim=-1, keepdim=True)


__all__ = ["Strike", "StrikePlanner", "goto_accel", "limit_tilt", "off_centre", "quintic"]
