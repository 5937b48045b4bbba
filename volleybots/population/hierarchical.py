"""Hierarchical members of a population (``population.members=hierarchical``; the HCSP route, docs/competitive.md).

A hierarchical member is the 3 vs 3 team of drills under a learned high level
(``volleybots.scripted.hierarchical``, ``volleybots.policies.high_level``). The run copies the drills it
plays with into ``population/drills/`` once (from ``population.drills``: a zoo team, a team file, or the
scripted drills), so a run dir holds everything its members need; each oracle trains a high level over
those drills against the opponent the loop hands it (the meta-solver's mixture of the population, with
``population.fixed_opponents`` beside it) and writes:

    population/member_<k>.pt       a record: builtin hierarchical, its files relative to the folder
    population/high_level_<k>.pt   the member's high level (``save_high_level``: weights only)

Stage I of HCSP (the drills) is reused from the zoo by default (its frames stated on the zoo card);
stage II (high levels as best responses to the population) is the oracle here; stage III (the
receiving drills fine-tuned on the serves recorded against the oracle's opponent) runs before the
oracles of ``population.tune_at`` where ``population.tune_drills`` names drills (population/tune_drills.py).

Determinism: an oracle is seeded by the run's seed and its iteration alone, and starts from a member
file, so an oracle killed before its member was written is trained again from the start by a resume
and gives the same member.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from omegaconf import OmegaConf

from volleybots.algos.population import population_of
from volleybots.config import to_dict
from volleybots.errors import ConfigError
from volleybots.policies import single_policy
from volleybots.policies.builtin import HIGH_LEVEL
from volleybots.policies.high_level import read_high_level, save_high_level
from volleybots.policies.store import policy_checkpoint
from volleybots.population.stage_one import drills_spec
from volleybots.population.team_files import copy_team, high_level_path
from volleybots.population.tune_drills import current_drills, tune
from volleybots.runs import CKPT_FORMAT, POPULATION_DIR, MetricsLog, population_members, read_checkpoint
from volleybots.train.high_level import HighLevelConfig, train_high_level
from volleybots.train.progress import note


def team_files(spec: str, what: str = "population.drills") -> tuple[str, dict[str, str]]:
    """The label and files (drill -> checkpoint file, and ``high_level``) of the hierarchical team ``spec``."""
    comp = single_policy(spec, what)
    src = comp.members[0].source
    if src["kind"] != "hierarchical":
        raise ConfigError(f"{what}={spec!r} is no hierarchical team (it is a {src['kind']} player); allowed: hierarchical "
                          "(scripted drills), a zoo team such as zoo:3v3/hcsp_return, or a team file 'hierarchical: {drill: checkpoint}'")
    files = {}
    for name, target in src["drills"].items():
        files[name] = str(target) if name == HIGH_LEVEL else str(policy_checkpoint(str(target), f"{what} drill {name!r}:", builtins=()))
    return comp.label, files


def team_record(label: str, files: dict[str, str], **extra) -> dict:
    """A member file's record of a hierarchical team (weights-only: plain strings and numbers)."""
    return {"format": CKPT_FORMAT, "builtin": "hierarchical", "task": "3v3", "label": label, "drills": dict(files), **extra}


def seed_member(run_path, spec: str, k: int) -> dict:
    """Member ``k`` from the seed ``spec`` when it is a hierarchical team: its files copied into the run."""
    label, files = team_files(spec, "population.seed_members entry")
    return team_record(label, copy_team(run_path, files, k), frames=0)


def run_drills(run_path, drills_spec: str) -> dict[str, str]:
    """The run's own copies of ``population.drills``' drills (absolute paths), made on first use."""
    _, files = team_files(drills_spec)
    rel = copy_team(run_path, {k: v for k, v in files.items() if k != HIGH_LEVEL}, 0)
    return {k: str(Path(run_path) / POPULATION_DIR / v) for k, v in rel.items()}


def team_options(drills_spec: str) -> tuple[bool, bool]:
    """The event settings (receive_coming, receive_attack) of the drills' team's high level: the drills
    were trained for them, so every high level over them keeps them."""
    _, files = team_files(drills_spec)
    if HIGH_LEVEL not in files:
        return False, False
    info = read_high_level(files[HIGH_LEVEL])[1]
    return bool(info.get("receive_coming", False)), bool(info.get("receive_attack", False))


