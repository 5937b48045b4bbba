"""What the multi-drone tasks (cooperative drills and matches) share: anchors, teams, the agent
grouping algorithms rely on, the anchor-distance term and the mirror of the -x team's view.

Agent grouping. Every drone is one agent under ``("agents", ...)``; ``env.teams[a]`` is agent ``a``'s
team (0 plays on +x, 1 on -x) and ``env.team_ids`` the same as a tensor [A]. ``env.team_index(t)``
gives the agent indices of team ``t`` in agent order, and ``env.select_team(td, t)`` /
``env.write_team(td, t, sub)`` gather and scatter a team's ``("agents", ...)`` sub-tensordict
[N, A_t], so a population method can drive one team with a frozen policy and the other with a
learner (``TeamPolicies`` does exactly that for any two callables).

Mirror. In matches the team on -x sees the world rotated 180 degrees about z (x, y -> -x, -y), so one
policy can play either side; ``mirror_root`` and ``mirror_vec`` apply that rotation to the root state
and to world vectors of the agents whose flag is set.
"""

from __future__ import annotations

from typing import Callable

import torch
from tensordict import TensorDict, TensorDictBase

from volleybots.keys import AGENTS, OBS, leaf, stat
from volleybots.tasks.base import VolleyEnv
from volleybots.tasks.layout import root_layout

_ROOT = root_layout(True)
# indices of the world-frame x, y components inside the root state (the throttles come last, so
# the same indices serve the 19 values of CTBR)
_ROOT_XY = tuple(_ROOT.slice(p).start + k for p in ("pos", "vel", "omega", "heading", "up") for k in (0, 1))
_QUAT = _ROOT.slice("quat")


def canonical_quat(q: torch.Tensor) -> torch.Tensor:
    """q and -q are the same rotation; observations use the one with w >= 0 so that a mirrored
    drone and its counterpart give identical numbers."""
    return torch.where(q[..., :1] < 0, -q, q)


def rotate_quat_z180(q: torch.Tensor) -> torch.Tensor:
    """(0, 0, 0, 1) * q: the world rotation by 180 degrees about z applied to an orientation."""
    w, x, y, z = q.unbind(-1)
    return torch.stack((-z, -y, x, w), -1)


def mirror_vec(v: torch.Tensor, flip: torch.Tensor) -> torch.Tensor:
    """Rotate world vectors [..., 3] by 180 degrees about z where ``flip`` [...] is set."""
    sign = torch.ones_like(v)
    sign[..., :2] = torch.where(flip.unsqueeze(-1), -1.0, 1.0).expand_as(v[..., :2])
    return v * sign


def mirror_root(root: torch.Tensor, flip: torch.Tensor) -> torch.Tensor:
    """The root state [N, A, 23|19] as seen by agents whose ``flip`` [A] (or [N, A]) is set;
    the quaternion is made canonical for every agent."""
    flip = flip.expand(root.shape[:-1])
    out = root.clone()
    idx = torch.tensor(_ROOT_XY, device=root.device)
    out[..., idx] = torch.where(flip.unsqueeze(-1), -root[..., idx], root[..., idx])
    quat = root[..., _QUAT]
    out[..., _QUAT] = canonical_quat(torch.where(flip.unsqueeze(-1), rotate_quat_z180(quat), quat))
    return out


def anchor_excess(pos: torch.Tensor, anchors: torch.Tensor, radius: float) -> torch.Tensor:
    """[N, A] distance of each drone beyond ``radius`` from its anchor (0 inside)."""
    return ((pos - anchors).norm(dim=-1) - radius).clamp_min(0.0)


def one_hot(index: torch.Tensor, n: int) -> torch.Tensor:
    return torch.nn.functional.one_hot(index.long(), n).float()


def flag_pair(flag: torch.Tensor) -> torch.Tensor:
    """A bool flag as the one-hot pair (flag, not flag)."""
    f = flag.float().unsqueeze(-1)
    return torch.cat((f, 1.0 - f), -1)


