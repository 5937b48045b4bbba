"""The keys of an env's TensorDict, spelled once (a leaf: it imports nothing).

Every task lays out its TensorDict the same way (tasks/base.py), batch [N] (``num_envs``; a
collected rollout is [N, T] with the same keys):

- ``AGENTS``: the group of per-drone entries, a sub-tensordict of batch [N, A] (A drones; a team
  policy sees only its own team's [N, A_t], tasks/multi.py). The env writes the observation ``OBS``
  [N, A, obs] and, after a step, the reward ``REWARD`` [N, A, 1]; a policy writes the action
  ``ACTION`` [N, A, 4] (or [N, A] int for the discrete space). What else the players write there:
  ``OBS_NORM``, ``LOG_PROB`` and ``VALUE`` (PPO and its variants), ``ACTION_VALUE`` and
  ``CHOSEN_VALUE`` (QMIX), ``Q_VALUE`` (MADDPG), ``TEACHER`` (BC), ``DRILL`` (a hierarchical team's
  high level). The joint replay items of the multi-agent off-policy learners give each drone the
  env's flags as ``AGENT_DONE`` and ``AGENT_TERMINATED``, for TorchRL's per-agent targets.
- ``DONE``, ``TERMINATED``, ``TRUNCATED`` [N, 1]: shared by all drones of an env.
- ``STATS``: the running episode statistics, ``stat(name)`` [N, 1] each (return, length, the task
  metric, every reward term), final when ``DONE`` is set.
- ``NEXT``: TorchRL's nesting of what a step produced. ``env.step(td)`` writes the next observation,
  the reward, the flags and the statistics under it; ``nxt(key)`` names a key there
  (``nxt(REWARD) == ("next", "agents", "reward")``).

``leaf(key)`` is an entry's name inside its group: what builds a group (``{leaf(OBS): obs}``) or
lays one drone's entries out at the root of its own tensordict.
"""

from __future__ import annotations

AGENTS = "agents"
TEAM_NAMES = ("blue", "red")  # team 0 (+x) and team 1 (-x): the agents' names of a match (blue_0, red_0, ...) and its colours
NEXT = "next"
STATS = "stats"
DONE = "done"
TERMINATED = "terminated"
TRUNCATED = "truncated"

# written by the env
OBS = (AGENTS, "observation")
REWARD = (AGENTS, "reward")
# written by a policy
ACTION = (AGENTS, "action")
# written by the learners and players that act or learn on the env's TensorDict
OBS_NORM = (AGENTS, "observation_norm")
LOG_PROB = (AGENTS, "action_log_prob")
VALUE = (AGENTS, "state_value")
ACTION_VALUE = (AGENTS, "action_value")
CHOSEN_VALUE = (AGENTS, "chosen_action_value")
Q_VALUE = (AGENTS, "state_action_value")
TEACHER = (AGENTS, "teacher_action")  # the scripted player's action, next to the executed one
DRILL = (AGENTS, "drill")
# the shared flags repeated per drone, in a joint replay item
AGENT_DONE = (AGENTS, DONE)
AGENT_TERMINATED = (AGENTS, TERMINATED)


def nxt(key: str | tuple[str, ...]) -> tuple[str, ...]:
    """``key`` under ``NEXT``: where a step's result holds it."""
    return (NEXT, key) if isinstance(key, str) else (NEXT, *key)


def stat(name: str) -> tuple[str, str]:
    """The episode statistic ``name`` [N, 1]."""
    return (STATS, name)


def leaf(key: str | tuple[str, ...]) -> str:
    """The name of ``key``'s entry inside its group (the key itself for a root key)."""
    return key if isinstance(key, str) else key[-1]
