"""Single-drone tasks: Hover, Back and Forth, Hit the Ball, Solo Bump (paper appendix C; docs/physics.md).

Relative vectors are "drone minus target" here. Coefficients are the reference implementation's.
"""

from __future__ import annotations

import math

import torch

from volleybots.physics.math import euler_to_quat, quat_axes
from volleybots.physics.torch_backend import masked_select
from volleybots.rules import COURTS, RefereeConfig
from volleybots.tasks.base import PARKED_BALL, StepResult, VolleyEnv

ANCHOR = (4.5, 0.0, 2.0)
MISBEHAVE = -10.0


def _col(x: torch.Tensor) -> torch.Tensor:
    """[N] -> [N, 1] (one agent)."""
    return x.unsqueeze(-1)


class Hover(VolleyEnv):
    """Fly to a target given in the observation and hold it (the drills' Hover, 3 vs 3 court)."""

    name = "hover"
    episode_len = 500
    obs_parts = (("root", 23), ("target", 3))  # target: drone minus target
    reward_terms = ("pose", "up", "spin", "crash")
    shaping_terms = ("up", "spin")
    metric = "distance"  # mean distance to the target over the episode, m (lower is better)
    metric_higher_is_better = False

    max_distance = 8.0  # m from the target; farther than any start, so only flying away ends an episode

    def __init__(self, *args, target=None, **kw):
        self.fixed_target = target
        super().__init__(*args, **kw)
        self.target = torch.zeros(self.num_envs, 3, device=self.device)

    def referee_config(self):
        return RefereeConfig(court=COURTS["3v3"], drone_min_z=0.2)

    def reset_task(self, mask):
        n = self.num_envs
        self.place_drones(mask, self.uniform((-2.5, -2.5, 1.0), (2.5, 2.5, 2.5), (n, 1)))
        if self.fixed_target is None:
            target = self.uniform((-2.5, -2.5, 1.5), (2.5, 2.5, 2.5), (n,))
        else:
            target = torch.as_tensor(self.fixed_target, device=self.device, dtype=torch.float32).expand(n, 3)
        self.target = masked_select(mask, target, self.target)
        self.place_ball(mask, PARKED_BALL)
        self.referee.reset(mask, self.physics.state.ball_pos)

    def observe(self):
        return self.layout.build(root=self.root_state(), target=self.physics.state.pos - self.target.unsqueeze(1))

    def evaluate(self, ev):
        s = self.physics.state
        d = (s.pos[:, 0] - self.target).norm(dim=-1)
        _, up = quat_axes(s.quat[:, 0])
        pose = 1.0 / (1.0 + (1.2 * d) ** 2)
        upright = ((up[:, 2] + 1) / 2) ** 2
        spin = 1.0 / (1.0 + s.omega[:, 0, 2] ** 2)
        # start and target are drawn independently (up to 7.2 m apart): only flying away ends it
        crash = (s.pos[:, 0, 2] < 0.2) | (d > self.max_distance)
        mean_d = (self._stats["distance"] * self.t.sub(1).clamp_min(0) + d) / self.t.clamp_min(1)
        return StepResult(
            terms={"pose": _col(pose), "up": _col(pose * upright), "spin": _col(pose * spin), "crash": _col(crash * MISBEHAVE)},
            terminated=crash,
            stats={"distance": mean_d},
        )


