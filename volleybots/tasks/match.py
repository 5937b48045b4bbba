"""Matches: 1 vs 1, 3 vs 3, 6 vs 6 (paper appendix C; docs/tasks.md).

Team 0 plays on +x, team 1 on -x; team 1's anchors are team 0's rotated by 180 degrees about z, and its
drones start with yaw pi, so the two sides are exact images of each other. A random team serves (the
task override ``serve=0|1`` fixes it): the ball starts at rest above its server, who alone may make
the first touch.

A rally ends when the referee's ``outcome`` finds a fault (the five violations: drone crosses or
touches the net, hit on the wrong turn, body hit, ball out of court, ball into the net; or the ball
landing in a half), blamed on a team. Both teams faulting in one step is a draw; so is a crash (a drone
below 0.3 m) or, in 3 vs 3 and 6 vs 6, two teammates closer than 0.8 m, when no fault decides the step;
so is the time limit. **Decision:** a ball that leaves the court before anyone touched it (possible only
from a serve) is the serving team's fault.

Observations are egocentric and mirrored: every vector an agent of team 1 sees is rotated by 180
degrees about z (``multi.mirror_root``), its turn flags say "my turn", and lists of drones start with
its own team, so the same policy plays either side. Relative vectors: "drone minus ball" in 1 vs 1,
"ball minus drone" in 3 vs 3 / 6 vs 6 (as in the reference).

Statistics per episode: ``win`` / ``loss`` / ``draw`` from team 0's side, ``winner`` (0, 1, -1),
``reason`` (index into ``Referee.FAULTS`` of the fault that ended the rally, -1 for draws),
``hits_team0`` / ``hits_team1`` (touches), ``serve_team``.
"""

from __future__ import annotations

import math

import torch

from volleybots.rules import COURTS, Referee, RefereeConfig
from volleybots.tasks.base import StepResult
from volleybots.tasks.multi import MultiDroneTask, flag_pair, mirror_root, mirror_vec, one_hot

WIN = 100.0
MISBEHAVE = -100.0
CRASH_Z = 0.3


def both_sides(team0: tuple[tuple[float, float, float], ...]) -> tuple[tuple[float, float, float], ...]:
    """Team 0's anchors followed by their images under the rotation by 180 degrees about z."""
    return tuple(team0) + tuple((-x, -y, z) for x, y, z in team0)


def team_match_parts(team_size: int) -> tuple[tuple[str, int], ...]:
    """The 3 vs 3 / 6 vs 6 observation: root, drone minus anchor, ball minus drone, ball velocity,
    turn (my team may hit, not), id within the team, may-hit flag (I may hit, not), every drone's
    position (own team first, each team in id order)."""
    return (("root", 23), ("anchor", 3), ("ball", 3), ("ball_vel", 3), ("turn", 2), ("id", team_size), ("may_hit", 2),
            ("positions", 3 * 2 * team_size))


