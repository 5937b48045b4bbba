"""What the Gymnasium and PettingZoo views share: the env's TorchRL specs as Gymnasium spaces, one
agent's action as the tensor the env takes, and the episode statistics as plain numbers.

The spaces are read from the env's own specs (one agent's slice of ``("agents", "observation")``
and ``("agents", "action")``), never restated: a task that changes its observation or action
changes its Gymnasium and PettingZoo spaces with it.
"""

from __future__ import annotations

import numpy as np
import torch
from gymnasium import spaces
from torchrl.data import Bounded, Categorical, Unbounded

from volleybots.keys import ACTION, OBS, STATS, stat
from volleybots.tasks import TASKS, VolleyEnv

SINGLE_TASKS = tuple(name for name, cls in TASKS.items() if cls.n_drones == 1)  # what the Gymnasium env accepts


def agent_space(spec) -> spaces.Space:
    """The Gymnasium space of one agent of a leaf spec of shape [N, A, ...]."""
    one = spec[0, 0]
    if isinstance(one, Categorical):
        return spaces.Discrete(int(one.space.n))
    dtype = np.dtype(str(one.dtype).removeprefix("torch."))
    if isinstance(one, Unbounded):  # TorchRL stores the dtype's extremes; Gymnasium says unbounded with inf
        return spaces.Box(-np.inf, np.inf, tuple(one.shape), dtype)
    if isinstance(one, Bounded):
        return spaces.Box(one.space.low.cpu().numpy(), one.space.high.cpu().numpy(), tuple(one.shape), dtype)
    raise TypeError(f"no Gymnasium space for a {type(one).__name__} spec")


def observation_space(env: VolleyEnv) -> spaces.Space:
    return agent_space(env.observation_spec[OBS])


def action_space(env: VolleyEnv) -> spaces.Space:
    return agent_space(env.action_spec[ACTION])


def action_tensor(env: VolleyEnv, action, shape: tuple[int, ...]) -> torch.Tensor:
    """``action`` (numpy or a sequence) as the env's ``("agents", "action")`` of batch ``shape``
    ([N, A]); a wrong size raises a ``ValueError`` naming the sizes."""
    spec = env.action_spec[ACTION]
    arr = np.asarray(action)
    want = (*shape, *spec.shape[2:])
    if arr.size != int(np.prod(want)):
        raise ValueError(f"{env.name}: got an action of shape {arr.shape}; expected shape {want}")
    return torch.as_tensor(arr.reshape(want), dtype=spec.dtype, device=env.device)


def to_numpy(x: torch.Tensor) -> np.ndarray:
    """A copy on the CPU: the env may write into its tensors at the next step."""
    return x.detach().cpu().numpy().copy()


def episode_stats(env: VolleyEnv, td, index: int | slice = slice(None)) -> dict:
    """``("stats", name)`` of ``td`` (an env output) as ``{name: np.ndarray [N]}`` (or floats for one ``index``)."""
    out = {}
    names = list(env.observation_spec[STATS].keys())
    for k in names:
        v = to_numpy(td.get(stat(k)).reshape(-1))[index]
        out[k] = float(v) if isinstance(index, int) else v
    return out
