"""Action spaces: PRT (per-rotor thrust), CTBR (through the rate controller) and discrete (16 actions).

Each turns a policy's action [N, D, ...] into a function the physics calls once per sub-step to get
per-rotor commands, so a rate controller runs at the physics rate.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import torch

from volleybots.physics.controllers import RateController
from volleybots.physics.math import num
from volleybots.physics.params import WorldParams

ACTION_SPACE_INFO = {
    "prt": "per-rotor thrust: 4 commands in [-1, 1] (default)",
    "ctbr": "collective thrust + body rates, through the 200 Hz PID rate controller",
    "discrete": "16 actions: each rotor at -1 or +1 (value-based methods such as DQN)",
}
ACTION_SPACES = tuple(ACTION_SPACE_INFO)


def discrete_table(device=None, dtype=torch.float32) -> torch.Tensor:
    """The 16 joint actions: row k sets rotor i to +1 where bit i of k is set, else -1."""
    k = torch.arange(16, device=device).unsqueeze(-1)
    bits = (k >> torch.arange(4, device=device)) & 1
    return bits.to(dtype) * 2.0 - 1.0


class ActionSpace(ABC):
    name: str
    continuous: bool = True
    dim: int = 4
    n: int = 0  # number of discrete actions, 0 when continuous

    def __init__(self, params: WorldParams, num_envs: int, n_drones: int, device, dtype=torch.float32):
        self.params = params

    def reset(self, mask: torch.Tensor) -> None:
        pass

    def check(self, action: torch.Tensor) -> None:
        """Raise ``ValueError`` for an action no policy may send (eager, before the compiled step)."""

    def sanitize(self, action: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(action with every non-finite drone action zeroed, [N, D] drones whose action was) - a
        masked select on fixed shapes: the env treats such an action as a crash of its drone (docs/physics.md)."""
        finite = torch.isfinite(action).all(-1)  # [N, D]
        return torch.where(finite.unsqueeze(-1), action, 0.0), ~finite

    @abstractmethod
    def command_fn(self, action: torch.Tensor):
        """Return ``fn(state) -> rotor commands [N, D, 4]``, called once per physics sub-step."""


class PRT(ActionSpace):
    name = "prt"

    def command_fn(self, action):
        one = num(1.0, action)
        cmd = action.clamp(-one, one)
        return lambda state: cmd


class Discrete(ActionSpace):
    name = "discrete"
    continuous = False
    n = 16

    def __init__(self, params, num_envs, n_drones, device, dtype=torch.float32):
        super().__init__(params, num_envs, n_drones, device, dtype)
        self.table = discrete_table(device, dtype)

    def check(self, action):
        """The actions are the integers 0..15: a float that is not an integer, a negative value (which
        indexing would wrap around) or 16 and above is refused, naming the first bad value."""
        if action.dtype.is_floating_point:
            bad = ~((action >= 0) & (action < self.n) & (action == action.round()))
        else:
            bad = (action < 0) | (action >= self.n)
        if bool(bad.any()):
            value = action[bad][0].item()
            raise ValueError(f"discrete action {value!r} is out of range: allowed integers 0..{self.n - 1}")

    def sanitize(self, action):
        return action, torch.zeros(action.shape[:2], dtype=torch.bool, device=action.device)

    def command_fn(self, action):
        cmd = self.table[action.long()]
        return lambda state: cmd


class CTBR(ActionSpace):
    name = "ctbr"

    def __init__(self, params, num_envs, n_drones, device, dtype=torch.float32):
        super().__init__(params, num_envs, n_drones, device, dtype)
        self.controller = RateController(params.drone, num_envs, n_drones, params.sub_dt, device, dtype)

    def reset(self, mask):
        self.controller.reset(mask)

    def command_fn(self, action):
        rates, thrust = RateController.scale_action(action)
        return lambda state: self.controller(state.omega, rates, thrust)


def make_action_space(name: str, params: WorldParams, num_envs: int, n_drones: int, device, dtype=torch.float32) -> ActionSpace:
    spaces = {"prt": PRT, "ctbr": CTBR, "discrete": Discrete}
    if name not in spaces:
        raise ValueError(f"unknown action_space {name!r}; allowed: {list(spaces)}")
    return spaces[name](params, num_envs, n_drones, device, dtype)
