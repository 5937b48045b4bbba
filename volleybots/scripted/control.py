"""Batched model-based flight control: position loop -> thrust vector -> attitude -> PRT or CTBR action.

The cascade is the usual one for quadrotors (Mellinger & Kumar 2011, Brescianini et al. 2013):

1. ``position_accel``: a PD law on a reference (position, velocity, feed-forward acceleration) gives
   the acceleration the drone should have; the model's gravity and linear damping are cancelled.
2. ``thrust_vector``: that acceleration plus gravity is the specific thrust the rotors must give,
   clipped to what the airframe can produce (vertical first, then as much horizontal as is left).
3. ``DroneController.act``: a reduced-attitude law turns the thrust direction into body-rate targets;
   for CTBR those rates and the collective thrust *are* the action (the env's rate controller does the
   rest), for PRT an inner rate loop, an exact allocation inverse of the airframe (the Iris's front and
   rear arms differ, so hover thrusts differ per rotor) and an inversion of the rotor lag give the four
   rotor commands.

Everything works on tensors of any batch shape ``[..., 3]`` on any device, so one controller drives
every drone of every env at once; nothing here keeps state between calls.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import torch

from volleybots.physics.controllers import RateController
from volleybots.physics.math import num, quat_axes, quat_rotate_inverse
from volleybots.physics.params import WorldParams
from volleybots.tasks.layout import root_layout


@dataclass(frozen=True)
class Gains:
    """Gains of the cascade. Units: 1/s^2 (kp), 1/s (kd, k_att, k_rate)."""

    k_pos_xy: float = 2.5  # 1/s: position error -> velocity correction
    k_pos_z: float = 3.0
    pos_accel_xy: float = 4.0  # m/s^2 the position law plans to brake with, beyond its linear range
    pos_accel_z: float = 3.0
    k_vel_xy: float = 5.0  # 1/s: velocity error -> acceleration
    k_vel_xy_ctbr: float = 4.0  # ... through the slower CTBR attitude loop
    k_vel_z: float = 7.0
    k_att: float = 20.0  # tilt error (rad) -> body rate (rad/s), PRT
    k_att_ctbr: float = 10.0  # the CTBR rate loop is slower, so the attitude loop must be too
    att_accel: float = 12.0  # rad/s^2 the attitude law plans to brake with (the Iris can do about 35 at hover)
    att_accel_ctbr: float = 15.0
    att_delay: float = 0.05  # s: rotor lag plus the hold of a control step, anticipated by the attitude law
    k_rate: float = 30.0  # PRT inner loop: rate error -> angular acceleration
    max_tilt: float = math.radians(30.0)
    thrust_margin: float = 0.95  # fraction of the maximum total thrust the position loop may ask for
    min_thrust_z: float = 5.0  # m/s^2: with little thrust its direction swings wildly and attitude is slow to follow
    max_climb: float = 4.5  # m/s^2 of upward acceleration at most, so some thrust is left to steer
    vertical_first: bool = True  # over the thrust budget: serve the vertical first, else keep the direction
    thrust_keep: float = 0.9  # the allocation trades at most 10 % of the thrust for torque
    lag_comp: float = 0.5  # 1: invert the rotor lag fully (needs observed throttles), 0: ignore it


@dataclass
class DroneObs:
    """One drone's root state as the observation gives it (tasks/single.py, base.root_state)."""

    pos: torch.Tensor  # [..., 3]
    quat: torch.Tensor  # [..., 4] w x y z
    vel: torch.Tensor  # [..., 3] world
    omega_world: torch.Tensor  # [..., 3]
    throttle: torch.Tensor | None  # [..., 4] in [0, 1], None without throttles in the observation (CTBR)

    @classmethod
    def from_obs(cls, obs: torch.Tensor, with_throttle: bool) -> DroneObs:
        """From an observation whose first part is the root state (every task's)."""
        layout = root_layout(with_throttle)
        return cls.from_root(layout.split(obs[..., : layout.size]))

    @classmethod
    def from_root(cls, root: dict[str, torch.Tensor]) -> DroneObs:
        """From the named parts of a root state (``tasks.layout.ROOT_PARTS``)."""
        thr = root.get("throttle")
        return cls(root["pos"], root["quat"], root["vel"], root["omega"], None if thr is None else (thr + 1.0) * 0.5)

    @property
    def omega_body(self) -> torch.Tensor:
        return quat_rotate_inverse(self.quat, self.omega_world)

    @property
    def root_dim(self) -> int:
        return 23 if self.throttle is not None else 19


