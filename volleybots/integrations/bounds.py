"""Declared finite bounds for the observation parts the physics leaves unbounded, and the clip that
holds observations to them (the adapters' opt-in ``clip_obs=True``).

Positions, velocities and angular velocities have no hard limit in the physics (a drone may leave
the court; nothing clamps a speed), so the adapters' spaces leave them infinite by default. Wrappers
that scale by the bounds (SuperSuit's ``normalize_obs_v0``) need every bound finite; with
``clip_obs=True`` the adapters declare these instead and clip every observation into them:

- absolute positions (the drone's own ``pos``, a team match's ``positions``): the task's court plus
  ``MARGIN`` on every side, height in ``HEIGHT``;
- relative positions (``anchor``, ``ball``, ``other``, ``target``: one point minus another), the
  difference of two such points: twice the half-extents, height +- the height range;
- linear velocities (the drone's ``vel``, ``ball_vel``): ``SPEED_CAP`` per component;
- angular velocities (``omega``): ``SPIN_CAP`` per component.

They are chosen wide enough that the clip rarely binds: ``benchmarks/obs_bounds.py`` measures how
often on scripted and random play of every task (docs/integrations.md gives the figures). A value the
clip changed is counted (``ObsClip.clipped`` of ``ObsClip.seen``), so a user can check it on their own
play.
"""

from __future__ import annotations

import numpy as np

MARGIN = 3.0  # m beyond the court's lines on every side
HEIGHT = (-1.0, 10.0)  # m: the ground is at 0 (a bouncing ball dips below it within a sub-step)
SPEED_CAP = 20.0  # m/s per component: a ball dropped from 10 m lands at 14 m/s
SPIN_CAP = 20.0  # rad/s per component: the CTBR rate controller commands at most 144 deg/s (2.5 rad/s)

ABSOLUTE = ("pos", "positions")  # points in the (own-side) world frame
RELATIVE = ("anchor", "ball", "other", "target")  # one point minus another
VELOCITY = ("vel", "ball_vel")
SPIN = ("omega",)


def declared(name: str, size: int, court) -> tuple[list[float], list[float]]:
    """(low, high) of a part ``name`` of ``size`` values (xyz triples) on ``court`` (``rules.Court``).
    A ``ValueError`` for a part of no declared kind: a task that adds one must say what bounds it."""
    half = np.array([court.length / 2 + MARGIN, court.width / 2 + MARGIN])
    if name in ABSOLUTE:
        lo, hi = [-half[0], -half[1], HEIGHT[0]], [half[0], half[1], HEIGHT[1]]
    elif name in RELATIVE:
        span = HEIGHT[1] - HEIGHT[0]
        lo, hi = [-2 * half[0], -2 * half[1], -span], [2 * half[0], 2 * half[1], span]
    elif name in VELOCITY + SPIN:
        cap = SPEED_CAP if name in VELOCITY else SPIN_CAP
        lo, hi = [-cap] * 3, [cap] * 3
    else:
        raise ValueError(f"observation part {name!r} has no declared bound; kinds: absolute {ABSOLUTE}, "
                         f"relative {RELATIVE}, velocity {VELOCITY}, spin {SPIN}")
    if size % 3:
        raise ValueError(f"observation part {name!r} of size {size} is not a list of xyz triples")
    return [float(v) for v in lo] * (size // 3), [float(v) for v in hi] * (size // 3)


class ObsClip:
    """Clips observations [..., obs] into (low, high) and counts the values it changed."""

    def __init__(self, low: np.ndarray, high: np.ndarray):
        self.low, self.high = low, high
        self.clipped = 0  # values moved onto a bound
        self.seen = 0  # values clipped or not

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        outside = (obs < self.low) | (obs > self.high)
        self.clipped += int(np.count_nonzero(outside))
        self.seen += obs.size
        return np.clip(obs, self.low, self.high, out=obs) if outside.any() else obs
