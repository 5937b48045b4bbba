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

from volleybots.keys import ACTION, OBS
from volleybots.physics.params import WorldParams
from volleybots.scripted.ballistics import launch_for_apex, time_to_height
from volleybots.scripted.control import DroneController, DroneObs, Gains
from volleybots.scripted.plan import StrikePlanner, goto_accel, off_centre
from volleybots.tasks.layout import ObsLayout, root_layout

ANCHOR = (4.5, 0.0, 2.0)


class ScriptedPolicy(TensorDictModuleBase):
    """Base of the scripted policies: parses the observation, calls ``act``, writes the action."""

    task: str = ""

    def __init__(self, action_space: str = "prt", params: WorldParams | None = None, gains: Gains | None = None):
        super().__init__()
        self.in_keys = [OBS]
        self.out_keys = [ACTION]
        self.params = params or WorldParams()
        self.action_space = action_space
        self.ctrl = DroneController(self.params, action_space, gains)

    @property
    def layout(self) -> ObsLayout:
        """The named layout of the observation this policy reads (its task's, tasks/layout.py)."""
        from volleybots.tasks import TASKS

        return TASKS[self.task].obs_layout(self.action_space == "prt")

    def act(self, drone: DroneObs, obs: dict[str, torch.Tensor]) -> torch.Tensor:
        """The action [..., 4] from the drone's root state and the observation's named parts."""
        raise TypeError(f"{type(self).__name__} must define act()")

    def parts(self, obs: torch.Tensor) -> tuple[DroneObs, dict[str, torch.Tensor]]:
        """An observation [..., obs] as (the drone's state, its named parts)."""
        parts = self.layout.split(obs)
        return DroneObs.from_root(root_layout(self.action_space == "prt").split(parts["root"])), parts

    def forward(self, td: TensorDictBase) -> TensorDictBase:
        td.set(ACTION, self.act(*self.parts(td.get(OBS))))
        return td

    def replan_every(self, steps: int) -> "ScriptedPolicy":
        """Let every lookahead of this player (and of the players inside it) keep a chosen variant for
        ``steps`` control steps (``Lookahead.every``): the player is then no longer memoryless, but
        its search costs about ``steps`` times less. 1 (the default) chooses afresh every step."""
        for m in self.modules():
            if getattr(m, "lookahead", None) is not None:
                m.lookahead.every = steps
        return self

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
    lead: float = 0.0  # s: brake this much early (the time to turn the thrust around)


class HoverPolicy(ScriptedPolicy):
    """Fly to the target (drone minus target is the observation's task part) and hold it."""

    task = "hover"

    # per action space: (gains, guidance); the defaults keep within the default 30 degree tilt
    defaults = dict.fromkeys(("prt", "ctbr"), (None, GotoConfig(accel=6.0, brake=4.5, lead=0.15)))

    def __init__(self, action_space="prt", params=None, gains=None, goto: GotoConfig | None = None):
        default_gains, default_goto = self.defaults.get(action_space, (None, None))
        super().__init__(action_space, params, gains or default_gains)
        self.goto = goto or default_goto

    def target(self, drone: DroneObs, obs: dict[str, torch.Tensor]) -> torch.Tensor:
        return drone.pos - obs["target"]

    def act(self, drone, obs):
        c = self.goto
        acc = goto_accel(drone.pos, drone.vel, self.target(drone, obs), c.accel, c.speed, c.k_v, c.k_p, c.brake, c.stop_at, c.lead)
        return self.ctrl.act_accel(drone, acc)


class BackAndForthPolicy(HoverPolicy):
    """Shuttle between the two anchors as fast as the airframe allows.

    A target counts after 5 steps within 0.6 m, so the drone need not stop on it: the speed profile
    brakes to a stop ``stop_at`` short of it (inside the sphere), and the observation's target has
    swapped to the other anchor by the time the drone turns.
    """

    task = "back_and_forth"

    # the legs are bang-bang: full thrust and steep tilts (PRT also inverts the rotor lag fully;
    # CTBR turns at most 144 deg/s, so it tilts less)
    defaults = {
        "prt": (
            Gains(max_tilt=math.radians(50.0), thrust_margin=1.0, lag_comp=1.0, thrust_keep=0.8),
            GotoConfig(accel=13.0, brake=8.5, lead=0.2, stop_at=0.4, k_p=10.0, k_v=6.0),
        ),
        "ctbr": (
            Gains(max_tilt=math.radians(45.0), thrust_margin=1.0),
            GotoConfig(accel=12.0, brake=8.0, lead=0.2, stop_at=0.5, k_p=4.0, k_v=4.0),
        ),
    }