class _Match(MultiDroneTask):
    court: str = "full"
    team_size: int = 1
    server_rank: int = 0  # the serving drone's index within its team
    ball_above: float = 3.0  # the ball starts this high above the server
    turn_mode: str = "possession"
    out_at_any_height: bool = False
    init_noise: float = 0.1
    metric = "win"
    competitive = True
    default_algo = "sp"
    extra_stats = ("loss", "draw", "winner", "reason", "hits_team0", "hits_team1", "serve_team")
    default_hit_reward: float = 10.0  # the paper's success_hit per legal touch (1 vs 1: 5)

    def __init__(self, *args, serve: int | None = None, hit_reward: float | None = None, fall_fault: bool = False, **kw):
        """``fall_fault``: a drone falling below the crash height is a fault of its team (the volleyball
        rule), where the paper's rule (the default) ends the match with no winner, so that a team about to
        lose a rally could save it by flying into the floor.
        ``hit_reward``: the shaping reward of a legal touch (None: the paper's, ``default_hit_reward``).
        A win is worth 100, so at the paper's 5 a 1 vs 1 self-play learner is paid for a serve that ends
        the point, not for keeping a rally going (docs/results/table3-1v1.md); a larger value pays returns."""
        if serve not in (None, 0, 1):
            raise ValueError(f"serve must be None (random), 0 or 1; got {serve!r}")
        self.fixed_serve = serve
        if not isinstance(fall_fault, bool):
            raise ValueError(f"fall_fault must be true or false; got {fall_fault!r}")
        self.fall_fault = fall_fault
        self.hit_reward = self.default_hit_reward if hit_reward is None else float(hit_reward)
        super().__init__(*args, **kw)
        n, a = self.num_envs, self.n_drones
        dev = self.device
        self.flip = self.team_ids == 1  # [A]: agents that see the mirrored world
        self.rank = torch.cat([torch.arange(len(self.team_index(t)), device=dev) for t in (0, 1)])  # id within team
        own = [torch.cat((self.team_index(t), self.team_index(1 - t))) for t in self.teams]
        self.view_order = torch.stack(own)  # [A, A]: for agent a, its team's agents first, then the others
        self.yaw = self.flip.float() * math.pi
        self.team_onehot = one_hot(self.team_ids, 2)  # [A, 2]
        self.serve_team = torch.zeros(n, dtype=torch.long, device=dev)
        self.winner = torch.full((n,), -1, dtype=torch.long, device=dev)
        self.reason = torch.full((n,), -1, dtype=torch.long, device=dev)
        self.is_draw = torch.zeros(n, dtype=torch.bool, device=dev)
        self.same_team = (self.team_ids[:, None] == self.team_ids[None, :]) & ~torch.eye(a, dtype=torch.bool, device=dev)

    @property
    def teams(self) -> tuple[int, ...]:
        return (0,) * self.team_size + (1,) * self.team_size

    @property
    def n_drones(self) -> int:
        return 2 * self.team_size

    def referee_config(self):
        return RefereeConfig(court=COURTS[self.court], turns=self.turn_mode, drone_min_z=CRASH_Z, out_at_any_height=self.out_at_any_height)

    # ------------------------------------------------------------------ reset
    def reset_task(self, mask):
        n = self.num_envs
        noise = (self.init_noise,) * 3
        pos = self.place_around_anchors(mask, tuple(-x for x in noise), noise, yaw=self.yaw)
        team = (self.uniform(0.0, 1.0, (n,)) < 0.5).long()  # a fair coin per env
        if self.fixed_serve is not None:
            team = torch.full_like(team, self.fixed_serve)
        server = torch.stack((self.team_index(0)[self.server_rank], self.team_index(1)[self.server_rank]))[team]
        above = torch.tensor((0.0, 0.0, self.ball_above), device=self.device)
        ball = pos.gather(1, server.view(n, 1, 1).expand(n, 1, 3)).squeeze(1) + above
        self.place_ball(mask, ball)
        self.referee.reset(mask, self.physics.state.ball_pos, first=server)
        self.serve_team = torch.where(mask, team, self.serve_team)
        self.winner = torch.where(mask, -1, self.winner)
        self.reason = torch.where(mask, -1, self.reason)
        self.is_draw = self.is_draw & ~mask

    # ------------------------------------------------------------------ observation helpers
    def own_root(self) -> torch.Tensor:
        return mirror_root(self.root_state(), self.flip)

    def own(self, v: torch.Tensor) -> torch.Tensor:
        """World vectors [N, A, 3] as each agent sees them."""
        return mirror_vec(v, self.flip.expand(v.shape[:-1]))

    def my_turn(self) -> torch.Tensor:
        """[N, A] my team may hit now."""
        return self.referee.turn_team().unsqueeze(1) == self.team_ids

    def all_positions(self) -> torch.Tensor:
        """[N, A, 3A]: every drone's position in the agent's frame, its own team first."""
        pos = self.physics.state.pos[:, self.view_order]  # [N, A, A, 3]
        return mirror_vec(pos, self.flip[None, :, None].expand(pos.shape[:-1])).flatten(2)

    # ------------------------------------------------------------------ rules and rewards
    def decide(self, ev):
        """The rally outcome of this step: (winner [N], reason [N], draw [N], crash [N, A], collide [N, A])."""
        out = self.referee.outcome(ev)
        fault = out.fault.clone()
        reason = out.reason.clone()
        # a ball out (or in the net) with no hitter yet is the server's
        unclaimed = (ev.ball_out | ev.ball_net) & (ev.last_hitter < 0) & ~out.ended
        fault = fault | (one_hot(self.serve_team, 2).bool() & unclaimed.unsqueeze(1))
        ball_fault = torch.where(ev.ball_out, Referee.FAULTS.index("ball_out"), Referee.FAULTS.index("ball_net"))
        reason = torch.where(unclaimed, ball_fault, reason)
        crash = ev.drone_low
        if self.fall_fault:  # a fall is its team's fault; both teams falling (or faulting) in one step is a draw
            fell = torch.stack([crash[:, self.team_ids == t].any(1) for t in (0, 1)], 1)
            reason = torch.where(fell.any(1) & ~fault.any(1), Referee.FAULTS.index("fell"), reason)
            fault = fault | fell
        ended = fault.any(1)
        draw_fault = fault.all(1)
        collide = self.teammates_too_close()
        stop = crash.any(1) | collide.any(1)
        decided = ended & ~draw_fault
        winner = torch.where(decided, torch.where(fault[:, 0], 1, 0), -1)
        draw = draw_fault | (stop & ~decided)
        reason = torch.where(decided, reason, -1)
        return winner, reason, draw, crash, collide

    def teammates_too_close(self) -> torch.Tensor:
        return torch.zeros(self.num_envs, self.n_drones, dtype=torch.bool, device=self.device)

    def team_terms(self, ev, winner, crash, collide) -> dict[str, torch.Tensor]:
        raise TypeError(f"{type(self).__name__} must define team_terms()")

    def evaluate(self, ev):
        winner, reason, draw, crash, collide = self.decide(ev)
        terminated = (winner >= 0) | draw
        self.winner = torch.where(terminated, winner, self.winner)
        self.reason = torch.where(terminated, reason, self.reason)
        timeout = (self.t >= self.episode_len) & ~terminated
        self.is_draw = self.is_draw | draw | timeout
        decided = winner.unsqueeze(1) >= 0
        result = torch.where(decided, torch.where(self.team_ids == winner.unsqueeze(1), WIN, -WIN), 0.0)
        terms = {"win_or_lose": result, "drone_misbehave": crash.float() * MISBEHAVE}
        terms.update(self.team_terms(ev, winner, crash, collide))
        hits = self.referee.hits.float() @ self.team_onehot  # [N, 2]
        stats = {
            "win": (self.winner == 0).float(),
            "loss": (self.winner == 1).float(),
            "draw": self.is_draw.float(),
            "winner": self.winner.float(),
            "reason": self.reason.float(),
            "hits_team0": hits[:, 0],
            "hits_team1": hits[:, 1],
            "serve_team": self.serve_team.float(),
        }
        return StepResult(terms=terms, terminated=terminated, stats=stats)

    def legal_hits(self, ev) -> torch.Tensor:
        return ev.racket_hit & ~ev.wrong_hit


