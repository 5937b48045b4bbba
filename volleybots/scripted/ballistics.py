"""Ball flight prediction and racket geometry for intercepts (no drag: the default ball, physics.md).

All functions are batched over leading dimensions and differentiable-free plain tensor maths:

* ``ball_at`` / ``time_to_height``: where the ball will be, and when it will pass a height;
* ``launch_for_apex`` / ``launch_for_range``: the outgoing velocity that sends the ball to a point
  (with a given apex, or with a given elevation angle);
* ``racket_for``: the racket normal and normal speed that turn an incoming velocity into a wanted
  outgoing one (the impulse of a frictionless racket is along its normal, so the normal is the
  direction of the velocity change; the restitution law fixes the speed);
* ``bounce``: the forward model of the same contact (what the physics does), for checks.
"""

from __future__ import annotations

import functools

import torch

from volleybots.physics.math import num

G = 9.81


def ball_at(pos: torch.Tensor, vel: torch.Tensor, t: torch.Tensor, g: float = G) -> tuple[torch.Tensor, torch.Tensor]:
    """Ballistic position and velocity after ``t`` seconds (t [...], pos/vel [..., 3])."""
    t = t.unsqueeze(-1)
    grav = torch.zeros_like(vel)
    grav[..., 2] = -g
    return pos + vel * t + num(0.5, vel) * grav * t * t, vel + grav * t


def time_to_height(z: torch.Tensor, vz: torch.Tensor, height, g: float = G, descending: bool = True) -> torch.Tensor:
    """Time until the ball's centre passes ``height`` (on the way down by default).

    Returns +inf where the ball never reaches that height (its apex is below it). The descending
    root is the later one, so a ball below ``height`` and rising still gets the time of its fall.
    """
    k = functools.partial(num, like=vz)  # the numbers as 0-d tensors: physics.math.num
    disc = vz * vz + k(2.0 * g) * (z - height)
    root = torch.sqrt(disc.clamp_min(k(0.0)))
    t = (vz + root) / k(g) if descending else (vz - root) / k(g)
    return torch.where(disc >= k(0.0), t, k(float("inf")))


def launch_for_apex(pos: torch.Tensor, target_xy: torch.Tensor, apex, land_z, g: float = G) -> torch.Tensor:
    """Velocity that throws a ball from ``pos`` through an apex at height ``apex`` and down through
    height ``land_z`` at ``target_xy``. ``apex`` must be above both heights (clamped to be)."""
    z = pos[..., 2]
    lowest = torch.maximum(z, torch.as_tensor(land_z, dtype=z.dtype, device=z.device))
    apex = torch.maximum(torch.as_tensor(apex, dtype=z.dtype, device=z.device), lowest)
    vz = torch.sqrt(2.0 * g * (apex - z))
    t = (vz + torch.sqrt(2.0 * g * (apex - land_z))) / g
    vxy = (target_xy - pos[..., :2]) / t.clamp_min(1e-6).unsqueeze(-1)
    return torch.cat((vxy, vz.unsqueeze(-1)), -1)


def launch_for_range(pos: torch.Tensor, target_xy: torch.Tensor, land_z, elevation: torch.Tensor, g: float = G) -> torch.Tensor:
    """Velocity at elevation angle ``elevation`` (rad, [...]) that brings the ball down through
    ``land_z`` at ``target_xy``. Where no speed can (the target is above the line of fire), the
    speed is +inf."""
    d = target_xy - pos[..., :2]
    r = d.norm(dim=-1)
    cos, tan = torch.cos(elevation), torch.tan(elevation)
    # z(t) = z0 + r tan(e) - g r^2 / (2 v^2 cos^2 e) must equal land_z at horizontal distance r
    rise = pos[..., 2] - land_z + r * tan
    v2 = g * r * r / (2.0 * cos * cos * rise.clamp_min(1e-9))
    speed = torch.where(rise > 0, torch.sqrt(v2), torch.full_like(v2, float("inf")))
    horiz = d / r.clamp_min(1e-9).unsqueeze(-1)
    return torch.cat((horiz * (speed * cos).unsqueeze(-1), (speed * torch.sin(elevation)).unsqueeze(-1)), -1)


def racket_for(v_in: torch.Tensor, v_out: torch.Tensor, restitution: float = 0.8) -> tuple[torch.Tensor, torch.Tensor]:
    """Racket unit normal [..., 3] and racket speed along it [...] turning ``v_in`` into ``v_out``.

    With the normal n and the racket's normal speed s, the contact gives
    ``v_out = v_in + (1 + e) (s - v_in . n) n``; so n is along ``v_out - v_in`` and
    ``s = v_in . n + |v_out - v_in| / (1 + e)``.
    """
    dv = v_out - v_in
    mag = dv.norm(dim=-1)
    n = dv / mag.clamp_min(num(1e-9, mag)).unsqueeze(-1)
    s = (v_in * n).sum(-1) + mag / num(1.0 + restitution, mag)
    return n, s


def bounce(v_in: torch.Tensor, normal: torch.Tensor, racket_vel: torch.Tensor, restitution: float = 0.8) -> torch.Tensor:
    """Ball velocity after a contact with a racket of unit ``normal`` moving at ``racket_vel``."""
    vn = ((v_in - racket_vel) * normal).sum(-1, keepdim=True)
    return v_in - (1.0 + restitution) * vn.clamp(max=0.0) * normal


def crossing(pos: torch.Tensor, vel: torch.Tensor, height, g: float = G) -> tuple[torch.Tensor, torch.Tensor]:
    """Where (position [..., 3]) and when ([...]) the ball next comes down through ``height``."""
    t = time_to_height(pos[..., 2], vel[..., 2], height, g)
    p, _ = ball_at(pos, vel, torch.where(torch.isfinite(t), t, torch.zeros_like(t)), g)
    return p, t


__all__ = ["G", "ball_at", "bounce", "crossing", "launch_for_apex", "launch_for_range", "racket_for", "time_to_height"]
