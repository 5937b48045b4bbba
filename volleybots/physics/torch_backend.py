"""Batched rigid-body, rotor, downwash and ball physics in PyTorch (docs/physics.md).

Pure dynamics: no volleyball rules live here. State tensors have shape [num_envs, n_drones, ...]
for drones and [num_envs, ...] for the ball; every function works on any torch device.
The per-sub-step update ``substep`` is a pure function of (constants, state, rotor commands), in the
spirit of Brax, so it can be compiled; ``TorchPhysics`` is the thin stateful wrapper the env uses.
"""

from __future__ import annotations

import contextlib
import functools
from dataclasses import dataclass, fields, replace
from typing import Callable, NamedTuple

import torch

from volleybots.physics.math import Quat, Vec3, num, quat_axes, quat_rotate
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
        # plain numbers for the component-wise sub-step (inductor folds them into its kernels)
        self.torque_rows = self.torque_map.tolist()
        self.inertia_xyz = tuple(float(i) for i in d.inertia)
        self.half_xyz = tuple(float(x) for x in d.body_half_extents)
        self.kf = kf
        self.mass = d.mass
        self.h = p.sub_dt
        self.g = p.gravity
        self.lag = p.lag_per_substep
        self.lin_damp = d.lin_damping
        self.ang_damp = d.ang_damping
        self.racket_r = d.racket_radius
        self.racket_off = d.racket_offset
        self.body_e = d.body_restitution
        self.ball_r = p.ball.radius
        self.ball_m = p.ball.mass
        self.ball_e = p.ball.restitution
        self.ground_e = p.ball.ground_restitution
        self.drag = p.ball.drag
        self.downwash = p.downwash
        self.drone_ground = d.body_half_extents[2]
        # no part of the body box is farther from its centre than this ball-centre distance (``may_touch``)
        self.body_reach = p.ball.radius + sum(x * x for x in d.body_half_extents) ** 0.5 + 1e-3


def rotor_thrusts(throttle: torch.Tensor, kf: float) -> torch.Tensor:
    return throttle * throttle * num(kf, throttle)


def throttle_target(cmd: torch.Tensor) -> torch.Tensor:
    """Command in [-1, 1] -> throttle whose squared value (the thrust) is linear in the command."""
    one = num(1.0, cmd)
    return torch.sqrt((cmd.clamp(-one, one) + one) * num(0.5, cmd))


def downwash_force(pos: torch.Tensor, up: torch.Tensor, total_thrust: torch.Tensor) -> torch.Tensor:
    """Force on every drone i from the rotor wash of every other drone j above it. [N, D, 3].

    One pass per drone j over all drones i ([N, D] components) rather than an [N, D, D] tensor
    summed over j: without the short reduction the compiled pass vectorises over envs.
    """
    pos, up = Vec3.of(pos), Vec3.of(up)
    k = functools.partial(num, like=total_thrust)
    force = Vec3(0.0, 0.0, 0.0)
    for j in range(pos.x.shape[1]):
        pj, axis = pos[:, j : j + 1], -up[:, j : j + 1]  # wash direction of j
        diff = pos - pj  # p_i - p_j
        z = diff.dot(axis)  # distance below j along its wash
        radial = (diff - axis.scale(z)).norm()
        z = z.clamp_min(k(0.0))
        mag = torch.exp(k(-0.5) * (k(2.0) * radial / z.clamp_min(k(1e-6))) ** 2) / (k(1.0) + k(0.3) * z) ** 2
        mag = torch.where(z > k(0.0), mag, k(0.0))  # zero for i = j too
        force = force + axis.scale(total_thrust[:, j : j + 1] * mag)
    return force.stack()


def control_step_downwash(c: Constants, s: PhysicsState) -> torch.Tensor | None:
    """Downwash acceleration [N, D, 3] held for a whole control step, or None without downwash.

    Computed once per control step from its initial state (positions, tilt and rotor thrusts), not
    every sub-step: the pairwise [N, D, D] terms were half of a 6-drone sub-step's cost, and over 20 ms
    the wash a drone feels changes by far less than the wash itself (docs/physics.md).
    """
    if not c.downwash or s.pos.shape[1] < 2:
        return None
    _, up = quat_axes(s.quat)
    return downwash_force(s.pos, up, rotor_thrusts(s.throttle, c.kf).sum(-1)) / num(c.mass, s.pos)


