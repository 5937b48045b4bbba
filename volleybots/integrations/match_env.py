"""The matches (1v1, 3v3, 6v6) for single-agent trainers: every world stepped in one batched call, the
learning side's drones as the vector env's envs, the other side played by a competitor.

``VolleyMatchVectorEnv`` is a Gymnasium vector env of ``num_envs`` worlds x the learner's drones: row
``w * A + k`` is drone ``k`` of the learning team in world ``w`` (A = 1, 3 or 6, the team's size;
``n_worlds`` worlds). Its observation is that drone's own (mirrored to the +x side for team 1, as the
task gives it), its reward that drone's, and its episode ends when its world's does. The other team is
played by ``opponent``:

- a competitor spec of ``volleybots.policies.resolve_competitor`` (``scripted``, ``zoo:1v1/bc``, a run
  directory, a checkpoint, a mixture ``scripted+zoo:1v1/bc``, a user's ``module:function``), a
  ``Competitor`` (``volleybots.policies.callable_competitor`` makes one of any function of the
  observation batch), or a plain function of a torch observation batch;
- ``"self"``: nobody else. The learner plays both teams: every drone of every world is a row (team 0's
  drones first in each world), so one shared policy learns from both sides of each game.

``set_opponent(...)`` swaps the opponent between steps (the worlds play on): a trainer refreshes a
frozen snapshot of itself for self-play this way (``sb3_env.SnapshotOpponent`` does it for SB3).
A mixture draws its member per world at each episode start from the env's own generator (seeded by
``seed``), so a seed fixes the games on the CPU.

Everything of the match (physics, rewards, resets, the opponent's view) is the TorchRL env's own: this
class drives ``step_and_maybe_reset`` with ``TeamPolicies`` and moves numbers between numpy and
tensordicts. Worlds reset within the step that ends them (Gymnasium's same-step autoreset, what the
batched env does): a done row's observation is already the next episode's, its last one is in
``info["final_obs"]`` and the episode's statistics (of its world: the match's winner, length,
team-0 return, ...) in ``info["final_stats"]``, rows where ``info["_final_obs"]`` is set.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import torch
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from volleybots.integrations import spaces as sp
from volleybots.integrations.gym_env import _BatchedVectorEnv
from volleybots.integrations.render import RENDER_MODES, check_render_mode
from volleybots.integrations.spaces import Actions, to_numpy
from volleybots.keys import ACTION, NEXT, OBS, REWARD
from volleybots.policies import Competitor, callable_competitor, resolve_competitor
from volleybots.tasks import TASKS
from volleybots.tasks.multi import TeamPolicies

MATCHES = tuple(name for name, cls in TASKS.items() if cls.competitive)
SELF = "self"  # the opponent that is the learner itself: it plays both teams


def as_competitor(opponent) -> Competitor:
    """A competitor from what ``VolleyMatchVectorEnv`` takes as ``opponent`` (not ``"self"``)."""
    if isinstance(opponent, Competitor):
        return opponent
    if isinstance(opponent, str):
        return resolve_competitor(opponent)  # a ConfigError (a ValueError) names a bad spec
    if callable(opponent):
        return callable_competitor(opponent)
    raise ValueError(f"opponent must be a competitor spec, a Competitor, a function or {SELF!r}, got {type(opponent).__name__}")


class VolleyMatchVectorEnv(_BatchedVectorEnv):
    """The learner's drones of ``n_worlds`` batched matches as one Gymnasium vector env (module docstring).

    Args:
        task: ``1v1``, ``3v3`` or ``6v6``.
        n_worlds: matches stepped together; ``num_envs`` is ``n_worlds`` x the learner's drones per world.
        opponent: who plays the other team (module docstring), or ``"self"``.
        team: the learner's team, 0 (+x) or 1 (-x); with ``opponent="self"``, both.
        opponent_deterministic: the opponent acts on its mean (a trained one) instead of sampling.
        action_space: ``prt``, ``ctbr`` or ``discrete``.
        physics: ``torch`` or ``mujoco``.
        device: where the env's tensors live (arrays always come back on the CPU).
        seed: the generator's seed (the env's and the mixture's draws) until ``reset(seed=...)`` gives another.
        clip_obs: clip observations into declared bounds, as ``VolleyVectorEnv`` does.
        render_mode: None or ``"rgb_array"``: ``render()`` gives world 0's video frame with the score
            (points each team won there since the env was made), for the video recorders.
        **task_overrides: as for ``volleybots.make_env`` (``episode_len``, ``serve``, ...).
    """

    metadata: ClassVar[dict] = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": list(RENDER_MODES), "render_fps": 50}

    def __init__(self, task: str = "1v1", n_worlds: int = 8, opponent="scripted", team: int = 0, opponent_deterministic: bool = False,
                 action_space: str = "prt", physics: str = "torch", device="cpu", seed: int = 0, clip_obs: bool = False,
                 render_mode: str | None = None, **task_overrides):
        if task not in MATCHES:
            raise ValueError(f"task {task!r} is not a match; allowed: {list(MATCHES)} (VolleyVectorEnv takes the single-drone tasks)")
        if team not in (0, 1) or isinstance(team, bool):
            raise ValueError(f"team must be 0 or 1, got {team!r}")
        if not isinstance(opponent_deterministic, (bool, np.bool_)):
            raise ValueError(f"opponent_deterministic must be True or False, got {opponent_deterministic!r}")
        check_render_mode(render_mode)  # before the env is built: a bad mode is one line
        self.env = sp.build(task, n_worlds, action_space=action_space, physics=physics, device=device, seed=seed, **task_overrides)
        self._init_render(render_mode)
        self.task, self.team, self.n_worlds = task, int(team), int(n_worlds)
        self.opponent_deterministic = bool(opponent_deterministic)
        # the mixture's draws: a generator of its own, seeded with the env, so a seed fixes who plays which world
        self._draws = torch.Generator(device=self.env.device)
        self._draws.manual_seed(seed)
        self._td = None
        self.set_opponent(opponent)
        self._observe = sp.Observations(self.env, clip_obs)
        self.obs_clip = self._observe.clip
        self.single_observation_space = self._observe.space
        self.single_action_space = sp.action_space(self.env)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)

    # ------------------------------------------------------------------ the opponent
    def set_opponent(self, opponent) -> None:
        """Who plays the other team from the next step on (a spec, a ``Competitor``, a function or
        ``"self"``); checked against the task first. ``"self"`` changes the row count, so it is fixed
        at construction: a self-play env stays one and a learner's never becomes one."""
        selfplay = isinstance(opponent, str) and opponent == SELF
        if hasattr(self, "per_world") and selfplay != (self.opponent is None):  # set once by the constructor
            raise ValueError(f"opponent {SELF!r} changes the rows of the env: make a new env for it")
        if selfplay:
            self.opponent, self._policy = None, None
            self.agents = torch.arange(self.env.n_drones, device=self.env.device)  # team 0's drones come first
        else:
            comp = as_competitor(opponent)
            comp.check_fits(self.task, self.env.action_space_name, self.env.obs_dim)
            policy = comp.team_policy(self.env, self.opponent_deterministic, self._draws)
            self.opponent, self.agents = comp, self.env.team_index(self.team)
            own = self._act  # the learner's actions, put into its team's tensordict
            self._policy = TeamPolicies(self.env, (own, policy) if self.team == 0 else (policy, own))
            if self._td is not None:  # the worlds play on: the new one's episodes start now
                starts = torch.ones(self.n_worlds, dtype=torch.bool, device=self.env.device)
                if hasattr(policy, "begin_episodes"):
                    policy.begin_episodes(starts)
        self.per_world = len(self.agents)
        self.num_envs = self.n_worlds * self.per_world
        self._actions = Actions(self.env, (self.n_worlds, self.per_world))
        self._shape = self._actions.shape((self.num_envs,))
        self._action = None

    def _act(self, sub):
        sub.set(ACTION, self._action)
        return sub

    # ------------------------------------------------------------------ stepping
    def _rows(self, x: torch.Tensor) -> torch.Tensor:
        """The learner's rows ``[n_worlds * per_world, ...]`` of a per-agent tensor ``[n_worlds, A, ...]``."""
        x = x[:, self.agents]
        return x.reshape(self.num_envs, *x.shape[2:])

    def _per_row(self, x: np.ndarray) -> np.ndarray:
        """A per-world array [n_worlds] as the learner's rows (each world's value once per drone)."""
        return np.repeat(x, self.per_world)

    def _reseed(self, seed: int) -> None:
        self.env.set_seed(seed)
        self._draws.manual_seed(seed)  # the mixture's draws too: a seed fixes who plays which world

    def step32(self, actions):
        """``step`` with the reward as the env's float32 (what SB3's buffers hold)."""
        self._check_open()
        if self._td is None:
            raise RuntimeError("call reset() before step()")
        self._action = self._actions.tensor(self._actions.array(actions, self._shape))
        if self._policy is None:  # self-play: the rows are every drone
            self._td.set(ACTION, self._action)
        else:
            self._policy(self._td)
        cur, self._td = self.env.step_and_maybe_reset(self._td)
        nxt = cur.get(NEXT)
        term, trunc = self._flags(nxt)
        self._trail_step(nxt, bool(term[0] or trunc[0]))  # row 0 is a drone of world 0
        reward = to_numpy(self._rows(nxt.get(REWARD))[:, 0])
        return self._observe(self._rows(self._td.get(OBS))), reward, term, trunc, self._ended_info(nxt, term | trunc)


__all__ = ["MATCHES", "SELF", "VolleyMatchVectorEnv", "as_competitor"]
