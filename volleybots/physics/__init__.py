"""Pure batched dynamics of drones and ball: no volleyball rules here."""

from volleybots.physics.actions import ACTION_SPACE_INFO, ACTION_SPACES, make_action_space
from volleybots.physics.controllers import RateController
from volleybots.physics.params import BallParams, DroneParams, WorldParams
from volleybots.physics.torch_backend import Contacts, PhysicsState, TorchPhysics

BACKEND_INFO = {
    "torch": "batched PyTorch rigid-body physics on CPU or CUDA, swept racket contact (fast default)",
    "mujoco": "the same scene in MuJoCo, all envs stepped by mujoco.rollout (reference fidelity)",
}
BACKENDS = tuple(BACKEND_INFO)


def make_physics(name: str, params: WorldParams, num_envs: int, n_drones: int, device="cpu", compile: bool = False):
    if name == "torch":
        return TorchPhysics(params, num_envs, n_drones, device=device, compile=compile)
    if name == "mujoco":
        # imported here so that ``import volleybots`` does not load MuJoCo
        from volleybots.physics.mujoco_backend import MujocoPhysics

        return MujocoPhysics(params, num_envs, n_drones, device=device, compile=compile)
    raise ValueError(f"unknown physics backend {name!r}; allowed: {list(BACKENDS)}")


__all__ = [
    "ACTION_SPACE_INFO", "ACTION_SPACES", "BACKEND_INFO", "BACKENDS", "BallParams", "Contacts", "DroneParams", "PhysicsState",
    "RateController", "TorchPhysics", "WorldParams", "make_action_space", "make_physics",
]
