"""Scripted Set and Spike pair (Easy and Hard): the setter sets, the attacker spikes into the target.

The set is a ``_Player`` strike of the dropped ball, or a glide into it (``set_action``), as high as
a half-second swing from rest gives (apex ~4.8 m); the setter picks among aims, flights and contact
heights on the world's model (``setting``). The spike is a "throw" (``SetAndSpikePlayer.spike_action``): it needs 50-60 deg of
racket tilt, which a drone cannot hold still, so the attacker hovers where a constant thrust along
the racket's normal carries it into the contact point and flies that throw, closed-loop along the
normal (the racket's speed) and in the racket's plane (where the ball meets it)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import torch

from volleybots.scripted.ballistics import launch_for_apex, time_to_height
from volleybots.scripted.control import DroneController, Gains
from volleybots.scripted.lookahead import Lookahead, variant_rows
from volleybots.scripted.plan import goto_accel, off_centre
from volleybots.scripted.players import TouchConfig, _Player, apex_height
from volleybots.scripted.policies import SCRIPTED_POLICIES


# --------------------------------------------------------------------------- Set and Spike
def grid_5x5(ref: torch.Tensor) -> torch.Tensor:
    """[25, 2] unit steps -2..2 in x and y, (0, 0) first (a lookahead's plain touch goes first)."""
    steps = torch.tensor((0.0, -1.0, 1.0, -2.0, 2.0), dtype=ref.dtype, device=ref.device)
    return torch.cartesian_prod(steps, steps)


# the setter meets the drop a little higher than the default, with a shorter lock: a truer set
SET_TOUCH = TouchConfig(first_contact_z=2.7, first_window=0.4, first_lock=0.2, early=())


@dataclass(frozen=True)
class SpikeConfig:
    # the set
    set_apex: float = 4.8  # the set's apex (the setter swings from rest in half a second: it cannot set much higher)
    set_slack: float = 0.1  # m off the racket's centre the setter may meet the drop
    set_att_accel: float = 12.0  # rad/s^2 the setter plans its turns with (the racket's tilt at the contact sets the set's direction)
    # the setter's lookahead may also glide sideways into the contact (least effort), not stop there (off: the plain strike only)
    set_glide: bool = True
    set_nav: float = 3.0  # the glide's guidance gain on the miss (3: the least-effort law)
    set_nav_min: float = 0.15  # s: the glide's steering time (to the lock) is taken as this at least (near its end the law grows stiff)
    # the spike
    # where the attacker meets the set (drone centre; above the net's top, so beside the net is no fault)
    attack_spot: tuple[float, float, float] = (1.2, -1.0, 3.3)
    target: tuple[float, float] = (-4.5, 0.0)  # where the spike should land
    short: float = 0.5  # m short of the target the spike aims (the near side of the target circle)
    land_z: float = 0.2  # the ball lands when its centre is this low
    spike_vz: float = -0.6  # m/s the spike leaves with downward: barely (the fall time is the range)
    max_tilt: float = math.radians(60.0)  # racket tilt at most
    apex_margin: float = 0.3  # a set peaking below the attack height is met this far under its apex
    throw: float = 0.25  # s of the spike's throw: constant thrust along the racket's normal into the contact
    lead: float = 0.15  # s the turn to the normal starts before the throw (the attitude takes time)
    throw_kp: float = 40.0  # 1/s^2: position gain in the racket's plane during the throw
    throw_kd: float = 12.0  # 1/s: its speed gain
    throw_fix: float = 4.0  # m/s^2 of correction at most
    lock: float = 0.14  # s before the contact the racket is left on its normal
    min_thrust: float = 3.0  # m/s^2 of specific thrust in the throw at least (the attitude needs some)
    max_thrust: float = 15.5  # ... and at most (the airframe's maximum is 15.8)
    rush_accel: float = 8.0  # m/s^2 the attacker flies to its spot with
    rush_brake: float = 4.0  # m/s^2 it plans to brake with
    rush_speed: float = 6.0  # m/s at most
    rush_lead: float = 0.3  # s: it plans the braking this early (turning the thrust around takes that long)
    rush_tilt: float = math.radians(45.0)  # the attacker's tilt limit when it flies
    recover_att_accel: float = 35.0  # rad/s^2 the attacker plans its turn out of the throw with (the Iris can do about 35)
    min_x: float = 0.7  # m: the set is met no closer to the net than this (the spike's tilt carries the drone toward it)
    # where the attacker flies after the spike, from the attack spot: back, and up (over the net's top)
    retreat: tuple[float, float, float] = (1.5, 0.0, 1.0)
    net_x: float = 0.2  # m: after its touch the attacker turns hard away where it would be closer to the net than this ...
    net_look: float = 0.25  # s ... this soon (a drone across the net, x < 0, is a fault at any height)
    # m: ... and climbs to this height at least (by the net and below its top is a fault too; 3.0 left it sinking onto the net)
    off_net_z: float = 3.5
    wait_dz: float = 0.0  # m above the attack spot the attacker waits for the set
    # m (x, y) the racket's centre is aimed off the ball: back from the net, and ahead of the attacker, which comes from +y
    # and lags
    offset: tuple[float, float] = (0.05, -0.1)
    # the lookahead (lookahead.py): the last moments of the throw are chosen among variants tried on the model
    lookahead: bool = True  # off: the plain throw
    look_time: float = 0.5  # s before the contact the choosing starts (the turn into the throw and the throw take 0.4 s)
    set_lookahead: bool = True  # the setter chooses its set on the model too (off: the plain set)
    set_look_time: float = 0.5  # s before the set the setter starts choosing among sets aimed around the attack spot
    # m the set's contact may move down (a setter that starts high has no room to swing up into it)
    set_look_dz: tuple[float, ...] = (0.0, -0.25)
    set_low_cost: float = 2.0  # per metre the set peaks under ``set_apex`` (as against per metre off the spot)
    # m nearer the net a set should come down per metre it peaks under ``set_apex`` (it falls slowly, so is spiked slower:
    # from nearer the net it still reaches the target)
    set_low_near: float = 0.6
    set_look_aim: float = 0.5  # m between those aims (a 5 x 5 grid)
    look_aim: float = 0.3  # m between the aim variants (a 5 x 5 grid around the aim)
    # m/s added to the spike's planned vz (the throw sinks: a spike planned steeper comes out downward)
    look_vz: tuple[float, ...] = (0.0, -0.6)
    look_dz: tuple[float, ...] = (0.0, -0.25)  # m the contact may move down (a set that peaks low falls slowly: met lower, it is faster)
    look_offset: float = 0.06  # m the racket-centre variants move in its plane
    look_near: float = 1.0  # m: a ball this close with no plan left (met late) is still chosen on the model
    look_inside: float = 0.6  # m from the target's centre a spike counts as surely in (the target's radius is 1 m)
    look_after: int = 15  # control steps flown past the contact (the throw must not carry the drone into the net)
    look_margin: float = 0.15  # m: the variant's drone must stay this far back from the net
    net_height: float = 2.43  # m: the ball's centre must pass the net's zone above this


class SetAndSpikePlayer(_Player):
    """Drone 1 (the setter) sets the dropped ball as high as it can swing to the attack spot; drone 2
    (the attacker) flies there and meets the set as it comes down, sending it to the near side of
    the target barely downward.

    The racket's normal is along the ball's change of velocity, so its tilt is ``atan(horizontal
    change / vertical change)``: the spike needs ~7 m/s toward -x and leaves barely falling, so the
    vertical change is the set's fall speed at the attacker (~6 m/s) and the racket tilts ~50 deg.
    A drone cannot hold such a tilt still, so the attacker throws itself into the contact (see
    ``spike_action``). The attack spot is on the setter's side of y = 0, so the set already carries
    the ball a little toward the target, and near the net (a shorter spike), but not so near that
    the throw, which carries the drone toward the net, ends across it before the ball lands."""

    task = "set_and_spike_easy"

    def __init__(self, action_space="prt", params=None, gains=None, cfg: SpikeConfig = SpikeConfig(), touch: TouchConfig = SET_TOUCH):
        # the setter's swing and the attacker's throw need the airframe's full thrust
        super().__init__(action_space, params, gains or Gains(thrust_margin=1.0, max_climb=6.0), touch)
        self.cfg = cfg
        # the attacker crosses the court to its spot and throws itself into the spike: steeper tilts
        self.attack_ctrl = DroneController(self.params, action_space, replace(self.ctrl.gains, max_tilt=cfg.rush_tilt))
        # ... and, after the spike, turns out of its throw as fast as the airframe can
        recover = replace(self.ctrl.gains, max_tilt=cfg.rush_tilt, att_accel=cfg.recover_att_accel)
        self.recover_ctrl = DroneController(self.params, action_space, recover)
        self.ctrl = DroneController(self.params, action_space, replace(self.ctrl.gains, att_accel=cfg.set_att_accel))
        self.lookahead = Lookahead(self.params, action_space)

    # ------------------------------------------------------------------ the set
    def set_action(self, drone, ball_p, ball_v, want_out, wait, glide=None, dz=None):
        """The setter's touch of the dropped ball (``_Player.play`` for the drop), met up to
        ``set_slack`` off the racket's centre on the drone's side: the drone starts up to 0.7 m
        off the ball's line, and the less it has to fly sideways, the more level its racket is at
        the contact, so the more accurate the set. ``glide`` [...] (a lookahead variant's): glide
        into the contact instead of the plain strike; ``dz`` [...]: meet the drop that much higher."""
        t, c = self.touch, self.cfg
        z = self.contact_height(ball_p, ball_v)
        if dz is not None:
            z = z + dz
        strike = self.planner.plan(ball_p, ball_v, z, want_out, t.max_tilt)
        strike = off_centre(strike, drone.pos, c.set_slack)
        plain = self.strike_action(drone, strike, wait, t.first_window, t.first_lock, early=t.early)
        if glide is None:
            return plain
        # the racket is frictionless, so the drone may pass through the contact point moving in the
        # racket's plane; what it must not do is still be braking there (braking tilts it off the
        # racket's normal, and 1 degree of tilt moves the set ~0.25 m). Gliding, it steers sideways
        # by the least-effort law onto the contact point, done by the lock, and ends with the
        # contact's own acceleration; vertically it keeps the timed approach (the racket's speed).
        tg = strike.t.unsqueeze(-1)
        a_end = strike.drone_acc[..., :2]
        miss = strike.drone_pos[..., :2] - drone.pos[..., :2] - drone.vel[..., :2] * tg - 0.5 * a_end * tg * tg
        lock = t.first_lock
        tp = (tg - lock).clamp_min(c.set_nav_min)
        lateral = a_end + c.set_nav * miss / (tp * tp + 2.0 * tp * lock)
        glider = self.strike_action(drone, strike, wait, t.first_window, lock, early=t.early, lateral=lateral)
        return torch.where(glide.unsqueeze(-1), glider, plain)

    def attack_ball(self, ref: torch.Tensor) -> torch.Tensor:
        """[3] where the set should come down: the ball's centre at the attack spot."""
        spot = torch.tensor(self.cfg.attack_spot, dtype=ref.dtype, device=ref.device)
        return spot + torch.tensor((0.0, 0.0, self.planner.reach), dtype=ref.dtype, device=ref.device)

    def set_velocity(self, bp, bv, variant=None):
        """The set [..., 3]: through ``set_apex`` down onto the attack spot, moved by the first two
        values of ``variant`` (a lookahead's)."""
        a = self.attack_ball(bp)
        target = a[:2] if variant is None else a[:2] + variant[..., :2]
        return launch_for_apex(bp, target, self.cfg.set_apex, a[2], self.params.gravity)

    def set_cost(self, o, *_) -> torch.Tensor:
        """Metres from the attack spot where the set comes down through the attack height (the spot
        moved toward the net for a set that peaks low, ``set_low_near``); a miss or a body touch
        costs far more."""
        a = self.attack_ball(o.ball_pos)
        t = time_to_height(o.ball_pos[..., 2], o.ball_vel[..., 2], a[2], self.params.gravity).nan_to_num(posinf=10.0)
        where = o.ball_pos[..., :2] + o.ball_vel[..., :2] * t.unsqueeze(-1)
        # a set under its apex falls slower at the attacker, and the spike then needs more tilt than it may take
        low = (self.cfg.set_apex - apex_height(o.ball_pos, o.ball_vel, self.params.gravity)).clamp_min(0.0)
        spot = a[:2] - torch.stack((self.cfg.set_low_near * low, torch.zeros_like(low)), -1)
        return (where - spot).norm(dim=-1) + self.cfg.set_low_cost * low + 100.0 * (~o.hit | o.body)

    def setting(self, drone, ball_p, ball_v, wait, mine):
        """The setter's action: the plain set, or in its last ``set_look_time`` seconds the best of
        the sets aimed around the attack spot, tried on the model (``mine`` [...]: the setters)."""
        c = self.cfg
        plain = self.set_action(drone, ball_p, ball_v, self.set_velocity, wait)
        if not c.set_lookahead:
            return plain
        s = self.planner.plan(ball_p, ball_v, self.contact_height(ball_p, ball_v), self.set_velocity, self.touch.max_tilt)
        now = mine & s.valid & (s.t > 0) & (s.t < c.set_look_time)
        # variants: aim (dx, dy) x flight (plain, glide) x contact height
        kw = {"dtype": ball_p.dtype, "device": ball_p.device}
        variants = variant_rows(grid_5x5(ball_p) * c.set_look_aim, torch.tensor((0.0, 1.0) if c.set_glide else (0.0,), **kw),
                                torch.tensor(c.set_look_dz, **kw))

        def fly(d, p, v, w, var):
            return self.set_action(d, p, v, lambda bp, bv: self.set_velocity(bp, bv, var), w, var[..., 2] > 0.5, var[..., 3])

        return self.lookahead.refine(plain, now, s.t, drone, ball_p, ball_v, variants, fly, self.set_cost, context=(wait,))

    # ------------------------------------------------------------------ the spike
    def spike(self, bp, bv, aim=None, dvz=None):
        """Outgoing velocity [..., 3]: down at ``spike_vz`` (plus ``dvz`` [...]), landing ``short`` of
        the target (moved by ``aim`` [..., 2]); ``aim`` and ``dvz`` come from a lookahead variant."""
        c = self.cfg
        target = torch.tensor(c.target, dtype=bp.dtype, device=bp.device)
        if aim is not None:
            target = target + aim
        d = target - bp[..., :2]
        dist = d.norm(dim=-1, keepdim=True)
        aim = d * ((dist - c.short) / dist.clamp_min(1e-6))
        vz = torch.full_like(bp[..., 2], c.spike_vz)
        if dvz is not None:
            vz = vz + dvz
        t = time_to_height(bp[..., 2], vz, c.land_z, self.params.gravity).clamp_min(0.05)
        vh = aim / t.unsqueeze(-1)
        # the racket tilts along the change of velocity: past ``max_tilt`` the spike gives up range,
        # not its way down
        dv = vh - bv[..., :2]
        cap = math.tan(c.max_tilt) * (vz - bv[..., 2]).clamp_min(0.0)
        vh = bv[..., :2] + dv * (cap / dv.norm(dim=-1).clamp_min(1e-9)).clamp(max=1.0).unsqueeze(-1)
        return torch.cat((vh, vz.unsqueeze(-1)), -1)

    def spike_height(self, ball_p, ball_v):
        """Ball-centre height [...] of the spike: the attack height, or higher where the set comes
        down closer to the net than ``min_x`` there (met earlier, the ball is further back), or
        lower for a set that does not come up to it."""
        c, g = self.cfg, self.params.gravity
        z = torch.full_like(ball_p[..., 2], c.attack_spot[2] + self.planner.reach)
        vx = ball_v[..., 0]
        t_x = (c.min_x - ball_p[..., 0]) / vx.clamp(max=-1e-6)  # when the ball passes min_x
        z_x = ball_p[..., 2] + ball_v[..., 2] * t_x - 0.5 * g * t_x * t_x
        late = (vx < 0) & (t_x > ball_v[..., 2] / g)  # passes min_x on the way down
        z = torch.where(late, torch.maximum(z, z_x), z)
        return torch.minimum(z, apex_height(ball_p, ball_v, g) - c.apex_margin)

    def spike_action(self, drone, ball_p, ball_v, wait, variant=None):
        """The attacker's touch, a throw: the drone hovers at the point from which a constant
        thrust along the racket's normal carries it into the contact point in ``throw`` seconds,
        then turns to that normal and holds it. A tilted racket cannot be held still (its thrust
        pushes the drone sideways), so the throw makes that push part of the plan. Along the
        normal the thrust is closed-loop: whatever the turn cost, it is the thrust that brings the
        racket's normal speed to the planned one at the contact. ``variant`` [..., 6] (a
        lookahead's, ``variants``): the aim moved by its values 0-1, the racket's offset by 2-3, the
        spike's planned vz by 4 and the contact's height by 5."""
        c, g = self.cfg, self.params.gravity
        aim = None if variant is None else variant[..., :2]
        dvz = None if variant is None else variant[..., 4]
        z = self.spike_height(ball_p, ball_v)
        if variant is not None:
            z = z + variant[..., 5]
        s = self.planner.plan(ball_p, ball_v, z, lambda bp, bv: self.spike(bp, bv, aim, dvz), c.max_tilt)
        n = s.normal
        nz = n[..., 2].clamp_min(0.3)
        # the racket's centre is aimed ``offset`` (in its plane) from the ball
        off = torch.zeros_like(n)
        off[..., :2] = torch.tensor(c.offset, dtype=n.dtype, device=n.device)
        if variant is not None:
            off[..., :2] = off[..., :2] + variant[..., 2:4]
        p_c = s.drone_pos + off - (off * n).sum(-1, keepdim=True) * n
        # the throw's constant thrust gives the racket its normal speed from rest
        tau = c.throw
        thrust0 = (g * nz + s.speed / tau).clamp(c.min_thrust, c.max_thrust)
        acc = thrust0.unsqueeze(-1) * n
        acc = torch.cat((acc[..., :2], acc[..., 2:] - g), -1)
        start = p_c - 0.5 * tau**2 * acc
        t_go = s.t.clamp_min(self.params.dt)
        # along the normal: the constant-jerk law that arrives at the contact point with the planned
        # normal speed (the turn into the throw costs some of both)
        gap = ((p_c - drone.pos) * n).sum(-1)
        t_n = t_go.clamp_min(c.lock)
        a_n = 6.0 * gap / t_n**2 - (4.0 * (drone.vel * n).sum(-1) + 2.0 * s.speed) / t_n
        thrust = (g * nz + a_n).clamp(c.min_thrust, c.max_thrust)
        throw_f = thrust.unsqueeze(-1) * n
        # in the racket's plane the throw follows its ideal path (the turn lags it), but leaves the
        # racket on its normal for the last moments
        tt = t_go.unsqueeze(-1).clamp(max=tau)
        err = p_c - acc * (tau * tt - 0.5 * tt * tt) - drone.pos
        verr = acc * (tau - tt) - drone.vel
        fix = c.throw_kp * err + c.throw_kd * verr
        fix = fix - (fix * n).sum(-1, keepdim=True) * n
        fix = fix * (c.throw_fix / fix.norm(dim=-1, keepdim=True).clamp_min(1e-9)).clamp(max=1.0)
        throw_f = throw_f + torch.where((s.t > c.lock).unsqueeze(-1), fix, torch.zeros_like(fix))
        ctrl = self.attack_ctrl
        # a ball that will not come down to the contact height, or has passed it: wait
        valid = s.valid & (s.t > 0)
        hover = ctrl.thrust_vector(drone, ctrl.position_accel(drone, start, torch.zeros_like(start)))
        far = self.rush(drone, torch.where(valid.unsqueeze(-1), start, wait))
        near = ((drone.pos - start).norm(dim=-1) < 0.3) & valid
        f = torch.where(near.unsqueeze(-1), hover, far)
        f = torch.where((valid & (s.t < tau + c.lead)).unsqueeze(-1), throw_f, f)
        return ctrl.act_thrust(drone, f)

    def after_touch(self, drone):
        """The attacker once its touch is done: out of the throw as fast as the airframe turns, to
        the retreat point, or straight back where it is about to reach the net."""
        c = self.cfg
        attack = torch.tensor(c.attack_spot, dtype=drone.pos.dtype, device=drone.pos.device)
        retreat = (attack + torch.tensor(c.retreat, dtype=attack.dtype, device=attack.device)).expand_as(drone.pos)
        go = torch.where(self.near_net(drone).unsqueeze(-1), self.off_net(drone), retreat)
        return self.recover_ctrl.act_thrust(drone, self.rush(drone, go))

    def near_net(self, drone):
        """[...] the drone will soon be closer to the net than ``net_x``."""
        c = self.cfg
        return drone.pos[..., 0] + c.net_look * drone.vel[..., 0] < c.net_x

    def off_net(self, drone):
        # far enough back that the flight there starts with a hard turn away from the net
        back = drone.pos.clone()
        back[..., 0] = self.cfg.net_x + 1.5
        back[..., 2] = back[..., 2].clamp_min(self.cfg.off_net_z)
        return back

    def rush(self, drone, target):
        """Thrust [..., 3] that flies to ``target`` in about minimum time and stops there."""
        c = self.cfg
        accel = goto_accel(drone.pos, drone.vel, target, c.rush_accel, c.rush_speed, brake=c.rush_brake, lead=c.rush_lead)
        return self.attack_ctrl.thrust_vector(drone, accel)

    def act(self, drone, t):
        c = self.cfg
        anchor = drone.pos - t["anchor"]
        ball_p, ball_v = self.ball(drone, t)
        turn = t["turn"]  # (setter's turn, attacker's, done)
        setter = t["id"][..., 0] > 0.5
        attack = torch.tensor(c.attack_spot, dtype=ball_p.dtype, device=ball_p.device)
        # after the spike the attacker's throw carries it toward the net: it brakes straight away (``after_touch``)
        done = turn[..., 2:] > 0.5
        ready = attack + torch.tensor((0.0, 0.0, c.wait_dz), dtype=attack.dtype, device=attack.device)
        wait = torch.where(setter.unsqueeze(-1), anchor, ready)
        go = self.rush(drone, wait)
        idle = torch.where(done, self.after_touch(drone), self.attack_ctrl.act_thrust(drone, go))

        setting = (setter & (turn[..., 0] > 0.5)).unsqueeze(-1)
        spiking = (~setter & (turn[..., 1] > 0.5)).unsqueeze(-1)
        out = torch.where(setting, self.setting(drone, ball_p, ball_v, wait, setting.squeeze(-1)), idle)
        return torch.where(spiking, self.attack(drone, ball_p, ball_v, wait, spiking.squeeze(-1)), out)

    # ------------------------------------------------------------------ the lookahead
    def variants(self, ref: torch.Tensor) -> torch.Tensor:
        """[K, 6] throw variants (aim dx, dy, racket offset dx, dy, spike vz change, contact height change); the plain throw first."""
        c = self.cfg
        aim = grid_5x5(ref) * c.look_aim
        off = torch.tensor(((0, 0), (1, 0), (-1, 0), (0, 1), (0, -1)), dtype=ref.dtype, device=ref.device) * c.look_offset
        kw = {"dtype": ref.dtype, "device": ref.device}
        return variant_rows(aim, off, torch.tensor(c.look_vz, **kw), torch.tensor(c.look_dz, **kw))

    def spike_cost(self, o, *_) -> torch.Tensor:
        """Lower is better: metres from the target where the spike lands, plus a large cost for
        every way the touch can fail (no racket touch, not downward, into the net, the drone at the net)."""
        c, g = self.cfg, self.params.gravity
        p, v = o.ball_pos, o.ball_vel
        t = time_to_height(p[..., 2], v[..., 2], c.land_z, g)
        land = p[..., :2] + v[..., :2] * t.nan_to_num(posinf=10.0).unsqueeze(-1)
        # anywhere well inside the target will do; among those, the variant that leaves the drone the most room before the net
        off = (land - torch.tensor(c.target, dtype=p.dtype, device=p.device)).norm(dim=-1)
        cost = (off - c.look_inside).clamp_min(0.0) - 0.1 * o.min_x.clamp(max=1.0)
        # where the ball leaves the net's zone (the referee's: 0.3 m either side)
        t_net = (p[..., 0] + 0.3) / (-v[..., 0]).clamp_min(1e-3)
        z_net = p[..., 2] + v[..., 2] * t_net - 0.5 * g * t_net**2
        drone_bad = (o.min_x < c.look_margin) | (o.min_x_low < 0.2 + c.look_margin) | (o.min_z < 0.5)
        # each failure costs what it costs the success rate: a miss three of its four parts, the others one
        lost = (v[..., 2] >= 0).float() + ((z_net < c.net_height + 0.05) | drone_bad | (off > 1.0)).float()
        lost = lost + 3.0 * (~o.hit | o.body).float()
        return cost + 10.0 * lost

    def attack(self, drone, ball_p, ball_v, wait, mine):
        """The attacker's action: the plain throw, or in its last ``look_time`` seconds the best
        variant of it on the model (``mine`` [...]: the drones that attack now)."""
        c = self.cfg
        plain = self.spike_action(drone, ball_p, ball_v, wait)
        if not c.lookahead:
            return plain
        s = self.planner.plan(ball_p, ball_v, self.spike_height(ball_p, ball_v), self.spike, c.max_tilt)
        # a set met late (below the planned height: no plan left) is still chosen on the model
        late = ~(s.valid & (s.t > 0)) & ((ball_p - drone.pos).norm(dim=-1) < c.look_near)
        now = mine & ((s.valid & (s.t > 0) & (s.t < c.look_time)) | late)
        return self.lookahead.refine(plain, now, s.t, drone, ball_p, ball_v, self.variants(ball_p), self.spike_action,
                                     self.spike_cost, context=(wait,), after=lambda d, p, v: self.after_touch(d),
                                     after_steps=c.look_after)


SCRIPTED_POLICIES.update({SetAndSpikePlayer.task: SetAndSpikePlayer})