class _BallPolicy(ScriptedPolicy):
    """Observation of the ball drills: root, drone minus anchor, drone minus ball, ball velocity."""

    def ball(self, drone: DroneObs, obs: dict[str, torch.Tensor]) -> tuple[torch.Tensor, torch.Tensor]:
        """Ball position and velocity (these tasks observe drone minus ball)."""
        return drone.pos - obs["ball"], obs["ball_vel"]

    def strike_action(self, drone: DroneObs, strike, home: torch.Tensor, window, lock_time: float, hold=None, early=(0, 1),
                      early_feed: bool = True, lateral: torch.Tensor | None = None) -> torch.Tensor:
        """Fly the strike along the planned approach (hold, then the quintic into the contact state,
        ``window`` s long), which times the racket's speed. Along the world axes in ``early`` the
        drone goes to the contact point as soon as it can instead (arriving early leaves time to
        settle the tilt; right for axes without racket speed), with the contact's velocity and
        acceleration fed forward the whole way, or, without ``early_feed``, only once the racket
        locks: held for the whole approach, a tilted racket's sideways acceleration is balanced by a
        steady position error (about 0.2 m for a 14 degree tilt: the ball lands on the rim). In the
        last ``lock_time`` s the thrust, so the racket, points along the planned normal whatever the
        position error: the tilt at contact, not where on the racket the ball lands, decides where
        the ball goes. ``lateral`` [..., 2]: a sideways acceleration to fly instead of the
        approach's (until the lock), e.g. a glide through the contact point."""
        p, v, a = self.planner.reference(strike, window, hold)
        mask = torch.zeros(3, dtype=torch.bool, device=p.device)
        mask[list(early)] = True
        feed = mask if early_feed else mask & (strike.t < lock_time).unsqueeze(-1)
        p = torch.where(mask, strike.drone_pos, p)
        v = torch.where(mask, torch.where(feed, strike.drone_vel, 0.0), v)
        a = torch.where(mask, torch.where(feed, strike.drone_acc, 0.0), a)
        acc = self.ctrl.position_accel(drone, p, v, a)
        if lateral is not None:
            acc = torch.cat((lateral, acc[..., 2:]), -1)
        f = self.ctrl.thrust_vector(drone, acc)
        n = strike.normal
        locked = f[..., 2:] / n[..., 2:].clamp_min(0.3) * n
        f = torch.where((strike.t < lock_time).unsqueeze(-1), locked, f)
        # a ball that will never come down to the contact height (it is below it): hold at home
        wait = self.ctrl.thrust_vector(drone, self.ctrl.position_accel(drone, home.expand_as(drone.pos), torch.zeros_like(drone.vel)))
        f = torch.where(strike.valid.unsqueeze(-1), f, wait)
        return self.ctrl.act_thrust(drone, f)


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

    def act(self, drone, obs):
        strike = self.plan(drone, obs)
        return self.strike_action(drone, strike, self._vec(drone.pos, ANCHOR), self.cfg.window, self.cfg.lock_time)

    def plan(self, drone, obs):
        """The next contact."""
        c = self.cfg
        ball_p, ball_v = self.ball(drone, obs)
        anchor = self._vec(ball_p, ANCHOR)
        contact_ball_z = c.contact_z + self.planner.reach

        def want_out(bp, bv):
            home = bp[..., :2] + c.return_gain * (anchor[:2] - bp[..., :2])
            v = launch_for_apex(bp, home, c.apex, contact_ball_z, self.params.gravity)
            h = v[..., :2]
            h = h * (c.max_drift / h.norm(dim=-1, keepdim=True).clamp_min(1e-9)).clamp(max=1.0)
            return torch.cat((h, v[..., 2:]), -1)

        return off_centre(self.planner.plan(ball_p, ball_v, contact_ball_z, want_out, c.max_tilt), drone.pos, c.slack)


@dataclass(frozen=True)
class HitConfig:
    contact_z: float = 3.0  # drone centre height at contact: the climb to it gives the racket speed
    lock_time: float = 0.2  # s before contact when the racket turns to its tilt
    run: float = 1.0  # m/s toward -x at contact
    tilts: tuple[float, float, int] = (5.0, 50.0, 46)  # racket tilts tried (deg): first, last, count
    net_clearance: float = 2.6  # the ball's centre must pass x = 0 above this (the net is 2.43 m)
    max_tilt: float = math.radians(50.0)