class Approach(NamedTuple):
    """The ball seen from each drone across a sub-step (a NamedTuple: ``torch.compile`` traces it as its
    tensors): where the contact tests start from."""

    rel0: Vec3  # [N, D] ball minus racket centre, before the sub-step's motion
    rel1: Vec3  # ... and after it
    hgt0: torch.Tensor  # [N, D] the ball's height above the racket plane, before ...
    hgt1: torch.Tensor  # ... and after
    up1: Vec3  # [N, D] the racket plane's normal (body z), after
    racket1: Vec3  # [N, D] the racket centre, after
    off: Vec3  # [N, D] ball minus drone centre, after


def may_touch(c: Constants, a: Approach) -> bool:
    """Whether some drone may meet the ball in this sub-step: the ball crosses a racket's plane from above (the
    first two of the racket test's conditions in ``touch``) or comes within the body's reach of a drone's
    centre (the body box's half-diagonal plus the ball's radius, and a millimetre for rounding: a ball
    nearer the box than its radius is nearer the centre than that). Where neither holds ``touch`` finds no
    contact, so skipping it changes no number and saves 40 % of the sub-step's torch calls and nearly
    half its time: most sub-steps of a game, and every one of Hover's. A compiled sub-step always touches
    (its graph has no data-dependent branch), and so does one on an accelerator, where reading the answer
    back would stall the queue of kernels every sub-step. The near test comes first: in a game it is the one
    that holds, and the test then costs 8 calls."""
    if torch.compiler.is_compiling() or a.hgt1.device.type != "cpu":
        return True
    k = functools.partial(num, like=a.hgt1)
    if bool((a.off.dot(a.off) < k(c.body_reach**2)).any()):
        return True
    return bool(((a.hgt0 >= k(0.5 * c.ball_r)) & (a.hgt1 < k(c.ball_r))).any())


def touch(c: Constants, q1: Quat, pos: Vec3, vel: Vec3, omega: Vec3, ball_pos: Vec3, ball_vel: Vec3, a: Approach):
    """The ball's contacts with the drones after a sub-step's free motion (the drones at ``pos``, ``q1``,
    the ball as ``a`` sees it): the racket and body flags [N, D], and the ball's position and velocity and
    the drones' velocities after the impulses."""
    rel0, rel1, hgt0, hgt1, up1, racket1, off = a
    # ball vs racket: swept test of the ball centre against the racket plane (offset by the ball
    # radius) so that no speed can tunnel through the thin disk; the racket's own motion counts.
    k = functools.partial(num, like=hgt1)
    ball_r = k(c.ball_r)
    frac = ((hgt0 - ball_r) / (hgt0 - hgt1).clamp_min(k(1e-9))).clamp(k(0.0), k(1.0))
    cross_pt = rel0 + (rel1 - rel0).scale(frac)
    in_plane = cross_pt - up1.scale(cross_pt.dot(up1))
    radial = in_plane.norm()
    contact_pt = racket1 + in_plane
    v_pt = vel + q1.rotate(omega).cross(contact_pt - pos)
    v_rel = ball_vel.unsqueeze(1) - v_pt
    vn = v_rel.dot(up1)
    racket_hit = (hgt0 >= k(0.5 * c.ball_r)) & (hgt1 < ball_r) & (radial <= k(c.racket_r)) & (vn < k(0.0))

    # ball vs body box (everything that is not the racket's upper face)
    local = q1.rotate_inverse(off)
    hx, hy, hz = (k(x) for x in c.half_xyz)
    d_local = local - Vec3(local.x.clamp(-hx, hx), local.y.clamp(-hy, hy), local.z.clamp(-hz, hz))
    dist = d_local.norm()
    inside = dist < k(1e-9)
    # (a number over a tensor is this reciprocal times the number: the same bits)
    n_local = Vec3.where(inside, Vec3(k(0.0), k(0.0), k(1.0)), d_local.scale(dist.clamp_min(k(1e-9)).reciprocal()))
    n_body = q1.rotate(n_local)
    vn_body = v_rel.dot(n_body)
    body_hit = (dist < ball_r) & ~racket_hit & (vn_body < k(0.0))

    # at most one drone answers per env and sub-step: the first in drone order that touched
    any_racket = racket_hit.any(1)
    racket_hit = racket_hit & (torch.cumsum(racket_hit.int(), 1) == 1)
    body_hit = body_hit & ~any_racket.unsqueeze(1)
    body_hit = body_hit & (torch.cumsum(body_hit.int(), 1) == 1)

    normal = Vec3.where(racket_hit, up1, n_body)
    e = torch.where(racket_hit, k(c.ball_e), k(c.body_e))
    hit = racket_hit | body_hit
    dv = normal.scale(torch.where(hit, -(k(1.0) + e) * torch.where(racket_hit, vn, vn_body), k(0.0)))  # ball velocity change
    depth = torch.where(racket_hit, ball_r - hgt1, ball_r - dist).clamp_min(k(0.0))
    ball_vel = ball_vel + dv.sum(1)
    ball_pos = ball_pos + normal.scale(torch.where(hit, depth, k(0.0))).sum(1)
    vel = vel - dv.scale(k(c.ball_m / c.mass))  # reaction on the drone (linear part)

    return racket_hit, body_hit, ball_pos, ball_vel, vel


