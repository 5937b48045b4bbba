"""Drills of the hierarchical 3 vs 3 policy: Serve, Pass, Set, Attack (paper section 5.4 and appendix E;
docs/hierarchical.md). Hover (tasks/single.py) is the fifth.

Each is one drone of team 0 on the 3 vs 3 court (12 x 6), in its own half (x > 0, the net at x = 0),
at the anchor of its role in the team, with the ball placed as it arrives there in a rally:

- ``serve``. Drone (role, anchor): back, (6, 0, 2). Ball at reset: at rest 3 m above the drone. Done
  when: the ball lands. Success: in the opponent's court (x < 0).
- ``pass``. Drone: back, (6, 0, 2). Ball at reset: sent over the net by the opponents: from x in
  [-4.5, -2] it comes down through 2.75 m in the back of the court, x in [4.5, 6.5], y in
  [-1.5, 1.5], 1.3-1.7 s later. Done when: after the touch the ball comes down through 2.75 m.
  Success: within 1 m (horizontally) of the front-left anchor (3, -1.5). A share ``serves`` of the
  balls are the 3 vs 3 scripted team's serve instead (two touches: the server tosses the ball up in
  its own court, a teammate sends it over): from where the teammate sends it, x in [-3.25, -3.05],
  y in [-1.5, 1.5], z in [2.6, 2.8], over the net high (about 4.9 m) and down through 2.75 m just
  behind it, x in [2.3, 2.7], y in [-1.6, 1.6], 1.3-1.4 s later (measured on its serves: from
  (-3.15, +-1.45, 2.7) at (4.2, 0, 6.7) m/s, down through 2.75 m at x 2.4-2.65 after 1.31-1.38 s).
- ``set``. Drone: front-left, (3, -1.5, 2). Ball at reset: passed by the back drone: from its touch
  (x in [4.5, 6.5], y in [-1, 1], 2.75 m) it comes down through 2.75 m within 0.5 m of the
  front-left anchor, 1.2-1.6 s later. Done when: as Pass. Success: within 1 m of the front-right
  anchor (3, 1.5).
- ``attack``. Drone: front-right, (3, 1.5, 2). Ball at reset: set by the front-left drone: from
  (3, -1.5, 2.75) +- 0.5 m it comes down through 2.75 m within 0.5 m of the front-right anchor,
  1.2-1.6 s later. Done when: the ball lands. Success: in the opponent's court, in the half the
  one-hot ``side`` says (left: y < 0, right: y > 0; the attacker faces -x). A share ``serves`` of the
  balls are the scripted team's serve as in ``pass`` (``SERVE_BALL``), which the front-right drone
  returns at once (the drone may touch it once it has crossed the net): a one-touch possession, the
  answer to a serve that comes down near the front drones, where a pass from the back would be late.

2.75 m is where a drone at the scripted players' contact height (2.6 m) meets the ball's centre.
Drones start at their anchor +- 0.1 m, level, at rest (as in the match).

Rules: the 3 vs 3 referee (``possession``: the drone may touch the ball once, and in Pass only once
it has crossed the net), drone too low 0.4 m. Every misbehaviour is -10 and ends the episode: drone
below 0.4 m, at or across the net, a wrong hit (body, second touch, a touch before the ball came
over), the ball into the net, and the ball landing before the drill is done (missed, or after a
serve or attack anywhere but the opponent's court).

Observation (34, 30 with CTBR; Attack 36 / 32), in the same frame and conventions as the 3 vs 3
match's (``ThreeVsThree``: "ball minus drone", quaternion with w >= 0), so that a drill's
observation is the match's parts of the same name (``volleybots.scripted.hierarchical`` builds it
from a match's): root, drone minus anchor, ball minus drone, ball velocity, may-hit flag (I may hit,
not); Attack adds ``side`` (left, right).

Rewards: ``hit`` +5 for the drill's touch (a legal racket hit), ``success`` +10, ``misbehave`` -10;
shaping ``accuracy`` up to +5 when the drill is done: 5 x max(0, 1 - error / 3 m), the error being
the distance from where the ball came down (Pass, Set) or landed (Serve, Attack) to the drill's aim
(Pass: the front-left anchor, Set: the front-right anchor, Serve: (-3, 0), the middle of the
opponent's half, Attack: (-3, -+1.5), the middle of the chosen quarter), and ``dist_to_ball``
0.05 / (1 + distance to the ball) per step until the touch.

Statistics: ``success`` (the metric, 0/1), ``hits`` (the drone's touches), ``error`` (m, as above,
where the drill was done; 0 where it was not).
"""