def _unit(v: torch.Tensor, eps: float = 1e-9) -> torch.Tensor:
    return v / v.norm(dim=-1, keepdim=True).clamp_min(num(eps, v))


class DroneController:
    """Reference state -> action in the env's action space (``"prt"`` or ``"ctbr"``), batched.

    ``act(drone, p_ref, v_ref, a_ref)`` tracks a reference; ``act_accel(drone, accel)`` flies a
    commanded acceleration (for guidance laws that are not a reference trajectory). The discrete
    action space is not supported: a model-based controller needs a continuous actuator.
    """

    def __init__(self, params: WorldParams | None = None, action_space: str = "prt", gains: Gains | None = None):
        if action_space not in ("prt", "ctbr"):
            raise ValueError(f"scripted control supports action spaces ['prt', 'ctbr'], got {action_space!r}")
        self.params = params or WorldParams()
        self.action_space = action_space
        self.gains = gains or Gains()
        d = self.params.drone
        self.g = self.params.gravity
        self.mass = d.mass
        self.kf = d.max_rotor_thrust
        self.max_accel = 4 * d.max_rotor_thrust / d.mass  # specific thrust at full throttle, m/s^2
        self.inertia = torch.tensor(d.inertia, dtype=torch.float64)
        rp = torch.tensor(d.rotor_positions, dtype=torch.float64)
        dirs = torch.tensor(d.directions, dtype=torch.float64)
        # allocation: rotor thrusts -> (total thrust, body torque x, y, z); same model as the physics
        alloc = torch.stack((torch.ones(4, dtype=torch.float64), rp[:, 1], -rp[:, 0], -dirs * d.max_rotor_moment / d.max_rotor_thrust))
        self.mix = torch.linalg.inv(alloc)  # [4 rotors, 4 wrench]
        # the rotor lag over one control step: the thrust the physics applies in sub-step k uses a
        # throttle that has closed 1 - (1 - lag)^k of the gap, so the step's mean throttle is
        # target + beta * (start - target)
        keep = 1.0 - self.params.lag_per_substep
        self.beta = sum(keep**k for k in range(1, self.params.substeps + 1)) / self.params.substeps
        self._cache: dict = {}

    # ------------------------------------------------------------------ constants per device
    def _c(self, ref: torch.Tensor) -> dict[str, torch.Tensor]:
        key = (ref.device, ref.dtype)
        if key not in self._cache:
            self._cache[key] = {
                "mix": self.mix.to(ref.device, ref.dtype),
                "inertia": self.inertia.to(ref.device, ref.dtype),
                "ez": torch.tensor((0.0, 0.0, 1.0), device=ref.device, dtype=ref.dtype),
            }
        return self._cache[key]

    # ------------------------------------------------------------------ outer loops
    def position_accel(self, drone: DroneObs, p_ref, v_ref, a_ref=None) -> torch.Tensor:
        """Tracking law: the acceleration [..., 3] the drone should have now.

        Position error -> velocity correction by a square-root law (a large error asks for a speed
        the drone can brake from, not for a huge tilt), velocity error -> acceleration, plus the
        reference's feed-forward acceleration. Horizontal and vertical are shaped separately."""
        g = self.gains
        e = p_ref - drone.pos
        k = functools.partial(num, like=e)
        eh = e[..., :2]
        dist = eh.norm(dim=-1, keepdim=True)
        v_h = eh / dist.clamp_min(k(1e-9)) * sqrt_law(dist, g.k_pos_xy, g.pos_accel_xy)
        ez = e[..., 2:]
        v_z = torch.sign(ez) * sqrt_law(ez.abs(), g.k_pos_z, g.pos_accel_z)
        dv = v_ref + torch.cat((v_h, v_z), -1) - drone.vel
        k_xy = g.k_vel_xy_ctbr if self.action_space == "ctbr" else g.k_vel_xy
        acc = torch.cat((k(k_xy) * dv[..., :2], k(g.k_vel_z) * dv[..., 2:]), -1)
        return acc if a_ref is None else acc + a_ref

    def thrust_vector(self, drone: DroneObs, accel: torch.Tensor) -> torch.Tensor:
        """Specific thrust (m/s^2, world) that yields ``accel``, clipped to the airframe's envelope.

        Gravity and the model's linear damping are cancelled here. With ``vertical_first`` the
        vertical part is served first and the horizontal gets what is left of the thrust budget
        (holding height matters most when hovering); otherwise an over-budget vector keeps its
        direction and is shortened (for manoeuvres whose direction is the point). Both respect
        the tilt limit.
        """
        g = self.gains
        k = functools.partial(num, like=accel)
        f = accel + k(self.params.drone.lin_damping) * drone.vel
        fmax = g.thrust_margin * self.max_accel
        fz = (f[..., 2] + k(self.g)).clamp(k(g.min_thrust_z), k(min(fmax, self.g + g.max_climb)))
        h = f[..., :2]
        if not g.vertical_first:
            scale = (torch.cat((h, fz.unsqueeze(-1)), -1).norm(dim=-1).reciprocal() * k(fmax)).clamp(max=k(1.0))
            h, fz = h * scale.unsqueeze(-1), fz * scale
        h_max = torch.minimum(torch.sqrt((k(fmax**2) - fz**2).clamp_min(k(0.0))), fz * k(math.tan(g.max_tilt)))
        h_norm = h.norm(dim=-1)
        h = h * (h_max / h_norm.clamp_min(k(1e-9))).clamp(max=k(1.0)).unsqueeze(-1)
        return torch.cat((h, fz.unsqueeze(-1)), -1)

    # ------------------------------------------------------------------ attitude and actuation
    def body_rates(
        self, drone: DroneObs, b3_des: torch.Tensor, k_att: float, brake: float, yaw_rate: torch.Tensor | None = None
    ) -> torch.Tensor:
        """Reduced-attitude law: rotate the body z axis onto ``b3_des`` at a rate proportional to the
        angle between them (well defined up to 180 degrees, unlike the SO(3) error's sine), and for
        large angles no faster than a braking of ``brake`` rad/s^2 can stop on the target: the
        torque is limited, so a linear law would overshoot large turns."""
        _, up = quat_axes(drone.quat)
        axis = torch.cross(up, b3_des, dim=-1)
        angle = torch.atan2(axis.norm(dim=-1), (up * b3_des).sum(-1))
        axis_b = _unit(quat_rotate_inverse(drone.quat, axis))
        # the rotors answer with a delay: brake for the angle that will be left after it
        closing = (drone.omega_body * axis_b).sum(-1)
        left = angle - num(self.gains.att_delay, closing) * closing
        speed = torch.sign(left) * sqrt_law(left.abs(), k_att, brake)
        rates = axis_b * speed.unsqueeze(-1)
        yaw = torch.zeros_like(angle) if yaw_rate is None else yaw_rate
        return torch.cat((rates[..., :2], yaw.unsqueeze(-1)), -1)

    def act(self, drone: DroneObs, p_ref, v_ref, a_ref=None, yaw_rate=None) -> torch.Tensor:
        return self.act_accel(drone, self.position_accel(drone, p_ref, v_ref, a_ref), yaw_rate)

    def act_accel(self, drone: DroneObs, accel: torch.Tensor, yaw_rate=None) -> torch.Tensor:
        return self.act_thrust(drone, self.thrust_vector(drone, accel), yaw_rate)

    def act_thrust(self, drone: DroneObs, f: torch.Tensor, yaw_rate=None) -> torch.Tensor:
        """Fly the specific thrust vector ``f`` [..., 3] (world): the action [..., 4] in [-1, 1]."""
        b3 = _unit(f)
        _, up = quat_axes(drone.quat)
        # thrust along the body axis we have now, so a tilt error does not turn into a height error
        k = functools.partial(num, like=f)
        collective = (f * up).sum(-1).clamp_min(k(0.0))
        if self.action_space == "ctbr":
            rates = self.body_rates(drone, b3, self.gains.k_att_ctbr, self.gains.att_accel_ctbr, yaw_rate)
            rate_act = rates / k(math.radians(RateController.max_rate_deg))
            thrust_act = k(2.0) * collective * k(self.mass) / k(4 * self.kf) - k(1.0)
            return torch.cat((rate_act, thrust_act.unsqueeze(-1)), -1).clamp(-k(1.0), k(1.0))
        rates = self.body_rates(drone, b3, self.gains.k_att, self.gains.att_accel, yaw_rate)
        return self.rotor_commands(drone, collective * k(self.mass), rates)

    def rotor_commands(self, drone: DroneObs, thrust: torch.Tensor, rates_des: torch.Tensor) -> torch.Tensor:
        """PRT inner loop: body-rate targets and total thrust (N) -> rotor commands in [-1, 1]."""
        c = self._c(thrust)
        J = c["inertia"]
        w = drone.omega_body
        d = self.params.drone
        k = functools.partial(num, like=thrust)
        alpha = k(self.gains.k_rate) * (rates_des - w) + k(d.ang_damping) * w
        torque = J * alpha + torch.cross(w, J * w, dim=-1)
        t = self.allocate(thrust, torque)
        kf, zero, one = k(self.kf), k(0.0), k(1.0)
        if drone.throttle is not None and self.gains.lag_comp > 0:
            # choose the throttle target whose mean over the coming step is the wanted throttle
            want = torch.sqrt(t / kf)
            b = self.beta * self.gains.lag_comp
            target = ((want - k(b) * drone.throttle) / k(1.0 - b)).clamp(zero, one)
            t = target * target * kf
        return (k(2.0) * t / kf - one).clamp(-one, one)

    def allocate(self, thrust: torch.Tensor, torque: torch.Tensor) -> torch.Tensor:
        """Total thrust [...] and body torque [..., 3] -> rotor thrusts [..., 4] in [0, KF].

        Where both cannot be had, the thrust gives way first, but never below ``thrust_keep`` of
        the request (a drone that keeps its attitude but drops out of the sky is no better); past
        that the torque is scaled down just enough to fit.
        """
        mix = self._c(thrust)["mix"]
        k = functools.partial(num, like=thrust)
        kf = k(self.kf)
        w = torque @ mix[:, 1:].T  # [..., 4] torque part, sums to zero
        # rotor share of one newton of total thrust, laid out as w: dividing by the broadcast [4]
        # runs a 4-long inner loop, ~6x slower on a lookahead's 10^4 rollouts (the same quotients)
        u = mix[:, 0].expand(w.shape).contiguous()
        floor = k(self.gains.thrust_keep) * thrust.clamp(max=k(4 * self.kf))

        def bounds(wk):
            # thrust range keeping every rotor in [0, KF]: 0 <= T u_i + w_i <= KF
            lo = (-wk / u).amax(-1)
            hi = ((kf - wk) / u).amin(-1)
            return torch.maximum(lo, floor), hi

        lo, hi = bounds(w)
        ok = lo <= hi
        # bisection on the torque scale where no thrust fits (saturated manoeuvres); with none, the
        # torque stays as it is (times 1: the same numbers), without the bisection's ~100 torch calls
        if not bool(ok.all()):
            s_lo, s_hi = torch.zeros_like(thrust), torch.ones_like(thrust)
            half = k(0.5)
            for _ in range(10):
                mid = half * (s_lo + s_hi)
                l2, h2 = bounds(w * mid.unsqueeze(-1))
                fits = l2 <= h2
                s_lo = torch.where(fits, mid, s_lo)
                s_hi = torch.where(fits, s_hi, mid)
            w = w * torch.where(ok, torch.ones_like(s_lo), s_lo).unsqueeze(-1)
            lo, hi = bounds(w)
        total = torch.minimum(torch.maximum(thrust, lo), hi)
        t = total.unsqueeze(-1) * u + w
        return t.clamp(k(0.0), kf)