def cosine_xy(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Cosine between the horizontal parts of a and b (0 where either is zero)."""
    return torch.nn.functional.cosine_similarity(a[..., :2], b[..., :2], dim=-1, eps=1e-6)


class MultiDroneTask(VolleyEnv):
    """Base of the cooperative tasks and the matches: anchors, teams and the agent-grouping helpers."""

    anchors_xyz: tuple[tuple[float, float, float], ...] = ()  # one anchor per drone
    default_algo = "mappo"

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self.anchors = torch.tensor(self.anchors_xyz, device=self.device, dtype=torch.float32)  # [A, 3]
        self.team_ids = torch.tensor(self.teams, device=self.device, dtype=torch.long)  # [A]
        self._team_index = [torch.nonzero(self.team_ids == t).flatten() for t in (0, 1)]

    # ---------------------------------------------------------------- agent grouping
    def team_index(self, team: int) -> torch.Tensor:
        """Agent indices [A_t] of ``team`` in agent order (empty for a team the task lacks)."""
        return self._team_index[team]

    def select_team(self, td: TensorDictBase, team: int) -> TensorDictBase:
        """The ``("agents", ...)`` entries of ``team``'s agents: a tensordict of batch [N, A_t]."""
        return td.get(AGENTS)[:, self.team_index(team)]

    def write_team(self, td: TensorDictBase, team: int, sub: TensorDictBase) -> TensorDictBase:
        """Scatter ``sub`` [N, A_t] (e.g. a team policy's actions) back into ``td``'s agents."""
        agents = td.get(AGENTS)
        idx = self.team_index(team)
        for key in sub.keys(include_nested=True, leaves_only=True):
            val = sub.get(key)
            if key in agents.keys(include_nested=True, leaves_only=True):
                # a new tensor, never a write into the old one: the old one may be the previous step's
                # (the env carries the last action into the next step's tensordict), already collected
                full = agents.get(key).clone()
            else:
                full = torch.zeros((agents.batch_size[0], agents.batch_size[1], *val.shape[2:]), dtype=val.dtype, device=val.device)
            full[:, idx] = val
            agents.set(key, full)
        return td

    # ---------------------------------------------------------------- shared pieces
    def place_around_anchors(self, mask: torch.Tensor, low, high, yaw: torch.Tensor | None = None) -> torch.Tensor:
        """Drones at rest, uniform in anchor + [low, high], level, heading ``yaw`` [A] (default 0).
        Returns the positions [N, A, 3] (those of the envs outside ``mask`` are not used)."""
        pos = self.anchors + self.uniform(low, high, (self.num_envs, self.n_drones))
        quat = None
        if yaw is not None:
            half = 0.5 * yaw.to(self.device, torch.float32)
            quat = torch.stack((half.cos(), torch.zeros_like(half), torch.zeros_like(half), half.sin()), -1)
        self.place_drones(mask, pos, quat)
        return pos

    def anchor_distance(self) -> torch.Tensor:
        """[N, A] distance of each drone to its anchor."""
        return (self.physics.state.pos - self.anchors).norm(dim=-1)


class TeamPolicies:
    """Drive a match with one policy per team. Each policy receives a tensordict laid out like the
    env's, batch [N], whose ``("agents", ...)`` holds only its team's agents ([N, A_t], with
    ``"observation"``), and writes ``("agents", "action")`` there, so any policy written for the env
    (scripted, or a TorchRL actor with those keys) plays one team; its outputs are scattered back.
    Usable as the policy of ``env.rollout`` and of TorchRL collectors.

    A policy with a ``begin_episodes(starts [N])`` method is told which envs start an episode this
    step (a population opponent draws its member then).

    Args:
        env: the match env (``make_env("1v1" | "3v3" | "6v6", ...)``), which splits and merges the teams.
        policies: the policy of team 0 (the +x side) and of team 1; each sees its team's observations
            mirrored to the +x side, so one policy plays either side.
    """

    def __init__(self, env: MultiDroneTask, policies: tuple[Callable, Callable]):
        self.env = env
        self.policies = policies

    def __call__(self, td: TensorDictBase) -> TensorDictBase:
        starts = td.get(stat("episode_len")).reshape(-1) == 0
        for team, policy in enumerate(self.policies):
            if hasattr(policy, "begin_episodes"):
                policy.begin_episodes(starts)
            sub = TensorDict({AGENTS: self.env.select_team(td, team)}, batch_size=td.batch_size, device=td.device)
            out = policy(sub)
            out = sub if out is None else out
            # everything it wrote (a learner's log-probabilities too), not the observation it read
            self.env.write_team(td, team, out.get(AGENTS).exclude(leaf(OBS)))
        return td
