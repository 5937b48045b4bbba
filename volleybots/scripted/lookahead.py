"""Lookahead: model-predictive choice among variants of a touch.

A scripted touch is planned on an idealised contact (the racket exactly on its normal, at its speed,
at the planned time); the drone flies it with some error, and where the racket needs a steep tilt
(the Set and Spike attack needs about 50 degrees) a small error in the racket's attitude or in where
the ball meets it sends the ball far from where it was meant to go, or past the racket's rim. A
player that knows the world's model (the same ``WorldParams`` the physics uses; nothing of the env's
own state) can instead try ``K`` variants of its touch from the state it observes, fly each on that
model until the contact and a little past it, and act on the variant whose outcome is best: the
shooting form of model-predictive control, with the scripted controller as the rollout policy, so
only a few set-points are searched, never raw rotor commands. By default nothing is remembered between
steps: every step re-plans from the observation (receding horizon), so the player stays a plain
policy. ``every = k`` trades that for speed (collecting a teacher's demonstrations, algos/bc.py): a
drone's chosen variant is kept for k steps and flown closed-loop from each new observation, and only
then chosen again; the search, nearly all of such a player's time, costs about k times less.

The rollout is the physics' own pure sub-step (``physics.torch_backend.substep``) on a single drone
and the ball; other drones are left out (their downwash on the player is ignored).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import torch

from volleybots.physics.actions import make_action_space
from volleybots.physics.math import quat_rotate, quat_rotate_inverse
from volleybots.physics.params import WorldParams
from volleybots.physics.torch_backend import Constants, PhysicsState, substep
from volleybots.scripted.control import DroneObs

# control steps ``refine``'s rollouts fly past the plan's time to the contact, which is an estimate: a
# constant, not a parameter: no caller ever set another
MARGIN_STEPS = 3

Fly = Callable[[DroneObs, torch.Tensor, torch.Tensor], torch.Tensor]  # (drone, ball pos, ball vel) -> action [M, 4]


@dataclass
class Outcome:
    """What one rollout of each variant gave, per variant [M]."""

    hit: torch.Tensor  # bool: the ball met the racket (before any body touch)
    body: torch.Tensor  # bool: the ball touched the drone's body first
    ball_pos: torch.Tensor  # [M, 3] right after the racket touch
    ball_vel: torch.Tensor  # [M, 3]
    drone_pos: torch.Tensor  # [M, 3] at the racket touch
    drone_vel: torch.Tensor  # [M, 3]
    min_x: torch.Tensor  # lowest drone x over the whole rollout (the net is at x = 0)
    min_x_low: torch.Tensor  # ... while the drone was below ``net_z`` (by the net's side is a fault there)
    min_z: torch.Tensor  # lowest drone height over the whole rollout
    action: torch.Tensor  # [M, 4] the first action: what the player does now if it picks this variant


def variant_rows(*tables: torch.Tensor) -> torch.Tensor:
    """Every combination of the tables' rows [K_i, P_i] (a 1-D table is one column), as one variant
    table [prod K_i, sum P_i]; the first table varies slowest, so the combination of first rows
    (each table's plain value) comes first."""
    tables = tuple(t.unsqueeze(-1) if t.dim() == 1 else t for t in tables)
    idx = torch.cartesian_prod(*(torch.arange(len(t), device=t.device) for t in tables)).view(-1, len(tables))
    return torch.cat([t[idx[:, i]] for i, t in enumerate(tables)], -1)


class Lookahead:
    """Rolls a single drone and the ball forward on the world's model under a scripted flight."""

    def __init__(self, params: WorldParams, action_space: str, every: int = 1):
        self.params = params
        self.action_space = action_space
        self.every = every  # steps a chosen variant is kept (1: every step chooses afresh)
        self._consts: dict = {}
        self._memo: dict[str, dict[str, torch.Tensor]] = {}  # per call site: the variant each drone keeps

    def _c(self, ref: torch.Tensor) -> Constants:
        key = (ref.device, ref.dtype)
        if key not in self._consts:
            self._consts[key] = Constants(self.params, ref.device, ref.dtype)
        return self._consts[key]

    def rollout(self, drone: DroneObs, ball_p: torch.Tensor, ball_v: torch.Tensor, fly: Fly, steps: int,
                after: Fly | None = None, after_steps: int = 0, net_z: float = 2.6) -> Outcome:
        """Fly ``fly`` from the observed state [M, ...] for up to ``steps`` control steps or until the
        ball meets the drone, then ``after`` for ``after_steps`` more (how the drone gets out of its
        touch matters too: a throw toward the net must not end across it)."""
        c = self._c(ball_p)
        m = ball_p.shape[0]
        # the rate controller of CTBR starts with empty integrators: a close enough model of the env's
        space = make_action_space(self.action_space, self.params, m, 1, ball_p.device, ball_p.dtype)
        with_throttle = self.action_space == "prt"
        throttle = drone.throttle if drone.throttle is not None else torch.tensor(
            self.params.drone.hover_throttle, dtype=ball_p.dtype, device=ball_p.device).expand(m, 4)
        s = PhysicsState(pos=drone.pos.unsqueeze(1), quat=drone.quat.unsqueeze(1), vel=drone.vel.unsqueeze(1),
                         omega=quat_rotate_inverse(drone.quat, drone.omega_world).unsqueeze(1), throttle=throttle.unsqueeze(1),
                         ball_pos=ball_p.clone(), ball_vel=ball_v.clone())
        false = torch.zeros(m, dtype=torch.bool, device=ball_p.device)
        hit, body = false.clone(), false.clone()
        ball_pos, ball_vel = ball_p.clone(), ball_v.clone()
        drone_pos, drone_vel = drone.pos.clone(), drone.vel.clone()
        min_x, min_z = drone.pos[:, 0].clone(), drone.pos[:, 2].clone()
        far = torch.full_like(min_x, float("inf"))
        min_x_low = torch.where(drone.pos[:, 2] < net_z, min_x, far)
        first = None
        since = torch.zeros(m, dtype=torch.long, device=ball_p.device)  # control steps since the touch
        for _ in range(steps + after_steps):
            d = DroneObs(s.pos[:, 0], s.quat[:, 0], s.vel[:, 0], quat_rotate(s.quat[:, 0], s.omega[:, 0]),
                         s.throttle[:, 0] if with_throttle else None)
            done = hit | body
            a = fly(d, s.ball_pos, s.ball_vel)
            if after is not None and bool(done.any()):
                a = torch.where(done.unsqueeze(-1), after(d, s.ball_pos, s.ball_vel), a)
            if first is None:
                first = a
            command = space.command_fn(a.unsqueeze(1))
            for _ in range(self.params.substeps):
                s, racket, touched, _ = substep(c, s, command(s))
                new = racket[:, 0] & ~done
                hit = hit | new
                body = body | (touched[:, 0] & ~done & ~hit)
                ball_pos = torch.where(new.unsqueeze(-1), s.ball_pos, ball_pos)
                ball_vel = torch.where(new.unsqueeze(-1), s.ball_vel, ball_vel)
                drone_pos = torch.where(new.unsqueeze(-1), s.pos[:, 0], drone_pos)
                drone_vel = torch.where(new.unsqueeze(-1), s.vel[:, 0], drone_vel)
                done = hit | body
            # a rollout whose window is over keeps flying (the batch runs on) but no longer counts,
            # so a variant's outcome does not depend on how long the others take
            live = since <= after_steps
            x, z = s.pos[:, 0, 0], s.pos[:, 0, 2]
            min_x = torch.where(live, torch.minimum(min_x, x), min_x)
            min_z = torch.where(live, torch.minimum(min_z, z), min_z)
            min_x_low = torch.where(live, torch.minimum(min_x_low, torch.where(z < net_z, x, far)), min_x_low)
            since = since + done.long()
            if bool((since > after_steps).all()):
                break
        return Outcome(hit, body, ball_pos, ball_vel, drone_pos, drone_vel, min_x, min_x_low, min_z, first)

    def choose(self, drone: DroneObs, ball_p: torch.Tensor, ball_v: torch.Tensor, variants: torch.Tensor,
               fly: Callable[[DroneObs, torch.Tensor, torch.Tensor, torch.Tensor], torch.Tensor],
               cost: Callable[[Outcome], torch.Tensor], steps: int, after: Fly | None = None,
               after_steps: int = 0, net_z: float = 2.6) -> tuple[torch.Tensor, torch.Tensor]:
        """For every drone [B] try every variant [K, P] (``fly(drone, ball_p, ball_v, variant)``),
        score each outcome with ``cost`` (lower is better) and return the best variant's action
        [B, 4] and its cost [B]. Ties go to the earlier variant, so put the plain touch first."""
        action, score, _ = self._search(drone, ball_p, ball_v, variants, fly, cost, steps, after, after_steps, net_z)
        return action, score

    def _search(self, drone, ball_p, ball_v, variants, fly, cost, steps, after=None, after_steps=0, net_z=2.6):
        """``choose``, also returning each drone's best row of ``variants`` [B]."""
        b, k = ball_p.shape[0], variants.shape[0]

        def rep(x):
            return None if x is None else x.repeat_interleave(k, 0)

        many = DroneObs(rep(drone.pos), rep(drone.quat), rep(drone.vel), rep(drone.omega_world), rep(drone.throttle))
        var = variants.repeat(b, 1)
        # the search only chooses an action, so its rollouts skip autograd's bookkeeping (as the env's
        # physics does); the indexing below copies what it returns into ordinary tensors
        with torch.inference_mode():
            out = self.rollout(many, rep(ball_p), rep(ball_v), lambda d, bp, bv: fly(d, bp, bv, var), steps, after, after_steps, net_z)
            score = cost(out).view(b, k)
        best = score.argmin(-1)
        idx = torch.arange(b, device=ball_p.device) * k + best
        return out.action[idx], score.gather(-1, best.unsqueeze(-1)).squeeze(-1), best

    def refine(self, plain: torch.Tensor, now: torch.Tensor, t_go: torch.Tensor, drone: DroneObs, ball_p: torch.Tensor,
               ball_v: torch.Tensor, variants: torch.Tensor, fly, cost: Callable[..., torch.Tensor],
               context: tuple[torch.Tensor, ...] = (), after: Fly | None = None, after_steps: int = 0) -> torch.Tensor:
        """``plain`` [..., 4] (a player's actions, any batch shape) with the drones where ``now``
        [...] is set flying their best variant instead (``choose``); the rollouts last ``t_go`` [...]
        seconds (the plan's time to the contact) plus ``MARGIN_STEPS``. ``fly(drone, ball_p,
        ball_v, *context, variant)``: ``context`` holds per-drone tensors [..., n] the flight needs
        besides the drone and the ball; ``cost(outcome, *context)`` gets them too, one row per
        rollout. With ``every`` > 1 a drone keeps its choice for that many steps (kept per call
        site, told apart by ``fly``'s qualified name)."""
        flat_now, flat_t = now.reshape(-1), t_go.reshape(-1)
        keep = self._kept(getattr(fly, "__qualname__", ""), flat_now, flat_t)
        if not bool(flat_now.any()):
            return plain
        out = plain.reshape(-1, plain.shape[-1]).clone()
        k = variants.shape[0]

        def pick(x, idx):
            return None if x is None else x.reshape(-1, x.shape[-1])[idx]

        def drone_of(idx):
            return DroneObs(
                pick(drone.pos, idx), pick(drone.quat, idx), pick(drone.vel, idx), pick(drone.omega_world, idx), pick(drone.throttle, idx)
            )

        # drones that keep their variant fly it from where they are now: no search
        held = (flat_now & keep["valid"]).nonzero().squeeze(-1)
        if len(held):
            ctx = tuple(pick(x, held) for x in context)
            out[held] = fly(drone_of(held), pick(ball_p, held), pick(ball_v, held), *ctx, variants[keep["best"][held]])
        idx = (flat_now & ~keep["valid"]).nonzero().squeeze(-1)
        if len(idx):
            ctx = tuple(pick(x, idx).repeat_interleave(k, 0) for x in context)
            steps = math.ceil(float(flat_t[idx].clamp_min(0.0).max()) / self.params.dt) + MARGIN_STEPS
            out[idx], _, best = self._search(drone_of(idx), pick(ball_p, idx), pick(ball_v, idx), variants,
                                             lambda dd, p, v, var: fly(dd, p, v, *ctx, var), lambda o: cost(o, *ctx),
                                             steps, after, after_steps)
            if self.every > 1:
                keep["best"][idx], keep["age"][idx], keep["t"][idx] = best, 0, flat_t[idx]
        return out.view_as(plain)

    def _kept(self, key: str, now: torch.Tensor, t_go: torch.Tensor) -> dict[str, torch.Tensor]:
        """The memo of call site ``key`` for a batch [B], advanced by one step: ``valid`` [B] where a
        drone may fly the variant it chose before (it has searched within the last ``every`` steps,
        has been choosing ever since, and its contact is still the one it chose for: the plan's time
        to go fell by the steps since, within two steps; a new episode's touch is a new plan)."""
        b, dt = now.shape[0], self.params.dt
        if self.every == 1:  # the memoryless player: nothing to keep
            return {"valid": torch.zeros_like(now)}
        memo = self._memo.get(key)
        if memo is None or memo["best"].shape[0] != b:
            memo = self._memo[key] = {"best": torch.zeros(b, dtype=torch.long, device=now.device),
                                      "age": torch.full((b,), self.every, dtype=torch.long, device=now.device),
                                      "t": torch.zeros(b, dtype=t_go.dtype, device=now.device)}
        memo["age"] = torch.where(now, memo["age"] + 1, self.every)
        memo["t"] = memo["t"] - dt
        on_plan = (t_go - memo["t"]).abs() < 2.0 * dt
        memo["valid"] = now & (memo["age"] < self.every) & on_plan
        return memo
