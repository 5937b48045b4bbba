"""The tasks as Gymnasium and PettingZoo environments, for trainers written against those APIs.

- ``VolleyVectorEnv`` / ``VolleyGymEnv``: the single-drone tasks as a Gymnasium vector env (the
  batched env, numpy in and out) and as one ``gymnasium.Env``; importing this package registers
  ``volleybots/<Task>-v0`` (``gymnasium.make("volleybots/SoloBump-v0")``, ``gymnasium.make_vec(...)``).
- ``VolleyParallelEnv``: any task, the multi-drone ones above all, as a PettingZoo ``ParallelEnv``
  with agents named per team and a ``groups`` map (one group per team).
- ``VolleySB3VecEnv``: the single-drone tasks as a Stable-Baselines3 ``VecEnv`` over the batched env.
- ``VolleyMatchVectorEnv`` / ``VolleyMatchSB3VecEnv``: the matches (1v1, 3v3, 6v6) as a Gymnasium
  vector env and an SB3 ``VecEnv`` of the learning team's drones over batched worlds, the other team
  played by any competitor (``match_env``); ``sb3_competitor``, ``SnapshotOpponent`` and
  ``export_torchscript`` take an SB3 policy into the matches and the verbs (``sb3_match``).

Both are views of the TorchRL env (``volleybots.make_env``): nothing of a task is written again here.
They need optional extras, so that the core install stays as it is: ``pip install 'volleybots[gym]'``
(gymnasium), ``pip install 'volleybots[pettingzoo]'`` (pettingzoo and gymnasium) and
``pip install 'volleybots[sb3]'`` (stable-baselines3 and gymnasium).
"""

from __future__ import annotations

try:
    import gymnasium  # noqa: F401
except ImportError:  # the message names the extra: a bare "No module named gymnasium" does not
    raise ImportError("volleybots.integrations needs gymnasium: pip install 'volleybots[gym]' "
                      "(or 'volleybots[pettingzoo]' for the PettingZoo env)") from None

from volleybots.integrations.gym_env import IDS, VolleyGymEnv, VolleyVectorEnv, register

register()


_SB3_MATCH = ("VolleyMatchSB3VecEnv", "SnapshotOpponent", "export_torchscript", "sb3_competitor")


def __getattr__(name: str):
    # PettingZoo is imported on first use, so that the gym extra alone is enough for the Gymnasium envs
    if name in ("VolleyParallelEnv", "parallel_env"):
        from volleybots.integrations import pettingzoo_env

        return getattr(pettingzoo_env, name)
    if name == "VolleySB3VecEnv":  # likewise Stable-Baselines3
        from volleybots.integrations import sb3_env

        return sb3_env.VolleySB3VecEnv
    if name == "VolleyMatchVectorEnv":  # the matches pull in the competitors (checkpoints, the zoo) on first use
        from volleybots.integrations import match_env

        return match_env.VolleyMatchVectorEnv
    if name in _SB3_MATCH:
        from volleybots.integrations import sb3_match

        return getattr(sb3_match, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["IDS", "SnapshotOpponent", "VolleyGymEnv", "VolleyMatchSB3VecEnv", "VolleyMatchVectorEnv", "VolleyParallelEnv",
           "VolleySB3VecEnv", "VolleyVectorEnv", "export_torchscript", "parallel_env", "register", "sb3_competitor"]