class OneVsOne(_Match):
    name = "1v1"
    court = "1v1"
    team_size = 1
    anchors_xyz = both_sides(((1.5, 0.0, 2.0),))
    ball_above = 1.5
    turn_mode = "alternate"  # strict alternation of hits
    out_at_any_height = True
    episode_len = 800
    default_hit_reward = 5.0
    # anchor: drone minus anchor; ball: drone minus ball; other: other drone minus self; turn: (my turn, not); id within the team
    obs_parts = (("root", 23), ("anchor", 3), ("ball", 3), ("ball_vel", 3), ("other", 3), ("turn", 2), ("id", 2))
    reward_terms = ("win_or_lose", "drone_misbehave", "drone_out_of_court", "success_hit", "dist_to_ball")
    shaping_terms = ("success_hit", "dist_to_ball")

    def observe(self):
        s = self.physics.state
        n, a = self.num_envs, self.n_drones
        other = s.pos[:, self.view_order[:, 1]] - s.pos
        ids = one_hot(self.rank, 2).expand(n, a, 2)  # id within the team: the same for both sides
        return self.layout.build(
            root=self.own_root(),
            anchor=self.own(s.pos - self.anchors),
            ball=self.own(s.pos - s.ball_pos.unsqueeze(1)),
            ball_vel=self.own(s.ball_vel.unsqueeze(1).expand(-1, a, -1)),
            other=self.own(other),
            turn=flag_pair(self.referee.may_hit),
            id=ids,
        )

    def team_terms(self, ev, winner, crash, collide):
        s = self.physics.state
        court = COURTS[self.court]
        mine = self.own(s.pos)  # in its own frame every drone's half is x in [0, L/2]
        ex = (-mine[..., 0]).clamp_min(0.0) + (mine[..., 0] - court.length / 2).clamp_min(0.0)
        ey = (mine[..., 1].abs() - court.width / 2).clamp_min(0.0)
        turn = self.referee.may_hit
        horiz = (s.pos[..., :2] - s.ball_pos[:, None, :2]).norm(dim=-1)
        return {
            "drone_out_of_court": -0.2 * torch.sqrt(ex * ex + ey * ey),
            "success_hit": self.hit_reward * self.legal_hits(ev).float(),
            "dist_to_ball": turn.float() * 0.5 / (1.0 + horiz),
        }


