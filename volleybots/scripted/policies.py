"""Scripted policies of the single-drone tasks, and the registry ``make_scripted_policy``.

A scripted policy is a policy like a learned one: it reads ``("agents", "observation")`` only (its
layout: tasks/single.py) and writes ``("agents", "action")`` for every env of the batch, in the PRT
or CTBR action space. It keeps no state between steps, so resets need no special handling. What it
may know besides the observation are the task's constants (the anchor (4.5, 0, 2), the court).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase

from volleybots.physics.params import WorldParams
from volleybots.scripted.ballistics import launch_for_apex, launch_for_range
from volleybots.scripted.control import DroneController, DroneObs, Gains
from volleybots.scripted.plan import StrikePlanner, goto_accel, off_centre

ANCHOR = (4.5, 0.0, 2.0)


class ScriptedPolicy(TensorDictModuleBase):
    """Base of the scripted policies: parses the observation, calls ``act``, writes the action."""

    task: str = ""

    def __init__(self, action_space: str = "prt", params: WorldParams | None = None, gains: Gains | None = None):
        super().__init__()
        self.in_keys = [("agents", "observation")]
        self.out_keys = [("agents", "action")]
        self.params = params or WorldParams()
        self.action_space = action_space
        self.ctrl = DroneController(self.params, action_space, gains)

    def act(self, drone: DroneObs, task_obs: torch.Tensor) -> torch.Tensor:
        raise TypeError(f"{type(self).__name__} must define act()")

    def forward(self, td: TensorDictBase) -> TensorDictBase:
        obs = td.get(("agents", "observation"))
        drone = DroneObs.from_obs(obs, self.action_space == "prt")
        td.set(("agents", "action"), self.act(drone, obs[..., drone.root_dim :]))
        return td

    def _vec(self, ref: torch.Tensor, values) -> torch.Tensor:
        return torch.as_tensor(values, dtype=ref.dtype, device=ref.device)


@dataclass(frozen=True)
class GotoConfig:
    accel: float = 10.0  # m/s^2 the guidance may ask for (horizontal thrust left after hovering is about 11)
    brake: float = 9.0  # braking the speed profile plans with, a little below what the drone can do
    speed: float = 12.0  # m/s cap
    k_v: float = 8.0  # 1/s speed tracking
    k_p: float = 3.0  # 1/s close-in position gain
    stop_at: float = 0.0  # stop this far short of the target


class HoverPolicy(ScriptedPolicy):
    """Fly to the target (drone minus target is the observation's task part) and hold it."""

    task = "hover"

    def __init__(self, action_space="prt", params=None, gains=None, goto: GotoConfig = GotoConfig()):
        super().__init__(action_space, params, gains)
        self.goto = goto

    def target(self, drone: DroneObs, task_obs: torch.Tensor) -> torch.Tensor:
        return drone.pos - task_obs[..., 0:3]

    def act(self, drone, task_obs):
        c = self.goto
        acc = goto_accel(drone.pos, drone.vel, self.target(drone, task_obs), c.accel, c.speed, c.k_v, c.k_p, c.brake, c.stop_at)
        return self.ctrl.act_accel(drone, acc)


class BackAndForthPolicy(HoverPolicy):
    """Shuttle between the two anchors as fast as the airframe allows.

    A target counts after 5 steps within 0.6 m, so the drone need not stop on it: the speed profile
    brakes to a stop ``stop_at`` short of it (inside the sphere), and the observation's target has
    swapped to the other anchor by the time the drone turns.
    """

    task = "back_and_forth"

    def __init__(self, action_space="prt", params=None, gains=None, goto: GotoConfig = GotoConfig(stop_at=0.45)):
        super().__init__(action_space, params, gains, goto)


class _BallPolicy(ScriptedPolicy):
    """Observation of the ball drills: root, drone minus anchor, drone minus ball, ball velocity."""

    def ball(self, drone: DroneObs, task_obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return drone.pos - task_obs[..., 3:6], task_obs[..., 6:9]


@dataclass(frozen=True)
class BumpConfig:
    contact_z: float = 2.2  # drone centre height at contact (the drone must stay below 2.5 m)
    apex: float = 3.9  # wanted apex: the window is [3.5, 4.5] and above 4.5 m ends the episode
    return_gain: float = 1.0  # fraction of the ball's offset from the anchor removed per bump
    max_drift: float = 1.5  # m/s cap on the horizontal ball speed a bump gives
    window: float = 0.45  # s: length of the vertical approach into the contact
    lock_time: float = 0.2  # s before contact when the racket is held along the planned normal
    slack: float = 0.0  # m off the racket's centre the ball may be met (0: aim at the centre)
    max_tilt: float = math.radians(25.0)


class SoloBumpPolicy(_BallPolicy):
    """Bump the ball straight up to ``apex`` again and again, steering it back over the anchor."""

    task = "solo_bump"

    def __init__(self, action_space="prt", params=None, gains=None, cfg: BumpConfig = BumpConfig()):
        super().__init__(action_space, params, gains)
        self.cfg = cfg
        self.planner = StrikePlanner(self.params)

    def act(self, drone, task_obs):
        strike = self.plan(drone, task_obs)
        return self.strike_action(drone, strike, self._vec(drone.pos, ANCHOR), self.cfg.window, self.cfg.lock_time)

    def plan(self, drone, task_obs):
        """The next contact."""
        c = self.cfg
        ball_p, ball_v = self.ball(drone, task_obs)
        anchor = self._vec(ball_p, ANCHOR)
        contact_ball_z = c.contact_z + self.planner.reach

        def want_out(bp, bv):
            home = bp[..., :2] + c.return_gain * (anchor[:2] - bp[..., :2])
            v = launch_for_apex(bp, home, c.apex, contact_ball_z, self.params.gravity)
            h = v[..., :2]
            h = h * (c.max_drift / h.norm(dim=-1, keepdim=True).clamp_min(1e-9)).clamp(max=1.0)
            return torch.cat((h, v[..., 2:]), -1)

        return off_centre(self.planner.plan(ball_p, ball_v, contact_ball_z, want_out, c.max_tilt), drone.pos, c.slack)

    def strike_action(self, drone: DroneObs, strike, home: torch.Tensor, window, lock_time: float, hold=None) -> torch.Tensor:
        """Fly the strike. Horizontally the drone goes to the contact point as soon as it can
        (arriving early leaves time to settle the tilt); vertically it follows the planned approach
        (hold below the contact point, then the quintic into it, ``window`` s long), which times the
        racket's speed. In the last ``lock_time`` s the thrust, so the racket, points along the
        planned normal whatever the position error: the tilt at contact, not where on the racket
        the ball lands, decides where the ball goes."""
        p, v, a = self.planner.reference(strike, window, hold)
        p_ref = torch.cat((strike.drone_pos[..., :2], p[..., 2:]), -1)
        v_ref = torch.cat((strike.drone_vel[..., :2], v[..., 2:]), -1)
        a_ref = torch.cat((strike.drone_acc[..., :2], a[..., 2:]), -1)
        f = self.ctrl.thrust_vector(drone, self.ctrl.position_accel(drone, p_ref, v_ref, a_ref))
        n = strike.normal
        locked = f[..., 2:] / n[..., 2:].clamp_min(0.3) * n
        f = torch.where((strike.t < lock_time).unsqueeze(-1), locked, f)
        # a ball that will never come down to the contact height (it is below it): hold at home
        wait = self.ctrl.thrust_vector(drone, self.ctrl.position_accel(drone, home.expand_as(drone.pos), torch.zeros_like(drone.vel)))
        f = torch.where(strike.valid.unsqueeze(-1), f, wait)
        return self.ctrl.act_thrust(drone, f)
