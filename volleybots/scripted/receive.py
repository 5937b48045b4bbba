"""A 1 vs 1 scripted player that also receives deep, flat serves: the ``receiver`` built-in player.

The match player (match.py) meets every ball where it comes down through its contact height (the
drone at 2.6 m). A flat, deep serve (the ace of ``zoo:1v1/sp_noanchor``: apex about 2.9 m, landing
about 2.4 m behind the net) comes down through that height less than a metre behind the net, where
the match player lets balls go (it keeps clear of the net), so it never plays it
(docs/evaluation.md, "What the ace is").

This player meets such a ball lower and deeper: where its flight reaches ``meet_x`` metres behind the
net, the drone no lower than ``min_z`` (docs/receive.md). The flight is planned for a steep, fast
ball: the drone flies along x and y straight to the contact point as soon as the ball is on its way
(``early``), so it has arrived and settled before the ball comes down, and only the vertical axis
runs the timed approach that gives the racket its speed; the racket meets the ball with its face,
not the front of its body, because the drone is no longer closing on the ball sideways when it
arrives. Every other ball it plays as the match player does, so it serves, sets and attacks alike.

Balls that would land out of the court are let go (touching one makes it the receiver's).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from volleybots.rules import COURTS
from volleybots.scripted.ballistics import crossing, launch_for_apex, time_to_height
from volleybots.scripted.lookahead import Lookahead, variant_rows
from volleybots.scripted.match import OneVsOnePlayer
from volleybots.scripted.players import is_drop
from volleybots.scripted.policies import SCRIPTED_POLICIES


@dataclass(frozen=True)
class DeepConfig:
    meet_x: float = 1.4  # m behind the net where a deep ball is met (its flight reaches this depth)
    min_z: float = 1.2  # m: the drone's centre is no lower than this at the contact
    early: tuple[int, ...] = (0, 1)  # world axes flown straight to the contact point for a deep ball
    wait_z: float | None = 2.0  # m: the drone's height while it waits (None: the match player's contact height)
    window: float = 0.5  # s of the timed vertical approach into a deep contact
    lock: float = 0.35  # s before a deep contact the racket is locked on its planned normal
    depth: float = 0.5  # a deep ball's return comes down this fraction of the opponent's half length from the net
    # the lookahead (lookahead.py): in its last ``look_time`` s the deep touch is chosen among variants tried on the model
    lookahead: bool = False  # tried: on the ace it returned 4 of 40 (19 body hits) against 6 of 40 without (docs/receive.md)
    look_time: float = 0.6  # s before the contact the search starts
    look_apex: tuple[float, ...] = (0.0, 1.0)  # m added to the return's apex
    look_lock: tuple[float, ...] = (0.3, 0.35, 0.4)  # s: the racket's lock before the contact
    look_dx: tuple[float, ...] = (0.0, 0.2, -0.2)  # m: the contact moved deeper
    look_after: int = 10  # control steps after the touch the rollout goes on (the drone must not fly into the net)
    net_margin: float = 0.15  # m: the return's ball centre passes the net this far above its top plus the ball's radius


class OneVsOneReceiver(OneVsOnePlayer):
    """The 1 vs 1 match player, meeting deep balls lower (module docstring)."""

    def __init__(self, action_space="prt", params=None, gains=None, cfg=None, touch=None, deep: DeepConfig | None = None):
        super().__init__(action_space, params, gains, cfg, touch)
        self.deep = deep or DeepConfig()
        court = COURTS[self.task_cls.court]
        self.half_width = court.width / 2
        self.lookahead = Lookahead(self.params, action_space)

    def deep_height(self, ball_p, ball_v, dx=None) -> torch.Tensor:
        """[...] the drone's height where the ball's flight reaches ``meet_x`` (a point of its parabola,
        so the same all along the flight; ``dx`` [...] metres deeper), within [``min_z``, the match
        player's contact height]."""
        d, g = self.deep, self.params.gravity
        meet_x = d.meet_x if dx is None else d.meet_x + dx
        t = (meet_x - ball_p[..., 0]) / ball_v[..., 0].clamp_min(1e-3)
        z = ball_p[..., 2] + ball_v[..., 2] * t - 0.5 * g * t * t
        return (z - self.planner.reach).clamp(min=d.min_z, max=self.touch.contact_z)

    def meet_height(self, drone, ball_p, ball_v, ours):
        c, g = self.cfg, self.params.gravity
        plain = torch.where(is_drop(ball_v), self.touch.first_contact_z, self.touch.contact_z)  # the match player's heights
        fall, _ = crossing(ball_p, ball_v, self.contact_height(ball_p, ball_v), g)
        land, _ = crossing(ball_p, ball_v, self.params.ball.radius, g)
        in_court = (land[..., 0] <= self.half_length) & (land[..., 1].abs() <= self.half_width)
        # a ball going deeper that the match player would let go (it comes down by the net)
        deep = ours & (ball_v[..., 0] > 0) & (fall[..., 0] <= c.guard_x + c.reach_margin) & in_court
        return torch.where(deep, self.deep_height(ball_p, ball_v), plain)

    def deep_strike(self, ball_p, ball_v, apex_up=None, dx=None):
        """The plan of a deep touch: met at ``deep_height``, returned over an apex ``apex_up`` [...]
        higher than the match player's, to come down ``depth`` of the way into the opponent's half."""
        c, d, g = self.cfg, self.deep, self.params.gravity
        contact_z = self.contact_height(ball_p, ball_v, drone_z=self.deep_height(ball_p, ball_v, dx))
        apex = torch.maximum(torch.as_tensor(2.43 + c.net_clear), contact_z + 0.5)
        if apex_up is not None:
            apex = apex + apex_up

        def want_out(bp, bv):
            target = torch.stack((torch.full_like(bp[..., 0], -d.depth * self.half_length), bp[..., 1]), -1)
            return launch_for_apex(bp, target, apex, 0.2, g)

        return self.planner.plan(ball_p, ball_v, contact_z, want_out, self.touch.max_tilt)

    def deep_action(self, drone, ball_p, ball_v, home, variant=None):
        """The deep touch's action: x and y flown straight to the contact point, the vertical timed;
        ``variant`` [..., 3] (a lookahead's): apex raised by its value 0, the racket locked its value 1 s
        early, met its value 2 metres deeper."""
        d = self.deep
        strike = self.deep_strike(ball_p, ball_v, *((None, None) if variant is None else (variant[..., 0], variant[..., 2])))
        lock = d.lock if variant is None else variant[..., 1]
        return self.strike_action(drone, strike, home, d.window, lock, early=d.early, early_feed=False)

    def deep_cost(self, o, *_) -> torch.Tensor:
        """Lower is better: metres from the aim where the return lands, plus 10 for each way it fails
        (not over the net with ``net_margin`` to spare, out of the court, the drone at the net) and 30
        for no racket touch or a body touch first."""
        c, d, g = self.cfg, self.deep, self.params.gravity
        p, v = o.ball_pos, o.ball_vel
        t_net = p[..., 0] / (-v[..., 0]).clamp_min(1e-3)
        z_net = p[..., 2] + v[..., 2] * t_net - 0.5 * g * t_net**2
        t = time_to_height(p[..., 2], v[..., 2], self.params.ball.radius, g)
        land = p[..., :2] + v[..., :2] * t.nan_to_num(posinf=10.0).unsqueeze(-1)
        aim = torch.stack((torch.full_like(land[..., 0], -d.depth * self.half_length), torch.zeros_like(land[..., 0])), -1)
        off = (land - aim).norm(dim=-1)
        over = (v[..., 0] < 0) & (z_net > 2.43 + self.params.ball.radius + d.net_margin)
        inside = (land[..., 0] > -self.half_length) & (land[..., 0] < 0) & (land[..., 1].abs() < self.half_width)
        lost = (~over).float() + (~inside).float() + (o.min_x_low < c.guard_x / 2).float()
        return off + 10.0 * lost + 30.0 * (~o.hit | o.body).float()

    def fly(self, drone, ball_p, ball_v, want_out, mine, home, drone_z):
        if self.deep.wait_z is not None:
            home = torch.cat((home[..., :2], torch.full_like(home[..., 2:], self.deep.wait_z)), -1)
        plain = self.play(drone, ball_p, ball_v, want_out, mine, home, drone_z=drone_z)
        deep = (drone_z < self.touch.contact_z) & ~is_drop(ball_v)
        if not bool(deep.any()):
            return plain
        low = self.deep_action(drone, ball_p, ball_v, home)
        d = self.deep
        if d.lookahead:
            s = self.deep_strike(ball_p, ball_v)
            now = deep & mine & s.valid & (s.t > 0) & (s.t < d.look_time)
            kw = {"dtype": ball_p.dtype, "device": ball_p.device}
            variants = variant_rows(torch.tensor(d.look_apex, **kw), torch.tensor(d.look_lock, **kw), torch.tensor(d.look_dx, **kw))
            low = self.lookahead.refine(low, now, s.t, drone, ball_p, ball_v, variants, self._variant_action, self.deep_cost,
                                        context=(home,), after=self._after, after_steps=d.look_after)
        return torch.where(deep.unsqueeze(-1), low, plain)

    def _after(self, drone, ball_p, ball_v):
        """After the touch: back to the anchor's depth, level (what the match player does once the ball is gone)."""
        home = torch.tensor((self.anchors[0][0], 0.0, self.deep.wait_z or self.touch.contact_z), dtype=ball_p.dtype, device=ball_p.device)
        home = torch.cat((home[:1].expand_as(drone.pos[..., :1]), drone.pos[..., 1:2], home[2:].expand_as(drone.pos[..., :1])), -1)
        return self.ctrl.act(drone, home, torch.zeros_like(home))

    def _variant_action(self, drone, ball_p, ball_v, home, variant):
        return self.deep_action(drone, ball_p, ball_v, home, variant)


class ReceiveDrillPlayer(OneVsOneReceiver):
    """The receiver on the receive drill (tasks/receive.py), whose observation is the 1 vs 1 match's."""


ReceiveDrillPlayer.task = "receive"  # (set after the class: the match players take their task's name when defined)
SCRIPTED_POLICIES[ReceiveDrillPlayer.task] = ReceiveDrillPlayer

__all__ = ["DeepConfig", "OneVsOneReceiver", "ReceiveDrillPlayer"]
