"""What the Gymnasium, PettingZoo and Stable-Baselines3 views share: the env's TorchRL specs as
Gymnasium spaces, one agent's action as the tensor the env takes (checked exactly), the checks of
seeds and constructor keywords, and the episode statistics as plain numbers.

The spaces are read from the env's own specs (one agent's slice of ``("agents", "observation")``
and ``("agents", "action")``) and its named observation layout, never restated: a task that changes
its observation or action changes its Gymnasium and PettingZoo spaces with it.

Observation bounds. A part of the observation is bounded where its construction bounds it: the
attitude quaternion (a unit quaternion), the heading and up axes (unit vectors) and the rotor
throttles (mapped to [-1, 1]) lie in [-1, 1], up to float32 rounding (a unit vector's component
computed from a renormalised quaternion comes out as 1.0000002): their boxes allow ``UNIT_SLACK``
more. The turn, id, may-hit and side parts are one-hots or
flags in [0, 1]. Positions, velocities and angular velocities have no hard limit in the physics (a
drone may leave the court, and nothing clamps its speed), so they stay unbounded, unless the
adapter is made with ``clip_obs=True``: then they take the declared bounds of ``bounds`` and the
observations are clipped into them.
"""

from __future__ import annotations

import numpy as np
import torch
from gymnasium import spaces
from torchrl.data import Bounded, Categorical, Unbounded

from volleybots.config import build_env
from volleybots.integrations.bounds import ObsClip, declared
from volleybots.keys import ACTION, OBS, STATS, stat
from volleybots.tasks import TASKS, VolleyEnv
from volleybots.tasks.layout import ROOT, root_layout

SINGLE_TASKS = tuple(name for name, cls in TASKS.items() if cls.n_drones == 1)  # what the Gymnasium env accepts
STATS_KEY = "final_stats"  # the info key of the episode statistics: "episode" belongs to RecordEpisodeStatistics and Monitor
SEED_MAX = 2**63 - 1  # torch.Generator.manual_seed takes a signed 64-bit integer
BOOL_KEYS = ("reward_shaping", "downwash", "compile", "compile_physics")  # task keywords that are switches
UNIT_PARTS = ("quat", "heading", "up", "throttle")  # root parts in [-1, 1] by construction
FLAG_PARTS = ("turn", "id", "may_hit", "side")  # one-hots and flag pairs, in [0, 1] exactly
UNIT_SLACK = 1e-4  # float32 rounding of the unit parts: hundreds of ulps at 1.0, far below any physical change


def check_seed(seed) -> int | None:
    """``seed`` as an int, or a ``ValueError`` naming it: None, or an integer in [0, 2**63 - 1]."""
    if seed is None:
        return None
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)):
        raise ValueError(f"seed must be None or an integer in [0, {SEED_MAX}], got {seed!r} ({type(seed).__name__})")
    if not 0 <= int(seed) <= SEED_MAX:
        raise ValueError(f"seed must be None or an integer in [0, {SEED_MAX}], got {seed!r}")
    return int(seed)


def build(task: str, num_envs: int, seed=0, **kw) -> VolleyEnv:
    """``build_env`` after the checks the adapters' users need on top of it: the switches are bools
    (``reward_shaping="no"`` is not read as true), ``num_envs`` an int >= 1 and ``seed`` as for ``reset``."""
    for key in BOOL_KEYS:
        if key in kw and not isinstance(kw[key], (bool, np.bool_)):
            raise ValueError(f"{key} must be True or False, got {kw[key]!r} ({type(kw[key]).__name__})")
    if isinstance(num_envs, (bool, np.bool_)) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
        raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
    return build_env(task, num_envs=int(num_envs), seed=check_seed(seed), **kw)


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