def sqrt_law(error: torch.Tensor, k: float, accel: float) -> torch.Tensor:
    """Rate to close ``error`` (>= 0): linear ``k * error`` close in, beyond ``accel / k^2`` the speed
    from which a deceleration of ``accel`` stops on target (continuous, with a continuous slope; the
    "square-root controller" of ArduPilot). A linear law alone would demand decelerations of
    ``k^2 * error`` that a torque- or thrust-limited airframe cannot give."""
    linear = accel / (k * k)
    n = functools.partial(num, like=error)
    return torch.where(error <= n(linear), n(k) * error, torch.sqrt((n(2.0 * accel) * (error - n(0.5 * linear))).clamp_min(n(0.0))))


def heading_yaw_rate(drone: DroneObs, yaw_des: torch.Tensor | float, k: float) -> torch.Tensor:
    """Yaw-rate command turning the heading toward ``yaw_des`` (rad), wrapped to the short way."""
    heading, _ = quat_axes(drone.quat)
    yaw = torch.atan2(heading[..., 1], heading[..., 0])
    err = torch.remainder(torch.as_tensor(yaw_des, dtype=yaw.dtype, device=yaw.device) - yaw + math.pi, 2 * math.pi) - math.pi
    return k * err


__all__ = ["DroneController", "DroneObs", "Gains", "heading_yaw_rate", "sqrt_law"]
