"""Scripted Bump and Pass pair: each drone bumps the ball over to its partner when it is its turn."""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from volleybots.scripted.ballistics import crossing, launch_for_apex
from volleybots.scripted.control import Gains
from volleybots.scripted.lookahead import Lookahead
from volleybots.scripted.plan import quintic
from volleybots.scripted.players import (
    TouchConfig,
    _Player,
    apex_height,
    is_drop,
    with_z,
)
from volleybots.scripted.policies import SCRIPTED_POLICIES

FIRST_ANCHOR_XY = (4.5, -2.5)  # the ball is dropped from rest above drone 1's anchor


# --------------------------------------------------------------------------- Bump and Pass
@dataclass(frozen=True)
class PassConfig:
    inward: float = 1.75  # the drones play this much closer to each other than their anchors: less tilt
    apex: float = 4.1  # a bump counts when it crosses the midline above 4 m; passes met high peak 0.07 m higher (+- 0.06)
    # asked of the opening; it peaks ~0.5 m lower (the swing from rest falls short), above 4 m in ~72 % without the lookahead
    first_apex: float = 4.6
    first_to: float = 0.6  # |y| where the receiver waits during the drop
    first_aim: float = 0.9  # |y| the opening pass is aimed at: just past the midline (less racket tilt)
    # m (x, y) the opener's racket may meet the ball off its centre (radius 0.2): 0.08 or 0.15 gave body hits (the
    # lookahead tries more where the model says it is safe)
    first_slack: tuple[float, float] = (0.05, 0.1)
    fast: float = 2.0  # m/s: a ball crossing faster than this (the opening; passes cross at ~1.4) is met low, as a low one
    low_apex: float = 4.0  # a ball peaking below this (a weak opening, mostly: met high, it came back wild) ...
    far: float = 0.4  # ... or coming down farther than this from the spot ...
    low_z: float = 1.8  # ... is met with the drone this high: it falls longer, so there is time to get there
    low_pass_apex: float = 4.3  # passes from that low come out about 0.2 m below the apex asked
    cross_y: float = 0.1  # m past the midline a ball is met at least, where it comes down that far across above ...
    cross_floor: float = 1.0  # ... this drone height
    idle_z: float = 1.8  # height of the drone waiting for its turn behind a low pass: out of the ball's and the partner's way
    # ... behind a good pass (peaking above low_apex, coming down near the partner's spot): close under its next contact
    high_idle_z: float = 2.1
    # the lookahead (lookahead.py): the opening, and a pass met low, are chosen among variants tried on the model
    lookahead: bool = True  # off: the plain touches
    # s before the contact the opening's choosing starts: the whole fall (from 0.4 s, the swing's window, a drone starting
    # far off was already too late)
    look_time: float = 0.7
    # m (x, y) the racket-centre variants move (a grid)
    look_shift: tuple[tuple[float, ...], tuple[float, ...]] = ((0.0, -0.05, 0.05, -0.1, 0.1), (0.0, 0.05, 0.1))
    look_aim: tuple[tuple[float, ...], tuple[float, ...]] = ((0.0, -0.3, 0.3), (0.0, 0.3))  # m (x, y) the aim variants move (a grid)
    look_apex: tuple[float, ...] = (0.4,)  # m: the other asked apexes tried, above first_apex
    look_min_apex: float = 4.05  # m: a touch predicted to peak lower than this may not count
    look_max_apex: float = 4.4  # m: ... one peaking higher takes longer than the episode leaves for 14 bumps
    look_cross: float = 0.3  # m past the midline a touch must come down at least (it counts once across)
    look_passes: bool = True  # off: only the opening is chosen on the model
    look_pass_time: float = 0.5  # s before the contact a pass met low (after the opening or a bad pass) is chosen on the model
    look_pass_shift: tuple[float, ...] = (0.0, -0.1, 0.1)  # m the racket-centre variants of such a pass move along x and y (a grid)