def observation_bounds(env: VolleyEnv, clip_obs: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) [obs_dim] of one agent's observation: finite where the construction bounds a part
    (module docstring); elsewhere infinite, or with ``clip_obs`` the declared bounds of ``bounds``."""
    low, high = [], []
    unit = 1.0 + UNIT_SLACK
    for name, size in env.layout.parts:
        parts = root_layout(env.with_throttle).parts if name == ROOT else ((name, size),)
        for sub, k in parts:
            if name == ROOT and sub in UNIT_PARTS:
                lo, hi = [-unit] * k, [unit] * k
            elif sub in FLAG_PARTS:
                lo, hi = [0.0] * k, [1.0] * k
            elif clip_obs:
                lo, hi = declared(sub, k, env.referee.cfg.court)
            else:
                lo, hi = [-np.inf] * k, [np.inf] * k
            low += lo
            high += hi
    return np.array(low, np.float32), np.array(high, np.float32)


def check_clip_obs(clip_obs) -> bool:
    if not isinstance(clip_obs, (bool, np.bool_)):
        raise ValueError(f"clip_obs must be True or False, got {clip_obs!r} ({type(clip_obs).__name__})")
    return bool(clip_obs)


def observation_space(env: VolleyEnv, clip_obs: bool = False) -> spaces.Box:
    """One agent's observation ``Box`` (``observation_bounds``)."""
    one = env.observation_spec[OBS][0, 0]
    low, high = observation_bounds(env, clip_obs)
    if low.shape != tuple(one.shape):  # the layout and the spec are one declaration: they cannot disagree
        raise AssertionError(f"{env.name}: observation layout of size {low.shape} against a spec of shape {tuple(one.shape)}")
    return spaces.Box(low, high, tuple(one.shape), np.float32)


class Observations:
    """One agent's observation space and the arrays an adapter returns from the env's observation
    tensors: copies on the CPU and, with ``clip_obs``, clipped into the declared bounds (``clip``
    counts the values it changed; None without ``clip_obs``)."""

    def __init__(self, env: VolleyEnv, clip_obs: bool = False):
        self.clip_obs = check_clip_obs(clip_obs)
        self.space = observation_space(env, self.clip_obs)
        self.clip = ObsClip(self.space.low, self.space.high) if self.clip_obs else None

    def __call__(self, x: torch.Tensor) -> np.ndarray:
        out = to_numpy(x)
        return out if self.clip is None else self.clip(out)


def action_space(env: VolleyEnv) -> spaces.Space:
    return agent_space(env.action_spec[ACTION])


class Actions:
    """One env's actions as an adapter takes them: checked against what the adapter's API promises, then
    the env's ``("agents", "action")`` tensor. The spec is read once here: TorchRL builds ``action_spec``
    anew on every access, a tenth of a millisecond per step on a batched step of a few milliseconds.

    ``batch`` is the env's batch of agents' actions (``(N, 1)`` for the vector env, ``(1, A)`` for one
    world of ``A`` agents); ``shape(api_batch)`` the shape an API's action has."""

    def __init__(self, env: VolleyEnv, batch: tuple[int, ...]):
        spec = env.action_spec[ACTION]
        self.name, self.device, self.batch = env.name, env.device, tuple(batch)
        self.discrete = isinstance(spec, Categorical)
        self.dtype, self.one = spec.dtype, tuple(spec.shape[2:])  # one agent's action: (4,) or ()

    def shape(self, batch: tuple[int, ...] = ()) -> tuple[int, ...]:
        """The shape an API's action has: ``batch`` followed by one agent's (``(4,)`` or ``()``)."""
        return (*batch, *self.one)

    def array(self, action, shape: tuple[int, ...], agent: str | None = None) -> np.ndarray:
        """``action`` (numpy, a number or a sequence) checked: exactly ``shape`` (``(4,)`` for one
        continuous agent, ``()`` for one discrete one, ``(N, 4)`` or ``(N,)`` for a batch), real numbers
        for a ``Box``, integers for a ``Discrete``. A ``ValueError`` names the bad shape or type, what
        is allowed and the ``agent`` it is of; nothing is reshaped, rounded or cast silently."""
        who = f"{self.name}" + (f", agent {agent!r}" if agent is not None else "")
        kind = "integers (a Discrete action)" if self.discrete else "real numbers (a Box action)"
        try:
            arr = np.asarray(action.detach().cpu() if isinstance(action, torch.Tensor) else action)
        except (ValueError, TypeError):  # numpy's own words for a ragged list name neither the agent nor the shape
            raise ValueError(f"{who}: got a ragged action (rows of different lengths); expected shape {tuple(shape)} "
                             f"of {kind}") from None
        if arr.shape != tuple(shape):
            raise ValueError(f"{who}: got an action of shape {arr.shape}; expected shape {tuple(shape)} of {kind}")
        if arr.dtype.kind not in ("iu" if self.discrete else "iuf"):
            shown = np.array2string(arr.ravel()[:6], separator=", ") + (" ..." if arr.size > 6 else "")
            raise ValueError(f"{who}: got an action of dtype {arr.dtype} ({shown}); expected {kind}")
        return arr

    def tensor(self, arr: np.ndarray) -> torch.Tensor:
        """A checked action (``array``) as the env's ``("agents", "action")`` [*batch, *one]."""
        return torch.as_tensor(arr.reshape(*self.batch, *self.one), dtype=self.dtype, device=self.device)


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