def substep(
    c: Constants, s: PhysicsState, cmd: torch.Tensor, wash: torch.Tensor | None = None
) -> tuple[PhysicsState, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Advance the world by one sub-step under rotor commands ``cmd`` [N, D, 4] in [-1, 1].

    ``wash`` is the control step's downwash acceleration (``control_step_downwash``), None for none.
    Returns the new state and this sub-step's racket / body contact flags [N, D] and ground flag [N].
    The arithmetic runs on one tensor per component (``Vec3``, ``Quat``): see ``Vec3`` for why; every
    number is a 0-d tensor (``num``): see there.
    """
    k = functools.partial(num, like=s.pos)
    h = k(c.h)
    q0 = Quat.of(s.quat)
    pos0, vel0, omega0 = Vec3.of(s.pos), Vec3.of(s.vel), Vec3.of(s.omega)
    up0 = q0.up()
    racket0 = pos0 + up0.scale(k(c.racket_off))
    bpos0, bvel0 = Vec3.of(s.ball_pos), Vec3.of(s.ball_vel)
    ball0 = bpos0.unsqueeze(1)
    rel0 = ball0 - racket0
    hgt0 = rel0.dot(up0)  # [N, D] ball height above each racket plane

    # rotors: first-order lag toward the commanded throttle, thrust ~ throttle^2
    throttle = s.throttle + (throttle_target(cmd) - s.throttle) * k(c.lag)
    t = rotor_thrusts(throttle, c.kf).unbind(-1)
    total = t[0] + t[1] + t[2] + t[3]
    rows = [[k(x) for x in row] for row in c.torque_rows]
    torque = Vec3(*(t[0] * rows[0][j] + t[1] * rows[1][j] + t[2] * rows[2][j] + t[3] * rows[3][j] for j in range(3)))  # body frame

    # linear: thrust along body z, gravity, damping, downwash (semi-implicit Euler)
    acc = up0.scale(total / k(c.mass)) - vel0.scale(k(c.lin_damp))
    if wash is not None:
        acc = acc + Vec3.of(wash)
    acc = Vec3(acc.x, acc.y, acc.z - k(c.g))
    vel = vel0 + acc.scale(h)
    pos = pos0 + vel.scale(h)

    # angular: Euler's equations in the body frame
    inertia = Vec3(*(k(i) for i in c.inertia_xyz))
    gyro = torque - omega0.cross(omega0.mul(inertia))
    dw = Vec3(gyro.x / inertia.x, gyro.y / inertia.y, gyro.z / inertia.z) - omega0.scale(k(c.ang_damp))
    omega = omega0 + dw.scale(h)
    q1 = q0.integrate(omega, c.h)

    # ball flight
    if c.drag > 0:
        bacc = Vec3(0.0, 0.0, -k(c.g)) - bvel0.scale(k(c.drag) * bvel0.norm())
        ball_vel = bvel0 + bacc.scale(h)
    else:
        ball_vel = Vec3(bvel0.x, bvel0.y, bvel0.z + k(-c.g * c.h))
    ball_pos = bpos0 + ball_vel.scale(h)

    # ball vs drones: the contacts of this sub-step (``touch``), where some drone may meet the ball
    up1 = q1.up()
    racket1 = pos + up1.scale(k(c.racket_off))
    ball1 = ball_pos.unsqueeze(1)
    rel1 = ball1 - racket1
    seen = Approach(rel0, rel1, hgt0, rel1.dot(up1), up1, racket1, ball1 - pos)
    if may_touch(c, seen):
        racket_hit, body_hit, ball_pos, ball_vel, vel = touch(c, q1, pos, vel, omega, ball_pos, ball_vel, seen)
    else:
        racket_hit = body_hit = torch.zeros_like(seen.hgt1, dtype=torch.bool)

    # ground: the ball bounces, a drone rests on its body box
    ball_r = k(c.ball_r)
    ground = (ball_pos.z < ball_r) & (ball_vel.z < k(0.0))
    ball_vel = Vec3(ball_vel.x, ball_vel.y, torch.where(ground, k(-c.ground_e) * ball_vel.z, ball_vel.z))
    ball_pos = Vec3(ball_pos.x, ball_pos.y, ball_pos.z.clamp_min(ball_r))
    drone_ground = k(c.drone_ground)
    low = pos.z < drone_ground
    vel = Vec3(vel.x, vel.y, torch.where(low, vel.z.clamp_min(k(0.0)), vel.z))
    pos = Vec3(pos.x, pos.y, pos.z.clamp_min(drone_ground))

    new = PhysicsState(
        pos=pos.stack(), quat=q1.stack(), vel=vel.stack(), omega=omega.stack(), throttle=throttle,
        ball_pos=ball_pos.stack(), ball_vel=ball_vel.stack(),
    )
    return new, racket_hit, body_hit, ground


def masked_select(mask: torch.Tensor, new: torch.Tensor, old: torch.Tensor) -> torch.Tensor:
    """``new`` where the per-env ``mask`` [N] is set, else ``old`` (both [N, ...]): a reset written
    without boolean indexing, so that its shapes never depend on how many envs it touches."""
    return torch.where(mask.reshape(mask.shape + (1,) * (old.dim() - mask.dim())), new, old)


# torch.compile options for batched [N, D, ...] code on a CPU (docs/performance.md): inductor
# vectorises the innermost loop, here a drone or xyz dimension of 1-6 in the referee and observations,
# and by default fills 16-wide masked vectors for it; plain loops there ran the referee 8x faster.
# Its tiling heuristics leave a kernel scalar when it reads many strided values, as the fused sub-step
# does from the [N, D, 3] state: vectorised anyway, the compiled Solo Bump physics ran 1.7x faster.
INDUCTOR_OPTIONS = {"cpp.enable_loop_tail_vec": False, "cpp.enable_tiling_heuristics": False}


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
        self.compiled = compile
        self._substep = torch.compile(substep_flat, **compile_options()) if compile else substep_flat

    def step(self, command_fn: CommandFn) -> Contacts:
        """Advance one control step (``substeps`` sub-steps); ``command_fn(state)`` gives rotor commands."""
        state = self.state
        racket = body = ground = None
        # Eager sub-steps run in inference mode, which skips autograd's bookkeeping on each of their
        # ~650 small torch calls (about 1.2x on the 1 vs 1 physics step at 32 envs; docs/performance.md).
        # The env is not differentiable anyway; its results are cloned into ordinary tensors below,
        # so callers may still write into the state. The command function (the rate controller keeps
        # its integrators across steps) runs outside, on ordinary tensors.
        fast = not (self.compiled or torch.compiler.is_compiling())  # a compiled step has no such overhead
        infer = torch.inference_mode if fast else contextlib.nullcontext  # (inference_mode(False) would switch it off)
        with infer():
            wash = control_step_downwash(self.consts, state)
        for _ in range(self.params.substeps):
            cmd = command_fn(state)
            with infer():
                *tensors, r, b, g = self._substep(self.consts, cmd, wash, *(getattr(state, k) for k in _FIELDS))
                state = PhysicsState(*tensors)
                racket = r if racket is None else racket | r
                body = b if body is None else body | b
                ground = g if ground is None else ground | g
        if fast:
            state, racket, body, ground = state.clone(), racket.clone(), body.clone(), ground.clone()
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