def newest_high_level(run_path, paths: list[Path]):
    """The high level of the newest member that has one (FSP / warm-started PSRO), or None."""
    for path in reversed(paths):
        state = read_checkpoint(path)
        high = (state.get("drills") or {}).get(HIGH_LEVEL)
        if state.get("builtin") == "hierarchical" and high:
            return read_high_level(Path(run_path) / POPULATION_DIR / high)[0]
    return None


def train_member(cfg, run_path, metrics_path, i: int, k: int, opponent, frames: int, time_left: float, seed: int) -> dict:
    """Iteration ``i``'s oracle: a high level over the run's drills trained on ``seed`` against
    ``opponent`` (a ``Competitor``, the loop's choice; None: self-play, population=sp), to be written as member ``k``; ``frames`` were
    spent before it, ``time_left`` seconds remain to it (inf: no limit). Returns the member's record."""
    m = population_of(cfg)  # the loop's keys
    spec = drills_spec(run_path, m.drills)  # population.drills=train: stage I's team file
    drills = current_drills(run_path, i - 1, run_drills(run_path, spec))
    if m.tune_drills:  # stage III: the receiving drills fine-tuned on the serves the newest member meets
        receiver = str(population_members(run_path)[k - 1])
        drills = tune(cfg, run_path, i, receiver, opponent, drills, seed, note(cfg.progress))
    coming, attack = team_options(spec)
    # the newest member's high level (last), the first member's (first: the team the run starts from), or none
    since = {"last": k, "first": 1}.get(m.learner_init, 0)
    start = newest_high_level(run_path, population_members(run_path)[:since]) if since else None
    limit = 0.0 if time_left == float("inf") else max(time_left, 1e-3)
    hc = HighLevelConfig(games=m.high_level_games, batch=m.high_level_batch, lr=m.high_level_lr, seed=seed,
                         receive_coming=coming, receive_attack=attack, time_limit=limit,
                         pool=m.oracle_pool, chunks=m.oracle_chunks)
    metrics = MetricsLog(metrics_path, keep_until_frames=frames)  # rows of an oracle a kill cut short go
    t0, spent = time.monotonic(), [0]

    def log(row: dict) -> None:
        spent[0] += row["frames"]
        games = row["won"] + row["drawn"] + row["lost"]
        metrics.write({"phase": "train", "frames": frames + spent[0], "iteration": i, "games": row["games"],
                       "train_win": row["won"] / max(games, 1), "train_draw": row["drawn"] / max(games, 1)})
        if cfg.progress:
            eta = (time.monotonic() - t0) / row["games"] * max(m.high_level_games - row["games"], 0)
            print(f"iteration {i}/{m.iterations}, high level: games {row['games']}/{m.high_level_games}, W/D/L "
                  f"{row['won']}/{row['drawn']}/{row['lost']}, oracle ETA {eta:.0f} s", file=sys.stderr, flush=True)

    match = OmegaConf.create(to_dict(cfg))
    if m.oracle_fall_fault:  # no oracle learns to save a rally it would lose by crashing into a draw
        match.task.fall_fault = True
    net, history = train_high_level(match, drills, opponent, hc, log, start=start)
    info = {"games": history[-1]["games"], "seed": seed, "iteration": i, "receive_coming": coming, "receive_attack": attack,
            "opponent": "self" if opponent is None else opponent.label}
    save_high_level(net, high_level_path(run_path, k), info)
    root = Path(run_path) / POPULATION_DIR
    files = {**{name: str(Path(p).relative_to(root)) for name, p in drills.items()}, HIGH_LEVEL: high_level_path(run_path, k).name}
    last = history[-4:]  # the oracle's last batches: its win rate against the opponent at the end
    won = sum(r["won"] for r in last) / max(sum(r["won"] + r["drawn"] + r["lost"] for r in last), 1)
    oracle = {"updates": len(history), "games": history[-1]["games"], "converged": None, "win_rate": round(won, 4)}
    return team_record("sp" if opponent is None else f"br{i}", files, frames=frames + spent[0], iteration=len(history), oracle=oracle)


__all__ = ["copy_team", "high_level_path", "run_drills", "seed_member", "team_files",
           "team_record", "train_member"]
