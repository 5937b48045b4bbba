"""Stable-Baselines3 on the matches: a ``VecEnv`` of the learner's drones over batched worlds, the
other team played by any competitor, and the pieces that take an SB3 policy into the verbs.

- ``VolleyMatchSB3VecEnv``: ``VolleyMatchVectorEnv`` (its rows, opponent, seeds and numbers) as SB3's
  ``VecEnv``, stepping every world in one call; the info dicts are ``VolleySB3VecEnv``'s
  (``terminal_observation``, ``TimeLimit.truncated``, ``final_stats``).
- ``sb3_competitor(model)``: an SB3 model or policy as a ``Competitor`` (through SB3's own
  ``policy.predict``), to play as an opponent or in ``volleybots.eval.crossplay``.
- ``SnapshotOpponent``: an SB3 callback for self-play against a frozen past self: every ``every``
  rollouts it copies the policy and makes the copy the env's opponent.
- ``export_torchscript(model, path)``: the policy's deterministic action as a TorchScript file, which
  the CLI takes as ``torchscript:PATH`` (``volleybots eval crossplay torchscript:PATH zoo:1v1/bc``).
"""

from __future__ import annotations

import torch

try:
    from stable_baselines3.common.callbacks import BaseCallback
except ImportError:  # the message names the extra: a bare "No module named stable_baselines3" does not
    raise ImportError("volleybots.integrations.VolleyMatchSB3VecEnv needs stable-baselines3: pip install 'volleybots[sb3]'") from None

from volleybots.integrations.match_env import VolleyMatchVectorEnv
from volleybots.integrations.sb3_env import _BatchedVecEnv
from volleybots.policies import Competitor, callable_competitor


class VolleyMatchSB3VecEnv(_BatchedVecEnv):
    """The learner's drones of ``n_worlds`` batched matches as one SB3 ``VecEnv`` (arguments as for
    ``VolleyMatchVectorEnv``: ``task``, ``n_worlds``, ``opponent``, ``team``, ...). ``set_opponent``
    (or SB3's ``env_method("set_opponent", ...)``) changes the opponent between steps."""

    def __init__(self, task: str = "1v1", n_worlds: int = 8, opponent="scripted", **kwargs):
        super().__init__(VolleyMatchVectorEnv(task, n_worlds, opponent=opponent, **kwargs))

    def set_opponent(self, opponent) -> None:
        self.venv.set_opponent(opponent)


def _policy_of(model):
    return getattr(model, "policy", model)


def frozen_copy(model, device="cpu"):
    """A copy of an SB3 policy for acting only: rebuilt from its constructor's arguments with its weights,
    as SB3's own ``load`` does (a deep copy fails on the graph its last training step left behind)."""
    policy = _policy_of(model)
    snap = type(policy)(**policy._get_constructor_parameters()).to(device)
    snap.load_state_dict(policy.state_dict())
    snap.set_training_mode(False)
    return snap


def sb3_competitor(model, label: str = "sb3", deterministic: bool = True, task: str | None = None) -> Competitor:
    """An SB3 model (or its ``policy``) as a competitor: each team's observation batch goes through
    ``policy.predict`` (SB3's preprocessing and action clipping), on its mean unless ``deterministic``
    is False. The policy is used as it is, not copied: ``SnapshotOpponent`` copies it first."""
    policy = _policy_of(model)

    def act(obs):
        return policy.predict(obs, deterministic=deterministic)[0]

    return callable_competitor(act, label, numpy=True, task=task, source={"kind": "callable", "name": f"sb3:{type(policy).__name__}"})


class SnapshotOpponent(BaseCallback):
    """Self-play against a frozen copy of the learner, refreshed every ``every`` rollouts (and at the
    start of training): the copy plays the env's other team through ``set_opponent``.

    Args:
        every: rollouts between refreshes.
        deterministic: the snapshot acts on its mean instead of sampling.
    """

    def __init__(self, every: int = 1, deterministic: bool = False, verbose: int = 0):
        super().__init__(verbose)
        if isinstance(every, bool) or not isinstance(every, int) or every < 1:
            raise ValueError(f"every must be an integer >= 1 (rollouts between refreshes), got {every!r}")
        self.every, self.deterministic, self.rollouts, self.refreshes = every, deterministic, 0, 0

    def refresh(self) -> None:
        snap = frozen_copy(self.model, self.model.device)
        self.training_env.env_method("set_opponent", sb3_competitor(snap, f"snapshot_{self.refreshes}", self.deterministic))
        self.refreshes += 1

    def _on_training_start(self) -> None:
        self.refresh()

    def _on_rollout_end(self) -> None:
        self.rollouts += 1
        if self.rollouts % self.every == 0:
            self.refresh()

    def _on_step(self) -> bool:
        return True


class _MeanAction(torch.nn.Module):
    """An SB3 actor-critic policy's deterministic action, clipped into the Box [-1, 1] the env takes."""

    def __init__(self, policy):
        super().__init__()
        self.policy = policy

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.policy(obs, deterministic=True)[0].clamp(-1.0, 1.0)


def export_torchscript(model, path) -> None:
    """Write the SB3 policy's deterministic action (``obs [B, obs_dim] -> action [B, 4]``, float32, CPU)
    as a TorchScript file (``torch.jit.trace``) for the CLI's ``torchscript:PATH``."""
    policy = frozen_copy(model)
    example = torch.zeros(2, *policy.observation_space.shape)
    with torch.no_grad():
        traced = torch.jit.trace(_MeanAction(policy), example, check_trace=False)
    torch.jit.save(traced, str(path))


__all__ = ["SnapshotOpponent", "VolleyMatchSB3VecEnv", "export_torchscript", "frozen_copy", "sb3_competitor"]
