"""Policies trained elsewhere as competitors: a Python callable, a ``module:function`` named on the
command line, a TorchScript file and a Stable-Baselines3 archive (docs/matches.md, "Your policy in
every verb").

The contract is the one every trainer can meet: a function from a batch of observations to a batch of
actions. It sees one row per drone of its team, ``[B, obs_dim]`` (B = worlds x drones of the team),
already mirrored to the +x side as every competitor sees it, and returns ``[B, 4]`` real numbers
(``prt`` / ``ctbr``) or ``[B]`` integers (``discrete``), as a torch tensor or a numpy array. By default
it is handed a torch tensor (on the env's device); ``numpy=True`` hands it a float32 numpy array
(Stable-Baselines3's ``model.predict`` takes those). It is called under ``torch.no_grad()``.

- ``callable_competitor(fn, label)``: the Python API; its result plays wherever a ``Competitor`` does
  (``volleybots.eval.crossplay.crossplay``, the match envs of ``volleybots.integrations``).
- ``module:function`` (``pkg.mod:attr``): the CLI spec of ``eval crossplay``, ``eval elo``, ``eval
  exploitability`` and ``opponent=``. The module is imported by name from the Python path (the user's
  own installed or importable code), never from a file a run directory or results file points to. The
  attribute is a function (called as above with torch tensors) or a ``Competitor`` built with
  ``callable_competitor`` (for numpy input or a declared task).
- ``torchscript:FILE``: a module saved with ``torch.jit.save`` whose ``forward`` is the function above
  (torch in, torch out); any other file is refused in one line.
- ``sb3:FILE.zip``: a PPO or A2C model saved by Stable-Baselines3, its actor rebuilt from the saved
  weights and the readable parts of the archive, without unpickling anything (``load_sb3``).

A callable's cross-play results are never copied by ``reuse=`` (nothing proves the code is the same);
a TorchScript file or an SB3 archive is recognised by its sha256 as a checkpoint is. Why a spec names
a module and not a file: importing by name runs only code the user installed or put on the path
themselves, while a file path could come from a run directory or a results file someone else wrote.
"""

from __future__ import annotations

import importlib
import re
from typing import Callable

import numpy as np
import torch
from tensordict import TensorDictBase

from volleybots.errors import ConfigError
from volleybots.files import exists
from volleybots.keys import ACTION, OBS

TORCHSCRIPT = "torchscript:"  # the prefix of a TorchScript file's spec
SB3 = "sb3:"  # the prefix of a model saved by Stable-Baselines3 (its .zip)
# pkg.mod:attr (dotted Python names on both sides): what a ``module:function`` spec looks like
IMPORT_SPEC = re.compile(r"^[A-Za-z_]\w*(\.[A-Za-z_]\w*)*:[A-Za-z_]\w*(\.[A-Za-z_]\w*)*$")
UNVERIFIED = ("callable", "import")  # member kinds whose code no hash pins down (``reuse=`` replays them)


def is_import_spec(target: str) -> bool:
    """Whether ``target`` reads as ``module:function`` (and is no existing path)."""
    return bool(IMPORT_SPEC.match(target)) and not exists(target)


class CallablePolicy:
    """One team's ``td -> td`` policy from an obs-batch -> action-batch function (the module docstring)."""

    def __init__(self, fn: Callable, env, label: str, numpy: bool = False):
        if isinstance(fn, torch.nn.Module) and not numpy:  # a loaded network (TorchScript, SB3) acts where the env's tensors are
            fn = fn.to(env.device)
        self.fn, self.label, self.numpy = fn, label, numpy
        acts = env.actions
        self.device = env.device
        self.continuous = acts.continuous
        self.one = (acts.dim,) if acts.continuous else ()
        self.dtype = torch.float32 if acts.continuous else torch.long

    def __call__(self, td: TensorDictBase) -> TensorDictBase:
        obs = td.get(OBS)
        n, a = obs.shape[:2]
        x = obs.reshape(n * a, obs.shape[-1])
        with torch.no_grad():
            y = self.fn(x.detach().cpu().numpy() if self.numpy else x)
        td.set(ACTION, self.check(y, n * a).reshape(n, a, *self.one))
        return td

    def check(self, y, rows: int) -> torch.Tensor:
        """The function's result as the env's action tensor: exactly ``[rows, *one]`` real numbers (a
        Box action) or integers (a discrete one); anything else is one ``ConfigError`` line naming it
        (bad input: the CLI's one line and exit code 2, not a traceback)."""
        if isinstance(y, torch.Tensor):
            t = y.detach()
        else:
            arr = np.asarray(y)
            if arr.dtype == object:
                raise ConfigError(f"competitor {self.label!r} returned {type(y).__name__}, "
                                 "not an action batch (torch tensor or numpy array)")
            t = torch.from_numpy(np.ascontiguousarray(arr))
        want = (rows, *self.one)
        kind = "real numbers (a Box action)" if self.continuous else "integers (a discrete action)"
        if tuple(t.shape) != want:
            raise ConfigError(f"competitor {self.label!r} returned actions of shape {tuple(t.shape)} for {rows} observations; "
                             f"expected shape {want} of {kind}")
        if t.dtype == torch.bool or t.is_complex() or (not self.continuous and t.is_floating_point()):
            raise ConfigError(f"competitor {self.label!r} returned actions of dtype {t.dtype}; expected {kind}")
        return t.to(self.device, self.dtype)


