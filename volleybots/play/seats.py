"""Seats: whom a learner plays for (docs/competitive.md).

``AllAgents`` (the default): it drives every drone and learns from all of them; on a match that is
MAPPO's shared-parameter self-play, one actor for both teams and a critic over all drones, whose
``win`` is team 0's and says little. ``SelfPlay``: one actor and critic for a team, both teams driven
by it, each side's samples (mirrored views) a separate slice of the batch it learns from. ``Versus``:
the learner plays team 0 against a frozen competitor on team 1 (a checkpoint, a population's mixture
drawn per episode, scripted or random) and learns from its own team only; ``win`` is then the learner's.
"""

from __future__ import annotations

import torch

from volleybots.algos.base import AgentSpec
from volleybots.keys import AGENTS, nxt
from volleybots.policies.competitors import resolve_competitor
from volleybots.tasks.multi import TeamPolicies


def team_slice(batch, idx: torch.Tensor):
    """The ``("agents", ...)`` entries of the agents ``idx`` of a [N, T] batch (``next`` too)."""
    out = batch.exclude(AGENTS, nxt(AGENTS))
    out.set(AGENTS, batch.get(AGENTS)[:, :, idx])
    out.set(nxt(AGENTS), batch.get(nxt(AGENTS))[:, :, idx])
    return out


class AllAgents:
    """The learner drives every drone and learns from all of them."""

    yardstick = None  # a competitor the evaluations play on team 1 (None: the learner plays every drone)
    team = None  # the team whose return and reward terms metrics.csv logs (None: every drone's mean)

    def spec(self, env) -> AgentSpec:
        return AgentSpec.of(env)

    def policy(self, env, learner):
        return learner

    def eval_policy(self, env, learner):
        """What the periodic and final evaluations play: against a fixed yardstick, so that the curves
        of successive learners (and of self-play, whose own win rate is 1/2) compare."""
        if self.yardstick is None:
            return self.policy(env, learner)
        return TeamPolicies(env, (learner, self.yardstick.team_policy(env, deterministic=False)))

    def view(self, env, batch):
        return batch

    def state_dict(self) -> dict:
        return {}

    def load_state_dict(self, state: dict) -> None:
        pass


class SelfPlay(AllAgents):
    """One learner for a team plays both teams; each team's samples train it (mirrored views), as
    2N envs of one team each, so a centralised critic sees its own team."""

    team = 0  # both teams are the learner; team 0's figures, since both teams' together cancel out

    def __init__(self, yardstick=None):
        self.yardstick = yardstick

    def spec(self, env) -> AgentSpec:
        return AgentSpec.of(env, len(env.team_index(0)))

    def view(self, env, batch):
        return torch.cat([team_slice(batch, env.team_index(t)) for t in (0, 1)], dim=0)


class Versus(AllAgents):
    """The learner plays team 0 against a frozen ``Competitor`` on team 1 (the sides are mirror images,
    so a learner always on team 0 loses nothing: serves are drawn at random)."""

    team = 0  # the learner's

    def __init__(self, opponent, deterministic: bool = False, seed: int = 0, yardstick=None):
        self.opponent, self.deterministic, self.yardstick = opponent, deterministic, yardstick
        self.gen = torch.Generator()  # which population member each episode meets
        self.gen.manual_seed(seed)

    def spec(self, env) -> AgentSpec:
        return AgentSpec.of(env, len(env.team_index(0)))

    def policy(self, env, learner):
        return TeamPolicies(env, (learner, self.opponent.team_policy(env, self.deterministic, self.gen)))

    def view(self, env, batch):
        return team_slice(batch, env.team_index(0))

    def state_dict(self) -> dict:
        return {"gen": self.gen.get_state()}

    def load_state_dict(self, state: dict) -> None:
        self.gen.set_state(state["gen"])


def default_seat(cfg):
    """``opponent=``: the learner plays team 0 against that competitor; otherwise every drone."""
    if cfg.get("opponent") is None:
        return AllAgents()
    return Versus(resolve_competitor(cfg.opponent), cfg.opponent_deterministic, cfg.seed)


__all__ = ["AllAgents", "SelfPlay", "Versus", "default_seat", "team_slice"]
