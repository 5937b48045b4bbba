"""Stage I of HCSP for hierarchical members: the drills trained by the run itself (``population.drills=train``;
docs/competitive.md, "Hierarchical members").

Each drill that plays the ball (serve, pass, set, attack) is imitated from its scripted player
(``algo=bc``, ``population.drill_bc_frames`` frames) and the clone fine-tuned by PPO
(``population.drill_frames`` frames) with the recipe of the learned drills of docs/hierarchical.md (a
critic warm-up, then a slow, tightly clipped actor, no entropy bonus); hover stays scripted. The drills
are written as a team file, ``population/stage_one/trained_drills.yaml`` (``hierarchical: {drill: checkpoint}``),
which then stands wherever the run reads ``population.drills``: the drills every oracle plays over, and
member 0 (the drills under the rule-based high level) where ``population.seed_members`` names ``train``.

Files (resume: a drill whose PPO run finished is kept; one cut short is trained again from its seed,
which the run's seed and the drill's place fix, so it gives the same drill):

    population/stage_one/<drill>/bc/    the drill's imitation run
    population/stage_one/<drill>/ppo/   its fine-tuning run
    population/stage_one/trained_drills.yaml      the team file, written last
"""

from __future__ import annotations

import shutil
from pathlib import Path

from volleybots.algos.population import TRAIN, population_of
from volleybots.algos.ppo import FINE_TUNE
from volleybots.config import load
from volleybots.files import write_atomic
from volleybots.runs import POPULATION_DIR
from volleybots.train import train

STAGE_DIR = "stage_one"
TRAINED = ("serve", "pass", "set", "attack")  # the drills that play the ball; hover stays scripted
RECIPE = ("algo=ppo", *FINE_TUNE)  # the learned drills' fine-tuning from their clones (docs/hierarchical.md)
SEED_STRIDE = 100  # drill j's runs use seed + SEED_STRIDE * (j + 1) (bc) and one more (PPO)


def team_path(run_path) -> Path:
    return Path(run_path) / POPULATION_DIR / STAGE_DIR / "trained_drills.yaml"  # member 0 takes its name


def drills_spec(run_path, spec) -> str:
    """``spec`` as a competitor can be read: ``train`` is the run's stage-I team file, anything else itself."""
    return str(team_path(run_path)) if str(spec) == TRAIN else str(spec)


def train_drills(cfg, run_path, log=None) -> Path:
    """Stage I: train the drills of ``TRAINED`` (bc, then PPO from it) in ``run_path`` and write their team
    file; returns its path. Done before (the team file exists): nothing is trained again."""
    m = population_of(cfg)
    team = team_path(run_path)
    if team.is_file():
        return team
    common = (f"threads={cfg.threads}", f"env.num_envs={cfg.env.num_envs}", f"env.action_space={cfg.env.action_space}", "progress=false",
              "evaluation.record=false", f"evaluation.episodes={cfg.evaluation.episodes}")
    for j, name in enumerate(TRAINED):
        work = team.parent / name
        if (work / "ppo" / "summary.json").is_file():
            continue
        shutil.rmtree(work, ignore_errors=True)  # cut short: trained again from its seed
        seed = cfg.seed + SEED_STRIDE * (j + 1)
        train(load([f"task={name}", "algo=bc", f"total_frames={m.drill_bc_frames}", f"seed={seed}", *common]), work / "bc")
        train(load([f"task={name}", *RECIPE, f"init={work / 'bc'}", f"total_frames={m.drill_frames}", f"seed={seed + 1}", *common]),
              work / "ppo")
        if log is not None:
            log(f"stage I: drill {name} trained ({m.drill_bc_frames:,} frames of imitation, {m.drill_frames:,} of PPO)")
    lines = [f"  {name}: {name}/ppo/checkpoints/final.pt" for name in TRAINED]
    text = "# the drills population.drills=train made (population/stage_one.py); paths relative to this file\nhierarchical:\n"
    write_atomic(team, text + "\n".join(lines) + "\n", "a stage I team file")
    return team


__all__ = ["RECIPE", "TRAIN", "TRAINED", "drills_spec", "team_path", "train_drills"]