def import_target(spec: str):
    """The object a ``module:function`` spec names: the module imported by name from the Python path,
    then its (dotted) attribute; a failure is one ``ConfigError`` line."""
    module, _, attr = spec.partition(":")
    try:
        obj = importlib.import_module(module)
    except ImportError as e:
        raise ConfigError(f"competitor {spec!r}: cannot import module {module!r} ({e}); it must be importable by name "
                          "(installed, or on PYTHONPATH)") from None
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise ConfigError(f"competitor {spec!r}: module {module!r} has no attribute {attr!r}")
        obj = getattr(obj, part)
    return obj


def load_torchscript(path: str):
    """The module a TorchScript file holds (on the CPU, in eval mode); a file that is not TorchScript
    (a checkpoint, a pickle, text) is one ``ConfigError`` line."""
    if not exists(path):
        raise ConfigError(f"competitor {TORCHSCRIPT}{path!r} does not exist; expected a file written by torch.jit.save")
    try:
        module = torch.jit.load(path, map_location="cpu")
    except Exception as e:  # noqa: BLE001 - torch raises RuntimeError, ValueError or zip errors alike for a foreign file
        reason = " ".join(str(e).split())[:120]
        raise ConfigError(f"competitor {TORCHSCRIPT}{path!r} is not a TorchScript file (torch.jit.save writes one): {reason}") from None
    module.eval()
    return module


# SB3's activation classes by the name its saved "data" shows them (torch.nn.modules.activation.<Name>)
SB3_ACTIVATIONS = {"Tanh": torch.nn.Tanh, "ReLU": torch.nn.ReLU, "ELU": torch.nn.ELU, "LeakyReLU": torch.nn.LeakyReLU,
                   "SiLU": torch.nn.SiLU, "GELU": torch.nn.GELU}


def load_sb3(path: str) -> torch.nn.Module:
    """The deterministic actor of a model saved by Stable-Baselines3's ``model.save`` (PPO or A2C with an
    ``MlpPolicy``), rebuilt without unpickling anything: the weights come from the archive's
    ``policy.pth`` (``torch.load(weights_only=True)``), the layout from their names and shapes, the
    activation from the readable text SB3 writes beside its pickles in ``data`` (JSON). The action is
    the Gaussian's mean clipped into [-1, 1] (a Box, what SB3's ``predict(deterministic=True)`` gives)
    or the most likely action (a Discrete). Anything else is one ``ConfigError`` line."""
    import io
    import json
    import zipfile

    what = f"competitor {SB3}{path!r}"
    if not exists(path):
        raise ConfigError(f"{what} does not exist; expected a .zip written by a Stable-Baselines3 model's save()")
    try:
        with zipfile.ZipFile(path) as z:
            data = json.loads(z.read("data"))
            state = torch.load(io.BytesIO(z.read("policy.pth")), map_location="cpu", weights_only=True)
    except (zipfile.BadZipFile, KeyError, ValueError, RuntimeError, OSError) as e:
        raise ConfigError(f"{what} is not a saved Stable-Baselines3 model ({' '.join(str(e).split())[:100]})") from None
    init = str((data.get("policy_class") or {}).get("__init__", ""))
    if "ActorCriticPolicy." not in init or data.get("use_sde"):
        raise ConfigError(f"{what}: only an ActorCriticPolicy without gSDE (PPO or A2C, MlpPolicy) loads without unpickling")
    named = str((data.get("policy_kwargs") or {}).get("activation_fn", "Tanh"))
    act = next((cls for name, cls in SB3_ACTIVATIONS.items() if named.rstrip("'>").endswith(name)), None)
    if act is None:
        raise ConfigError(f"{what}: activation {named!r} is not one of {', '.join(SB3_ACTIVATIONS)}")
    if any("features_extractor." in k for k in state):
        raise ConfigError(f"{what}: a features extractor with weights (not SB3's flatten) needs SB3 itself: use callable_competitor")
    layers, k = [], 0
    while f"mlp_extractor.policy_net.{k}.weight" in state:
        w = state[f"mlp_extractor.policy_net.{k}.weight"]
        layers += [torch.nn.Linear(w.shape[1], w.shape[0]), act()]
        layers[-2].load_state_dict({"weight": w, "bias": state[f"mlp_extractor.policy_net.{k}.bias"]})
        k += 2  # SB3's Sequential puts the activation between: the linear layers are 0, 2, 4, ...
    head = torch.nn.Linear(state["action_net.weight"].shape[1], state["action_net.weight"].shape[0])
    head.load_state_dict({"weight": state["action_net.weight"], "bias": state["action_net.bias"]})
    actor = _SB3Actor(torch.nn.Sequential(*layers, head), "log_std" in state).eval()
    actor.obs_dim = int((layers[0] if layers else head).in_features)  # what a cross-play checks the task's against
    return actor


class _SB3Actor(torch.nn.Module):
    def __init__(self, net: torch.nn.Module, box: bool):
        super().__init__()
        self.net, self.box = net, box

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        out = self.net(obs.float())
        return out.clamp(-1.0, 1.0) if self.box else out.argmax(-1)


__all__ = ["IMPORT_SPEC", "SB3", "TORCHSCRIPT", "UNVERIFIED", "CallablePolicy", "import_target", "is_import_spec", "load_sb3",
           "load_torchscript"]
