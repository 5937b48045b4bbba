"""Two-drone cooperative tasks: Bump and Pass, Set and Spike (Easy, Hard) (paper appendix C;
docs/tasks.md).

Observation (39 for Bump and Pass, 40 for Set and Spike; 4 fewer with CTBR): root state, drone minus
its anchor, drone minus ball, ball velocity, other drone minus self, turn one-hot, id one-hot.
Relative vectors are "drone minus target" (the other drone is "other minus self", as in the reference).

Rewards: ``shared`` terms are paid to both drones, the others to the drone concerned. Every
misbehaviour is -10 and ends the episode. Coefficients are the reference implementation's.
"""

from __future__ import annotations

import torch

from volleybots.physics.torch_backend import masked_select
from volleybots.rules import COURTS, RefereeConfig
from volleybots.tasks.base import StepResult
from volleybots.tasks.defence import DefenceRacket
from volleybots.tasks.multi import MultiDroneTask, anchor_excess, cosine_xy, one_hot

MISBEHAVE = -10.0
ANCHOR_RADIUS = 0.5
ANCHOR_COEF = 0.05
DIST_COEF = 0.05


def coop_parts(n_turn: int) -> tuple[tuple[str, int], ...]:
    """The cooperative observation: root, drone minus anchor, drone minus ball, ball velocity, other
    drone minus self, turn one-hot (``n_turn``), id one-hot (2)."""
    return (("root", 23), ("anchor", 3), ("ball", 3), ("ball_vel", 3), ("other", 3), ("turn", n_turn), ("id", 2))


def _shared(x: torch.Tensor, n_drones: int = 2) -> torch.Tensor:
    """[N] -> [N, A]: the same value for every drone."""
    return x.float().unsqueeze(-1).expand(-1, n_drones)


class _CoopTask(MultiDroneTask):
    """Reset around the anchors with the ball at rest 2 m above drone 0, the observation, and the
    anchor-distance and turn-toward-ball terms both tasks share."""

    n_drones = 2
    teams = (0, 0)
    episode_len = 800
    init_low = (-0.5, -0.5, -0.2)
    init_high = (0.5, 0.5, 0.2)
    n_turn = 2  # size of the turn one-hot

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self.prev_ball = torch.zeros(self.num_envs, 3, device=self.device)
        self._ids = torch.eye(2, device=self.device)

    def reset_task(self, mask):
        pos = self.place_around_anchors(mask, self.init_low, self.init_high)
        ball = self.anchors[0] + torch.tensor((0.0, 0.0, 2.0), device=self.device)
        self.place_ball(mask, ball)
        self.prev_ball = masked_select(mask, ball.expand_as(self.prev_ball), self.prev_ball)
        self.referee.reset(mask, self.physics.state.ball_pos)
        self.reset_coop(mask, pos)

    def reset_coop(self, mask, pos):
        pass

    def turn_obs(self) -> torch.Tensor:
        """[N, n_turn] turn one-hot, the same for both drones."""
        raise TypeError(f"{type(self).__name__} must define turn_obs()")

    def observe(self):
        s = self.physics.state
        n = self.num_envs
        other = s.pos.flip(1) - s.pos
        return self.layout.build(
            root=self.root_state(),
            anchor=s.pos - self.anchors,
            ball=s.pos - s.ball_pos.unsqueeze(1),
            ball_vel=s.ball_vel.unsqueeze(1).expand(-1, 2, -1),
            other=other,
            turn=self.turn_obs().unsqueeze(1).expand(-1, 2, -1),
            id=self._ids.expand(n, 2, 2),
        )

    def anchor_term(self) -> torch.Tensor:
        """Shared -0.05 x mean excess distance beyond 0.5 m from the anchors."""
        excess = anchor_excess(self.physics.state.pos, self.anchors, ANCHOR_RADIUS)
        return _shared(-ANCHOR_COEF * excess.mean(1))

    def toward_ball_term(self, turn: torch.Tensor) -> torch.Tensor:
        """0.05 / (1 + horizontal distance to the ball), positive for the drone whose turn it is and
        negative for the other; zero for both when nobody may hit. ``turn`` [N, 2] bool."""
        s = self.physics.state
        d = (s.pos[..., :2] - s.ball_pos[:, None, :2]).norm(dim=-1)
        sign = torch.where(turn, 1.0, -1.0) * turn.any(1, keepdim=True)
        return DIST_COEF * sign / (1.0 + d)


