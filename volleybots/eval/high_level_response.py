"""Best responses over the high level (``eval exploitability ... high_level=GAMES``, 3 vs 3).

A flat MAPPO response to a hierarchical team has to learn volleyball from nothing in its budget; a
response over the high level keeps a team's drills (``high_level_drills``, by default
``zoo:3v3/hcsp_return``'s) and trains only who receives, sets and attacks, by PPO on game results
against the target (``volleybots.train.high_level``, the hierarchical population's oracle). Each
training seed's response is saved in the report's folder as ``hl/`` (seed 0), ``hl_s1/``, ...: its
``high_level.pt`` and a team file ``team.yaml`` that any verb plays (``eval crossplay OUT/hl/team.yaml
...``). They join the candidates like every trained response, so the figure stays the best candidate's.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from volleybots.errors import ConfigError
from volleybots.policies.builtin import HIGH_LEVEL
from volleybots.population.hierarchical import team_files, team_options

NAME = "hl"  # the responses' folders and candidate names: hl (seed 0), hl_s1, ...
BATCH = 128  # games per update: 8 updates in the smallest useful budget (1,024 games)


def check_high_level(games: int, drills_spec: str, task: str) -> dict[str, str]:
    """The drills (name -> checkpoint) high-level responses will play, checked before anything is written."""
    if not games:
        return {}
    if task != "3v3":
        raise ConfigError(f"high_level={games}: responses over the high level play task 3v3, not {task!r}; give high_level=0")
    _, files = team_files(drills_spec, "high_level_drills")
    return {k: v for k, v in files.items() if k != HIGH_LEVEL}


def name(i: int) -> str:
    return NAME if i == 0 else f"{NAME}_s{i}"


def train_responses(path: Path, target, match_cfg, drills_spec: str, games: int, seeds: int, seed: int, stride: int, say) -> list[dict]:
    """Train ``seeds`` high levels over ``drills_spec``'s drills against ``target`` for ``games`` games each
    (seed ``seed + i * stride``), save them under ``path``; returns per response its name, team file and
    training figures."""
    from volleybots.policies.high_level import save_high_level
    from volleybots.train.high_level import HighLevelConfig, train_high_level

    drills = check_high_level(games, drills_spec, match_cfg.task.name)
    coming, attack = team_options(drills_spec)
    out = []
    for i in range(seeds):
        s = seed + i * stride
        say(f"training response {name(i)} (a high level over {drills_spec}'s drills, {games} games, seed {s}) against {target.label}")
        hc = HighLevelConfig(games=games, batch=min(BATCH, games), seed=s, receive_coming=coming, receive_attack=attack)
        net, history = train_high_level(match_cfg, drills, target, hc)
        folder = path / name(i)
        folder.mkdir(parents=True, exist_ok=True)
        save_high_level(net, folder / "high_level.pt", {"games": history[-1]["games"], "seed": s, "opponent": target.label,
                                                        "receive_coming": coming, "receive_attack": attack})
        (folder / "team.yaml").write_text(yaml.safe_dump({"hierarchical": {**drills, HIGH_LEVEL: "high_level.pt"}}))
        last = history[-4:]
        won, decided = sum(r["won"] for r in last), sum(r["won"] + r["lost"] for r in last)
        out.append({"name": name(i), "team": str(folder / "team.yaml"), "games": history[-1]["games"], "seed": s,
                    "train_win_rate": round(won / decided, 4) if decided else None})
    return out


__all__ = ["check_high_level", "train_responses"]
