"""Batched rigid-body, rotor, downwash and ball physics in PyTorch (spec: physics.md).

Pure dynamics: no volleyball rules live here. State tensors have shape [num_envs, n_drones, ...]
for drones and [num_envs, ...] for the ball; every function works on any torch device.
The per-sub-step update ``substep`` is a pure function of (constants, state, rotor commands), in the
spirit of Brax, so it can be compiled; ``TorchPhysics`` is the thin stateful wrapper the env uses.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Callable

import torch

from volleybots.physics.math import quat_axes, quat_integrate, quat_rotate, quat_rotate_inverse
from volleybots.physics.params import WorldParams


@dataclass
class PhysicsState:
    pos: torch.Tensor  # [N, D, 3] drone centre, world
    quat: torch.Tensor  # [N, D, 4] w, x, y, z body -> world
    vel: torch.Tensor  # [N, D, 3] world linear velocity
    omega: torch.Tensor  # [N, D, 3] body-frame angular velocity
    throttle: torch.Tensor  # [N, D, 4] rotor throttle in [0, 1]
    ball_pos: torch.Tensor  # [N, 3]
    ball_vel: torch.Tensor  # [N, 3]

    def clone(self) -> "PhysicsState":
        return PhysicsState(**{f.name: getattr(self, f.name).clone() for f in fields(self)})

    def tensors(self) -> dict[str, torch.Tensor]:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @property
    def omega_world(self) -> torch.Tensor:
        return quat_rotate(self.quat, self.omega)


@dataclass
class Contacts:
    """Ball-drone contacts during one control step (any sub-step), per drone."""

    racket: torch.Tensor  # [N, D] bool: the ball touched the racket's upper face
    body: torch.Tensor  # [N, D] bool: the ball touched the rest of the drone
    ground: torch.Tensor  # [N] bool: the ball touched the ground


class Constants:
    """Everything ``substep`` needs besides the state, as tensors on the physics device."""

    def __init__(self, p: WorldParams, device, dtype):
        d = p.drone
        kw = dict(device=device, dtype=dtype)
        rp = torch.tensor(d.rotor_positions, **kw)  # [4, 3]
        dirs = torch.tensor(d.directions, **kw)
        kf = d.max_rotor_thrust
        # rotor thrusts t (N) -> body torque: r_i x (0, 0, t_i) plus the yaw reaction of each rotor
        self.torque_map = torch.stack((rp[:, 1], -rp[:, 0], -dirs * d.max_rotor_moment / kf), -1)  # [4, 3]
        self.inertia = torch.tensor(d.inertia, **kw)
        self.kf = kf
        self.mass = d.mass
        self.h = p.sub_dt
        self.g = p.gravity
        self.gravity = torch.tensor((0.0, 0.0, -p.gravity), **kw)
        self.lag = p.lag_per_substep
        self.lin_damp = d.lin_damping
        self.ang_damp = d.ang_damping
        self.racket_r = d.racket_radius
        self.racket_off = d.racket_offset
        self.half = torch.tensor(d.body_half_extents, **kw)
        self.body_e = d.body_restitution
        self.ball_r = p.ball.radius
        self.ball_m = p.ball.mass
        self.ball_e = p.ball.restitution
        self.ground_e = p.ball.ground_restitution
        self.drag = p.ball.drag
        self.downwash = p.downwash
        self.drone_ground = d.body_half_extents[2]


def rotor_thrusts(throttle: torch.Tensor, kf: float) -> torch.Tensor:
    return throttle * throttle * kf


def throttle_target(cmd: torch.Tensor) -> torch.Tensor:
    """Command in [-1, 1] -> throttle whose squared value (the thrust) is linear in the command."""
    return torch.sqrt((cmd.clamp(-1.0, 1.0) + 1.0) * 0.5)


def downwash_force(pos: torch.Tensor, up: torch.Tensor, total_thrust: torch.Tensor) -> torch.Tensor:
    """Force on every drone i from the rotor wash of every other drone j above it. [N, D, 3]."""
    diff = pos.unsqueeze(2) - pos.unsqueeze(1)  # [N, i, j, 3] = p_i - p_j
    axis = -up.unsqueeze(1)  # wash direction of j
    z = (diff * axis).sum(-1)  # distance below j along its wash
    radial = (diff - z.unsqueeze(-1) * axis).norm(dim=-1)
    z = z.clamp_min(0.0)
    mag = torch.exp(-0.5 * (2 * radial / z.clamp_min(1e-6)) ** 2) / (1 + 0.3 * z) ** 2
    mag = torch.where(z > 0, mag, torch.zeros_like(mag))
    thrust_vec = up * total_thrust.unsqueeze(-1)  # [N, j, 3]
    return -(mag.unsqueeze(-1) * thrust_vec.unsqueeze(1)).sum(2)


def control_step_downwash(c: Constants, s: PhysicsState) -> torch.Tensor | None:
    """Downwash acceleration [N, D, 3] held for a whole control step, or None without downwash.

    Computed once per control step from its initial state (positions, tilt and rotor thrusts), not
    every sub-step: the pairwise [N, D, D] terms were half of a 6-drone sub-step's cost, and over 20 ms
    the wash a drone feels changes by far less than the wash itself (docs/physics.md).
    """
    if not c.downwash or s.pos.shape[1] < 2:
        return None
    _, up = quat_axes(s.quat)
    return downwash_force(s.pos, up, rotor_thrusts(s.throttle, c.kf).sum(-1)) / c.mass


def substep(c: Constants, s: PhysicsState, cmd: torch.Tensor, wash: torch.Tensor | None = None) -> tuple[PhysicsState, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Advance the world by one sub-step under rotor commands ``cmd`` [N, D, 4] in [-1, 1].

    ``wash`` is the control step's downwash acceleration (``control_step_downwash``), None for none.
    Returns the new state and this sub-step's racket / body contact flags [N, D] and ground flag [N].
    """
    h = c.h
    _, up0 = quat_axes(s.quat)
    racket0 = s.pos + c.racket_off * up0
    ball0 = s.ball_pos.unsqueeze(1)
    hgt0 = ((ball0 - racket0) * up0).sum(-1)  # [N, D] ball height above each racket plane

    # rotors: first-order lag toward the commanded throttle, thrust ~ throttle^2
    throttle = s.throttle + (throttle_target(cmd) - s.throttle) * c.lag
    t = rotor_thrusts(throttle, c.kf)
    total = t.sum(-1)
    torque = t @ c.torque_map  # [N, D, 3] body frame

    # linear: thrust along body z, gravity, damping, downwash (semi-implicit Euler)
    force = up0 * (total / c.mass).unsqueeze(-1)
    if wash is not None:
        force = force + wash
    acc = force + c.gravity - c.lin_damp * s.vel
    vel = s.vel + acc * h
    pos = s.pos + vel * h

    # angular: Euler's equations in the body frame
    jw = s.omega * c.inertia
    dw = (torque - torch.cross(s.omega, jw, dim=-1)) / c.inertia - c.ang_damp * s.omega
    omega = s.omega + dw * h
    quat = quat_integrate(s.quat, omega, h)

    # ball flight
    bacc = c.gravity.expand_as(s.ball_vel)
    if c.drag > 0:
        bacc = bacc - c.drag * s.ball_vel.norm(dim=-1, keepdim=True) * s.ball_vel
    ball_vel = s.ball_vel + bacc * h
    ball_pos = s.ball_pos + ball_vel * h

    # ball vs racket: swept test of the ball centre against the racket plane (offset by the ball
    # radius) so that no speed can tunnel through the thin disk; the racket's own motion counts.
    _, up1 = quat_axes(quat)
    racket1 = pos + c.racket_off * up1
    ball1 = ball_pos.unsqueeze(1)
    rel1 = ball1 - racket1
    hgt1 = (rel1 * up1).sum(-1)
    rel0 = ball0 - racket0
    frac = ((hgt0 - c.ball_r) / (hgt0 - hgt1).clamp_min(1e-9)).clamp(0.0, 1.0).unsqueeze(-1)
    cross_pt = rel0 + (rel1 - rel0) * frac
    radial = (cross_pt - (cross_pt * up1).sum(-1, keepdim=True) * up1).norm(dim=-1)
    contact_pt = racket1 + cross_pt - (cross_pt * up1).sum(-1, keepdim=True) * up1
    v_pt = vel + torch.cross(quat_rotate(quat, omega), contact_pt - pos, dim=-1)
    v_rel = ball_vel.unsqueeze(1) - v_pt
    vn = (v_rel * up1).sum(-1)
    racket_hit = (hgt0 >= 0.5 * c.ball_r) & (hgt1 < c.ball_r) & (radial <= c.racket_r) & (vn < 0)

    # ball vs body box (everything that is not the racket's upper face)
    local = quat_rotate_inverse(quat, ball1 - pos)
    closest = torch.maximum(torch.minimum(local, c.half), -c.half)
    d_local = local - closest
    dist = d_local.norm(dim=-1)
    inside = dist < 1e-9
    n_local = torch.where(inside.unsqueeze(-1), torch.tensor((0.0, 0.0, 1.0), dtype=local.dtype, device=local.device), d_local / dist.clamp_min(1e-9).unsqueeze(-1))
    n_body = quat_rotate(quat, n_local)
    vn_body = (v_rel * n_body).sum(-1)
    body_hit = (dist < c.ball_r) & ~racket_hit & (vn_body < 0)

    # at most one drone answers per env and sub-step: the first in drone order that touched
    any_racket = racket_hit.any(1)
    racket_hit = racket_hit & (torch.cumsum(racket_hit.int(), 1) == 1)
    body_hit = body_hit & ~any_racket.unsqueeze(1)
    body_hit = body_hit & (torch.cumsum(body_hit.int(), 1) == 1)

    normal = torch.where(racket_hit.unsqueeze(-1), up1, n_body)
    e = torch.where(racket_hit, torch.full_like(vn, c.ball_e), torch.full_like(vn, c.body_e))
    vn_sel = torch.where(racket_hit, vn, vn_body)
    hit = racket_hit | body_hit
    dv = (-(1 + e) * vn_sel).unsqueeze(-1) * normal * hit.unsqueeze(-1)  # [N, D, 3] ball velocity change
    depth = torch.where(racket_hit, c.ball_r - hgt1, c.ball_r - dist).clamp_min(0.0)
    dp = depth.unsqueeze(-1) * normal * hit.unsqueeze(-1)
    ball_vel = ball_vel + dv.sum(1)
    ball_pos = ball_pos + dp.sum(1)
    vel = vel - (c.ball_m / c.mass) * dv  # reaction on the drone (linear part)

    # ground: the ball bounces, a drone rests on its body box
    ground = (ball_pos[:, 2] < c.ball_r) & (ball_vel[:, 2] < 0)
    ball_vel = torch.cat((ball_vel[:, :2], torch.where(ground, -c.ground_e * ball_vel[:, 2], ball_vel[:, 2]).unsqueeze(-1)), -1)
    ball_pos = torch.cat((ball_pos[:, :2], ball_pos[:, 2:].clamp_min(c.ball_r)), -1)
    low = pos[..., 2] < c.drone_ground
    vz = torch.where(low, vel[..., 2].clamp_min(0.0), vel[..., 2])
    vel = torch.cat((vel[..., :2], vz.unsqueeze(-1)), -1)
    pos = torch.cat((pos[..., :2], pos[..., 2:].clamp_min(c.drone_ground)), -1)

    new = PhysicsState(pos=pos, quat=quat, vel=vel, omega=omega, throttle=throttle, ball_pos=ball_pos, ball_vel=ball_vel)
    return new, racket_hit, body_hit, ground