class BumpAndPass(_CoopTask):
    """Two drones bump the ball to each other, above 4 m, as many times as they can."""

    name = "bump_and_pass"
    anchors_xyz = ((4.5, -2.5, 2.0), (4.5, 2.5, 2.0))
    obs_parts = coop_parts(2)
    reward_terms = (
        "success_hit", "success_cross", "dist_to_anchor", "ball_misbehave", "drone_misbehave", "wrong_hit", "hit_direction", "dist_to_ball",
    )
    shaping_terms = ("hit_direction", "dist_to_ball")
    metric = "bumps"  # longest run of consecutive successful bumps
    extra_stats = ("passes", "hits")
    min_height = 4.0

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        n = self.num_envs
        b = lambda: torch.zeros(n, dtype=torch.bool, device=self.device)  # noqa: E731
        f = lambda: torch.zeros(n, device=self.device)  # noqa: E731
        self.pending, self.crossed = b(), b()  # a bump in flight, and whether it crossed the midline yet
        self.receiver = torch.zeros(n, dtype=torch.long, device=self.device)
        self.apex, self.streak, self.best, self.passes, self.hits = f(), f(), f(), f(), f()
        self.side_y = torch.sign(self.anchors[:, 1])  # which side of y = 0 each drone plays

    def referee_config(self):
        return RefereeConfig(court=COURTS["full"], turns="alternate", drone_min_z=0.4)

    def reset_coop(self, mask, pos):
        self.pending, self.crossed = self.pending & ~mask, self.crossed & ~mask
        self.apex, self.streak, self.best, self.passes, self.hits = (
            torch.where(mask, 0.0, buf) for buf in (self.apex, self.streak, self.best, self.passes, self.hits)
        )
        self.receiver = torch.where(mask, 1, self.receiver)

    def turn_obs(self):
        return self.referee.may_hit.float()

    def evaluate(self, ev):
        s = self.physics.state
        bz, by = s.ball_pos[:, 2], s.ball_pos[:, 1]
        legal = ev.racket_hit & ~ev.wrong_hit  # [N, 2]
        hit = legal.any(1)
        hitter = legal.long().argmax(1)
        # a bump still short of success when the next hit comes has failed: the run restarts
        self.streak = torch.where(hit & self.pending, torch.zeros_like(self.streak), self.streak)
        self.pending = self.pending | hit
        self.receiver = torch.where(hit, 1 - hitter, self.receiver)
        self.crossed = self.crossed & ~hit
        self.apex = torch.where(hit, bz, torch.maximum(self.apex, bz))
        side = self.side_y[self.receiver]
        self.crossed = self.crossed | ((self.prev_ball[:, 1] * side < 0) & (by * side >= 0) & ~hit)
        success = self.pending & self.crossed & (self.apex >= self.min_height)
        self.pending = self.pending & ~success
        self.streak = self.streak + success.float()
        self.best = torch.maximum(self.best, self.streak)
        self.passes = self.passes + success.float()
        self.hits = self.hits + hit.float()
        self.prev_ball = s.ball_pos.clone()

        # the hitter is paid for sending the ball toward its partner
        partner = s.pos.flip(1) - s.pos
        direction = legal.float() * cosine_xy(s.ball_vel.unsqueeze(1), partner)
        ball_bad = ev.ball_landed | ev.ball_net | ev.ball_out
        drone_bad = ev.drone_low | ev.drone_net
        return StepResult(
            terms={
                "success_hit": _shared(hit),
                "success_cross": _shared(success),
                "dist_to_anchor": self.anchor_term(),
                "ball_misbehave": _shared(ball_bad) * MISBEHAVE,
                "drone_misbehave": drone_bad.float() * MISBEHAVE,
                "wrong_hit": ev.wrong_hit.float() * MISBEHAVE,
                "hit_direction": direction,
                "dist_to_ball": self.toward_ball_term(self.referee.may_hit),
            },
            terminated=ball_bad | drone_bad.any(1) | ev.wrong_hit.any(1),
            stats={"bumps": self.best, "passes": self.passes, "hits": self.hits},
        )