class BackAndForth(VolleyEnv):
    name = "back_and_forth"
    obs_parts = (("root", 23), ("target", 3))  # target: drone minus the current target
    reward_terms = ("target_stay", "dist_to_target", "target_reached", "misbehave")
    metric = "targets"  # targets reached (5 consecutive steps within 0.6 m)

    def __init__(self, *args, stay_reward: float = 2.5, target_reward: float = 0.0, **kw):
        """``stay_reward`` per step inside the sphere is the reference's; it pays a drone that dithers at a
        target's edge more than one that completes stays and flies on (docs/results/imitation.md), so
        ``target_reward``, paid per target reached (0 in the reference), can align the return with the metric."""
        self.stay_reward, self.target_reward = stay_reward, target_reward
        super().__init__(*args, **kw)
        self.anchors = torch.tensor((ANCHOR, (9.0, 4.5, 2.0)), device=self.device)
        self.target_idx = torch.ones(self.num_envs, dtype=torch.long, device=self.device)
        self.inside = torch.zeros(self.num_envs, dtype=torch.long, device=self.device)
        self.reached = torch.zeros(self.num_envs, device=self.device)

    def referee_config(self):
        return RefereeConfig(court=COURTS["full"], drone_min_z=0.4, drone_max_z=5.0)

    def reset_task(self, mask):
        n = self.num_envs
        rp = self.uniform((-0.1 * math.pi, -0.1 * math.pi, -math.pi), (0.1 * math.pi, 0.1 * math.pi, math.pi), (n, 1))
        quat = euler_to_quat(rp[..., 0], rp[..., 1], rp[..., 2])
        self.place_drones(mask, self.anchors[0].expand(n, 1, 3), quat)
        self.place_ball(mask, PARKED_BALL)
        self.target_idx = torch.where(mask, 1, self.target_idx)
        self.inside = torch.where(mask, 0, self.inside)
        self.reached = torch.where(mask, 0.0, self.reached)
        self.referee.reset(mask, self.physics.state.ball_pos)

    @property
    def target(self):
        return self.anchors[self.target_idx]

    def observe(self):
        return self.layout.build(root=self.root_state(), target=self.physics.state.pos - self.target.unsqueeze(1))

    def evaluate(self, ev):
        s = self.physics.state
        d = (s.pos[:, 0] - self.target).norm(dim=-1)
        within = d < 0.6
        self.inside = torch.where(within, self.inside + 1, torch.zeros_like(self.inside))
        stay = within.float() * self.stay_reward
        dist = 0.5 / (1 + d * d) * 0.02 * (50 - self.reached).clamp_min(0)
        done_stay = self.inside >= 5
        self.reached = self.reached + done_stay.float()
        self.target_idx = torch.where(done_stay, 1 - self.target_idx, self.target_idx)
        self.inside = torch.where(done_stay, torch.zeros_like(self.inside), self.inside)
        bad = ev.drone_low[:, 0] | ev.drone_high[:, 0] | (d > 7.5)
        return StepResult(
            terms={"target_stay": _col(stay), "dist_to_target": _col(dist), "target_reached": _col(done_stay * self.target_reward),
                   "misbehave": _col(bad * MISBEHAVE)},
            terminated=bad,
            stats={"targets": self.reached},
        )


class _BallDrill(VolleyEnv):
    """Shared by Hit the Ball and Solo Bump: reset around the anchor, ball at rest above it, and the
    observation root, drone minus anchor, drone minus ball, ball velocity (32 / 28)."""

    # anchor: drone minus anchor; ball: drone minus ball; ball_vel: the ball's velocity
    obs_parts = (("root", 23), ("anchor", 3), ("ball", 3), ("ball_vel", 3))
    ball_start = (4.5, 0.0, 4.0)

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self.anchor = torch.tensor(ANCHOR, device=self.device)

    def reset_task(self, mask):
        self.place_drones(mask, self.drone_start())
        self.place_ball(mask, self.ball_start)
        self.referee.reset(mask, self.physics.state.ball_pos)
        self.reset_drill(mask)

    def drone_start(self) -> torch.Tensor:
        """Start positions [N, 1, 3]: uniform in a 1 m x 1 m x 0.4 m box centred under the ball."""
        return self.uniform((4.0, -0.5, 1.8), (5.0, 0.5, 2.2), (self.num_envs, 1))

    def reset_drill(self, mask):
        pass

    def observe(self):
        s = self.physics.state
        return self.layout.build(
            root=self.root_state(), anchor=s.pos - self.anchor, ball=s.pos - s.ball_pos.unsqueeze(1), ball_vel=s.ball_vel.unsqueeze(1)
        )


