"""Crazyflie-style body-rate PID controller: CTBR commands -> per-rotor commands (physics.md).

A module of its own so it can drive any drone outside the env (scripted policies, sim-to-real
checks). It runs at the physics rate, keeps its integrator per drone and resets with the env.
"""

from __future__ import annotations

import math

import torch

from volleybots.physics.math import num
from volleybots.physics.params import DroneParams

PWM = 65535.0  # the Crazyflie mixer works in motor PWM units; we divide back to a thrust fraction


class RateController:
    max_rate_deg = 144.0

    def __init__(self, drone: DroneParams, num_envs: int, n_drones: int, dt: float, device="cpu", dtype=torch.float32):
        kw = dict(device=device, dtype=dtype)
        self.kp = torch.tensor((250.0, 250.0, 120.0), **kw)
        self.ki = torch.tensor((500.0, 500.0, 16.7), **kw)
        self.kd = torch.tensor((2.5, 2.5, 0.0), **kw)
        self.i_limit = torch.tensor((33.3, 33.3, 166.7), **kw)
        self.dt = dt
        rp = torch.tensor(drone.rotor_positions, **kw)
        dirs = torch.tensor(drone.directions, **kw)
        # mixer signs: roll torque is raised by rotors at +y, pitch by rotors at -x,
        # yaw by rotors spinning with direction -1 (their reaction torque is +z)
        self.mix = torch.stack((torch.sign(rp[:, 1]) * 0.5, -torch.sign(rp[:, 0]) * 0.5, -dirs), -1)  # [4, 3]
        self.integral = torch.zeros(num_envs, n_drones, 3, **kw)
        self.prev_err = torch.zeros(num_envs, n_drones, 3, **kw)

    def reset(self, mask: torch.Tensor | None = None) -> None:
        if mask is None:
            self.integral.zero_()
            self.prev_err.zero_()
        else:  # a masked select, not boolean indexing: static shapes for the compiled env step
            m = mask.reshape(-1, *(1,) * (self.integral.dim() - 1))
            self.integral = torch.where(m, 0.0, self.integral)
            self.prev_err = torch.where(m, 0.0, self.prev_err)

    @classmethod
    def scale_action(cls, action: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """CTBR action in [-1, 1]^4 -> (body rate targets in deg/s [.., 3], collective thrust fraction [..])."""
        one = num(1.0, action)
        a = action.clamp(-one, one)
        return a[..., :3] * num(cls.max_rate_deg, a), (a[..., 3] + one) * num(0.5, a)

    def __call__(self, omega_body: torch.Tensor, rate_target_deg: torch.Tensor, thrust_frac: torch.Tensor) -> torch.Tensor:
        """One controller tick. Returns per-rotor commands in [-1, 1] whose steady thrust is the mix."""
        dt = num(self.dt, omega_body)  # numbers as 0-d tensors: see physics.math.num
        rate = omega_body * num(180.0 / math.pi, omega_body)
        err = rate_target_deg - rate
        self.integral = torch.maximum(torch.minimum(self.integral + err * dt, self.i_limit), -self.i_limit)
        deriv = (err - self.prev_err) / dt
        self.prev_err = err
        out = self.kp * err + self.ki * self.integral + self.kd * deriv  # PWM units
        frac = thrust_frac.unsqueeze(-1) + (out @ self.mix.T) / num(PWM, out)
        one = num(1.0, frac)
        return frac.clamp(num(0.0, frac), one) * num(2.0, frac) - one