class _SetAndSpike(_CoopTask):
    """Setter (drone 0) sets, attacker (drone 1) spikes down into the -x half."""

    anchors_xyz = ((2.0, -2.5, 2.5), (2.0, 2.5, 3.5))
    obs_parts = coop_parts(3)  # the turn one-hot over (setter, attacker, done)
    n_turn = 3
    metric = "success_rate"  # mean of the four components below
    goal = ""  # the fourth component: "in_target" (Easy) or "success_spike" (Hard)
    target_xy = (-4.5, 0.0)
    target_radius = 1.0
    drone_min_z = 0.4
    hit_reward = 5.0
    spike_coef = 0.2

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        n = self.num_envs
        flags = ("setter_hit", "attacker_hit", "downward_spike", "crossed", self.goal)
        self.flags = {k: torch.zeros(n, dtype=torch.bool, device=self.device) for k in flags}
        self.target = torch.tensor(self.target_xy, device=self.device)

    @property
    def components(self) -> tuple[str, ...]:
        return ("setter_hit", "attacker_hit", "downward_spike", self.goal)

    def referee_config(self):
        return RefereeConfig(court=COURTS["full"], turns="sequence", order=(0, 1), drone_min_z=self.drone_min_z)

    def reset_coop(self, mask, pos):
        for k, v in self.flags.items():
            self.flags[k] = v & ~mask

    def turn_obs(self):
        return one_hot(self.referee.seq_index.clamp_max(2), 3)

    def goal_reached(self, ev, landed_after_spike) -> torch.Tensor:
        """[N] the fourth success component happens this step."""
        raise TypeError(f"{type(self).__name__} must define goal_reached()")

    def evaluate(self, ev):
        s = self.physics.state
        f = self.flags
        legal = ev.racket_hit & ~ev.wrong_hit
        set_now, spike_now = legal[:, 0] & ~f["setter_hit"], legal[:, 1] & f["setter_hit"] & ~f["attacker_hit"]
        downward = spike_now & (s.ball_vel[:, 2] < 0)
        f["setter_hit"] = f["setter_hit"] | set_now
        f["attacker_hit"] = f["attacker_hit"] | spike_now
        f["downward_spike"] = f["downward_spike"] | downward
        cross_now = f["attacker_hit"] & ev.ball_crossed & (s.ball_pos[:, 0] < 0) & ~f["crossed"]
        f["crossed"] = f["crossed"] | cross_now
        landed = ev.ball_landed & f["attacker_hit"]
        goal_now = self.goal_reached(ev, landed) & ~f[self.goal]
        f[self.goal] = f[self.goal] | goal_now
        self.prev_ball = s.ball_pos.clone()

        # hit direction: the setter toward the attacker, the attacker toward the target
        aim = torch.stack((s.pos[:, 1, :2] - s.pos[:, 0, :2], self.target - s.pos[:, 1, :2]), 1)
        direction = legal.float() * cosine_xy(s.ball_vel.unsqueeze(1), aim)
        spike_vel = spike_now * self.spike_coef * (5.0 - s.ball_vel[:, 2]).clamp_min(0.0)
        ball_bad = (ev.ball_landed & ~goal_now) | ev.ball_net | (ev.ball_out & ~goal_now)
        drone_bad = ev.drone_low | ev.drone_cross | ev.drone_net
        terms = {
            "success_hit": _shared(set_now | spike_now) * self.hit_reward,
            "downward_spike": _shared(downward) * self.hit_reward,
            "success_cross": _shared(cross_now) * self.hit_reward,
            self.goal: _shared(goal_now) * self.hit_reward,
            "dist_to_anchor": self.anchor_term(),
            "ball_misbehave": _shared(ball_bad) * MISBEHAVE,
            "drone_misbehave": drone_bad.float() * MISBEHAVE,
            "wrong_hit": ev.wrong_hit.float() * MISBEHAVE,
            "hit_direction": direction,
            "spike_velocity": _shared(spike_vel),
            "dist_to_ball": self.toward_ball_term(self.referee.may_hit),
        }
        terms.update(self.extra_terms(ev, landed))
        stats = {k: f[k].float() for k in self.components}
        stats["success_rate"] = sum(stats.values()) / 4.0
        stats.update(self.extra_stat_values())
        terminated = ev.ball_landed | ev.ball_net | ev.ball_out | drone_bad.any(1) | ev.wrong_hit.any(1) | self.stop(ev)
        return StepResult(terms=terms, terminated=terminated, stats=stats)

    def extra_terms(self, ev, landed) -> dict[str, torch.Tensor]:
        return {}

    def extra_stat_values(self) -> dict[str, torch.Tensor]:
        return {}

    def stop(self, ev) -> torch.Tensor:
        """[N] further reasons to end the episode."""
        return torch.zeros(self.num_envs, dtype=torch.bool, device=self.device)