class HitTheBall(_BallDrill):
    name = "hit_the_ball"
    ball_start = (4.5, 0.0, 5.0)
    reward_terms = ("hit", "anchor", "distance", "misbehave")
    shaping_terms = ("anchor",)
    metric = "distance"  # 4.5 - x where the ball comes down through z = 2 after one hit, m

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self.prev_ball = torch.zeros(self.num_envs, 3, device=self.device)
        self.distance = torch.zeros(self.num_envs, device=self.device)

    def referee_config(self):
        # exactly one hit: drone 0 may hit once, after that any touch is on the wrong turn
        return RefereeConfig(court=COURTS["full"], turns="sequence", order=(0,), drone_min_z=0.4, ball_low_z=0.15)

    def reset_drill(self, mask):
        self.prev_ball = masked_select(mask, self.physics.state.ball_pos, self.prev_ball)
        self.distance = torch.where(mask, 0.0, self.distance)

    def evaluate(self, ev):
        s = self.physics.state
        z0, z1 = self.prev_ball[:, 2], s.ball_pos[:, 2]
        one_hit = self.referee.hits.sum(1) == 1
        down = one_hit & (z0 >= 2.0) & (z1 < 2.0) & (s.ball_vel[:, 2] < 0)
        frac = ((z0 - 2.0) / (z0 - z1).clamp_min(1e-9)).unsqueeze(-1)
        cross_x = (self.prev_ball + (s.ball_pos - self.prev_ball) * frac)[:, 0]
        dist = torch.where(down, self.anchor[0] - cross_x, torch.zeros_like(cross_x))
        self.distance = torch.where(down, dist, self.distance)
        self.prev_ball = s.ball_pos.clone()
        far = (s.pos[:, 0] - self.anchor).norm(dim=-1) > 1.0
        bad = ev.ball_landed | ev.ball_net | ev.drone_low[:, 0] | ev.drone_net[:, 0] | ev.wrong_hit[:, 0]
        bad = bad & ~down
        return StepResult(
            terms={
                "hit": _col(ev.racket_hit[:, 0].float()),
                "anchor": _col(far * -0.05),
                "distance": _col(2.0 * dist),
                "misbehave": _col(bad * MISBEHAVE),
            },
            terminated=down | bad,
            stats={"distance": self.distance},
        )