class _TeamMatch(_Match):
    """3 vs 3 and 6 vs 6: possession rules, the out-of-court ball counts where it lands."""

    turn_mode = "possession"
    out_at_any_height = False
    episode_len = 500
    min_separation = 0.8
    reward_terms = ("win_or_lose", "drone_misbehave", "drone_collision", "success_hit", "dist_to_ball", "dist_to_anchor")
    shaping_terms = ("success_hit", "dist_to_ball", "dist_to_anchor")

    def observe(self):
        s = self.physics.state
        n, a = self.num_envs, self.n_drones
        return self.layout.build(
            root=self.own_root(),
            anchor=self.own(s.pos - self.anchors),
            ball=self.own(s.ball_pos.unsqueeze(1) - s.pos),
            ball_vel=self.own(s.ball_vel.unsqueeze(1).expand(-1, a, -1)),
            turn=flag_pair(self.my_turn()),
            id=one_hot(self.rank, self.team_size).expand(n, a, self.team_size),
            may_hit=flag_pair(self.referee.may_hit),
            positions=self.all_positions(),
        )

    def teammates_too_close(self):
        pos = self.physics.state.pos
        d = (pos.unsqueeze(2) - pos.unsqueeze(1)).norm(dim=-1)  # [N, A, A]
        return ((d < self.min_separation) & self.same_team).any(-1)

    def team_terms(self, ev, winner, crash, collide):
        s = self.physics.state
        team_hit = self.legal_hits(ev).float() @ self.team_onehot  # [N, 2] legal touches per team
        d_ball = (s.pos - s.ball_pos.unsqueeze(1)).norm(dim=-1)
        return {
            "drone_collision": collide.float() * MISBEHAVE,
            "success_hit": self.hit_reward * team_hit[:, self.team_ids],
            "dist_to_ball": self.referee.may_hit.float() * 0.5 / (1.0 + d_ball),
            "dist_to_anchor": 0.05 / (1.0 + self.anchor_distance()),
        }


class ThreeVsThree(_TeamMatch):
    name = "3v3"
    court = "3v3"
    team_size = 3
    anchors_xyz = both_sides(((3.0, -1.5, 2.0), (3.0, 1.5, 2.0), (6.0, 0.0, 2.0)))
    server_rank = 2  # the back drone
    obs_parts = team_match_parts(3)


class SixVsSix(_TeamMatch):
    name = "6v6"
    court = "full"  # the paper's appendix says 12 x 6; volleybots uses the full court
    team_size = 6
    anchors_xyz = both_sides(((3.0, -3.0, 2.0), (3.0, 0.0, 2.0), (3.0, 3.0, 2.0), (6.0, -3.0, 2.0), (9.0, 0.0, 2.0), (6.0, 3.0, 2.0)))
    server_rank = 4  # the (9, 0, 2) drone
    obs_parts = team_match_parts(6)