# the receiver of a pass flies up to 2 m to the ball and must arrive still: it plans its braking with
# 2.5 m/s^2, not the default 4, which it overshoots (then the ball meets its body, not the racket)
PASS_GAINS = Gains(pos_accel_xy=2.5)
# the higher the ball is met, the shorter a pass (the metric counts bumps in 16 s), but the less time
# the receiver has to get under it: 2.6 m keeps nearly every episode going; CTBR, slower to tilt, 1.8 m
PASS_TOUCH = {"prt": TouchConfig(contact_z=2.6), "ctbr": TouchConfig(contact_z=1.8)}
# CTBR meets the ball at 1.8 m: its waiting drone is already under its next contact; choosing its
# passes met low on the model made it worse (8.5 bumps against 10.5 with the opening's lookahead only)
PASS_CFG = {"prt": PassConfig(), "ctbr": PassConfig(high_idle_z=1.8, look_passes=False)}
# the opening: drone 1 starts at rest up to 0.7 m off the ball's line and has the ball's 0.6 s fall to
# get under it and swing: it swings up over 0.4 s, the racket locked on its normal for the last 0.25 s
# (a 0.3 s lock made 7 % of the drones meet the ball with their body, against 1.5-4 %; a 0.5 s swing
# scattered the opening along x and the receiver missed it more often). Default gains: turns planned
# with 9 rad/s^2 made the opening count more often (81 % against 72 %) but ended more episodes early,
# and the receivers' gentler braking made no difference worth keeping
OPEN_GAINS = Gains()
# ... the lookahead may also fly it (and a pass met low) with steeper, quicker turns: a drone starting
# far from the ball's line arrives late (with these choices too, the opening counts in 85-89 % of episodes)
FAST_OPEN_GAINS = Gains(max_tilt=math.radians(40.0), att_accel=20.0, k_pos_xy=3.5, k_vel_xy=7.0, pos_accel_xy=6.0)
OPEN_TOUCH = TouchConfig(first_window=0.4, first_lock=0.25)


class _Opener(_Player):
    """Drone 1's touch of the dropped ball, swung up from the drone's own height.

    A fixed contact height (a fixed hold point under it) made the swing depend on where the drone
    starts (1.8 to 2.2 m): one starting high was still sinking to the hold point when the swing began,
    and its opening peaked up to 0.5 m lower. Here the contact is wherever the swing takes the drone: the
    hold point is its current height before the swing, and during it the height the quintic would
    have started from given where the drone is now; the contact is that plus the swing's rise
    (``contact_z``, a few fixed-point rounds with the plan's racket speed). Height errors therefore
    move the contact, not the racket's speed."""

    rounds = 3  # fixed-point rounds of contact height and racket speed
    z_range = (1.9, 2.6)  # drone centre height the contact is kept within

    def contact_z(self, drone, ball_p, ball_v, want_out):
        t = self.touch
        zc = drone.pos[..., 2] + 0.2
        for _ in range(self.rounds):
            strike = self.planner.plan(ball_p, ball_v, zc + self.planner.reach, want_out, t.max_tilt)
            vz, az = strike.drone_vel[..., 2:], strike.drone_acc[..., 2:]
            rise = vz * t.first_window / 2  # as ``hold_point``: a uniform acceleration from rest
            zero = torch.zeros_like(rise)
            window = torch.full_like(strike.t, t.first_window)
            done, _, _ = quintic(zero, zero, zero, rise, vz, az, window, (window - strike.t).clamp(min=0.0).minimum(window))
            zc = (drone.pos[..., 2:] - done + rise).squeeze(-1).clamp(*self.z_range)
        return strike

    def touch_drop(self, drone, ball_p, ball_v, want_out, wait, slack: tuple[float, float], shift=None) -> torch.Tensor:
        """The opening's action. The drone starts up to 0.7 m off the ball's line and has little
        time to get under it; one starting on its partner's side must first fly back behind it and
        arrives late and tilted the wrong way. Its racket's centre may stay up to ``slack`` (x, y) m
        off the ball on the drone's side: along x either way, along y only toward the partner (+y:
        the opener is drone 1). ``shift`` [..., 2] (a lookahead's variant) moves it further."""
        t = self.touch
        strike = self.contact_z(drone, ball_p, ball_v, want_out)
        off = drone.pos[..., :2] - strike.drone_pos[..., :2]
        sx = off[..., :1].clamp(-slack[0], slack[0])
        sy = off[..., 1:].clamp(0.0, slack[1])
        if shift is not None:
            sx, sy = sx + shift[..., :1], sy + shift[..., 1:]
        strike.drone_pos = strike.drone_pos + torch.cat((sx, sy, torch.zeros_like(sy)), -1)
        return self.strike_action(drone, strike, wait, t.first_window, t.first_lock, early=t.early, early_feed=t.early_feed)