class SoloBump(_BallDrill):
    name = "solo_bump"
    ball_start = (4.5, 0.0, 4.0)
    reward_terms = ("success_hit", "success_height", "dist_to_ball", "ball_height", "misbehave")
    shaping_terms = ("dist_to_ball", "ball_height")
    metric = "bumps"  # longest streak of bumps with apex in [3.5, 4.5] m, hit within 1 m of the anchor
    extra_stats = ("hits",)

    far_start = 0.5  # m from the ball's column: the scripted player misses first balls from starts this far (docs/results/imitation.md)

    def __init__(
        self, *args, hit_reward: float = 2.0, height_reward: float = 8.0, strict_bumps: bool = False, far_starts: float = 0.0, **kw
    ):
        """``strict_bumps`` pays ``height_reward`` only for the bumps the metric counts (struck within
        1 m of the anchor, apex in [3.5, 4.5] m); the paper's reward (False) pays every apex of 3.5 m or
        more, so a policy can earn it while drifting off the anchor, where the metric's streak restarts.
        ``far_starts`` is the probability that an episode's start is drawn (uniformly) from the part
        of the start box at least ``far_start`` from the ball's column rather than from all of it: a
        training curriculum for the hardest openings, which the paper's box (``far_starts=0``) gives
        one episode in five."""
        self.hit_reward = hit_reward
        self.height_reward = height_reward
        self.strict_bumps = strict_bumps
        self.far_starts = far_starts
        super().__init__(*args, **kw)
        n = self.num_envs
        self.pending = torch.zeros(n, dtype=torch.bool, device=self.device)  # a hit whose apex is still to come
        self.hit_ok = torch.zeros(n, dtype=torch.bool, device=self.device)  # that hit was within 1 m of the anchor
        self.apex = torch.zeros(n, device=self.device)
        self.streak = torch.zeros(n, device=self.device)
        self.best = torch.zeros(n, device=self.device)

    def referee_config(self):
        return RefereeConfig(court=COURTS["full"], min_hit_gap=25, drone_min_z=0.4, drone_max_z=2.5, ball_low_z=0.15)

    def drone_start(self) -> torch.Tensor:
        """The box's starts; with probability ``far_starts`` one from its part far from the ball instead."""
        start = super().drone_start()
        if self.far_starts <= 0:  # the paper's box, from the same random numbers as ever
            return start
        n = self.num_envs
        far = self.uniform(0.0, 1.0, (n,)) < self.far_starts
        # uniform over the box outside the disc, by rejection; when all 32 tries fall inside it (4e-4 of
        # the far episodes) the first is pushed out to the disc's edge, which lies inside the box
        tries = self.uniform((-0.5, -0.5), (0.5, 0.5), (n, 32))
        r = tries.norm(dim=-1, keepdim=True)
        ok = r[..., 0] >= self.far_start
        pick = torch.gather(tries, 1, ok.float().argmax(1)[:, None, None].expand(n, 1, 2))[:, 0]  # the first that lies out
        edge = tries[:, 0] * (self.far_start / r[:, 0].clamp_min(1e-6))
        off = torch.where(ok.any(1, keepdim=True), pick, edge)
        xy = (torch.as_tensor(self.ball_start[:2], device=self.device) + off).unsqueeze(1)
        return torch.cat((torch.where(far[:, None, None], xy, start[..., :2]), start[..., 2:]), -1)

    def reset_drill(self, mask):
        self.apex, self.streak, self.best = (torch.where(mask, 0.0, buf) for buf in (self.apex, self.streak, self.best))
        self.pending = self.pending & ~mask
        self.hit_ok = self.hit_ok & ~mask

    def evaluate(self, ev):
        s = self.physics.state
        hit = ev.racket_hit[:, 0] & ~ev.wrong_hit[:, 0]
        bz = s.ball_pos[:, 2]
        # an unfinished bump interrupted by a new hit never reached its apex: it failed
        self.streak = torch.where(hit & self.pending, torch.zeros_like(self.streak), self.streak)
        near = (s.pos[:, 0] - self.anchor).norm(dim=-1) <= 1.0
        self.hit_ok = torch.where(hit, near, self.hit_ok)
        self.apex = torch.where(hit, bz, torch.maximum(self.apex, bz))
        at_apex = self.pending & ~hit & (s.ball_vel[:, 2] <= 0)
        success = at_apex & (self.apex >= 3.5) & (self.apex <= 4.5) & self.hit_ok
        self.streak = torch.where(at_apex, torch.where(success, self.streak + 1, torch.zeros_like(self.streak)), self.streak)
        self.best = torch.maximum(self.best, self.streak)
        self.pending = (self.pending & ~at_apex) | hit
        horiz = (s.pos[:, 0, :2] - s.ball_pos[:, :2]).norm(dim=-1)
        height = (bz - s.pos[:, 0, 2].clamp_min(1.0)).clamp(0.0, 2.0)
        d = ev
        bad = (
            d.drone_low[:, 0] | d.drone_high[:, 0] | d.ball_landed | (bz > 4.5) | d.ball_out | d.wrong_hit[:, 0]
        )
        return StepResult(
            terms={
                "success_hit": _col(hit * self.hit_reward),
                "success_height": _col((success if self.strict_bumps else at_apex & (self.apex >= 3.5)) * self.height_reward),
                "dist_to_ball": _col(1.0 / (1.0 + horiz)),
                "ball_height": _col(0.5 * height),
                "misbehave": _col(bad * MISBEHAVE),
            },
            terminated=bad,
            stats={"bumps": self.best, "hits": self.referee.hits[:, 0].float()},
        )
