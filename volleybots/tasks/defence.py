"""The defence racket of Set and Spike (Hard) (paper appendix A.3; docs/tasks.md).

A thin disk (radius 0.5 m) held by an imaginary defender on the -x half. It is kinematic: it does not
take part in the physics step; after each control step the task calls ``DefenceRacket.step`` with the
ball's state, which plans, moves the racket and, if the ball reached the racket's face during the step,
returns the ball's new state (the task writes it with ``physics.set_state``). Its touches are not
drone hits: the referee never sees them.

Plan (A.3). When the spike heads down into the racket's half (vx < -2, vz < 0, z >= 1.2), the ballistic
crossing of the interception height ``h_pre`` gives the descent time ``t_pre``, the crossing point
``p_land`` and the pre-collision velocity ``v_pre``. The post-collision velocity ``v_post`` is the one
that carries the ball from ``p_land`` to the return target in ``t_post``. The racket must then meet the
ball at ``p_land`` with normal ``n = (v_post - v_pre) / |v_post - v_pre|`` (roll ``-asin n_y``, pitch
``atan2(n_x, n_z)``, yaw 0) and velocity ``v_c = (beta v_pre + v_post) / (1 + beta)``: with restitution
beta along ``n`` that turns ``v_pre`` into exactly ``v_post``. It moves toward that pose each step at the
rate that would arrive just in time, limited to ``max_speed`` (m/s) and ``max_rot`` (rad/s per angle);
a ball it cannot reach in time gets through.

**Decisions.** Only the disk's upper face collides (the spike comes from above); ``t_post`` is 1.2 s so
that the return clears the net; after a touch, or when the ball is not coming, the racket flies home at
its speed limits and levels out.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from volleybots.physics.math import euler_to_quat


@dataclass(frozen=True)
class DefenceParams:
    home: tuple[float, float, float] = (-4.0, 0.0, 0.5)
    radius: float = 0.5
    restitution: float = 0.77
    max_speed: float = 8.0
    max_rot: float = 4.0
    intercept_z: float = 1.1  # h_pre
    trigger_z: float = 1.2  # the ball must still be at least this high when the plan is made
    trigger_vx: float = -2.0  # ... and moving toward -x faster than this
    return_target: tuple[float, float, float] = (3.0, 1.0, 1.3)  # p_b,des
    t_post: float = 1.2
    half_length: float = 9.0  # the racket only plans for crossings over its own half
    half_width: float = 4.5


def ballistic_crossing(pos: torch.Tensor, vel: torch.Tensor, z: float, g: float):
    """Time, point and velocity where a ballistic ball [M, 3] next comes down through height ``z``.
    Time is NaN-free: negative where the ball never gets there."""
    disc = vel[:, 2] ** 2 + 2.0 * g * (pos[:, 2] - z)
    t = (vel[:, 2] + disc.clamp_min(0.0).sqrt()) / g
    t = torch.where(disc >= 0, t, torch.full_like(t, -1.0))
    tt = t.clamp_min(0.0).unsqueeze(-1)
    gvec = torch.tensor((0.0, 0.0, -g), device=pos.device, dtype=pos.dtype)
    return t, pos + vel * tt + 0.5 * gvec * tt * tt, vel + gvec * tt


def racket_angles(normal: torch.Tensor) -> torch.Tensor:
    """(roll, pitch) of a racket with yaw 0 whose face normal is ``normal`` (A.3: n = (sin p cos r,
    -sin r, cos p cos r))."""
    roll = -torch.asin(normal[..., 1].clamp(-1.0, 1.0))
    pitch = torch.atan2(normal[..., 0], normal[..., 2])
    return torch.stack((roll, pitch), -1)


def racket_normal(angles: torch.Tensor) -> torch.Tensor:
    r, p = angles.unbind(-1)
    return torch.stack((torch.sin(p) * torch.cos(r), -torch.sin(r), torch.cos(p) * torch.cos(r)), -1)


class DefenceRacket:
    """Batched kinematic defence racket, one per env."""

    def __init__(self, num_envs: int, device, dt: float, ball_radius: float, gravity: float = 9.81, params: DefenceParams | None = None):
        self.p = params or DefenceParams()
        self.num_envs = num_envs
        self.device = torch.device(device)
        self.dt = dt
        self.ball_r = ball_radius
        self.g = gravity
        n = num_envs
        z = lambda *s: torch.zeros(*s, device=self.device)  # noqa: E731
        self.home = torch.tensor(self.p.home, device=self.device)
        self.target = torch.tensor(self.p.return_target, device=self.device)
        self.pos = self.home.expand(n, 3).clone()  # centre of the upper face
        self.angles = z(n, 2)  # roll, pitch
        self.vel = z(n, 3)  # velocity of the last step's motion
        self.planned = torch.zeros(n, dtype=torch.bool, device=self.device)
        self.touched = torch.zeros(n, dtype=torch.bool, device=self.device)  # touched the ball this episode
        self.goal_pos = z(n, 3)
        self.goal_angles = z(n, 2)
        self.strike_vel = z(n, 3)
        self.t_left = z(n)
        self.v_post = z(n, 3)  # the return velocity it planned (for tests and replays)

    def reset(self, mask: torch.Tensor) -> None:
        """Home, level and idle in the envs of ``mask`` (masked selects: static shapes)."""
        m = mask.unsqueeze(-1)
        self.pos = torch.where(m, self.home, self.pos)
        self.angles = torch.where(m, 0.0, self.angles)
        self.vel = torch.where(m, 0.0, self.vel)
        self.planned = self.planned & ~mask
        self.touched = self.touched & ~mask
        self.t_left = torch.where(mask, 0.0, self.t_left)

    @property
    def normal(self) -> torch.Tensor:
        return racket_normal(self.angles)

    @property
    def quat(self) -> torch.Tensor:
        """[N, 4] orientation (w, x, y, z) for visualisation."""
        return euler_to_quat(self.angles[:, 0], self.angles[:, 1], torch.zeros_like(self.angles[:, 0]))

    def _plan(self, ball_pos, ball_vel, armed) -> None:
        p = self.p
        go = (
            armed & ~self.planned & ~self.touched
            & (ball_vel[:, 0] < p.trigger_vx) & (ball_vel[:, 2] < 0) & (ball_pos[:, 2] >= p.trigger_z)
        )
        t, p_land, v_pre = ballistic_crossing(ball_pos, ball_vel, p.intercept_z, self.g)
        go = go & (t > 0) & (p_land[:, 0] <= 0) & (p_land[:, 0] >= -p.half_length) & (p_land[:, 1].abs() <= p.half_width)
        tp = p.t_post
        gvec = torch.tensor((0.0, 0.0, -self.g), device=self.device)
        v_post = (self.target - p_land) / tp - 0.5 * gvec * tp
        dv = v_post - v_pre
        n = dv / dv.norm(dim=-1, keepdim=True).clamp_min(1e-9)
        beta = p.restitution
        g = go.unsqueeze(-1)
        self.goal_pos = torch.where(g, p_land - self.ball_r * n, self.goal_pos)
        self.goal_angles = torch.where(g, racket_angles(n), self.goal_angles)
        self.strike_vel = torch.where(g, (beta * v_pre + v_post) / (1 + beta), self.strike_vel)
        self.v_post = torch.where(g, v_post, self.v_post)
        self.t_left = torch.where(go, t, self.t_left)
        self.planned = self.planned | go

    def _move(self) -> None:
        p, dt = self.p, self.dt
        active = self.planned & ~self.touched
        goal_pos = torch.where(active.unsqueeze(-1), self.goal_pos, self.home)
        goal_ang = torch.where(active.unsqueeze(-1), self.goal_angles, torch.zeros_like(self.angles))
        # the rate that arrives just in time (home: as fast as allowed), capped by the limits
        horizon = torch.where(active, self.t_left.clamp_min(dt), torch.full_like(self.t_left, dt)).unsqueeze(-1)
        step = (goal_pos - self.pos) / horizon * dt
        norm = step.norm(dim=-1, keepdim=True)
        step = step * (p.max_speed * dt / norm.clamp_min(1e-9)).clamp(max=1.0)
        rot = ((goal_ang - self.angles) / horizon * dt).clamp(-p.max_rot * dt, p.max_rot * dt)
        self.pos = self.pos + step
        self.angles = self.angles + rot
        self.vel = step / dt
        self.t_left = (self.t_left - dt).clamp_min(0.0)

    def step(self, prev_ball: torch.Tensor, ball_pos: torch.Tensor, ball_vel: torch.Tensor, armed: torch.Tensor):
        """One control step. ``prev_ball`` / ``ball_pos`` are the ball centre before and after the
        physics step, ``ball_vel`` its velocity after; ``armed`` [N] says a spike may be defended.

        Returns (touch [N] bool, new ball position, new ball velocity); untouched envs keep theirs."""
        self._plan(ball_pos, ball_vel, armed)
        pos0, n0 = self.pos.clone(), self.normal
        self._move()
        pos1, n1 = self.pos, self.normal
        # swept test of the ball centre against the face (offset by the ball radius), as for the drones
        h0 = ((prev_ball - pos0) * n0).sum(-1)
        h1 = ((ball_pos - pos1) * n1).sum(-1)
        r = self.ball_r
        frac = ((h0 - r) / (h0 - h1).clamp_min(1e-9)).clamp(0.0, 1.0).unsqueeze(-1)
        centre = prev_ball + (ball_pos - prev_ball) * frac
        face = pos0 + (pos1 - pos0) * frac
        rel = centre - face
        radial = (rel - (rel * n1).sum(-1, keepdim=True) * n1).norm(dim=-1)
        racket_vel = torch.where((self.planned & ~self.touched).unsqueeze(-1), self.strike_vel, self.vel)
        vn = ((ball_vel - racket_vel) * n1).sum(-1)
        touch = (h0 >= 0.5 * r) & (h1 < r) & (radial <= self.p.radius) & (vn < 0) & ~self.touched
        new_vel = ball_vel - ((1 + self.p.restitution) * vn).unsqueeze(-1) * n1
        new_pos = centre + ((r - (rel * n1).sum(-1)).clamp_min(0.0)).unsqueeze(-1) * n1
        t = touch.unsqueeze(-1)
        self.touched = self.touched | touch
        return touch, torch.where(t, new_pos, ball_pos), torch.where(t, new_vel, ball_vel)