from __future__ import annotations

import io

import torch

from volleybots.errors import ConfigError
from volleybots.files import read_bytes
from volleybots.physics.torch_backend import masked_select
from volleybots.rules import COURTS, RefereeConfig
from volleybots.tasks.base import StepResult, VolleyEnv
from volleybots.tasks.match import ThreeVsThree
from volleybots.tasks.multi import flag_pair, mirror_root, one_hot

FRONT_LEFT, FRONT_RIGHT, BACK = 0, 1, 2  # roles: ids within a 3 vs 3 team
TEAM_ANCHORS = ThreeVsThree.anchors_xyz[:3]  # in the team's own frame (x > 0)
CONTACT_Z = 2.75  # m: the ball's centre where a drone at 2.6 m meets it; Pass and Set are judged here
TARGET_RADIUS = 1.0  # m: a pass or set coming down this close to the teammate's anchor succeeds
ERROR_SCALE = 3.0  # m: the accuracy term falls to 0 at this error
MISBEHAVE = -10.0
HIT_REWARD = 5.0
SUCCESS_REWARD = 10.0
ACCURACY_REWARD = 5.0
DIST_COEF = 0.05
# the 3 vs 3 scripted team's serve as it comes to the receivers (module docstring, ``pass``): where the
# teammate hits it over from (low, high), its flight (s), and where it comes down through CONTACT_Z (centre, spread)
SERVE_BALL = ((-3.25, -1.5, 2.6), (-3.05, 1.5, 2.8), (1.3, 1.4), (2.5, 0.0), (0.2, 1.6))
DRILL_PARTS = (("root", 23), ("anchor", 3), ("ball", 3), ("ball_vel", 3), ("may_hit", 2))


def serve_share_arg(serves) -> float:
    """The ``serves`` argument of the drills that mix in the scripted serve (Pass, Attack), checked."""
    if not 0.0 <= float(serves) <= 1.0:
        raise ValueError(f"serves must be a share in [0, 1]; got {serves!r}")
    return float(serves)


BANK_FORMAT = "volleybots-ball-bank/1"  # a file of recorded incoming balls (``read_ball_bank``)
BANK_BYTES = 64 << 20  # a bank holds 24 bytes a ball: a million balls fit


def read_ball_bank(path) -> torch.Tensor:
    """[K, 6] the balls (position, velocity; the receiving team on +x) of a ball bank file, as
    ``volleybots.play.serves.record_serves`` writes it: the balls a team met, which the Pass and Attack
    drills draw their serves from (``serve_bank``; HCSP's stage III, drills fine-tuned on what they meet)."""
    try:  # a bounded read (a folder, a device or a huge file is one line), then weights only
        data = torch.load(io.BytesIO(read_bytes(path, "ball bank", BANK_BYTES)), map_location="cpu", weights_only=True)
    except (OSError, RuntimeError, EOFError, ValueError, ConfigError) as e:
        raise ValueError(f"serve_bank={str(path)!r} is no readable ball bank ({type(e).__name__}); allowed: a file "
                         "written by volleybots.play.serves.record_serves") from None
    balls = data.get("balls") if isinstance(data, dict) and data.get("format") == BANK_FORMAT else None
    if not isinstance(balls, torch.Tensor) or balls.ndim != 2 or balls.shape[1] != 6 or balls.shape[0] < 1:
        raise ValueError(f"serve_bank={str(path)!r} is no ball bank (format {BANK_FORMAT!r}, 'balls' [K >= 1, 6])")
    balls = balls.float()
    if not bool(torch.isfinite(balls).all()) or bool((balls[:, 0] >= 0).any()):
        raise ValueError(f"serve_bank={str(path)!r} holds balls that are not finite or not in the opponents' half (x < 0)")
    return balls


def velocity_through(start: torch.Tensor, end: torch.Tensor, flight: torch.Tensor, g: float) -> torch.Tensor:
    """[N, 3] the launch velocity that carries a ball from ``start`` to ``end`` [N, 3] in ``flight`` [N]
    seconds (no drag): how a drill's reset sends the ball in as a teammate or an opponent would."""
    t = flight.unsqueeze(-1)
    v = (end - start) / t
    return torch.cat((v[:, :2], v[:, 2:] + 0.5 * g * t), -1)


