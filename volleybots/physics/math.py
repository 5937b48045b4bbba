"""Batched quaternion and rotation helpers. Quaternions are (w, x, y, z), last dimension."""

from __future__ import annotations

import torch


def quat_mul(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    aw, ax, ay, az = a.unbind(-1)
    bw, bx, by, bz = b.unbind(-1)
    return torch.stack(
        (
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ),
        -1,
    )


def quat_rotate(q: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Rotate vectors v (body frame) by q into the world frame."""
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * torch.cross(u, v, dim=-1)
    return v + w * t + torch.cross(u, t, dim=-1)


def quat_rotate_inverse(q: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Rotate world vectors v into the body frame of q."""
    w = q[..., :1]
    u = -q[..., 1:]
    t = 2.0 * torch.cross(u, v, dim=-1)
    return v + w * t + torch.cross(u, t, dim=-1)


def quat_axes(q: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Body x axis (heading) and body z axis (up) in the world frame, without building a matrix."""
    w, x, y, z = q.unbind(-1)
    heading = torch.stack((1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)), -1)
    up = torch.stack((2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)), -1)
    return heading, up


def quat_integrate(q: torch.Tensor, omega_body: torch.Tensor, h: float) -> torch.Tensor:
    """Advance q by body rates over h with the exact exponential map (keeps |q| = 1 up to rounding)."""
    angle = omega_body.norm(dim=-1, keepdim=True) * h
    half = 0.5 * angle
    # sin(x)/x with a series near 0 so that zero rotation stays exact and differentiable
    small = angle < 1e-6
    scale = torch.where(small, 0.5 * h * (1 - half * half / 6), torch.sin(half) / angle.clamp_min(1e-12) * h)
    dq = torch.cat((torch.cos(half), omega_body * scale), -1)
    out = quat_mul(q, dq)
    return out / out.norm(dim=-1, keepdim=True)


def euler_to_quat(roll: torch.Tensor, pitch: torch.Tensor, yaw: torch.Tensor) -> torch.Tensor:
    """ZYX (yaw, pitch, roll) Euler angles to a quaternion."""
    cr, sr = torch.cos(roll / 2), torch.sin(roll / 2)
    cp, sp = torch.cos(pitch / 2), torch.sin(pitch / 2)
    cy, sy = torch.cos(yaw / 2), torch.sin(yaw / 2)
    return torch.stack(
        (
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ),
        -1,
    )


def quat_to_euler(q: torch.Tensor) -> torch.Tensor:
    w, x, y, z = q.unbind(-1)
    roll = torch.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = torch.asin((2 * (w * y - z * x)).clamp(-1, 1))
    yaw = torch.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return torch.stack((roll, pitch, yaw), -1)