class BumpAndPassPlayer(_Player):
    """Each drone bumps the ball over to its partner's spot when it is its turn, and otherwise waits
    at its own spot (its anchor moved ``inward`` toward the partner), low, or behind a good pass a
    little below its next contact.

    A pass is met high (``TouchConfig.contact_z``): the shorter the ball's fall, the more passes fit
    in an episode. A ball that will come down away from the spot or peaks low is met low instead,
    which leaves the receiver the time to get under it. The opening pass (of the ball dropped from
    rest, ``_Opener``) is aimed short, just past the midline, where the receiver waits for it during
    the drop, and asked high: a drone starting behind the ball (away from its partner) swings hard
    enough for it to count (above 4 m), one starting more than 0.25 m on its partner's side rarely.
    The receiver meets it low (it crosses fast: met high it came back wild), and lower still where
    it would otherwise meet it before it is across the midline (``cross_y``).

    Over the opening's whole fall the opener flies the best of ~360 variants of its touch (racket
    shift, aim, asked apex, quicker turns) tried on the world's model (``Lookahead``), and a pass
    met low (the opening's return, a bad pass's) the best of 18 in its last half second: those
    touches were what ended episodes early (a drone starting far off the ball's line met it with
    its body, or sent it where the receiver could not get)."""

    task = "bump_and_pass"

    def __init__(self, action_space="prt", params=None, gains=None, cfg: PassConfig | None = None,
                 touch: TouchConfig | None = None):
        super().__init__(action_space, params, gains or PASS_GAINS, touch or PASS_TOUCH.get(action_space, TouchConfig()))
        self.cfg = cfg or PASS_CFG.get(action_space, PassConfig())
        self.opener = _Opener(action_space, params, OPEN_GAINS, OPEN_TOUCH)
        self.fast_opener = _Opener(action_space, params, FAST_OPEN_GAINS, OPEN_TOUCH)
        self.fast = _Player(action_space, params, FAST_OPEN_GAINS, self.touch)
        self.lookahead = Lookahead(self.params, action_space)

    def opening(self, ball_p, ball_v, turn) -> torch.Tensor:
        """[...] the ball is the opening drop: drone 1's turn, still falling straight down over its
        anchor. (A slow pass alone is no drop: ``is_drop`` would take it for one.)"""
        anchor = torch.tensor(FIRST_ANCHOR_XY, dtype=ball_p.dtype, device=ball_p.device)
        still = is_drop(ball_v)  # ... and not enough: a slow pass is no drop
        over = (ball_p[..., :2] - anchor).norm(dim=-1) < 0.3
        return still & over & (ball_v[..., 2] <= 0.0) & (turn[..., 0] > 0.5)

    def act(self, drone, t):
        c, tc, g = self.cfg, self.touch, self.params.gravity
        anchor = drone.pos - t["anchor"]
        ball_p, ball_v = self.ball(drone, t)
        my_turn = (t["turn"] * t["id"]).sum(-1) > 0.5
        side = torch.sign(anchor[..., 1:2])  # -1 for drone 1, +1 for drone 2
        drop = self.opening(ball_p, ball_v, t["turn"])
        d = drop.unsqueeze(-1)
        spot_xy = torch.cat((anchor[..., :1], torch.where(d, side * c.first_to, anchor[..., 1:2] - side * c.inward)), -1)
        partner_xy = torch.cat((anchor[..., :1], torch.where(d, -side * c.first_aim, side * c.inward - anchor[..., 1:2])), -1)
        # a ball that comes down low or away from the spot is met low; the others high
        ball_apex = apex_height(ball_p, ball_v, g)
        landing, _ = crossing(ball_p, ball_v, tc.contact_z + self.planner.reach, g)
        low = (ball_apex < c.low_apex) | ((landing[..., :2] - spot_xy).norm(dim=-1) > c.far) | (ball_v[..., 1].abs() > c.fast)
        # behind a good pass the waiting drone stays high: its climb from 1.8 m to the next contact left it
        # still moving at the hold point (its passes peaked 4.25 +- 0.08 m; from 2.1 m, 4.16 +- 0.04, so
        # the asked apex is met and the cycle is 2 steps shorter); behind a bad one it keeps low, clear
        # of the ball that the partner chases
        good = (ball_apex >= c.low_apex) & ((landing[..., :2] - partner_xy).norm(dim=-1) < c.far)
        apex = torch.where(drop, c.first_apex, torch.where(low, c.low_pass_apex, c.apex))
        drone_z = torch.where(drop, tc.first_contact_z, torch.where(low, c.low_z, tc.contact_z))
        # a ball that would be met before it is across the midline (a weak opening, mostly) is met
        # lower, once across: met on the partner's side, neither it nor the return would count
        sy, reach = side[..., 0], self.planner.reach
        there, _ = crossing(ball_p, ball_v, drone_z + reach, g)
        t_x = (c.cross_y - sy * ball_p[..., 1]) / (sy * ball_v[..., 1]).clamp_min(1e-3)
        z_x = ball_p[..., 2] + ball_v[..., 2] * t_x - 0.5 * g * t_x**2 - reach
        wait_x = ~drop & (sy * there[..., 1] < c.cross_y) & (sy * ball_v[..., 1] > 0) & (t_x > 0) & (z_x >= c.cross_floor)
        drone_z = torch.where(wait_x, torch.minimum(drone_z, z_x), drone_z)
        land_z = tc.contact_z + reach

        def want_out(bp, bv):
            return launch_for_apex(bp, partner_xy, apex, land_z, g)

        wait = with_z(spot_xy, drone_z.unsqueeze(-1))
        opening = self.opener.touch_drop(drone, ball_p, ball_v, want_out, wait, c.first_slack)
        if c.lookahead:
            opening = self.look(opening, drop & my_turn, drone, ball_p, ball_v, want_out, wait, partner_xy, apex, land_z)
        # the opening is told apart by ``opening``, not by the ball's speed alone
        idle = with_z(spot_xy, torch.where(good, c.high_idle_z, c.idle_z).unsqueeze(-1))
        rest = self.play(drone, ball_p, ball_v, want_out, my_turn, wait, drop=drop, drone_z=drone_z, idle=idle)
        if c.lookahead and c.look_passes:
            rest = self.look_pass(rest, my_turn & ~drop & low, drone, ball_p, ball_v, wait, drone_z, partner_xy, apex, land_z)
        return torch.where((drop & my_turn).unsqueeze(-1), opening, rest)

    # ------------------------------------------------------------------ the lookahead
    def variants(self, ref: torch.Tensor) -> torch.Tensor:
        """[K, 6] opening variants (racket shift dx, dy, aim dx, dy, apex asked above first_apex, fast
        turns or not); the plain one first."""
        c = self.cfg
        kw = {"dtype": ref.dtype, "device": ref.device}
        aim = torch.cartesian_prod(torch.tensor(c.look_aim[0], **kw), torch.tensor(c.look_aim[1], **kw))
        shift = torch.cartesian_prod(torch.tensor(c.look_shift[0], **kw), torch.tensor(c.look_shift[1], **kw))
        apex = torch.tensor((0.0, *c.look_apex), **kw)
        fast = torch.tensor((0.0, 1.0), **kw)
        grid = torch.cartesian_prod(torch.arange(len(fast)), torch.arange(len(apex)), torch.arange(len(aim)), torch.arange(len(shift)))
        grid = grid.to(ref.device)
        return torch.cat((shift[grid[:, 3]], aim[grid[:, 2]], apex[grid[:, 1]].unsqueeze(-1), fast[grid[:, 0]].unsqueeze(-1)), -1)

    def opening_cost(self, o, *_) -> torch.Tensor:
        """Lower is better: how far from the receiver's spot the opening comes down, plus what keeps
        it from counting (no racket touch, too low, not across the midline)."""
        c, g = self.cfg, self.params.gravity
        p, v = o.ball_pos, o.ball_vel
        top = apex_height(p, v, g)
        down, _ = crossing(p, v, c.low_z + self.planner.reach, g)  # the receiver meets it low
        spot = torch.tensor((FIRST_ANCHOR_XY[0], c.first_aim), dtype=p.dtype, device=p.device)
        off = (down[..., :2] - spot).norm(dim=-1)
        short = (c.look_min_apex - top).clamp_min(0.0) + (c.look_cross - down[..., 1]).clamp_min(0.0)
        long = (top - c.look_max_apex).clamp_min(0.0)
        # one that does not cross costs the return's bump too (met on the opener's side, the return cannot cross)
        missed = 10.0 * (top < c.look_min_apex).float() + 20.0 * (down[..., 1] < c.look_cross).float()
        return off + 20.0 * short + 5.0 * long + missed + 100.0 * (~o.hit | o.body).float()

    def look(self, plain, now, drone, ball_p, ball_v, want_out, wait, partner_xy, apex, land_z):
        """The opening ``plain``, or in its last ``look_time`` seconds (where ``now``) its best variant on the model."""
        c, g = self.cfg, self.params.gravity
        strike = self.opener.contact_z(drone, ball_p, ball_v, want_out)
        now = now & strike.valid & (strike.t > 0) & (strike.t < c.look_time)

        def fly(d, bp, bv, wait, aim, apex, var):
            def out(p, v):
                return launch_for_apex(p, aim + var[..., 2:4], apex[..., 0] + var[..., 4], land_z, g)
            plain = self.opener.touch_drop(d, bp, bv, out, wait, c.first_slack, var[..., :2])
            fast = self.fast_opener.touch_drop(d, bp, bv, out, wait, c.first_slack, var[..., :2])
            return torch.where(var[..., 5:] > 0.5, fast, plain)

        return self.lookahead.refine(plain, now, strike.t, drone, ball_p, ball_v, self.variants(ball_p), fly,
                                     self.opening_cost, context=(wait, partner_xy, apex.unsqueeze(-1)))

    def pass_variants(self, ref: torch.Tensor) -> torch.Tensor:
        """[K, 3] variants of a pass met low (racket shift dx, dy, fast turns or not); the plain one first."""
        kw = {"dtype": ref.dtype, "device": ref.device}
        shift = torch.tensor(self.cfg.look_pass_shift, **kw)
        fast = torch.tensor((0.0, 1.0), **kw)
        grid = torch.cartesian_prod(fast, shift, shift)
        return grid[:, [2, 1, 0]]

    def pass_cost(self, o, partner_xy: torch.Tensor, side: torch.Tensor) -> torch.Tensor:
        """As ``opening_cost`` for a pass to ``partner_xy`` [M, 2], whose side of the midline is ``side`` [M] (+-1)."""
        c, g = self.cfg, self.params.gravity
        p, v = o.ball_pos, o.ball_vel
        top = apex_height(p, v, g)
        down, _ = crossing(p, v, self.touch.contact_z + self.planner.reach, g)
        off = (down[..., :2] - partner_xy).norm(dim=-1)
        short = (c.look_min_apex - top).clamp_min(0.0) + (c.look_cross - side * down[..., 1]).clamp_min(0.0)
        return off + 20.0 * short + 10.0 * (top < c.look_min_apex).float() + 100.0 * (~o.hit | o.body).float()

    def look_pass(self, plain, now, drone, ball_p, ball_v, wait, drone_z, partner_xy, apex, land_z):
        """The pass ``plain``, or in its last ``look_pass_time`` seconds (where ``now``) its best
        variant on the model: a ball met low comes from a bad touch, and its receiver has far to fly."""
        c, t, g = self.cfg, self.touch, self.params.gravity
        contact_z = self.contact_height(ball_p, ball_v, torch.zeros_like(now), drone_z)
        strike = self.planner.plan(ball_p, ball_v, contact_z, lambda p, v: v, t.max_tilt)
        now = now & strike.valid & (strike.t > 0) & (strike.t < c.look_pass_time)

        def fly(d, bp, bv, wait, dz, aim, apex, var):
            def out(p, v):
                return launch_for_apex(p, aim, apex[..., 0], land_z, g)
            contact_z = self.contact_height(bp, bv, torch.zeros_like(dz[..., 0], dtype=torch.bool), dz[..., 0])
            s = self.planner.plan(bp, bv, contact_z, out, t.max_tilt)
            s.drone_pos = s.drone_pos + torch.cat((var[..., :2], torch.zeros_like(var[..., :1])), -1)
            args = (d, s, wait, t.window, t.lock)
            kw = {"early": t.early, "early_feed": t.early_feed}
            return torch.where(var[..., 2:] > 0.5, self.fast.strike_action(*args, **kw), self.strike_action(*args, **kw))

        return self.lookahead.refine(plain, now, strike.t, drone, ball_p, ball_v, self.pass_variants(ball_p), fly,
                                     lambda o, wait, dz, aim, apex: self.pass_cost(o, aim, torch.sign(aim[..., 1])),
                                     context=(wait, drone_z.unsqueeze(-1), partner_xy, apex.unsqueeze(-1)))


SCRIPTED_POLICIES.update({cls.task: cls for cls in (BumpAndPassPlayer,)})
