"""Stage III of HCSP for hierarchical members: the receiving drills fine-tuned on the serves the team meets
(``population.tune_drills``; docs/competitive.md, "Stage III").

Before the oracle of an iteration in ``population.tune_at`` trains its high level, the loop records the
serves of the oracle's opponent (the meta-solver's mixture with the fixed opponents beside it) in
``population.tune_games`` games that the newest member receives (``play.serves.record_serves``: the
ball right after the server's hit that sent it over), writes them as a ball bank, and fine-tunes
each drill of ``population.tune_drills`` (Pass, Attack: the drills that receive) by PPO from its
current weights for ``population.tune_frames`` frames, a share ``population.tune_share`` of its
balls drawn from the bank and the rest its own (``task.serve_bank``), with the fine-tuning recipe
the zoo's attack used on the scripted serve (critic warm-up, no entropy bonus). The tuned drills
are copied into ``population/drills/`` by content, and from that iteration on every oracle plays
them (members keep the drills they were trained over: a member is its drills and its high level).

Files (resume: a tuning whose record exists is not redone; one cut short is trained again from the
start, seeded by the run's seed and the iteration alone, so it gives the same drills):

    population/tune/<i>/serves.pt     the ball bank of iteration i
    population/tune/<i>/<drill>/      the drill's PPO run
    population/tune_<i>.json          the record: the drills after iteration i's tuning (relative paths)
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from volleybots.algos.population import population_of
from volleybots.config import load
from volleybots.files import write_atomic
from volleybots.play.serves import record_serves, write_bank
from volleybots.policies import resolve_competitor
from volleybots.population.team_files import copy_team
from volleybots.runs import POPULATION_DIR
from volleybots.train import train

TUNE_DIR = "tune"
# the PPO recipe of the zoo's attack on the scripted serve (docs/hierarchical.md): the critic first
# learns the new balls' values, then the actor moves at a rate that keeps the drill's own skill
RECIPE = ("algo=ppo", "algo.actor_freeze_updates=10", "algo.actor_lr=3e-4", "algo.clip_epsilon=0.2", "algo.entropy_coeff=0.0")


def record_path(run_path, i: int) -> Path:
    return Path(run_path) / POPULATION_DIR / f"tune_{i:03d}.json"


def current_drills(run_path, i: int, base: dict[str, str]) -> dict[str, str]:
    """The drills (name -> absolute path) iteration ``i``'s oracle plays: the newest tuning's at or before
    ``i``, else ``base`` (the run's copies of ``population.drills``)."""
    root = Path(run_path) / POPULATION_DIR
    for j in range(i, 0, -1):
        path = record_path(run_path, j)
        if path.is_file():
            return {**base, **{k: str(root / v) for k, v in json.loads(path.read_text())["drills"].items()}}
    return dict(base)


def tune(cfg, run_path, i: int, receiver: str, opponent, base: dict[str, str], seed: int, log=None) -> dict[str, str]:
    """Iteration ``i``'s stage III (when ``i`` is in ``population.tune_at``): ``receiver`` (a member file)
    receives ``opponent``'s serves, and the drills of ``population.tune_drills`` are fine-tuned on them from
    ``base``'s weights; returns the drills the oracle then plays (unchanged when ``i`` tunes nothing)."""
    m = population_of(cfg)
    if not m.tune_drills or i not in m.tune_at:
        return base
    root = Path(run_path) / POPULATION_DIR
    if record_path(run_path, i).is_file():  # done before a kill: the same drills
        return current_drills(run_path, i, base)
    work = root / TUNE_DIR / f"{i:03d}"
    shutil.rmtree(work, ignore_errors=True)  # a tuning cut short starts again from its seed
    work.mkdir(parents=True)
    me = resolve_competitor(receiver)
    balls = record_serves(cfg, me, me if opponent is None else opponent, m.tune_games, seed)  # None: self-play
    label = receiver if opponent is None else opponent.label
    bank = work / "serves.pt"
    write_bank(bank, balls, opponent=label, iteration=i, games=m.tune_games)
    if log is not None:
        log(f"iteration {i}, stage III: {len(balls)} serves recorded in {m.tune_games} games against {label}")
    tuned = {}
    for k, name in enumerate(m.tune_drills):
        drill_cfg = load([f"task={name}", f"task.serves={m.tune_share}", f"task.serve_bank={bank}", *RECIPE,
                          f"init={base[name]}", f"total_frames={m.tune_frames}", f"seed={seed + k + 1}",
                          f"threads={cfg.threads}", f"env.num_envs={cfg.env.num_envs}", "progress=false", "evaluation.record=false"])
        run = work / name
        summary = train(drill_cfg, run)
        tuned.update(copy_team(run_path, {name: str(run / "checkpoints" / "final.pt")}, i))
        if log is not None:
            log(f"iteration {i}, stage III: {name} tuned for {summary.get('frames', m.tune_frames)} frames")
    write_atomic(record_path(run_path, i), json.dumps({"iteration": i, "serves": len(balls), "drills": tuned}, indent=1),
                 "a stage III record")
    return current_drills(run_path, i, base)


__all__ = ["current_drills", "record_path", "tune"]
