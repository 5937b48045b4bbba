"""The behaviour clone a population starts from (``population.learner_init=bc``, ``population.seed_members=[bc]``).

The clone is an ordinary ``algo=bc`` run (docs/imitation.md): the learner sits on team 0 against the
task's scripted team and clones its own team's scripted player, for ``population.bc_frames`` frames, the
first half driven by the teacher alone, then DAgger. It is made once per population run, in
``<run>/population/bc/`` (a normal run dir: ``replay``, ``eval`` and ``resume=`` work on it), before
the first iteration, and reused by every iteration and by every resume of the run: a finished clone
is never retrained, a clone killed mid-training is resumed from its own checkpoint.

Its networks are the population learner's (the keys of ``PPONetConfig``: hidden sizes, activation,
normalisations, centralised critic, discount), so every learner can start from it through ``init=``.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import torch

from volleybots.algos.population import CLONE
from volleybots.algos.ppo import PPONetConfig
from volleybots.config import to_dict, validate
from volleybots.policies.competitors import POPULATION_DIR
from volleybots.runs import CKPT_FORMAT, RunDir, read_checkpoint

CLONE_SEED = 700_000  # the clone trains with seed + CLONE_SEED: a stream of its own
# keys of the learner's algo config the clone is not given: the clone's own learning rate (bc's, for
# its maximum-likelihood fit) and the rest of what PPO's update alone uses
_NOT_COPIED = ("actor_lr",)


def clone_dir(run_path: Path) -> Path:
    return Path(run_path) / POPULATION_DIR / CLONE


def needs_clone(pop) -> bool:
    """Whether the population node ``pop`` starts learners or its first members from the clone."""
    return pop.learner_init == CLONE or CLONE in [str(s) for s in pop.seed_members]


def clone_config(cfg):
    """The validated config of the clone's run: the population's task, env, seed stream and networks;
    ``algo=bc opponent=scripted`` for ``population.bc_frames`` frames, fitted at ``population.bc_replay_ratio``."""
    data = to_dict(cfg)
    m = cfg.population
    net = {f.name: getattr(cfg.algo, f.name) for f in dataclasses.fields(PPONetConfig) if f.name not in _NOT_COPIED}
    net["hidden"] = list(net["hidden"])
    data["algo"] = {"name": "bc", **net, "expert_frames": m.bc_frames // 2, "replay_ratio": m.bc_replay_ratio}
    data.update(population=None, opponent="scripted", opponent_deterministic=False, total_frames=m.bc_frames, init=None, time_limit=0,
                seed=cfg.seed + CLONE_SEED, resume=None)
    return validate(data)


def make_clone(cfg, run_path: Path) -> Path:
    """Train the clone if the run has none (resume one cut short); return the checkpoint learners start
    from: its ``best.pt`` (best periodic evaluation against the scripted team), else ``final.pt``."""
    from volleybots.train import resume, train

    run = RunDir(clone_dir(run_path))
    if not run.final_path.is_file():
        if cfg.progress:  # the clone's lines say "clone", and this one what it is: the run's first phase, not an iteration
            print(f"clone: the population's first phase, a behaviour clone of the scripted team (algo=bc, population.bc_frames="
                  f"{cfg.population.bc_frames}) in {run.path}; iteration 1 starts from it", file=sys.stderr, flush=True)
        if (run.path / "config.yaml").is_file():
            resume(run.path, label="clone")
        else:
            train(clone_config(cfg), run.path, label="clone")
    return run.best_path if run.best_path.is_file() else run.final_path


def clone_member(ckpt: Path, dest: Path) -> None:
    """Member file of the clone (``seed_members=[bc]``): its checkpoint without the imitation dataset
    (only the policy plays in a population), labelled ``bc``."""
    state = read_checkpoint(ckpt)
    algo = dict(state["algo"])
    if "data" in algo:  # bc's dataset: empty it, so the file is the networks' size
        obs, act = algo["data"]["obs"], algo["data"]["action"]
        algo["data"] = {"obs": obs[:0].clone(), "action": act[:0].clone()}
        frames = int(algo["counters"][0])
        algo["counters"] = torch.tensor([frames, 0, 0])
    state.update(algo=algo, label=CLONE, format=state.get("format", CKPT_FORMAT))
    tmp = dest.with_suffix(".tmp")
    torch.save(state, tmp)
    tmp.replace(dest)


__all__ = ["CLONE", "CLONE_SEED", "clone_config", "clone_dir", "clone_member", "make_clone", "needs_clone"]
