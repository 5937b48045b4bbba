"""Scripted Set and Spike pair (Easy and Hard): the setter sets, the attacker spikes into the target."""

from __future__ import annotations

from dataclasses import dataclass

import torch

from volleybots.scripted.ballistics import launch_for_apex, launch_for_range, racket_for
from volleybots.scripted.players import TouchConfig, _Player
from volleybots.scripted.policies import SCRIPTED_POLICIES


# --------------------------------------------------------------------------- Set and Spike
@dataclass(frozen=True)
class SpikeConfig:
    attack_spot: tuple[float, float, float] = (1.5, 0.5, 3.0)  # where the attacker meets the set (drone centre), clear of the net
    set_apex: float = 4.6  # the set's apex: a steep fall onto the attacker needs less racket tilt
    target: tuple[float, float] = (-4.5, 0.0)  # where the spike should land
    land_z: float = 0.1
    elevations: tuple[float, float, int] = (-40.0, -1.0, 40)  # downward launch angles tried for the spike (deg)
    max_vx: float = float("inf")  # cap on the spike's speed toward -x (a tip under 2 m/s never wakes the defence racket)


class SetAndSpikePlayer(_Player):
    """Drone 1 (the setter) sets the dropped ball to the attack spot; drone 2 (the attacker) waits
    there and spikes it down to the target with the launch angle that needs the least racket tilt.
    Before and after its touch each waits at its spot."""

    task = "set_and_spike_easy"

    def __init__(self, action_space="prt", params=None, gains=None, cfg: SpikeConfig = SpikeConfig(),
                 touch: TouchConfig = TouchConfig(contact_z=3.0, first_contact_z=2.45, early=())):
        super().__init__(action_space, params, gains, touch)
        self.cfg = cfg

    def spike(self, bp, bv):
        """Outgoing velocity [..., 3] that lands the ball on the target, going down, with the least tilt."""
        c = self.cfg
        lo, hi, k = c.elevations
        elev = torch.deg2rad(torch.linspace(lo, hi, k, dtype=bp.dtype, device=bp.device))
        shape = bp.shape[:-1] + (k,)
        target = torch.tensor(c.target, dtype=bp.dtype, device=bp.device).expand(*shape, 2)
        v = launch_for_range(bp.unsqueeze(-2).expand(*shape, 3), target, c.land_z, elev.expand(shape))
        n, _ = racket_for(bv.unsqueeze(-2).expand_as(v), v, self.params.ball.restitution)
        cost = torch.where(torch.isfinite(v).all(-1) & (v[..., 0] >= -c.max_vx), -n[..., 2], torch.full_like(n[..., 2], float("inf")))
        best = cost.argmin(-1)
        return torch.gather(v, -2, best[..., None, None].expand(*bp.shape[:-1], 1, 3)).squeeze(-2)

    def act(self, drone, t):
        c = self.cfg
        anchor = drone.pos - t[..., 0:3]
        ball_p, ball_v = self.ball(drone, t)
        turn = t[..., 12:15]
        setter = t[..., 15] > 0.5
        attack = torch.tensor(c.attack_spot, dtype=ball_p.dtype, device=ball_p.device)
        land_z = attack[2] + self.planner.reach

        def want_out(bp, bv):
            set_v = launch_for_apex(bp, attack[:2].expand_as(bp[..., :2]), c.set_apex, land_z, self.params.gravity)
            return torch.where(setter.unsqueeze(-1), set_v, self.spike(bp, bv))

        mine = torch.where(setter, turn[..., 0] > 0.5, turn[..., 1] > 0.5)
        wait = torch.where(setter.unsqueeze(-1), anchor, attack.expand_as(anchor))
        return self.play(drone, ball_p, ball_v, want_out, mine, wait)


class SetAndSpikeHardPlayer(SetAndSpikePlayer):
    task = "set_and_spike_hard"


SCRIPTED_POLICIES.update({cls.task: cls for cls in (SetAndSpikePlayer, SetAndSpikeHardPlayer,)})
