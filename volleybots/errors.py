"""What counts as bad user input: ``ConfigError`` and the valid ranges of numeric config keys.

A leaf module (it imports nothing of volleybots), so that the config, the algorithms, the run
directory and evaluation can all raise the same error and declare ranges without importing each
other: ``volleybots.config`` imports the algorithms to validate their configs, and the algorithms
declare their keys' ranges here rather than there.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass


class ConfigError(ValueError):
    """A bad user input (unknown name or key, wrong type, out-of-range value, incompatible choice, a
    run directory in use): the CLI prints its message as one line and exits with code 2."""


@dataclass(frozen=True)
class Range:
    """The values a numeric key may take: bounds (open or closed, ``None`` for none), always finite.

    A list value (``algo.hidden``) is checked element by element; ``length`` asks for a list of
    exactly that many numbers (a position)."""

    low: float | None = None
    high: float | None = None
    low_open: bool = False  # value > low rather than >= low
    high_open: bool = False  # value < high rather than <= high
    length: int | None = None

    def __contains__(self, value) -> bool:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return False
        if isinstance(value, float) and not math.isfinite(value):
            return False
        if self.low is not None and (value <= self.low if self.low_open else value < self.low):
            return False
        return not (self.high is not None and (value >= self.high if self.high_open else value > self.high))

    def holds(self, value) -> bool:
        """Whether ``value`` (a number, or a list of numbers) is allowed."""
        if self.length is None and not isinstance(value, (list, tuple)):
            return value in self
        if not isinstance(value, (list, tuple)) or (self.length is not None and len(value) != self.length):
            return False
        return all(v in self for v in value)

    def __str__(self) -> str:
        if self.low is None and self.high is None:
            bound = "finite"
        elif self.high is None:
            bound = f"{'>' if self.low_open else '>='} {self.low}"
        elif self.low is None:
            bound = f"{'<' if self.high_open else '<='} {self.high}"
        else:
            bound = f"in {'(' if self.low_open else '['}{self.low}, {self.high}{')' if self.high_open else ']'}"
        if self.length is not None:
            return f"a list of {self.length} numbers, each {bound}"
        return "a finite number" if bound == "finite" else bound


def ranged(default=dataclasses.MISSING, *, ge=None, gt=None, le=None, lt=None, factory=dataclasses.MISSING):
    """A dataclass field with its valid range in the metadata (``volleybots.config.validate`` reads
    it): ``lr: float = ranged(5e-4, gt=0)``; ``factory`` for list defaults."""
    rng = Range(low=gt if gt is not None else ge, high=lt if lt is not None else le, low_open=gt is not None, high_open=lt is not None)
    return dataclasses.field(default=default, default_factory=factory, metadata={"range": rng})


def field_range(schema: type, name: str) -> Range | None:
    """The range of the field ``name`` of the dataclass ``schema``; a subclass that only changes a
    default (``iterations: int = 1``) keeps the range its base class declared."""
    for klass in schema.__mro__:
        f = getattr(klass, "__dataclass_fields__", {}).get(name)
        if f is not None and "range" in f.metadata:
            return f.metadata["range"]
    return None


def check_device(key: str, value: str) -> None:
    """Raise ``ConfigError`` unless ``value`` names a torch device that exists here (``cuda:3``
    needs four GPUs): torch itself would fail only at the first tensor, with a traceback."""
    import torch

    try:
        dev = torch.device(value)
    except (RuntimeError, ValueError, TypeError):
        raise ConfigError(f"bad value for {key!r}: {value!r} is not a torch device (cpu, cuda, cuda:1, ...)") from None
    if dev.type == "cuda":
        n = torch.cuda.device_count() if torch.cuda.is_available() else 0
        if n == 0:
            raise ConfigError(f"{key}={value!r} but no CUDA device is available here; use {key}=cpu")
        if dev.index is not None and dev.index >= n:
            raise ConfigError(f"{key}={value!r} but this machine has {n} CUDA device(s): cuda:0 to cuda:{n - 1}")
    elif dev.type == "mps" and not torch.backends.mps.is_available():
        raise ConfigError(f"{key}={value!r} but no MPS device is available here; use {key}=cpu")
    elif dev.type not in ("cpu", "cuda", "mps"):
        raise ConfigError(f"bad value for {key!r}: {value!r} is not supported; use cpu or cuda")


__all__ = ["ConfigError", "Range", "check_device", "field_range", "ranged"]
