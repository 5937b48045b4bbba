"""Rollouts: batches of steps for training, whole episodes for evaluation, and their statistics.

Every floor above stands on these: ``train`` collects batches, ``eval`` and ``replay`` play episodes,
``play.games`` plays matches. A policy is any ``td -> td`` writing ``("agents", "action")``.
"""

from __future__ import annotations

import inspect
import math

import torch
from torchrl.envs.utils import step_mdp

from volleybots.errors import ConfigError
from volleybots.keys import DONE, NEXT, OBS, STATS, stat


def stat_keys(env) -> list[str]:
    return list(env.observation_spec[STATS].keys())


def run_episodes(env, policy, on_step=None, until=None) -> dict[str, torch.Tensor]:
    """Play until every env of the batch has finished one episode; return the statistics of those
    first episodes ([num_envs] per statistic). ``on_step(env, td, next_td)`` sees every step before
    the finished envs are reset (the recorder uses it); ``until()`` true after a step ends the play
    there (a caller that has seen what it needs; the unfinished envs' statistics stay 0)."""
    keys = stat_keys(env)
    n = env.num_envs
    finished = torch.zeros(n, dtype=torch.bool, device=env.device)
    out = {k: torch.zeros(n, device=env.device) for k in keys}
    td = env.reset()
    # a task may end episodes by itself, but never later than its time limit
    for _ in range(env.episode_len + 1):
        td = act(policy, td)
        td = env.step(td)
        nxt = td[NEXT]
        if on_step is not None:
            on_step(env, td, nxt)
        new = nxt[DONE].reshape(n) & ~finished
        for k in keys:
            out[k] = torch.where(new, nxt[stat(k)].reshape(n), out[k])
        finished |= new
        if bool(finished.all()) or (until is not None and until()):
            break
        td = env.maybe_reset(step_mdp(td, keep_other=True, exclude_action=True))
    return out


def act(policy, td):
    """``policy(td)``; an error inside it that non-finite numbers explain (a NaN observation, weights
    that training took to NaN) is one ``ConfigError`` line naming them, not tensordict's "Failed while
    executing module '0'" under a traceback. Any other error is left as it is."""
    try:
        return policy(td)
    except Exception as e:  # noqa: BLE001 - only named here when the numbers explain it; re-raised otherwise
        cause = _nonfinite(policy, td)
        if cause is None:
            raise
        raise ConfigError(f"the policy failed while acting ({type(e).__name__}: {' '.join(str(e).split())[:120]}) "
                          f"because {cause}") from None


def _nonfinite(policy, td) -> str | None:
    """What is not finite where a policy acts: its observation, or one of its weights; None if nothing."""
    obs = td.get(OBS, None)
    if obs is not None and obs.is_floating_point() and not bool(torch.isfinite(obs).all()):
        return "its observation holds NaN or infinity (the env's state left the finite numbers)"
    for name, w in _weights(policy):
        if w.is_floating_point() and not bool(torch.isfinite(w).all()):
            return (f"its weight {name} holds NaN or infinity (the training diverged: lower algo.lr or algo.max_grad_norm, "
                    "or start from another seed)")
    return None


def _weights(policy, depth: int = 0):
    """The named parameters of ``policy``: a module's own, or those of the policies it holds (a
    match's ``TeamPolicies``, a seat's wrapper)."""
    if isinstance(policy, torch.nn.Module):
        yield from policy.named_parameters()
        return
    if depth > 3:
        return
    for attr in ("policies", "policy", "learner"):
        sub = getattr(policy, attr, None)
        for p in sub if isinstance(sub, (list, tuple)) else [sub]:
            if p is not None and not inspect.ismethod(p):
                yield from _weights(p, depth + 1)


def summarize(results: dict[str, torch.Tensor], metric: str) -> dict:
    """Mean and standard deviation of every statistic; the task metric first."""
    table = {}
    for k in [metric, *[k for k in results if k != metric]]:
        v = results[k].double()
        table[k] = {"mean": float(v.mean()), "std": float(v.std(unbiased=False)) if v.numel() > 1 else 0.0}
    return {"metric": metric, "episodes": int(next(iter(results.values())).numel()), "stats": table}


def collect(env, policy, td, steps: int):
    """``steps`` steps of every env; returns the [num_envs, steps] batch and the next input."""
    out = []
    for _ in range(steps):
        td = act(policy, td)
        step, td = env.step_and_maybe_reset(td)
        out.append(step)
    return torch.stack(out, dim=1), td


def finished_stats(batch, team: int | None = None) -> dict[str, float]:
    """Means of the statistics of the episodes that ended in ``batch`` (NaN when none did).

    ``team=0`` (a seat whose learner plays team 0): ``return`` and ``r_*`` are that team's (a
    competitive task's ``*_team0`` statistics) and the all-drone means move to ``*_all``; on a match
    the all-drone ``r_win_or_lose`` is 0 by construction, since one team's win is the other's loss."""
    nxt = batch[NEXT]
    done = nxt[DONE].reshape(-1)
    n = int(done.sum())
    out = {"episodes": float(n)}
    for k in nxt[STATS].keys():
        v = nxt[stat(k)].reshape(-1)[done]
        out[k] = float(v.mean()) if n else math.nan
    suffix = f"_team{team}"
    if team is not None:
        for base in [k for k in out if k == "return" or k.startswith("r_")]:
            if base + suffix in out:
                out[f"{base}_all"], out[base] = out[base], out.pop(base + suffix)
    return out


__all__ = ["act", "collect", "finished_stats", "run_episodes", "stat_keys", "summarize"]