class SetAndSpikeEasy(_SetAndSpike):
    name = "set_and_spike_easy"
    goal = "in_target"  # the spiked ball lands within 1 m of (-4.5, 0)
    extra_stats = ("setter_hit", "attacker_hit", "downward_spike", "in_target")
    drone_min_z = 0.2
    reward_terms = (
        "success_hit", "downward_spike", "success_cross", "in_target", "dist_to_anchor", "ball_misbehave",
        "drone_misbehave", "wrong_hit", "hit_direction", "spike_velocity", "dist_to_ball", "dist_to_target",
    )
    shaping_terms = ("hit_direction", "spike_velocity", "dist_to_ball", "dist_to_target")

    def goal_reached(self, ev, landed):
        d = (self.physics.state.ball_pos[:, :2] - self.target).norm(dim=-1)
        return landed & (d <= self.target_radius)

    def extra_terms(self, ev, landed):
        # up to 2 for landing close to the target
        d = (self.physics.state.ball_pos[:, :2] - self.target).norm(dim=-1)
        return {"dist_to_target": _shared(landed * 0.2 * (10.0 - d).clamp_min(0.0))}


class SetAndSpikeHard(_SetAndSpike):
    """As Easy, against the kinematic defence racket on the -x half (``volleybots.tasks.defence``)."""

    name = "set_and_spike_hard"
    goal = "success_spike"  # the spiked ball lands in the -x half without the racket touching it
    extra_stats = ("setter_hit", "attacker_hit", "downward_spike", "success_spike", "intercepted")
    reward_terms = (
        "success_hit", "downward_spike", "success_cross", "success_spike", "dist_to_anchor", "ball_misbehave",
        "drone_misbehave", "wrong_hit", "hit_direction", "spike_velocity", "dist_to_ball",
    )
    shaping_terms = ("hit_direction", "spike_velocity", "dist_to_ball")

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self.defence = DefenceRacket(self.num_envs, self.device, self.params.dt, self.params.ball.radius, self.params.gravity)
        self.intercepted = torch.zeros(self.num_envs, dtype=torch.bool, device=self.device)

    def reset_coop(self, mask, pos):
        super().reset_coop(mask, pos)
        self.defence.reset(mask)
        self.intercepted = self.intercepted & ~mask

    def evaluate(self, ev):
        # the racket acts on the ball first, so that a returned ball is never scored as landed
        s = self.physics.state
        touch, bpos, bvel = self.defence.step(self.prev_ball, s.ball_pos, s.ball_vel, self.flags["attacker_hit"])
        self.physics.set_state(touch, ball_pos=bpos, ball_vel=bvel)  # untouched envs keep their ball
        ev.ball_landed = ev.ball_landed & ~touch
        self.intercepted = self.intercepted | touch
        return super().evaluate(ev)

    def goal_reached(self, ev, landed):
        s = self.physics.state
        in_half = (s.ball_pos[:, 0] < 0) & ~ev.ball_out
        return landed & in_half & ~self.intercepted

    def extra_stat_values(self):
        return {"intercepted": self.intercepted.float()}

    def stop(self, ev):
        # an intercepted spike is over: no success, and no penalty either
        return self.intercepted
