"""Batched quaternion and rotation helpers. Quaternions are (w, x, y, z), last dimension."""

from __future__ import annotations

import torch

_NUMBERS: dict = {}


def num(value: float, like: torch.Tensor):
    """``value`` as a 0-d tensor of ``like``'s dtype and device, made once and kept.

    On a CPU, ``tensor * 0.5`` costs ~2.7x ``tensor * k`` with ``k`` such a tensor: torch wraps the
    Python number in a double tensor and converts it to ``like``'s dtype on every call (four extra
    torch calls), and the physics sub-step does that ~100 times (docs/performance.md). The result is
    bit for bit the same: the number is rounded to ``like``'s dtype either way. Under
    ``torch.compile`` the plain number is returned: the compiler folds it into its kernels. Meant for
    constants (gains, model parameters): a number that changes every call would only fill the cache,
    which is therefore emptied past 4096 entries.
    """
    if torch.compiler.is_compiling():
        return value
    key = (value, like.dtype, like.device)
    t = _NUMBERS.get(key)
    if t is None:
        if len(_NUMBERS) >= 4096:
            _NUMBERS.clear()
        with torch.inference_mode(False):  # an ordinary tensor, usable wherever autograd records
            t = _NUMBERS[key] = torch.tensor(value, dtype=like.dtype, device=like.device)
    return t


class Vec3:
    """A batch of 3-vectors held as three separate tensors (struct of arrays), for the physics sub-step.

    Inductor vectorises a kernel's innermost loop. With [N, D, 3] tensors that loop is the 3 of xyz
    (or a drone dimension of 1-6): too short to vectorise, so the compiled physics ran scalar code.
    With one [N, D] tensor per component the innermost loop runs over envs and drones, and the
    compiled 3 vs 3 physics ran 1.47x faster (docs/performance.md); the eager step gained too.
    Multiplying by a tensor is ``scale`` rather than ``*``: TorchDynamo does not dispatch a tensor
    operand to a user class's ``__mul__``.
    """

    def __init__(self, x, y, z):
        self.x, self.y, self.z = x, y, z

    @staticmethod
    def of(t: torch.Tensor) -> "Vec3":
        """Split a [..., 3] tensor into its components."""
        return Vec3(*t.unbind(-1))

    def stack(self) -> torch.Tensor:
        return torch.stack((self.x, self.y, self.z), -1)

    def __add__(self, o: "Vec3") -> "Vec3":
        return Vec3(self.x + o.x, self.y + o.y, self.z + o.z)

    def __sub__(self, o: "Vec3") -> "Vec3":
        return Vec3(self.x - o.x, self.y - o.y, self.z - o.z)

    def __neg__(self) -> "Vec3":
        return Vec3(-self.x, -self.y, -self.z)

    def scale(self, k) -> "Vec3":
        """Times a number or a tensor of the components' shape."""
        return Vec3(self.x * k, self.y * k, self.z * k)

    def mul(self, o: "Vec3") -> "Vec3":
        """Component-wise product."""
        return Vec3(self.x * o.x, self.y * o.y, self.z * o.z)

    def dot(self, o: "Vec3"):
        return self.x * o.x + self.y * o.y + self.z * o.z

    def cross(self, o: "Vec3") -> "Vec3":
        return Vec3(self.y * o.z - self.z * o.y, self.z * o.x - self.x * o.z, self.x * o.y - self.y * o.x)

    def norm(self):
        return torch.sqrt(self.dot(self))

    def __getitem__(self, index) -> "Vec3":
        return Vec3(self.x[index], self.y[index], self.z[index])

    def unsqueeze(self, dim: int) -> "Vec3":
        return Vec3(self.x.unsqueeze(dim), self.y.unsqueeze(dim), self.z.unsqueeze(dim))

    def sum(self, dim: int) -> "Vec3":
        return Vec3(self.x.sum(dim), self.y.sum(dim), self.z.sum(dim))

    @staticmethod
    def where(mask: torch.Tensor, a: "Vec3", b: "Vec3") -> "Vec3":
        return Vec3(torch.where(mask, a.x, b.x), torch.where(mask, a.y, b.y), torch.where(mask, a.z, b.z))


class Quat:
    """A batch of unit quaternions (w, x, y, z) as four component tensors: ``Vec3``'s layout."""

    def __init__(self, w, v: Vec3):
        self.w, self.v = w, v

    @staticmethod
    def of(q: torch.Tensor) -> "Quat":
        w, x, y, z = q.unbind(-1)
        return Quat(w, Vec3(x, y, z))

    def stack(self) -> torch.Tensor:
        return torch.stack((self.w, self.v.x, self.v.y, self.v.z), -1)

    def mul(self, o: "Quat") -> "Quat":
        """The Hamilton product self * o."""
        return Quat(self.w * o.w - self.v.dot(o.v), o.v.scale(self.w) + self.v.scale(o.w) + self.v.cross(o.v))

    def heading(self) -> Vec3:
        """The body x axis in the world frame."""
        w, x, y, z = self.w, self.v.x, self.v.y, self.v.z
        one, two = num(1.0, w), num(2.0, w)
        return Vec3(one - two * (y * y + z * z), two * (x * y + w * z), two * (x * z - w * y))

    def up(self) -> Vec3:
        """The body z axis in the world frame."""
        w, x, y, z = self.w, self.v.x, self.v.y, self.v.z
        one, two = num(1.0, w), num(2.0, w)
        return Vec3(two * (x * z + w * y), two * (y * z - w * x), one - two * (x * x + y * y))

    def rotate(self, v: Vec3) -> Vec3:
        """Body-frame vectors into the world frame."""
        t = self.v.cross(v).scale(num(2.0, self.w))
        return v + t.scale(self.w) + self.v.cross(t)

    def rotate_inverse(self, v: Vec3) -> Vec3:
        """World vectors into the body frame."""
        t = (-self.v).cross(v).scale(num(2.0, self.w))
        return v + t.scale(self.w) - self.v.cross(t)

    def integrate(self, omega_body: Vec3, h: float) -> "Quat":
        """Advance by body rates over h with the exact exponential map (renormalised, so |q| = 1 up to rounding)."""
        w = self.w
        angle = omega_body.norm() * num(h, w)
        half = num(0.5, w) * angle
        # sin(x)/x with a series near 0 so that zero rotation stays exact and differentiable
        small = num(0.5 * h, w) * (num(1.0, w) - half * half / num(6.0, w))
        scale = torch.where(angle < num(1e-6, w), small, torch.sin(half) / angle.clamp_min(num(1e-12, w)) * num(h, w))
        q = self.mul(Quat(torch.cos(half), omega_body.scale(scale)))
        inv = torch.rsqrt(q.w * q.w + q.v.dot(q.v))
        return Quat(q.w * inv, q.v.scale(inv))


# Tensor forms ([..., 4] quaternions, [..., 3] vectors) of the component arithmetic above: one
# implementation of each rotation, shared by the physics, the observations and the scripted players.
def quat_rotate(q: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Rotate vectors v (body frame) by q into the world frame."""
    return Quat.of(q).rotate(Vec3.of(v)).stack()


def quat_rotate_inverse(q: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Rotate world vectors v into the body frame of q."""
    return Quat.of(q).rotate_inverse(Vec3.of(v)).stack()


def quat_axes(q: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Body x axis (heading) and body z axis (up) in the world frame, without building a matrix."""
    quat = Quat.of(q)
    return quat.heading().stack(), quat.up().stack()


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
