"""The receive drill: return a serve in 1 vs 1 (docs/receive.md).

One drone of team 0 on the 1 vs 1 court (6 x 3, its half x > 0, the net at x = 0), at its match
anchor (1.5, 0, 2) +- 0.1 m, level, at rest. The ball starts as a serve leaves the server's racket:
from around the server's anchor (x in [-1.6, -1.4], y in [-0.3, 0.3], z in [2.3, 2.8]) it flies over
the net to land in the drone's half (x in [0.6, 2.9], y in [-1.3, 1.3]). A share ``deep`` of the
serves are deep and flat (apex 2.7-3.1 m, landing beyond x = 1.9: the kind of serve no learned 1v1
policy has returned, docs/evaluation.md), the rest lobs (apex 3.1-3.9 m). Serves that would not
clear the net by 0.15 m are drawn again (up to 4 candidates, then a lob to the middle of the half).

With ``opening`` the episode starts as the match's does for the receiver: the ball at rest 1 m above
the serve's start and the drone's turn flag off; where the ball has fallen to that start, a virtual
server serves it (its velocity set to the serve's) and the turn flag comes on. A policy trained
without it never sees the wait before the serve, and in the match it falls out of the sky there.

Done when: the drone's touch sends the ball back over the net (success, the metric "serve
returned"), or on a misbehaviour (-10, ends the episode): the ball lands or leaves the court, a body
hit or a second touch, the ball into the net, the drone below 0.3 m, at or across the net.

Observation: the 1 vs 1 match's, part for part (``OneVsOne.obs_parts``), as team 0 sees it, with the
opponent standing at its anchor (-1.5, 0, 2) and the turn flag "I may hit"; so a 1 vs 1 policy plays
the drill as it is (``init=zoo:1v1/...``) and a policy trained on the drill plays the match.

Rewards: ``hit`` +5 for the drill's touch, ``success`` +10, ``misbehave`` -10, and the shaping
``under`` until the touch: ``under_reward`` x under x upright x height each step, where

- under = exp(-(d / 0.3 m)^2), d the horizontal distance from the drone to where the ball comes down
  through the drone's racket height (0 where it never comes down to that height);
- upright = the racket normal's (body z axis's) vertical component, clipped at 0;
- height = 1 while the drone's centre is in [``LOW_Z``, ``HIGH_Z``], the heights at which a
  drone can still return the ball over the net, falling as exp(-(metres outside) / 0.3) beyond.

So the drone is paid for flying to where the ball will come down at its own height and waiting
there racket up, which is what a receive takes before anything touches (the match pays nothing until
then). Statistics: ``success`` (the metric, 0/1), ``hits``, ``deep_serve`` (1 for a deep serve).
"""

from __future__ import annotations

import torch

from volleybots.physics.math import quat_axes
from volleybots.rules import COURTS, RefereeConfig
from volleybots.tasks.base import StepResult, VolleyEnv
from volleybots.tasks.match import OneVsOne
from volleybots.tasks.multi import flag_pair, mirror_root, one_hot

ANCHOR = OneVsOne.anchors_xyz[0]  # the receiver's, (1.5, 0, 2)
SERVER = OneVsOne.anchors_xyz[1]  # the opponent's, (-1.5, 0, 2)
LOW_Z, HIGH_Z = 1.1, 2.8  # m: the drone heights paid for as contact heights
UNDER_SCALE = 0.3  # m: the under term's width
HEIGHT_SCALE = 0.3  # m: the height term's fall-off outside [LOW_Z, HIGH_Z]
NET_CLEAR = 0.15  # m: a serve's ball centre passes the net this much above its top at least
DRAWS = 4  # candidate serves drawn per reset
FALLBACK = (1.75, 0.0, 3.9)  # a lob landing here over this apex, where no candidate clears the net
OPENING_DROP = 1.0  # m: with ``opening`` the ball starts at rest this far above the serve's start
MISBEHAVE = -10.0
HIT_REWARD = 5.0
SUCCESS_REWARD = 10.0
UNDER_REWARD = 0.1


def serve_velocity(start: torch.Tensor, land_xy: torch.Tensor, apex: torch.Tensor, land_z: float, g: float) -> torch.Tensor:
    """[N, 3] the launch velocity from ``start`` [N, 3] over an apex at ``apex`` [N] down through ``land_z`` at ``land_xy`` [N, 2]."""
    vz = torch.sqrt(2.0 * g * (apex - start[:, 2]).clamp_min(0.0))
    t = (vz + torch.sqrt(2.0 * g * (apex - land_z))) / g
    return torch.cat(((land_xy - start[:, :2]) / t.unsqueeze(-1), vz.unsqueeze(-1)), -1)


