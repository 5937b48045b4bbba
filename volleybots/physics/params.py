"""Physical parameters of the drone, the ball and the world (docs/physics.md).

They are plain dataclasses so that a test, a backend or a config file can build them; the drone's
numbers are read from ``conf/env/drone/<name>.yaml`` so that another airframe is a config, not code.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from pathlib import Path

import yaml

from volleybots.paths import conf_dir


@dataclass(frozen=True)
class DroneParams:
    name: str = "iris"
    mass: float = 1.52
    inertia: tuple[float, float, float] = (0.0347563, 0.0458929, 0.0977)
    arm_lengths: tuple[float, ...] = (0.255539, 0.238537, 0.255539, 0.238537)
    arm_angles: tuple[float, ...] = (-0.533708, 2.565218, 0.533708, -2.565218)
    directions: tuple[float, ...] = (1.0, 1.0, -1.0, -1.0)
    max_rotor_thrust: float = 6.0032
    max_rotor_moment: float = 0.096051
    lag_per_step: float = 0.43
    lin_damping: float = 0.2
    ang_damping: float = 0.2
    racket_radius: float = 0.2
    racket_offset: float = 0.05
    body_half_extents: tuple[float, float, float] = (0.235, 0.235, 0.05)
    body_restitution: float = 0.5

    @property
    def rotor_positions(self) -> list[tuple[float, float, float]]:
        return [
            (r * math.cos(a), r * math.sin(a), 0.0)
            for r, a in zip(self.arm_lengths, self.arm_angles)
        ]

    @property
    def hover_thrusts(self) -> tuple[float, ...]:
        """Per-rotor thrusts (N) that hold the drone still: total = weight, zero roll/pitch/yaw torque.

        The Iris's front and rear arms differ in length, so equal thrusts would pitch it.
        """
        import numpy as np

        rp = np.array(self.rotor_positions)
        a = np.stack((np.ones(len(rp)), rp[:, 1], rp[:, 0], np.array(self.directions, dtype=float)))
        b = np.array((self.mass * 9.81, 0.0, 0.0, 0.0))
        return tuple(float(t) for t in np.linalg.lstsq(a, b, rcond=None)[0])

    @property
    def hover_command(self) -> tuple[float, ...]:
        """Per-rotor commands in [-1, 1] whose steady thrust holds the drone still."""
        return tuple(2.0 * t / self.max_rotor_thrust - 1.0 for t in self.hover_thrusts)

    @property
    def hover_throttle(self) -> tuple[float, ...]:
        return tuple(math.sqrt(t / self.max_rotor_thrust) for t in self.hover_thrusts)

    def lag_time_constant(self, control_dt: float = 0.02) -> float:
        return -control_dt / math.log(1.0 - self.lag_per_step)

    @classmethod
    def from_yaml(cls, path: str | Path) -> "DroneParams":
        with open(path) as f:
            raw = yaml.safe_load(f)
        return cls.from_dict(raw)

    @classmethod
    def from_dict(cls, raw: dict) -> "DroneParams":
        allowed = {f.name for f in fields(cls)}
        unknown = set(raw) - allowed
        if unknown:
            raise ValueError(f"unknown drone parameter(s) {sorted(unknown)}; allowed: {sorted(allowed)}")
        kw = {k: tuple(v) if isinstance(v, list) else v for k, v in raw.items()}
        return cls(**kw)

    @classmethod
    def named(cls, name: str) -> "DroneParams":
        folder = conf_dir() / "env" / "drone"
        path = folder / f"{name}.yaml"
        if not path.exists():
            known = sorted(p.stem for p in folder.glob("*.yaml"))
            raise ValueError(f"unknown drone model {name!r}; allowed: {known}")
        return cls.from_yaml(path)


@dataclass(frozen=True)
class BallParams:
    radius: float = 0.1
    mass: float = 0.005
    restitution: float = 0.8  # against rackets
    ground_restitution: float = 0.8
    drag: float = 0.0  # quadratic drag coefficient (1/m); off by default (physics.md decision)


@dataclass(frozen=True)
class WorldParams:
    dt: float = 0.02  # control step, s (50 Hz)
    substeps: int = 4  # physics sub-steps per control step
    gravity: float = 9.81
    downwash: bool = True  # only acts where there is more than one drone
    drone: DroneParams = field(default_factory=DroneParams)
    ball: BallParams = field(default_factory=BallParams)

    @property
    def sub_dt(self) -> float:
        return self.dt / self.substeps

    @property
    def lag_per_substep(self) -> float:
        """Fraction of the throttle error closed per sub-step: same continuous lag as 0.43 per 20 ms."""
        keep = (1.0 - self.drone.lag_per_step) ** (self.sub_dt / 0.02)
        return 1.0 - keep
