"""The receive drill's figures for a policy: serves returned, deep and lob apart.

    python benchmarks/receive_drill.py POLICY [POLICY ...] episodes=256 seed=9800 [opening=true] [json=OUT]

POLICY is ``scripted`` (the drill's scripted player: the ``receiver``'s play) or a run dir /
checkpoint of a policy that plays the drill (trained on it, or a 1v1 policy: the drill shares the
1v1 observation). Each plays ``episodes`` drill episodes (one serve each) on ``seed``, on its mean
action; ``opening=true`` plays the drill with ``opening=True`` (the match's wait before the serve).
docs/receive.md quotes these figures.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import torch

import volleybots
from volleybots.config.args import option, script_options
from volleybots.play import run_episodes
from volleybots.policies.store import load_policy, policy_checkpoint
from volleybots.scripted import make_scripted_policy


def drill_record(policy: str, episodes: int, seed: int, opening: bool = False) -> dict:
    env = volleybots.make_env("receive", num_envs=episodes, seed=seed, opening=opening)
    if policy == "scripted":
        pol = make_scripted_policy(env)
    else:
        pol = load_policy(policy_checkpoint(policy, "policy"), env, deterministic=True)
    res = run_episodes(env, pol)
    deep = res["deep_serve"] > 0.5
    ok = res["success"] > 0.5
    return {"policy": policy, "seed": seed, "opening": opening, "episodes": episodes, "returned": int(ok.sum()), "deep": int(deep.sum()),
            "deep_returned": int((ok & deep).sum()), "lob_returned": int((ok & ~deep).sum()), "touched": int((res["hits"] >= 1).sum()),
            "return_mean": float(res["return"].mean())}


@dataclass
class Args:
    policies: list[str] = option(help="the policies played in the drill", factory=lambda: [], positional="+")
    episodes: int = option(256, "episodes played")
    seed: int = option(9800, "the seed")
    opening: bool = option(False, "start each episode at the rally's opening")
    json: Optional[Path] = option(None, "FILE: also write the results here")


def main() -> None:
    a = script_options(Args, None, __doc__)
    torch.set_num_threads(1)
    rows = [drill_record(p, a.episodes, a.seed, a.opening) for p in a.policies]
    for r in rows:
        print(json.dumps(r), flush=True)
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps({"rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
