"""Named observation layouts: what each slice of an observation vector is.

A task declares its observation once, as ordered ``(name, size)`` parts (``obs_parts``, with the
drone's root state first under ``"root"``, 23 values with rotor throttles); ``VolleyEnv.obs_layout``
turns that into an ``ObsLayout`` for an action space (CTBR observations carry no throttles, so the
root is 19 there). The task builds its vector with ``layout.build(name=tensor, ...)`` and anyone
holding the vector (a scripted player, the hierarchical policy building a drill's observation out of
a match's) splits it again with ``layout.split(obs)``: nobody reads index slices by hand.

Everything is a pure tensor op on static shapes (a concatenation, views), so a compiled env step
stays one graph.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

ROOT = "root"
# the root state of one drone (base.VolleyEnv.root_state), world frame
ROOT_PARTS = (("pos", 3), ("quat", 4), ("vel", 3), ("omega", 3), ("heading", 3), ("up", 3), ("throttle", 4))
THROTTLES = 4  # the root's rotor throttles, absent from CTBR observations


@dataclass(frozen=True)
class ObsLayout:
    """Ordered named parts of the last dimension of an observation."""

    parts: tuple[tuple[str, int], ...]

    def __post_init__(self):
        names = [n for n, _ in self.parts]
        if len(set(names)) != len(names):
            raise ValueError(f"an observation layout names each part once, got {names}")

    @property
    def size(self) -> int:
        return sum(s for _, s in self.parts)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(n for n, _ in self.parts)

    def slice(self, name: str) -> slice:
        start = 0
        for n, s in self.parts:
            if n == name:
                return slice(start, start + s)
            start += s
        raise KeyError(f"no part {name!r} in this observation; parts: {', '.join(self.names)}")

    def size_of(self, name: str) -> int:
        s = self.slice(name)
        return s.stop - s.start

    def build(self, **values: torch.Tensor) -> torch.Tensor:
        """The vector [..., size] from one tensor [..., part size] per part, in the layout's order."""
        if set(values) != set(self.names):
            raise ValueError(f"observation parts given {sorted(values)}, the layout has {list(self.names)}")
        for n, s in self.parts:
            if values[n].shape[-1] != s:
                raise ValueError(f"observation part {n!r} has size {values[n].shape[-1]}, the layout says {s}")
        return torch.cat([values[n] for n in self.names], -1)

    def split(self, obs: torch.Tensor) -> dict[str, torch.Tensor]:
        """Part name -> view [..., part size] of ``obs`` [..., size]."""
        if obs.shape[-1] != self.size:
            raise ValueError(f"an observation of size {obs.shape[-1]} does not fit a layout of size {self.size} ({', '.join(self.names)})")
        return {n: obs[..., self.slice(n)] for n in self.names}

    def get(self, obs: torch.Tensor, name: str) -> torch.Tensor:
        return obs[..., self.slice(name)]


def root_layout(with_throttle: bool) -> ObsLayout:
    return ObsLayout(ROOT_PARTS if with_throttle else ROOT_PARTS[:-1])


def for_action_space(parts: tuple[tuple[str, int], ...], with_throttle: bool) -> ObsLayout:
    """A task's declared parts (root with throttles) as the layout of one action space."""
    if with_throttle:
        return ObsLayout(tuple(parts))
    return ObsLayout(tuple((n, s - THROTTLES if n == ROOT else s) for n, s in parts))


__all__ = ["ObsLayout", "ROOT", "ROOT_PARTS", "for_action_space", "root_layout"]