def height_at_net(start: torch.Tensor, vel: torch.Tensor, g: float) -> torch.Tensor:
    """[N] the ball centre's height where its flight from ``start`` with ``vel`` crosses x = 0."""
    t = -start[:, 0] / vel[:, 0].clamp_min(1e-6)
    return start[:, 2] + vel[:, 2] * t - 0.5 * g * t * t


def under_terms(drone_pos: torch.Tensor, up: torch.Tensor, ball_pos: torch.Tensor, ball_vel: torch.Tensor, reach: float,
                g: float) -> torch.Tensor:
    """[N] under x upright x height (module docstring) for drones at ``drone_pos`` [N, 3] with body z
    axis ``up`` [N, 3] and the ball at ``ball_pos`` / ``ball_vel`` [N, 3]."""
    z = drone_pos[:, 2] + reach  # the ball centre's height at a contact on this racket
    disc = ball_vel[:, 2] ** 2 + 2.0 * g * (ball_pos[:, 2] - z)
    t = (ball_vel[:, 2] + torch.sqrt(disc.clamp_min(0.0))) / g
    fall = ball_pos[:, :2] + ball_vel[:, :2] * t.clamp_min(0.0).unsqueeze(-1)
    d = (fall - drone_pos[:, :2]).norm(dim=-1)
    under = torch.where(disc >= 0.0, torch.exp(-(d / UNDER_SCALE) ** 2), torch.zeros_like(d))
    upright = up[:, 2].clamp_min(0.0)
    outside = (LOW_Z - drone_pos[:, 2]).clamp_min(0.0) + (drone_pos[:, 2] - HIGH_Z).clamp_min(0.0)
    return under * upright * torch.exp(-outside / HEIGHT_SCALE)