def masked_select(mask: torch.Tensor, new: torch.Tensor, old: torch.Tensor) -> torch.Tensor:
    """``new`` where the per-env ``mask`` [N] is set, else ``old`` (both [N, ...]): a reset written
    without boolean indexing, so that its shapes never depend on how many envs it touches."""
    return torch.where(mask.reshape(mask.shape + (1,) * (old.dim() - mask.dim())), new, old)


# torch.compile options for batched [N, D, ...] code on a CPU: inductor vectorises the innermost loop,
# here a drone or xyz dimension of 1-6, and by default fills 16-wide masked vectors for it; plain loops
# there ran the referee 8x and the physics 1.2x faster (docs/performance.md)
INDUCTOR_OPTIONS = {"cpp.enable_loop_tail_vec": False}


def compile_options(backend="inductor") -> dict:
    """Keyword arguments of ``torch.compile`` for a pure batched step of static shape."""
    opts = dict(dynamic=False, fullgraph=True, backend=backend)
    if backend == "inductor":
        opts["options"] = dict(INDUCTOR_OPTIONS)
    return opts


CommandFn = Callable[[PhysicsState], torch.Tensor]

_FIELDS = tuple(f.name for f in fields(PhysicsState))


def substep_flat(c: Constants, cmd: torch.Tensor, wash: torch.Tensor | None, *tensors: torch.Tensor):
    """``substep`` over a flat tuple of state tensors: the form ``torch.compile`` traces best."""
    new, racket, body, ground = substep(c, PhysicsState(*tensors), cmd, wash)
    return (*(getattr(new, k) for k in _FIELDS), racket, body, ground)