class _Drill(VolleyEnv):
    """One drone of a 3 vs 3 team playing one touch of a rally (the table in the module docstring)."""

    n_drones = 1
    teams = (0,)
    episode_len = 500
    obs_parts = DRILL_PARTS
    reward_terms = ("hit", "success", "accuracy", "dist_to_ball", "misbehave")
    shaping_terms = ("accuracy", "dist_to_ball")
    metric = "success"
    extra_stats = ("hits", "error")
    role: int = BACK
    init_noise = 0.1  # m around the anchor, as in the match
    comes_over = False  # the ball starts in the opponents' half: the drone may touch it only once it crosses
    serves = 0.0  # the share of balls that are the scripted team's serve (``serve_share``; Pass and Attack take it)
    bank = None  # [K, 6] recorded balls the serves are drawn from instead (``serve_bank``), or None

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        n, dev = self.num_envs, self.device
        self.anchor = torch.tensor(TEAM_ANCHORS[self.role], device=dev)
        self.aim = torch.zeros(n, 2, device=dev)  # where the ball should go (xy)
        self.prev_ball = torch.zeros(n, 3, device=dev)
        self.touched = torch.zeros(n, dtype=torch.bool, device=dev)
        self.success = torch.zeros(n, device=dev)
        self.error = torch.zeros(n, device=dev)
        self._no_flip = torch.zeros(1, dtype=torch.bool, device=dev)
        self.served = torch.zeros(n, dtype=torch.bool, device=dev)  # this reset's balls that are a serve (``serve_share``)

    def referee_config(self):
        return RefereeConfig(court=COURTS["3v3"], turns="possession", drone_min_z=0.4, out_at_any_height=False)

    # ------------------------------------------------------------------ reset
    def ball_start(self) -> tuple[torch.Tensor, torch.Tensor]:
        """[N, 3] ball position and velocity at reset (for all envs; drawn with ``uniform``)."""
        raise TypeError(f"{type(self).__name__} must define ball_start()")

    def aim_point(self) -> torch.Tensor:
        """[N, 2] where the drill should send the ball (xy), after ``ball_start``."""
        raise TypeError(f"{type(self).__name__} must define aim_point()")

    def reset_task(self, mask):
        n = self.num_envs
        noise = (self.init_noise,) * 3
        pos = self.anchor + self.uniform(tuple(-x for x in noise), noise, (n, 1))
        self.place_drones(mask, pos)
        ball_pos, ball_vel = self.ball_start()
        self.place_ball(mask, ball_pos, ball_vel)
        self.referee.reset(mask, self.physics.state.ball_pos)
        # the opponents' possession until the ball crosses the net: every ball of a drill that comes over,
        # and the serves a drill mixes in
        over = mask & (self.served | self.comes_over)
        self.referee.may_hit = self.referee.may_hit & ~over.unsqueeze(1)
        self.aim = masked_select(mask, self.aim_point(), self.aim)
        self.prev_ball = masked_select(mask, self.physics.state.ball_pos, self.prev_ball)
        self.touched = self.touched & ~mask
        self.success = torch.where(mask, 0.0, self.success)
        self.error = torch.where(mask, 0.0, self.error)

    def uniform_point(self, low, high) -> torch.Tensor:
        return self.uniform(low, high, (self.num_envs,))

    def incoming(self, start_low, start_high, flight: tuple[float, float], centre, spread) -> tuple[torch.Tensor, torch.Tensor]:
        """A ball sent from uniform in [start_low, start_high] to come down through ``CONTACT_Z``
        uniformly within ``spread`` (x, y) of ``centre`` (xy), ``flight`` seconds later."""
        start = self.uniform_point(start_low, start_high)
        lo = (centre[0] - spread[0], centre[1] - spread[1], CONTACT_Z)
        hi = (centre[0] + spread[0], centre[1] + spread[1], CONTACT_Z)
        end = self.uniform_point(lo, hi)
        t = self.uniform(flight[0], flight[1], (self.num_envs,))
        return start, velocity_through(start, end, t, self.params.gravity)

    def serve_share(self, pos: torch.Tensor, vel: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``pos``, ``vel`` with the share ``serves`` of the balls replaced by the scripted team's serve
        (``SERVE_BALL``), or by balls drawn from the bank (``serve_bank``); ``self.served`` [N] says
        which. Drawn always when on, so a seed's balls do not depend on the share's draws."""
        if self.serves <= 0.0:
            return pos, vel
        if self.bank is None:
            spos, svel = self.incoming(*SERVE_BALL)
        else:
            pick = (self.uniform(0.0, 1.0, (self.num_envs,)) * len(self.bank)).long().clamp_max(len(self.bank) - 1)
            balls = self.bank.to(pos.device)[pick]
            spos, svel = balls[:, :3], balls[:, 3:]
        self.served = self.uniform(0.0, 1.0, (self.num_envs,)) < self.serves
        take = self.served.unsqueeze(-1)
        return torch.where(take, spos, pos), torch.where(take, svel, vel)

    # ------------------------------------------------------------------ observation
    def observe_parts(self) -> dict[str, torch.Tensor]:
        s = self.physics.state
        return dict(
            root=mirror_root(self.root_state(), self._no_flip),
            anchor=s.pos - self.anchor,
            ball=s.ball_pos.unsqueeze(1) - s.pos,
            ball_vel=s.ball_vel.unsqueeze(1),
            may_hit=flag_pair(self.referee.may_hit),
        )

    def observe(self):
        return self.layout.build(**self.observe_parts())

    # ------------------------------------------------------------------ rewards
    def outcome(self, ev) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """This step: (the drill is done [N], it succeeded [N], the error [N] in m)."""
        raise TypeError(f"{type(self).__name__} must define outcome()")

    def evaluate(self, ev):
        s = self.physics.state
        legal = ev.racket_hit[:, 0] & ~ev.wrong_hit[:, 0]
        first = legal & ~self.touched
        before = ~self.touched
        self.touched = self.touched | legal
        done, success, error = self.outcome(ev)
        self.prev_ball = s.ball_pos.clone()
        missed = ev.ball_landed & ~done
        bad = ev.drone_low[:, 0] | ev.drone_net[:, 0] | ev.drone_cross[:, 0] | ev.wrong_hit[:, 0] | ev.ball_net | missed
        bad = bad & ~done
        self.success = torch.where(done, success.float(), self.success)
        self.error = torch.where(done, error, self.error)
        d = (s.pos[:, 0] - s.ball_pos).norm(dim=-1)
        accuracy = done * ACCURACY_REWARD * (1.0 - error / ERROR_SCALE).clamp_min(0.0)
        return StepResult(
            terms={
                "hit": (first * HIT_REWARD).unsqueeze(-1),
                "success": (done & success).float().unsqueeze(-1) * SUCCESS_REWARD,
                "accuracy": accuracy.unsqueeze(-1),
                "dist_to_ball": (before * DIST_COEF / (1.0 + d)).unsqueeze(-1),
                "misbehave": (bad * MISBEHAVE).unsqueeze(-1),
            },
            terminated=done | bad,
            stats={"success": self.success, "hits": self.referee.hits[:, 0].float(), "error": self.error},
        )

    def came_down(self, ev) -> tuple[torch.Tensor, torch.Tensor]:
        """After the touch, the ball comes down through ``CONTACT_Z`` this step: (that [N], where, xy [N, 2])."""
        s = self.physics.state
        z0, z1 = self.prev_ball[:, 2], s.ball_pos[:, 2]
        down = self.touched & (z0 >= CONTACT_Z) & (z1 < CONTACT_Z) & (s.ball_vel[:, 2] < 0)
        frac = ((z0 - CONTACT_Z) / (z0 - z1).clamp_min(1e-9)).unsqueeze(-1)
        where = (self.prev_ball + (s.ball_pos - self.prev_ball) * frac)[:, :2]
        return down, where

    def landed_over(self, ev) -> torch.Tensor:
        """[N] after the touch the ball lands in the opponent's court this step."""
        s = self.physics.state
        return self.touched & ev.ball_landed & ~ev.ball_out & (s.ball_pos[:, 0] < 0)


class _PassDrill(_Drill):
    """Pass and Set: the touch sends the ball to a teammate's anchor; judged where it comes down."""

    target_role: int = FRONT_LEFT

    def aim_point(self):
        return torch.tensor(TEAM_ANCHORS[self.target_role][:2], device=self.device).expand(self.num_envs, 2)

    def outcome(self, ev):
        down, where = self.came_down(ev)
        error = (where - self.aim).norm(dim=-1)
        # a ball sent back over the net (or into it) is no pass: done, and failed
        over = self.touched & ev.ball_crossed
        return down | over, down & (error <= TARGET_RADIUS), torch.where(down, error, torch.full_like(error, ERROR_SCALE))


class Serve(_Drill):
    name = "serve"
    role = BACK
    ball_above = 3.0  # m above the server, at rest (as in the match)
    aim_xy = (-3.0, 0.0)  # the middle of the opponent's half

    def ball_start(self):
        # the drone's position is drawn just before: the ball starts above where the drone is
        pos = self.physics.state.pos[:, 0] + torch.tensor((0.0, 0.0, self.ball_above), device=self.device)
        return pos, torch.zeros_like(pos)

    def aim_point(self):
        return torch.tensor(self.aim_xy, device=self.device).expand(self.num_envs, 2)

    def outcome(self, ev):
        landed = self.landed_over(ev)
        error = (self.physics.state.ball_pos[:, :2] - self.aim).norm(dim=-1)
        return landed, landed, error


class Pass(_PassDrill):
    name = "pass"
    role = BACK
    target_role = FRONT_LEFT
    comes_over = True

    def __init__(self, *args, serves: float = 0.0, serve_bank: str | None = None, **kw):
        self.serves = serve_share_arg(serves)
        self.bank = None if serve_bank is None else read_ball_bank(serve_bank)  # before the first reset
        super().__init__(*args, **kw)

    def ball_start(self):
        pos, vel = self.incoming((-4.5, -2.0, 2.5), (-2.0, 2.0, 3.0), (1.3, 1.7), (5.5, 0.0), (1.0, 1.5))
        return self.serve_share(pos, vel)


class Set(_PassDrill):
    name = "set"
    role = FRONT_LEFT
    target_role = FRONT_RIGHT

    def ball_start(self):
        me = TEAM_ANCHORS[FRONT_LEFT]
        return self.incoming((4.5, -1.0, CONTACT_Z), (6.5, 1.0, CONTACT_Z), (1.2, 1.6), me[:2], (0.5, 0.5))


class Attack(_Drill):
    name = "attack"
    role = FRONT_RIGHT
    obs_parts = DRILL_PARTS + (("side", 2),)  # (left, right): y < 0 or y > 0 of the opponent's court, facing -x
    quarter = (-3.0, 1.5)  # the middle of a quarter of the opponent's court: (x, |y|)

    def __init__(self, *args, side: int | None = None, serves: float = 0.0, serve_bank: str | None = None, **kw):
        if side not in (None, 0, 1):
            raise ValueError(f"side must be None (random), 0 (left) or 1 (right); got {side!r}")
        self.fixed_side, self.serves = side, serve_share_arg(serves)
        self.bank = None if serve_bank is None else read_ball_bank(serve_bank)  # before the first reset
        super().__init__(*args, **kw)
        self.side = torch.zeros(self.num_envs, dtype=torch.long, device=self.device)

    def ball_start(self):
        setter, me = TEAM_ANCHORS[FRONT_LEFT], TEAM_ANCHORS[FRONT_RIGHT]
        start = self.uniform_point((setter[0] - 0.5, setter[1] - 0.5, CONTACT_Z), (setter[0] + 0.5, setter[1] + 0.5, CONTACT_Z))
        end = self.uniform_point((me[0] - 0.5, me[1] - 0.5, CONTACT_Z), (me[0] + 0.5, me[1] + 0.5, CONTACT_Z))
        t = self.uniform(1.2, 1.6, (self.num_envs,))
        # the serves: a front drone returning the opponents' serve at once, a one-touch possession
        return self.serve_share(start, velocity_through(start, end, t, self.params.gravity))

    def reset_task(self, mask):
        side = (self.uniform(0.0, 1.0, (self.num_envs,)) < 0.5).long()
        if self.fixed_side is not None:
            side = torch.full_like(side, self.fixed_side)
        self.side = torch.where(mask, side, self.side)
        super().reset_task(mask)

    def aim_point(self):
        x, y = self.quarter
        return torch.stack((torch.full_like(self.side, x, dtype=torch.float32), torch.where(self.side == 1, y, -y)), -1)

    def observe_parts(self):
        parts = super().observe_parts()
        parts["side"] = one_hot(self.side, 2).unsqueeze(1)
        return parts

    def outcome(self, ev):
        landed = self.landed_over(ev)
        y = self.physics.state.ball_pos[:, 1]
        right_side = torch.where(self.side == 1, y > 0, y < 0)
        error = (self.physics.state.ball_pos[:, :2] - self.aim).norm(dim=-1)
        return landed, landed & right_side, error


DRILLS = (Serve, Pass, Set, Attack)

__all__ = [
    "Attack", "BACK", "CONTACT_Z", "DRILLS", "DRILL_PARTS", "FRONT_LEFT", "FRONT_RIGHT", "Pass", "Serve", "Set", "TEAM_ANCHORS",
    "velocity_through",
]