class HitTheBallPolicy(_BallPolicy):
    """Hit the falling ball once, as far as possible toward -x, over the net.

    The strike is a climb: from the anchor's height the drone climbs under the ball's line at a
    uniform acceleration timed from the ball's release (the ball falls from rest, so the time since
    its release is -vz / g), meeting it at ``contact_z`` with the speed that climb gives; only in
    the last ``lock_time`` s does the racket tilt toward -x. Of the tilts in ``tilts`` the one whose
    return (restitution law, ballistic flight) comes down through z = 2 farthest away while
    clearing the net is flown. After the hit (the ball flies toward -x) the drone returns to the
    anchor and waits there.
    """

    task = "hit_the_ball"

    def __init__(self, action_space="prt", params=None, gains=None, cfg: HitConfig = HitConfig()):
        super().__init__(action_space, params, gains or Gains(max_tilt=cfg.max_tilt, thrust_margin=1.0))
        self.cfg = cfg
        self.planner = StrikePlanner(self.params)

    def climb(self, ball_p: torch.Tensor, ball_v: torch.Tensor):
        """Time from the ball's release to the contact [...] and the climb's speed at contact [...]."""
        g = self.params.gravity
        z_ball = self.cfg.contact_z + self.planner.reach
        total = torch.sqrt(2.0 * (ball_p[..., 2] + ball_v[..., 2] ** 2 / (2.0 * g) - z_ball).clamp_min(1e-3) / g)
        return total, 2.0 * (self.cfg.contact_z - ANCHOR[2]) / total

    def best_return(self, bp: torch.Tensor, bv: torch.Tensor, speed: torch.Tensor) -> torch.Tensor:
        """Outgoing velocity of the racket tilt (in the x-z plane) that sends the ball farthest, for
        a racket rising at ``speed``."""
        c, g, e = self.cfg, self.params.gravity, self.params.ball.restitution
        lo, hi, k = c.tilts
        th = torch.deg2rad(torch.linspace(lo, hi, k, dtype=bp.dtype, device=bp.device))
        n = torch.stack((-torch.sin(th), torch.zeros_like(th), torch.cos(th)), -1)  # [k, 3]
        s = speed.unsqueeze(-1) * n[:, 2] - self.cfg.run * n[:, 0]  # racket speed along n
        bv_k = bv.unsqueeze(-2)
        v_out = bv_k + ((1.0 + e) * (s - (bv_k * n).sum(-1))).unsqueeze(-1) * n  # [..., k, 3]
        z0 = bp[..., 2:3]
        dist = -v_out[..., 0] * time_to_height(z0.expand_as(v_out[..., 2]), v_out[..., 2], ANCHOR[2], g)
        t_net = bp[..., 0:1] / (-v_out[..., 0]).clamp_min(1e-3)
        z_net = z0 + v_out[..., 2] * t_net - 0.5 * g * t_net * t_net
        dist = torch.where(torch.isfinite(dist) & (z_net > c.net_clearance), dist, torch.full_like(dist, -1e9))
        best = dist.argmax(-1)
        return torch.gather(v_out, -2, best[..., None, None].expand(*bp.shape[:-1], 1, 3)).squeeze(-2)

    def act(self, drone, obs):
        c = self.cfg
        ball_p, ball_v = self.ball(drone, obs)
        anchor = self._vec(drone.pos, ANCHOR).expand_as(drone.pos)
        total, speed = self.climb(ball_p, ball_v)
        strike = self.planner.plan(
            ball_p, ball_v, c.contact_z + self.planner.reach, lambda bp, bv: self.best_return(bp, bv, speed), c.max_tilt
        )
        # the climb: up at contact, plus a run toward -x (only the normal part of the racket's
        # velocity counts); the run starts from rest c.run * total / 2 behind the contact point
        vel = torch.zeros_like(strike.drone_vel)
        vel[..., 0] = -c.run
        vel[..., 2] = speed
        strike.drone_vel = vel
        strike.drone_acc = vel / total.unsqueeze(-1)
        hold = strike.drone_pos - 0.5 * total.unsqueeze(-1) * vel
        hold = torch.cat((hold[..., :2], anchor[..., 2:]), -1)
        hit = self.strike_action(drone, strike, anchor, total, c.lock_time, hold, early=(1,))
        # after the hit the ball flies toward -x: go home, out of its way
        home = self.ctrl.act(drone, anchor, torch.zeros_like(drone.vel))
        return torch.where((ball_v[..., :1] < -1.0), home, hit)


SCRIPTED_POLICIES: dict[str, type[ScriptedPolicy]] = {
    cls.task: cls for cls in (HoverPolicy, BackAndForthPolicy, HitTheBallPolicy, SoloBumpPolicy)
}


def make_scripted_policy(env_or_task, action_space: str | None = None, **kwargs) -> ScriptedPolicy:
    """The scripted policy of a task, for an env or a task name.

    The discrete space has no scripted policy: a model-based controller needs a continuous actuator.

    Args:
        env_or_task: an env of ``make_env`` (its task, action space and physical parameters are used)
            or a task name (default physics).
        action_space: "prt" or "ctbr"; ``None`` takes the env's, or "prt" for a task name.
        **kwargs: keywords of the policy class (gains, configs).

    Returns:
        A TensorDict module reading ``("agents", "observation")`` and writing ``("agents", "action")``;
        on a match it drives every drone (wrap it in ``TeamPolicies`` to play one team).

    Raises:
        ValueError: an unknown task or action space, named with the allowed values.
    """
    if isinstance(env_or_task, str):
        task, params = env_or_task, None
    else:
        task, params = env_or_task.name, env_or_task.params
        action_space = action_space or env_or_task.action_space_name
    action_space = action_space or "prt"
    if task not in SCRIPTED_POLICIES:
        raise ValueError(f"no scripted policy for task {task!r}; allowed: {sorted(SCRIPTED_POLICIES)}")
    if action_space not in ("prt", "ctbr"):
        raise ValueError(f"scripted policies support action spaces ['prt', 'ctbr'], got {action_space!r}")
    return SCRIPTED_POLICIES[task](action_space, params, **kwargs)