class TorchPhysics:
    """Stateful wrapper: holds the batched state and advances it one control step at a time."""

    name = "torch"

    def __init__(self, params: WorldParams, num_envs: int, n_drones: int, device="cpu", dtype=torch.float32, compile: bool = False):
        self.params = params
        self.num_envs = num_envs
        self.n_drones = n_drones
        self.device = torch.device(device)
        self.dtype = dtype
        self.consts = Constants(params, self.device, dtype)
        z = lambda *s: torch.zeros(*s, device=self.device, dtype=dtype)  # noqa: E731
        quat = z(num_envs, n_drones, 4)
        quat[..., 0] = 1.0
        self.state = PhysicsState(
            pos=z(num_envs, n_drones, 3),
            quat=quat,
            vel=z(num_envs, n_drones, 3),
            omega=z(num_envs, n_drones, 3),
            throttle=torch.tensor(params.drone.hover_throttle, device=self.device, dtype=dtype).expand(num_envs, n_drones, 4).clone(),
            ball_pos=z(num_envs, 3),
            ball_vel=z(num_envs, 3),
        )
        # compile the pure sub-step only (static shapes): the command function changes every step
        self._substep = torch.compile(substep_flat, **compile_options()) if compile else substep_flat

    def step(self, command_fn: CommandFn) -> Contacts:
        """Advance one control step (``substeps`` sub-steps); ``command_fn(state)`` gives rotor commands."""
        state = self.state
        racket = body = ground = None
        wash = control_step_downwash(self.consts, state)
        for _ in range(self.params.substeps):
            cmd = command_fn(state)
            *tensors, r, b, g = self._substep(self.consts, cmd, wash, *(getattr(state, k) for k in _FIELDS))
            state = PhysicsState(*tensors)
            racket = r if racket is None else racket | r
            body = b if body is None else body | b
            ground = g if ground is None else ground | g
        self.state = state
        return Contacts(racket=racket, body=body, ground=ground)

    def set_state(self, mask: torch.Tensor, **values: torch.Tensor) -> None:
        """Overwrite the named state fields of the envs selected by the bool mask [N].

        A value holds either one row per env ([N, ...], or anything that broadcasts to the field's
        shape): a masked select on fixed shapes, the form the compiled env step uses; or one row per
        selected env ([mask.sum(), ...]), written by boolean indexing (scripts and tests).
        """
        for name, v in values.items():
            cur = getattr(self.state, name)
            v = torch.as_tensor(v, device=cur.device).to(cur.dtype)
            if v.dim() < cur.dim() or v.shape[0] == self.num_envs:
                new = masked_select(mask, v.expand_as(cur), cur)
            else:
                new = cur.clone()
                new[mask] = v
            setattr(self.state, name, new)

    def replace_state(self, state: PhysicsState) -> None:
        self.state = replace(state)