class Receive(VolleyEnv):
    name = "receive"
    n_drones = 1
    teams = (0,)
    episode_len = 200  # control steps (4 s): every serve is down within 1.6 s
    obs_parts = OneVsOne.obs_parts
    reward_terms = ("hit", "success", "under", "misbehave")
    shaping_terms = ("under",)
    metric = "success"
    extra_stats = ("hits", "deep_serve")
    init_noise = 0.1
    policy_task = OneVsOne.name  # its policies are 1 vs 1 players, and 1 vs 1 players play it (tasks.plays_as)

    def __init__(self, *args, deep: float = 0.5, under_reward: float | None = None, opening: bool = False, **kw):
        """``deep``: the share of deep, flat serves (the rest are lobs); ``under_reward``: the shaping
        coefficient (None: ``UNDER_REWARD``); ``opening``: start as the match does (module docstring)."""
        if not 0.0 <= float(deep) <= 1.0:
            raise ValueError(f"deep must be a share in [0, 1]; got {deep!r}")
        self.deep = float(deep)
        self.opening = bool(opening)
        self.under_reward = UNDER_REWARD if under_reward is None else float(under_reward)
        super().__init__(*args, **kw)
        n, dev = self.num_envs, self.device
        self.anchor = torch.tensor(ANCHOR, device=dev)
        self.server = torch.tensor(SERVER, device=dev)
        self.touched = torch.zeros(n, dtype=torch.bool, device=dev)
        self.success = torch.zeros(n, device=dev)
        self.deep_serve = torch.zeros(n, device=dev)
        self.served = torch.ones(n, dtype=torch.bool, device=dev)
        self.serve_at = torch.zeros(n, 3, device=dev)  # the serve's start (the virtual server's touch)
        self.serve_to = torch.zeros(n, 3, device=dev)  # where it lands (x, y) and its apex
        self._no_flip = torch.zeros(1, dtype=torch.bool, device=dev)

    def referee_config(self):
        return RefereeConfig(court=COURTS[OneVsOne.court], turns="possession", drone_min_z=0.3, out_at_any_height=True)

    # ------------------------------------------------------------------ reset
    def draw_serves(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """[N, 3] ball positions and velocities, [N] deep flags and [N, 3] aims (landing x, y and
        apex) of serves that clear the net: the
        first of ``DRAWS`` candidates per env that does (a reset draws the same count of numbers
        every time), else a lob to the middle of the half."""
        n, g = self.num_envs, self.params.gravity
        land_z = self.params.ball.radius
        pos = vel = deep = aim = None
        ok = torch.zeros(n, dtype=torch.bool, device=self.device)
        for _ in range(DRAWS):
            p = self.uniform((SERVER[0] - 0.1, -0.3, 2.3), (SERVER[0] + 0.1, 0.3, 2.8), (n,))
            d = self.uniform(0.0, 1.0, (n,)) < self.deep
            lob = self.uniform((0.6, -1.3, 3.1), (2.9, 1.3, 3.9), (n,))
            flat = self.uniform((1.9, -1.3, 2.7), (2.9, 1.3, 3.1), (n,))
            target = torch.where(d.unsqueeze(-1), flat, lob)
            target = torch.cat((target[:, :2], torch.maximum(target[:, 2], p[:, 2] + 0.05).unsqueeze(-1)), -1)
            v = serve_velocity(p, target[:, :2], target[:, 2], land_z, g)
            good = height_at_net(p, v, g) >= COURTS[OneVsOne.court].net_height + NET_CLEAR
            take = good & ~ok
            if pos is None:
                pos, vel, deep, aim = p, v, d, target
            aim = torch.where(take.unsqueeze(-1), target, aim)
            pos = torch.where(take.unsqueeze(-1), p, pos)
            vel = torch.where(take.unsqueeze(-1), v, vel)
            deep = torch.where(take, d, deep)
            ok = ok | good
        fallback = torch.tensor(FALLBACK, device=self.device).expand(n, 3)
        lob = serve_velocity(pos, fallback[:, :2], fallback[:, 2], land_z, g)
        return pos, torch.where(ok.unsqueeze(-1), vel, lob), deep & ok, torch.where(ok.unsqueeze(-1), aim, fallback)

    def reset_task(self, mask):
        n = self.num_envs
        noise = (self.init_noise,) * 3
        self.place_drones(mask, self.anchor + self.uniform(tuple(-x for x in noise), noise, (n, 1)))
        pos, vel, deep, aim = self.draw_serves()
        if self.opening:  # the ball at rest above the virtual server, the serve still to come, the drone's turn flag off
            self.place_ball(mask, pos + torch.tensor((0.0, 0.0, OPENING_DROP), device=self.device), torch.zeros_like(vel))
        else:
            self.place_ball(mask, pos, vel)
        self.referee.reset(mask, self.physics.state.ball_pos)
        if self.opening:
            self.referee.may_hit = self.referee.may_hit & ~mask.unsqueeze(1)
        self.served = torch.where(mask, not self.opening, self.served)
        self.serve_at = torch.where(mask.unsqueeze(-1), pos, self.serve_at)
        self.serve_to = torch.where(mask.unsqueeze(-1), aim, self.serve_to)
        self.touched = self.touched & ~mask
        self.success = torch.where(mask, 0.0, self.success)
        self.deep_serve = torch.where(mask, deep.float(), self.deep_serve)

    # ------------------------------------------------------------------ observation
    def observe(self):
        s = self.physics.state
        n = self.num_envs
        return self.layout.build(
            root=mirror_root(self.root_state(), self._no_flip),
            anchor=s.pos - self.anchor,
            ball=s.pos - s.ball_pos.unsqueeze(1),
            ball_vel=s.ball_vel.unsqueeze(1),
            other=self.server - s.pos,
            turn=flag_pair(self.referee.may_hit),
            id=one_hot(torch.zeros(n, 1, dtype=torch.long, device=self.device), 2),
        )

    # ------------------------------------------------------------------ rewards
    def serve(self) -> None:
        """With ``opening``: the virtual server's touch, where the dropped ball comes down to the serve's
        start height: the ball leaves for the drawn aim, and the drone may hit (as the match's receiver)."""
        s = self.physics.state
        now = ~self.served & (s.ball_pos[:, 2] <= self.serve_at[:, 2])
        vel = serve_velocity(s.ball_pos, self.serve_to[:, :2], self.serve_to[:, 2], self.params.ball.radius, self.params.gravity)
        self.physics.set_state(now, ball_vel=vel)
        self.referee.may_hit = self.referee.may_hit | now.unsqueeze(1)
        self.served = self.served | now

    def evaluate(self, ev):
        if self.opening:
            self.serve()
        s = self.physics.state
        legal = ev.racket_hit[:, 0] & ~ev.wrong_hit[:, 0]
        before = ~self.touched
        first = legal & before
        self.touched = self.touched | legal
        done = self.touched & ev.ball_crossed & (s.ball_pos[:, 0] < 0)
        bad = (ev.drone_low[:, 0] | ev.drone_net[:, 0] | ev.drone_cross[:, 0] | ev.wrong_hit[:, 0] | ev.ball_net | ev.ball_landed
               | ev.ball_out) & ~done
        self.success = torch.where(done, 1.0, self.success)
        up = quat_axes(s.quat[:, 0])[1]
        under = under_terms(s.pos[:, 0], up, s.ball_pos, s.ball_vel, self.params.ball.radius + self.params.drone.racket_offset,
                            self.params.gravity)
        return StepResult(
            terms={
                "hit": (first * HIT_REWARD).unsqueeze(-1),
                "success": (done.float() * SUCCESS_REWARD).unsqueeze(-1),
                "under": (before * self.under_reward * under).unsqueeze(-1),
                "misbehave": (bad * MISBEHAVE).unsqueeze(-1),
            },
            terminated=done | bad,
            stats={"success": self.success, "hits": self.referee.hits[:, 0].float(), "deep_serve": self.deep_serve},
        )


__all__ = ["HIGH_Z", "LOW_Z", "Receive", "height_at_net", "serve_velocity", "under_terms"]

